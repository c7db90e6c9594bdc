"""Static detectors: two distinct formulas (method.md §5)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from impactcli.detect.static import causal_lowpass
from impactcli.errors import ImpactWarning

from .reference.static import static_baseline, static_loading


def test_static_baseline_is_plain_abs_comparison() -> None:
    r = np.array([[0.1, -0.5], [-0.3, 0.2], [0.05, -0.25]])
    res = static_baseline(r, [0.2, 0.3])
    np.testing.assert_array_equal(res.statistic, np.abs(r))
    np.testing.assert_array_equal(res.decision, [[False, True], [True, False], [False, False]])
    np.testing.assert_allclose(res.ratio, np.abs(r) / [0.2, 0.3])


def test_static_loading_first_order_matches_lfilter_and_differs_from_baseline() -> None:
    fs, fc = 250.0, 2.0
    rng = np.random.default_rng(0)
    r = 0.2 + rng.standard_normal((3000, 2))
    a = np.exp(-2 * np.pi * fc / fs)
    zi = signal.lfilter_zi([1 - a], [1, -a])[:, None] * r[:1]
    expected = np.abs(signal.lfilter([1 - a], [1, -a], r, axis=0, zi=zi)[0])
    res = static_loading(r, [1.0, 1.0], fs, cutoff_hz=fc)
    np.testing.assert_allclose(res.statistic, expected, atol=1e-12)
    # the low-pass lowers the noise floor several-fold: baseline fires on noise, loading not
    assert static_baseline(r, [1.0, 1.0]).decision.mean() > 0.25
    assert not res.decision[500:].any()
    # a slow clamp (1 s ramp to 2 N·m) is seen by the loading detector
    r2 = r.copy()
    r2[1000:, 1] += np.minimum(np.arange(2000) / 250.0, 1.0) * 2.5
    assert static_loading(r2, [1.0, 1.0], fs).decision[1300:, 1].all()


def test_static_loading_second_order_unit_dc_gain_and_clipping() -> None:
    x = np.ones((500, 1)) * 3.0
    np.testing.assert_allclose(causal_lowpass(x, 2.0, 250.0, order=2), 3.0, atol=1e-9)
    np.testing.assert_allclose(causal_lowpass(x, 2.0, 250.0, order=1), 3.0, atol=1e-12)
    with pytest.warns(ImpactWarning, match="clipped"):
        causal_lowpass(x, 50.0, 100.0)
    with pytest.raises(ValueError, match="order"):
        causal_lowpass(x, 2.0, 250.0, order=3)
