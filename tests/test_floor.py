"""The detection floor's quantiles per link (impactcli.detect.floor): a link ending on its own
joint's axis takes its floor from the joints before it; a joint alarming for most of the
log (its median none) must not lower the link's worst tenth below its median."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.detect.floor import FloorAccumulator

from .helpers import motion_residual


def _jac(q: np.ndarray, i: int) -> np.ndarray:
    """Constant link-end Jacobians: joints a and b turn every link; link 3 ends on joint c's
    axis (no lever)."""
    cols = {1: [[0.0], [0.4]], 2: [[0.0, 0.0], [0.8, 0.4]],
            3: [[0.0, 0.0, 0.0], [0.9, 0.5, 0.0]]}
    return np.array(cols[i])


def test_a_joint_alarming_most_of_the_log_does_not_lower_a_links_worst_tenth() -> None:
    """Known truth: joint a's margin is 1 N·m throughout; joint b alarms 60 % of the time
    (margin 0: its median is none, its worst tenth 0.1 N·m). Link 3 ends on joint c's axis,
    so the joints before it give its floor: over a alone its median is 1 / 0.9 N. With b
    counted at the worst tenth only, that quantile read 0.1 / 0.5 = 0.2 N, below the
    median (a new user's trial on the real UR arm: 3.0 N worst tenth against an 8.9 N
    median). Now b gives link 3 no floor at either quantile."""
    n = 2000
    vl = np.array([2.0, 2.0, 2.0])
    loading = np.empty((n, 3))
    loading[:, 0] = vl[0] - 1.0
    loading[:, 1] = np.where(np.arange(n) % 10 < 6, vl[1], vl[1] - 0.1)
    loading[:, 2] = vl[2] - 0.5
    acc = FloorAccumulator(3, n, 10, vl)
    acc.update(loading, np.zeros((n, 3)), np.ones((n, 3)), np.zeros((n, 3)), np.ones(3))
    floor = acc.finish(np.zeros(3, dtype=int), 0, ("a", "b", "c"), ("a", "b", "c"),
                       [1, 2, 3], [0, 1, 2], _jac)
    b = floor["per_joint"]["b"]["static_loading"]
    assert b["median_nm"] is None and b["in_alarm"] > 0.5
    assert b["worst_tenth_nm"] is not None and b["worst_tenth_nm"] < 0.11
    link3 = floor["per_link"][2]["static_loading"]
    assert link3["median_n"] is not None and link3["worst_tenth_n"] is not None
    assert link3["worst_tenth_n"] >= link3["median_n"]
    assert abs(link3["median_n"] - 1.0 / 0.9) < 0.06 * (1.0 / 0.9)  # bins 5 % below


def test_pulse_gain_of_many_g_hats_is_each_ones_response() -> None:
    """The vectorised gain (F1 of G x as F1 x minus its delays) against the response
    computed sample by sample — G applied to the half-sine, then F1, then the RMS window —
    for random G_hat's of degree 2 and 3, at 250 and 1000 Hz."""
    from impactcli.detect.floor import pulse_gain

    rng = np.random.default_rng(3)
    for fs, a1, n1, eta in ((250.0, 0.9, 25, 2), (1000.0, 0.97, 100, 3)):
        th = rng.normal(0.0, 0.6, (4, 5, eta))
        got = pulse_gain(th, fs, a1, n1)
        assert got.shape == (4, 5)
        m = round(0.1 * fs)
        n = m + n1 + round(5.0 / (1.0 - a1)) + 1
        x = np.zeros(n)
        x[:m] = np.sin(np.pi * (np.arange(m) + 0.5) / m)
        for idx in np.ndindex(4, 5):
            g = x.copy()
            for d, c in enumerate(th[idx], start=1):
                g[d:] -= c * x[:-d]
            y, prev = np.empty(n), 0.0
            for k in range(n):
                prev = a1 * prev + (1.0 - a1) * g[k]
                y[k] = prev
            win = [np.sum(y[k - n1:k] ** 2) for k in range(n1, n)]
            assert got[idx] == pytest.approx(np.sqrt(max(win) / n1), rel=1e-9)


def test_each_sample_takes_the_gain_of_g_hat_as_it_stood() -> None:
    """Snapshots of G_hat at the log's samples 0, 16, 32, …: a chunk starting at sample 10
    has them at its samples 6, 22, …; its samples 0–5 take the previous chunk's gain, each
    later one the snapshot at or before it."""
    from impactcli.detect.floor import GAIN_EVERY, gain_per_sample, pulse_gain

    assert GAIN_EVERY == 16
    th = np.array([[[0.0, 0.0]], [[1.0, 0.0]], [[0.5, 0.2]]])  # (S=3, J=1, eta=2)
    g = pulse_gain(th[:, 0, :], 500.0, 0.9, 25).astype(np.float32).tolist()  # kept as float32
    out = gain_per_sample(th, 39, 10, 500.0, 0.9, 25, before=np.array([7.0]))
    assert out.dtype == np.float32
    assert out[:, 0].tolist() == [7.0] * 6 + [g[0]] * 16 + [g[1]] * 16 + [g[2]]
    assert gain_per_sample(th[:0], 3, 1, 500.0, 0.9, 25, np.array([2.0]))[:, 0].tolist() \
        == [2.0, 2.0, 2.0]


def test_the_blows_floor_follows_g_hat_along_the_log() -> None:
    """Known truth: the adaptive threshold stands 0.4 above r_rms throughout; G_hat passes
    a blow at 0.2 for the first 70 % of the log (the arm moving) and 1.0 for the rest (at
    rest, as the log ends). The blow's floor is 0.4 / 0.2 = 2 N·m at the median and worst
    tenth, not the 0.4 N·m the log's last G_hat gives; the median gain is stated."""
    n = 10_000
    acc = FloorAccumulator(1, n, 10, np.array([1.0]))
    gain = np.where(np.arange(n) < 0.7 * n, 0.2, 1.0)[:, None]
    for a in range(0, n, 3000):
        sl = slice(a, a + 3000)
        acc.update(np.zeros((gain[sl].shape[0], 1)), np.full_like(gain[sl], 0.1),
                   np.full_like(gain[sl], 0.5), None, gain[sl])
    floor = acc.finish([0], 0, ("a",))
    ad = floor["per_joint"]["a"]["adaptive"]
    assert 2.0 / 1.13 <= ad["median_nm"] <= 2.0 and 2.0 / 1.13 <= ad["worst_tenth_nm"] <= 2.0
    assert floor["pulse_gain"] == {"a": pytest.approx(0.2)}


def test_a_blow_passes_the_adapting_filter_no_more_than_the_frozen_one() -> None:
    """The floor's blow takes G_hat frozen over it; the evaluator's RLS adapts while the
    blow lasts. Known truth by running it: half-sines of 100 ms and 0.2–5 N·m added to a
    moving joint's residual at four times raise its r_rms by at most the frozen G_hat's
    gain × amplitude (measured 0.29–0.79 of it), so the floor taken with it stays a lower
    bound."""
    from scipy import signal

    from impactcli.config import AdaptiveConfig
    from impactcli.detect.adaptive import evaluate_chunk
    from impactcli.detect.axes import EvaluatorState
    from impactcli.detect.floor import GAIN_EVERY, pulse_gain

    fs = 250.0
    rng = np.random.default_rng(0)
    n = int(40 * fs)
    t = np.arange(n) / fs
    pos = np.stack([0.8 * signal.sawtooth(2 * np.pi * t / p, 0.5) for p in (2.0, 2.6)], 1)
    r, u = motion_residual(pos, fs, rng)
    cfg, vs = AdaptiveConfig(), np.full(2, 0.1)
    base, _ = evaluate_chunk(EvaluatorState.initial(2, cfg, fs), r, u, fs, vs, cfg)
    rates = base.rates
    m = round(0.1 * fs)
    for tb in (10.0, 17.3, 25.1, 33.7):
        k0 = int(tb * fs)
        g = float(pulse_gain(base.theta_g[k0 // GAIN_EVERY, 1], fs, rates.a1, rates.n1))
        assert 0.0 < g < 1.0
        for amp in (0.2, 1.0, 5.0):
            hit = r.copy()
            hit[k0:k0 + m, 1] += amp * np.sin(np.pi * (np.arange(m) + 0.5) / m)
            res, _ = evaluate_chunk(EvaluatorState.initial(2, cfg, fs), hit, u, fs, vs, cfg)
            win = slice(k0, k0 + m + rates.n1 + 100)
            rise = float(np.max(res.r_rms[win, 1] - base.r_rms[win, 1]))
            assert 0.0 < rise <= g * amp, (tb, amp, rise / (g * amp))


def test_a_blow_no_g_hat_passes_is_no_floor_not_a_lower_one() -> None:
    """Where G_hat passes no blow (gain 0) for 30 % of the log, no size was seen there: those
    samples count at the top, so the worst tenth states no figure rather than one taken
    over the rest only; the median still stands."""
    n = 10_000
    acc = FloorAccumulator(1, n, 10, np.array([1.0]))
    gain = np.where(np.arange(n) % 10 < 3, 0.0, 0.5)[:, None]
    acc.update(np.zeros((n, 1)), np.full((n, 1), 0.1), np.full((n, 1), 0.5), None, gain)
    ad = acc.finish([0], 0, ("a",))["per_joint"]["a"]["adaptive"]
    assert 0.8 / 1.13 <= ad["median_nm"] <= 0.8 and ad["worst_tenth_nm"] is None
