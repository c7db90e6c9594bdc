"""The sample configs' free logs at several false-alarm rates and confidences.

    python tests/benchmarks/sample_rate_scan.py [R:CONF ...]

For each arm, ``calibrate`` on its three free sample logs (the committed configs' logs,
1.0–1.3 min after warm-up) for each R [1/h] and confidence, then the product on the arm's
sample contact logs: contacts caught, false alarms between contacts, the rate the free
minutes support and the thresholds. What decided the sample configs' rule and the default
(docs/validation.md, "Why the default is the leave-one-out margin, its rate stated").
"""

from __future__ import annotations

import os
import platform
import sys
import time
import warnings
from datetime import date
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from impactcli.quality.match import PRODUCT
from impactcli.run.calibration import RATE_RULE, calibrate_run
from tests.benchmarks import sample_quality as sq

ARMS = {"assist_like": ("assist_impacts", "assist_pushes", "assist_clamps"),
        "heavy_geared": ("heavy_impacts",)}
GRID = ("1:0.9", "10:0.9", "30:0.9", "100:0.9", "1:0.5", "10:0.5")


def main(argv: list[str]) -> int:
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    grid = [(float(r), float(c)) for r, c in (x.split(":") for x in (argv or GRID))]
    print("| arm | R [1/h] | confidence | supported [1/h] | caught | false alarms | "
          "v_stat | vL |")
    print("|---|---|---|---|---|---|---|---|")
    for arm, contact_logs in ARMS.items():
        names = sq.CALIBRATION_LOGS[arm]
        logs = [sq.read(n) for n in names]
        for r, conf in grid:
            done = calibrate_run(logs, robot=sq.robot_of(names[0]), threshold_rule=RATE_RULE,
                                 false_alarms_per_hour=r, confidence=conf)
            assert done.rate is not None
            det = n = fa = 0
            for c in contact_logs:
                s = sq.run(c, done.config)[1].scores[PRODUCT]
                det, n, fa = det + s.detected, n + s.n_contacts, fa + s.false_alarms
            tab = done.rate.table()
            cells = [", ".join(f"{j} {v:.3g}" for j, v in tab[d].items())
                     for d in ("adaptive", "static_loading")]
            print(f"| {arm} | {r:g} | {conf:g} | {done.rate.rate_supported:.2f} | {det}/{n} | "
                  f"{fa} | {cells[0]} | {cells[1]} |")
    print(f"\nmachine: {platform.platform()}, {os.cpu_count()} CPUs; python "
          f"{sys.version.split()[0]}; {date.today().isoformat()}; total "
          f"{time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
