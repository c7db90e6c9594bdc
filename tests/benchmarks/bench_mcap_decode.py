"""Benchmark: ROS 2 JointState MCAP reading, impactcli's reader vs the official decoder.

Writes a 200k-message, 7-joint JointState MCAP (zstd chunks) and measures, on the same
file, each in a fresh process:
* ``read_log`` end to end (the reader's scan, then its chunks collected), messages/s;
* the MCAP walk + bulk decode alone (``scan_mcap`` + ``decode_topic``);
* the official ``mcap`` reader with ``mcap_ros2`` DecoderFactory (one object per message),
  plus its raw iteration (no decoding) for reference.
``--release REF`` measures the first two with that commit's code too, in the same run
(targets: ``read_log`` ≥ 300k msg/s and ≥ 10× the official decoder).

Run: ``python tests/benchmarks/bench_mcap_decode.py [N] [--release REF]``
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

_CHILD = r"""
import json, sys, time
from pathlib import Path
path, n = Path(sys.argv[1]), int(sys.argv[2])
try:
    from impactcli.logs import read_log
    from impactcli.logs.messages.ros2_cdr import decode_topic
    from impactcli.logs.messages.mcap import scan_mcap
except ImportError:  # a release before the layout of docs/development.md
    from impactcli.io import read_log
    from impactcli.io.mcap_ros2 import decode_topic
    from impactcli.io.mcap_scan import scan_mcap

def best(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter(); fn(); times.append(time.perf_counter() - t0)
    return min(times)

def end_to_end():
    assert read_log(path).n_samples == n

def decode():
    scan = scan_mcap(path)
    arr = decode_topic(scan, scan.topics()["/joint_states"], str(path), "/joint_states")
    assert arr.position.shape == (n, 7)

print(json.dumps({"read_log": best(end_to_end), "decode": best(decode)}))
"""


def make_log(n: int, joints: int = 7):  # type: ignore[no-untyped-def]
    from impactcli.types import RobotLog

    rng = np.random.default_rng(1)
    t = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 1_000_000
    return RobotLog(
        t_ns=t, joint_names=tuple(f"joint_{k + 1}" for k in range(joints)),
        position=rng.normal(size=(n, joints)), torque=rng.normal(size=(n, joints)),
        velocity=rng.normal(size=(n, joints)),
    )


def ours(path: Path, n: int, tree: Path | None) -> dict[str, float]:
    """The reader's times in a fresh process (``tree``: that commit's code)."""
    env = dict(os.environ, PYTHONPATH=str(tree)) if tree is not None else None
    r = subprocess.run([sys.executable, "-c", _CHILD, str(path), str(n)], env=env,
                       cwd=tempfile.gettempdir(), capture_output=True, text=True, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def official(path: Path, n: int) -> tuple[float, float]:
    """The official reader: decoded, and raw iteration [s]."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    t0 = time.perf_counter()
    k = 0
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _s, _c, _m, msg in reader.iter_decoded_messages():
            k += len(msg.position)
    decoded = time.perf_counter() - t0
    assert k == 7 * n
    t0 = time.perf_counter()
    with open(path, "rb") as f:
        k = sum(1 for _ in make_reader(f).iter_messages(log_time_order=False))
    assert k == n
    return decoded, time.perf_counter() - t0


def main() -> None:
    from release_tree import release_tree

    from impactcli.logs import write_log

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("n", nargs="?", type=int, default=200_000)
    ap.add_argument("--release", help="also measure this commit's reader (a git ref)")
    args = ap.parse_args()
    n = args.n
    with tempfile.TemporaryDirectory() as d, release_tree(args.release) as tree:
        path = Path(d) / "bench.mcap"
        t0 = time.perf_counter()
        write_log(make_log(n), path, mcap_encoding="ros2")
        t_write = time.perf_counter() - t0
        mine = ours(path, n, None)
        base = ours(path, n, tree) if tree is not None else None
        ref_decoded, ref_raw = official(path, n)
        size = path.stat().st_size
    print(f"machine: {platform.platform()}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cpus, Python {platform.python_version()}, load "
          f"{os.getloadavg()[0]:.1f}")
    print(f"file: {n} JointState messages, 7 joints, zstd, {size / 1e6:.1f} MB "
          f"(written in {t_write:.2f} s)")
    rows = [("impactcli read_log (end to end)", mine["read_log"]),
            ("impactcli MCAP walk + bulk decode", mine["decode"])]
    if base is not None:
        rows += [(f"{args.release} read_log (end to end)", base["read_log"]),
                 (f"{args.release} MCAP walk + bulk decode", base["decode"])]
    rows += [("mcap make_reader raw iteration", ref_raw),
             ("mcap_ros2 DecoderFactory (decoded)", ref_decoded)]
    print(f"{'path':<40} {'time [s]':>9} {'k msg/s':>9} {'x decoder':>10}")
    for name, t in rows:
        print(f"{name:<40} {t:>9.3f} {n / t / 1e3:>9.0f} {ref_decoded / t:>10.1f}")


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).parent))
    main()
