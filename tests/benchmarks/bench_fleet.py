"""Fleet benchmark: ``impactcli detect`` over a batch of simulated logs, three ways.

    python tests/benchmarks/bench_fleet.py [--logs 120] [--duration 360] [--workers 2]

Simulates ``--logs`` logs (assist_like arm, 250 Hz, scenarios in turn, seeds 0..n-1;
default 120 × 6 min = 12 h of robot time) as ``.csv.gz`` into a temporary folder (cached
in ``/tmp/impactcli-bench-fleet`` between runs), identifies a model once, then runs the
detect command (the real CLI path: expansion, jobs, atomic writes, summary) serially, with
``--jobs W`` and on a Dask LocalCluster (``--scheduler local --jobs W``; cluster start-up
included), checks that the three give byte-identical timelines, and prints logs/s and hours
of log per second for each. Needs the dask extra for the last row.
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

SCENARIOS = ("free_triangle", "free_fm_triangle", "free_p2p", "free_multisine", "pushes",
             "impacts")


def make_logs(folder: Path, n: int, duration_s: float) -> list[Path]:
    """Simulate ``n`` logs into ``folder`` (kept when already there)."""
    from impactcli.logs import write_log
    from impactcli.sim import scenario, simulate

    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for k in range(n):
        name = SCENARIOS[k % len(SCENARIOS)]
        p = folder / f"{name}_{k:04d}.csv.gz"
        if not p.exists():
            res = simulate(scenario(name, arm="assist_like", duration_s=duration_s), seed=k)
            write_log(res.log, p)
        paths.append(p)
    return paths


def run(args: list[str]) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "impactcli", *args], capture_output=True,
                          text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"failed ({proc.returncode}): {' '.join(args)}\n{proc.stderr[-2000:]}")
    return wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", type=int, default=120)
    ap.add_argument("--duration", type=float, default=360.0, help="seconds per log")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--root", type=Path, default=Path("/tmp/impactcli-bench-fleet"))
    a = ap.parse_args()
    logs_dir = a.root / f"logs-{a.logs}x{a.duration:g}s"
    t0 = time.perf_counter()
    logs = make_logs(logs_dir, a.logs, a.duration)
    print(f"simulated/cached {len(logs)} logs in {time.perf_counter() - t0:.1f} s")
    model = a.root / "model.json"
    if not model.exists():
        run(["identify", str(logs[0]), "-o", str(model)])
    pattern = str(logs_dir / "*.csv.gz")
    rows = []
    outs = {}
    for label, extra in [("serial", []), (f"--jobs {a.workers}", ["--jobs", str(a.workers)]),
                         (f"LocalCluster x{a.workers}",
                          ["--scheduler", "local", "--jobs", str(a.workers)])]:
        out = a.root / ("out-" + label.replace(" ", "_").replace("-", ""))
        shutil.rmtree(out, ignore_errors=True)
        summary = a.root / f"{out.name}.summary.json"
        wall = run(["detect", pattern, "-o", str(out), "--model", str(model),
                    "--summary", str(summary), *extra])
        doc = json.loads(summary.read_text())
        assert doc["logs"]["failed"] == 0, doc["failures"]
        hours = doc["hours_analysed"]
        rows.append((label, doc["logs"]["done"], hours, wall, doc["wall_s"]))
        outs[label] = out
    ref = next(iter(outs.values()))
    names = sorted(p.name for p in ref.glob("*.timeline.json"))
    same = all(filecmp.cmpfiles(ref, o, names, shallow=False)[0] == names for o in outs.values())
    print(f"\nmachine: {platform.platform()}, {platform.processor() or platform.machine()}, "
          f"os.cpu_count()={os.cpu_count()}, Python {platform.python_version()}")
    print(f"batch: {rows[0][1]} logs, {rows[0][2]:.2f} h of robot time (250 Hz, 2 joints), "
          f"model given; identical timelines across the three: {same}")
    print(f"{'executor':<18} {'logs':>5} {'wall_s':>8} {'batch_s':>8} {'logs/s':>7} "
          f"{'log h/s':>8} {'x realtime':>10}")
    for label, n, hours, wall, batch_s in rows:
        print(f"{label:<18} {n:>5} {wall:>8.1f} {batch_s:>8.1f} {n / wall:>7.2f} "
              f"{hours / wall:>8.3f} {hours * 3600 / wall:>10.0f}")
    print("(wall_s: the whole command incl. interpreter and cluster start; batch_s: the "
          "batch itself, from --summary; rates use wall_s)")


if __name__ == "__main__":
    main()
