"""The two static detectors on a whole log (tests only): the formulas of
docs/method.md §5 written out, with the product's low-pass
(:func:`impactcli.detect.static.causal_lowpass`). The replay compares the same statistics
with their thresholds chunk by chunk (:mod:`impactcli.run.replay`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from impactcli.detect.static import causal_lowpass


@dataclass(frozen=True)
class StaticResult:
    """statistic (N, J) [N·m], threshold (J,) [N·m], decision (N, J) bool."""

    statistic: np.ndarray
    threshold: np.ndarray
    decision: np.ndarray

    @property
    def ratio(self) -> np.ndarray:
        """(N, J) statistic / threshold."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.threshold > 0, self.statistic / self.threshold, np.inf)


def static_loading(
    residual: np.ndarray, v_l: Sequence[float] | np.ndarray, sample_rate_hz: float,
    cutoff_hz: float = 2.0, order: int = 1,
) -> StaticResult:
    """|LP(r)| > vL per joint. residual (N, J) [N·m]; v_l (J,) [N·m]; fs [Hz]."""
    stat = np.abs(causal_lowpass(residual, cutoff_hz, sample_rate_hz, order))
    thr = np.asarray(v_l, dtype=np.float64)
    return StaticResult(stat, thr, stat > thr[None, :])


def static_baseline(residual: np.ndarray, v0: Sequence[float] | np.ndarray) -> StaticResult:
    """|r| > v0 per joint, no filter. residual (N, J) [N·m]; v0 (J,) [N·m]."""
    stat = np.abs(np.asarray(residual, dtype=np.float64))
    thr = np.asarray(v0, dtype=np.float64)
    return StaticResult(stat, thr, stat > thr[None, :])
