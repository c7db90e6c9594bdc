"""Payloads on the simulator's arms, measured (docs/models.md, "Measured: payloads").

    python tests/benchmarks/payloads.py            # every arm
    python tests/benchmarks/payloads.py --arm assist_like

Per arm (ASSIST-like, 2 joints, 1.2 kg; heavy geared, 3 joints, 2 kg; robot seed 411, one
physical robot per arm, none of the sample logs'), free runs of 60 s of the smooth motion
families (point-to-point, multi-sine; :data:`FAMILIES`) without the controller's channels
(the tool's own model, ``inverse_dynamics``), and the nominal robot description (planar
kinematics):

- **Calibration** on two light runs and two heavy runs (one per family each), with one
  load for all (``payload_per_log=False``) and with a payload per log; and, for reference,
  on four light runs (one load, as a calibration whose logs all carry the same load).
- **Held-out RMS error** [N·m] per joint of each model on a fresh light run and a fresh
  heavy run (the per-log model carrying the heavy calibration log's load on the heavy
  one), with its standard error over five stretches of the run.
- **Detection** with each config on fresh runs: pushes (5–40 N on both links) carrying no
  load and carrying the heavy load (the load weighed at the log's start), and a
  pick-and-place (a load picked at 20 s and released at 40 s, pushes of 20–30 N before,
  while carrying and after): labelled contacts caught by a counted incident, counted
  incidents matching no contact (false), and the payload changes found.

And a spatial arm, ``ur10e`` (the tool's URDF built from Universal Robots' published
table; ``--arm ur10e``): the same tables from motor-side torques that Pinocchio's inverse
dynamics gives, with Coulomb and viscous friction and noise (tests/robot_logs.py,
``carrying_log``): multi-sine runs of 60 s about a bent-arm pose, a 5 kg load with its
centre of mass 10 cm out along the flange's axis, pushes of 80 N at the flange (0.3 s
half-sines every 10 s) and a pick-and-place of the load at 20 s and 40 s.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from impactcli.model import IdentifyOptions, RigidModel
from impactcli.model.identification import prepare_rows
from impactcli.model.payload import carrying, log_payload
from impactcli.model.selection import stacked
from impactcli.run.calibration import calibrate_run
from impactcli.run.collect import detect_in_memory
from impactcli.sim import scenario, simulate
from impactcli.types import DetectionResult, Labels, LogSource, RobotLog

ROBOT_SEED = 411
KG = {"assist_like": 1.2, "heavy_geared": 2.0, "ur10e": 5.0}
#: The spatial arm's load: its centre of mass in the flange's frame [m].
SPATIAL_COM = (0.0, 0.0, 0.10)
#: The spatial arm's pushes [s] (0.3 s each, 80 N at the flange).
SPATIAL_PUSHES = (10.0, 30.0, 50.0)
#: The smooth motion families: with the triangles' velocity steps too, the heavy runs'
#: residual spikes at every reversal set thresholds 10-50x higher (vL 15 N·m on the
#: ASSIST-like shoulder, measured 2026-11-29), whatever the payload fit.
FAMILIES = ("free_p2p", "free_multisine")
MATCH = (0.02, 0.25)  # an incident starting within [start - 0.02, end + 0.25] s


def run(arm: str, name: str, seed: int, kg: float = 0.0) -> tuple[RobotLog, Labels, object]:
    """A simulated run of scenario ``name``, its labels and its nominal robot description."""
    if arm == "ur10e":
        return spatial_run(name, seed, kg)
    sc = scenario(name, arm=arm, duration_s=60.0, robot_seed=ROBOT_SEED, payload_kg=kg)
    res = simulate(sc, seed=seed)
    log = replace(res.log, source=LogSource(f"{name}-{seed}", f"{arm}-{name}-{seed}",
                                            "memory"))
    return log, res.labels, res.robot


def spatial_run(name: str, seed: int, kg: float) -> tuple[RobotLog, Labels, object]:
    """A run of the spatial arm (module docstring): free (``free_*``: carrying ``kg`` all
    along), ``pushes`` (carrying ``kg``) or ``pick_and_place`` (KG's load from 20 to 40 s),
    its labels and the robot description (the built ``ur10e``)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from impactcli.logs.robot_files import read_robot
    from impactcli.types import ContactLabel
    from tests.robot_logs import carrying_log

    pushes: tuple[float, ...] = ()
    load = (0.0, 1e9, kg, SPATIAL_COM) if kg else None
    if name == "pushes":
        pushes = SPATIAL_PUSHES
    elif name == "pick_and_place":
        pushes, load = SPATIAL_PUSHES, (20.0, 40.0, KG["ur10e"], SPATIAL_COM)
    log = carrying_log("ur10e", seed, 60.0, load=load,
                       pushes=tuple((t, t + 0.3, 80.0) for t in pushes))
    log = replace(log, source=LogSource(f"{name}-{seed}", f"ur10e-{name}-{seed}", "memory"))
    labels = Labels(tuple(ContactLabel(t, t + 0.3, 80.0, "push", 6) for t in pushes), 250.0)
    return log, labels, read_robot("ur10e")


def caught(res: DetectionResult, labels: Labels) -> tuple[int, int, int]:
    """(labelled contacts after warm-up matched by a counted incident, how many, counted
    incidents matching no contact)."""
    counted = res.counted_incidents()
    lab = [e for e in labels.events if e.start >= res.warmup_end_s]
    hit = sum(any(e.start - MATCH[0] <= i.t_start <= e.end + MATCH[1] for i in counted)
              for e in lab)
    false = sum(not any(e.start - MATCH[0] <= i.t_start <= e.end + MATCH[1] for e in lab)
                for i in counted)
    return hit, len(lab), false


def held_out(model: RigidModel, log: RobotLog, robot: object) -> tuple[np.ndarray, np.ndarray]:
    """(J,) RMS error [N·m] on the log's identification rows and its standard error over 5
    stretches."""
    rows = prepare_rows(log, robot, model.kind, IdentifyOptions())  # type: ignore[arg-type]
    y, tau, _ = stacked([rows])
    e = y @ model.theta - tau
    parts = np.array_split(np.arange(e.shape[0]), 5)
    rms = np.array([np.sqrt(np.mean(e[p] ** 2, axis=0)) for p in parts])
    return np.sqrt(np.mean(e**2, axis=0)), rms.std(axis=0, ddof=1) / np.sqrt(len(parts))


def arm_table(arm: str) -> None:
    kg = KG[arm]
    _, _, robot = run(arm, "free_multisine", 0)
    light = [run(arm, f, 1 + k)[0] for k, f in enumerate(FAMILIES)]
    heavy = [run(arm, f, 11 + k, kg)[0] for k, f in enumerate(FAMILIES)]
    light2 = [run(arm, f, 21 + k)[0] for k, f in enumerate(FAMILIES)]
    fresh_light, _, _ = run(arm, "free_multisine", 31)
    fresh_heavy, _, _ = run(arm, "free_multisine", 32, kg)
    t = time.perf_counter()
    cfgs = {
        "light + heavy, one load": calibrate_run([*light, *heavy], robot=robot,
                                                 payload_per_log=False).config,
        "light + heavy, a payload per log": calibrate_run([*light, *heavy],
                                                          robot=robot).config,
        "light + light (reference)": calibrate_run([*light, *light2], robot=robot).config,
    }
    print(f"\n### {arm} (payload {kg:g} kg; calibrations {time.perf_counter() - t:.0f} s)\n")
    joints = tuple(light[0].joint_names)
    print("Held-out RMS error [N·m] ± its standard error over 5 stretches, per joint ("
          + ", ".join(joints) + "):\n")
    print("| calibration | fresh light run | fresh heavy run |")
    print("|---|---|---|")
    for name, cfg in cfgs.items():
        model = RigidModel.from_dict(cfg.model)  # type: ignore[arg-type]
        pi = log_payload(model, heavy[-1].source.path)  # a heavy multi-sine's load
        cells = []
        for log, m in ((fresh_light, model),
                       (fresh_heavy, model if pi is None else carrying(model, pi))):
            rms, se = held_out(m, log, robot)
            cells.append(" / ".join(f"{r:.3g} ± {s:.1g}" for r, s in zip(rms, se, strict=True)))
        print(f"| {name} | {cells[0]} | {cells[1]} |")
    cases = {
        "pushes, no load": run(arm, "pushes", 11),
        f"pushes carrying {kg:g} kg": run(arm, "pushes", 12, kg),
        "pick-and-place": run(arm, "pick_and_place", 13),
    }
    print("\nDetection: labelled contacts caught / after warm-up, counted incidents matching "
          "no contact (false), payload changes found:\n")
    print("| calibration | " + " | ".join(cases) + " |")
    print("|---|" + "---|" * len(cases))
    for name, cfg in cfgs.items():
        cells = []
        for log, labels, _ in cases.values():
            res, _ = detect_in_memory(log, config=cfg)
            k, n, false = caught(res, labels)
            ch = res.payload_changes or ()
            load = res.payload or {}
            start = (f", start {load['mass_kg']:+.2g} kg" if load.get("verdict") == "used"
                     else "")
            changes = (", changes " + " ".join(f"{c['mass_kg']:+.2g} kg@{c['t_start']:.1f}s"
                                               for c in ch)) if ch else ""
            cells.append(f"{k}/{n}, {false} false{start}{changes}")
        print(f"| {name} | " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arm", choices=sorted(KG), action="append")
    args = ap.parse_args()
    import warnings

    warnings.simplefilter("ignore")
    for arm in args.arm or sorted(KG):
        arm_table(arm)


if __name__ == "__main__":
    main()
