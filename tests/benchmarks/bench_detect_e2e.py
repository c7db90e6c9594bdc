"""Benchmark: end-to-end ``impactcli detect`` on a long 2-joint 1 kHz canonical CSV.

Run: ``python tests/benchmarks/bench_detect_e2e.py [MINUTES] [--keep DIR]`` (default 120:
a 2-hour, ~1 GB CSV). The log is simulated (assist_like at Ts = 1 ms, the collision-free
free_multisine scenario), written as plain CSV, then ``impactcli detect`` runs in
a fresh subprocess exactly as a user runs it — no model, no config: the model is identified
from the log and the run is uncalibrated, the heaviest path. Reported: CSV size, wall time
of the command, real-time factor, peak resident memory of the command (ru_maxrss of the
child), and the machine. A second run with ``--signals`` shows the cost of the Parquet.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path


def _make_log(minutes: float, path: Path) -> float:
    from impactcli.logs import write_log
    from impactcli.sim import scenario, simulate
    from impactcli.sim.arm import assist_like

    arm = replace(assist_like(), sample_period_s=0.001)
    res = simulate(scenario("free_multisine", arm, minutes * 60.0), seed=7)
    write_log(res.log, path)
    return res.log.duration_s


def _run(args: list[str]) -> tuple[float, float]:
    """Wall time [s] and peak RSS [MB] of ``impactcli`` with ``args`` in a fresh process."""
    exe = Path(sys.executable).with_name("impactcli")
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    proc = subprocess.run([str(exe), *args], capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    if proc.returncode != 0:
        sys.exit(f"impactcli failed ({proc.returncode}):\n{proc.stderr}")
    return wall, max(peak, before) / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("minutes", nargs="?", type=float, default=120.0)
    ap.add_argument("--keep", type=Path, help="folder to keep the CSV in (default: a temp dir)")
    args = ap.parse_args()
    tmp = Path(args.keep or tempfile.mkdtemp(prefix="impactcli-bench-"))
    tmp.mkdir(parents=True, exist_ok=True)
    try:
        _bench(args.minutes, tmp)
    finally:
        if args.keep is None:  # the CSV alone is ~1 GB at 120 min
            shutil.rmtree(tmp, ignore_errors=True)


def _bench(minutes: float, tmp: Path) -> None:
    """Simulate (unless kept) and time ``detect`` twice on the log in ``tmp``."""
    args = argparse.Namespace(minutes=minutes)
    csv = tmp / f"bench_{args.minutes:g}min.csv"
    if not csv.exists():
        t0 = time.perf_counter()
        _make_log(args.minutes, csv)
        print(f"simulated and wrote {csv} in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    size_mb = csv.stat().st_size / 1e6
    _run(["detect", str(csv), "-o", str(tmp / "warm")]) if args.minutes <= 1 else None
    duration = args.minutes * 60.0
    rows = []
    for label, extra in (("timeline only", []), ("with --signals", ["--signals"])):
        wall, peak = _run(["detect", str(csv), "-o", str(tmp / "out"), *extra])
        rows.append((label, wall, duration / wall, peak))
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, {platform.system()} {platform.release()}")
    print(f"log: {args.minutes:g} min, 2 joints, 1 kHz canonical CSV, {size_mb:.0f} MB")
    print("| run | wall [s] | × real time | peak RSS [MB] |")
    print("|---|---|---|---|")
    for label, wall, rt, peak in rows:
        print(f"| {label} | {wall:.1f} | {rt:.0f}× | {peak:.0f} |")


if __name__ == "__main__":
    main()
