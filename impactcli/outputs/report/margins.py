"""The false-alarm margin: how close each detector came to a false alarm (a maximum of the
run's per-sample ratios, the one quantity the report reduces itself):

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

from ...types import DETECTORS, DetectionResult, Labels
from .common import GUARD_S
from .samples import Samples


def _spans(result: DetectionResult, labels: Labels | None,
           guard_s: float) -> list[tuple[float, float]]:
    """Every event and labelled contact, widened by ``guard_s`` on both sides [s]."""
    spans = [(e.t_start, e.t_end) for e in result.events]
    if labels is not None:
        spans += [(c.start, c.end) for c in labels.events]
    return [(a - guard_s, b + guard_s) for a, b in spans]


def false_alarm_margins(
    result: DetectionResult, labels: Labels | None = None, guard_s: float = GUARD_S, *,
    samples: Samples,
) -> dict[str, Any]:
    """Per detector and joint, the largest statistic / threshold ratio on collision-free
    stretches (see the module docstring), its time [s] and the headroom 1 / ratio.

    ``samples``: where the per-sample ratios are read (:mod:`.samples`).

    Returns ``{"rule": {...}, "per_detector": {det: {joint: {...}}}, "worst": {det: {...}}}``;
    ``max_ratio`` is None when no collision-free sample remains.
    """
    n_free, maxima = samples.ratio_maxima(_spans(result, labels, guard_s),
                                          result.warmup_end_s)
    period = result.log.sample_period_s
    considered = float(n_free) * period
    after_warmup = max(result.log.duration_s + period - result.warmup_end_s, 0.0)
    per: dict[str, dict[str, Any]] = {}
    worst: dict[str, Any] = {}
    for d in DETECTORS:
        if d not in maxima:
            continue
        per[d] = {}
        best: tuple[float, str, float] | None = None
        for name, got in zip(result.log.joint_names, maxima[d], strict=True):
            if got is None:
                per[d][name] = {"max_ratio": None, "t_s": None, "headroom": None}
                continue
            m, t_m = got
            per[d][name] = {
                "max_ratio": m,
                "t_s": t_m,
                "headroom": (1.0 / m) if m > 0 else None,
            }
            if best is None or m > best[0]:
                best = (m, name, t_m)
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
            # a share: the two sums' rounding can put a whole log at 1 + 2e-16
            "considered_fraction": (min(1.0, considered / after_warmup) if after_warmup > 0
                                    else 0.0),
        },
        "per_detector": per,
        "worst": worst,
    }


