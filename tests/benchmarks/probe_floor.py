"""The measured detection floor against blows on the simulated arm (docs/method.md, "The
floor measured").

    python tests/benchmarks/probe_floor.py

Per arm (ASSIST-like, 2 joints; heavy geared, 3 joints) and robot (:data:`ROBOT_SEEDS`):
a config calibrated on two collision-free multi-sine runs (60 s, no controller channels),
then a third multi-sine run (:data:`SEED`, no contact) whose ``detect`` states the floor —
the lower bound and the measured one (``detection_floor.probed``) per link: the adaptive
detector's alone, and either product detector's. Then, per link and per figure, the same
run with 100 ms half-sine pushes at the end of that link every :data:`EVERY_S` seconds
from 10 s (apart: the dynamic threshold rises after a blow, and a blow every 2.5 s on the
heavy arm's shoulder hid the next from the adaptive detector), perpendicular to the link
where it is when the push begins (the contact-free run's link-side angles), whose peak is
:data:`RATIOS` × that figure's median. Per ratio, the pushes caught: for the adaptive
figure, an adaptive event on the pushed link's own joint starting within [start − 0.02,
end + 0.25] s; for the product's, a counted incident starting there. A median says that
about half the blows of its size are caught; what the figures leave out (the pushed
link's force reaches the joints before it too; the arm's elasticity between the link and
the motor) shows as the rows' departures from that.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import replace
from typing import Any

import numpy as np

from impactcli.run.calibration import calibrate_run
from impactcli.run.collect import detect_in_memory
from impactcli.sim import scenario, simulate
from impactcli.sim.contacts import Push
from impactcli.types import LogSource

ARMS = ("assist_like", "heavy_geared")
ROBOT_SEEDS = (7, 9)
SEED = 3
DURATION_S = 60.0
EVERY_S = 5.0
RATIOS = (0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
MATCH = (0.02, 0.25)


def run(arm: str, rs: int, seed: int, pushes: tuple[Push, ...] = ()) -> Any:
    sc = scenario("free_multisine", arm=arm, duration_s=DURATION_S, robot_seed=rs,
                  controller_channels=False)
    res = simulate(replace(sc, pushes=pushes), seed=seed)
    name = f"{arm}-{rs}-{seed}-{len(pushes)}"
    return res, replace(res.log, source=LogSource(name, name, "memory"))


def main() -> None:
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    print("| arm | robot | link | lower bound (median) | probed median, worst tenth | "
          + " | ".join(f"{r:g}× caught" for r in RATIOS) + " |")
    print("|---|---|---|---|---|" + "---|" * len(RATIOS))
    totals = {w: {r: [0, 0] for r in RATIOS} for w in ("adaptive", "product")}
    for arm in ARMS:
        for rs in ROBOT_SEEDS:
            logs = [run(arm, rs, s)[1] for s in (1, 2)]
            cfg = calibrate_run(logs, robot=run(arm, rs, 1)[0].robot).config
            free, log = run(arm, rs, SEED)
            out, _ = detect_in_memory(log, config=cfg)
            floor = out.detection_floor or {}
            probed = floor.get("probed") or {}
            links = {row["link"]: row for row in probed.get("per_link") or []}
            bound = {row["link"]: row.get("adaptive", {}).get("median_n")
                     for row in floor.get("per_link") or []}
            n = len(out.log.joint_names)
            ang = np.cumsum(free.truth["x2"], axis=1)  # each link's absolute angle
            tt = free.truth["time_s"]
            times = np.arange(10.0, DURATION_S - 3.0, EVERY_S)
            rows: dict[int, dict[str, list[str]]] = {
                i: {"adaptive": [], "product": []} for i in range(1, n + 1)}
            for link in range(1, n + 1):
                joint = out.log.joint_names[link - 1]
                row = links.get(link, {})
                for which, med in (("adaptive", row.get("adaptive", {}).get("median_n")),
                                   ("product", row.get("median_n"))):
                    for ratio in RATIOS:
                        if med is None:
                            rows[link][which].append("-")
                            continue
                        pushes = tuple(
                            Push(link, float(t), ratio * med, duration_s=0.1, point=1.0,
                                 direction_deg=math.degrees(float(
                                     ang[int(np.searchsorted(tt, t)), link - 1])) + 90.0)
                            for t in times)
                        _, plog = run(arm, rs, SEED, pushes)
                        got, _ = detect_in_memory(plog, config=cfg)
                        caught = 0
                        for push in pushes:
                            lo = push.t0_s - MATCH[0]
                            hi = push.t0_s + push.duration_s + MATCH[1]
                            caught += (any(e.detector == "adaptive" and joint in e.joints
                                           and lo <= e.t_start <= hi for e in got.events)
                                       if which == "adaptive" else
                                       any(lo <= i.t_start <= hi
                                           for i in got.counted_incidents()))
                        rows[link][which].append(f"{caught}/{len(pushes)}")
                        totals[which][ratio][0] += len(pushes)
                        totals[which][ratio][1] += caught
            for i in range(1, n + 1):
                row = links.get(i, {})
                b = bound.get(i)
                for which, fig in (("adaptive", row.get("adaptive", {})), ("product", row)):
                    lower = "-" if b is None or which == "product" else f"{b:.3g} N"
                    print(f"| {arm} | {rs} | {i} {which} | {lower} | "
                          f"{_n(fig.get('median_n'))}, {_n(fig.get('worst_tenth_n'))} | "
                          + " | ".join(rows[i][which]) + " |")
    for which, tot in totals.items():
        print(f"| all | | {which} | | | " + " | ".join(
            f"{100 * c / max(m, 1):.0f} % of {m}" for m, c in tot.values()) + " |")
    print(f"\n{time.perf_counter() - t0:.0f} s")


def _n(x: float | None) -> str:
    return "-" if x is None else f"{x:.3g} N"


if __name__ == "__main__":
    main()
