"""Time and size of the Rerun recording of a long run: ``python tests/benchmarks/bench_rerun.py``.

A synthetic 2-joint DetectionResult at 1 kHz (1 hour = 3.6 M samples per series by
default; ``--minutes`` changes it) with the fake's three events plus one adaptive event
per minute, written with the default decimation (200 000 samples per series, ±2 s
full-rate windows) and, for comparison on shorter runs, at full rate.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from impactcli.outputs.rerun import write_rrd
from impactcli.types import Event
from tests.fakes import fake_result


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--full-rate", action="store_true", help="also write without decimation")
    ap.add_argument("--no-extra-events", action="store_true",
                    help="only the fake's three events (no event per minute)")
    args = ap.parse_args()
    n = int(args.minutes * 60_000)
    t0 = time.perf_counter()
    res = fake_result(n=n, dt=0.001)
    t = res.log.time_s
    extra = []
    for minute in range(1, 0 if args.no_extra_events else int(args.minutes)):
        i0 = int(np.searchsorted(t, minute * 60.0))
        extra.append(Event("adaptive", float(t[i0]), float(t[i0 + 80]), i0, i0 + 80, ("j1",),
                           1.7, {"j1": 2.0}, False))
    res = dataclasses.replace(res, events=tuple(sorted((*res.events, *extra),
                                                       key=lambda e: e.t_start)))
    build = time.perf_counter() - t0
    t0 = time.perf_counter()
    import rerun  # noqa: F401 - timed apart: write_rrd imports it lazily

    imp = time.perf_counter() - t0
    rows = [("machine", f"{platform.platform()} {platform.processor() or platform.machine()}, "
                        f"{os.cpu_count()} CPUs, Python {platform.python_version()}"),
            ("series length", f"{n:,} samples × 2 joints, {len(res.events)} events"),
            ("build fake result", f"{build:.2f} s"),
            ("import rerun (once per process)", f"{imp:.2f} s")]
    with tempfile.TemporaryDirectory() as tmp:
        variants = [("decimated (default)", {})]
        if args.full_rate:
            variants.append(("full rate", {"max_points": 10**12}))
        for name, kw in variants:
            path = Path(tmp) / "bench.rrd"
            t1 = time.perf_counter()
            write_rrd(res, path, **kw)  # type: ignore[arg-type]
            dt = time.perf_counter() - t1
            rows.append((f"write_rrd {name}", f"{dt:.2f} s, {path.stat().st_size / 1e6:.1f} MB"))
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    rows.append(("peak RSS (whole process)", f"{peak:.0f} MB"))
    w = max(len(a) for a, _ in rows)
    for a, b in rows:
        print(f"{a:<{w}}  {b}")


if __name__ == "__main__":
    main()
