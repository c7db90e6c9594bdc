"""Table I's settings converted at a log's sample rate (docs/method.md §5b).

Model orders (eta, p, rho) stay in samples; the RMS windows N1, N2 are durations converted
at the log's rate (at least 1 sample); the cut-offs w1, w2 are clipped below 0.4 × fs with
an ImpactWarning. F1, F2 and the static-loading low-pass are first-order, unit DC gain,
discretised by matching the pole: ``a = exp(-2π f_c Ts)``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..config import AdaptiveConfig
from ..errors import ImpactWarning


@dataclass(frozen=True)
class Rates:
    """Table I's settings converted at a sample rate.

    Attributes:
        sample_rate_hz: sample rate [Hz].  n1, n2: RMS windows [samples].
        w1_hz, w2_hz: F1/F2 cut-offs after clipping [Hz].
        a1, a2: F1/F2 poles exp(-2π w Ts).
    """

    sample_rate_hz: float
    n1: int
    n2: int
    w1_hz: float
    w2_hz: float
    a1: float
    a2: float


def clip_cutoff(f_hz: float, sample_rate_hz: float, what: str) -> float:
    """Clip a cut-off below 0.4·fs with an ImpactWarning (docs/method.md §5b)."""
    lim = 0.4 * sample_rate_hz
    if f_hz > lim:
        warnings.warn(
            f"{what} cut-off {f_hz:g} Hz is above 0.4 × the sample rate {sample_rate_hz:g} Hz; "
            f"clipped to {lim:g} Hz", ImpactWarning, stacklevel=3,
        )
        return lim
    return float(f_hz)


def lowpass_pole(f_hz: float, sample_rate_hz: float) -> float:
    """Pole a = exp(-2π f Ts) of the unit-DC-gain first-order low-pass."""
    return float(np.exp(-2.0 * np.pi * f_hz / sample_rate_hz))


def resolve_rates(cfg: AdaptiveConfig, sample_rate_hz: float) -> Rates:
    """Convert durations and cut-offs of ``cfg`` at ``sample_rate_hz`` (docs/method.md §5b)."""
    n1 = max(1, round(cfg.n1_s * sample_rate_hz))
    n2 = max(1, round(cfg.n2_s * sample_rate_hz))
    w1 = clip_cutoff(cfg.w1_hz, sample_rate_hz, "F1 (w1)")
    w2 = clip_cutoff(cfg.w2_hz, sample_rate_hz, "F2 (w2)")
    return Rates(float(sample_rate_hz), n1, n2, w1, w2, lowpass_pole(w1, sample_rate_hz),
                 lowpass_pole(w2, sample_rate_hz))
