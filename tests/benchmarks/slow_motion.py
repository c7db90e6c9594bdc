"""Slow motion against the calibration's motion envelope, measured (docs/validation.md,
"Slow motion").

    python tests/benchmarks/slow_motion.py [--out DIR] [--runs 6] [--arm heavy_geared]

What it asks: the sample contact logs (pushes, clamps) move slowly — a multi-sine of
0.03–0.15 Hz, where the free logs a user calibrates on cross zero velocity in a fraction
of a second. Does the false-alarm rate a config states hold there, and does ``detect`` say
when it may not?

Per arm (the sample logs' robots: ASSIST-like, robot seed 100; heavy geared, 200), free
runs of that slow motion (the ``clamps`` scenario without its clamps; ``--runs`` of 120 s,
seeds 500… and 600…; every incident after warm-up is a false alarm), against configs
``calibrate`` makes with its default rule (leave-one-out, its rate stated) on the arm's
shipped free logs (triangle, point-to-point, multi-sine: all three and each pair) and on
pairs of other free runs of the same robot (:data:`POOL`, the calibration pool of
``tests/benchmarks/false_alarm_rate.py``, simulated by the same command). Printed
per config: the rate it states (predicted / 90 % bound), the false alarms and their rate,
and the share of time outside the motion envelope and the false alarms touching it — with
the envelope as ``detect`` checks it (ranges and slow stretches) and with its ranges
alone (what the envelope was before it recorded slow stretches). The product's own
answer: each run through ``impactcli detect`` (its timeline's incidents).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import platform
import subprocess
import sys
import time
import warnings
from dataclasses import replace
from datetime import date
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CLI = str(Path(sys.executable).with_name("impactcli"))
ARMS = {"assist_like": ("assist", 500), "heavy_geared": ("heavy", 600)}
FREE = ("triangle", "p2p", "multisine")
#: Other free runs of each robot: name → (scenario, seed, duration [s]); and the pairs
#: calibrated on.
POOL = {"tri_s1010_60": ("free_triangle", 1010, 60), "p2p_s1011_90": ("free_p2p", 1011, 90),
        "ms_s1012_120": ("free_multisine", 1012, 120)}
PAIRS = (("ms_s1012_120", "tri_s1010_60"), ("p2p_s1011_90", "ms_s1012_120"),
         ("tri_s1010_60", "p2p_s1011_90"))
ROBOT_SEED = {"assist_like": 100, "heavy_geared": 200}


def pool_run(out: Path, arm: str, name: str) -> Path:
    """The free run ``name`` of :data:`POOL` (simulated when absent)."""
    scen, seed, dur = POOL[name]
    path = out / arm / "pool" / f"{name}.csv.gz"
    if not path.exists():
        subprocess.run([CLI, "simulate", "--arm", arm, "--scenario", scen, "--duration",
                        str(dur), "--seed", str(seed), "--robot-seed", str(ROBOT_SEED[arm]),
                        "-o", str(path.parent), "--name", name], check=True,
                       capture_output=True)
    return path


def slow_runs(out: Path, arm: str, n: int) -> list[Path]:
    """``n`` free runs of the sample contact logs' slow motion on the arm's sample robot
    (made when absent)."""
    from impactcli.logs import write_log
    from impactcli.sim import scenario, simulate
    from impactcli.sim.sample_logs import CONTROLLER_CHANNEL_ARMS, ROBOT_SEEDS

    paths = []
    for k in range(n):
        seed = ARMS[arm][1] + k
        path = out / arm / f"slow_{seed}.csv.gz"
        if not path.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
            sc = replace(scenario("clamps", arm, 120.0, robot_seed=ROBOT_SEEDS[arm],
                                  controller_channels=arm in CONTROLLER_CHANNEL_ARMS),
                         clamps=(), name="slow_free")
            write_log(simulate(sc, seed=seed).log, path)
        paths.append(path)
    return paths


def judge(config: Path, runs: list[Path], out: Path) -> dict[str, float]:
    """``detect`` on the runs with ``config``; false alarms and the envelope, full and
    ranges alone."""
    from impactcli.config import load_config
    from impactcli.detect.envelope import EnvelopeCheck, MotionEnvelope
    from impactcli.logs import read_log

    subprocess.run([CLI, "detect", *map(str, runs), "--config", str(config), "-o",
                    str(out)], check=True, capture_output=True)
    rec = load_config(config).calibration
    assert rec.motion_envelope is not None and rec.false_alarm_rate is not None
    env = MotionEnvelope.from_dict(rec.motion_envelope)
    plain = MotionEnvelope(env.joints, env.source, env.samples, env.cutoff_hz)
    tot = {"hours": 0.0, "false": 0, "touch": 0, "touch_ranges": 0, "outside": 0,
           "outside_ranges": 0, "samples": 0,
           "predicted": float(rec.false_alarm_rate["predicted_per_hour"]),
           "upper": float(rec.false_alarm_rate["upper_per_hour"])}
    for run in runs:
        log = read_log(run)
        tl = json.loads((out / f"{run.name.split('.')[0]}.timeline.json").read_text())
        start = round(float(tl["warmup_end_s"]) * log.sample_rate_hz)
        shares = []
        for e in (env, plain):
            chk = EnvelopeCheck(e, log.sample_rate_hz, log.joint_names)
            chk.update_arrays(log.time_s, log.position, log.position_ref)
            shares.append(chk.finish(start))
        full, ranges = shares
        assert full.outside == tl["motion_envelope"]["outside"]  # detect's own check
        inc = [i for i in tl["incidents"] if not i["in_warmup"]]
        tot["hours"] += full.samples / log.sample_rate_hz / 3600.0
        tot["false"] += len(inc)
        tot["touch"] += sum(bool(i["outside_envelope"]) for i in inc)
        tot["touch_ranges"] += sum(ranges.touches(i["t_start"], i["t_end"]) for i in inc)
        tot["outside"] += full.outside
        tot["outside_ranges"] += ranges.outside
        tot["samples"] += full.samples
    return tot


def arm_rows(arm: str, runs: int, out: Path) -> list[str]:
    pre = ARMS[arm][0]
    logs = [ROOT / "sample_logs" / "csv" / f"{pre}_free_{m}.csv.gz" for m in FREE]
    robot = ROOT / "sample_logs" / "csv" / f"{pre}_free_triangle.robot.json"
    slow = slow_runs(out, arm, runs)
    sets = [("+".join(FREE[i] for i in pick), [logs[i] for i in pick])
            for k in (3, 2) for pick in itertools.combinations(range(3), k)]
    sets += [("+".join(pair), [pool_run(out, arm, n) for n in pair]) for pair in PAIRS]
    rows = []
    for name, cal in sets:
        cfg = out / arm / f"{name}.config.toml"
        subprocess.run([CLI, "calibrate", *map(str, cal), "--robot", str(robot), "-o",
                        str(cfg)], check=True, capture_output=True)
        t = judge(cfg, slow, out / arm / name)
        rate = t["false"] / t["hours"]
        rows.append(
            f"| {arm} | {name} | {t['predicted']:.3g} / {t['upper']:.3g} | "
            f"{t['false']} in {t['hours']:.2f} h: {rate:.3g} per h"
            f"{' (above the bound)' if rate > t['upper'] else ''} | "
            f"{100 * t['outside'] / t['samples']:.3g} % / "
            f"{100 * t['outside_ranges'] / t['samples']:.3g} % | "
            f"{t['touch']}/{t['false']} / {t['touch_ranges']}/{t['false']} |")
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "slow_motion",
                    help="where the runs and configs go (runs reused when present)")
    ap.add_argument("--runs", type=int, default=6, help="slow free runs of 120 s per arm")
    ap.add_argument("--arm", choices=sorted(ARMS), action="append")
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    print("| arm | calibrated on | stated: predicted / bound [1/h] | "
          "false alarms in slow motion | time outside: envelope / ranges alone | "
          "false alarms touching it: envelope / ranges alone |")
    print("|---|---|---|---|---|---|")
    for arm in a.arm or sorted(ARMS):
        print("\n".join(arm_rows(arm, a.runs, a.out)), flush=True)
    print(f"\nmachine: {platform.platform()}, {os.cpu_count()} CPUs; python "
          f"{sys.version.split()[0]}; {date.today().isoformat()}; total "
          f"{time.perf_counter() - t0:.0f} s; command: python tests/benchmarks/"
          f"slow_motion.py --runs {a.runs}"
          + "".join(f" --arm {x}" for x in a.arm or []))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
