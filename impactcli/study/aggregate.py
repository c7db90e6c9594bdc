"""The sensitivity study's outcomes summarised (:func:`summarize`): per variant, the soak's
false alarms per swept scale, the matched (zero soak false alarm) scales, per detector and
stiffness the minimal detected force and the force above which all were detected, the ROC
points, and the verdict (:func:`_verdict`: does the adaptive detector help at matched
rates?) — one JSON-ready mapping (schemas/sensitivity.schema.json).

It reads the task outcomes (:mod:`impactcli.study.tasks`); the tables
(:mod:`impactcli.study.tables`) render what it returns.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..quality.match import EVALUATED
from ..types import GRAVITY_M_S2
from .arms import amplitudes
from .spec import (
    ARM_GEOMETRY,
    PAPER_ADAPTIVE_N,
    PAPER_STATIC_N,
    SCHEMA_VERSION,
    SETTINGS,
    VARIANTS,
    StudySpec,
)
from .tasks import CalibOutcome, CaseOutcome, ContactRecord, SoakOutcome


def poisson_upper_95(n: int, hours: float) -> float | None:
    """Exact one-sided 95 % upper bound on a Poisson rate [1/h] after ``n`` events in
    ``hours``: χ²₀.₉₅(2(n+1)) / (2 T). For n = 0 it is −ln(0.05) / T ≈ 3.00 / T."""
    from scipy.stats import chi2

    if hours <= 0:
        return None
    return float(chi2.ppf(0.95, 2 * (n + 1)) / 2.0 / hours)


def zero_fa_index(false_alarms: Sequence[int]) -> int | None:
    """Index of the smallest scale from which on every (larger) scale has zero false alarms,
    given counts at ascending scales; None when even the largest scale false-alarms."""
    best = None
    for i in range(len(false_alarms) - 1, -1, -1):
        if false_alarms[i]:
            break
        best = i
    return best


def _r(x: float | None, nd: int = 4) -> float | None:
    if x is None or not math.isfinite(x):
        return None
    return round(float(x), nd)


def _cell(contacts: Sequence[ContactRecord], det: str, i: int) -> dict[str, Any]:
    """Scores of one detector at scale index i over a set of contacts."""
    hit = [c for c in contacts if math.isfinite(c.delays[det][i])]
    miss = [c for c in contacts if not math.isfinite(c.delays[det][i])]
    fmin = min((c.peak_force for c in hit), default=None)
    return {
        "n_contacts": len(contacts), "detected": len(hit),
        "min_detected_force_n": _r(fmin, 3),
        "equivalent_mass_kg": _r(fmin / GRAVITY_M_S2, 3) if fmin is not None else None,
        "all_detected_above_n": _r(max((c.peak_force for c in miss), default=None), 3),
        "delay_median_s": _r(statistics.median(c.delays[det][i] for c in hit) if hit else None,
                             4),
    }


def summarize(spec: StudySpec, calibs: Sequence[CalibOutcome],
              soaks: Sequence[SoakOutcome], cases: Sequence[CaseOutcome]) -> dict[str, Any]:
    """The study's results as one JSON-ready mapping (schemas/sensitivity.schema.json)."""
    scales = list(spec.scales)
    order = sorted(range(len(scales)), key=lambda i: scales[i])
    i_one = scales.index(1.0)
    calib_of = {c.arm: c for c in calibs}
    variants = []
    for v in spec.variants:
        var = VARIANTS[v]
        so = sorted((s for s in soaks if s.variant == v), key=lambda s: (s.family, s.run))
        cs = sorted((c for c in cases if c.variant == v),
                    key=lambda c: (c.stiffness, c.amplitude, c.seed))
        contacts = [x for c in cs for x in c.contacts]
        free_h = sum(s.free_s for s in so) / 3600.0
        fa = {d: [sum(s.false_alarms[d][i] for s in so) for i in range(len(scales))]
              for d in EVALUATED}
        case_fa = {d: [sum(c.false_alarms[d][i] for c in cs) for i in range(len(scales))]
                   for d in EVALUATED}
        case_free_h = sum(c.free_s for c in cs) / 3600.0
        # matched: the smallest scale from which on the soak stays silent
        matched: dict[str, int | None] = {}
        for d in EVALUATED:
            asc = [fa[d][i] for i in order]
            z = zero_fa_index(asc)
            matched[d] = None if z is None else order[z]
        settings: dict[str, dict[str, Any]] = {}
        for setting in SETTINGS:
            per_det: dict[str, dict[str, Any]] = {}
            for d in EVALUATED:
                i = i_one if setting == "calibrated" else matched[d]
                if i is None:
                    per_det[d] = {"scale": None, "reached": False}
                    continue
                by_k = {}
                for k in spec.stiffnesses:
                    by_k[f"{k:g}"] = _cell([c for c in contacts if c.stiffness == k], d, i)
                per_det[d] = {
                    "scale": scales[i], "reached": True,
                    "at_sweep_edge": setting == "matched" and i == order[0],
                    "soak_false_alarms": fa[d][i],
                    "soak_false_alarms_per_hour": _r(fa[d][i] / free_h if free_h else None, 4),
                    "soak_false_alarms_per_hour_upper95": _r(poisson_upper_95(fa[d][i], free_h),
                                                             4),
                    "case_false_alarms": case_fa[d][i],
                    "all": _cell(contacts, d, i),
                    "by_stiffness": by_k,
                }
            settings[setting] = per_det
        roc = {d: [{
            "scale": scales[i], "soak_false_alarms": fa[d][i],
            "soak_false_alarms_per_hour": _r(fa[d][i] / free_h if free_h else None, 4),
            "soak_false_alarms_per_hour_upper95": _r(poisson_upper_95(fa[d][i], free_h), 4),
            **_cell(contacts, d, i)} for i in order] for d in EVALUATED}
        cal = calib_of[var.arm]
        variants.append({
            "name": v, "arm": var.arm, "payload_kg": var.payload_kg,
            "description": var.description,
            "calibration": {"runs": list(cal.runs), "margins": cal.margins,
                            "thresholds": {"v_stat": cal.config.thresholds.v_stat,
                                           "v0": cal.config.thresholds.v0,
                                           "vL": cal.config.thresholds.vL},
                            "model_sha256": cal.config.calibration.model_sha256},
            "soak": {
                "hours_after_warmup": _r(free_h, 4),
                "runs": [{"family": s.family, "run": s.run, "seed": s.seed,
                          "duration_s": _r(s.duration_s, 3),
                          "warmup_end_s": _r(s.warmup_end_s, 3),
                          "false_alarms_calibrated": {d: s.false_alarms[d][i_one]
                                                      for d in EVALUATED}} for s in so],
            },
            "cases": {"n_cases": len(cs), "n_contacts": len(contacts),
                      "uncounted_contacts": sum(c.uncounted for c in cs),
                      "collision_free_hours": _r(case_free_h, 4),
                      "amplitudes_rad": list(amplitudes(var.arm, spec.forces_n)),
                      "period_s": ARM_GEOMETRY[var.arm][1],
                      "gap_rad": ARM_GEOMETRY[var.arm][0]},
            "settings": settings,
            "roc": roc,
            "verdict": _verdict(v, contacts, matched, order, scales),
            "contacts": [{
                "stiffness": c.stiffness, "amplitude_rad": c.amplitude,
                "nominal_force_n": c.nominal_force_n, "seed": c.seed,
                "start_s": _r(c.start_s, 4), "peak_force_n": _r(c.peak_force, 3),
                "tip_speed_m_s": _r(c.tip_speed_m_s, 4),
                "peak_ratio_calibrated": {d: _r(x, 4) for d, x in c.peak_ratio.items()},
                "delay_calibrated_s": {d: _r(c.delays[d][i_one], 4) for d in EVALUATED},
                "delay_matched_s": {d: (_r(c.delays[d][i], 4) if (i := matched[d]) is not None
                                        else None) for d in EVALUATED},
            } for c in contacts],
            "g_gain": _mean_gain(cs),
        })
    return {
        "schema_version": SCHEMA_VERSION,
        "spec": spec.to_dict(),
        "paper": {"adaptive_min_detected_force_n": {f"{k:g}": v
                                                    for k, v in PAPER_ADAPTIVE_N.items()},
                  "static_threshold_min_detected_force_n": f"> {PAPER_STATIC_N:g}"},
        "definitions": {
            "min_detected_force": "smallest labelled peak force among detected contacts [N]",
            "all_detected_above": "largest labelled peak force among missed contacts [N]: "
                                  "every contact above it was detected (null: none missed)",
            "calibrated": "thresholds as calibrated (scale 1) by leave-one-out on the arm's "
                          "collision-free, payload-free calibration runs",
            "matched": "per detector, the smallest swept threshold scale from which on the "
                       "soak has zero false alarms",
            "upper95": "exact one-sided 95 % Poisson upper bound on false alarms per hour "
                       "(3.00 / T for none in T hours)",
        },
        "variants": variants,
    }


def _mean_gain(cs: Sequence[CaseOutcome]) -> dict[str, Any]:
    """G_hat's gain at the end of each case run, mean and range over cases, per joint."""
    gains: dict[str, list[list[float]]] = {}
    freqs: list[float] = []
    for c in cs:
        g = c.g_gain or {}
        freqs = list(g.get("frequencies_hz", freqs))
        for j, vals in (g.get("gain") or {}).items():
            gains.setdefault(j, []).append(list(vals))
    return {"frequencies_hz": freqs,
            "mean": {j: [_r(x, 4) for x in np.mean(v, axis=0)] for j, v in gains.items()},
            "min": {j: [_r(x, 4) for x in np.min(v, axis=0)] for j, v in gains.items()},
            "max": {j: [_r(x, 4) for x in np.max(v, axis=0)] for j, v in gains.items()}}


#: Paired median delay gain needed to call the adaptive detector earlier [s] (one sample at
#: the paper's 4 ms period).
EARLIER_MIN_S = 0.004


def _verdict(variant: str, contacts: Sequence[ContactRecord], matched: dict[str, int | None],
             order: Sequence[int], scales: Sequence[float]) -> dict[str, Any]:
    """Does the adaptive detector help on this robot, at matched (zero) soak false alarms?

    Adaptive and static_loading each at its own zero-false-alarm scale on the soak; their
    OR (the product) is then silent on the soak too. The adaptive detector *helps* when,
    added to static_loading, it catches impacts static_loading misses, or fires at least
    :data:`EARLIER_MIN_S` earlier (median over the impacts both catch). The text also
    compares the two alone: impacts detected, smallest detected force, force above which
    all were detected.
    """
    ia, il = matched["adaptive"], matched["static_loading"]
    if not contacts:
        return {"adaptive_helps": None, "text": f"{variant}: undetermined — no counted contact."}
    if ia is not None and il is None:
        a = _cell(contacts, "adaptive", ia)
        return {"adaptive_helps": True, "adaptive_only": a["detected"], "static_loading_only": 0,
                "both": 0, "paired_delay_gain_s": None,
                "text": f"{variant}: YES by default — static_loading false-alarms on the soak at "
                        f"every swept scale up to {max(scales):g} × its calibrated threshold, so "
                        "it cannot run without false alarms; adaptive is silent from scale "
                        f"{scales[ia]:g} and there detects {a['detected']}/{a['n_contacts']} "
                        f"impacts (smallest {fmt(a['min_detected_force_n'], ' N')}, all above "
                        f"{fmt(a['all_detected_above_n'], ' N')})."}
    if ia is None or il is None:
        miss = [d for d, i in (("adaptive", ia), ("static_loading", il)) if i is None]
        return {"adaptive_helps": None,
                "text": f"{variant}: undetermined — {' and '.join(miss)} never reached zero "
                        "false alarms on the soak within the swept scales."}
    a = _cell(contacts, "adaptive", ia)
    s = _cell(contacts, "static_loading", il)
    da = [c.delays["adaptive"][ia] for c in contacts]
    ds = [c.delays["static_loading"][il] for c in contacts]
    pairs = [(math.isfinite(x), math.isfinite(y), y - x) for x, y in zip(da, ds, strict=True)]
    both = [g for fa_, fs_, g in pairs if fa_ and fs_]
    a_only = sum(1 for fa_, fs_, _ in pairs if fa_ and not fs_)
    s_only = sum(1 for fa_, fs_, _ in pairs if fs_ and not fa_)
    gain = statistics.median(both) if both else None
    earlier = gain is not None and gain >= EARLIER_MIN_S - 1e-9
    edge = [d for d, i in (("adaptive", ia), ("static_loading", il)) if i == order[0]]
    helps: bool | None = (a_only > 0 or earlier) if not edge else None

    def alone(name: str, c: dict[str, Any], i: int) -> str:
        return (f"{name} (scale {scales[i]:g}) {c['detected']}/{c['n_contacts']}, smallest "
                f"{fmt(c['min_detected_force_n'], ' N')}, all above "
                + ("none missed" if c["all_detected_above_n"] is None
                   else fmt(c["all_detected_above_n"], " N")))

    facts = (f"added to static_loading it catches {a_only} impact(s) static_loading misses"
             + (f" and fires {abs(gain) * 1e3:.0f} ms {'earlier' if gain >= 0 else 'later'} "
                f"(median) on the {len(both)} both catch" if gain is not None else "")
             + f"; alone: {alone('adaptive', a, ia)}; {alone('static_loading', s, il)} "
             f"({s_only} impact(s) only static_loading catches)")
    if 2 * max(a["detected"], s["detected"]) < a["n_contacts"]:
        facts += ("; neither detects half of the impacts at zero soak false alarms on this "
                  "robot")
    if edge:
        text = (f"{variant}: undetermined — {' and '.join(edge)} already silent at the smallest "
                f"swept scale; {facts}.")
    elif helps:
        text = f"{variant}: YES, the adaptive detector helps at zero soak false alarms — {facts}."
    else:
        text = (f"{variant}: NO, the adaptive detector does not help at zero soak false "
                f"alarms — {facts}.")
    return {"adaptive_helps": helps, "adaptive_only": a_only, "static_loading_only": s_only,
            "both": len(both), "paired_delay_gain_s": _r(gain, 4), "text": text}


def fmt(x: float | None, unit: str = "", nd: str = ".3g") -> str:
    """``x`` formatted by ``nd`` with ``unit`` after it; ``-`` for None."""
    return "-" if x is None else f"{x:{nd}}{unit}"
