"""Time and size of the Rerun recording of a long run, written from its chunks:
``python tests/benchmarks/bench_rerun.py [--minutes M] [--release REF]``.

A synthetic 2-joint run at 1 kHz (1 hour = 3.6 M samples per series by default) with the
fake's three events plus one adaptive event per minute, handed to the writer in chunks of
65,536 samples as a replay hands them (``detect --rerun``, ``view``) and written with the
default decimation (200 000 samples per series, ±2 s full-rate windows); ``--full-rate``
also without decimation. ``--release REF`` measures REF's code in the same run (a git
worktree, each code in a fresh process): its chunked writer and, where it has one, its
writer of a whole in-memory result.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
CHUNK_ROWS = 65_536


def _fake_run(minutes: float, extra_events: bool) -> Any:
    import dataclasses

    import numpy as np

    from impactcli.types import Event
    from tests.fakes import fake_result

    res = fake_result(n=int(minutes * 60_000), dt=0.001)
    t = res.log.time_s
    extra = []
    for minute in range(1, int(minutes) if extra_events else 0):
        i0 = int(np.searchsorted(t, minute * 60.0))
        extra.append(Event("adaptive", float(t[i0]), float(t[i0 + 80]), i0, i0 + 80, ("j1",),
                           1.7, {"j1": 2.0}, False))
    return dataclasses.replace(res, events=tuple(sorted((*res.events, *extra),
                                                       key=lambda e: e.t_start)))


def _chunks(res: Any) -> list[Any]:
    log = res.log
    out = []
    for a in range(0, log.n_samples, CHUNK_ROWS):
        b = min(a + CHUNK_ROWS, log.n_samples)
        out.append(SimpleNamespace(
            joints=tuple(log.joint_names), t_ns=log.t_ns[a:b], time_s=log.time_s[a:b],
            signals={k: v[a:b] for k, v in res.signals.items()},
            decisions={k: v[a:b] for k, v in res.decisions.items()},
            position=log.position[a:b], position_ref=log.position_ref[a:b]))
    return out


def child(minutes: float, extra_events: bool, full_rate: bool) -> None:
    """Measure the importable code (one JSON object on stdout)."""
    import importlib

    t0 = time.perf_counter()
    res = _fake_run(minutes, extra_events)
    chunks = _chunks(res)
    build = time.perf_counter() - t0
    t0 = time.perf_counter()
    import pandas  # noqa: F401 - timed apart: the writers import them lazily (pyarrow
    import pyarrow.parquet  # noqa: F401 - imports pandas on its first table)
    import rerun  # noqa: F401

    out: dict[str, Any] = {"build_s": build, "import_rerun_s": time.perf_counter() - t0,
                           "samples": res.log.n_samples, "events": len(res.events)}
    rerun_mod = importlib.import_module("impactcli.outputs.rerun")
    variants = [("", {})] + ([(" full rate", {"max_points": 10**12})] if full_rate else [])
    with tempfile.TemporaryDirectory() as tmp:
        for name, kw in variants:
            path = Path(tmp) / "bench.rrd"
            t1 = time.perf_counter()
            if hasattr(rerun_mod, "RerunWriter"):
                with rerun_mod.RerunWriter() as w:
                    for c in chunks:
                        w(c)
                    w.write(res, path, **kw)
            else:  # before the one writer: the streamed spill and its writer
                rs = importlib.import_module("impactcli.outputs.rerun_stream")
                spill = rs.SpillWriter()
                try:
                    for c in chunks:
                        spill.append(rs.spill_columns(c.joints, c.t_ns, c.signals, c.decisions,
                                                      c.position, c.position_ref))
                    rs.write_rrd_from_spill(res, spill, path, **kw)
                finally:
                    spill.close()
            out[f"chunks → recording{name}"] = (time.perf_counter() - t1,
                                                path.stat().st_size / 1e6)
            path.unlink()
            if not hasattr(rerun_mod, "RerunWriter"):  # the whole-result writer it had
                t1 = time.perf_counter()
                rerun_mod.write_rrd(res, path, **kw)
                out[f"whole result in memory → recording{name}"] = (
                    time.perf_counter() - t1, path.stat().st_size / 1e6)
                path.unlink()
    out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps(out))


def _measure(tree: Path, args: argparse.Namespace) -> dict[str, Any]:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(tree),
           "--minutes", str(args.minutes)]
    cmd += ["--no-extra-events"] if args.no_extra_events else []
    cmd += ["--full-rate"] if args.full_rate else []
    p = subprocess.run(cmd, capture_output=True, text=True, check=True,
                       cwd=tempfile.gettempdir())
    return dict(json.loads(p.stdout.splitlines()[-1]))


def main() -> None:
    from machine import machine_line
    from release_tree import release_tree

    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--full-rate", action="store_true", help="also write without decimation")
    ap.add_argument("--no-extra-events", action="store_true",
                    help="only the fake's three events (no event per minute)")
    ap.add_argument("--release", default=None, help="also measure this git ref's code")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        sys.path.insert(0, args.child)
        child(args.minutes, not args.no_extra_events, args.full_rate)
        return
    codes = [("this", ROOT)]
    with release_tree(args.release) as release:
        if release is not None and args.release is not None:
            codes.append((args.release, release))
        got = [(name, _measure(tree, args)) for name, tree in codes]
    first = got[0][1]
    print(machine_line())
    print(f"series: {first['samples']:,} samples × 2 joints, {first['events']} events, chunks "
          f"of {CHUNK_ROWS:,}; build {first['build_s']:.2f} s, import rerun, pyarrow, pandas "
          f"{first['import_rerun_s']:.2f} s")
    print("| code | writer | s | MB | peak RSS MB |")
    print("|---|---|---|---|---|")
    for name, out in got:
        for k, v in out.items():
            if "→" in k:
                print(f"| {name} | {k} | {v[0]:.2f} | {v[1]:.1f} | {out['peak_rss_mb']:.0f} |")


if __name__ == "__main__":
    main()
