"""The product on real robot logs made by others (``../shared/real_logs`` when present).

    python tests/benchmarks/real_logs.py

Data (public sources; none of it carries contact labels):
- KUKA LWR4+, 7 joints, 200 Hz, 25 s of an identification excitation trajectory, measured
  joint torques — the FloBaRoID project's ``data/KUKA/HW/measurements_1.npz``; no contact
  was planned: every alarm on it is a false alarm.
- Universal Robots arm, 6 joints, 100 Hz, torque from motor currents — the ext_observer
  project's ``matlab/link4.csv`` (19.7 s of motion; the name suggests contacts on link 4)
  and ``ur-static.csv`` (45 s holding still while someone pushes the arm by hand).

For each log and each model kind and generator the tool offers without a controller
channel (these logs have none), as a user would run it: **calibrate on one part, detect
on another** — KUKA: calibrate on the first 60 %, detect on the last 40 % (collision-free:
events are false alarms); UR: calibrate on the first 60 % of ``link4``, detect on its last
40 % and on ``ur-static`` (pushes by hand: events are expected, unlabelled). Printed per
row: the model's held-back fit error on the calibration part (RMS error / RMS torque, per
joint), and the product's events after warm-up (adaptive, static_loading), with the joints
left out of detection. Kinds that need what the machine lacks (``coupled`` before it
exists, ``urdf`` without the robots extra) are reported as not available.
"""

from __future__ import annotations

import os
import platform
import sys
import time
import warnings
from pathlib import Path

from impactcli.logs import read_log
from impactcli.run.calibration import calibrate
from impactcli.run.collect import detect_in_memory
from impactcli.types import RobotLog

REAL = Path(__file__).resolve().parents[3] / "shared" / "real_logs"
KINDS = ("decoupled", "coupled", "urdf")
GENERATORS = ("inverse_dynamics", "momentum_observer")
#: The calibration part of each log (fraction of its samples).
CAL_FRACTION = 0.6


def split(log: RobotLog, frac: float = CAL_FRACTION) -> tuple[RobotLog, RobotLog]:
    """The first ``frac`` of the samples and the rest."""
    k = int(frac * log.n_samples)
    return log.slice(0, k), log.slice(k, log.n_samples)


def _robot(kind: str, which: str) -> object | None:
    """A robot description for ``urdf`` (a shipped robot), else None."""
    if kind != "urdf":
        return None
    name = {"ur": "ur5", "kuka": None}[which]
    if name is None:
        raise LookupError("no shipped URDF of the KUKA LWR4")
    from impactcli.logs.robot_files import robot_from_dict

    # the log names the UR joints shoulder_pan ... wrist_3; the URDF's are <name>_joint
    ur = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
    return robot_from_dict({"name": "ur (ur5 URDF)", "kinematics": {"type": "urdf",
                                                                     "robot": name},
                            "joint_map": {j: f"{j}_joint" for j in ur}}, "ur5 robot file")


def run_case(which: str, kind: str, generator: str, cal: RobotLog,
             tests: dict[str, RobotLog]) -> str:
    """One table row: fit on the calibration part, events on each test part."""
    import dataclasses

    from impactcli.config import DetectorConfig
    from impactcli.model import IdentifyOptions, identify

    try:
        robot = _robot(kind, which)
        model = identify(cal, robot=robot, kind=kind,  # type: ignore[arg-type]
                         options=IdentifyOptions(allow_still_joints=True))
    except Exception as err:
        return f"| {which} | {kind} | {generator} | not available: {str(err)[:80]} | | |"
    base = DetectorConfig()
    base = dataclasses.replace(base, residual=dataclasses.replace(base.residual,
                                                                  generator=generator))
    cfg = calibrate([cal], model=model, config=base, robot=robot)  # type: ignore[arg-type]
    hold = ((model.fit or {}).get("joints") or {}).get("holdout") or {}
    fit = ", ".join(f"{j} {100 * v['rms_rel_torque_rms']:.0f} %"
                    for j, v in hold.items() if v.get("rms_rel_torque_rms") is not None)
    cells = []
    for name, log in tests.items():
        res, _ = detect_in_memory(log, config=cfg, robot=robot)  # type: ignore[arg-type]
        s = res.summary()
        left = ", ".join(d["name"] for d in res.joints_left_out) or "none"
        cells.append(f"{name}: adaptive {s['adaptive']['events']}, static_loading "
                     f"{s['static_loading']['events']} (left out: {left})")
    return f"| {which} | {kind} | {generator} | {fit or '—'} | " + " | ".join(cells) + " |"


def main() -> int:
    if not REAL.is_dir():
        print(f"{REAL} is absent: nothing to measure")
        return 0
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    kuka = read_log(REAL / "kuka_lwr4" / "measurements_1.npz", channel_map="kuka_lwr4")
    link4 = read_log(REAL / "ur_ext_observer" / "link4.csv", channel_map="ur_ext_observer")
    static = read_log(REAL / "ur_ext_observer" / "ur-static.csv",
                      channel_map="ur_ext_observer")
    k_cal, k_test = split(kuka)
    u_cal, u_test = split(link4)
    cases = {
        "kuka": (k_cal, {"last 40 % (no contact)": k_test}),
        "ur": (u_cal, {"link4 last 40 %": u_test, "ur-static (pushed by hand)": static}),
    }
    print("| log | model | generator | held-back fit error (calibration part) | "
          "events after warm-up, test parts | |")
    print("|---|---|---|---|---|---|")
    for which, (cal, tests) in cases.items():
        for kind in KINDS:
            for gen in GENERATORS:
                print(run_case(which, kind, gen, cal, tests))
    print(f"\nmachine: {platform.platform()}, {os.cpu_count()} CPUs; python "
          f"{sys.version.split()[0]}; total {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
