"""The model kind chosen by held-back error (impactcli/model/selection.py), measured.

    python tests/benchmarks/model_selection.py            # simulated arms + real logs
    python tests/benchmarks/model_selection.py --no-sim   # the real logs only

**Simulated arms** (ASSIST-like, 2 joints; heavy geared, 3 joints; robot seed 305, one
physical robot per arm, none of the sample logs' or the other benchmarks'): four free
runs of 40 s, one per motion family (triangle, frequency-modulated triangle,
point-to-point, multi-sine), without the controller's channels (the tool's own model:
``inverse_dynamics``). Printed per joint: each kind's held-back RMS error, leave-one-log-out
over the four families (``planar``: the exact model, from the nominal robot description);
the kind chosen with no kinematics given (a user without a robot file). Then calibrate as
a user without a robot file would, **before** (today's default: the decoupled model,
``identify_many``) and **after** (``select_model``: the call run/calibration.py is to make
when no model is given), with the current threshold rule, and replay fresh contact logs
(impacts, pushes on every link, clamps; labelled) and fresh free runs of every family
(another seed): labelled contacts >= 10 N caught, and incidents after warm-up on the free
runs (false alarms).

**Real logs** (``../shared/real_logs``, when present; no contact labels): KUKA LWR4+
(calibrate on the first 60 %, replay the last 40 %: every incident is a false alarm); UR
``link4`` (calibrate on its first 60 %; replay its last 40 % and ``ur-static``, where
someone pushes the arm by hand: incidents expected, not labelled). Before/after as above.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from dataclasses import replace
from pathlib import Path

from impactcli.config import DetectorConfig
from impactcli.model import IdentifyOptions, RigidModel, identify_many
from impactcli.model.selection import select_model
from impactcli.run.calibration import calibrate
from impactcli.run.collect import detect_in_memory
from impactcli.sim import scenario, simulate
from impactcli.types import DetectionResult, Labels, RobotLog

REAL = Path(os.environ.get("IMPACTCLI_REAL_LOGS",
                         Path(__file__).resolve().parents[3] / "shared" / "real_logs"))
FAMILIES = ("free_triangle", "free_fm_triangle", "free_p2p", "free_multisine")
OPTS = IdentifyOptions(allow_still_joints=True)
MIN_FORCE_N = 10.0
MATCH = (0.02, 0.25)  # an incident starting within [start - 0.02, end + 0.25] s
ROBOT_SEED = 305


def caught(res: DetectionResult, labels: Labels) -> tuple[int, int]:
    """(labelled contacts >= MIN_FORCE_N after warm-up with an incident, how many)."""
    n = k = 0
    for lab in labels.events:
        if lab.peak_force < MIN_FORCE_N or lab.start < res.warmup_end_s:
            continue
        n += 1
        k += any(lab.start - MATCH[0] <= i.t_start <= lab.end + MATCH[1]
                 for i in res.counted_incidents())
    return k, n


def incidents(res: DetectionResult) -> int:
    """Incidents counted after warm-up."""
    return len(res.counted_incidents())


def models(free: list[RobotLog]) -> dict[str, RigidModel]:
    """The model before (decoupled, today's default without a robot file) and after."""
    return {"before": identify_many(free, options=OPTS),
            "after": select_model(free, options=OPTS)}


def held_back_table(name: str, free: list[RobotLog], robot: object) -> None:
    """Held-back RMS error per kind and joint, leave-one-log-out over the families."""
    sel = select_model(free, robot=robot, options=OPTS).fit["selection"]  # type: ignore[arg-type]
    chosen = select_model(free, options=OPTS).fit["selection"]
    print(f"\n### {name}: held-back RMS error [N·m], {sel['held_back']}\n")
    print("| joint | decoupled | coupled (λ) | planar (exact) | chosen without kinematics |")
    print("|---|---|---|---|---|")
    for j, e in sel["joints"].items():
        c = chosen["joints"][j]
        lam = f"λ {c['lambda']:.0e}" if "lambda" in c else "cross terms off"
        print(f"| {j} | {e['decoupled']['rms_nm']:.3g} | {e['coupled']['rms_nm']:.3g} "
              f"({e['coupled']['lambda']:.0e}) | {e['planar']['rms_nm']:.3g} | "
              f"{c['chosen']} ({lam}) |")
    print(f"\nchosen: {chosen['reason']}")


def simulated(arm: str) -> None:
    def run(sc, seed):  # type: ignore[no-untyped-def]
        return simulate(replace(sc, robot_seed=ROBOT_SEED, controller_channels=False),
                        seed=seed)

    free = [run(scenario(f, arm, 40.0), 50 + k) for k, f in enumerate(FAMILIES)]
    held_back_table(arm, [s.log for s in free], free[0].robot)
    tests = {n: run(scenario(n, arm), 60 + k)
             for k, n in enumerate(("impacts", "pushes", "clamps"))}
    other = {f: run(scenario(f, arm, 60.0), 70 + k) for k, f in enumerate(FAMILIES)}
    base = DetectorConfig()
    print("\n| model | kind | " + " | ".join(f"{n}: caught" for n in tests)
          + " | free runs (4 × 60 s): incidents |")
    print("|---|---|" + "---|" * (len(tests) + 1))
    for when, model in models([s.log for s in free]).items():
        cfg = calibrate([s.log for s in free], model=model, config=base,
                        generator="inverse_dynamics")
        cells = []
        for sim in tests.values():
            res, _ = detect_in_memory(sim.log, config=cfg)
            k, n = caught(res, sim.labels)
            cells.append(f"{k}/{n}")
        fa = sum(incidents(detect_in_memory(s.log, config=cfg)[0]) for s in other.values())
        print(f"| {when} | {model.kind} | " + " | ".join(cells) + f" | {fa} |")


def real() -> None:
    from real_logs import dev_cases

    if not REAL.is_dir():
        print(f"\n{REAL} is absent: no real logs measured")
        return
    base = DetectorConfig()
    base = replace(base, residual=replace(base.residual, generator="inverse_dynamics"))
    names = {"kuka": "KUKA LWR4+", "ur": "UR"}
    for which, (cal, tests) in dev_cases(REAL).items():
        name = names[which]
        print(f"\n### {name}: calibrated on the first 60 %\n")
        print("| model | kind | " + " | ".join(f"{t}: incidents (adaptive / static_loading "
                                                 "events)" for t in tests) + " |")
        print("|---|---|" + "---|" * len(tests))
        for when, model in models([cal]).items():
            cfg = calibrate([cal], model=model, config=base)
            cells = []
            for log in tests.values():
                res, _ = detect_in_memory(log, config=cfg)
                s = res.summary()
                cells.append(f"{incidents(res)} ({s['adaptive']['events']} / "
                             f"{s['static_loading']['events']})")
            print(f"| {when} | {model.kind} | " + " | ".join(cells) + " |")
            if when == "after":
                print(f"\nchosen: {model.fit['selection']['reason']}")


def main() -> int:
    from machine import machine_line

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-sim", action="store_true", help="the real logs only")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    if not args.no_sim:
        for arm in ("assist_like", "heavy_geared"):
            simulated(arm)
    real()
    print("\n" + machine_line(t0))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
