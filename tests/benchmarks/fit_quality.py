"""Fit quality of the rough rigid model, per model kind: on the simulator, the sample logs
and the real logs when present (the tables of docs/validation.md, "Fit quality").

    python tests/benchmarks/fit_quality.py            # everything (about a minute)
    python tests/benchmarks/fit_quality.py sim real   # only some sections

Sections (markdown tables, then the machine):

* ``sim`` — the flexible-joint simulator's ASSIST-like arm: the preset, and three robots
  whose every physical parameter is drawn ±20 % off it (``impactcli.study.arms.the_robot``).
  A ``planar`` model is identified on a 60 s collision-free multi-sine run and judged on
  *other* trajectories of the same robot (multi-sine, triangles, point-to-point, 30 s each,
  another seed): RMS torque error relative to the joint's torque RMS (both zero-phase
  filtered at 10 Hz, as identification sees them). Then the residual during two slow 2 s,
  20 N pushes against the applied external torque at the push's peak. A second table
  judges ``planar``, ``coupled`` and ``decoupled`` models made the same way.
* ``samples`` — the shipped free-motion sample logs (``sample_logs/csv/*free*``):
  identification's own held-back error (the last 20 % of the log) per kind.
* ``real`` — the real logs in ``../shared/real_logs`` (skipped when absent): the KUKA LWR4+
  (7 joints) and UR (6 joints) logs, ``decoupled`` vs ``coupled`` (and ``coupled`` with
  velocity products), fitted part and held-back part, fit time; and, for the KUKA log, the
  held-back 20 % stretch put at five places in the log (a check that one split does not
  decide the comparison).
* ``time`` — fit time and rows of a synthetic 10 min, 1 kHz, 7-joint log.
"""

from __future__ import annotations

import os
import platform
import resource
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from impactcli.logs import read_log
from impactcli.logs.robot_files import read_robot
from impactcli.model import (
    IdentifyOptions,
    ResidualOptions,
    compute_residual,
    identify,
    identify_signals,
    zero_phase_derivatives,
    zero_phase_lowpass,
)
from impactcli.model import structures as st
from impactcli.sim import Push, preset, scenario, simulate
from impactcli.study.arms import the_robot
from impactcli.types import LogSource, RobotLog

REPO = Path(__file__).resolve().parents[2]
#: the real recordings: IMPACTCLI_REAL_LOGS, else shared/real_logs beside the repository
REAL = Path(os.environ.get("IMPACTCLI_REAL_LOGS", REPO.parent / "shared" / "real_logs"))
KINDS3 = ("planar", "coupled", "decoupled")


def _rel_error(model, log) -> np.ndarray:  # type: ignore[no-untyped-def]
    qf, qd, qdd = zero_phase_derivatives(log.time_s, log.position, 10.0)
    tau = zero_phase_lowpass(log.torque, log.sample_rate_hz, 10.0)
    inner = slice(100, -100)
    err = model.predict(qf, qd, qdd)[inner] - tau[inner]
    return np.sqrt(np.mean(err**2, axis=0)) / np.sqrt(np.mean(tau[inner] ** 2, axis=0))


def _pcts(xs) -> str:  # type: ignore[no-untyped-def]
    return " / ".join("still" if x is None else f"{100 * x:.1f} %" for x in xs)


def sim() -> None:
    robots = [("preset", preset("assist_like"))] + [
        (f"±20 % robot {k}", the_robot("assist_like", k)) for k in range(3)]
    tests = ("free_multisine", "free_triangle", "free_p2p")
    print("| robot | " + " | ".join(f"{t} (shoulder / elbow)" for t in tests)
          + " | push residual error at peak (link 2 / link 1) |")
    print("|---|" + "---|" * (len(tests) + 1))
    kinds_rows = []
    for label, arm in robots:
        train = simulate(scenario("free_multisine", arm, 60.0, uncertainty=0.0), seed=1)
        models = {k: identify(train.log, robot=train.robot if k == "planar" else None, kind=k)
                  for k in KINDS3}
        logs = {name: simulate(scenario(name, arm, 30.0, uncertainty=0.0), seed=7).log
                for name in tests}
        cells = [_pcts(_rel_error(models["planar"], logs[name])) for name in tests]
        for k in KINDS3:
            kinds_rows.append(f"| {label} | {k} | " + " | ".join(
                _pcts(_rel_error(models[k], logs[name])) for name in tests) + " |")
        pushes = (Push(link=2, t0_s=10.0, peak_n=20.0, duration_s=2.0, point=0.8),
                  Push(link=1, t0_s=20.0, peak_n=20.0, duration_s=2.0, point=0.8,
                       direction_deg=90.0))
        run = simulate(replace(scenario("pushes", arm, 25.0, uncertainty=0.0), pushes=pushes),
                       seed=3)
        r = compute_residual(models["planar"], run.log, ResidualOptions()).r
        ext, t = run.truth["tau_ext"], run.log.time_s
        errs = []
        for start in (10.0, 20.0):
            k = np.flatnonzero((t >= start) & (t <= start + 2.0))
            peak = k[np.argmax(np.abs(ext[k]).max(axis=1))]
            j = int(np.argmax(np.abs(ext[peak])))
            errs.append(f"{100 * abs(r[peak, j] - ext[peak, j]) / abs(ext[peak, j]):.1f} %")
        print(f"| {label} | " + " | ".join(cells) + " | " + " / ".join(errs) + " |")
    print("\nThe same protocol per model kind (identified on the 60 s multi-sine run):\n")
    print("| robot | kind | " + " | ".join(f"{t} (shoulder / elbow)" for t in tests) + " |")
    print("|---|---|" + "---|" * len(tests))
    print("\n".join(kinds_rows))


def samples() -> None:
    print("\nSample logs, identification's held-back last 20 % (RMS error / torque RMS, "
          "per joint):\n")
    print("| log | planar | coupled | decoupled |")
    print("|---|---|---|---|")
    for path in sorted((REPO / "sample_logs" / "csv").glob("*free*.csv.gz")):
        name = path.name.removesuffix(".csv.gz")
        robot = read_robot(path.with_name(f"{name}.robot.json"))
        log = read_log(path, robot=robot)
        cells = []
        for k in KINDS3:
            m = identify(log, robot=robot if k == "planar" else None, kind=k)
            hold = m.fit["joints"]["holdout"]
            cells.append(_pcts([hold[j]["rms_rel_torque_rms"] for j in m.joint_names]))
        print(f"| {name} | " + " | ".join(cells) + " |")


def _fit_row(m, part: str) -> list[str]:  # type: ignore[no-untyped-def]
    stats = m.fit["joints"][part]
    out = []
    for j in m.joint_names:
        s = stats[j]
        rel = s["rms_rel_torque_rms"]
        out.append(f"{s['rms_nm']:.3g} N·m (still)" if rel is None else f"{100 * rel:.1f} %")
    return out


def real() -> None:
    if not REAL.is_dir():
        print(f"\n{REAL} is absent: real-log section skipped")
        return
    cases = (("KUKA LWR4+", "kuka_lwr4/measurements_1.npz", "kuka_lwr4", 0.2),
             ("UR", "ur_ext_observer/link4.csv", "ur_ext_observer", 0.2),
             ("UR", "ur_ext_observer/link4.csv", "ur_ext_observer", 0.35))
    for label, rel, cmap, frac in cases:
        base = IdentifyOptions(allow_still_joints=True, holdout_fraction=frac)
        variants = (("decoupled", "decoupled", base), ("coupled", "coupled", base),
                    ("coupled + q'q'", "coupled", replace(base, coupled_velocity_products=True)))
        log = read_log(REAL / rel, channel_map=cmap)
        print(f"\n{label} (`{rel}`, {log.n_joints} joints, {log.sample_rate_hz:.0f} Hz, "
              f"{log.duration_s:.1f} s), held back: the last {100 * frac:.0f} %, "
              "RMS error / torque RMS:\n")
        print("| model | params | fit time | part | " + " | ".join(log.joint_names)
              + " | mean |")
        print("|---|---|---|---|" + "---|" * (log.n_joints + 1))
        for name, kind, opts in variants:
            t0 = time.perf_counter()
            m = identify(log, kind=kind, options=opts)
            dt = time.perf_counter() - t0
            for part in ("fit", "holdout"):
                rels = [m.fit["joints"][part][j]["rms_rel_torque_rms"] for j in m.joint_names]
                given = [x for x in rels if x is not None]
                mean = f"{100 * np.mean(given):.1f} %" if given else "—"
                print(f"| {name} | {len(m.theta)} | {dt:.2f} s | "
                      f"{'held back' if part == 'holdout' else 'fit'} | "
                      + " | ".join(_fit_row(m, part)) + f" | {mean} |")
            if m.fit.get("ridge"):
                lams = [v["lambda"] for v in m.fit["ridge"]["joints"].values()]
                print("| | | | ridge penalty | " + " | ".join(
                    "off" if v is None else f"{v:.1g}" for v in lams) + " | |")
    _positions("KUKA", "kuka_lwr4/measurements_1.npz", "kuka_lwr4")
    _positions("UR", "ur_ext_observer/link4.csv", "ur_ext_observer")


def _positions(label: str, rel: str, cmap: str) -> None:
    """A real log's held-back 20 % at five places (identify_signals on the zero-phase
    filtered signals, regressor unfiltered: close to, not identical with, ``identify``)."""
    log = read_log(REAL / rel, channel_map=cmap)
    fs, cut = log.sample_rate_hz, 10.0
    q, qd, qdd = zero_phase_derivatives(log.time_s, log.position, cut)
    tau = zero_phase_lowpass(log.torque, fs, cut)
    k1 = max(1, int(fs // (10 * cut)))
    q, qd, qdd, tau = q[::k1], qd[::k1], qdd[::k1], tau[::k1]
    n, edge = q.shape[0], int(np.ceil(fs / k1 / cut))
    nh = round(0.2 * n)
    print(f"\n{label}, the held-back 20 % stretch at five places (mean over the joints that "
          "move in it of RMS error / torque RMS; identify_signals on the filtered signals):\n")
    print("| held-back stretch | " + " | ".join(("decoupled", "coupled")) + " |")
    print("|---|---|---|")
    means: dict[str, list[float]] = {"decoupled": [], "coupled": []}
    for pos in (0.0, 0.25, 0.5, 0.75, 1.0):
        a = round(pos * (n - nh))
        hold = np.arange(a + edge, a + nh - edge)
        fit = np.concatenate([np.arange(edge, max(edge, a - edge)),
                              np.arange(min(n - edge, a + nh + edge), n - edge)])
        cells = []
        for kind in ("decoupled", "coupled"):
            m = identify_signals(q[fit], qd[fit], qdd[fit], tau[fit], joint_names=log.joint_names,
                                 kind=kind, holdout=(q[hold], qd[hold], qdd[hold], tau[hold]),
                                 options=IdentifyOptions(check_sanity=False,
                                                         allow_still_joints=True))
            rels = [v["rms_rel_torque_rms"] for v in m.fit["joints"]["holdout"].values()]
            given = [x for x in rels if x is not None]
            err = float(np.mean(given)) if given else float("nan")
            means[kind].append(err)
            cells.append(f"{100 * err:.1f} % ({len(given)} joints)" if given
                         else "— (the arm stands still)")
        t0, t1 = a / (fs / k1), (a + nh) / (fs / k1)
        print(f"| {t0:.1f}–{t1:.1f} s | " + " | ".join(cells) + " |")
    print("| mean | " + " | ".join(f"{100 * np.nanmean(v):.1f} %" for v in means.values())
          + " |")


def timing() -> None:
    nj, fs, dur = 7, 1000.0, 600.0
    n = int(fs * dur)
    rng = np.random.default_rng(3)
    t = np.arange(n) / fs
    w = rng.uniform(0.3, 2.5, (3, nj)) * np.pi
    amp, ph = rng.uniform(0.6, 1.1, (3, nj)), rng.uniform(0, 2 * np.pi, (3, nj))
    q = np.zeros((n, nj))
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    for k in range(3):
        arg = np.outer(t, w[k]) + ph[k]
        q += amp[k] * np.sin(arg)
        qd += amp[k] * w[k] * np.cos(arg)
        qdd -= amp[k] * w[k] ** 2 * np.sin(arg)
    joints = tuple(f"j{k + 1}" for k in range(nj))
    s = {"coulomb_slope_rad_s": 0.01, "offset": True, "motor_inertia": True}
    theta = rng.normal(0, 0.3, len(st.param_names("coupled", joints, s)))
    tau = np.concatenate([st.coupled_predict(q[a:a + 50000], qd[a:a + 50000],
                                             qdd[a:a + 50000], s, theta)
                          for a in range(0, n, 50000)]) + rng.normal(0, 0.05, (n, nj))
    log = RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=joints, position=q,
                   torque=tau, source=LogSource("synthetic", "", "memory"))
    print(f"\nFit time, synthetic {dur / 60:.0f} min, {fs:.0f} Hz, {nj}-joint log (torque made by "
          "a coupled model + noise):\n")
    print("| kind | params | fit rows | fit time | peak RSS |")
    print("|---|---|---|---|---|")
    for kind in ("decoupled", "coupled"):
        t0 = time.perf_counter()
        m = identify(log, kind=kind)
        dt = time.perf_counter() - t0
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(f"| {kind} | {len(m.theta)} | {m.fit['n_samples_fit']} | {dt:.1f} s | "
              f"{rss:.0f} MB |")


def main() -> None:
    warnings.simplefilter("ignore")
    sections = {"sim": sim, "samples": samples, "real": real, "time": timing}
    for name in sys.argv[1:] or list(sections):
        sections[name]()
    print(f"\nmachine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, load average {os.getloadavg()[0]:.1f}, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")


if __name__ == "__main__":
    main()
