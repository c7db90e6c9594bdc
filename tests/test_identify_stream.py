"""Identification fed in chunks (impactcli.model.rows): the same rows, bit for bit, as the
whole log fed at once, and the windows' margins leave only rounding against one filter
over the whole log."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from impactcli.model import IdentifyOptions, zero_phase_lowpass
from impactcli.model import rows as rows_mod
from impactcli.model.identification import IdentifyStream
from impactcli.model.rows import Windows, decay_margin


def _signals(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 500.0
    q = np.stack([0.8 * np.sin(2 * np.pi * f * t + p) for f, p in ((0.3, 0), (0.5, 1.0))], 1)
    noise = 0.01 * rng.standard_normal(q.shape)
    tau = 3.0 * q + 0.5 * np.tanh(np.gradient(q, t, axis=0) / 0.01) + noise
    return t, q, tau


def _rows(t: np.ndarray, q: np.ndarray, tau: np.ndarray, cuts: list[int]) -> object:
    s = IdentifyStream.start(("a", "b"), t.size, 500.0, t[-1], kind="decoupled",
                             options=IdentifyOptions(max_fit_samples=2_000))
    for a, b in zip([0, *cuts], [*cuts, t.size], strict=True):
        s.feed(t[a:b], q[a:b], tau[a:b])
    return s.rows()


def test_rows_do_not_depend_on_how_the_log_arrives(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(rows_mod, "WINDOW", 3_000)     # several windows at both rates
    monkeypatch.setattr(rows_mod, "ROW_WINDOW", 400)
    t, q, tau = _signals(20_000)
    whole = _rows(t, q, tau, [])
    rng = np.random.default_rng(3)
    for cuts in ([1, 2, 3], list(range(997, 20_000, 997)),
                 sorted(rng.choice(np.arange(1, 20_000), 25, replace=False).tolist())):
        got = _rows(t, q, tau, cuts)
        assert np.array_equal(got.y_fit, whole.y_fit)
        assert np.array_equal(got.tau_fit, whole.tau_fit)
        assert got.y_hold is not None and whole.y_hold is not None
        assert np.array_equal(got.y_hold[0], whole.y_hold[0])
        assert np.array_equal(got.acc_rms, whole.acc_rms)
        assert got.filter_info == whole.filter_info
    assert whole.y_fit.shape[0] > 1_000


def test_windows_equal_one_filter_over_the_whole_signal_to_rounding() -> None:
    _, q, _ = _signals(50_000)
    fs, cut = 500.0, 10.0
    whole = zero_phase_lowpass(q, fs, cut, 4)
    parts: list[np.ndarray] = []

    def fn(a: int, s: int, e: int, x: np.ndarray) -> None:
        parts.append(zero_phase_lowpass(x, fs, cut, 4)[s - a:e - a])

    w = Windows(q.shape[0], 4_096, decay_margin(fs, cut, 4), fn)
    for k in range(0, q.shape[0], 1_234):
        w.feed(q[k:k + 1_234])
    w.finish()
    got = np.concatenate(parts)
    assert got.shape == whole.shape
    # rounding only (the IIR sums start elsewhere): 1e-20 of transient, 1e-13 of arithmetic
    assert np.max(np.abs(got - whole)) < 1e-13 * np.max(np.abs(whole))


def test_too_few_or_too_many_rows_is_an_error() -> None:
    w = Windows(10, 4, 2, lambda *a: None)
    w.feed(np.zeros(6))
    with pytest.raises(ValueError, match="6 rows arrived, 10 expected"):
        w.finish()
    with pytest.raises(ValueError, match="11 rows arrived"):
        w.feed(np.zeros(5))


def test_a_still_joint_is_found_from_the_chunks_ranges() -> None:
    t, q, tau = _signals(5_000)
    q[:, 1] = 0.25
    s = IdentifyStream.start(("a", "b"), t.size, 500.0, t[-1], kind="decoupled",
                             options=IdentifyOptions(allow_still_joints=True))
    for k in range(0, t.size, 777):
        s.feed(t[k:k + 777], q[k:k + 777], tau[k:k + 777])
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        r = s.rows()
    assert r.still == ["b"]
    assert any("joint(s) stay constant (b 0 rad)" in str(x.message) for x in w)

