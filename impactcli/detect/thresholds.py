"""The decision: each detector's statistic against its threshold (eq. 42 for the adaptive
detector; |LP(r)| > vL and |r| > v0 for the static ones), for a whole log or a chunk of it.

The ratio statistic / threshold is what events report as their peak and what a threshold
sweep rescales (the decision at scale s is ``ratio > s``); it is computed here once, by one
expression, for every consumer. Pure array functions.
"""

from __future__ import annotations

import numpy as np


def detector_ratios(r_rms: np.ndarray, threshold_adaptive: np.ndarray, loading: np.ndarray,
                    baseline: np.ndarray, v_loading: np.ndarray | float,
                    v_baseline: np.ndarray | float) -> dict[str, np.ndarray]:
    """Each detector's statistic over its threshold: adaptive r_rms / |v_stat + v_rms|
    (eq. 42; inf where that threshold is 0), static_loading |LP(r)| / vL, static_baseline
    |r| / v0.

    Args:
        r_rms, threshold_adaptive, loading, baseline: (n, J) residual RMS, adaptive
            threshold, loading statistic and |r| [N·m] (or a joint's (n,) columns).
        v_loading, v_baseline: vL and v0 [N·m], broadcast against them ((1, J), or a
            joint's scalars).
    Returns:
        detector → ratio, shaped as the statistics.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return {"adaptive": np.where(threshold_adaptive > 0, r_rms / threshold_adaptive, np.inf),
                "static_loading": loading / v_loading,
                "static_baseline": baseline / v_baseline}


def compare_to_thresholds(
    thr: dict[str, np.ndarray], r_rms: np.ndarray, v_rms: np.ndarray, loading: np.ndarray,
    baseline: np.ndarray,
) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The thresholds applied to a replay's statistics.

    Args:
        thr: detector → (J,) threshold (v_stat, vL, v0) [N·m].
        r_rms, v_rms: (n, J) the adaptive evaluator's residual RMS and its dynamic part of
            the threshold; loading: (n, J) |LP(r)|; baseline: (n, J) |r| [N·m].
    Returns:
        ((n, J) adaptive threshold |v_stat + v_rms|, detector → (n, J) ratio
        (:func:`detector_ratios`), detector → (n, J) decision: statistic above threshold).
    """
    thr_ad = np.abs(thr["adaptive"][None, :] + v_rms)
    v_l, v_0 = thr["static_loading"][None, :], thr["static_baseline"][None, :]
    ratios = detector_ratios(r_rms, thr_ad, loading, baseline, v_l, v_0)
    decisions = {"adaptive": np.greater(r_rms, thr_ad), "static_loading": np.greater(loading, v_l),
                 "static_baseline": np.greater(baseline, v_0)}
    return thr_ad, ratios, decisions
