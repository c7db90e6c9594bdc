"""Residual generation, causal (docs/method.md §1, §2, §8; paper eq. 7–8).

Two generators, both causal (sample k uses samples 0..k only), both estimating the external
torque with the same sign: with M q'' + n(q, q') = tau + tau_ext, r ≈ tau_ext.

* ``inverse_dynamics`` (the paper's, eq. 7–8): r = tau_hat − G tau, where
  tau_hat = Y(G q, sG q, s²G q) theta is the model torque from the causal state-variable
  filter G(s) of :func:`causal_derivatives`, and the measured torque passes through the
  same G (docs/method.md §8: consistent filtering lowers the residual's noise floor 2–5×);
  ``filter_torque=False`` uses the raw torque instead.
* ``momentum_observer`` (De Luca et al.): with the generalized momentum p = M(q) q',
  r(k) = K [ p(k) − p(0) − Σ_{i<k} (tau(i) − n(i) + Ṁq'(i) + r(i)) dt ], i.e. dr/dt =
  K (tau_ext − r): a first-order estimate of tau_ext with bandwidth K [1/s] that needs no
  acceleration. M(q) comes from the regressor (M e_i = Y(q, 0, e_i) θ − Y(q, 0, 0) θ),
  n = Y(q, q', 0) θ (Coriolis, gravity, friction, offset), Ṁ q' by a backward difference of
  M along the trajectory. Positions and velocities come from the same causal filter G, and
  the torque is passed through G when ``filter_torque``. For this generator ``tau_used``
  is the input torque through the observer's own first-order lag K/(s + K) and
  ``tau_hat = tau_used + r`` (the model torque the observer implies).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..errors import ModelError
from ..types import RobotLog
from .causal import Carry
from .derivatives import (
    MAX_CUTOFF_FRACTION,
    causal_derivatives,
    causal_lowpass,
    clip_cutoff,
    first_order_lowpass,
    svf_coefficients,
)
from .rigid import RigidModel

GENERATORS: tuple[str, ...] = ("inverse_dynamics", "momentum_observer")


@dataclass(frozen=True)
class ResidualOptions:
    """Settings of :func:`compute_residual`.

    Attributes:
        cutoff_hz: cut-off of the causal derivative filter G [Hz] (clipped below 0.4 fs).
        filter_torque: pass the measured torque through the same G (docs/method.md §8; default).
        generator: ``inverse_dynamics`` (eq. 7–8) or ``momentum_observer`` (De Luca).
        observer_gain: K of the momentum observer [1/s] (bandwidth K / 2π Hz); K × Ts < 1.
        coulomb_through_filter: when the torque is filtered, compute the Coulomb term
            fc tanh(q'/v_s) from a wide-band causal velocity estimate (the same filter at
            0.4 fs) and pass it through G like the torque: G(fc tanh(q')) instead of
            fc tanh(G q'). The measured torque's friction step at a velocity reversal is
            smoothed by G; without this the model's step stays sharp and the residual
            spikes at every reversal (rigid 2-link test arm, fc = 0.4/0.25 N·m,
            v_s = 0.01 rad/s, largest |r| in free motion: 20 Hz 0.10 N·m without, 0.034
            with; 10 Hz 0.20 vs 0.020).
    """

    cutoff_hz: float = 20.0
    filter_torque: bool = True
    generator: str = "inverse_dynamics"
    observer_gain: float = 50.0
    coulomb_through_filter: bool = True

    def __post_init__(self) -> None:
        if self.generator not in GENERATORS:
            raise ModelError(
                f"residual generator must be one of {', '.join(GENERATORS)}, got {self.generator!r}"
            )
        if not self.observer_gain > 0:
            raise ModelError(f"observer_gain must be positive, got {self.observer_gain!r}")


@dataclass(frozen=True, eq=False)
class ResidualResult:
    """Causal residual of one log (all arrays (N, J), joints in ``joint_names`` order).

    Attributes:
        r: residual tau_hat − tau_used [N·m] (≈ external torque, eq. 8).
        tau_hat: model torque [N·m].
        tau_used: measured torque after the same causal filter [N·m].
        q_f, qd, qdd: causally filtered position [rad], velocity [rad/s], acceleration [rad/s²].
        generator: which generator made ``r``.
        settings: the options used, with the effective (clipped) cut-off.
    """

    joint_names: tuple[str, ...]
    r: np.ndarray
    tau_hat: np.ndarray
    tau_used: np.ndarray
    q_f: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    generator: str
    settings: dict[str, Any]


def _log_columns(model: RigidModel, log: RobotLog) -> list[int]:
    missing = [j for j in model.joint_names if j not in log.joint_names]
    if missing:
        raise ModelError(
            f"{log.source.path}: the model's joints {missing} are not in the log "
            f"(log joints: {list(log.joint_names)})"
        )
    return [log.joint_names.index(j) for j in model.joint_names]


def causal_velocity(dt: float, q: np.ndarray, cutoff_hz: float, carry: Carry | None,
                    name: str) -> np.ndarray:
    """The velocity of :func:`causal_derivatives` alone (s G q: the same filter, state
    and values). The Coulomb correction and the replay's joint speed read only the
    velocity; the position and acceleration filters they also ran were unused (two of
    the residual's seven (n, J) filters)."""
    b, a = svf_coefficients(dt, cutoff_hz)[1]
    return (carry if carry is not None else Carry()).lfilter(
        f"{name}.sG", b, a, np.asarray(q, dtype=np.float64), "steady")


def _coulomb_correction(
    model: RigidModel, q: np.ndarray, qd: np.ndarray, dt: float, cutoff: float,
    carry: Carry | None = None,
) -> np.ndarray:
    """(N, J) G(fc tanh(q'_fast / v_s)) − fc tanh(q'_G / v_s): add to the model torque."""
    vs = float(model.structure.get("coulomb_slope_rad_s", 0.0) or 0.0)
    names = model.param_names
    fc = np.array([
        model.theta[names.index(f"{j}.fc")] if f"{j}.fc" in names else 0.0
        for j in model.joint_names
    ])
    if vs <= 0 or not np.any(fc):
        return np.zeros_like(qd)
    fast_cut = 0.999 * MAX_CUTOFF_FRACTION / dt
    qd_fast = causal_velocity(dt, q, fast_cut, carry, "q_fast")
    smooth = causal_lowpass(fc * np.tanh(qd_fast / vs), dt, cutoff, carry, "coulomb")
    return np.asarray(smooth - fc * np.tanh(qd / vs))


def momentum_observer(
    model: RigidModel, q: np.ndarray, qd: np.ndarray, tau: np.ndarray, dt: float, gain: float,
    n_correction: np.ndarray | None = None, carry: Carry | None = None,
) -> np.ndarray:
    """(N, J) generalized-momentum observer residual [N·m] (De Luca), causal.

    Args:
        model: the rigid model (M(q), n(q, q') from its regressor).
        q, qd: (N, J) positions [rad] and velocities [rad/s] (causally filtered).
        tau: (N, J) input torque [N·m]. dt: sample period [s]. gain: K [1/s].
        n_correction: optional (N, J) added to n(q, q') (the Coulomb correction).
        carry: the state after the previous chunk (:mod:`impactcli.model.causal`: the previous
            sample's p, M and u, and the observer's delay line), or None for a whole log.
    """
    alpha = gain * dt
    if not alpha < 1.0:
        raise ModelError(
            f"momentum observer gain {gain:g} 1/s is too high for the sample period "
            f"{dt:g} s (need gain × period < 1)"
        )
    carry = carry if carry is not None else Carry()
    m = model.mass_matrix(q)
    p = np.einsum("nij,nj->ni", m, qd)
    n_term = model.predict(q, qd, np.zeros_like(q))
    if n_correction is not None:
        n_term = n_term + n_correction
    m_prev = carry.previous("observer.M", m)
    mdot_qd = np.zeros_like(q)
    if m_prev is None:  # the log's first sample: no step before it
        mdot_qd[1:] = np.einsum("nij,nj->ni", (m[1:] - m[:-1]) / dt, qd[1:])
    else:
        mdot_qd[:] = np.einsum("nij,nj->ni", (m - m_prev) / dt, qd)
    u = tau - n_term + mdot_qd
    p_prev = carry.previous("observer.p", p)
    u_prev = carry.previous("observer.u", u)
    x = np.zeros_like(q)
    if p_prev is None:
        x[1:] = gain * ((p[1:] - p[:-1]) - dt * u[:-1])
    else:
        assert u_prev is not None
        x[:] = gain * ((p - p_prev) - dt * u_prev)
    return carry.lfilter("observer", np.array([1.0]), np.array([1.0, alpha - 1.0]), x, "rest")


def compute_residual(
    model: RigidModel, log: RobotLog, options: ResidualOptions = ResidualOptions()
) -> ResidualResult:
    """Causal residual of ``log`` under ``model`` (eq. 7–8, or the momentum observer).

    Joints are matched by name; the result is in the model's joint order.
    Raises ModelError when a model joint is missing from the log.
    """
    cols = _log_columns(model, log)
    return residual_chunk(model, log.position[:, cols], log.torque[:, cols],
                          log.sample_period_s, options)


def residual_chunk(
    model: RigidModel, q: np.ndarray, tau: np.ndarray, dt: float,
    options: ResidualOptions = ResidualOptions(), carry: Carry | None = None,
) -> ResidualResult:
    """The residual of one chunk, continued from ``carry`` (:func:`compute_residual` is
    this on the whole log with a fresh carry: one implementation).

    Args:
        model: the rigid model.
        q: (n, J) positions [rad] and tau: (n, J) torques [N·m], in the model's joint order.
        dt: the whole log's sample period [s] (not the chunk's).
        options: the generator's settings.
        carry: the filters' state after the previous chunk (updated in place), or None.
    """
    cutoff = clip_cutoff(options.cutoff_hz, 1.0 / dt, "derivative cut-off")
    q = np.asarray(q, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    q_f, qd, qdd = causal_derivatives(dt, q, cutoff, carry, "q")
    tau_in = causal_lowpass(tau, dt, cutoff, carry, "tau") if options.filter_torque \
        else np.array(tau)
    corr = None
    if options.filter_torque and options.coulomb_through_filter:
        corr = _coulomb_correction(model, q, qd, dt, cutoff, carry)
    if options.generator == "inverse_dynamics":
        tau_hat = model.predict(q_f, qd, qdd)
        if corr is not None:
            tau_hat = tau_hat + corr
        tau_used = tau_in
        r = tau_hat - tau_used
    else:
        r = momentum_observer(model, q_f, qd, tau_in, dt, options.observer_gain, corr, carry)
        tau_used = first_order_lowpass(tau_in, dt, options.observer_gain, carry, "tau_obs")
        tau_hat = tau_used + r
    settings = asdict(options)
    settings["cutoff_hz_effective"] = cutoff
    settings["filter"] = "2nd-order Butterworth state-variable filter (bilinear, prewarped), causal"
    arrays = [r, tau_hat, tau_used, q_f, qd, qdd]
    for a in arrays:
        a.setflags(write=False)
    return ResidualResult(
        joint_names=model.joint_names, r=r, tau_hat=tau_hat, tau_used=tau_used,
        q_f=q_f, qd=qd, qdd=qdd, generator=options.generator, settings=settings,
    )
