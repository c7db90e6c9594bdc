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
40 % and on ``ur-static`` (pushes by hand: events are expected, unlabelled). Each
calibration twice: **before**, the leave-one-out rule (``calibrate``'s default), and
**after**, a false-alarm rate of 1 per hour (``--false-alarms-per-hour 1``, the audit's).
Printed per row: the model's held-back fit error on the calibration part (RMS error / RMS
torque, per joint), and per test part and rule the product's incidents after warm-up,
their rate per hour of log after warm-up, and the rate the config states with its bound.
Kinds that need what the machine lacks (``urdf`` without the robots extra) are reported as
not available.

No real log here carries contact labels: the contacts caught are measured on every
labelled log the repository has, the simulated sample contact logs, calibrated on their
arm's free sample logs by each rule (``--labelled``; also run by default).
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from pathlib import Path

from impactcli.logs import read_log
from impactcli.run.calibration import MARGIN_RULE, RATE_RULE, calibrate
from impactcli.run.collect import detect_in_memory
from impactcli.types import DetectionResult, RobotLog

REPO = Path(__file__).resolve().parents[2]
#: ``../shared/real_logs`` beside the checkout (or beside a folder of worktrees above it).
#: the real recordings: IMPACTCLI_REAL_LOGS, else shared/real_logs beside the repository
#: (or beside a folder above it: a worktree)
REAL = Path(os.environ.get("IMPACTCLI_REAL_LOGS") or next(
    (p / "shared" / "real_logs" for p in REPO.parents if (p / "shared" / "real_logs").is_dir()),
    REPO.parent / "shared" / "real_logs"))
RULES = (("before", MARGIN_RULE), ("after", RATE_RULE))
KINDS = ("decoupled", "coupled", "urdf")
GENERATORS = ("inverse_dynamics", "momentum_observer")
#: The calibration part of each log (fraction of its samples).
CAL_FRACTION = 0.6


def split(log: RobotLog, frac: float = CAL_FRACTION) -> tuple[RobotLog, RobotLog]:
    """The first ``frac`` of the samples and the rest."""
    k = int(frac * log.n_samples)
    return log.slice(0, k), log.slice(k, log.n_samples)


def dev_cases(real: Path) -> dict[str, tuple[RobotLog, dict[str, RobotLog]]]:
    """The real development logs below ``real``, arm → (calibration part, test parts): the
    KUKA LWR4+ and UR link4 logs split at :data:`CAL_FRACTION`, and the UR pushed by hand."""
    kuka = read_log(real / "kuka_lwr4" / "measurements_1.npz", channel_map="kuka_lwr4")
    link4 = read_log(real / "ur_ext_observer" / "link4.csv", channel_map="ur_ext_observer")
    static = read_log(real / "ur_ext_observer" / "ur-static.csv",
                      channel_map="ur_ext_observer")
    k_cal, k_test = split(kuka)
    u_cal, u_test = split(link4)
    return {
        "kuka": (k_cal, {"last 40 % (no contact)": k_test}),
        "ur": (u_cal, {"link4 last 40 %": u_test, "ur-static (pushed by hand)": static}),
    }


def _robot(kind: str, which: str) -> object | None:
    """A robot description for ``urdf`` (a shipped robot), else None."""
    if kind != "urdf":
        return None
    # the UR arm is a UR10e: held still, its controller's model torque is the gravity of
    # the UR10e's published table (tests/test_published_arms.py)
    name = {"ur": "ur10e", "kuka": None}[which]
    if name is None:
        raise LookupError("no shipped URDF of the KUKA LWR4")
    from impactcli.logs.robot_files import robot_from_dict

    # the log names the UR joints shoulder_pan ... wrist_3; the URDF's are <name>_joint
    ur = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
    return robot_from_dict({"name": f"ur ({name})", "kinematics": {"type": "urdf",
                                                                    "robot": name},
                            "joint_map": {j: f"{j}_joint" for j in ur}}, f"{name} robot file")


def incidents_per_hour(res: DetectionResult) -> tuple[int, float]:
    """Counted incidents (after warm-up) and their rate per hour of log after warm-up."""
    n = sum(1 for i in res.incidents if not i.in_warmup)
    hours = max(res.log.duration_s - res.warmup_end_s, 1e-9) / 3600.0
    return n, n / hours


def envelope_share(cfg: object, log: RobotLog, res: DetectionResult) -> float:
    """Share of ``log`` after warm-up outside the motion envelope ``cfg`` records."""
    from impactcli.detect.envelope import EnvelopeCheck, MotionEnvelope

    env = cfg.calibration.motion_envelope  # type: ignore[attr-defined]
    chk = EnvelopeCheck(MotionEnvelope.from_dict(env), log.sample_rate_hz, log.joint_names)
    chk.update_arrays(log.time_s, log.position, log.position_ref)
    return chk.finish(int(res.warmup_end_s * log.sample_rate_hz)).share


def run_case(which: str, kind: str, generator: str, cal: RobotLog,
             tests: dict[str, RobotLog]) -> str:
    """One table row: fit on the calibration part, incidents on each test part, before
    (leave-one-out) and after (false-alarm rate, 1 per hour)."""
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
    hold = ((model.fit or {}).get("joints") or {}).get("holdout") or {}
    fit = ", ".join(f"{j} {100 * v['rms_rel_torque_rms']:.0f} %"
                    for j, v in hold.items() if v.get("rms_rel_torque_rms") is not None)
    cells = []
    for name, log in tests.items():
        parts = []
        for label, rule in RULES:
            cfg = calibrate([cal], model=model, config=base, robot=robot,  # type: ignore[arg-type]
                            threshold_rule=rule)
            res, _ = detect_in_memory(log, config=cfg, robot=robot)  # type: ignore[arg-type]
            n, per_h = incidents_per_hour(res)
            fa = cfg.calibration.false_alarm_rate
            stated = (f"; stated {fa['predicted_per_hour']:.2g}, bound "
                      f"{fa['upper_per_hour']:.2g}/h on {fa['free_minutes']:.2f} min, "
                      f"{100 * envelope_share(cfg, log, res):.0f} % of the part outside the "
                      "motion envelope" if fa else "")
            parts.append(f"{label}: {n} ({per_h:.3g}/h){stated}")
        cells.append(f"{name}: " + "; ".join(parts))
    return f"| {which} | {kind} | {generator} | {fit or '—'} | " + " | ".join(cells) + " |"


def labelled() -> None:
    """Contacts caught on every labelled log of the repository (the sample contact logs),
    by each rule, calibrated on their arm's three free sample logs."""
    sys.path.insert(0, str(REPO))
    from impactcli.quality.match import PRODUCT
    from tests import sample_criteria as sq

    print("\n| arm | rule | " + " | ".join(
        f"{n}: caught / contacts, false alarms" for n in ("impacts", "pushes", "clamps"))
          + " |")
    print("|---|---|---|---|---|")
    for arm, names in (("assist_like", ("assist_impacts", "assist_pushes", "assist_clamps")),
                       ("heavy_geared", ("heavy_impacts",))):
        free = sq.CALIBRATION_LOGS[arm]
        logs = [sq.read(n) for n in free]
        for label, rule in RULES:
            cfg = calibrate(logs, robot=sq.robot_of(free[0]), threshold_rule=rule)
            cells = []
            for n in names:
                s = sq.run(n, cfg)[1].scores[PRODUCT]
                cells.append(f"{s.detected}/{s.n_contacts}, {s.false_alarms}")
            print(f"| {arm} | {label} | " + " | ".join(cells) + " |" * (4 - len(cells)))


def main() -> int:
    from machine import machine_line

    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    if "--labelled" in sys.argv[1:] or not REAL.is_dir():
        if not REAL.is_dir():
            print(f"{REAL} is absent: the labelled sample logs only")
        labelled()
        return 0
    cases = dev_cases(REAL)
    print("| log | model | generator | held-back fit error (calibration part) | "
          "incidents after warm-up (per hour), before / after, test parts | |")
    print("|---|---|---|---|---|---|")
    for which, (cal, tests) in cases.items():
        for kind in KINDS:
            for gen in GENERATORS:
                print(run_case(which, kind, gen, cal, tests))
    labelled()
    print("\n" + machine_line(t0))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
