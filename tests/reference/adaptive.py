"""The adaptive evaluator on a whole log, and its plain NumPy reference (tests only).

:func:`evaluate` is the product's compiled evaluator
(:func:`impactcli.detect.adaptive.evaluate_chunk`) run on a whole log as one chunk;
:func:`evaluate_reference` implements eq. 24–42 again in plain NumPy, obviously correct
and slow, for the tests to compare the kernel against (to 1e-9); :func:`threshold_inputs`
is the inputs of a whole log. The product replays logs chunk by chunk
(:mod:`impactcli.run.replay`) and never calls these.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy import signal

from impactcli.config import AdaptiveConfig
from impactcli.detect.adaptive import (
    AdaptiveResult,
    ThresholdInputs,
    default_threads,
    evaluate_chunk,
    inputs_chunk,
)
from impactcli.detect.axes import EvaluatorState
from impactcli.detect.rates import resolve_rates
from impactcli.detect.rls import REGULARIZE_EVERY, max_diag_of, regularization_weight
from impactcli.model.causal import Carry
from impactcli.types import RobotLog


def _check(r: np.ndarray, u: np.ndarray, v_stat: np.ndarray, cfg: AdaptiveConfig) -> None:
    if r.ndim != 2:
        raise ValueError(f"residual must be (N, J), got shape {r.shape}")
    if u.ndim != 3 or u.shape[1:] != r.shape:
        raise ValueError(f"inputs must be (m, N, J) = (m, {r.shape}), got {u.shape}")
    if v_stat.shape != (r.shape[1],):
        raise ValueError(f"v_stat must be ({r.shape[1]},), got {v_stat.shape}")


def threshold_inputs(log: RobotLog, cfg: AdaptiveConfig | None = None) -> ThresholdInputs:
    """(u1, u2) of a whole log (paper Sec. IV: inputs from the reference trajectory): the
    product's ``inputs_chunk`` on the log as one chunk."""
    return inputs_chunk(log, log.time_s, log.sample_rate_hz, cfg, Carry(), log.source.path)


def evaluate(
    residual: np.ndarray, inputs: np.ndarray, sample_rate_hz: float,
    v_stat: Sequence[float] | np.ndarray, cfg: AdaptiveConfig | None = None,
    threads: int | None = None, progress: Callable[[int, int], None] | None = None,
) -> AdaptiveResult:
    """The product's compiled evaluator on a whole log: ``evaluate_chunk`` on the whole log
    as one chunk from ``EvaluatorState.initial``.

    Args:
        residual: (N, J) residual r = tau_hat − tau [N·m].
        inputs: (m, N, J) threshold inputs (see :func:`threshold_inputs`).
        sample_rate_hz: fs [Hz].
        v_stat: (J,) static thresholds [N·m] (eq. 42).
        cfg: settings (Table I defaults).
        threads: > 1 runs the axes concurrently, each on a thread of its own (results are
            identical: axes are independent); None → :func:`default_threads`.
        progress: called with (axes done, axes) after each axis (every axis costs the same).
    """
    cfg = cfg or AdaptiveConfig()
    if threads is None:
        threads = default_threads(np.shape(residual)[0])
    r = np.asarray(residual)
    if r.ndim != 2:
        raise ValueError(f"residual must be (N, J), got shape {r.shape}")
    state = EvaluatorState.initial(r.shape[1], cfg, sample_rate_hz)
    res, _ = evaluate_chunk(state, r, inputs, sample_rate_hz, v_stat, cfg, threads, progress)
    return res


def evaluate_reference(
    residual: np.ndarray, inputs: np.ndarray, sample_rate_hz: float,
    v_stat: Sequence[float] | np.ndarray, cfg: AdaptiveConfig | None = None,
) -> AdaptiveResult:
    """Plain NumPy implementation of the same equations, obviously correct and slow: a
    Python loop over samples with the textbook RLS (full P), the wind-up cap applied by
    its definition, then at every REGULARIZE_EVERY-th sample the regulariser's
    pseudo-measurement theta_i = theta0 (weight c, coordinate i = (k / REGULARIZE_EVERY) mod
    nu) as one more textbook update with lambda = 1."""
    cfg = cfg or AdaptiveConfig()
    r = np.asarray(residual, dtype=np.float64)
    u = np.asarray(inputs, dtype=np.float64)
    vs = np.asarray(v_stat, dtype=np.float64)
    _check(r, u, vs, cfg)
    rates = resolve_rates(cfg, sample_rate_hz)
    n, J = r.shape
    eta, p, rho = cfg.eta, cfg.p, cfg.rho
    nu = cfg.n_params(J)
    lam = cfg.forgetting_factor
    cap = max_diag_of(nu, cfg.p0, cfg.max_trace)
    c_reg = regularization_weight(nu, lam, cfg.regularization)

    def past(x: np.ndarray, k: int, order: int) -> np.ndarray:
        """[x(k-1), ..., x(k-order)], zero before the start."""
        return np.array([x[k - d] if k - d >= 0 else 0.0 for d in range(1, order + 1)])

    res = {name: np.zeros((n, J)) for name in
           ("rt", "vd", "rf", "vf", "rr", "vr", "thr", "eps")}
    dec = np.zeros((n, J), dtype=bool)
    thetas = np.zeros((J, nu))
    capped = np.zeros(J, dtype=np.int64)
    for j in range(J):
        theta = np.full(nu, cfg.theta0)
        P = cfg.p0 * np.eye(nu)
        for k in range(n):
            parts = [past(r[:, j], k, eta), past(res["vd"][:, j], k, p)]
            for i in range(len(rho)):
                for ll in range(J):
                    parts.append(past(u[i, :, ll], k, rho[i]))
            phi = np.concatenate(parts)
            eps0 = r[k, j] - theta @ phi                                  # eq. 40
            s = phi @ P @ phi
            h = P @ phi
            gain = h / (lam + s)
            theta_new = theta + gain * eps0                               # eq. 38
            P = (P - np.outer(h, h) / (lam + s)) / lam                    # eq. 39
            over = np.diag(P) > cap                                       # wind-up guard
            if over.any():
                w = np.where(over, np.sqrt(cap / np.where(over, np.diag(P), 1.0)), 1.0)
                P = P * np.outer(w, w)                                    # W P W
                capped[j] += 1
            if c_reg > 0.0 and k % REGULARIZE_EVERY == 0:                 # regulariser
                i = (k // REGULARIZE_EVERY) % nu
                e_i = np.zeros(nu)
                e_i[i] = np.sqrt(c_reg)
                h = P @ e_i
                den = 1.0 + e_i @ h
                theta_new = theta_new + h * (np.sqrt(c_reg) * cfg.theta0 - e_i @ theta_new) / den
                P = P - np.outer(h, h) / den
            tv = theta_new if cfg.estimate == "a_posteriori" else theta
            theta = theta_new
            res["eps"][k, j] = eps0
            res["rt"][k, j] = r[k, j] - phi[:eta] @ tv[:eta]
            res["vd"][k, j] = phi[eta:] @ tv[eta:]
        thetas[j] = theta
    res["rf"] = signal.lfilter([1 - rates.a1], [1, -rates.a1], res["rt"], axis=0)
    res["vf"] = signal.lfilter([1 - rates.a2], [1, -rates.a2], res["vd"], axis=0)
    for name, src, nn in (("rr", "rf", rates.n1), ("vr", "vf", rates.n2)):
        padded = np.vstack([np.zeros((nn, J)), res[src]])
        for k in range(n):
            window = padded[k : k + nn]        # samples k-nn .. k-1
            res[name][k] = np.sqrt(np.sum(window**2, axis=0) / nn)
    res["thr"] = np.abs(vs + res["vr"])
    dec = res["rr"] > res["thr"]
    return AdaptiveResult(
        res["rt"], res["vd"], res["rf"], res["vf"], res["rr"], res["vr"], res["thr"], dec,
        res["eps"], thetas, np.zeros(J, dtype=np.int64), rates=rates, nu=nu, eta=eta,
        n_capped=capped,
    )
