"""Benchmark: the threshold sweep of ``impactcli evaluate --sweep`` on a long synthetic run.

Run: ``python tests/benchmarks/bench_evaluate_sweep.py [minutes]`` (default 60 minutes of
log at 250 Hz, 6 joints, 100 contacts, the CLI's default scales 0.2:5:x1.05).
"""

from __future__ import annotations

import os
import platform
import sys
import time

import numpy as np
from scipy.signal import lfilter

from impactcli.cli.evaluate import DEFAULT_SCALES, parse_scales
from impactcli.evaluate import at_zero_false_alarms, sweep_ratios, verdict
from impactcli.types import ContactLabel, Labels


def main(minutes: float = 60.0) -> None:
    fs, J = 250.0, 6
    n = int(minutes * 60 * fs)
    rng = np.random.default_rng(0)
    t = np.arange(n) / fs
    # ratio-like noise: |AR(1)| with a floor near 0.4, max around 1–1.5
    ratios = {}
    for d in ("adaptive", "static_loading", "static_baseline"):
        e = rng.standard_normal((n, J))
        a = 0.9 if d != "static_baseline" else 0.0
        x = lfilter([1.0], [1.0, -a], e, axis=0)
        ratios[d] = 0.25 * np.abs(x) / np.sqrt(1 / (1 - a * a))
    contacts = []
    for i, c0 in enumerate(np.linspace(30.0, t[-1] - 30.0, 100)):
        force = 1.0 + 0.2 * i
        m = (t >= c0) & (t <= c0 + 0.2)
        for r in ratios.values():
            r[m, i % J] += 0.05 * force
        contacts.append(ContactLabel(float(c0), float(c0 + 0.2), force, "impact", 1 + i % J))
    labels = Labels(tuple(contacts), fs)
    scales = parse_scales(DEFAULT_SCALES)
    t0 = time.perf_counter()
    rows = sweep_ratios(ratios, t, labels=labels,
                        scales=scales, warmup_end_s=5.0, merge_gap_s=0.1, min_duration_s=0.0)
    dt = time.perf_counter() - t0
    zero = at_zero_false_alarms(rows)
    print(f"machine: {platform.platform()}, {platform.processor() or platform.machine()}, "
          f"cpu_count={os.cpu_count()}, python {platform.python_version()}")
    print(f"{'log':>10} {'samples':>10} {'joints':>6} {'scales':>6} {'rows':>5} "
          f"{'max events':>10} {'sweep s':>8}")
    print(f"{minutes:>8.0f} m {n:>10} {J:>6} {len(scales):>6} {len(rows):>5} "
          f"{max(r.n_events for r in rows):>10} {dt:>8.2f}")
    for d, r in zero.items():
        where = "never" if r is None else f"scale {r.scale:g}, {r.detected}/{r.n_contacts}"
        print(f"  {d}: {where}")
    print(" ", verdict(zero))


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 60.0)
