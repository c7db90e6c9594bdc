"""Derivative estimators: zero-phase accuracy, causal filter's exactness, causality, clipping."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.errors import ImpactWarning, ModelError
from impactcli.model import (
    causal_derivatives,
    causal_lowpass,
    zero_phase_derivatives,
    zero_phase_lowpass,
)

FS = 500.0
T = np.arange(5000) / FS


def sine(f: float, a: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    w = 2 * np.pi * f
    return a * np.sin(w * T), a * w * np.cos(w * T), -a * w * w * np.sin(w * T)


def test_zero_phase_derivatives_are_accurate_in_band() -> None:
    q, qd, qdd = sine(1.0)
    qf, d1, d2 = zero_phase_derivatives(T, q[:, None], 10.0)
    inner = slice(200, -200)
    assert np.max(np.abs(qf[inner, 0] - q[inner])) < 1e-5
    assert np.max(np.abs(d1[inner, 0] - qd[inner])) < 1e-3 * np.abs(qd).max()
    assert np.max(np.abs(d2[inner, 0] - qdd[inner])) < 1e-3 * np.abs(qdd).max()


def test_zero_phase_removes_noise_above_cutoff() -> None:
    q, _, _ = sine(1.0)
    noisy = q + 0.01 * np.sin(2 * np.pi * 60 * T)
    assert np.max(np.abs(zero_phase_lowpass(noisy, FS, 10.0)[100:-100] - q[100:-100])) < 1e-4


def test_causal_svf_outputs_are_the_derivatives_of_its_position() -> None:
    # G q, sG q and s²G q of the same filter: d/dt of the first is the second, etc.
    q, _, _ = sine(0.7, 0.5)
    qf, qd, qdd = causal_derivatives(1 / FS, q, 20.0)
    inner = slice(500, -5)
    np.testing.assert_allclose(np.gradient(qf, T)[inner], qd[inner], atol=2e-3 * np.abs(qd).max())
    np.testing.assert_allclose(np.gradient(qd, T)[inner], qdd[inner],
                               atol=5e-3 * np.abs(qdd).max())
    # and, in band, close to the truth with a small lag (2nd-order Butterworth at 20 Hz:
    # group delay about √2 / (2π·20) ≈ 11 ms)
    lag = round(np.sqrt(2) / (2 * np.pi * 20) * FS)
    w = 2 * np.pi * 0.7
    true_qd = 0.5 * w * np.cos(w * (T - lag / FS))
    assert np.max(np.abs(qd[500:] - true_qd[500:])) < 0.02 * 0.5 * w


def test_causal_filters_do_not_look_ahead() -> None:
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.normal(size=(1000, 2)), axis=0) * 1e-3
    y = x.copy()
    y[600:] += rng.normal(size=(400, 2))  # change only the future of sample 599
    filters = (lambda a: causal_derivatives(0.002, a, 25.0),
               lambda a: (causal_lowpass(a, 0.002, 25.0),))
    for f in filters:
        for u, v in zip(f(x), f(y), strict=True):
            np.testing.assert_array_equal(u[:600], v[:600])
            assert not np.allclose(u[600:], v[600:])


def test_causal_filter_starts_in_steady_state() -> None:
    x = np.full((100, 1), 3.0)
    qf, qd, qdd = causal_derivatives(0.004, x, 10.0)
    np.testing.assert_allclose(qf, 3.0, atol=1e-12)
    np.testing.assert_allclose(qd, 0.0, atol=1e-9)
    np.testing.assert_allclose(qdd, 0.0, atol=1e-6)
    np.testing.assert_allclose(causal_lowpass(x, 0.004, 10.0), 3.0, atol=1e-12)


def test_cutoff_above_0p4_fs_is_clipped_with_a_warning() -> None:
    q, _, _ = sine(1.0)
    with pytest.warns(ImpactWarning, match="clipped to 40 Hz"):
        causal_derivatives(0.01, q[:500], 50.0)
    with pytest.raises(ModelError, match="positive"):
        causal_lowpass(q, 0.002, 0.0)
