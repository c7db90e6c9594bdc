"""Threshold calibration rules (method.md §5b)."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.detect.calibrate import (
    adaptive_statistic,
    calibrate_thresholds,
    leave_one_out_margins,
    uncalibrated_thresholds,
)
from impactcli.errors import ImpactWarning


def _stat(maxima: list[float], n: int = 100, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    s = rng.uniform(0, 1, (n, len(maxima))) * np.array(maxima) * 0.9
    s[n // 2] = maxima
    return s


def test_leave_one_out_is_the_smallest_margin_keeping_every_left_out_log_silent() -> None:
    logs = [_stat([1.0, 2.0], seed=0), _stat([1.5, 2.2], seed=1), _stat([1.2, 1.0], seed=2)]
    cal = calibrate_thresholds(logs)
    assert cal.rule == "leave-one-out" and not cal.weak
    np.testing.assert_allclose(cal.margins, [1.5 / 1.2, 1.1])
    np.testing.assert_allclose(cal.thresholds, [1.5 * 1.25, 2.2 * 1.1])
    # silent property: every log left out stays under margin × max of the others …
    m = cal.maxima
    for j in range(2):
        for lo in range(3):
            assert m[lo, j] <= cal.margins[j] * np.delete(m[:, j], lo).max() * (1 + 1e-12)
        # … and a smaller margin would not be enough
        smaller = cal.margins[j] * 0.99
        assert any(m[lo, j] > smaller * np.delete(m[:, j], lo).max() for lo in range(3))


def test_margin_floor_and_cap() -> None:
    same = [_stat([1.0]), _stat([1.0], seed=3)]
    cal = calibrate_thresholds(same)
    np.testing.assert_allclose(cal.margins, [1.05])               # floor
    with pytest.warns(ImpactWarning, match="capped"):
        cal = calibrate_thresholds([_stat([1.0]), _stat([5.0])])
    assert cal.weak and cal.margins[0] == 3.0
    np.testing.assert_allclose(cal.thresholds, [15.0])
    np.testing.assert_allclose(leave_one_out_margins(np.array([[0.0], [1.0]])), [np.inf])


def test_single_log_and_negative_statistics() -> None:
    cal = calibrate_thresholds([_stat([2.0, 0.5])])
    assert cal.rule == "fixed-single-log" and cal.weak
    np.testing.assert_allclose(cal.thresholds, [3.0, 0.75])
    # adaptive statistic r_rms − v_rms that never rose above 0 → tiny positive threshold
    st = adaptive_statistic(np.full((10, 1), 0.1), np.full((10, 1), 0.3))
    cal = calibrate_thresholds([st, st])
    assert 0 < cal.thresholds[0] < 1e-3


def test_uncalibrated_rule_ignores_a_short_contact() -> None:
    rng = np.random.default_rng(5)
    s = np.abs(rng.standard_normal((20_000, 1)))
    s[1000:1050] += 20.0                                         # 0.25 % of samples
    cal = uncalibrated_thresholds(s)
    q = np.quantile(np.abs(rng.standard_normal(1_000_000)), 0.995)
    assert cal.rule == "uncalibrated-quantile"
    assert cal.thresholds[0] == pytest.approx(1.5 * q, rel=0.1)
    assert cal.thresholds[0] < 20.0
