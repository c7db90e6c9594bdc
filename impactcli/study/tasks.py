"""The sensitivity study's tasks: calibrate an arm, one soak run, one Table II case.

Each task is a picklable dataclass and a top-level function (:func:`run_calibration`,
:func:`run_soak`, :func:`run_case`): they run in worker processes
(:func:`impactcli.study.runner.run_study` maps them with its runner). Each simulates its
run, replays it at the arm's calibrated config and keeps only what the summary needs
(:mod:`impactcli.study.aggregate`): false alarms and delays per swept threshold scale.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config import DetectorConfig
from ..quality.match import EVALUATED
from ..quality.sweep import sweep_ratios
from ..run.collect import detect_in_memory
from .arms import amplitudes, case_scenario, free_scenario, the_robot
from .spec import SOAK_FAMILIES, VARIANTS, StudySpec, seed_of


@dataclass(frozen=True)
class CalibTask:
    arm: str
    spec: StudySpec


@dataclass(frozen=True)
class CalibOutcome:
    """The config calibrated for one arm and what it was calibrated on."""

    arm: str
    config: DetectorConfig
    runs: tuple[str, ...]
    margins: dict[str, dict[str, float]]
    model_fit: dict[str, Any]


def run_calibration(task: CalibTask) -> CalibOutcome:
    """Calibrate one arm on its collision-free, payload-free runs (:mod:`impactcli.study`)."""
    import warnings

    from ..errors import ImpactWarning
    from ..run.calibration import calibrate
    from ..sim import preset, simulate

    spec = task.spec
    arm = the_robot(task.arm, spec.seed)
    amps = amplitudes(task.arm, spec.forces_n)
    logs, names = [], []
    for fam in SOAK_FAMILIES:
        sc = free_scenario(arm, fam, spec.calib_run_s, 0.0, amps)
        seed = seed_of("calib", task.arm, fam, spec.seed)
        logs.append(simulate(sc, seed=seed).log)
        names.append(f"{fam} seed={seed} {spec.calib_run_s:g} s")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        cfg = calibrate(logs, robot=preset(task.arm).robot_description())
    fit = dict((cfg.model or {}).get("fit", {})) if isinstance(cfg.model, dict) else {}
    return CalibOutcome(task.arm, cfg, tuple(names), cfg.calibration.margins, fit)


@dataclass(frozen=True)
class SoakTask:
    variant: str
    family: str
    run: int
    spec: StudySpec
    config: DetectorConfig


@dataclass(frozen=True)
class SoakOutcome:
    """False alarms of one collision-free run, per detector and swept scale.

    false_alarms: detector → (S,) counts at ``spec.scales``; free_s: time after warm-up [s].
    """

    variant: str
    family: str
    run: int
    seed: int
    duration_s: float
    warmup_end_s: float
    free_s: float
    false_alarms: dict[str, tuple[int, ...]]
    n_warnings: int


def soak_false_alarms(ratios: dict[str, np.ndarray], time_s: np.ndarray, warmup_end_s: float,
                      scales: Sequence[float], merge_gap_s: float,
                      min_duration_s: float) -> dict[str, tuple[int, ...]]:
    """False alarms of a collision-free run per detector at each scale (in ``scales`` order).

    At scale s a detector decides ``ratio > s`` ((N, J), ORed over joints; the product ORs
    adaptive and static_loading); events are the intervals of
    :func:`impactcli.quality.sweep.event_intervals` (the run's merge gap and minimum duration).
    Every event still on at or after ``warmup_end_s`` is a false alarm — including one that
    began in the warm-up and never ended (a detector stuck on, e.g. a static threshold under
    an unknown payload, is not silent).
    """
    from ..quality.sweep import event_intervals

    t = np.asarray(time_s, dtype=np.float64)
    out: dict[str, tuple[int, ...]] = {}
    for d in EVALUATED:
        counts = []
        for s in scales:
            if d == "product":
                dec = ((np.asarray(ratios["adaptive"]) > s)
                       | (np.asarray(ratios["static_loading"]) > s))
            else:
                dec = np.asarray(ratios[d]) > s
            _, i1 = event_intervals(dec, t, merge_gap_s, min_duration_s)
            counts.append(int(np.count_nonzero(t[i1] >= warmup_end_s - 1e-9)))
        out[d] = tuple(counts)
    return out


def run_soak(task: SoakTask) -> SoakOutcome:
    """Simulate and replay one soak run; count false alarms at every swept scale."""
    from ..sim import simulate

    spec, var = task.spec, VARIANTS[task.variant]
    arm = the_robot(var.arm, spec.seed)
    sc = free_scenario(arm, task.family, spec.soak_run_s, var.payload_kg,
                       amplitudes(var.arm, spec.forces_n))
    seed = seed_of("soak", task.variant, task.family, task.run, spec.seed)
    log = simulate(sc, seed=seed).log
    res, sig = detect_in_memory(log, config=task.config)
    ev = res.config.get("events", {})
    fa_t = soak_false_alarms(sig.ratios, sig.time_s, res.warmup_end_s, spec.scales,
                             float(ev.get("merge_gap_s", 0.0)),
                             float(ev.get("min_duration_s", 0.0)))
    return SoakOutcome(task.variant, task.family, task.run, seed, log.duration_s,
                       res.warmup_end_s, max(0.0, log.duration_s - res.warmup_end_s), fa_t,
                       len(res.warnings))


@dataclass(frozen=True)
class CaseTask:
    variant: str
    stiffness: float
    amplitude: float
    force_n: float
    seed_index: int
    spec: StudySpec
    config: DetectorConfig


@dataclass(frozen=True)
class ContactRecord:
    """One counted impact of a case.

    delays: detector → (S,) delay [s] at each swept scale (NaN = missed);
    peak_ratio: detector → the largest statistic / threshold (calibrated, scale 1) inside the
    contact's match window, max over joints (> 1 ⇔ above the calibrated threshold there).
    """

    variant: str
    stiffness: float
    amplitude: float
    nominal_force_n: float
    seed: int
    start_s: float
    peak_force: float
    tip_speed_m_s: float
    delays: dict[str, tuple[float, ...]]
    peak_ratio: dict[str, float]


@dataclass(frozen=True)
class CaseOutcome:
    """A case's counted contacts, false alarms per scale on its collision-free parts,
    uncounted contacts, and the adaptive filter G's gain at the run's end per joint."""

    variant: str
    stiffness: float
    amplitude: float
    seed: int
    contacts: tuple[ContactRecord, ...]
    uncounted: int
    free_s: float
    false_alarms: dict[str, tuple[int, ...]]
    g_gain: dict[str, Any]


def run_case(task: CaseTask) -> CaseOutcome:
    """Simulate one case, replay it at the arm's calibrated config, sweep every scale."""
    from ..quality.evaluation import evaluate_result
    from ..sim import simulate

    spec, var = task.spec, VARIANTS[task.variant]
    arm = the_robot(var.arm, spec.seed)
    sc = case_scenario(arm, task.stiffness, task.amplitude, spec, var.payload_kg)
    seed = seed_of("case", task.variant, task.stiffness, task.amplitude, task.seed_index,
                 spec.seed)
    sim = simulate(sc, seed=seed)
    res, sig = detect_in_memory(sim.log, config=task.config)
    ev_cfg = res.config.get("events", {})
    rows = sweep_ratios(sig.ratios, sig.time_s, labels=sim.labels, scales=spec.scales,
                        warmup_end_s=res.warmup_end_s,
                        merge_gap_s=float(ev_cfg["merge_gap_s"]),
                        min_duration_s=float(ev_cfg["min_duration_s"]),
                        tolerance=spec.tolerance)
    ev = evaluate_result(res, sim.labels, tolerance=spec.tolerance)
    order = np.argsort(np.argsort(spec.scales))
    by_det: dict[str, list[Any]] = {d: [] for d in EVALUATED}
    for r in rows:
        by_det[r.detector].append(r)
    t = sig.time_s
    contacts = []
    for k, c in enumerate(sim.labels.events):
        if ev.contacts[k].status != "counted":
            continue
        lo, hi = spec.tolerance.window(c)
        sel = (t >= lo) & (t <= hi)
        peak = {}
        for d in ("adaptive", "static_loading", "static_baseline"):
            rr = sig.ratios[d][sel]
            peak[d] = float(np.max(rr)) if rr.size else float("nan")
        peak["product"] = max(peak["adaptive"], peak["static_loading"])
        delays = {d: tuple(float("nan") if (v := by_det[d][i].contact_delays_s[k]) is None
                           else float(v) for i in order) for d in EVALUATED}
        contacts.append(ContactRecord(
            task.variant, task.stiffness, task.amplitude, task.force_n, seed, c.start,
            c.peak_force, float(c.extra.get("tip_speed_m_s", float("nan"))), delays, peak))
    fa = {d: tuple(int(by_det[d][i].false_alarms) for i in order) for d in EVALUATED}
    n_unc = sum(1 for c in ev.contacts if c.status != "counted")
    return CaseOutcome(task.variant, task.stiffness, task.amplitude, seed, tuple(contacts),
                       n_unc, ev.collision_free_s, fa, res.filter_gain)
