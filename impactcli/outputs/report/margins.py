"""The false-alarm margin: how close each detector came to a false alarm (a maximum of
``result.ratios``, the one quantity the report reduces itself):

    margin_d,j = max { ratio_d(k, j) : t_k >= warmup_end_s, t_k outside every event }

where ``ratio_d = statistic / threshold`` of detector d on joint j (eq. 41–42 for the
adaptive detector; |LP(r)| / vL and |r| / v0 for the static ones) and "outside every event"
excludes each detected event of *any* detector, and each labelled contact when labels are
given, widened by :data:`GUARD_S` on both sides (the RMS windows and filters spread a
contact over a few hundred ms). A margin of 0.6 means the statistic came to 60 % of its
threshold on the collision-free stretches; 1 / margin is the factor by which the threshold
could be lowered before the first false alarm there.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...result import DetectionResult
from ...types import DETECTORS, Labels
from .common import GUARD_S


def statistic(result: DetectionResult, detector: str, j: int) -> tuple[np.ndarray, np.ndarray]:
    """(statistic, threshold) of ``detector`` on joint index ``j``, each (N,) [N·m].

    adaptive: residual_rms vs threshold (v_stat + v_rms, eq. 42); static_loading:
    loading_statistic vs vL; static_baseline: |residual| vs v0.
    """
    n = result.log.n_samples
    name = result.log.joint_names[j]
    if detector == "adaptive":
        return result.signals["residual_rms"][:, j], result.signals["threshold"][:, j]
    if detector == "static_loading":
        return result.signals["loading_statistic"][:, j], np.full(n, result.thresholds[name]["vL"])
    return np.abs(result.signals["residual"][:, j]), np.full(n, result.thresholds[name]["v0"])


def collision_free_mask(
    result: DetectionResult, labels: Labels | None = None, guard_s: float = GUARD_S
) -> np.ndarray:
    """(N,) bool: samples after warm-up and outside every event / labelled contact ± guard."""
    t = result.log.time_s
    mask = t >= result.warmup_end_s
    spans = [(e.t_start, e.t_end) for e in result.events]
    if labels is not None:
        spans += [(c.start, c.end) for c in labels.events]
    for a, b in spans:
        lo = int(np.searchsorted(t, a - guard_s, side="left"))
        hi = int(np.searchsorted(t, b + guard_s, side="right"))
        mask[lo:hi] = False
    return mask


def false_alarm_margins(
    result: DetectionResult, labels: Labels | None = None, guard_s: float = GUARD_S
) -> dict[str, Any]:
    """Per detector and joint, the largest statistic / threshold ratio on collision-free
    stretches (see the module docstring), its time [s] and the headroom 1 / ratio.

    Returns ``{"rule": {...}, "per_detector": {det: {joint: {...}}}, "worst": {det: {...}}}``;
    ``max_ratio`` is None when no collision-free sample remains.
    """
    t = result.log.time_s
    mask = collision_free_mask(result, labels, guard_s)
    period = result.log.sample_period_s
    considered = float(np.count_nonzero(mask)) * period
    after_warmup = max(result.log.duration_s + period - result.warmup_end_s, 0.0)
    per: dict[str, dict[str, Any]] = {}
    worst: dict[str, Any] = {}
    for d in DETECTORS:
        if d not in result.ratios:
            continue
        ratios = np.asarray(result.ratios[d], dtype=np.float64)
        per[d] = {}
        best: tuple[float, str, float] | None = None
        for j, name in enumerate(result.log.joint_names):
            r = np.where(mask & np.isfinite(ratios[:, j]), ratios[:, j], -np.inf)
            k = int(np.argmax(r)) if r.size else 0
            if r.size == 0 or not np.isfinite(r[k]):
                per[d][name] = {"max_ratio": None, "t_s": None, "headroom": None}
                continue
            m = float(r[k])
            per[d][name] = {
                "max_ratio": m,
                "t_s": float(t[k]),
                "headroom": (1.0 / m) if m > 0 else None,
            }
            if best is None or m > best[0]:
                best = (m, name, float(t[k]))
        worst[d] = (
            {"max_ratio": best[0], "joint": best[1], "t_s": best[2]}
            if best
            else {"max_ratio": None, "joint": None, "t_s": None}
        )
    return {
        "rule": {
            "after_warmup_s": result.warmup_end_s,
            "guard_s": guard_s,
            "excludes": "every detected event of any detector"
            + (" and every labelled contact" if labels is not None else "")
            + f", each widened by {guard_s} s on both sides",
            "considered_s": considered,
            "considered_fraction": considered / after_warmup if after_warmup > 0 else 0.0,
        },
        "per_detector": per,
        "worst": worst,
    }


