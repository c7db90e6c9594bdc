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
is counted in ``n_resets`` (never seen in the tests with the wind-up guard on; without it,
wind-up makes it happen — below).

Wind-up guard: each diagonal element of P capped, by congruence
----------------------------------------------------------------
With lambda < 1, P grows as lambda^-k in every direction the regressor does not excite
(0.999^-15000 ≈ 3e6 after a minute at 4 ms) and overflows after ~7e5 steps; the first
excitation afterwards meets a huge gain. In the adaptive regression (eq. 34-35, 51-54) two
kinds of directions go unexcited: (a) a still joint's input lags — exactly 0 when its
reference is constant — and (b) combinations that the motion itself never excites, e.g. on
triangle references sign(x1_ref') changes exactly where x1_ref'' is non-zero, so u1's lag
differences are proportional to u2's lags (``tests/test_detect_adaptive.py``: in 10 min of
such motion plain eq. 39 loses positive definiteness and resets P 5 times per axis, r_rms
swinging to 4× its settled level; the guard acts at 3 % of the samples: no reset, 1.07×).
Guard chosen: after eq. 39, with ``cap = max_trace / nu``,

    w_i  = min(1, sqrt(cap / P(k)[i, i]))        P(k) <- W P(k) W,   W = diag(w)

i.e. coordinate i stops being forgotten while its variance sits at the cap; the other
coordinates keep lambda. Properties: W P W is symmetric positive definite when P is (a
congruence), every P[i, i] <= cap, so trace(P) <= max_trace and |P[i, j]| <= cap; theta(k)
and eps0(k) of the step are eq. 38/40's (the gain comes from P(k-1)). **Exactness where the
regressor is silent**: if phi_i = 0, row and column i of P enter ``h = P phi`` only as
``P[j, i] phi_i = 0`` and theta_i only as ``theta_i phi_i = 0``, so capping such a
coordinate leaves eps0, theta of the other coordinates, r_tilde and v_dyn bit for bit those
of plain eq. 39 as long as phi_i stays 0 — whether its block of P is decoupled (never
excited) or coupled (excited before) — and a joint that moves again starts from
P[i, i] <= cap instead of p0 lambda^-k. Cost: O(nu) per step to find w, plus one
multiplication per stored element at the steps where a cap acts (one pass, fused into
eq. 39's). Not chosen: (i) leaving identically-zero regressor entries out of the update —
as exact, but blind to kind (b); (ii) directional forgetting (Kulhavý) — departs from
eq. 39 at every step, also where everything is excited; (iii) clipping P's eigenvalues —
exact in direction but O(nu^3); (iv) the previous guard, forgetting switched off for all
parameters whenever trace(P) would exceed a bound — a still joint's block alone fills any
bound, so on ``sample_logs/csv/assist_impacts`` it ran 11,841 / 12,172 of 18,176 steps per
axis without forgetting and 36 decision samples differed from plain eq. 39.

Level, measured (``max_trace = inf`` is plain eq. 39, same kernel and rounding): default
``max_trace = DEFAULT_TRACE_FACTOR · nu · p0`` with the factor 1e5 (each P[i, i] <= 1e6 at
p0 = 10). On the 12 sample logs (CSV, replayed with their arm's committed config) the guard
acts on assist_impacts (6,669 of 18,176 steps per axis: the elbow's 6 silent input lags)
and heavy_impacts (14,187 of 25,694: two still joints) with every output equal to plain
eq. 39 bit for bit; on 8 logs it never acts; it acts on heavy_free_triangle (1,594 steps
per axis, from 25.1 s) and heavy_free_multisine (193-309, from 23.7 s) — kind (b): u1
and u2 lag differences, growing as lambda^-k from the start — where
r_rms then departs from plain eq. 39 by up to 0.11 N·m (of 4.1) and 0.46 (of 2.6), no
decision changed. "Numerically sound" was measured as plain eq. 39 in float64 against the
same recursion in 80-bit long double: only 3 of the 12 logs agree to 1e-9 throughout
(fm_triangle, p2p, triangle of the ASSIST-like arm); the pseudo-linear loop (past v_dyn
in phi) amplifies rounding, and on the two heavy logs above plain eq. 39 had lost 1e-9 on
every axis by 8.8-19.9 s (up to 0.17 on heavy_free_multisine), before the cap first acts.
A cap of 1e4 p0 would act on assist_free_multisine and assist_clamps while plain eq. 39 is
still reproducible there, so 1e5 p0 is the lowest decade with no action where eq. 39 is
sound; higher is worse conditioned (heavy_free_triangle played 6 times, 3 min: float64 vs
long double stays 1e-4 to 5e-4 for the middle minutes with cap 1e6 against 5e-3 to 1e-2
with 1e8; plain eq. 39 resets P 3 times per axis there, neither cap does). Long standstill
(``tests/test_rls.py``, nu = 34, one joint's inputs 0 for 1.2e6 steps = 83 min at 4 ms
after 20,000 steps of motion): max P[i, i] = 1e6 = cap, P positive definite throughout, no
reset, on resumption the a priori error stays at the noise level (< 0.031 against 2.4 at
start-up) and theta within 0.014 of the truth; plain eq. 39 reached 1.5e301 and reset P
twice. In the evaluator (``tests/test_detect_adaptive.py``): joint 2 still for 250,000
samples while joint 1 moves — plain eq. 39 reset P 10 times per axis and joint 1's r_rms
swung to 3.7× its level before, the guard 0 resets and r_rms within 0.97×; 3.5 min of
full standstill — plain r_rms 3.9× after resuming, the guard 1.06×.

``max_trace`` (config ``adaptive.max_trace``, read from old configs unchanged) still bounds
trace(P), now by capping each diagonal element at ``max_trace / nu``; ``inf`` disables the
guard. An old config that wrote the former default ``100 · nu · p0`` out caps each
element at 100 p0 — below what moving logs reach in excited directions (6e4 on
assist_free_triangle), so that replay departs from eq. 39.

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
    forgetting_factor: float, max_diag: float, p0: float, h: np.ndarray, w: np.ndarray,
) -> tuple[float, int, int]:
    """One RLS step (eq. 38–40) in place on ``theta`` (nu,) and ``P`` (nu, nu), then the
    wind-up guard: each diagonal element of P(k) capped at ``max_diag`` (module docstring).

    ``P`` holds the symmetric covariance in its LOWER triangle (``P[i, j]``, j ≤ i); the
    strict upper triangle is neither read nor written (use :func:`symmetrize`).

    Args:
        theta: (nu,) estimate theta(k-1), overwritten with theta(k).
        P: (nu, nu) covariance P(k-1) (lower triangle), overwritten with P(k).
        phi: (nu,) regressor phi(k).
        y: measurement y(k).
        forgetting_factor: lambda in (0, 1].
        max_diag: cap on every diagonal element of P(k) (``inf``: none, pure eq. 39).
        p0: reset value of P's diagonal if P ever lost positive definiteness.
        h, w: (nu,) work arrays.

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
    bad = False
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
    if bad:
        for i in range(nu):
            for j in range(i + 1):
                P[i, j] = 0.0
            P[i, i] = p0
        reset = 1
    return e, reset, capped


def symmetrize(P: np.ndarray) -> np.ndarray:
    """Full symmetric matrix from the lower triangle the kernels maintain."""
    low = np.tril(P)
    return low + np.tril(low, -1).T


@nb.njit(cache=True, nogil=True, fastmath=FASTMATH)
def _rls_run_kernel(
    Phi: np.ndarray, y: np.ndarray, theta: np.ndarray, P: np.ndarray,
    forgetting_factor: float, max_diag: float, p0: float, keep_history: bool,
) -> tuple[np.ndarray, np.ndarray, int, int]:
    n, nu = Phi.shape
    h = np.empty(nu)
    w = np.empty(nu)
    eps = np.empty(n)
    hist = np.empty((n if keep_history else 0, nu))
    resets = 0
    capped = 0
    for k in range(n):
        e, r, c = rls_update_inplace(theta, P, Phi[k], y[k], forgetting_factor, max_diag, p0,
                                     h, w)
        eps[k] = e
        resets += r
        capped += c
        if keep_history:
            hist[k] = theta
    return eps, hist, resets, capped


#: Default cap on each diagonal element of P as a multiple of p0 (module docstring): the
#: default ``max_trace`` is ``DEFAULT_TRACE_FACTOR · nu · p0``.
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


@dataclass(frozen=True)
class RlsRun:
    """Result of :func:`rls_run`.

    Attributes:
        theta: (nu,) final estimate theta(N).
        P: (nu, nu) final covariance P(N).
        prediction_error: (N,) a priori errors eps0(k) (eq. 40).
        theta_history: (N, nu) theta(k) after each step (empty (0, nu) if not kept).
        n_resets: number of times P had to be reset (0 in healthy runs).
        n_capped: number of steps at which a wind-up cap scaled P.
    """

    theta: np.ndarray
    P: np.ndarray
    prediction_error: np.ndarray
    theta_history: np.ndarray
    n_resets: int
    n_capped: int = 0


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
        max_trace: wind-up guard: every diagonal element of P capped at ``max_trace / nu``;
            None → ``DEFAULT_TRACE_FACTOR · nu · p0``; ``inf`` disables it (pure eq. 39).
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
    eps, hist, resets, capped = _rls_run_kernel(
        Phi, y, theta, P, float(forgetting_factor), max_diag_of(nu, p0, max_trace),
        float(p0), bool(keep_history),
    )
    return RlsRun(theta, symmetrize(P), eps, hist, int(resets), int(capped))


def rls_step(
    theta: np.ndarray, P: np.ndarray, phi: np.ndarray, y: float, *,
    forgetting_factor: float = 0.999, max_trace: float | None = np.inf, p0: float = 10.0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Pure RLS step: returns ``(theta(k), P(k), eps0(k))`` without touching the inputs.

    Args:
        theta: (nu,) theta(k-1).  P: (nu, nu) P(k-1).  phi: (nu,) phi(k).  y: y(k).
        forgetting_factor: lambda.
        max_trace: wind-up guard, each diagonal element of P capped at ``max_trace / nu``
            (default ``inf``: none, pure eq. 39; None: the default guard).
        p0: reset diagonal should P have lost positive definiteness.
    """
    th = np.array(theta, dtype=np.float64)
    PP = np.array(P, dtype=np.float64)
    ph = np.ascontiguousarray(phi, dtype=np.float64)
    e, _, _ = rls_update_inplace(
        th, PP, ph, float(y), float(forgetting_factor), max_diag_of(th.shape[0], p0, max_trace),
        float(p0), np.empty(th.shape[0]), np.empty(th.shape[0]),
    )
    return th, symmetrize(PP), float(e)


class RecursiveLeastSquares:
    """Stateful RLS with constant forgetting (eq. 38–40) and the per-coordinate wind-up cap.

    Args:
        n_params: nu.
        forgetting_factor: lambda in (0, 1] (Table I: 0.999).
        p0: P(1) = p0 I (Table I: 10).
        theta0: initial estimate (Table I: 0).
        max_trace: wind-up guard, each diagonal element of P capped at ``max_trace /
            n_params``; None → ``DEFAULT_TRACE_FACTOR · n_params · p0``; ``inf`` disables it.
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
        self.max_diag = max_diag_of(self.n_params, self.p0, self.max_trace)
        self.theta = np.array(
            np.broadcast_to(np.asarray(theta0, dtype=np.float64), (self.n_params,))
        )
        self._P = self.p0 * np.eye(self.n_params)  # lower triangle is authoritative
        self.n_resets = 0
        self.n_capped = 0
        self._h = np.empty(self.n_params)
        self._w = np.empty(self.n_params)

    @property
    def P(self) -> np.ndarray:
        """(nu, nu) covariance P(k), symmetric (a copy)."""
        return symmetrize(self._P)

    def update(self, phi: np.ndarray, y: float) -> float:
        """Absorb one sample; return the a priori error eps0(k) (eq. 40)."""
        ph = np.ascontiguousarray(phi, dtype=np.float64)
        if ph.shape != (self.n_params,):
            raise ValueError(f"phi must have shape ({self.n_params},), got {ph.shape}")
        e, r, c = rls_update_inplace(
            self.theta, self._P, ph, float(y), self.forgetting_factor, self.max_diag, self.p0,
            self._h, self._w,
        )
        self.n_resets += int(r)
        self.n_capped += int(c)
        return float(e)

    def predict(self, phi: np.ndarray) -> float:
        """phi^T theta with the current estimate."""
        return float(np.dot(phi, self.theta))

    def run(self, Phi: np.ndarray, y: np.ndarray, keep_history: bool = True) -> RlsRun:
        """Absorb a batch (continuing from the current state); return its histories."""
        Phi = np.ascontiguousarray(Phi, dtype=np.float64)
        y = np.ascontiguousarray(y, dtype=np.float64)
        eps, hist, resets, capped = _rls_run_kernel(
            Phi, y, self.theta, self._P, self.forgetting_factor, self.max_diag, self.p0,
            keep_history,
        )
        self.n_resets += int(resets)
        self.n_capped += int(capped)
        return RlsRun(self.theta.copy(), self.P, eps, hist, int(resets), int(capped))


def _check_lambda(lam: float) -> None:
    if not (0.0 < lam <= 1.0):
        raise ValueError(f"forgetting_factor must be in (0, 1], got {lam}")
