"""Benchmark: peak memory and wall time of reading a long CSV: scan + chunks, and read_log.

Run: ``python tests/benchmarks/bench_stream_read.py [MINUTES ...] [--chunk-rows 65536]
[--keep DIR] [--release REF]`` (default 10 60).

For each duration a synthetic 7-joint 1 kHz canonical CSV is written into a temporary
folder (``time`` with 9 decimals, then per joint ``.position``, ``.torque``,
``.position_ref``, ``.velocity_ref``, ``.acceleration_ref``, values with about 10
significant digits). Then, each in a fresh process, ``scan_log`` + iterating every chunk of
:func:`impactcli.logs.reader.iter_chunks` (``chunk_rows``) and :func:`impactcli.logs.read_log`
(the chunks collected) read it; the benchmark reports their wall time and peak resident
memory (ru_maxrss of that process, which reports it itself). ``--release REF`` measures
that commit's code too, in the same run.
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
import time
from pathlib import Path

JOINTS = 7
RATE_HZ = 1000
BLOCK_ROWS = 200_000

_CHILD = r"""
import json, resource, sys, time
mode, path, chunk_rows = sys.argv[1], sys.argv[2], int(sys.argv[3])
t0 = time.perf_counter()
out = {}
if mode == "stream":
    try:
        from impactcli.logs.reader import iter_chunks, scan_log
    except ImportError:  # a release before the layout of docs/development.md
        from impactcli.io.stream import iter_chunks, scan_log
    scan = scan_log(path)
    out["scan_s"] = time.perf_counter() - t0
    n = 0
    for c in iter_chunks(path, scan, chunk_rows):
        n += c.n_samples
else:
    try:
        from impactcli.logs import read_log
    except ImportError:  # a release before the layout of docs/development.md
        from impactcli.io import read_log
    n = read_log(path).n_samples
out["n"] = n
out["wall_s"] = time.perf_counter() - t0
out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
"""


def write_csv(minutes: float, path: Path, seed: int = 1) -> int:
    """Write the synthetic log; returns its number of rows."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from impactcli.logs.write import ns_to_decimal_text

    n = int(minutes * 60 * RATE_HZ)
    rng = np.random.default_rng(seed)
    freq = rng.uniform(0.05, 0.5, (3, JOINTS))
    amp = rng.uniform(0.2, 1.0, (3, JOINTS))
    names = ["time"] + [f"j{j + 1}.{s}" for j in range(JOINTS)
                        for s in ("position", "torque", "position_ref", "velocity_ref",
                                  "acceleration_ref")]
    opts = pacsv.WriteOptions(include_header=False, quoting_style="none")
    with open(path, "wb") as f:
        f.write((",".join(names) + "\n").encode())
        for a in range(0, n, BLOCK_ROWS):
            k = np.arange(a, min(n, a + BLOCK_ROWS))
            t = k[:, None] / RATE_HZ
            ph = 2 * np.pi * freq[:, None, :] * t[None]  # (3, n, J)
            q = (amp[:, None, :] * np.sin(ph)).sum(axis=0)
            qd = (amp[:, None, :] * 2 * np.pi * freq[:, None, :] * np.cos(ph)).sum(axis=0)
            qdd = -(amp[:, None, :] * (2 * np.pi * freq[:, None, :]) ** 2
                    * np.sin(ph)).sum(axis=0)
            tau = 20 * qdd + 5 * np.sin(q) + 2 * qd + rng.normal(0, 0.05, q.shape)
            cols: dict[str, object] = {"time": ns_to_decimal_text(k * (10**9 // RATE_HZ))}
            for j in range(JOINTS):
                for s, v, d in (("position", q + rng.normal(0, 1e-5, q.shape), 9),
                                ("torque", tau, 8), ("position_ref", q, 9),
                                ("velocity_ref", qd, 9), ("acceleration_ref", qdd, 8)):
                    cols[f"j{j + 1}.{s}"] = pa.array(np.round(v[:, j], d))
            pacsv.write_csv(pa.table(cols), f, opts)
    return n


def measure(mode: str, path: Path, chunk_rows: int, tree: Path | None = None
            ) -> dict[str, float]:
    """Wall time and peak RSS of reading ``path`` in a fresh process (``tree``: with that
    commit's code)."""
    env = dict(os.environ, PYTHONPATH=str(tree)) if tree is not None else None
    r = subprocess.run([sys.executable, "-c", _CHILD, mode, str(path), str(chunk_rows)],
                       capture_output=True, text=True, check=True, env=env,
                       cwd=tempfile.gettempdir())
    return json.loads(r.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("minutes", nargs="*", type=float, default=[10.0, 60.0])
    ap.add_argument("--chunk-rows", type=int, default=65536)
    ap.add_argument("--keep", type=Path, help="write the logs here and keep them")
    ap.add_argument("--release", help="also measure this commit's code (a git ref)")
    args = ap.parse_args()
    with release_tree(args.release) as tree:
        _run(args, tree)


def _run(args: argparse.Namespace, tree: Path | None) -> None:
    folder = args.keep or Path(tempfile.mkdtemp(prefix="bench_stream_read_"))
    folder.mkdir(parents=True, exist_ok=True)
    print(f"machine: {platform.processor() or platform.machine()}, python "
          f"{platform.python_version()}; chunk_rows {args.chunk_rows}")
    try:
        for minutes in args.minutes:
            path = folder / f"log_{minutes:g}min.csv"
            t0 = time.perf_counter()
            n = write_csv(minutes, path)
            size = path.stat().st_size / 1e6
            print(f"\n{minutes:g} min: {n} rows x {1 + 5 * JOINTS} columns, {size:.0f} MB "
                  f"(written in {time.perf_counter() - t0:.0f} s)")
            for code, where in (("this", None), (args.release, tree)):
                if code is None or (code != "this" and where is None):
                    continue
                for mode in ("stream", "whole"):
                    r = measure(mode, path, args.chunk_rows, where)
                    extra = f" (scan {r['scan_s']:.1f} s)" if mode == "stream" else ""
                    print(f"  {code:>8s} {mode:6s}: wall {r['wall_s']:6.1f} s, peak RSS "
                          f"{r['peak_mb']:7.0f} MB{extra}", flush=True)
                    assert r["n"] == n
            if not args.keep:
                path.unlink()
    finally:
        if not args.keep:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).parent))
    from release_tree import release_tree

    main()
