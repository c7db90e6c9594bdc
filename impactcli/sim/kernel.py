"""Compiled core of the flexible-joint simulator (numba).

Model (the paper's eq. 1–2, planar serial chain in a vertical plane)::

    M(x2) x2'' + H(x2, x2') + tau_fa + K (x2 - x1) + D (x2' - x1') = tau_ext      (1)
    I_mot x1'' + tau_fm - K (x2 - x1) - D (x2' - x1')            = tau            (2)

with x1 the motor positions after reduction, x2 the link positions (first angle from the
horizontal, each next relative to the previous link), H = C(x2, x2') x2' + g(x2) from a
recursive Newton–Euler pass, friction ``tau_f = s(t) * (Fv v + Fc tanh(v / v_eps))``
(viscous + smoothed Coulomb: the tanh has slope ``Fc / v_eps`` at v = 0; ``s(t)`` is the
slowly drifting friction scale) and ``tau_ext = J(x2)^T F`` for every external force F
(eq. 1's context). D is an optional transmission damping (the paper: "additional damping
effects can be included"; 0 reproduces eq. 1–2 exactly).

The controller runs at the sample period Ts (zero-order hold): PD on the quantised motor
position with gravity feed-forward from the nominal model, evaluated at the reference.
Between samples the state is integrated with classical RK4 on ``n_sub`` equal substeps.
Kernels use numba's ``error_model="numpy"`` (a division by zero gives inf/nan; the caller
checks the result is finite) and inline the small helpers into :func:`derivative`, for
speed (``tests/benchmarks/bench_sim.py``).

State vector layout: ``s = [x1 (n), x2 (n), x1' (n), x2' (n)]``.
"""

# force_profile returns from each phase of its piecewise profile:
# ruff: noqa: PLR0911
from __future__ import annotations

import math

import numpy as np
from numba import njit

# force-profile kinds (column 8 of the force table)
N_SCRATCH = 12  # rows of the per-call scratch array w (n + 1 columns)
PULSE = 0  # half-sine pulse: t0, duration
RAMP = 1  # ramp up over t_rise, hold t_hold, release over t_fall


# rows of the per-call scratch array w (N_SCRATCH, n + 1): indexing rows directly (no
# views) keeps the compiled inner loop free of reference counting
CS, SN, OX, OY, JX, JY, ACX, ACY, ALPH, HV, RHS, YV = range(12)


@njit(cache=True, error_model="numpy", inline="always")
def kin_w(x: np.ndarray, off: int, n: int, lengths: np.ndarray, w: np.ndarray) -> None:
    """Kinematics of the chain whose angles are x[off:off+n], into w's CS, SN, OX, OY rows."""
    a = 0.0
    px = 0.0
    py = 0.0
    for i in range(n):
        a += x[off + i]
        c = math.cos(a)
        s = math.sin(a)
        w[CS, i] = c
        w[SN, i] = s
        w[OX, i] = px
        w[OY, i] = py
        px += lengths[i] * c
        py += lengths[i] * s
    w[OX, n] = px
    w[OY, n] = py


@njit(cache=True, error_model="numpy")
def kinematics(q: np.ndarray, lengths: np.ndarray, cs: np.ndarray, sn: np.ndarray,
               ox: np.ndarray, oy: np.ndarray) -> None:
    """Absolute link directions and joint origins of a planar chain.

    q (n,) relative joint angles [rad] (first from the horizontal, each next relative to the
    previous link); lengths (n,) [m]. Fills cs, sn (n,) with the cosine and sine of each
    link's absolute angle and ox, oy (n+1,) with the joint origins [m] (index n is the tip
    of link n = the end effector).
    """
    n = q.shape[0]
    w = np.zeros((N_SCRATCH, n + 1))
    kin_w(q, 0, n, lengths, w)
    for i in range(n):
        cs[i] = w[CS, i]
        sn[i] = w[SN, i]
    for i in range(n + 1):
        ox[i] = w[OX, i]
        oy[i] = w[OY, i]


@njit(cache=True, error_model="numpy", inline="always")
def mass_matrix_k(n: int, mass: np.ndarray, com: np.ndarray, inertia: np.ndarray,
                  w: np.ndarray, out: np.ndarray) -> None:
    """M(q) given the chain's kinematics already in w (rows CS, SN, OX, OY)."""
    for r in range(n):
        for c in range(n):
            out[r, c] = 0.0
    for i in range(n):
        px = w[OX, i] + com[i] * w[CS, i]
        py = w[OY, i] + com[i] * w[SN, i]
        for j in range(i + 1):
            w[JX, j] = -(py - w[OY, j])
            w[JY, j] = px - w[OX, j]
        for r in range(i + 1):
            for c in range(i + 1):
                out[r, c] += mass[i] * (w[JX, r] * w[JX, c] + w[JY, r] * w[JY, c]) + inertia[i]


@njit(cache=True, error_model="numpy")
def mass_matrix(q: np.ndarray, lengths: np.ndarray, mass: np.ndarray, com: np.ndarray,
                inertia: np.ndarray, out: np.ndarray) -> None:
    """Link inertia matrix M(q) (n, n) [kg·m²] of eq. 1, from the COM Jacobians.

    q (n,) [rad]; mass (n,) [kg]; com (n,) distance of each COM from its joint along the
    link [m]; inertia (n,) about the COM [kg·m²].
    """
    n = q.shape[0]
    w = np.zeros((N_SCRATCH, n + 1))
    kin_w(q, 0, n, lengths, w)
    mass_matrix_k(n, mass, com, inertia, w, out)


@njit(cache=True, error_model="numpy")
def rnea(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, lengths: np.ndarray,
         mass: np.ndarray, com: np.ndarray, inertia: np.ndarray, gx: float, gy: float,
         out: np.ndarray) -> None:
    """Inverse dynamics M(q) qdd + C(q, qd) qd + g(q) of the planar chain (Newton–Euler).

    All vectors (n,): q [rad], qd [rad/s], qdd [rad/s²]; gravity (gx, gy) [m/s²];
    out (n,) joint torques [N·m]. With qdd = 0 this is H(x2, x2') of eq. 1.
    """
    n = q.shape[0]
    w = np.zeros((N_SCRATCH, n + 1))
    kin_w(q, 0, n, lengths, w)
    rnea_k(n, qd, 0, qdd, 0, lengths, mass, com, inertia, gx, gy, w, w, HV)
    for i in range(n):
        out[i] = w[HV, i]


@njit(cache=True, error_model="numpy", inline="always")
def rnea_k(n: int, qd: np.ndarray, qd_off: int, qdd: np.ndarray, qdd_off: int,
           lengths: np.ndarray, mass: np.ndarray, com: np.ndarray, inertia: np.ndarray,
           gx: float, gy: float, w: np.ndarray, out: np.ndarray, row: int) -> None:
    """Newton–Euler with velocities qd[qd_off:], accelerations qdd[qdd_off:] (a negative
    qdd_off means zero accelerations), given the kinematics in w; writes out[row, 0:n]."""
    om = 0.0
    al = 0.0
    ax = 0.0
    ay = 0.0
    for i in range(n):
        om += qd[qd_off + i]
        if qdd_off >= 0:
            al += qdd[qdd_off + i]
        w[ALPH, i] = al
        c = w[CS, i]
        s = w[SN, i]
        # a = a_o + alpha × r - om² r, r along the link
        w[ACX, i] = ax - al * com[i] * s - om * om * com[i] * c
        w[ACY, i] = ay + al * com[i] * c - om * om * com[i] * s
        ax = ax - al * lengths[i] * s - om * om * lengths[i] * c
        ay = ay + al * lengths[i] * c - om * om * lengths[i] * s
    fx = 0.0
    fy = 0.0
    nm = 0.0
    for i in range(n - 1, -1, -1):
        mx = mass[i] * (w[ACX, i] - gx)
        my = mass[i] * (w[ACY, i] - gy)
        rcx = com[i] * w[CS, i]
        rcy = com[i] * w[SN, i]
        rlx = lengths[i] * w[CS, i]
        rly = lengths[i] * w[SN, i]
        nm = inertia[i] * w[ALPH, i] + nm + (rcx * my - rcy * mx) + (rlx * fy - rly * fx)
        fx = mx + fx
        fy = my + fy
        out[row, i] = nm


@njit(cache=True, error_model="numpy")
def solve_spd(a: np.ndarray, b: np.ndarray, low: np.ndarray, y: np.ndarray,
              out: np.ndarray) -> None:
    """Solve a x = b for a small symmetric positive-definite a (n, n) by Cholesky.

    low (n, n) and y (n,) are scratch.
    """
    n = b.shape[0]
    w = np.zeros((N_SCRATCH, n + 1))
    for i in range(n):
        w[RHS, i] = b[i]
    solve_spd_k(n, a, w, low, out, 0)


@njit(cache=True, error_model="numpy", inline="always")
def solve_spd_k(n: int, a: np.ndarray, w: np.ndarray, low: np.ndarray, out: np.ndarray,
                out_off: int) -> None:
    """Cholesky solve of a x = w[RHS, :n] into out[out_off:out_off+n] (w[YV] is scratch)."""
    for i in range(n):
        for j in range(i + 1):
            s = a[i, j]
            for k in range(j):
                s -= low[i, k] * low[j, k]
            if i == j:
                low[i, i] = math.sqrt(s)
            else:
                low[i, j] = s / low[j, j]
    for i in range(n):
        s = w[RHS, i]
        for k in range(i):
            s -= low[i, k] * w[YV, k]
        w[YV, i] = s / low[i, i]
    for i in range(n - 1, -1, -1):
        s = w[YV, i]
        for k in range(i + 1, n):
            s -= low[k, i] * out[out_off + k]
        out[out_off + i] = s / low[i, i]


@njit(cache=True, error_model="numpy", inline="always")
def force_profile(t: float, forces: np.ndarray, p: int) -> float:
    """Magnitude [N] at time t [s] of prescribed force p (row p of the force table).

    Row: [link (0-based), point (fraction of the link length), direction [rad, world],
    peak [N], t0 [s], a, b, c, kind]; kind PULSE: half-sine of duration a; kind RAMP:
    linear rise over a, hold b, linear release over c.
    """
    t0 = forces[p, 4]
    if t < t0:
        return 0.0
    dt = t - t0
    peak = forces[p, 3]
    if forces[p, 8] == PULSE:
        if dt >= forces[p, 5]:
            return 0.0
        return peak * math.sin(math.pi * dt / forces[p, 5])
    rise = forces[p, 5]
    hold = forces[p, 6]
    fall = forces[p, 7]
    if dt < rise:
        return peak * dt / rise
    if dt < rise + hold:
        return peak
    if dt < rise + hold + fall:
        return peak * (1.0 - (dt - rise - hold) / fall)
    return 0.0


@njit(cache=True, error_model="numpy", inline="always")
def external(t: float, n: int, qd: np.ndarray, qd_off: int, lengths: np.ndarray,
             w: np.ndarray, surfaces: np.ndarray, forces: np.ndarray, tau_ext: np.ndarray,
             src_force: np.ndarray, penetration: np.ndarray) -> None:
    """External joint torques tau_ext = sum J_p(q)^T F_p [N·m] at time t (eq. 1).

    surfaces (S, 7): [height y_s [m], x_min, x_max [m], stiffness [N/m], damping [N·s/m],
    t_on, t_off [s]] — a horizontal unilateral elastomer under the end effector, force
    ``max(0, k δ + c δ')`` upward while the tip penetrates δ = y_s - y_tip > 0.
    forces (P, 9): prescribed forces, see :func:`force_profile`.
    Fills tau_ext (n,), src_force (S + P,) force magnitudes [N] and penetration (S,) [m].
    The chain's kinematics must already be in w; link velocities are qd[qd_off:qd_off+n].
    """
    for j in range(n):
        tau_ext[j] = 0.0
    ns = surfaces.shape[0]
    tx = w[OX, n]
    ty = w[OY, n]
    for k in range(ns):
        src_force[k] = 0.0
        penetration[k] = 0.0
        if t < surfaces[k, 5] or t >= surfaces[k, 6]:
            continue
        if tx < surfaces[k, 1] or tx > surfaces[k, 2]:
            continue
        d = surfaces[k, 0] - ty
        if d <= 0.0:
            continue
        penetration[k] = d
        vy = 0.0
        for j in range(n):
            vy += (tx - w[OX, j]) * qd[qd_off + j]
        f = max(surfaces[k, 3] * d - surfaces[k, 4] * vy, 0.0)
        src_force[k] = f
        for j in range(n):
            tau_ext[j] += (tx - w[OX, j]) * f
    for p in range(forces.shape[0]):
        f = force_profile(t, forces, p)
        src_force[ns + p] = abs(f)
        if f == 0.0:
            continue
        i = int(forces[p, 0])
        px = w[OX, i] + forces[p, 1] * lengths[i] * w[CS, i]
        py = w[OY, i] + forces[p, 1] * lengths[i] * w[SN, i]
        fx = f * math.cos(forces[p, 2])
        fy = f * math.sin(forces[p, 2])
        for j in range(i + 1):
            tau_ext[j] += (px - w[OX, j]) * fy - (py - w[OY, j]) * fx


@njit(cache=True, error_model="numpy")
def derivative(t: float, s: np.ndarray, u: np.ndarray, lengths: np.ndarray,
               mass: np.ndarray, com: np.ndarray, inertia: np.ndarray, gx: float, gy: float,
               i_mot: np.ndarray, stiff: np.ndarray, damp: np.ndarray,
               fv_m: np.ndarray, fc_m: np.ndarray, fv_a: np.ndarray, fc_a: np.ndarray,
               v_eps: float, fscale: np.ndarray, k_fs: int, surfaces: np.ndarray,
               forces: np.ndarray, out: np.ndarray, tau_ext: np.ndarray,
               src_force: np.ndarray, penetration: np.ndarray, w: np.ndarray,
               mm: np.ndarray, low: np.ndarray) -> None:
    """ds/dt of eq. 1–2 for state s = [x1, x2, x1', x2'] (4n,) under motor torque u (n,).

    fscale[k_fs] (n,) is the friction scale; w (N_SCRATCH, n + 1), mm and low (n, n) are
    scratch.
    """
    n = u.shape[0]
    kin_w(s, n, n, lengths, w)
    mass_matrix_k(n, mass, com, inertia, w, mm)
    rnea_k(n, s, 3 * n, s, -1, lengths, mass, com, inertia, gx, gy, w, w, HV)
    external(t, n, s, 3 * n, lengths, w, surfaces, forces, tau_ext, src_force, penetration)
    for j in range(n):
        x1 = s[j]
        x2 = s[n + j]
        v1 = s[2 * n + j]
        v2 = s[3 * n + j]
        spring = stiff[j] * (x2 - x1) + damp[j] * (v2 - v1)
        fsj = fscale[k_fs, j]
        tfa = fsj * (fv_a[j] * v2 + fc_a[j] * math.tanh(v2 / v_eps))
        tfm = fsj * (fv_m[j] * v1 + fc_m[j] * math.tanh(v1 / v_eps))
        w[RHS, j] = tau_ext[j] - w[HV, j] - tfa - spring
        out[j] = v1
        out[n + j] = v2
        out[2 * n + j] = (u[j] - tfm + spring) / i_mot[j]
    solve_spd_k(n, mm, w, low, out, 3 * n)


@njit(cache=True, error_model="numpy")
def run(s0: np.ndarray, ts: float, n_sub: int, n_samples: int,
        lengths: np.ndarray, masses: np.ndarray, coms: np.ndarray, inertias: np.ndarray,
        seg_start: np.ndarray,
        gx: float, gy: float, i_mot: np.ndarray, stiff: np.ndarray, damp: np.ndarray,
        fv_m: np.ndarray, fc_m: np.ndarray, fv_a: np.ndarray, fc_a: np.ndarray,
        v_eps: float, fscale: np.ndarray,
        surfaces: np.ndarray, forces: np.ndarray,
        control: bool, kp: np.ndarray, kd: np.ndarray, vel_alpha: float,
        nom_mass: np.ndarray, nom_com: np.ndarray,
        ref_pos: np.ndarray, ref_vel: np.ndarray,
        enc_res: np.ndarray, cur_scale: np.ndarray, cur_noise: np.ndarray,
        cur_lsb: np.ndarray,
        o_state: np.ndarray, o_u: np.ndarray, o_pos: np.ndarray, o_vel: np.ndarray,
        o_cur: np.ndarray, o_tau_ext: np.ndarray, o_src: np.ndarray, o_pen: np.ndarray,
        o_tip: np.ndarray) -> None:
    """Integrate n_samples sample periods, with the controller at each sample (ZOH).

    Per sample k (time k·ts), before integrating [k·ts, (k+1)·ts):
    measured position = encoder-quantised x1 (resolution enc_res (n,) [rad]); velocity
    estimate = first-order low-passed backward difference (gain vel_alpha); motor torque
    u = kp (x1_ref - x1_meas) + kd (v_ref - v_est) + g_nom(x1_ref) (or 0 if not control);
    measured current = u / cur_scale + cur_noise[k] quantised to cur_lsb [A].
    fscale (N, n) friction scale per sample; cur_noise (N, n) [A] pre-drawn.
    Outputs (N rows each): o_state (4n), o_u, o_pos, o_vel, o_cur, o_tau_ext (n),
    o_src (S + P) force magnitudes [N], o_pen (S) [m], o_tip (2) end-effector [m].
    The links' masses, centres of mass and inertias are rows of ``masses``, ``coms``,
    ``inertias`` (G, n): row g from sample ``seg_start[g]`` on (``seg_start[0]`` = 0; a
    payload picked or released mid-run).
    """
    n = lengths.shape[0]
    dim = 4 * n
    s = s0.copy()
    k1 = np.empty(dim)
    k2 = np.empty(dim)
    k3 = np.empty(dim)
    k4 = np.empty(dim)
    tmp = np.empty(dim)
    u = np.zeros(n)
    zero = np.zeros(n)
    tau_ext = np.empty(n)
    ns = surfaces.shape[0]
    src = np.empty(ns + forces.shape[0])
    pen = np.empty(ns)
    w = np.zeros((N_SCRATCH, n + 1))
    w2 = np.zeros((N_SCRATCH, n + 1))
    mm = np.empty((n, n))
    low = np.zeros((n, n))
    prev = np.empty(n)
    vest = np.zeros(n)
    h = ts / n_sub
    g = 0
    mass = masses[0]
    com = coms[0]
    inertia = inertias[0]
    for k in range(n_samples):
        t = k * ts
        while g + 1 < seg_start.shape[0] and k >= seg_start[g + 1]:
            g += 1
            mass = masses[g]
            com = coms[g]
            inertia = inertias[g]
        # record the true state and contact quantities at the sample instant
        kin_w(s, n, n, lengths, w)
        external(t, n, s, 3 * n, lengths, w, surfaces, forces, tau_ext, src, pen)
        for j in range(dim):
            o_state[k, j] = s[j]
        for j in range(n):
            o_tau_ext[k, j] = tau_ext[j]
        for j in range(src.shape[0]):
            o_src[k, j] = src[j]
        for j in range(ns):
            o_pen[k, j] = pen[j]
        o_tip[k, 0] = w[OX, n]
        o_tip[k, 1] = w[OY, n]
        # drive measurements and controller
        for j in range(n):
            xq = math.floor(s[j] / enc_res[j] + 0.5) * enc_res[j]
            if k == 0:
                prev[j] = xq
            vest[j] += vel_alpha * ((xq - prev[j]) / ts - vest[j])
            prev[j] = xq
            o_pos[k, j] = xq
            o_vel[k, j] = vest[j]
        if control:
            kin_w(ref_pos[k], 0, n, lengths, w2)
            rnea_k(n, zero, 0, zero, -1, lengths, nom_mass, nom_com, zero, gx, gy, w2, w2, HV)
            for j in range(n):
                u[j] = (kp[j] * (ref_pos[k, j] - o_pos[k, j])
                        + kd[j] * (ref_vel[k, j] - vest[j]) + w2[HV, j])
        for j in range(n):
            o_u[k, j] = u[j]
            cur = u[j] / cur_scale[j] + cur_noise[k, j]
            o_cur[k, j] = math.floor(cur / cur_lsb[j] + 0.5) * cur_lsb[j]
        if k == n_samples - 1:
            break
        # RK4 over the sample period, u held
        for m in range(n_sub):
            tt = t + m * h
            derivative(tt, s, u, lengths, mass, com, inertia, gx, gy, i_mot, stiff, damp,
                       fv_m, fc_m, fv_a, fc_a, v_eps, fscale, k, surfaces, forces, k1,
                       tau_ext, src, pen, w, mm, low)
            for j in range(dim):
                tmp[j] = s[j] + 0.5 * h * k1[j]
            derivative(tt + 0.5 * h, tmp, u, lengths, mass, com, inertia, gx, gy, i_mot,
                       stiff, damp, fv_m, fc_m, fv_a, fc_a, v_eps, fscale, k, surfaces, forces,
                       k2, tau_ext, src, pen, w, mm, low)
            for j in range(dim):
                tmp[j] = s[j] + 0.5 * h * k2[j]
            derivative(tt + 0.5 * h, tmp, u, lengths, mass, com, inertia, gx, gy, i_mot,
                       stiff, damp, fv_m, fc_m, fv_a, fc_a, v_eps, fscale, k, surfaces, forces,
                       k3, tau_ext, src, pen, w, mm, low)
            for j in range(dim):
                tmp[j] = s[j] + h * k3[j]
            derivative(tt + h, tmp, u, lengths, mass, com, inertia, gx, gy, i_mot,
                       stiff, damp, fv_m, fc_m, fv_a, fc_a, v_eps, fscale, k, surfaces, forces,
                       k4, tau_ext, src, pen, w, mm, low)
            for j in range(dim):
                s[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
