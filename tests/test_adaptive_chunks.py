"""Chunked adaptive evaluator (impactcli.detect.adaptive.evaluate_chunk): the outputs
concatenated over chunks are bit for bit the whole-log call's, for any chunk size and any
boundary (start-up, inside a contact, wind-up guard acting), and so is the final state."""

from __future__ import annotations

import dataclasses
import itertools
import json
from collections.abc import Sequence

import numpy as np
import pytest
from scipy import signal

from impactcli.config import AdaptiveConfig
from impactcli.detect.adaptive import SIGNALS, AdaptiveResult, evaluate_chunk, join_chunks
from impactcli.detect.axes import EvaluatorState

from .helpers import SAMPLES, assist_impacts_pass, motion_residual
from .reference.adaptive import evaluate

FS = 250.0
CHUNK_SIZES = (1, 7, 1000, 4096, None)  # None: the whole log as one chunk
STATE_ARRAYS = ("theta", "P", "r_lags", "v_lags", "u_lags", "filters", "ring_r", "ring_v",
                "sums", "n_resets", "n_capped")


def bounds_of(n: int, size: int | None) -> list[int]:
    return [0, n] if size is None else [*range(0, n, size), n]


def run_chunks(r: np.ndarray, u: np.ndarray, fs: float, vs: np.ndarray,
               cfg: AdaptiveConfig, bounds: Sequence[int], threads: int = 1
               ) -> tuple[AdaptiveResult, EvaluatorState]:
    st = EvaluatorState.initial(r.shape[1], cfg, fs)
    outs = []
    for a, b in itertools.pairwise(bounds):
        res, st = evaluate_chunk(st, r[a:b], u[:, a:b], fs, vs, cfg, threads=threads)
        assert res.r_rms.shape == (b - a, r.shape[1])
        outs.append(res)
    assert st.n_samples == r.shape[0]
    return join_chunks(outs), st


def assert_identical(a: AdaptiveResult, b: AdaptiveResult, what: str) -> None:
    for name in (*SIGNALS, "theta", "n_resets", "n_capped"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, f"{what}: {name}"
        assert np.array_equal(x, y), f"{what}: {name} differs"
    assert a.rates == b.rates and a.nu == b.nu and a.eta == b.eta


def assert_same_state(s: EvaluatorState, t: EvaluatorState, what: str) -> None:
    """Every array of the state bitwise equal — in particular the RMS windows' running
    sums, which therefore cannot drift with the chunking."""
    assert s.n_samples == t.n_samples
    for name in STATE_ARRAYS:
        assert np.array_equal(getattr(s, name), getattr(t, name)), f"{what}: state {name}"


def whole_log_state(r: np.ndarray, u: np.ndarray, fs: float, vs: np.ndarray,
                    cfg: AdaptiveConfig) -> tuple[AdaptiveResult, EvaluatorState]:
    return evaluate_chunk(EvaluatorState.initial(r.shape[1], cfg, fs), r, u, fs, vs, cfg)


# ----------------------------------------------------------------------------- sample log
@pytest.fixture(scope="module")
def assist_impacts() -> tuple[np.ndarray, np.ndarray, float, AdaptiveConfig, list[float]]:
    """Residual and inputs of sample_logs' assist_impacts through the replay's threshold-free
    pass (the elbow's reference is constant: the wind-up guard acts on both axes)."""
    log, cfg, st, inputs = assist_impacts_pass()
    csv = SAMPLES / "csv"
    labels = json.loads((csv / "assist_impacts.labels.json").read_text())
    t = log.time_s - log.time_s[0]
    mids = [float(np.searchsorted(t, 0.5 * (e["start"] + e["end"]))) for e in labels["events"]]
    return st.r, inputs.u, log.sample_rate_hz, cfg.adaptive, mids


@pytest.mark.parametrize("size", CHUNK_SIZES)
def test_sample_log_any_chunk_size_is_bitwise_the_whole_log(assist_impacts, size) -> None:
    r, u, fs, cfg, _ = assist_impacts
    vs = np.array([0.08, 0.03])
    # the regularised default (the regulariser's coordinate crosses every boundary), and
    # the guard alone, which acts there (a still joint)
    for c, guard in ((cfg, False), (dataclasses.replace(cfg, regularization=0.0), True)):
        whole = evaluate(r, u, fs, vs, c)
        assert (whole.n_capped > 0).all() if guard else whole.n_capped.sum() == 0
        assert whole.decision.any()
        got, st = run_chunks(r, u, fs, vs, c, bounds_of(len(r), size))
        assert_identical(got, whole, f"chunks of {size}")
        assert_same_state(st, whole_log_state(r, u, fs, vs, c)[1], f"chunks of {size}")


def test_sample_log_boundaries_inside_contacts_and_start_up(assist_impacts) -> None:
    """Boundaries after samples 1, 2, 3, 5 (inside the regression's start-up: eta = 2,
    rho = 4, p = 20 lags, N1, N2 windows), mid-contact of every labelled impact, and at
    random places; both estimate options."""
    r, u, fs, cfg, mids = assist_impacts
    n = len(r)
    rng = np.random.default_rng(4)
    cuts = {1, 2, 3, 5, 19, 21, 39, 41, *(int(m) for m in mids),
            *(int(m) + 1 for m in mids), *rng.integers(1, n, 40).tolist()}
    bounds = [0, *sorted(c for c in cuts if 0 < c < n), n]
    assert len(mids) >= 3
    vs = np.array([0.08, 0.03])
    for est in ("a_posteriori", "a_priori"):
        c = dataclasses.replace(cfg, estimate=est)
        whole = evaluate(r, u, fs, vs, c)
        got, st = run_chunks(r, u, fs, vs, c, bounds)
        assert_identical(got, whole, est)
        assert_same_state(st, whole_log_state(r, u, fs, vs, c)[1], est)


# ----------------------------------------------------------------------------- synthetic
def synthetic(seed: int = 0, n_s: float = 60.0, joints: int = 3):
    """Triangle references; joint 1 stands still from 10 s to 40 s (the wind-up guard acts),
    a 0.5 N·m, 80 ms contact pulse on the last joint at 20 s and 50 s."""
    rng = np.random.default_rng(seed)
    n = int(n_s * FS)
    t = np.arange(n) / FS
    per = 2.0 + 0.6 * np.arange(joints)
    pos = np.stack([0.8 * signal.sawtooth(2 * np.pi * t / p, 0.5) for p in per], axis=1)
    still = (t >= 10.0) & (t < 40.0)
    if still.any():
        pos[still, 1] = pos[np.flatnonzero(still)[0] - 1, 1]
    r, u = motion_residual(pos, FS, rng)
    pulses = []
    for tp in (20.0, 50.0):
        m = (t >= tp) & (t < tp + 0.08)
        if not m.any():
            continue
        r[m, -1] += 0.5 * np.sin(np.pi * (t[m] - tp) / 0.08)
        pulses.append(int(np.flatnonzero(m)[len(np.flatnonzero(m)) // 2]))
    return r, u, pulses


@pytest.mark.parametrize("size", CHUNK_SIZES)
def test_synthetic_any_chunk_size_is_bitwise_the_whole_log(size) -> None:
    r, u, _ = synthetic()
    vs = np.full(3, 0.1)
    for cfg in (AdaptiveConfig(), AdaptiveConfig(regularization=0.0)):
        whole = evaluate(r, u, FS, vs, cfg)
        if cfg.regularization == 0.0:
            assert whole.n_capped[0] > 0  # joint 1's silent input lags are capped
        got, st = run_chunks(r, u, FS, vs, cfg, bounds_of(len(r), size))
        assert_identical(got, whole, f"chunks of {size}")
        assert_same_state(st, whole_log_state(r, u, FS, vs, cfg)[1], f"chunks of {size}")


def test_synthetic_random_chunks_threads_and_plain_eq39() -> None:
    """Random chunk sizes 1..600 with boundaries inside both pulses, axes on 2 threads,
    a priori, and plain eq. 39 (``max_trace = inf``)."""
    r, u, pulses = synthetic(seed=1, n_s=30.0)
    n = len(r)
    rng = np.random.default_rng(7)
    cuts = set(np.cumsum(rng.integers(1, 600, n)).tolist()) | {p for p in pulses if p < n}
    bounds = [0, *sorted(c for c in cuts if 0 < c < n), n]
    vs = np.full(3, 0.1)
    for cfg in (AdaptiveConfig(), AdaptiveConfig(estimate="a_priori"),
                AdaptiveConfig(max_trace=np.inf), AdaptiveConfig(regularization=0.0),
                AdaptiveConfig(n1_s=0.1, n2_s=0.004)):
        whole = evaluate(r, u, FS, vs, cfg, threads=1)
        got, st = run_chunks(r, u, FS, vs, cfg, bounds, threads=2)
        assert_identical(got, whole, repr(cfg))
        assert_same_state(st, whole_log_state(r, u, FS, vs, cfg)[1], repr(cfg))


def test_state_is_not_modified_and_empty_chunks_change_nothing() -> None:
    r, u, _ = synthetic(n_s=2.0)
    cfg = AdaptiveConfig()
    vs = np.full(3, 0.1)
    st0 = EvaluatorState.initial(3, cfg, FS)
    res, st1 = evaluate_chunk(st0, r[:100], u[:, :100], FS, vs)
    assert_same_state(st0, EvaluatorState.initial(3, cfg, FS), "input state")
    again, st1b = evaluate_chunk(st0, r[:100], u[:, :100], FS, vs)  # replayable
    assert_identical(again, res, "same chunk twice")
    empty, st2 = evaluate_chunk(st1, r[:0], u[:, :0], FS, vs)
    assert empty.r_rms.shape == (0, 3) and empty.decision.dtype == np.bool_
    assert_same_state(st2, st1, "empty chunk")
    assert st1.n_samples == 100 and st1b.n_samples == 100


def test_initial_state_holds_table_i_start() -> None:
    cfg = AdaptiveConfig()
    st = EvaluatorState.initial(2, cfg, FS)
    assert st.nu == 34 and st.P.shape == (2, 34, 34)
    assert np.array_equal(st.P[0], cfg.p0 * np.eye(34)) and np.all(st.theta == cfg.theta0)
    assert st.r_lags.shape == (2, 2) and st.v_lags.shape == (2, 20)
    assert st.u_lags.shape == (2, 4, 2)
    assert st.ring_r.shape == (2, 10) and st.ring_v.shape == (2, 40)
    assert st.n_samples == 0 and not st.sums.any() and not st.filters.any()


def test_state_mismatch_is_refused() -> None:
    r, u, _ = synthetic(n_s=1.0)
    st = EvaluatorState.initial(3, AdaptiveConfig(), FS)
    vs = np.full(3, 0.1)
    with pytest.raises(ValueError, match="sample rate"):
        evaluate_chunk(st, r, u, 500.0, vs)
    with pytest.raises(ValueError, match="cfg differs"):
        evaluate_chunk(st, r, u, FS, vs, AdaptiveConfig(p=10))
    with pytest.raises(ValueError, match="joints"):
        evaluate_chunk(st, r[:, :2], u[:, :, :2], FS, vs[:2])


def test_g_hat_is_kept_every_sixteenth_sample_whatever_the_chunks() -> None:
    """The evaluator's snapshots of theta_G (the detection floor's G_hat as it stood): at
    the log's samples 0, 16, 32, …, theta_G as G_hat used it there — a posteriori the
    state's theta after that sample, a priori the one before it (known truth: chunks of one
    sample, the state read after each) — and bit for bit the same for any chunking."""
    from impactcli.detect.axes import SNAP_EVERY

    assert SNAP_EVERY == 16
    r, u, _ = synthetic(seed=2, n_s=4.0)
    n = len(r)
    vs = np.full(3, 0.1)
    for est in ("a_posteriori", "a_priori"):
        cfg = AdaptiveConfig(estimate=est)
        whole, _ = whole_log_state(r, u, FS, vs, cfg)
        assert whole.theta_g.shape == (-(-n // 16), 3, cfg.eta)
        st = EvaluatorState.initial(3, cfg, FS)
        truth = []
        for k in range(n):
            before = st.theta[:, :cfg.eta].copy()
            _, st = evaluate_chunk(st, r[k:k + 1], u[:, k:k + 1], FS, vs, cfg)
            if k % 16 == 0:
                truth.append(st.theta[:, :cfg.eta].copy() if est == "a_posteriori" else before)
        assert np.array_equal(whole.theta_g, np.stack(truth)), est
        for size in (1, 7, 16, 100, 333):
            got, _ = run_chunks(r, u, FS, vs, cfg, bounds_of(n, size))
            assert np.array_equal(got.theta_g, whole.theta_g), (est, size)
