"""Payloads on the controller's channel: a pick and a release with no contact, measured
(docs/models.md, "Payloads").

    python tests/benchmarks/payload_channels.py

Per robot of the ASSIST-like arm (:data:`ROBOT_SEEDS`, one physical robot each, its
controller's ``torque_ext`` logged as in the sample logs), a config calibrated by default
(generator ``auto`` → ``logged_external``, the controller's estimate corrected by the tool's
planar model) on three 60 s collision-free runs (triangle, point-to-point, multi-sine; no
load), then two 60 s pick-and-place runs with the scenario's pushes taken out (1 kg picked at
20 s, released at 40 s, nothing else). Every counted incident and lasting load there is
false; each payload change found is set against the labelled step (time, mass).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import replace

from impactcli.run.calibration import calibrate_run
from impactcli.run.collect import detect_in_memory
from impactcli.sim import scenario, simulate
from impactcli.types import LogSource

ROBOT_SEEDS = (101, 102, 103, 104, 105, 106)
FREE = ("free_triangle", "free_p2p", "free_multisine")
SEEDS = (21, 22)


def _log(sc: object, seed: int, name: str) -> tuple[object, object]:
    res = simulate(sc, seed=seed)  # type: ignore[arg-type]
    return replace(res.log, source=LogSource(name, name, "memory")), res


def main() -> None:
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    print("| robot | run | false incidents | lasting loads | changes found (labelled) |")
    print("|---|---|---|---|---|")
    tot = {"runs": 0, "false": 0, "lasting": 0, "found": 0, "steps": 0, "right": 0}
    for rs in ROBOT_SEEDS:
        logs, robot = [], None
        for k, name in enumerate(FREE):
            log, res = _log(scenario(name, duration_s=60.0, robot_seed=rs,
                                     controller_channels=True), 60 + k, f"{name}-{rs}")
            logs.append(log)
            robot = res.robot  # type: ignore[attr-defined]
        cfg = calibrate_run(logs, robot=robot).config
        for seed in SEEDS:
            sc = replace(scenario("pick_and_place", duration_s=60.0, robot_seed=rs,
                                  controller_channels=True), pushes=())
            log, res = _log(sc, seed, f"pnp-{rs}-{seed}")
            out, _ = detect_in_memory(log, config=cfg)
            # (time, mass change): the scenario lists the load from each step on
            loads = [float(getattr(sc, "payload_kg", 0.0) or 0.0),
                     *(kg for _, kg in sc.payload_changes)]
            steps = [(t, loads[k + 1] - loads[k]) for k, (t, _) in
                     enumerate(sc.payload_changes)]
            found = list(out.payload_changes or ())
            right = 0  # each labelled step matched once: the nearest change of its sign
            free = list(found)
            for t, dm in steps:
                near = [c for c in free if abs(c["t_start"] - t) <= 1.0
                        and (c["mass_kg"] > 0) == (dm > 0)]
                if near:
                    c = min(near, key=lambda x: abs(x["t_start"] - t))
                    free.remove(c)
                    right += abs(c["mass_kg"] - dm) <= 0.25 * abs(dm)
            n_false = len(out.counted_incidents())
            n_lasting = len(out.counted_lasting_loads())
            tot["runs"] += 1
            tot["false"] += n_false
            tot["lasting"] += n_lasting
            tot["found"] += len(found)
            tot["steps"] += len(steps)
            tot["right"] += right
            print(f"| {rs} | {seed} | {n_false} | {n_lasting} | "
                  + " ".join(f"{c['t_start']:.2f} s {c['mass_kg']:+.2f} kg" for c in found)
                  + " (" + " ".join(f"{t:g} s" for t, _ in steps) + ") |", flush=True)
    print(f"\n{tot['runs']} runs: {tot['false']} false incident(s), {tot['lasting']} lasting "
          f"load(s); {tot['found']} payload change(s) found for {tot['steps']} labelled, "
          f"{tot['right']} within 1 s and 25 % of the step; "
          f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
