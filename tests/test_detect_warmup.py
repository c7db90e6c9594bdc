"""Warm-up end from the RLS prediction error."""

from __future__ import annotations

import numpy as np

from impactcli.config import WarmupConfig

from .reference.warmup import trailing_rms, warmup_end


def test_trailing_rms_direct() -> None:
    x = np.random.default_rng(0).standard_normal((50, 2))
    got = trailing_rms(x, 5)
    for k in (0, 3, 4, 30, 49):
        w = x[max(0, k - 4) : k + 1]
        np.testing.assert_allclose(got[k], np.sqrt(np.mean(w**2, axis=0)))


def test_warmup_waits_for_min_time_and_settling_with_cap() -> None:
    fs = 250.0
    t = np.arange(int(60 * fs)) / fs
    rng = np.random.default_rng(1)
    noise = 0.1 * rng.standard_normal((t.size, 3))
    e = noise.copy()
    e[:, 0] += 5.0 * np.exp(-t / 0.2)            # settles fast: min_s decides (3 s)
    e[:, 1] += np.where(t < 7.0, 2.0, 0.0)       # settles at 7 s (+ window)
    e[:, 2] += np.where(t < 40.0, 2.0, 0.0)      # settles at 40 s: capped at max_s = 20 s
    w = warmup_end(e, t, WarmupConfig(min_s=3.0, window_s=0.5, tolerance=0.5, max_s=20.0))
    assert w.index[0] == int(3 * fs)
    assert 7.0 <= t[w.index[1]] <= 7.5
    assert w.index[2] == int(20 * fs)
    assert w.end_index == int(20 * fs) and w.end_s == 20.0


def test_warmup_longer_than_log() -> None:
    t = np.arange(100) / 250.0
    w = warmup_end(np.ones((100, 1)), t, WarmupConfig(min_s=3.0))
    assert w.end_index == 100 and w.end_s == 100 / 250.0
