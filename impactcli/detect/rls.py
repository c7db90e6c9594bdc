"""Recursive least squares with constant forgetting factor (paper eq. 36–40): the kernel.

For a regression ``y(k) = phi(k)^T theta + b(k)`` with ``nu`` parameters, one step is

    eps0(k)  = y(k) - theta(k-1)^T phi(k)                                   (40)
    g(k)     = P(k-1) phi(k) / (lambda + phi(k)^T P(k-1) phi(k))           (= P(k) phi(k))
    theta(k) = theta(k-1) + g(k) eps0(k)                                    (38)
    P(k)     = (P(k-1) - g(k) (P(k-1) phi(k))^T) / lambda                   (39)

Regularisation (docs/method.md §3, "Sensitivity, and the regularised form"): every 4th
step also adds the pseudo-measurement theta_i = theta0 with weight c for ONE coordinate
i = (k / 4) mod nu (cyclic), c = 4 nu (1 − lambda) delta (fused into eq. 39's pass): the
information matrix then carries delta I on average over time that forgetting never removes
(the minimiser of sum_i lambda^{k-i} eps_i^2 + delta |theta − theta0|^2, the regulariser
spread one coordinate at a time; within 0.88–1.13 delta at lambda = 0.999 and nu ≤ 64), so
P ≤ ~I / delta and two replays of a sample log started 1e-12 apart stay within 1e-10 of the
statistic's range instead of separating (the diagnosis and the choice of delta:
docs/method.md §3).

P is exactly symmetric by construction: :func:`rls_update_inplace` keeps the whole matrix
and makes each element of P(k) from products symmetric in (i, j) (eq. 39 as P − g g^T with
g = P phi sqrt(c), c = 1 / (lambda + phi^T P phi)), compiled without re-association
(:data:`SYMMETRIC`); P phi is then one vectorised dot product per row. Wind-up guard:
after eq. 39 every diagonal element of P is capped at ``max_trace / nu`` by a congruence
``P <- W P W``, ``w_i = min(1, sqrt(cap / P[i, i]))``: a coordinate at the cap stops
being forgotten, the others keep lambda, and where the capped regressor entries are
exactly 0 (a still joint's inputs) the step equals plain eq. 39 bit for bit. A
non-positive pivot resets P to p0 I (counted). Why this guard, its level
(:data:`DEFAULT_TRACE_FACTOR`) and what was measured: docs/method.md §3, "The wind-up guard".

The product runs this kernel inside the evaluator's per-axis loop
(:mod:`impactcli.detect.axes`); the batch, stateful and pure forms the tests check it with
are in ``tests/reference/rls.py``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

#: LLVM fast-math flags of the kernels: re-association (vectorised dot products), FMA
#: contraction, no signed zeros, reciprocal arithmetic — but NOT no-NaN/no-Inf, so the
#: positive-definiteness checks below keep working. The covariance pass drops
#: re-association (:data:`SYMMETRIC`) so that P stays exactly symmetric.
FASTMATH = {"reassoc", "contract", "nsz", "arcp"}


#: Flags of the covariance update: FASTMATH without re-association, so every element is
#: computed as written — from products symmetric in (i, j) — and P stays exactly symmetric.
SYMMETRIC = {"contract", "nsz", "arcp"}


@nb.njit(cache=True, nogil=True, fastmath=SYMMETRIC)
def _covariance_row(P: np.ndarray, q: int, g: np.ndarray, w: np.ndarray, inv_lam: float,
                    out: np.ndarray) -> None:
    """Row ``q`` of eq. 39's P(k) after the guard, as :func:`_covariance_update` makes it."""
    wq = w[q]
    gq = g[q]
    for j in range(P.shape[0]):
        out[j] = ((P[q, j] - gq * g[j]) * (wq * w[j])) * inv_lam


@nb.njit(cache=True, nogil=True, fastmath=SYMMETRIC)
def _covariance_update(P: np.ndarray, g: np.ndarray, w: np.ndarray, inv_lam: float,
                       capped: int, pr: np.ndarray, reg: bool) -> bool:
    """P <- (P − g g^T) ∘ w w^T / lambda − pr pr^T (eq. 39, the guard's congruence, the
    regulariser's rank-one term; w is all ones when ``capped`` is 0, pr only when ``reg``),
    over the whole matrix. Each element is a function of symmetric products (g_i g_j,
    w_i w_j, pr_i pr_j), evaluated as written (:data:`SYMMETRIC`), so P(k) is exactly
    symmetric when P(k−1) is. Returns False when a diagonal element is not > 0."""
    nu = P.shape[0]
    ok = True
    if capped == 0 and not reg:
        for i in range(nu):
            gi = g[i]
            for j in range(nu):
                P[i, j] = (P[i, j] - gi * g[j]) * inv_lam
            ok = ok and P[i, i] > 0.0
    elif capped == 0:
        for i in range(nu):
            gi = g[i]
            ri = pr[i]
            for j in range(nu):
                P[i, j] = (P[i, j] - gi * g[j]) * inv_lam - ri * pr[j]
            ok = ok and P[i, i] > 0.0
    elif not reg:
        for i in range(nu):
            gi = g[i]
            wi = w[i]
            for j in range(nu):
                P[i, j] = ((P[i, j] - gi * g[j]) * (wi * w[j])) * inv_lam
            ok = ok and P[i, i] > 0.0
    else:
        for i in range(nu):
            gi = g[i]
            wi = w[i]
            ri = pr[i]
            for j in range(nu):
                P[i, j] = ((P[i, j] - gi * g[j]) * (wi * w[j])) * inv_lam - ri * pr[j]
            ok = ok and P[i, i] > 0.0
    return ok


@nb.njit(cache=True, nogil=True, inline="always", fastmath=FASTMATH)
def rls_update_inplace(
    theta: np.ndarray, P: np.ndarray, phi: np.ndarray, y: float,
    forgetting_factor: float, max_diag: float, p0: float, h: np.ndarray, w: np.ndarray,
    q: int = 0, c_reg: float = 0.0, theta0: float = 0.0, pc: np.ndarray | None = None,
    g: np.ndarray | None = None,
) -> tuple[float, int, int]:
    """One RLS step (eq. 38–40) in place on ``theta`` (nu,) and ``P`` (nu, nu), then the
    wind-up guard: each diagonal element of P(k) capped at ``max_diag``, then the
    regulariser's pseudo-measurement theta_q = theta0 of weight ``c_reg`` (module
    docstring; 0: none) — one more update with lambda = 1 and regressor sqrt(c_reg) e_q:

        p_q    = P(k) e_q                   (column q of the step's P(k))
        theta <- theta + p_q c_reg (theta0 − theta_q) / (1 + c_reg P(k)_qq)
        P     <- P(k) − c_reg p_q p_q^T / (1 + c_reg P(k)_qq)

    in the same pass over P as eq. 39 (p_q is made from P(k−1) and h first).

    ``P`` is the whole symmetric covariance, kept exactly symmetric: eq. 39 is applied as
    P − g g^T with g = h sqrt(c) and the regulariser's term as pr pr^T, products symmetric
    in (i, j) (:func:`_covariance_update`).

    Args:
        theta: (nu,) estimate theta(k-1), overwritten with theta(k).
        P: (nu, nu) covariance P(k-1) (symmetric), overwritten with P(k).
        phi: (nu,) regressor phi(k).
        y: measurement y(k).
        forgetting_factor: lambda in (0, 1].
        max_diag: cap on every diagonal element of P(k) (``inf``: none, pure eq. 39).
        p0: reset value of P's diagonal if P ever lost positive definiteness.
        h, w: (nu,) work arrays.
        q, c_reg, theta0: the regulariser's coordinate, weight and target; ``pc`` (nu,) its
            work array (needed when ``c_reg`` > 0).
        g: (nu,) work array (None: one is allocated).

    Returns:
        (eps0, reset, capped) — the a priori error eq. 40; 1 if P had to be reset, else 0;
        1 if a cap scaled P this step, else 0.
    """
    nu = theta.shape[0]
    if g is None:
        g = np.empty(nu)
    # h = P phi, row by row
    for j in range(nu):
        acc = 0.0
        for i in range(nu):
            acc += P[j, i] * phi[i]
        h[j] = acc
    s = 0.0
    e = y
    for i in range(nu):
        s += phi[i] * h[i]
        e -= theta[i] * phi[i]
    reset = 0
    if not (s >= 0.0):  # P lost positive definiteness (or NaN): restart from p0 I
        for i in range(nu):
            for j in range(nu):
                P[i, j] = 0.0
            P[i, i] = p0
            h[i] = p0 * phi[i]
        s = 0.0
        for i in range(nu):
            s += phi[i] * h[i]
        reset = 1
    lam = forgetting_factor
    c = 1.0 / (lam + s)
    inv_lam = 1.0 / lam
    ec = e * c
    sc = np.sqrt(c)
    for i in range(nu):
        theta[i] += h[i] * ec
        g[i] = h[i] * sc
    # wind-up guard: w[i] = sqrt(max_diag / P(k)[i, i]) where eq. 39's diagonal would exceed
    # max_diag, else 1; P(k) <- W P(k) W (a congruence: positive definite stays so)
    capped = 0
    for i in range(nu):
        d = (P[i, i] - g[i] * g[i]) * inv_lam
        if d > max_diag:
            w[i] = np.sqrt(max_diag / d)
            capped = 1
        else:
            w[i] = 1.0
    # the regulariser: row q of P(k) (eq. 39 and the guard's W, from P(k-1) and g), then
    # theta's update; P's own is the rank-one term pr pr^T, pr = p_q sqrt(c_reg / (1 + ...))
    reg = c_reg > 0.0 and pc is not None
    if reg:
        assert pc is not None
        _covariance_row(P, q, g, w, inv_lam, pc)
        den = 1.0 / (1.0 + c_reg * pc[q])
        f = c_reg * (theta0 - theta[q]) * den
        sr = np.sqrt(c_reg * den)
        for i in range(nu):
            theta[i] += pc[i] * f
            pc[i] = pc[i] * sr
    ok = _covariance_update(P, g, w, inv_lam, capped, pc if reg and pc is not None else g, reg)
    if not ok:
        for i in range(nu):
            for j in range(nu):
                P[i, j] = 0.0
            P[i, i] = p0
        reset = 1
    return e, reset, capped


#: The regulariser acts at every REGULARIZE_EVERY-th sample (one coordinate, cyclic), with
#: that many times the weight: 4 costs a quarter of the extra pass over P at the same floor
#: (measured: docs/method.md §3, "Sensitivity, and the regularised form").
REGULARIZE_EVERY = 4


def regularization_weight(n_params: int, forgetting_factor: float, delta: float,
                          every: int = REGULARIZE_EVERY) -> float:
    """The weight c = every · nu (1 − lambda) delta of one coordinate's pseudo-measurement,
    made at every ``every``-th sample, so that each coordinate's share, forgotten by lambda,
    averages delta over time (between lambda^N c / (1 − lambda^N) and c / (1 − lambda^N),
    N = every · nu)."""
    if not delta >= 0.0:
        raise ValueError(f"regularization must be >= 0, got {delta}")
    return float(every) * float(n_params) * (1.0 - float(forgetting_factor)) * float(delta)


#: Default cap on each diagonal element of P as a multiple of p0: the default ``max_trace``
#: is ``DEFAULT_TRACE_FACTOR · nu · p0`` (the level's measurement: docs/method.md §3).
DEFAULT_TRACE_FACTOR = 1e5


def default_max_trace(n_params: int, p0: float) -> float:
    """Default ``max_trace``: ``DEFAULT_TRACE_FACTOR · n_params · p0``, i.e. each diagonal
    element of P capped at ``DEFAULT_TRACE_FACTOR · p0``."""
    return DEFAULT_TRACE_FACTOR * float(n_params) * float(p0)


def max_diag_of(n_params: int, p0: float, max_trace: float | None) -> float:
    """The kernel's per-coordinate cap ``max_trace / nu`` (None → :func:`default_max_trace`;
    ``inf`` → no cap, pure eq. 39). Hence trace(P) ≤ max_trace at every step."""
    mt = default_max_trace(n_params, p0) if max_trace is None else float(max_trace)
    if not mt > 0.0:
        raise ValueError(f"max_trace must be > 0, got {max_trace}")
    return mt / float(n_params)
