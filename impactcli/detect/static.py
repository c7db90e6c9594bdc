"""The low-pass of the static-loading detector (docs/method.md §5).

The two static detectors are two distinct formulas: ``static_baseline`` (paper Table II's
comparison) ``d_j(k) = |r_j(k)| > v0_j`` on the residual itself, no filter, and
``static_loading`` (paper Fig. 10: slow quasi-static contact, clamping, to which the
high-pass G(z) is blind) ``d_j(k) = |LP(r_j)(k)| > vL_j``. LP is :func:`causal_lowpass`:
unit DC gain, started at rest on r(0) (no start transient); order 1
``y(k) = a y(k-1) + (1 − a) r(k)``, ``a = exp(−2π f_c Ts)``, or order 2 Butterworth
(bilinear). Default f_c = 2 Hz, a deliberate deviation from the paper's plain comparison:
slow contacts are slow, and the low-pass lowers the noise floor several-fold. The cut-off
is clipped below 0.4 fs with an ImpactWarning.

The replay (:mod:`impactcli.run.replay`) compares both statistics with their thresholds chunk
by chunk; the whole-log forms the tests check the formulas with are in
``tests/reference/static.py``.
"""

from __future__ import annotations

import numpy as np

from ..model.causal import Carry
from ..model.iir import butter_lowpass
from .rates import clip_cutoff, lowpass_pole


def causal_lowpass(x: np.ndarray, cutoff_hz: float, sample_rate_hz: float, order: int = 1,
                   carry: Carry | None = None) -> np.ndarray:
    """Causal unit-DC-gain low-pass of (N, J) ``x`` along time, started at rest on x(0)
    (steady state on the first sample), continued from ``carry`` (:mod:`impactcli.model.causal`)
    when ``x`` is a chunk after the first."""
    x = np.asarray(x, dtype=np.float64)
    fc = clip_cutoff(cutoff_hz, sample_rate_hz, "static-loading low-pass")
    if order == 1:
        a = lowpass_pole(fc, sample_rate_hz)
        b_, a_ = np.array([1.0 - a]), np.array([1.0, -a])
    elif order == 2:
        b_, a_ = butter_lowpass(2, fc / (0.5 * sample_rate_hz))
    else:
        raise ValueError(f"static-loading low-pass order must be 1 or 2, got {order}")
    return (carry if carry is not None else Carry()).lfilter("loading", b_, a_, x, "steady")
