"""Recursive least squares with constant forgetting factor (paper eq. 36–40).

For a regression ``y(k) = phi(k)^T theta + b(k)`` with ``nu`` parameters, one step is

    eps0(k)  = y(k) - theta(k-1)^T phi(k)                                   (40)
    g(k)     = P(k-1) phi(k) / (lambda + phi(k)^T P(k-1) phi(k))           (= P(k) phi(k))
    theta(k) = theta(k-1) + g(k) eps0(k)                                    (38)
    P(k)     = (P(k-1) - g(k) (P(k-1) phi(k))^T) / lambda                   (39)

Numerical soundness over hours of samples
-----------------------------------------
The textbook update (39) loses symmetry, then positive definiteness, after ~1e5 steps in
double precision (performance.md). Here P is symmetric by construction: the kernel
stores and updates only its lower triangle (``P[i, j]``, j ≤ i) — the "update one triangle"
remedy, without a mirror pass — and computes ``P phi`` from that triangle. This also halves
the update's work. ``tests/test_rls.py`` runs 5e6 steps at nu = 34 and checks that P stays
positive definite (Cholesky) and the estimate stays right. As a last resort, a
non-positive diagonal element or a non-positive ``phi^T P phi`` resets P to ``p0 I`` and
is counted in ``n_resets`` (never seen in the tests).

Wind-up guard (covariance wind-up when excitation stops)
-------------------------------------------------------
With lambda < 1 and a regressor that stops exciting some directions (robot standing still:
the reference inputs u are 0, v_dyn decays), P grows as lambda^-k in those directions —
0.999^-15000 ≈ 3e6 after one minute at 4 ms — and the first motion afterwards gives a huge
gain and a parameter burst. Guard chosen: **bounded trace by switched forgetting**. Before
each step the trace the update would give, ``(tr P - |h|^2 c) / lambda``, is computed in
O(nu); if it would exceed ``max_trace`` the step is done with lambda = 1 (no forgetting,
which never increases the trace). Hence ``tr P(k) <= max(tr P(1), max_trace)`` for ever.
Why this one: it costs O(nu) per step (directional forgetting costs another O(nu^2)), it
never changes the estimate's direction of update, only how much is forgotten, and the
bound has a plain meaning. Default ``max_trace = 100 · nu · p0`` — a hundred times the
trace of P(1) = p0 I. Measured (synthetic 2-joint residual on triangle references, the
scenario of ``tests/test_detect_adaptive.py``): the adaptive regression is never excited in
all 34 directions (past v_dyn are collinear, u1 is piecewise constant), so even *while
moving* the unguarded trace grows to 4.4e5 in 40 s and any bound is reached within
seconds; across bounds nu·p0 … 1e4·nu·p0 the contact pulses' peak r_rms / threshold hardly
moved (mean 1.071 … 1.080, unguarded 1.080), whereas after a 3.5 min standstill the
unguarded evaluator's r_rms blew up 3.9× (P reset twice) and every bounded one stayed
within 1.06×. The factor 100 sits in that flat middle: P may grow well above start-up in
poorly excited directions (fast re-adaptation) but never without bound. ``max_trace =
inf`` disables the guard (pure eq. 39).

Three forms (architecture.md): :func:`rls_step` (pure), :class:`RecursiveLeastSquares`
(stateful ``.update()``), :func:`rls_run` (batch, returns histories); all call the same
numba kernel :func:`rls_update_inplace`.
"""

from __future__ import annotations

from dataclasses import dataclass

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
    forgetting_factor: float, max_trace: float, p0: float, h: np.ndarray,
) -> tuple[float, int]:
    """One RLS step (eq. 38–40) in place on ``theta`` (nu,) and ``P`` (nu, nu).

    ``P`` holds the symmetric covariance in its LOWER triangle (``P[i, j]``, j ≤ i); the
    strict upper triangle is neither read nor written (use :func:`symmetrize`).

    Args:
        theta: (nu,) estimate theta(k-1), overwritten with theta(k).
        P: (nu, nu) covariance P(k-1) (lower triangle), overwritten with P(k).
        phi: (nu,) regressor phi(k).
        y: measurement y(k).
        forgetting_factor: lambda in (0, 1].
        max_trace: wind-up bound on trace(P) (``inf`` disables it).
        p0: reset value of P's diagonal if P ever lost positive definiteness.
        h: (nu,) work array.

    Returns:
        (eps0, reset) — the a priori error eq. 40 and 1 if P had to be reset, else 0.
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
    tr = 0.0
    hh = 0.0
    for i in range(nu):
        s += phi[i] * h[i]
        e -= theta[i] * phi[i]
        tr += P[i, i]
        hh += h[i] * h[i]
    reset = 0
    if not (s >= 0.0):  # P lost positive definiteness (or NaN): restart from p0 I
        for i in range(nu):
            for j in range(i + 1):
                P[i, j] = 0.0
            P[i, i] = p0
            h[i] = p0 * phi[i]
        s = 0.0
        hh = 0.0
        tr = p0 * nu
        for i in range(nu):
            s += phi[i] * h[i]
            hh += h[i] * h[i]
        reset = 1
    lam = forgetting_factor
    if (tr - hh / (lam + s)) / lam > max_trace:
        lam = 1.0
    c = 1.0 / (lam + s)
    inv_lam = 1.0 / lam
    ec = e * c
    for i in range(nu):
        theta[i] += h[i] * ec
    bad = False
    for i in range(nu):
        hic = h[i] * c
        for j in range(i + 1):
            P[i, j] = (P[i, j] - hic * h[j]) * inv_lam
        if not (P[i, i] > 0.0):
            bad = True
    if bad:
        for i in range(nu):
            for j in range(i + 1):
                P[i, j] = 0.0
            P[i, i] = p0
        reset = 1
    return e, reset


def symmetrize(P: np.ndarray) -> np.ndarray:
    """Full symmetric matrix from the lower triangle the kernels maintain."""
    low = np.tril(P)
    return low + np.tril(low, -1).T


@nb.njit(cache=True, nogil=True, fastmath=FASTMATH)
def _rls_run_kernel(
    Phi: np.ndarray, y: np.ndarray, theta: np.ndarray, P: np.ndarray,
    forgetting_factor: float, max_trace: float, p0: float, keep_history: bool,
) -> tuple[np.ndarray, np.ndarray, int]:
    n, nu = Phi.shape
    h = np.empty(nu)
    eps = np.empty(n)
    hist = np.empty((n if keep_history else 0, nu))
    resets = 0
    for k in range(n):
        e, r = rls_update_inplace(theta, P, Phi[k], y[k], forgetting_factor, max_trace, p0, h)
        eps[k] = e
        resets += r
        if keep_history:
            hist[k] = theta
    return eps, hist, resets


#: Default wind-up bound as a multiple of trace(P(1)) = nu · p0 (see the module docstring).
DEFAULT_TRACE_FACTOR = 100.0


def default_max_trace(n_params: int, p0: float) -> float:
    """Default wind-up bound ``DEFAULT_TRACE_FACTOR · n_params · p0``."""
    return DEFAULT_TRACE_FACTOR * float(n_params) * float(p0)


@dataclass(frozen=True)
class RlsRun:
    """Result of :func:`rls_run`.

    Attributes:
        theta: (nu,) final estimate theta(N).
        P: (nu, nu) final covariance P(N).
        prediction_error: (N,) a priori errors eps0(k) (eq. 40).
        theta_history: (N, nu) theta(k) after each step (empty (0, nu) if not kept).
        n_resets: number of times P had to be reset (0 in healthy runs).
    """

    theta: np.ndarray
    P: np.ndarray
    prediction_error: np.ndarray
    theta_history: np.ndarray
    n_resets: int


def rls_run(
    Phi: np.ndarray, y: np.ndarray, *, forgetting_factor: float = 0.999, p0: float = 10.0,
    theta0: np.ndarray | float = 0.0, P0: np.ndarray | None = None,
    max_trace: float | None = None, keep_history: bool = True,
) -> RlsRun:
    """Batch RLS over a whole regression (eq. 38–40).

    Args:
        Phi: (N, nu) regressors phi(k).
        y: (N,) measurements y(k).
        forgetting_factor: lambda in (0, 1].
        p0: P(1) = p0 I (ignored if ``P0`` is given) [unit of theta² / unit of y²].
        theta0: (nu,) or scalar initial estimate theta(1).
        P0: optional (nu, nu) symmetric positive definite initial covariance.
        max_trace: wind-up bound on trace(P); None → ``100 · nu · p0``; ``inf`` disables it.
        keep_history: keep theta(k) for every k.
    """
    Phi = np.ascontiguousarray(Phi, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    if Phi.ndim != 2 or y.shape != (Phi.shape[0],):
        raise ValueError(f"Phi must be (N, nu) and y (N,), got {Phi.shape} and {y.shape}")
    nu = Phi.shape[1]
    _check_lambda(forgetting_factor)
    theta = np.array(np.broadcast_to(np.asarray(theta0, dtype=np.float64), (nu,)))
    P = p0 * np.eye(nu) if P0 is None else np.array(P0, dtype=np.float64)
    P = 0.5 * (P + P.T)
    mt = default_max_trace(nu, p0) if max_trace is None else float(max_trace)
    eps, hist, resets = _rls_run_kernel(
        Phi, y, theta, P, float(forgetting_factor), mt, float(p0), bool(keep_history)
    )
    return RlsRun(theta, symmetrize(P), eps, hist, int(resets))


def rls_step(
    theta: np.ndarray, P: np.ndarray, phi: np.ndarray, y: float, *,
    forgetting_factor: float = 0.999, max_trace: float = np.inf, p0: float = 10.0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Pure RLS step: returns ``(theta(k), P(k), eps0(k))`` without touching the inputs.

    Args:
        theta: (nu,) theta(k-1).  P: (nu, nu) P(k-1).  phi: (nu,) phi(k).  y: y(k).
        forgetting_factor: lambda.  max_trace: wind-up bound (default: none).
        p0: reset diagonal should P have lost positive definiteness.
    """
    th = np.array(theta, dtype=np.float64)
    PP = np.array(P, dtype=np.float64)
    ph = np.ascontiguousarray(phi, dtype=np.float64)
    e, _ = rls_update_inplace(
        th, PP, ph, float(y), float(forgetting_factor), float(max_trace), float(p0),
        np.empty(th.shape[0]),
    )
    return th, symmetrize(PP), float(e)


class RecursiveLeastSquares:
    """Stateful RLS with constant forgetting (eq. 38–40) and the bounded-trace guard.

    Args:
        n_params: nu.
        forgetting_factor: lambda in (0, 1] (Table I: 0.999).
        p0: P(1) = p0 I (Table I: 10).
        theta0: initial estimate (Table I: 0).
        max_trace: wind-up bound; None → ``100 · n_params · p0``; ``inf`` disables it.
    """

    def __init__(
        self, n_params: int, *, forgetting_factor: float = 0.999, p0: float = 10.0,
        theta0: np.ndarray | float = 0.0, max_trace: float | None = None,
    ) -> None:
        _check_lambda(forgetting_factor)
        self.n_params = int(n_params)
        self.forgetting_factor = float(forgetting_factor)
        self.p0 = float(p0)
        self.max_trace = (
            default_max_trace(n_params, p0) if max_trace is None else float(max_trace)
        )
        self.theta = np.array(
            np.broadcast_to(np.asarray(theta0, dtype=np.float64), (self.n_params,))
        )
        self._P = self.p0 * np.eye(self.n_params)  # lower triangle is authoritative
        self.n_resets = 0
        self._h = np.empty(self.n_params)

    @property
    def P(self) -> np.ndarray:
        """(nu, nu) covariance P(k), symmetric (a copy)."""
        return symmetrize(self._P)

    def update(self, phi: np.ndarray, y: float) -> float:
        """Absorb one sample; return the a priori error eps0(k) (eq. 40)."""
        ph = np.ascontiguousarray(phi, dtype=np.float64)
        if ph.shape != (self.n_params,):
            raise ValueError(f"phi must have shape ({self.n_params},), got {ph.shape}")
        e, r = rls_update_inplace(
            self.theta, self._P, ph, float(y), self.forgetting_factor, self.max_trace,
            self.p0, self._h,
        )
        self.n_resets += int(r)
        return float(e)

    def predict(self, phi: np.ndarray) -> float:
        """phi^T theta with the current estimate."""
        return float(np.dot(phi, self.theta))

    def run(self, Phi: np.ndarray, y: np.ndarray, keep_history: bool = True) -> RlsRun:
        """Absorb a batch (continuing from the current state); return its histories."""
        Phi = np.ascontiguousarray(Phi, dtype=np.float64)
        y = np.ascontiguousarray(y, dtype=np.float64)
        eps, hist, resets = _rls_run_kernel(
            Phi, y, self.theta, self._P, self.forgetting_factor, self.max_trace, self.p0,
            keep_history,
        )
        self.n_resets += int(resets)
        return RlsRun(self.theta.copy(), self.P, eps, hist, int(resets))


def _check_lambda(lam: float) -> None:
    if not (0.0 < lam <= 1.0):
        raise ValueError(f"forgetting_factor must be in (0, 1], got {lam}")
