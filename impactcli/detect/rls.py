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

P is symmetric by construction: :func:`rls_update_inplace` stores and updates only its
lower triangle (which also halves the work). Wind-up guard: after eq. 39 every diagonal
element of P is capped at ``max_trace / nu`` by a congruence ``P <- W P W``,
``w_i = min(1, sqrt(cap / P[i, i]))``: a coordinate at the cap stops being forgotten, the
others keep lambda, and where the capped regressor entries are exactly 0 (a still joint's
inputs) the step equals plain eq. 39 bit for bit. A non-positive pivot resets P to p0 I
(counted). Why this guard, its level (:data:`DEFAULT_TRACE_FACTOR`) and what was measured:
docs/method.md §3, "The wind-up guard".

The product runs this kernel inside the evaluator's per-axis loop
(:mod:`impactcli.detect.axes`); the batch, stateful and pure forms the tests check it with
are in ``tests/reference/rls.py``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

#: LLVM fast-math flags of the kernels: re-association (vectorised dot products), FMA
#: contraction, no signed zeros, reciprocal arithmetic — but NOT no-NaN/no-Inf, so the
#: positive-definiteness checks below keep working. Symmetry does not depend on rounding:
#: only one triangle is stored.
FASTMATH = {"reassoc", "contract", "nsz", "arcp"}


@nb.njit(cache=True, nogil=True, inline="always", fastmath=FASTMATH)
def rls_update_inplace(
    theta: np.ndarray, P: np.ndarray, phi: np.ndarray, y: float,
    forgetting_factor: float, max_diag: float, p0: float, h: np.ndarray, w: np.ndarray,
    q: int = 0, c_reg: float = 0.0, theta0: float = 0.0, pc: np.ndarray | None = None,
) -> tuple[float, int, int]:
    """One RLS step (eq. 38–40) in place on ``theta`` (nu,) and ``P`` (nu, nu), then the
    wind-up guard: each diagonal element of P(k) capped at ``max_diag``, then the
    regulariser's pseudo-measurement theta_q = theta0 of weight ``c_reg`` (module
    docstring; 0: none) — one more update with lambda = 1 and regressor sqrt(c_reg) e_q:

        p_q    = P(k) e_q                   (column q of the step's P(k))
        theta <- theta + p_q c_reg (theta0 − theta_q) / (1 + c_reg P(k)_qq)
        P     <- P(k) − c_reg p_q p_q^T / (1 + c_reg P(k)_qq)

    fused into eq. 39's pass over P (p_q is made from P(k−1) and h first).

    ``P`` holds the symmetric covariance in its LOWER triangle (``P[i, j]``, j ≤ i); the
    strict upper triangle is neither read nor written.

    Args:
        theta: (nu,) estimate theta(k-1), overwritten with theta(k).
        P: (nu, nu) covariance P(k-1) (lower triangle), overwritten with P(k).
        phi: (nu,) regressor phi(k).
        y: measurement y(k).
        forgetting_factor: lambda in (0, 1].
        max_diag: cap on every diagonal element of P(k) (``inf``: none, pure eq. 39).
        p0: reset value of P's diagonal if P ever lost positive definiteness.
        h, w: (nu,) work arrays.
        q, c_reg, theta0: the regulariser's coordinate, weight and target; ``pc`` (nu,) its
            work array (needed when ``c_reg`` > 0).

    Returns:
        (eps0, reset, capped) — the a priori error eq. 40; 1 if P had to be reset, else 0;
        1 if a cap scaled P this step, else 0.
    """
    nu = theta.shape[0]
    # h = P phi from the lower triangle: row j gives P[j, :j] (axpy) and its dot with phi
    for i in range(nu):
        h[i] = 0.0
    for j in range(nu):
        pj = phi[j]
        acc = 0.0
        for i in range(j):
            h[i] += P[j, i] * pj
            acc += P[j, i] * phi[i]
        h[j] += acc + P[j, j] * pj
    s = 0.0
    e = y
    for i in range(nu):
        s += phi[i] * h[i]
        e -= theta[i] * phi[i]
    reset = 0
    if not (s >= 0.0):  # P lost positive definiteness (or NaN): restart from p0 I
        for i in range(nu):
            for j in range(i + 1):
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
    for i in range(nu):
        theta[i] += h[i] * ec
    # wind-up guard: w[i] = sqrt(max_diag / P(k)[i, i]) where eq. 39's diagonal would exceed
    # max_diag, else 1; P(k) <- W P(k) W (a congruence: positive definite stays so)
    capped = 0
    for i in range(nu):
        d = (P[i, i] - h[i] * h[i] * c) * inv_lam
        if d > max_diag:
            w[i] = np.sqrt(max_diag / d)
            capped = 1
        else:
            w[i] = 1.0
    # the regulariser: column q of P(k) (eq. 39 and the guard's W, from P(k-1) and h), then
    # theta's update; P's own is fused into eq. 39's pass below (g_i p_q[j])
    cd = 0.0
    if c_reg > 0.0 and pc is not None:
        hqc = h[q] * c
        wq = w[q] * inv_lam
        for j in range(nu):
            pjq = P[q, j] if j <= q else P[j, q]
            pc[j] = (pjq - hqc * h[j]) * (wq * w[j])
        den = 1.0 / (1.0 + c_reg * pc[q])
        f = c_reg * (theta0 - theta[q]) * den
        for i in range(nu):
            theta[i] += pc[i] * f
        cd = c_reg * den
    bad = False
    if cd == 0.0:
        if capped == 0:
            for i in range(nu):
                hic = h[i] * c
                for j in range(i + 1):
                    P[i, j] = (P[i, j] - hic * h[j]) * inv_lam
                if not (P[i, i] > 0.0):
                    bad = True
        else:
            for i in range(nu):
                hic = h[i] * c
                wi = w[i] * inv_lam
                for j in range(i + 1):
                    P[i, j] = (P[i, j] - hic * h[j]) * (wi * w[j])
                if not (P[i, i] > 0.0):
                    bad = True
    else:
        assert pc is not None
        for i in range(nu):
            hic = h[i] * c
            wi = w[i] * inv_lam
            gi = cd * pc[i]
            for j in range(i + 1):
                P[i, j] = (P[i, j] - hic * h[j]) * (wi * w[j]) - gi * pc[j]
            if not (P[i, i] > 0.0):
                bad = True
    if bad:
        for i in range(nu):
            for j in range(i + 1):
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
