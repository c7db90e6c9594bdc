"""RLS (impactcli.detect.rls): equals (exponentially weighted) least squares, stays SPD
over millions of steps, and the bounded-trace guard stops covariance wind-up."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from impactcli.detect.rls import (
    RecursiveLeastSquares,
    default_max_trace,
    rls_run,
    rls_step,
    rls_update_inplace,
    symmetrize,
)


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
    Phi, y, _ = _data(200, 4, seed=2)
    batch = rls_run(Phi, y, forgetting_factor=0.98)
    obj = RecursiveLeastSquares(4, forgetting_factor=0.98)
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
    phi = np.empty(nu)
    resets = 0
    for _ in range(n_steps):
        row = pool[np.random.randint(pool.shape[0])]  # noqa: NPY002 (numba knows only the legacy API)
        sgn = 1.0 if np.random.random() < 0.5 else -1.0  # noqa: NPY002 (numba knows only the legacy API)
        y = 0.01 * np.random.standard_normal()  # noqa: NPY002 (numba knows only the legacy API)
        for i in range(nu):
            phi[i] = sgn * row[i]
            y += phi[i] * theta_true[i]
        _, r = rls_update_inplace(theta, P, phi, y, 0.999, 1e300, 10.0, h)
        resets += r
    return resets


def test_stays_symmetric_positive_definite_over_5e6_steps() -> None:
    """nu = 34, lambda = 0.999 (Table I), guard off: 5e6 steps (a compiled driver, 1e6 per
    chunk); P (symmetric by storage) Cholesky-factorisable after every chunk, no reset,
    estimate right at the end."""
    nu = 34
    rng = np.random.default_rng(3)
    theta_true = rng.standard_normal(nu)
    pool = rng.standard_normal((4096, nu))
    theta, P = np.zeros(nu), 10.0 * np.eye(nu)
    for chunk in range(5):
        assert _drive(theta, P, pool, theta_true, 1_000_000, chunk) == 0
        full = symmetrize(P)                      # the kernel keeps the lower triangle
        np.linalg.cholesky(full)
        assert np.linalg.eigvalsh(full).min() > 0
    np.testing.assert_allclose(theta, theta_true, atol=2e-3)


def test_windup_guard_bounds_trace_when_excitation_stops() -> None:
    """Half of the regressor goes silent for 45 000 steps (3 min at 4 ms), then returns."""
    nu, p0 = 8, 10.0
    rng = np.random.default_rng(4)
    theta_true = rng.standard_normal(nu)

    def segment(n: int, active: slice) -> tuple[np.ndarray, np.ndarray]:
        Phi = np.zeros((n, nu))
        Phi[:, active] = rng.standard_normal((n, active.stop - (active.start or 0)))
        return Phi, Phi @ theta_true + 0.05 * rng.standard_normal(n)

    segs = [segment(5000, slice(0, nu)), segment(45_000, slice(0, 4)), segment(200, slice(0, nu))]
    traces = {}
    errors = {}
    for name, mt in (("guarded", None), ("unguarded", np.inf)):
        rls = RecursiveLeastSquares(nu, forgetting_factor=0.999, p0=p0, max_trace=mt)
        tr = []
        for Phi, y in segs[:2]:
            for k0 in range(0, len(y), 1000):
                rls.run(Phi[k0:k0 + 1000], y[k0:k0 + 1000], keep_history=False)
                tr.append(np.trace(rls.P))
        run = rls.run(*segs[2])
        traces[name] = max(tr)
        errors[name] = np.abs(run.prediction_error).max()
        assert np.all(np.isfinite(rls.theta))
    assert traces["guarded"] <= default_max_trace(nu, p0) * (1 + 1e-12)
    assert traces["unguarded"] > 1e6 * traces["guarded"]       # the guard is what bounds it
    # on resumption the guarded estimator's a priori error stays at the scale of the signal
    assert errors["guarded"] < 3 * np.abs(theta_true).sum()
