"""The few linear recursive filters of the causal replay, without importing ``scipy.signal``.

``import scipy.signal`` pulls in scipy.stats, scipy.optimize and scipy.interpolate (about
0.8 s of every run's start-up, docs/performance.md); the replay needs four of its functions
on tiny arrays and one loop. They are here, computing
the same floating-point operations in the same order as SciPy 1.17 (the version pinned
in requirements.lock), so the results are the same bits (``tests/test_iir.py`` compares
them with SciPy's on random designs and signals):

- :func:`butter_lowpass`: ``scipy.signal.butter(N, Wn)`` (low-pass, ``ba`` form): the
  analog prototype's poles ``-exp(jπm/2N)``, pre-warped cut-off ``4 tan(πWn/2)``, the
  bilinear transform of the poles and zeros and the product of the roots' factors
  (``iirfilter`` → ``buttap``, ``lp2lp_zpk``, ``bilinear_zpk``, ``zpk2tf``).
- :func:`bilinear`: ``scipy.signal.bilinear(b, a, fs)`` (``normalize`` included).
- :func:`lfilter_zi`: ``scipy.signal.lfilter_zi(b, a)``, the steady state of a unit step.
- :func:`lfilter`: ``scipy.signal.lfilter(b, a, x, axis=0, zi=zi)`` for float64 ``x``:
  the transposed direct form II, coefficients divided by ``a[0]`` once, each delay
  ``z[i] = z[i+1] + x·b[i+1] − y·a[i+1]`` evaluated left to right (compiled without
  fast-math: no reassociation, no fused multiply-add).

Adapted from SciPy (BSD-3-Clause, Copyright (c) 2001-2002 Enthought, Inc. 2003, SciPy
Developers). Zero-phase filtering (``sosfiltfilt``) is only used by identification, which
imports ``scipy.signal`` itself.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["bilinear", "butter_lowpass", "lfilter", "lfilter_zi"]


def _poly(roots: np.ndarray) -> np.ndarray:
    """``numpy.poly`` of 1-D roots (real when they come in conjugate pairs)."""
    a = np.ones((1,), dtype=roots.dtype)
    if roots.shape[0] == 0:
        return np.asarray(1.0, dtype=np.real(roots).dtype)
    one = np.ones_like(roots[0])
    for zero in roots:
        a = np.convolve(a, np.stack((one, -zero)), mode="full")
    if np.iscomplexobj(a):
        r = np.asarray(roots, dtype=np.complex128)
        if np.all(np.sort(np.imag(r)) == np.sort(np.imag(np.conj(r)))):
            a = np.asarray(np.real(a), copy=True)
    return a


def butter_lowpass(order: int, wn: float) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.butter(order, wn)``: a digital Butterworth low-pass (b, a).

    Args:
        order: N ≥ 1.  wn: the -3 dB cut-off as a fraction of Nyquist, 0 < wn < 1.
    """
    if int(order) != order or order < 1:
        raise ValueError(f"filter order must be a positive integer, got {order}")
    w = float(np.asarray(wn, dtype=np.float64))
    if not 0.0 < w < 1.0:
        raise ValueError(f"digital filter critical frequencies must be 0 < Wn < 1, got {wn}")
    n = int(order)
    z = np.asarray([], dtype=np.float64)  # buttap
    m = np.arange(-n + 1, n, 2, dtype=np.float64)
    p = -np.exp(1j * np.pi * m / (2 * n))
    k = 1.0
    fs = 2.0
    warped = 2 * fs * np.tan(np.pi * np.asarray(w, dtype=np.float64) / fs)
    wo = float(warped)  # lp2lp_zpk
    degree = p.shape[0] - z.shape[0]
    z, p, k = wo * z, wo * p, k * wo**degree
    fs2 = 2.0 * fs  # bilinear_zpk
    z_z = (fs2 + z) / (fs2 - z)
    p_z = (fs2 + p) / (fs2 - p)
    z_z = np.concatenate((z_z, -np.ones(degree)))
    k_z = k * np.real(np.prod(fs2 - z) / np.prod(fs2 - p))
    kk = np.asarray(k_z, dtype=np.result_type(np.real(z_z), np.real(p_z), k_z))  # zpk2tf
    b = np.multiply(np.atleast_1d(kk), _poly(np.atleast_1d(z_z)))
    a = np.atleast_1d(np.asarray(_poly(p_z)))
    return b, a


def _normalize(b: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.normalize`` of a 1-D numerator."""
    den = np.atleast_1d(np.asarray(a))
    num = np.atleast_2d(np.asarray(b))
    if np.all(den == 0):
        raise ValueError("Denominator must have at least on nonzero element.")
    first = 0
    for v in den:
        if v != 0.0:
            break
        first += 1
    den = den[first:]
    num, den = num / den[0], den / den[0]
    lead = 0
    for j in range(num.shape[-1]):
        if np.all(np.abs(num[:, j]) <= 1e-14):
            lead += 1
        else:
            break
    if lead:
        if lead == num.shape[1]:
            lead -= 1
        num = num[:, lead:]
    return (num[0, :] if num.shape[0] == 1 else num), den


def bilinear(b: np.ndarray, a: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.bilinear(b, a, fs)``: the digital (b, a) of an analog transfer
    function by the bilinear transform (no pre-warping)."""
    b, a = np.atleast_1d(np.asarray(b)), np.atleast_1d(np.asarray(a))
    b, a = np.trim_zeros(b, "f"), np.trim_zeros(a, "f")
    fs = float(fs)
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"sampling frequency must be positive, got {fs}")
    fac = np.sqrt(fs * 2)
    zp1 = np.polynomial.Polynomial((+1, 1)) / fac
    zm1 = np.polynomial.Polynomial((-1, 1)) * fac
    n = max(len(a), len(b)) - 1
    numerator = sum(b_ * zp1**(n - q) * zm1**q for q, b_ in enumerate(b[::-1]))
    denominator = sum(a_ * zp1**(n - p) * zm1**p for p, a_ in enumerate(a[::-1]))
    return _normalize(numerator.coef[::-1].copy(), denominator.coef[::-1].copy())


def _padded(b: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """b and a as float64 of the same length, leading zeros of a removed."""
    b = np.atleast_1d(np.asarray(b, dtype=np.float64))
    a = np.atleast_1d(np.asarray(a, dtype=np.float64))
    while a.shape[0] > 1 and a[0] == 0.0:
        a = a[1:]
    if a.shape[0] < 1 or a[0] == 0.0:
        raise ValueError("There must be at least one nonzero `a` coefficient.")
    n = max(a.shape[0], b.shape[0])
    return (np.concatenate((b, np.zeros(n - b.shape[0]))),
            np.concatenate((a, np.zeros(n - a.shape[0]))))


def lfilter_zi(b: np.ndarray, a: np.ndarray) -> np.ndarray:
    """``scipy.signal.lfilter_zi(b, a)``: (order,) the delays of a unit step's steady
    state (multiply by the first sample to start a filter in steady state)."""
    b = np.atleast_1d(np.asarray(b, dtype=np.float64))
    a = np.atleast_1d(np.asarray(a, dtype=np.float64))
    while a.shape[0] > 1 and a[0] == 0.0:
        a = a[1:]
    if a.shape[0] < 1:
        raise ValueError("There must be at least one nonzero `a` coefficient.")
    if a[0] != 1.0:
        b = b / a[0]
        a = a / a[0]
    n = max(a.shape[0], b.shape[0])
    if a.shape[0] < n:
        a = np.concatenate((a, np.zeros(n - a.shape[0])))
    elif b.shape[0] < n:
        b = np.concatenate((b, np.zeros(n - b.shape[0])))
    comp = np.zeros((n - 1, n - 1), dtype=np.result_type(a))  # scipy.linalg.companion(a)
    if n > 1:
        comp[0] = -a[1:] / (1.0 * a[0])
        comp[list(range(1, n - 1)), list(range(0, n - 2))] = 1
    i_minus_a = np.eye(n - 1) - comp.T
    return np.linalg.solve(i_minus_a, b[1:] - a[1:] * b[0])


@nb.njit(cache=True, nogil=True)
def _df2t(b: np.ndarray, a: np.ndarray, x: np.ndarray, z: np.ndarray, y: np.ndarray) -> None:
    """y (n, C) = x (n, C) filtered column by column; z (order, C) the delays, updated."""
    n, c = x.shape
    nb_ = b.shape[0]
    for k in range(n):  # row by row (the columns are independent): memory order
        for col in range(c):
            xn = x[k, col]
            if nb_ > 1:
                yn = z[0, col] + b[0] * xn
                for i in range(nb_ - 2):
                    z[i, col] = z[i + 1, col] + xn * b[i + 1] - yn * a[i + 1]
                z[nb_ - 2, col] = xn * b[nb_ - 1] - yn * a[nb_ - 1]
            else:
                yn = xn * b[0]
            y[k, col] = yn


@nb.njit(cache=True, nogil=True)
def _df2t_1(b: np.ndarray, a: np.ndarray, x: np.ndarray, z: np.ndarray, y: np.ndarray
            ) -> None:
    """:func:`_df2t` of a first-order filter: the same operations, the coefficients and
    the delays held apart from ``y`` (so the compiler need not reload them)."""
    n, c = x.shape
    b0, b1, a1 = b[0], b[1], a[1]
    z0 = z[0].copy()
    for k in range(n):
        for col in range(c):
            xn = x[k, col]
            yn = z0[col] + b0 * xn
            z0[col] = xn * b1 - yn * a1
            y[k, col] = yn
    z[0] = z0


@nb.njit(cache=True, nogil=True)
def _df2t_2(b: np.ndarray, a: np.ndarray, x: np.ndarray, z: np.ndarray, y: np.ndarray
            ) -> None:
    """:func:`_df2t` of a second-order filter, as :func:`_df2t_1`."""
    n, c = x.shape
    b0, b1, b2, a1, a2 = b[0], b[1], b[2], a[1], a[2]
    z0, z1 = z[0].copy(), z[1].copy()
    for k in range(n):
        for col in range(c):
            xn = x[k, col]
            yn = z0[col] + b0 * xn
            z0[col] = z1[col] + xn * b1 - yn * a1
            z1[col] = xn * b2 - yn * a2
            y[k, col] = yn
    z[0], z[1] = z0, z1


@nb.njit(cache=True, nogil=True)
def _df2t_3(b: np.ndarray, a: np.ndarray, x: np.ndarray, z: np.ndarray, y: np.ndarray
            ) -> None:
    """:func:`_df2t` of a third-order filter, as :func:`_df2t_1`."""
    n, c = x.shape
    b0, b1, b2, b3, a1, a2, a3 = b[0], b[1], b[2], b[3], a[1], a[2], a[3]
    z0, z1, z2 = z[0].copy(), z[1].copy(), z[2].copy()
    for k in range(n):
        for col in range(c):
            xn = x[k, col]
            yn = z0[col] + b0 * xn
            z0[col] = z1[col] + xn * b1 - yn * a1
            z1[col] = z2[col] + xn * b2 - yn * a2
            z2[col] = xn * b3 - yn * a3
            y[k, col] = yn
    z[0], z[1], z[2] = z0, z1, z2


#: The kernel of each order, the general one for the others (3-5× faster on 7-21 columns).
_BY_ORDER = {1: _df2t_1, 2: _df2t_2, 3: _df2t_3}


def lfilter(b: np.ndarray, a: np.ndarray, x: np.ndarray,
            zi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.lfilter(b, a, x, axis=0, zi=zi)`` for real ``x``.

    Args:
        b, a: the filter's coefficients (a[0] ≠ 0, len(a) ≥ 2).
        x: (n, ...) the signal, filtered along its first axis.
        zi: (order, ...) the initial delays (order = max(len(a), len(b)) − 1).
    Returns:
        (y (n, ...) float64, zf (order, ...) the final delays).
    """
    if np.atleast_1d(np.asarray(a)).shape[0] < 2:
        raise ValueError("lfilter: a recursive filter (len(a) >= 2) expected; SciPy "
                         "filters FIR ones by convolution")
    bb, aa = _padded(b, a)
    a0 = aa[0]
    bb, aa = bb / a0, aa / a0
    xx = np.asarray(x, dtype=np.float64)
    order = bb.shape[0] - 1
    shape = xx.shape
    cols = int(np.prod(shape[1:], dtype=np.int64))
    x2 = np.ascontiguousarray(xx.reshape(shape[0], cols))
    zz = np.asarray(zi, dtype=np.float64)
    if zz.shape != (order, *shape[1:]):
        raise ValueError(f"zi must have shape {(order, *shape[1:])}, got {zz.shape}")
    z = np.array(zz.reshape(order, cols))
    y = np.empty_like(x2)
    _BY_ORDER.get(order, _df2t)(bb, aa, x2, z, y)
    return y.reshape(shape), z.reshape((order, *shape[1:]))
