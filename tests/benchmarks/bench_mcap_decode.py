"""Benchmark: ROS 2 JointState MCAP decoding, impactcli's bulk reader vs the official decoder.

Writes a 200k-message, 7-joint JointState MCAP (zstd chunks) and measures, on the same file:
* ``read_log`` end to end (scan + bulk decode + RobotLog), messages/s;
* the scan + bulk decode alone (``decode_topic``);
* the official ``mcap`` reader with ``mcap_ros2`` DecoderFactory (one object per message),
  plus its raw iteration (no decoding) for reference.

Run: ``python tests/benchmarks/bench_mcap_decode.py [N]``
"""

from __future__ import annotations

import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def make_log(n: int, joints: int = 7):  # type: ignore[no-untyped-def]
    from impactcli.types import RobotLog

    rng = np.random.default_rng(1)
    t = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 1_000_000
    return RobotLog(
        t_ns=t, joint_names=tuple(f"joint_{k + 1}" for k in range(joints)),
        position=rng.normal(size=(n, joints)), torque=rng.normal(size=(n, joints)),
        velocity=rng.normal(size=(n, joints)),
    )


def best(fn, repeat: int = 3) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from impactcli.io import read_log, write_log
    from impactcli.io.mcap_ros2 import decode_topic
    from impactcli.io.mcap_scan import scan_mcap

    n = int(sys.argv[1]) if len(sys.argv) > 1 else 200_000
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "bench.mcap"
        t0 = time.perf_counter()
        write_log(make_log(n), path, mcap_encoding="ros2")
        t_write = time.perf_counter() - t0

        def ours_end_to_end() -> None:
            log = read_log(path)
            assert log.n_samples == n

        def ours_decode() -> None:
            scan = scan_mcap(path)
            arr = decode_topic(scan, scan.topics()["/joint_states"], str(path), "/joint_states")
            assert arr.position.shape == (n, 7)

        def official_decoded() -> None:
            k = 0
            with open(path, "rb") as f:
                reader = make_reader(f, decoder_factories=[DecoderFactory()])
                for _s, _c, _m, msg in reader.iter_decoded_messages():
                    k += len(msg.position)
            assert k == 7 * n

        def official_raw() -> None:
            k = 0
            with open(path, "rb") as f:
                for _s, _c, _m in make_reader(f).iter_messages(log_time_order=False):
                    k += 1
            assert k == n

        rows = [
            ("impactcli read_log (end to end)", best(ours_end_to_end)),
            ("impactcli scan + bulk decode", best(ours_decode)),
            ("mcap make_reader raw iteration", best(official_raw, 1)),
            ("mcap_ros2 DecoderFactory (decoded)", best(official_decoded, 1)),
        ]
        size = path.stat().st_size
    print(f"machine: {platform.platform()}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cpus, Python {platform.python_version()}")
    print(f"file: {n} JointState messages, 7 joints, zstd, {size / 1e6:.1f} MB "
          f"(written in {t_write:.2f} s)")
    print(f"{'path':<38} {'time [s]':>9} {'k msg/s':>9}")
    for name, t in rows:
        print(f"{name:<38} {t:>9.3f} {n / t / 1e3:>9.0f}")


if __name__ == "__main__":
    main()
