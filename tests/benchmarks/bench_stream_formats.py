"""Benchmark: peak memory and wall time of streaming long MCAP and ``.npz`` logs.

Run: ``python tests/benchmarks/bench_stream_formats.py [MINUTES ...] [--chunk-rows 65536]
[--formats mcap npz rosbag2] [--whole] [--release REF]`` (default 10 60).

For each duration a synthetic 7-joint 1 kHz log is written, block by block (the benchmark
itself stays bounded), into a temporary folder:

- ``mcap``: ROS 2 JointState on ``/joint_states`` (position, velocity, effort) and its
  ``/joint_states_ref`` companion (position, velocity), zstd chunks of 1 MiB, header
  stamp = log time;
- ``rosbag2`` (not by default): the same two topics in a rosbag2 folder (SQLite);
- ``npz``: an uncompressed archive of ``t`` (N,) [s], ``q``, ``tau``, ``qref`` (N, 7),
  each ``.npy`` member written in blocks, read through a ``format: npz`` channel map.

Then, in a fresh process, :func:`impactcli.logs.reader.scan_log` and every chunk of
:func:`~impactcli.logs.reader.iter_chunks` (``chunk_rows``); ``--whole`` also times
:func:`impactcli.logs.read_log` in another fresh process; ``--release REF`` measures that
commit's code too, on the same files. Reported: wall time, the scan's
share, and the peak resident memory (``ru_maxrss`` of the child, which
reports it itself). Peak RSS must not grow with the duration.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

JOINTS = 7
NAMES = tuple(f"j{j + 1}" for j in range(JOINTS))
RATE_HZ = 1000
BLOCK_ROWS = 100_000

_CHILD = r"""
import json, resource, sys, time
mode, path, chunk_rows, opts = sys.argv[1], sys.argv[2], int(sys.argv[3]), json.loads(sys.argv[4])
t0 = time.perf_counter()
out = {}
if mode == "stream":
    try:
        from impactcli.logs.reader import iter_chunks, scan_log
    except ImportError:  # a release before the layout of docs/development.md
        from impactcli.io.stream import iter_chunks, scan_log
    scan = scan_log(path, **opts)
    out["scan_s"] = time.perf_counter() - t0
    n = 0
    for c in iter_chunks(path, scan, chunk_rows, **opts):
        n += c.n_samples
    scan.close()
else:
    try:
        from impactcli.logs import read_log
    except ImportError:  # a release before the layout of docs/development.md
        from impactcli.io import read_log
    n = read_log(path, **opts).n_samples
out["n"] = n
out["wall_s"] = time.perf_counter() - t0
out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
"""


def _block(a: int, b: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Samples ``a`` … ``b − 1``: times [ns] and (n, 7) signals (smooth, with noise)."""
    k = np.arange(a, b)
    t = k[:, None] / RATE_HZ
    freq = np.linspace(0.05, 0.5, JOINTS)
    q = np.sin(2 * np.pi * freq * t)
    qd = 2 * np.pi * freq * np.cos(2 * np.pi * freq * t)
    rng = np.random.default_rng(a)
    tau = 20 * np.sin(q) + 2 * qd + rng.normal(0, 0.05, q.shape)
    return 10**9 + k * (10**9 // RATE_HZ), {
        "position": q + rng.normal(0, 1e-5, q.shape), "velocity": qd, "torque": tau,
        "position_ref": q, "velocity_ref": qd}


def write_mcap(n: int, path: Path) -> None:
    """The ROS 2 MCAP log of ``n`` samples (module docstring)."""
    from impactcli.logs.messages.ros2_cdr import encode_jointstates
    from impactcli.logs.write import ros2_writer

    with open(path, "wb") as f:
        w, sid = ros2_writer(f)
        state = w.register_channel(topic="/joint_states", message_encoding="cdr",
                                   schema_id=sid)
        ref = w.register_channel(topic="/joint_states_ref", message_encoding="cdr",
                                 schema_id=sid)
        for a in range(0, n, BLOCK_ROWS):
            t, v = _block(a, min(n, a + BLOCK_ROWS))
            rs = encode_jointstates(t, NAMES, v["position"], v["velocity"], v["torque"])
            rr = encode_jointstates(t, NAMES, v["position_ref"], v["velocity_ref"], None)
            for i, ti in enumerate(t.tolist()):
                w.add_message(ref, log_time=ti, publish_time=ti, sequence=a + i,
                              data=rr[i].tobytes())
                w.add_message(state, log_time=ti, publish_time=ti, sequence=a + i,
                              data=rs[i].tobytes())
        w.finish()  # type: ignore[no-untyped-call]


def write_rosbag2(n: int, path: Path) -> None:
    """The same topics as :func:`write_mcap` in a rosbag2 folder (SQLite), written block
    by block."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from impactcli.logs.messages.ros2_cdr import JOINT_STATE, encode_jointstates
    from impactcli.logs.write import ros2_typestore

    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        store = ros2_typestore()
        ref = w.add_connection("/joint_states_ref", JOINT_STATE, typestore=store)
        state = w.add_connection("/joint_states", JOINT_STATE, typestore=store)
        for a in range(0, n, BLOCK_ROWS):
            t, v = _block(a, min(n, a + BLOCK_ROWS))
            rs = encode_jointstates(t, NAMES, v["position"], v["velocity"], v["torque"])
            rr = encode_jointstates(t, NAMES, v["position_ref"], v["velocity_ref"], None)
            for i, ti in enumerate(t.tolist()):
                w.write(ref, ti, rr[i].tobytes())
                w.write(state, ti, rs[i].tobytes())


def write_npz(n: int, path: Path) -> Path:
    """The ``.npz`` log of ``n`` samples and its channel map (module docstring)."""
    from numpy.lib import format as npf

    arrays = {"t": ((n,), lambda t, v: (t - 10**9) * 1e-9),
              "q": ((n, JOINTS), lambda t, v: v["position"]),
              "tau": ((n, JOINTS), lambda t, v: v["torque"]),
              "qref": ((n, JOINTS), lambda t, v: v["position_ref"])}
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        for key, (shape, pick) in arrays.items():
            with zf.open(f"{key}.npy", "w", force_zip64=True) as f:
                npf.write_array_header_2_0(f, {"descr": "<f8", "fortran_order": False,
                                               "shape": shape})
                for a in range(0, n, BLOCK_ROWS):
                    t, v = _block(a, min(n, a + BLOCK_ROWS))
                    f.write(np.ascontiguousarray(pick(t, v), dtype="<f8").tobytes())
    cmap = path.with_suffix(".map.json")
    cmap.write_text(json.dumps({
        "format": "npz", "time": {"column": "t", "unit": "s"},
        "joints": [{"name": nm, "position": {"column": "q", "index": j},
                    "torque": {"column": "tau", "index": j},
                    "position_ref": {"column": "qref", "index": j}}
                   for j, nm in enumerate(NAMES)]}))
    return cmap


def measure(mode: str, path: Path, chunk_rows: int, opts: dict[str, Any],
            tree: Path | None = None) -> dict[str, Any]:
    """Wall time and peak RSS of reading ``path`` in a fresh process (``tree``: with that
    commit's code)."""
    env = dict(os.environ, PYTHONPATH=str(tree)) if tree is not None else None
    r = subprocess.run([sys.executable, "-c", _CHILD, mode, str(path), str(chunk_rows),
                        json.dumps(opts)], capture_output=True, text=True, check=True,
                       env=env, cwd=tempfile.gettempdir())
    return json.loads(r.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("minutes", nargs="*", type=float, default=[10.0, 60.0])
    ap.add_argument("--chunk-rows", type=int, default=65536)
    ap.add_argument("--formats", nargs="*", default=["mcap", "npz"])
    ap.add_argument("--whole", action="store_true", help="also time read_log")
    ap.add_argument("--release", help="also measure this commit's code (a git ref)")
    args = ap.parse_args()
    modes = ("stream", "whole") if args.whole else ("stream",)
    with release_tree(args.release) as tree:
        codes = [("this", None)] + ([(args.release, tree)] if tree is not None else [])
        _all(args, modes, codes)


def _all(args: argparse.Namespace, modes: tuple[str, ...],
         codes: list[tuple[str, Path | None]]) -> None:
    print(f"{platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}, "
          f"chunk_rows {args.chunk_rows}\n{'format':6s} {'minutes':>7s} {'samples':>9s} "
          f"{'MB':>6s} {'read':6s} {'wall s':>7s} {'scan s':>7s} {'peak RSS MB':>11s} code")
    with tempfile.TemporaryDirectory(prefix="bench_stream_formats_") as tmp:
        for minutes in args.minutes:
            for fmt in args.formats:
                _bench(fmt, minutes, Path(tmp), modes, args.chunk_rows, codes)


def _bench(fmt: str, minutes: float, folder: Path, modes: tuple[str, ...],
           chunk_rows: int, codes: list[tuple[str, Path | None]]) -> None:
    """Write one log, read it each way, print a table row per way."""
    n = int(minutes * 60 * RATE_HZ)
    path = folder / f"log_{minutes:g}min.{fmt}"
    opts: dict[str, Any] = {}
    if fmt == "mcap":
        write_mcap(n, path)
    elif fmt == "rosbag2":
        write_rosbag2(n, path)
    else:
        opts["channel_map"] = str(write_npz(n, path))
    size = sum(f.stat().st_size for f in [path, *path.glob("*")] if f.is_file()) / 1e6
    for code, tree in codes:
        for mode in modes:
            r = measure(mode, path, chunk_rows, opts, tree)
            assert r["n"] == n
            scan = f"{r['scan_s']:7.1f}" if "scan_s" in r else f"{'':7s}"
            print(f"{fmt:6s} {minutes:7g} {n:9d} {size:6.0f} {mode:6s} {r['wall_s']:7.1f} "
                  f"{scan} {r['peak_mb']:11.0f} {code}", flush=True)
    if path.is_dir():
        shutil.rmtree(path)
    else:
        path.unlink()

if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).parent))
    from release_tree import release_tree

    main()
