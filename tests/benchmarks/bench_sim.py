"""Benchmark: simulate a long 1 kHz 2-joint log (assist_like at Ts = 1 ms).

Run: ``python tests/benchmarks/bench_sim.py [MINUTES]`` (default 120 = the 2-hour target).
Prints a small table with the machine, the duration simulated, RK4 substeps, wall time and
the real-time factor. The first call's numba compilation (or cache load) is timed apart.
"""

from __future__ import annotations

import os
import platform
import sys
import time
from dataclasses import replace

from impactcli.sim import scenario, simulate
from impactcli.sim.arm import assist_like


def main() -> None:
    minutes = float(sys.argv[1]) if len(sys.argv) > 1 else 120.0
    arm = replace(assist_like(), sample_period_s=0.001)
    t0 = time.perf_counter()
    simulate(scenario("free_fm_triangle", arm, 1.0), seed=0)
    warm = time.perf_counter() - t0
    sc = scenario("free_fm_triangle", arm, minutes * 60.0)
    t0 = time.perf_counter()
    res = simulate(sc, seed=0)
    wall = time.perf_counter() - t0
    n = res.log.n_samples
    print(f"machine      {platform.machine()} {platform.processor() or ''} "
          f"{platform.python_implementation()} {platform.python_version()}, "
          f"cpu_count={os.cpu_count()}")
    print(f"first call   {warm:.2f} s (numba compile or cache load)")
    print("| log | samples | substeps/sample | wall [s] | real-time factor | us/sample |")
    print("|---|---|---|---|---|---|")
    print(f"| {minutes:g} min, 2 joints, 1 kHz | {n} | {res.substeps} | {wall:.1f} | "
          f"{minutes * 60 / wall:.0f}x | {wall / n * 1e6:.2f} |")


if __name__ == "__main__":
    main()
