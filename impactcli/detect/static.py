"""The two static detectors — two distinct formulas (method.md §5).

- ``static_baseline`` (paper Table II's comparison): ``d_j(k) = |r_j(k)| > v0_j`` on the
  residual itself, no filter.
- ``static_loading`` (paper Fig. 10, slow quasi-static contact / clamping, to which the
  high-pass G(z) is blind): ``d_j(k) = |LP(r_j)(k)| > vL_j`` with LP a causal low-pass of
  unit DC gain, from rest at r(0) (no start transient). Order 1: ``y(k) = a y(k-1) +
  (1 − a) r(k)``, ``a = exp(−2π f_c Ts)``; order 2: Butterworth (bilinear, scipy
  ``butter``). Default f_c = 2 Hz: a deliberate deviation from the paper's plain
  comparison — slow contacts are slow, and the low-pass lowers the noise floor
  several-fold. The cut-off is clipped below 0.4 fs with an ImpactWarning.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..causal import Carry
from ..iir import butter_lowpass
from .adaptive import clip_cutoff, lowpass_pole


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


def causal_lowpass(x: np.ndarray, cutoff_hz: float, fs_hz: float, order: int = 1,
                   carry: Carry | None = None) -> np.ndarray:
    """Causal unit-DC-gain low-pass of (N, J) ``x`` along time, started at rest on x(0)
    (steady state on the first sample), continued from ``carry`` (:mod:`impactcli.causal`)
    when ``x`` is a chunk after the first."""
    x = np.asarray(x, dtype=np.float64)
    fc = clip_cutoff(cutoff_hz, fs_hz, "static-loading low-pass")
    if order == 1:
        a = lowpass_pole(fc, fs_hz)
        b_, a_ = np.array([1.0 - a]), np.array([1.0, -a])
    elif order == 2:
        b_, a_ = butter_lowpass(2, fc / (0.5 * fs_hz))
    else:
        raise ValueError(f"static-loading low-pass order must be 1 or 2, got {order}")
    return (carry if carry is not None else Carry()).lfilter("loading", b_, a_, x, "steady")


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
