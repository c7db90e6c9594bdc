"""The RLS of eq. 36–40 in the three forms of the style guide (docs/architecture.md,
"Three forms"): :func:`rls_step` (pure), :class:`RecursiveLeastSquares` (stateful
``.update()``) and :func:`rls_run` (batch, returning histories). All call the product's
kernel :func:`impactcli.detect.rls.rls_update_inplace`; the product itself runs that kernel
inside the evaluator's per-axis loop (:mod:`impactcli.detect.axes`), so these forms live
with the tests that check the kernel against known truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from impactcli.detect.rls import (
    FASTMATH,
    default_max_trace,
    max_diag_of,
    rls_update_inplace,
)


def checked_symmetric(P: np.ndarray) -> np.ndarray:
    """A copy of the kernel's P, which it keeps whole and exactly symmetric (every element
    from products symmetric in (i, j)): asserted bit for bit."""
    assert np.array_equal(P, P.T), "the kernel's P is not exactly symmetric"
    return np.array(P)


@nb.njit(cache=True, nogil=True, fastmath=FASTMATH)
def run_kernel(
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
    check_lambda(forgetting_factor)
    theta = np.array(np.broadcast_to(np.asarray(theta0, dtype=np.float64), (nu,)))
    P = p0 * np.eye(nu) if P0 is None else np.array(P0, dtype=np.float64)
    P = 0.5 * (P + P.T)
    eps, hist, resets, capped = run_kernel(
        Phi, y, theta, P, float(forgetting_factor), max_diag_of(nu, p0, max_trace),
        float(p0), bool(keep_history),
    )
    return RlsRun(theta, checked_symmetric(P), eps, hist, int(resets), int(capped))


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
    return th, checked_symmetric(PP), float(e)


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
        check_lambda(forgetting_factor)
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
        self._P = self.p0 * np.eye(self.n_params)
        self.n_resets = 0
        self.n_capped = 0
        self._h = np.empty(self.n_params)
        self._w = np.empty(self.n_params)

    @property
    def P(self) -> np.ndarray:
        """(nu, nu) covariance P(k), symmetric (a copy)."""
        return checked_symmetric(self._P)

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
        eps, hist, resets, capped = run_kernel(
            Phi, y, self.theta, self._P, self.forgetting_factor, self.max_diag, self.p0,
            keep_history,
        )
        self.n_resets += int(resets)
        self.n_capped += int(capped)
        return RlsRun(self.theta.copy(), self.P, eps, hist, int(resets), int(capped))


def check_lambda(lam: float) -> None:
    if not (0.0 < lam <= 1.0):
        raise ValueError(f"forgetting_factor must be in (0, 1], got {lam}")
