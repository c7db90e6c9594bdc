"""Velocities and accelerations from encoder positions (docs/method.md §1, §5b, §8).

Two estimators, for two purposes:

* :func:`zero_phase_derivatives` — identification only (offline): a Butterworth low-pass
  run forwards and backwards (``filtfilt``, no phase lag) on the positions, then central
  differences (``numpy.gradient``) for q' and q''. The torque used in the fit passes through
  the very same zero-phase filter (:func:`zero_phase_lowpass`), so tau and
  Y(q, q', q'') theta see the same smoothing.
* :func:`causal_derivatives` — detection (online-equivalent): a second-order Butterworth
  *state-variable filter* G(s) = w² / (s² + √2 w s + w²) whose three outputs are the
  filtered position G q, velocity s G q and acceleration s² G q — no look-ahead, one
  filter, consistent signals. Discretised by the bilinear transform prewarped at the
  cut-off. :func:`causal_lowpass` is the same G(s), for passing the measured torque through
  the filter the model estimate sees (docs/method.md §8: r = tau_hat − G tau, eq. 7–8).

Cut-offs are in Hz and are clipped below 0.4 × the sample rate with an ImpactWarning
(docs/method.md §5b). Defaults (in the option classes) suit 100 Hz – 1 kHz logs.
Filters start in steady state at the first sample (no start-up transient).
"""

from __future__ import annotations

import functools
import warnings

import numpy as np

from ..errors import ImpactWarning, ModelError
from .causal import Carry
from .iir import bilinear

#: Largest cut-off allowed, as a fraction of the sample rate (docs/method.md §5b).
MAX_CUTOFF_FRACTION = 0.4


def clip_cutoff(cutoff_hz: float, sample_rate_hz: float, what: str = "cut-off") -> float:
    """Return ``cutoff_hz`` clipped below 0.4 × ``sample_rate_hz`` (warns when it clips).

    Raises ModelError if the cut-off is not positive.
    """
    if not (cutoff_hz > 0 and np.isfinite(cutoff_hz)):
        raise ModelError(f"{what} must be a positive frequency in Hz, got {cutoff_hz!r}")
    limit = MAX_CUTOFF_FRACTION * sample_rate_hz
    if cutoff_hz > limit:
        warnings.warn(
            f"{what} {cutoff_hz:g} Hz is above 0.4 × the sample rate ({sample_rate_hz:g} Hz); "
            f"clipped to {limit:g} Hz", ImpactWarning, stacklevel=3,
        )
        return float(limit)
    return float(cutoff_hz)


def _as_2d(x: np.ndarray) -> tuple[np.ndarray, bool]:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 1:
        return a[:, None], True
    if a.ndim != 2:
        raise ModelError(f"expected an (N,) or (N, J) array, got shape {a.shape}")
    return a, False


def zero_phase_lowpass(x: np.ndarray, sample_rate_hz: float, cutoff_hz: float,
                       order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass (``filtfilt``) along axis 0.

    Args:
        x: (N,) or (N, J) signal (any unit; returned in the same unit and shape).
        sample_rate_hz: sample rate [Hz].
        cutoff_hz: -3 dB cut-off of the one-way filter [Hz] (clipped below 0.4 fs).
        order: Butterworth order of the one-way filter (the magnitude is squared).
    """
    a2, flat = _as_2d(x)
    wc = clip_cutoff(cutoff_hz, sample_rate_hz, "identification cut-off")
    from scipy import signal  # identification only (1.5 s to import)

    sos = signal.butter(order, wc, fs=sample_rate_hz, output="sos")
    n = a2.shape[0]
    padlen = min(n - 1, 4 * 3 * (2 * len(sos) + 1))  # 4× scipy's default: calmer edges
    y = np.asarray(signal.sosfiltfilt(sos, a2, axis=0, padtype="odd", padlen=padlen))
    return y[:, 0] if flat else y


def zero_phase_derivatives(
    t_s: np.ndarray, q: np.ndarray, cutoff_hz: float, order: int = 4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Filtered position, velocity and acceleration without phase lag (identification only).

    Args:
        t_s: (N,) sample times [s] (need not be uniform; the filter uses the median rate).
        q: (N, J) positions [rad].
        cutoff_hz: cut-off of the zero-phase Butterworth [Hz].
        order: Butterworth order (one way).

    Returns:
        q_f (N, J) [rad], qd (N, J) [rad/s], qdd (N, J) [rad/s²].
    """
    t = np.asarray(t_s, dtype=np.float64)
    q2, flat = _as_2d(q)
    if t.shape[0] != q2.shape[0] or t.shape[0] < 3:
        raise ModelError(
            f"need matching times and positions with >= 3 samples, got {t.shape}, {q2.shape}"
        )
    sample_rate_hz = 1.0 / float(np.median(np.diff(t)))
    qf = zero_phase_lowpass(q2, sample_rate_hz, cutoff_hz, order)
    qd = np.gradient(qf, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    if flat:
        return qf[:, 0], qd[:, 0], qdd[:, 0]
    return qf, qd, qdd


def svf_coefficients(dt: float, cutoff_hz: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Discrete (b, a) of G, sG, s²G for the 2nd-order Butterworth state-variable filter
    (the cut-off clipped, and warned about, on every call; the design cached)."""
    sample_rate_hz = 1.0 / dt
    wc = clip_cutoff(cutoff_hz, sample_rate_hz, "derivative cut-off")
    return list(_svf_design(sample_rate_hz, wc))


@functools.lru_cache(maxsize=64)
def _svf_design(sample_rate_hz: float, wc: float) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """:func:`svf_coefficients` for a clipped cut-off: a bilinear design costs ~2 ms and a
    streamed replay asks for it several times per chunk (read-only arrays: shared)."""
    w = 2.0 * sample_rate_hz * np.tan(np.pi * wc / sample_rate_hz)  # prewarped [rad/s]
    den = np.array([1.0, np.sqrt(2.0) * w, w * w])
    nums = [np.array([0.0, 0.0, w * w]), np.array([0.0, w * w, 0.0]), np.array([w * w, 0.0, 0.0])]
    out = []
    for num in nums:
        b, a = bilinear(num, den, sample_rate_hz)
        b, a = np.array(b, dtype=np.float64), np.array(a, dtype=np.float64)
        b.setflags(write=False)
        a.setflags(write=False)
        out.append((b, a))
    return tuple(out)


def _lfilter_steady(b: np.ndarray, a: np.ndarray, x: np.ndarray,
                    carry: Carry | None = None, name: str = "x") -> np.ndarray:
    """``lfilter`` along time started in steady state on x(0), continued from ``carry``
    (:mod:`impactcli.model.causal`) when given."""
    return (carry if carry is not None else Carry()).lfilter(name, b, a, x, "steady")


def causal_derivatives(
    dt: float, q: np.ndarray, cutoff_hz: float, carry: Carry | None = None, name: str = "q",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Causal filtered position, velocity and acceleration (detection).

    The three outputs of one state-variable filter G(s) = w²/(s² + √2 w s + w²): G q, s G q,
    s² G q (bilinear transform prewarped at the cut-off). Sample k uses samples 0..k only.

    Args:
        dt: sample period [s] (the log's median period).
        q: (N, J) or (N,) positions [rad].
        cutoff_hz: filter cut-off [Hz] (clipped below 0.4 / dt).
        carry: the filters' state from the previous chunk (:mod:`impactcli.model.causal`), or
            None for a whole log; ``name`` keys it.

    Returns:
        q_f [rad], qd [rad/s], qdd [rad/s²], each shaped like ``q``.
    """
    if not dt > 0:
        raise ModelError(f"sample period must be positive, got {dt!r}")
    q2, flat = _as_2d(q)
    (b0, a0), (b1, a1), (b2, a2) = svf_coefficients(dt, cutoff_hz)
    qf = _lfilter_steady(b0, a0, q2, carry, f"{name}.G")
    qd = _lfilter_steady(b1, a1, q2, carry, f"{name}.sG")
    qdd = _lfilter_steady(b2, a2, q2, carry, f"{name}.s2G")
    if flat:
        return qf[:, 0], qd[:, 0], qdd[:, 0]
    return qf, qd, qdd


def causal_lowpass(x: np.ndarray, dt: float, cutoff_hz: float, carry: Carry | None = None,
                   name: str = "x") -> np.ndarray:
    """The causal G(s) of :func:`causal_derivatives` applied to ``x`` (e.g. measured torque).

    Args:
        x: (N,) or (N, J) signal (unit kept).
        dt: sample period [s].
        cutoff_hz: cut-off [Hz] (clipped below 0.4 / dt).
        carry, name: as :func:`causal_derivatives`.
    """
    if not dt > 0:
        raise ModelError(f"sample period must be positive, got {dt!r}")
    x2, flat = _as_2d(x)
    b, a = svf_coefficients(dt, cutoff_hz)[0]
    y = _lfilter_steady(b, a, x2, carry, f"{name}.G")
    return y[:, 0] if flat else y


def first_order_lowpass(x: np.ndarray, dt: float, gain: float, carry: Carry | None = None,
                        name: str = "x") -> np.ndarray:
    """Causal first-order low-pass gain/(s + gain), discretised like the momentum observer.

    Args:
        x: (N, J) signal; dt: sample period [s]; gain: pole [1/s].
        carry, name: as :func:`causal_derivatives`.
    """
    x2, flat = _as_2d(x)
    alpha = gain * dt
    b = np.array([0.0, alpha])  # y(k) = (1 - alpha) y(k-1) + alpha x(k-1), alpha = gain dt
    a = np.array([1.0, alpha - 1.0])
    y = _lfilter_steady(b, a, x2, carry, f"{name}.lag")
    return y[:, 0] if flat else y
