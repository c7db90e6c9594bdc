"""RLS (the kernel of impactcli.detect.rls, in the forms of tests/reference/rls.py): equals
(exponentially weighted) least squares, stays SPD over millions of steps, and the
per-coordinate cap on P stops covariance wind-up without changing what eq. 38-40 compute
where the regressor is silent."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from impactcli.detect.rls import default_max_trace, rls_update_inplace

from .reference.rls import RecursiveLeastSquares, checked_symmetric, rls_run, rls_step


def _data(n: int, nu: int, seed: int = 0, noise: float = 0.1):
    rng = np.random.default_rng(seed)
    Phi = rng.standard_normal((n, nu))
    theta = rng.standard_normal(nu)
    y = Phi @ theta + noise * rng.standard_normal(n)
    return Phi, y, theta


@pytest.mark.parametrize("lam", [1.0, 0.99])
def test_rls_equals_weighted_least_squares(lam: float) -> None:
    """theta(N) = argmin sum lam^(N-k) (y - phi theta)^2 + lam^N |theta|^2 / p0 (P(1)=p0 I)."""
    n, nu, p0 = 400, 6, 10.0
    Phi, y, _ = _data(n, nu)
    w = lam ** (n - 1 - np.arange(n))
    A = (Phi * w[:, None]).T @ Phi + lam**n * np.eye(nu) / p0
    b = (Phi * w[:, None]).T @ y
    run = rls_run(Phi, y, forgetting_factor=lam, p0=p0, max_trace=np.inf)
    np.testing.assert_allclose(run.theta, np.linalg.solve(A, b), rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(run.P, np.linalg.inv(A), rtol=1e-7, atol=1e-12)
    # the a priori errors are y(k) - theta(k-1) phi(k)
    np.testing.assert_allclose(run.prediction_error[1:],
                               y[1:] - np.sum(Phi[1:] * run.theta_history[:-1], axis=1))


def test_lambda_one_equals_ordinary_least_squares_for_vague_prior() -> None:
    Phi, y, _ = _data(300, 5, seed=1)
    run = rls_run(Phi, y, forgetting_factor=1.0, p0=1e8, max_trace=np.inf)
    np.testing.assert_allclose(run.theta, np.linalg.lstsq(Phi, y, rcond=None)[0], rtol=1e-6)


def test_three_forms_agree() -> None:
    """Pure step, stateful update and batch run give the same result — here with the caps
    acting (max_trace = 40 = trace(P(1)): every diagonal element of P capped at p0)."""
    Phi, y, _ = _data(200, 4, seed=2)
    Phi[50:120, 2] = 0.0                                  # a silent coordinate for a while
    batch = rls_run(Phi, y, forgetting_factor=0.98, max_trace=40.0)
    assert batch.n_capped > 0
    obj = RecursiveLeastSquares(4, forgetting_factor=0.98, max_trace=40.0)
    eps = [obj.update(Phi[k], y[k]) for k in range(100)]
    rest = obj.run(Phi[100:], y[100:])
    theta, P = np.zeros(4), 10.0 * np.eye(4)
    for k in range(200):
        theta, P, _ = rls_step(theta, P, Phi[k], y[k], forgetting_factor=0.98, max_trace=40.0)
    for th in (obj.theta, rest.theta, theta):
        np.testing.assert_allclose(th, batch.theta, rtol=1e-12)
    np.testing.assert_allclose(eps, batch.prediction_error[:100], rtol=1e-12)
    np.testing.assert_allclose(P, batch.P, rtol=1e-12)


@numba.njit(cache=True)
def _drive(theta, P, pool, theta_true, n_steps, seed):
    """n_steps RLS steps on regressors drawn from ``pool`` (random row, random sign)."""
    np.random.seed(seed)  # noqa: NPY002 (numba knows only the legacy API)
    nu = theta.shape[0]
    h = np.empty(nu)
    w = np.empty(nu)
    phi = np.empty(nu)
    resets = 0
    for _ in range(n_steps):
        row = pool[np.random.randint(pool.shape[0])]  # noqa: NPY002 (numba knows only the legacy API)
        sgn = 1.0 if np.random.random() < 0.5 else -1.0  # noqa: NPY002 (numba knows only the legacy API)
        y = 0.01 * np.random.standard_normal()  # noqa: NPY002 (numba knows only the legacy API)
        for i in range(nu):
            phi[i] = sgn * row[i]
            y += phi[i] * theta_true[i]
        _, r, _ = rls_update_inplace(theta, P, phi, y, 0.999, np.inf, 10.0, h, w)
        resets += r
    return resets


def test_stays_symmetric_positive_definite_over_5e6_steps() -> None:
    """nu = 34, lambda = 0.999 (Table I), guard off: 5e6 steps (a compiled driver, 1e6 per
    chunk); P (exactly symmetric, checked bit for bit) Cholesky-factorisable after every
    chunk, no reset, estimate right at the end."""
    nu = 34
    rng = np.random.default_rng(3)
    theta_true = rng.standard_normal(nu)
    pool = rng.standard_normal((4096, nu))
    theta, P = np.zeros(nu), 10.0 * np.eye(nu)
    for chunk in range(5):
        assert _drive(theta, P, pool, theta_true, 1_000_000, chunk) == 0
        full = checked_symmetric(P)
        np.linalg.cholesky(full)
        assert np.linalg.eigvalsh(full).min() > 0
    np.testing.assert_allclose(theta, theta_true, atol=2e-3)


def test_cap_is_a_congruence_bounding_each_diagonal_element() -> None:
    """The guard scales P(k) of eq. 39 as W P W (w_i = min(1, sqrt(cap / P_ii))): each
    diagonal element ends at most at cap = max_trace / nu, P stays symmetric positive
    definite, and the step's estimate (its gain comes from P(k-1)) is eq. 38's."""
    nu, p0 = 5, 10.0
    rng = np.random.default_rng(5)
    A = rng.standard_normal((nu, nu))
    P = A @ A.T + 0.1 * np.eye(nu)
    P[0, :] *= 30.0
    P[:, 0] *= 30.0                                      # one poorly known coordinate
    theta, phi = rng.standard_normal(nu), rng.standard_normal(nu)
    phi[0] = 0.0
    cap = 50.0
    th_plain, P_plain, e_plain = rls_step(theta, P, phi, 0.3, max_trace=np.inf)
    th_cap, P_cap, e_cap = rls_step(theta, P, phi, 0.3, max_trace=cap * nu, p0=p0)
    assert np.diag(P_plain).max() > cap                  # the cap has something to do
    w = np.minimum(1.0, np.sqrt(cap / np.diag(P_plain)))
    np.testing.assert_allclose(P_cap, P_plain * np.outer(w, w), rtol=1e-12)
    assert np.diag(P_cap).max() <= cap * (1 + 1e-12)
    assert np.array_equal(P_cap, P_cap.T) and np.linalg.eigvalsh(P_cap).min() > 0
    np.testing.assert_array_equal(th_cap, th_plain)
    assert e_cap == e_plain


def test_capping_silent_coordinates_leaves_the_estimate_bitwise_unchanged() -> None:
    """Coordinates whose regressor entry is exactly 0 (a still joint's inputs): capping
    their rows of P changes neither the a priori errors nor the other coordinates'
    estimates while they stay 0 — whether they were never excited (a decoupled block of
    P) or were excited before (coupled) — and bounds them; from their first non-zero
    entry on, the step uses the capped state."""
    n, nu = 9000, 6
    rng = np.random.default_rng(6)
    Phi = rng.standard_normal((n, nu))
    Phi[:, 5] = 0.0                                      # never excited
    Phi[1000:6000, 3:5] = 0.0                            # excited, silent, excited again
    y = Phi @ rng.standard_normal(nu) + 0.05 * rng.standard_normal(n)
    kw = {"forgetting_factor": 0.99, "p0": 10.0}
    plain = rls_run(Phi, y, max_trace=np.inf, **kw)
    capped = rls_run(Phi, y, max_trace=100.0 * nu * 10.0, **kw)   # cap 100 p0
    assert capped.n_capped > 1000 and plain.n_capped == 0
    np.testing.assert_array_equal(capped.prediction_error[:6000],
                                  plain.prediction_error[:6000])
    np.testing.assert_array_equal(capped.theta_history[:6000, :3],
                                  plain.theta_history[:6000, :3])
    wound = rls_run(Phi[:6000], y[:6000], max_trace=np.inf, **kw)
    assert wound.P[5, 5] > 1e26                          # eq. 39: 10 / 0.99^6000
    assert np.diag(capped.P).max() <= 1000.0 * (1 + 1e-12)
    assert np.abs(capped.prediction_error[6000:] - plain.prediction_error[6000:]).max() > 0


def _two_joint_layout() -> tuple[int, np.ndarray]:
    """The paper's 2-joint regression (nu = 34, eq. 51-54): [r lags 2 | v_dyn lags 20 |
    u1 of joints A, B (2 each) | u2 of joints A, B (4 each)]; returns nu and B's columns."""
    b_u1 = np.arange(22 + 2, 22 + 4)
    b_u2 = np.arange(22 + 4 + 4, 22 + 4 + 8)
    return 34, np.concatenate([b_u1, b_u2])


@pytest.mark.parametrize("guard", ["default", "off"])
def test_one_joint_still_for_1_2e6_steps_then_moving(guard: str) -> None:
    """Joint B's inputs are exactly 0 for 1.2e6 steps (83 min at 4 ms) after 20 000
    steps of motion, then move again. Default guard: P bounded (each diagonal element at
    most 1e5 p0) and positive definite throughout, no reset, the estimate of the rest
    undisturbed, and on resumption no burst: the a priori error stays at the noise level
    and theta within 0.05 of the truth (start-up from P(1) = p0 I: 2.4 and 0.57). Plain
    eq. 39 ('off'): B's block grows as lambda^-k, overflows after ~7e5 steps and P has to
    be reset."""
    nu, B = _two_joint_layout()
    rng = np.random.default_rng(11)
    theta_true = 0.3 * rng.standard_normal(nu)
    A = np.setdiff1d(np.arange(nu), B)

    def segment(n: int, still: bool) -> tuple[np.ndarray, np.ndarray]:
        Phi = rng.standard_normal((n, nu))
        if still:
            Phi[:, B] = 0.0
        return Phi, Phi @ theta_true + 0.01 * rng.standard_normal(n)

    rls = RecursiveLeastSquares(nu, max_trace=None if guard == "default" else np.inf)
    start = rls.run(*segment(20_000, False))
    max_diag = 0.0
    for _ in range(12):
        rls.run(*segment(100_000, True), keep_history=False)
        P = rls.P
        max_diag = max(max_diag, float(np.max(np.diag(P))))
        if guard == "default":
            assert np.linalg.eigvalsh(P).min() > 0
            assert np.abs(rls.theta[A] - theta_true[A]).max() < 5e-3
    if guard == "off":
        assert rls.n_resets >= 1 and max_diag > 1e300
        return
    assert rls.n_resets == 0 and rls.n_capped > 1_000_000
    assert max_diag <= default_max_trace(nu, 10.0) / nu * (1 + 1e-12)
    resumed = rls.run(*segment(20_000, False))
    assert np.abs(start.prediction_error[:500]).max() > 1.0          # start-up transient
    assert np.abs(resumed.prediction_error[:500]).max() < 0.1        # noise 0.01
    assert np.abs(resumed.theta_history - theta_true).max() < 0.05
    assert np.abs(resumed.theta - theta_true).max() < 2e-3
    assert rls.n_resets == 0


@pytest.mark.parametrize("q", [0, 11, 23])
@pytest.mark.parametrize("cap", [np.inf, 2.0])
def test_regulariser_step_is_the_textbook_second_update(q: int, cap: float) -> None:
    """One kernel step with the regulariser (coordinate q, weight c) equals, to rounding,
    eq. 38–39 with the guard applied by its definition, then the textbook RLS update with
    lambda = 1 for the pseudo-measurement theta_q = theta0 (regressor sqrt(c) e_q) — with
    the guard off and acting (its scales enter the regulariser's column of P)."""
    nu, lam, c, theta0 = 24, 0.99, 0.7, 0.25
    rng = np.random.default_rng(q)
    a = rng.standard_normal((nu, nu))
    P_full = a @ a.T + 0.5 * np.eye(nu)
    P_full = (P_full + P_full.T) / 2  # exactly symmetric, as the kernel keeps P
    theta = rng.standard_normal(nu)
    phi = rng.standard_normal(nu)
    y = 0.3
    # textbook
    h = P_full @ phi
    s = phi @ h
    th = theta + h * (y - theta @ phi) / (lam + s)
    Pk = (P_full - np.outer(h, h) / (lam + s)) / lam
    over = np.diag(Pk) > cap
    wv = np.where(over, np.sqrt(cap / np.where(over, np.diag(Pk), 1.0)), 1.0)
    Pk = Pk * np.outer(wv, wv)
    e_q = np.zeros(nu)
    e_q[q] = np.sqrt(c)
    hq = Pk @ e_q
    den = 1.0 + e_q @ hq
    th = th + hq * (np.sqrt(c) * theta0 - e_q @ th) / den
    Pk = Pk - np.outer(hq, hq) / den
    # kernel (the whole matrix, kept exactly symmetric)
    P = P_full.copy()
    t = theta.copy()
    rls_update_inplace(t, P, phi, y, lam, cap, 10.0, np.empty(nu), np.empty(nu),
                       q, c, theta0, np.empty(nu))
    assert over.any() == (cap != np.inf)
    np.testing.assert_allclose(t, th, rtol=0, atol=1e-12)
    np.testing.assert_allclose(P, Pk, rtol=0, atol=1e-12)
    assert np.array_equal(P, P.T)
