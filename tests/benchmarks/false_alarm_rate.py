"""Predicted against observed false-alarm rates over many simulated free hours.

    python tests/benchmarks/false_alarm_rate.py [--data DIR] [--sets A1,C1] [--held 12]
                                                [--rates 1,10] [--jobs 2]

What a user does, measured: ``calibrate --false-alarms-per-hour R`` on a calibration set
of 3–4 collision-free logs of 60–120 s (the robot's own logs: two simulated arms, each one
robot), then the product runs on long free runs of the same arm that the calibration never
saw. Every incident there is a false alarm. Printed per arm, set and R: the hours and
incidents inside the set's motion families and outside them, the observed rate and its
two-sided 90 % Garwood interval against the rate the config states (predicted, upper
bound), the share of time outside the calibration's motion envelope, and how many
incidents touched it (inside and outside the families, and how many touched it only
through its slow stretches, :data:`impactcli.detect.envelope.SLOW_RAD_S`); the leave-one-out
rule (``calibrate``'s default) on the same logs, with the rate the tail fits predict for its
thresholds;
and per set and rule, the contacts of the arm's sample contact logs the product catches
(``--contacts-only``: only those).

Data (made here by ``impactcli simulate`` when absent, deterministic seeds; reused when
present): arms assist_like (robot seed 100) and heavy_geared (200), the sample logs' robots;
families triangle (tri), frequency-modulated triangle (fm), point-to-point (p2p), multi-sine
(ms). Calibration pool: seeds 1010–1015 of 60–120 s per family; held out: ``--held`` runs of
5 min (seeds 2000…) and one of 30 min (seed 3000) per family. Calibration sets
(:data:`CAL_SETS`): A* lack fm, B* lack p2p, C* have all four families.

Counting: each held-out log is replayed once per set (its threshold-free pass,
:func:`impactcli.run.collect.stats_in_memory`); incidents are clusters of the union over
joints and both product detectors of statistic > threshold, merged over 0.1 s
(:func:`impactcli.detect.tail.count_incidents`: the product's incident count without the
"pressing" bridge, which only merges more), after warm-up.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from datetime import date
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
CLI = str(Path(sys.executable).with_name("impactcli"))
ARMS = {"assist_like": 100, "heavy_geared": 200}
FAMILIES = {"tri": "free_triangle", "fm": "free_fm_triangle", "p2p": "free_p2p",
            "ms": "free_multisine"}
CAL_POOL = [(1010, 60), (1011, 90), (1012, 120), (1013, 90), (1014, 120), (1015, 60)]
CAL_SETS: dict[str, list[str]] = {
    "A1": ["tri_s1010_60", "p2p_s1011_90", "ms_s1012_120"],
    "A2": ["tri_s1013_90", "p2p_s1014_120", "ms_s1015_60", "ms_s1011_90"],
    "A3": ["tri_s1014_120", "p2p_s1010_60", "ms_s1013_90"],
    "A4": ["tri_s1011_90", "p2p_s1013_90", "ms_s1014_120", "p2p_s1015_60"],
    "B1": ["tri_s1010_60", "fm_s1011_90", "ms_s1012_120"],
    "B2": ["tri_s1013_90", "fm_s1014_120", "ms_s1015_60", "fm_s1012_120"],
    "C1": ["tri_s1011_90", "fm_s1012_120", "p2p_s1013_90", "ms_s1014_120"],
    "C2": ["tri_s1015_60", "fm_s1010_60", "p2p_s1012_120", "ms_s1011_90"],
}
CONF = 0.9


def held_names(n_short: int) -> list[str]:
    return [f"{f}_s{2000 + i}_300" for f in FAMILIES for i in range(n_short)] + \
        [f"{f}_s3000_1800" for f in FAMILIES]


def simulate(data: Path, arm: str, name: str) -> Path:
    """The log ``name`` (``<family>_s<seed>_<seconds>``) of ``arm``, simulated if absent."""
    fam, seed, dur = name.split("_")
    folder = data / arm / ("cal" if int(seed[1:]) < 2000 else "held")
    path = folder / f"{name}.csv.gz"
    if not path.exists():
        subprocess.run([CLI, "simulate", "--arm", arm, "--scenario", FAMILIES[fam],
                        "--duration", dur, "--seed", seed[1:], "--robot-seed", str(ARMS[arm]),
                        "-o", str(folder), "--name", name], check=True, capture_output=True)
    return path


CONTACT_LOGS = {"assist_like": ("assist_impacts", "assist_pushes", "assist_clamps"),
                "heavy_geared": ("heavy_impacts",)}


def contacts(arm: str, configs: dict[str, Any]) -> dict[str, list[int]]:
    """Per rule, [caught, contacts] of the product on the arm's sample contact logs (the
    same simulated robot: every labelled log of the repository)."""
    sys.path.insert(0, str(ROOT))
    from impactcli.quality.match import PRODUCT
    from tests.benchmarks import sample_quality as sq

    out = {}
    for k, cfg in configs.items():
        n = [0, 0]
        for name in CONTACT_LOGS[arm]:
            s = sq.run(name, cfg)[1].scores[PRODUCT]
            n[0] += s.detected
            n[1] += s.n_contacts
        out[k] = n
    return out


def run_set(data: Path, arm: str, set_name: str, n_short: int, rates: list[float],
            held: bool = True) -> dict[str, Any]:
    """One calibration set: thresholds for each R and by leave-one-out, the sample contact
    logs caught by each, then every held-out log counted against them."""
    from impactcli.detect.envelope import EnvelopeCheck, MotionEnvelope
    from impactcli.detect.tail import clusters, stack_detectors
    from impactcli.logs import read_log
    from impactcli.logs.robot_files import read_robot
    from impactcli.run.calibration import MARGIN_RULE, RATE_RULE, calibrate_run
    from impactcli.run.collect import stats_in_memory

    warnings.simplefilter("ignore")
    cal_paths = [simulate(data, arm, n) for n in CAL_SETS[set_name]]
    robot = read_robot(str(cal_paths[0]).replace(".csv.gz", ".robot.json"))
    logs = [read_log(p) for p in cal_paths]
    rules: dict[str, Any] = {}
    configs: dict[str, Any] = {}
    cfg = None
    for r in rates:
        done = calibrate_run(logs, robot=robot, threshold_rule=RATE_RULE,
                             false_alarms_per_hour=r, confidence=CONF)
        assert done.rate is not None
        rules[f"R={r:g}"] = {"thr": done.rate.thresholds, "rate": r,
                             "predicted": done.rate.predicted_total,
                             "upper": done.rate.upper_total,
                             "supported": not done.rate.below_support,
                             "minutes": done.rate.hours * 60.0}
        cfg = configs[f"R={r:g}"] = done.config
    loo = calibrate_run(logs, robot=robot, threshold_rule=MARGIN_RULE)
    base = configs["leave-one-out"] = loo.config
    joints = list(base.thresholds.v_stat)
    rules["leave-one-out"] = {"thr": np.array([base.thresholds.v_stat[j] for j in joints]
                                              + [base.thresholds.vL[j] for j in joints]),
                              "rate": None}
    if loo.rate is not None:  # the rate its thresholds are predicted to give
        rules["leave-one-out"].update(predicted=loo.rate.predicted_total,
                                      upper=loo.rate.upper_total, supported=True,
                                      minutes=loo.rate.hours * 60.0)
    assert cfg is not None and cfg.calibration.motion_envelope is not None
    env = MotionEnvelope.from_dict(cfg.calibration.motion_envelope)
    fams = {n.split("_")[0] for n in CAL_SETS[set_name]}
    counts: dict[str, dict[str, list[float]]] = {k: {} for k in rules}
    time_out = {"in": [0, 0], "out": [0, 0]}
    for name in held_names(n_short) if held else []:
        log = read_log(simulate(data, arm, name))
        st, rp, _ = stats_in_memory(log, config=cfg, robot=robot)
        x, _ = stack_detectors(st.stats, joints)
        w = rp.warmup.end_index
        dt = log.sample_period_s
        hours = (log.n_samples - w) * dt / 3600.0
        chk = EnvelopeCheck(env, log.sample_rate_hz, log.joint_names)
        chk.update_arrays(log.time_s, log.position, log.position_ref)
        share = chk.finish(w)
        # the same envelope without its slow stretches: what the ranges alone flag
        plain = EnvelopeCheck(MotionEnvelope(env.joints, env.source, env.samples,
                                             env.cutoff_hz), log.sample_rate_hz,
                              log.joint_names)
        plain.update_arrays(log.time_s, log.position, log.position_ref)
        ranges = plain.finish(w)
        where = "in" if name.split("_")[0] in fams else "out"
        time_out[where][0] += share.outside
        time_out[where][1] += share.samples
        t = st.time_s[w:]
        for k, rule in rules.items():
            c = clusters(x[w:], rule["thr"], dt)
            touching = sum(share.touches(float(t[a]), float(t[b]))
                           for a, b in zip(c.starts, c.ends, strict=True))
            by_ranges = sum(ranges.touches(float(t[a]), float(t[b]))
                            for a, b in zip(c.starts, c.ends, strict=True))
            g = counts[k].setdefault(where, [0.0, 0.0, 0.0, 0.0])
            g[0] += c.starts.size
            g[1] += hours
            g[2] += touching
            g[3] += touching - by_ranges
    return {"arm": arm, "set": set_name, "families": sorted(fams), "rules": {
        k: {kk: (vv.tolist() if isinstance(vv, np.ndarray) else vv) for kk, vv in r.items()}
        for k, r in rules.items()}, "counts": counts, "time_outside": time_out,
        "contacts": contacts(arm, configs)}


def table(results: list[dict[str, Any]]) -> str:
    from impactcli.detect.tail import poisson_interval

    head = ("| arm | set (families) | rule | free min | stated: predicted / bound [1/h] | "
            "inside: incidents / h | observed [1/h] (90 % interval) | within bound | "
            "outside: incidents / h | touching the envelope's outside | "
            "touching it inside / through slow motion alone (inside, outside) |")
    out = [head, "|" + "---|" * 11]
    for r in results:
        for k, rule in r["rules"].items():
            c = r["counts"][k]
            n_in, h_in, t_in, s_in = c.get("in", [0, 0, 0, 0])
            n_out, h_out, t_out, s_out = c.get("out", [0, 0, 0, 0])
            lo, hi = poisson_interval(int(n_in), h_in, CONF) if h_in else (0, 0)
            if "upper" not in rule:
                stated, within, mins = "none", "—", "—"
            else:
                stated = f"{rule['predicted']:.2g} / {rule['upper']:.2g}"
                # honest: the observed rate's interval reaches down to the bound or below
                within = "yes" if lo <= rule["upper"] else "**no**"
                mins = f"{rule['minutes']:.1f}" + ("" if rule["supported"] else " (R widened)")
            out.append(
                f"| {r['arm']} | {r['set']} ({','.join(r['families'])}) | {k} | {mins} | "
                f"{stated} | {int(n_in)} / {h_in:.1f} | {n_in / h_in if h_in else 0:.3g} "
                f"({lo:.3g}–{hi:.3g}) | {within} | {int(n_out)} / {h_out:.1f} | "
                f"{int(t_out)}/{int(n_out)} | {int(t_in)}/{int(n_in)} / "
                f"{int(s_in)}, {int(s_out)} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=ROOT / "out" / "false_alarm_rate",
                    help="where the simulated logs are (made when absent)")
    ap.add_argument("--sets", default="A1,C1", help="calibration sets (of %(default)s and "
                    + ",".join(CAL_SETS) + ")")
    ap.add_argument("--arms", default=",".join(ARMS))
    ap.add_argument("--held", type=int, default=12, help="5 min held-out runs per family")
    ap.add_argument("--rates", default="1,10", help="R [1/h]")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--contacts-only", action="store_true",
                    help="only the sample contact logs caught by each set's thresholds")
    a = ap.parse_args(argv)
    rates = [float(x) for x in a.rates.split(",")]
    jobs = [(arm, s) for arm in a.arms.split(",") for s in a.sets.split(",")]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(a.jobs) as ex:
        futs = [ex.submit(run_set, a.data, arm, s, a.held, rates, not a.contacts_only)
                for arm, s in jobs]
        results = [f.result() for f in futs]
    if not a.contacts_only:
        print(table(results))
    print("\n| arm | set | " + " | ".join(results[0]["contacts"]) + " |")
    print("|---|---|" + "---|" * len(results[0]["contacts"]))
    for r in results:
        print(f"| {r['arm']} | {r['set']} | " + " | ".join(
            f"{c}/{n}" for c, n in r["contacts"].values()) + " |")
    for r in results if not a.contacts_only else []:
        for where, (o, n) in r["time_outside"].items():
            print(f"{r['arm']} {r['set']}: time outside the motion envelope, {where} the "
                  f"set's families: {100 * o / max(n, 1):.2f} %")
    print(f"\nmachine: {platform.platform()}, {os.cpu_count()} CPUs; python "
          f"{sys.version.split()[0]}; {date.today().isoformat()}; total "
          f"{time.perf_counter() - t0:.0f} s; command: python tests/benchmarks/"
          f"false_alarm_rate.py --sets {a.sets} --arms {a.arms} --held {a.held} "
          f"--rates {a.rates}" + (" --contacts-only" if a.contacts_only else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
