"""The controller's own channels: model torque and external-torque estimate (numba).

The simulated controller computes both *online* from what it measures — the quantised
motor position q, the drive's velocity estimate v (a low-passed backward difference) and
the logged motor torque tau — with its NOMINAL rigid model (eq. 7: M_r = M + diag(I_mot),
H = C v + g, F = (Fv_m + Fv_a) v + (Fc_m + Fc_a) tanh(v / v_c)), so both carry the model
error a real controller's carry. Derivation and measured choices: docs/method.md §6, "The
simulated controller's channels".

``torque_model`` (eq. 8's tau_hat on the measured motion)::

    tau_m(k) = M_r(q_k) a_k + H(q_k, v_k) + F(v_k),
    a_k = a_{k-1} + beta ((v_k - v_{k-1}) / Ts - a_{k-1}),  beta = 1 - exp(-2 pi f_a Ts)

``torque_ext``: the generalized-momentum observer (De Luca & Mattone 2003), forward Euler,
then a first-order low-pass (``ArmParams.torque_ext_cutoff_hz``)::

    p_k = M_r(q_k) v_k,   n = C(q, v) v + g(q) + F(v)
    S_k = S_{k-1} + Ts (tau_{k-1} - n_{k-1} + Mdot_{k-1} v_{k-1} + r_{k-1}),   S_0 = 0
    r_k = K (p_k - p_0 - S_k),   y_k = y_{k-1} + gamma (r_k - y_{k-1}),   r_0 = y_0 = 0

Sign: r ≈ +tau_ext (the torque acting ON the joints, Jᵀ F). Logged values are quantised to
the controller's torque LSB (``ArmParams.controller_torque_lsb``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kernel import HV, N_SCRATCH, kin_w, mass_matrix_k, rnea_k

#: Step of the central difference giving Mdot v [s] (the displacement is eps · v [rad]).
MDOT_EPS_S = 1e-5


@njit(cache=True, error_model="numpy")
def controller_channels(pos: np.ndarray, vel: np.ndarray, tau: np.ndarray, ts: float,
                        lengths: np.ndarray, mass: np.ndarray, com: np.ndarray,
                        inertia: np.ndarray, i_mot: np.ndarray, fv: np.ndarray,
                        fc: np.ndarray, v_c: float, gx: float, gy: float, gain: float,
                        acc_beta: float, ext_gamma: float, out_model: np.ndarray,
                        out_ext: np.ndarray) -> None:
    """Model torque and momentum-observer output (module docstring) over a whole log.

    pos, vel, tau (N, n): measured motor position [rad], velocity estimate [rad/s] and
    motor torque [N·m]; ts sample period [s]; lengths, mass, com (distance [m]), inertia
    (about the COM), i_mot (reflected motor inertia), fv, fc (rigid viscous and Coulomb
    friction) (n,) — the NOMINAL model; v_c Coulomb smoothing [rad/s]; gravity (gx, gy);
    gain K [1/s]; acc_beta and ext_gamma the gains of the acceleration and output low-passes
    (1: none). Fills out_model and out_ext (N, n) [N·m], unquantised.
    """
    n_samples, n = pos.shape
    w = np.zeros((N_SCRATCH, n + 1))
    wp = np.zeros((N_SCRATCH, n + 1))
    mm = np.empty((n, n))
    mp = np.empty((n, n))
    mq = np.empty((n, n))
    qs = np.empty(n)
    acc = np.zeros(n)
    p0 = np.zeros(n)
    s_int = np.zeros(n)
    beta_prev = np.zeros(n)  # tau - n + Mdot v at the previous sample
    r = np.zeros(n)
    y = np.zeros(n)
    eps = MDOT_EPS_S
    for k in range(n_samples):
        # acceleration: low-passed difference of the velocity estimate
        if k > 0:
            for j in range(n):
                acc[j] += acc_beta * ((vel[k, j] - vel[k - 1, j]) / ts - acc[j])
        kin_w(pos[k], 0, n, lengths, w)
        mass_matrix_k(n, mass, com, inertia, w, mm)
        rnea_k(n, vel[k], 0, vel[k], -1, lengths, mass, com, inertia, gx, gy, w, w, HV)
        # Mdot v: central difference of M along v
        for j in range(n):
            qs[j] = pos[k, j] + eps * vel[k, j]
        kin_w(qs, 0, n, lengths, wp)
        mass_matrix_k(n, mass, com, inertia, wp, mp)
        for j in range(n):
            qs[j] = pos[k, j] - eps * vel[k, j]
        kin_w(qs, 0, n, lengths, wp)
        mass_matrix_k(n, mass, com, inertia, wp, mq)
        for i in range(n):
            v = vel[k, i]
            fric = fv[i] * v + fc[i] * math.tanh(v / v_c)
            nl = w[HV, i] + fric  # n = C v + g + F
            ma = i_mot[i] * acc[i]
            p = i_mot[i] * v
            mdv = 0.0
            for c in range(n):
                ma += mm[i, c] * acc[c]
                p += mm[i, c] * vel[k, c]
                mdv += (mp[i, c] - mq[i, c]) / (2.0 * eps) * vel[k, c]
            out_model[k, i] = ma + nl
            if k == 0:
                p0[i] = p
            else:
                s_int[i] += ts * (beta_prev[i] + r[i])
            r[i] = gain * (p - p0[i] - s_int[i])
            y[i] += ext_gamma * (r[i] - y[i])
            out_ext[k, i] = y[i]
            beta_prev[i] = tau[k, i] - nl + mdv


def quantise(x: np.ndarray, lsb: float) -> np.ndarray:
    """x rounded to the nearest multiple of lsb [same unit] (lsb <= 0: a copy of x)."""
    if lsb <= 0:
        return np.array(x, dtype=np.float64)
    return np.round(np.asarray(x) / lsb) * lsb


def simulate_channels(pos: np.ndarray, vel: np.ndarray, tau: np.ndarray, ts: float,
                      nom: dict[str, np.ndarray], gravity: tuple[float, float], *,
                      gain: float, accel_cutoff_hz: float, coulomb_eps: float,
                      ext_cutoff_hz: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(torque_model, torque_ext), each (N, n) [N·m] unquantised, for the measured
    ``pos``, ``vel``, ``tau`` (N, n) at period ``ts`` [s] with the nominal parameters
    ``nom`` (layout of :func:`impactcli.sim.arm.nominal_parameters`; motor and link
    friction add up in the rigid model), observer gain ``gain`` [1/s], acceleration
    cut-off ``accel_cutoff_hz`` [Hz], Coulomb smoothing velocity ``coulomb_eps`` [rad/s]
    and the observer's output low-pass ``ext_cutoff_hz`` [Hz] (0: unfiltered)."""
    # writable C-contiguous copies: one compiled signature whatever the caller passes
    pos = np.array(pos, dtype=np.float64, order="C")
    vel = np.array(vel, dtype=np.float64, order="C")
    tau = np.array(tau, dtype=np.float64, order="C")
    out_m = np.empty_like(pos)
    out_e = np.empty_like(pos)
    beta = 1.0 - math.exp(-2.0 * math.pi * accel_cutoff_hz * ts)
    gamma = 1.0 - math.exp(-2.0 * math.pi * ext_cutoff_hz * ts) if ext_cutoff_hz > 0 else 1.0
    controller_channels(pos, vel, tau, float(ts), nom["lengths"], nom["mass"], nom["com"],
                        nom["inertia"], nom["i_mot"], nom["fv_m"] + nom["fv_a"],
                        nom["fc_m"] + nom["fc_a"], float(coulomb_eps), float(gravity[0]),
                        float(gravity[1]), float(gain), beta, gamma, out_m, out_e)
    return out_m, out_e
