"""Adaptive evaluator (impactcli.detect.adaptive): compiled kernel = reference to 1e-9,
filters / RMS / decision against direct computations, inputs, sample-rate rules, the
a priori / a posteriori measurement and the wind-up guard in the full loop."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from impactcli.config import AdaptiveConfig
from impactcli.detect.adaptive import g_gain
from impactcli.detect.rates import resolve_rates
from impactcli.errors import ImpactWarning
from impactcli.types import RobotLog

from .helpers import assist_impacts_pass
from .reference.adaptive import evaluate, evaluate_reference, threshold_inputs
from .reference.warmup import warmup_end

FS = 250.0


def residual_of(pos: np.ndarray, rng: np.random.Generator, inertia: float = 0.002,
                cross: float = 0.001) -> tuple[np.ndarray, np.ndarray]:
    """(r, u) of joints at positions ``pos`` (n, J) [rad]: the residual of a robot whose
    model misses friction-like (0.3 tanh(50 x')) and inertia-like terms (``inertia`` x'' of
    the joint, ``cross`` x'' of the other) through an 8 Hz mode, plus white noise (σ 0.03,
    drawn from ``rng``) and an offset of 0.2; u the inputs (tanh(50 x'), x'')."""
    v = np.zeros_like(pos)
    v[1:] = np.diff(pos, axis=0) * FS
    acc = np.zeros_like(v)
    acc[1:] = np.diff(v, axis=0) * FS
    u = np.stack([np.tanh(50 * v), acc])
    b_, a_ = signal.butter(2, 8 / (FS / 2))
    raw = 0.3 * np.tanh(50 * v) + inertia * acc + cross * acc[:, ::-1]
    r = signal.lfilter(b_, a_, raw, axis=0) + 0.03 * rng.standard_normal(pos.shape) + 0.2
    return r, u


def scenario(seed: int, *, n_s: float = 40.0, joints: int = 2, pulses: tuple[float, ...] = (),
             amp: float = 0.5, still: tuple[float, float] | None = None):
    """Synthetic residual of a robot on triangle references (paper Sec. IV): friction-like
    and inertia-like model errors through a 8 Hz mode, an offset, white noise; optional
    80 ms half-sine contact pulses on the last joint and a standstill interval."""
    rng = np.random.default_rng(seed)
    n = int(n_s * FS)
    t = np.arange(n) / FS
    per = 2.0 + 0.6 * np.arange(joints)

    def tri(tt: np.ndarray) -> np.ndarray:
        return np.stack([0.8 * signal.sawtooth(2 * np.pi * tt / p, 0.5) for p in per], axis=1)

    pos = tri(t)
    if still is not None:
        a, b = still
        m = (t >= a) & (t < b)
        pos[m] = pos[np.flatnonzero(m)[0] - 1]
        pos[t >= b] = tri(t[t >= b] - b + a)
    r, u = residual_of(pos, rng)
    for tp in pulses:
        m = (t >= tp) & (t < tp + 0.08)
        r[m, -1] += amp * np.sin(np.pi * (t[m] - tp) / 0.08)
    return t, r, u


@pytest.mark.parametrize("joints", [2, 3])
@pytest.mark.parametrize("estimate", ["a_priori", "a_posteriori"])
def test_numba_equals_reference(joints: int, estimate: str) -> None:
    _, r, u = scenario(0, n_s=8.0, joints=joints)
    cfg = AdaptiveConfig(estimate=estimate)
    v_stat = np.linspace(0.05, 0.1, joints)
    a = evaluate(r, u, FS, v_stat, cfg)
    b = evaluate_reference(r, u, FS, v_stat, cfg)
    assert a.theta.shape == (joints, 2 + 20 + joints * 6)
    for name in ("r_tilde", "v_dyn", "r_f", "v_f", "r_rms", "v_rms", "threshold",
                 "prediction_error", "theta"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-9,
                                   err_msg=name)
    margin = np.abs(a.r_rms - a.threshold)
    assert np.array_equal(a.decision[margin > 1e-9], b.decision[margin > 1e-9])


def test_axes_on_threads_give_identical_results() -> None:
    _, r, u = scenario(1, n_s=8.0, joints=3)
    a = evaluate(r, u, FS, np.full(3, 0.05), threads=1)
    b = evaluate(r, u, FS, np.full(3, 0.05), threads=3)
    for name in ("r_tilde", "v_dyn", "r_rms", "v_rms", "decision", "prediction_error", "theta"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_nu_matches_paper() -> None:
    assert AdaptiveConfig().n_params(2) == 34
    assert AdaptiveConfig().n_params(7) == 64


def test_filters_rms_and_decision_match_direct_computation() -> None:
    _, r, u = scenario(1, n_s=4.0)
    v_stat = np.array([0.02, 0.03])
    res = evaluate(r, u, FS, v_stat)
    a1, a2 = np.exp(-2 * np.pi * 10 / FS), np.exp(-2 * np.pi * 50 / FS)
    np.testing.assert_allclose(res.r_f, signal.lfilter([1 - a1], [1, -a1], res.r_tilde, axis=0),
                               atol=1e-12)
    np.testing.assert_allclose(res.v_f, signal.lfilter([1 - a2], [1, -a2], res.v_dyn, axis=0),
                               atol=1e-12)
    assert (res.rates.n1, res.rates.n2) == (10, 40)
    for k in (0, 1, 5, 10, 11, 500, r.shape[0] - 1):
        prev = res.r_f[max(0, k - 10):k]           # samples k-1 .. k-10, current excluded
        np.testing.assert_allclose(res.r_rms[k], np.sqrt(np.sum(prev**2, axis=0) / 10),
                                   atol=1e-12)
        prev_v = res.v_f[max(0, k - 40):k]
        np.testing.assert_allclose(res.v_rms[k], np.sqrt(np.sum(prev_v**2, axis=0) / 40),
                                   atol=1e-12)
    np.testing.assert_allclose(res.threshold, np.abs(v_stat + res.v_rms))
    assert np.array_equal(res.decision, res.r_rms > res.threshold)
    # r_tilde is G_hat r with the final theta at the last sample
    th = res.theta
    k = r.shape[0] - 1
    np.testing.assert_allclose(res.r_tilde[k], r[k] - th[:, 0] * r[k - 1] - th[:, 1] * r[k - 2],
                               atol=1e-12)


def test_g_gain_against_polynomial() -> None:
    th = np.array([[1.8, -0.8], [0.95, 0.0]])      # G = 1 - 1.8 z^-1 + 0.8 z^-2; 1 - 0.95 z^-1
    f = np.array([1.0, 10.0, 62.5])
    g = g_gain(th, f, FS)
    z = np.exp(1j * 2 * np.pi * f / FS)
    np.testing.assert_allclose(g[0], np.abs(1 - 1.8 / z + 0.8 / z**2))
    np.testing.assert_allclose(g[1], np.abs(1 - 0.95 / z))
    assert g[0, 0] < 0.01 < g[0, 2]                # a near-differentiator (method.md §7)


def test_sample_rate_rules() -> None:
    r1k = resolve_rates(AdaptiveConfig(), 1000.0)
    assert (r1k.n1, r1k.n2) == (40, 160)
    with pytest.warns(ImpactWarning, match="clipped to 40 Hz"):
        r100 = resolve_rates(AdaptiveConfig(), 100.0)
    assert r100.w2_hz == pytest.approx(40.0) and r100.w1_hz == 10.0
    assert (r100.n1, r100.n2) == (4, 16)


def _log(n: int = 500, **kw) -> RobotLog:
    t = np.arange(n) * 4_000_000
    pos = np.stack([np.sin(np.arange(n) * 0.01), np.cos(np.arange(n) * 0.02)], axis=1)
    return RobotLog(t_ns=t, joint_names=("a", "b"), position=pos, torque=np.zeros((n, 2)),
                    **kw)


def test_threshold_inputs_sources() -> None:
    n = 500
    x = np.stack([np.sin(np.arange(n) * 0.01), np.cos(np.arange(n) * 0.02)], axis=1)
    v = np.gradient(x, 0.004, axis=0)
    acc = np.gradient(v, 0.004, axis=0)
    cfg = AdaptiveConfig(tanh_slope=20.0)
    got = threshold_inputs(_log(velocity_ref=v, acceleration_ref=acc), cfg)
    assert got.source == "velocity_ref" and got.u.shape == (2, n, 2)
    np.testing.assert_allclose(got.u[0], np.tanh(20.0 * v))
    np.testing.assert_allclose(got.u[1], acc)
    got = threshold_inputs(_log(position_ref=x), cfg)
    assert got.source == "position_ref"
    vd = np.diff(x, axis=0) / 0.004
    np.testing.assert_allclose(got.u[0][1:], np.tanh(20.0 * vd), atol=1e-9)
    np.testing.assert_allclose(got.u[1][2:], np.diff(vd, axis=0) / 0.004, atol=1e-6)
    with pytest.warns(ImpactWarning, match="no reference trajectory"):
        got = threshold_inputs(_log(), cfg)
    assert got.source == "measured"
    # causal: changing the future does not change the past
    later = _log().position.copy()
    later[300:] += 1.0
    with pytest.warns(ImpactWarning):
        got2 = threshold_inputs(RobotLog(t_ns=np.arange(n) * 4_000_000, joint_names=("a", "b"),
                                         position=later, torque=np.zeros((n, 2))), cfg)
    np.testing.assert_array_equal(got.u[:, :300], got2.u[:, :300])
    # well below the filter's cut-off the acceleration keeps its amplitude (6.25, 25 rad/s²)
    rms = np.sqrt(np.mean(got.u[1][100:] ** 2, axis=0))
    np.testing.assert_allclose(rms, np.array([6.25, 25.0]) / np.sqrt(2), rtol=0.1)


def test_a_posteriori_default_is_measured() -> None:
    """The measurement behind the default (module docstring of adaptive.py): v_stat set to
    1.2 × each option's own collision-free maximum of r_rms − v_rms after 5 s, then three
    0.5 N·m, 80 ms pulses; a posteriori gives the larger pulse/threshold ratio, and both
    stay silent outside the pulses."""
    assert AdaptiveConfig().estimate == "a_posteriori"
    pulses = (12.3, 21.7, 33.1)
    k0 = int(5 * FS)
    mean_ratio = {}
    for est in ("a_priori", "a_posteriori"):
        cfg = AdaptiveConfig(estimate=est)
        _, r, u = scenario(1)
        free = evaluate(r, u, FS, np.zeros(2), cfg)
        v_stat = 1.2 * np.maximum((free.r_rms - free.v_rms)[k0:].max(axis=0), 0.0)
        t, r, u = scenario(2, pulses=pulses)
        hit = evaluate(r, u, FS, v_stat, cfg)
        near = np.any([(t >= tp) & (t < tp + 0.3) for tp in pulses], axis=0)
        assert not hit.decision[k0:][~near[k0:]].any()
        mean_ratio[est] = np.mean([hit.ratio[(t >= tp) & (t < tp + 0.3), 1].max()
                                   for tp in pulses])
    assert mean_ratio["a_posteriori"] > mean_ratio["a_priori"]


def test_large_contact_is_detected_on_its_joint() -> None:
    _, r, u = scenario(1)
    free = evaluate(r, u, FS, np.zeros(2))
    v_stat = 1.2 * (free.r_rms - free.v_rms)[int(5 * FS):].max(axis=0)
    t, r, u = scenario(2, pulses=(20.0,), amp=2.0)
    hit = evaluate(r, u, FS, v_stat)
    fired = np.flatnonzero(hit.decision[:, 1] & (t > 5))
    assert fired.size and 20.0 < t[fired[0]] < 20.1


#: The wind-up guard alone (no regulariser) and plain eq. 39 (neither): the guard's tests
#: compare these two; the regularised default is tested beside them.
GUARD_ONLY = AdaptiveConfig(regularization=0.0)
PLAIN_39 = AdaptiveConfig(max_trace=np.inf, regularization=0.0)


def test_standstill_for_minutes_then_moving_gives_no_blow_up() -> None:
    """3.5 min standstill (u = 0, residual = noise + offset), then triangles again."""
    t, r, u = scenario(3, n_s=300.0, still=(40.0, 250.0))
    pre, post = (t > 10) & (t < 40), t >= 250
    res = {}
    for name, mt in (("guarded", None), ("unguarded", np.inf)):
        a = evaluate(r, u, FS, np.zeros(2), AdaptiveConfig(max_trace=mt, regularization=0.0))
        assert np.all(np.isfinite(a.theta))
        res[name] = (a, np.abs(a.r_rms[post]).max() / np.abs(a.r_rms[pre]).max())
    a, ratio = res["guarded"]
    assert a.n_resets.sum() == 0
    assert ratio < 1.5
    assert np.abs(a.v_dyn[post]).max() < 1.5 * np.abs(a.v_dyn[pre]).max()
    assert res["unguarded"][1] > 2.0 * ratio        # without the guard it does blow up


def sines(seed: int, n_s: float, still: tuple[float, float] | None = None):
    """2 joints on sine references (no exact collinearity in the regressor, unlike the
    triangles' sign(x') and x''); joint 2 (index 1) keeps its position during ``still``
    [s] — from 0 on: its reference is constant, its inputs exactly 0 — then moves again
    (smooth start)."""
    rng = np.random.default_rng(seed)
    n = int(n_s * FS)
    t = np.arange(n) / FS
    pos = np.stack([0.8 * np.sin(2 * np.pi * t / 3.0), 0.6 * np.sin(2 * np.pi * t / 4.1 + 1)],
                   axis=1)
    if still is not None:
        a, b = still
        hold = pos[max(0, int(a * FS) - 1), 1]
        pos[(t >= a) & (t < b), 1] = hold
        pos[t >= b, 1] = hold + 0.6 * (1 - np.cos(2 * np.pi * (t[t >= b] - b) / 4.1))
    r, u = residual_of(pos, rng, 0.02, 0.01)
    return t, r, u


FIELDS = ("r_tilde", "v_dyn", "r_f", "v_f", "r_rms", "v_rms", "threshold", "decision",
          "prediction_error")


@pytest.mark.parametrize(("regularization", "cap"), [(0.0, 10.0), (10.0, 0.05)])
def test_numba_equals_reference_with_the_cap_acting(regularization: float, cap: float) -> None:
    """Every diagonal element of P capped low (p0 with the guard alone; 0.05, under the
    regulariser's ~1/delta, with it), acting from the start — so the regulariser's column of
    P is made with the guard's scales: the fused path against the textbook updates."""
    _, r, u = scenario(0, n_s=8.0)
    cfg = AdaptiveConfig(max_trace=34 * cap, regularization=regularization)
    a = evaluate(r, u, FS, np.full(2, 0.05), cfg)
    b = evaluate_reference(r, u, FS, np.full(2, 0.05), cfg)
    assert a.n_capped.min() > 1000
    np.testing.assert_array_equal(a.n_capped, b.n_capped)
    for name in ("r_tilde", "v_dyn", "r_f", "v_f", "r_rms", "v_rms", "threshold",
                 "prediction_error", "theta"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-9,
                                   err_msg=name)


def test_still_joint_gives_plain_eq39_bitwise() -> None:
    """Joint 2's reference is constant for 80 s (its 6 input lags are exactly 0 in both
    axes' regressions, as the elbow's in sample_logs' assist_impacts): the default guard
    caps that block of P (from 46 s, when p0 lambda^-k reaches 1e5 p0) and every output
    equals plain eq. 39's (max_trace = inf) bit for bit."""
    _, r, u = sines(1, 80.0, still=(0.0, 1e9))
    g = evaluate(r, u, FS, np.full(2, 0.05), GUARD_ONLY)
    p = evaluate(r, u, FS, np.full(2, 0.05), PLAIN_39)
    assert g.n_capped.min() > 5000 and p.n_capped.sum() == 0
    for name in (*FIELDS, "theta"):
        np.testing.assert_array_equal(getattr(g, name), getattr(p, name), err_msg=name)


def test_one_joint_still_for_17_minutes_then_moving() -> None:
    """Joint 2 stops for 250 000 samples (17 min at 4 ms) while joint 1 keeps moving, then
    resumes. Plain eq. 39 (max_trace = inf) winds up — the P blocks of the still input lags
    and of triangle references' collinear u1/u2 lags — loses positive definiteness and
    resets P ten times per axis, and the moving joint's r_rms swings to 3.7 x its level
    before; the default guard: no reset, r_rms during the standstill and after resuming
    within its level before, v_dyn too."""
    n0, n_still, n1 = 10_000, 250_000, 10_000
    rng = np.random.default_rng(5)
    n = n0 + n_still + n1
    t = np.arange(n) / FS
    pos = np.stack([0.8 * signal.sawtooth(2 * np.pi * t / p, 0.5) for p in (2.0, 2.6)], axis=1)
    pos[n0:n0 + n_still, 1] = pos[n0 - 1, 1]
    pos[n0 + n_still:, 1] = 0.8 * signal.sawtooth(
        2 * np.pi * (t[n0 + n_still:] - t[n0 + n_still] + t[n0]) / 2.6, 0.5)
    r, u = residual_of(pos, rng)
    pre, still = slice(2500, n0), slice(n0 + 2500, n0 + n_still)
    post = slice(n0 + n_still, n)
    g = evaluate(r, u, FS, np.zeros(2), GUARD_ONLY)
    p = evaluate(r, u, FS, np.zeros(2), PLAIN_39)
    assert p.n_resets.min() >= 5
    assert p.r_rms[still, 0].max() > 2.5 * p.r_rms[pre, 0].max()
    assert g.n_resets.sum() == 0 and g.n_capped.min() > 0.9 * n_still
    for a in (still, post):
        assert np.all(g.r_rms[a].max(axis=0) < 1.1 * g.r_rms[pre].max(axis=0))
    assert np.all(np.abs(g.v_dyn[post]).max(axis=0) < 1.5 * np.abs(g.v_dyn[pre]).max(axis=0))


def test_ten_minutes_of_triangles_wind_up_plain_eq39_not_the_guard() -> None:
    """Both joints on triangle references for 10 min: sign(x1_ref') changes exactly where
    x1_ref'' is non-zero, so u1's lag differences are proportional to u2's lags and that
    combination is never excited while moving. Plain eq. 39 lets P grow as lambda^-k there,
    loses positive definiteness and resets P (every ~26 000 samples), r_rms swinging well
    above its level; the guard caps it at a few % of the samples, without a reset."""
    n = 150_000
    rng = np.random.default_rng(5)
    t = np.arange(n) / FS
    pos = np.stack([0.8 * signal.sawtooth(2 * np.pi * t / p, 0.5) for p in (2.0, 2.6)], axis=1)
    r, u = residual_of(pos, rng)
    g = evaluate(r, u, FS, np.zeros(2), GUARD_ONLY)
    p = evaluate(r, u, FS, np.zeros(2), PLAIN_39)
    settled = slice(int(60 * FS), int(100 * FS))           # after the start-up, before 26k
    assert p.n_resets.min() >= 3
    assert np.any(p.r_rms[settled.stop:].max(axis=0) > 2.0 * p.r_rms[settled].max(axis=0))
    assert g.n_resets.sum() == 0 and 0 < g.n_capped.max() < 0.1 * n
    assert np.all(g.r_rms[settled.stop:].max(axis=0) < 1.2 * g.r_rms[settled].max(axis=0))



def test_sample_impacts_log_gives_plain_eq39_bitwise() -> None:
    """sample_logs' assist_impacts (the elbow's reference is constant throughout, so the
    inputs' acceleration column is zero and the wind-up guard acts): the replay with the
    guard equals plain eq. 39 bit for bit, and plain eq. 39 is never capped."""
    from impactcli.run.plan import calibrated_thresholds

    log, cfg, st, inputs = assist_impacts_pass()
    th = calibrated_thresholds(cfg, log.joint_names)
    assert th is not None
    fs = log.sample_rate_hz
    g = evaluate(st.r, inputs.u, fs, th["adaptive"],
                 dataclasses.replace(cfg.adaptive, regularization=0.0))
    p = evaluate(st.r, inputs.u, fs, th["adaptive"],
                 dataclasses.replace(cfg.adaptive, max_trace=np.inf, regularization=0.0))
    assert np.all(inputs.u[:, :, 1] == 0.0)
    assert (g.n_capped > 0).all() and p.n_capped.sum() == 0
    for name in (*FIELDS, "theta"):
        np.testing.assert_array_equal(getattr(g, name), getattr(p, name), err_msg=name)


@pytest.mark.real_logs
def test_real_kuka_7_joints_at_200_hz(real_logs: Path) -> None:
    """KUKA LWR4+ (7 joints, 200 Hz, no contact): a crude per-joint LS residual; the
    evaluator stays finite without covariance resets, warms up within the cap, and G is
    high-pass (method.md §7)."""
    path = real_logs / "kuka_lwr4" / "measurements_1.npz"
    d = np.load(path)
    t = d["times"] - d["times"][0]
    q, v, a, tau = d["positions"], d["velocities"], d["accelerations"], d["torques"]
    r = np.zeros_like(tau)
    for j in range(7):
        Y = np.column_stack([a[:, j], v[:, j], np.tanh(50 * v[:, j]), np.ones(len(t)),
                             np.sin(q[:, j]), np.cos(q[:, j])])
        r[:, j] = Y @ np.linalg.lstsq(Y, tau[:, j], rcond=None)[0] - tau[:, j]
    fs = 1.0 / np.median(np.diff(t))
    res = evaluate(r, np.stack([np.tanh(50 * v), a]), fs, np.zeros(7))
    assert res.theta.shape == (7, 64)
    assert res.n_resets.sum() == 0 and np.all(np.isfinite(res.r_rms))
    w = warmup_end(res.prediction_error, t)
    assert 3.0 <= w.end_s <= 20.0
    f, g = res.g_gain()
    assert f[-1] == pytest.approx(fs / 4)
    assert np.all(g[:, 0] < g[:, -1])


def test_a_log_without_a_reference_is_warned_of_once(tmp_path) -> None:
    """detect on a log without reference channels: one warning says the threshold inputs
    come from the measured position (there were two, nearly the same)."""
    import dataclasses
    from pathlib import Path

    from click.testing import CliRunner

    from impactcli.cli import main
    from impactcli.logs import read_log, write_log

    repo = Path(__file__).resolve().parents[1]
    log = read_log(repo / "sample_logs" / "csv" / "assist_impacts.csv.gz")
    bare = dataclasses.replace(log, position_ref=None, velocity_ref=None,
                               acceleration_ref=None)
    write_log(bare, tmp_path / "bare.csv")
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "bare.csv"), "--config",
                                  str(repo / "sample_logs" / "assist_like.config.toml"),
                                  "-o", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    said = [ln for ln in r.stderr.splitlines() if "no reference trajectory" in ln
            or "no reference logged" in ln]
    assert len(said) == 1 and said[0].endswith(
        "no reference trajectory logged; the dynamic threshold's inputs come from the "
        "causally filtered measured position (no anticipation of the motion)"), said
