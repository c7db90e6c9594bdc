"""Simulate a planar flexible-joint arm (the paper's eq. 1–2) under PD control with contacts.

:func:`simulate` turns a :class:`Scenario` into a :class:`SimResult`: the drive's log
(quantised encoder position, noisy quantised current and the torque computed from it,
velocity estimate, reference position/velocity/acceleration), ground-truth labels, the
NOMINAL robot description and the true signals (link positions x2, contact forces,
tau_ext ...). The integrator is :mod:`impactcli.sim.kernel` (RK4, numba).

What differs between the nominal description and the simulated robot (like a real robot):
parameters drawn ±``uncertainty`` around nominal from the seed, an optional unknown payload,
and friction that drifts slowly — a warm-up decay of a few to ``friction_drift`` × 100 %
over ~10 min plus ±3 % wander over minutes (temperature).

With ``Scenario.controller_channels`` the log also carries the controller's own channels
``torque_model`` and ``torque_ext`` (:mod:`impactcli.sim.controller`: the nominal rigid
model and a momentum observer on it, computed after the integration from the logged
position, velocity estimate and torque, with no random draw: every other column and every
random stream are the same with the flag on or off).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..types import Labels, LogSource, RobotDescription, RobotLog
from . import kernel as kern
from .arm import ArmParams, nominal_parameters, true_parameters, with_payload
from .contacts import Clamp, Push, Surface, label_contacts, tables
from .controller import quantise, simulate_channels
from .reference import Reference


@dataclass(frozen=True)
class Scenario:
    """Everything one simulation run needs (apart from the seed).

    Attributes:
        name: scenario name (used for file names).
        arm: the NOMINAL arm (presets in :mod:`impactcli.sim.arm`).
        duration_s: log duration [s].
        reference: the motor-position reference x1_ref (:mod:`impactcli.sim.reference`).
        surfaces, pushes, clamps: contacts (:mod:`impactcli.sim.contacts`).
        payload_kg: unknown point mass at the end effector [kg] (not in the description).
        payload_changes: (time [s], payload [kg] from then on) pairs in time order: a
            payload picked or released mid-run (a point mass at the end effector, merged
            into the last link from the first sample at or after that time).
        uncertainty: relative spread of the true parameters around nominal [-].
        friction_drift: largest warm-up decrease of friction [-] (0 disables the drift).
        friction: False removes all friction (energy checks).
        control: False sets the motor torque to zero (free motion).
        noise: False removes the current noise (quantisation stays).
        t0_ns: absolute time of the first sample [ns] (0: time starts at 0).
        substeps: RK4 substeps per sample (None: chosen for stability, see
            :func:`choose_substeps`).
        initial_link_velocity: optional (n,) initial x1' = x2' [rad/s].
        log_decimals: round every logged channel to this many decimals (a logger prints
            fixed-point text; 7 decimals keep the encoder grid to < 0.1 % of a count);
            None keeps full precision.
        description: one line saying what the scenario is (for READMEs and reports).
        robot_seed: seed of the true parameters alone: runs with the same robot_seed
            simulate the same physical robot (as a robot's own logs do) whatever their
            run seed; None draws the robot from the run seed (every run another unit).
        controller_channels: also log the controller's own channels ``torque_model`` and
            ``torque_ext`` (:mod:`impactcli.sim.controller`; parameters on the arm). Off by
            default: most logs in the wild have neither. Turning it on changes no other
            column and no random draw.
    """

    name: str
    arm: ArmParams
    duration_s: float
    reference: Reference
    surfaces: tuple[Surface, ...] = ()
    pushes: tuple[Push, ...] = ()
    clamps: tuple[Clamp, ...] = ()
    payload_kg: float = 0.0
    payload_changes: tuple[tuple[float, float], ...] = ()
    uncertainty: float = 0.2
    friction_drift: float = 0.15
    friction: bool = True
    control: bool = True
    noise: bool = True
    t0_ns: int = 0
    substeps: int | None = None
    initial_link_velocity: tuple[float, ...] | None = None
    log_decimals: int | None = 7
    description: str = ""
    robot_seed: int | None = None
    controller_channels: bool = False


@dataclass(frozen=True)
class SimResult:
    """Output of :func:`simulate`.

    Attributes:
        log: the drive's log (source format ``memory``).
        labels: ground-truth contacts (docs/formats.md, "Ground-truth labels").
        robot: the NOMINAL robot description.
        truth: true signals, N rows each — ``time_s`` (N,), ``x1``, ``x2``, ``x1_dot``,
            ``x2_dot`` (N, n) [rad, rad/s]; ``tau`` (N, n) motor torque applied [N·m];
            ``tau_ext`` (N, n) [N·m]; ``contact_force`` (N, S+P) force magnitude per source
            [N] (surfaces first, then pushes, then clamps); ``contact_force_total`` (N,);
            ``penetration`` (N, S) [m]; ``tip`` (N, 2) end-effector position [m];
            ``friction_scale`` (N, n); ``source_kind`` (S+P,) str; ``source_link`` (S+P,).
            With ``controller_channels``, also ``torque_model_error`` (N, n) = logged
            ``torque_model`` − (``tau`` + ``tau_ext``) — what the controller's model gets
            wrong (in free motion the model should equal the applied torque; with contact,
            applied plus external) — and ``torque_ext_error`` (N, n) = logged
            ``torque_ext`` − ``tau_ext`` [N·m].
        params: the true parameters used (:func:`impactcli.sim.arm.true_parameters`).
        substeps: RK4 substeps per sample used.
        scenario: the scenario run.
        seed: the seed.
    """

    log: RobotLog
    labels: Labels
    robot: RobotDescription
    truth: dict[str, np.ndarray]
    params: dict[str, np.ndarray]
    substeps: int
    scenario: Scenario
    seed: int
    extra: dict[str, Any] = field(default_factory=dict)


def _min_link_inertia(p: dict[str, np.ndarray]) -> float:
    """Smallest eigenvalue of M(q) over a grid of the relative angles q2..qn [kg·m²]."""
    n = p["lengths"].size
    grid = np.linspace(-math.pi, math.pi, 13)
    best = math.inf
    mm = np.empty((n, n))
    combos = np.array(np.meshgrid(*([grid] * (n - 1)), indexing="ij")).reshape(n - 1, -1).T \
        if n > 1 else np.zeros((1, 0))
    for rest in combos:
        q = np.concatenate(([0.0], rest))
        kern.mass_matrix(q, p["lengths"], p["mass"], p["com"], p["inertia"], mm)
        best = min(best, float(np.linalg.eigvalsh(mm)[0]))
    return best


def choose_substeps(p: dict[str, np.ndarray], arm: ArmParams, surfaces: np.ndarray,
                    friction_max_scale: float) -> int:
    """RK4 substeps per sample (at least 2) so that |λ h| ≤ 0.8 for the fastest mode.

    RK4's stability limit is |λ h| ≈ 2.8; at 0.8 the fastest (friction) modes decay with
    < 1 % error per step. Set ``Scenario.substeps`` for more (the energy error falls as h⁴).
    Bounds used: spring modes ω² ≤ K (1/I_mot + 1/λ_min(M)), contact modes k_s L² / λ_min(M),
    and the decay rates of viscous + smoothed-Coulomb friction (slope Fc / v_eps) and
    transmission damping.
    """
    lam = _min_link_inertia(p)
    v_eps = arm.coulomb_velocity_eps
    sample_rate_hz = friction_max_scale
    w2 = p["stiff"] * (1 / p["i_mot"] + 1 / lam)
    rate_m = (p["damp"] + sample_rate_hz * (p["fv_m"] + p["fc_m"] / v_eps)) / p["i_mot"]
    rate_a = (p["damp"] + sample_rate_hz * (p["fv_a"] + p["fc_a"] / v_eps)) / lam
    reach = float(np.sum(p["lengths"]))
    w2_c = 0.0
    rate_c = 0.0
    if surfaces.size:
        w2_c = float(np.max(surfaces[:, 3])) * reach**2 / lam
        rate_c = float(np.max(surfaces[:, 4])) * reach**2 / lam
    rho = max(math.sqrt(float(np.max(w2)) + w2_c), float(np.max(rate_m)),
              float(np.max(rate_a)) + rate_c)
    h = 0.8 / rho
    return max(2, math.ceil(arm.sample_period_s / h))


def friction_scale(t: np.ndarray, n: int, drift: float, rng: np.random.Generator) -> np.ndarray:
    """(N, n) slowly drifting friction multiplier (temperature), ≈ 1 at t = 0.

    s_j(t) = (1 − a_j (1 − exp(−t / τ_j))) (1 + 0.03 w_j(t)), a_j ~ U(drift/3, drift),
    τ_j ~ U(300, 900) s, w_j a sum of three slow unit sines (periods 60–600 s) with
    random phases, starting at 0.
    """
    out = np.ones((t.size, n))
    if drift <= 0:
        return out
    for j in range(n):
        a = rng.uniform(drift / 3, drift)
        tau = rng.uniform(300.0, 900.0)
        per = rng.uniform(60.0, 600.0, 3)
        ph = rng.uniform(0, 2 * math.pi, 3)
        wander = np.zeros(t.size)
        for pk, phk in zip(per, ph, strict=True):
            wander += (np.sin(2 * math.pi * t / pk + phk) - math.sin(phk)) / 3
        out[:, j] = (1 - a * (1 - np.exp(-t / tau))) * (1 + 0.03 * wander)
    return out


def _static_link_position(x1: np.ndarray, p: dict[str, np.ndarray], g: tuple[float, float]
                          ) -> np.ndarray:
    """x2 with K (x2 − x1) + g(x2) = 0 (the arm at rest, motors at x1), by fixed point."""
    x2 = x1.copy()
    tau_g = np.empty_like(x1)
    zero = np.zeros_like(x1)
    for _ in range(50):
        kern.rnea(x2, zero, zero, p["lengths"], p["mass"], p["com"], p["inertia"],
                  g[0], g[1], tau_g)
        x2 = x1 - tau_g / p["stiff"]
    return x2


def _payload_segments(p: dict[str, np.ndarray], bare: dict[str, np.ndarray],
                      scenario: Scenario, n_samples: int, ts: float,
                      ) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """(first sample, masses, centres of mass, inertias) of the links in each stretch of
    constant payload: ``p``'s (with ``scenario.payload_kg``) first, then one per payload
    change, merged into ``bare`` (the same robot without a payload): a point mass at the
    end effector in the last link."""
    out = [(0, p["mass"], p["com"], p["inertia"])]
    for t_s, kg in scenario.payload_changes:
        k = min(n_samples, max(1, math.ceil(t_s / ts - 1e-9)))
        m, c, i = with_payload(bare["mass"], bare["com"], bare["inertia"], bare["lengths"], kg)
        out.append((k, m, c, i))
    return out


def simulate(scenario: Scenario, *, seed: int = 0) -> SimResult:
    """Run ``scenario`` with the random ``seed`` (deterministic for a seed).

    Returns a :class:`SimResult` whose log samples start at ``scenario.t0_ns`` with period
    ``arm.sample_period_s``; ``duration_s`` rounds to whole samples.
    """
    arm = scenario.arm
    n = arm.n_joints
    ts = arm.sample_period_s
    ts_ns = round(ts * 1e9)
    n_samples = round(scenario.duration_s / ts) + 1
    t = np.arange(n_samples, dtype=np.float64) * ts
    ss = np.random.SeedSequence(seed)
    r_par, r_ref, r_noise, r_drift = (np.random.default_rng(s) for s in ss.spawn(4))
    if scenario.robot_seed is not None:  # the same robot across runs
        r_par = np.random.default_rng(np.random.SeedSequence(scenario.robot_seed))

    r_bare = copy.deepcopy(r_par)  # the same draws: the same robot without a payload
    p = true_parameters(arm, r_par, scenario.uncertainty, scenario.payload_kg)
    segments = _payload_segments(
        p, true_parameters(arm, r_bare, scenario.uncertainty, 0.0), scenario, n_samples, ts)
    if not scenario.friction:
        for key in ("fv_m", "fc_m", "fv_a", "fc_a"):
            p[key] = np.zeros(n)
    nom = nominal_parameters(arm)
    ref_pos, ref_vel, ref_acc = scenario.reference.generate(t, ts, r_ref)
    fscale = np.ascontiguousarray(friction_scale(t, n, scenario.friction_drift, r_drift))
    cur_noise = r_noise.standard_normal((n_samples, n)) * np.asarray(arm.current_noise_a)
    if not scenario.noise:
        cur_noise[:] = 0.0
    surf, forces = tables(scenario.surfaces, scenario.pushes, scenario.clamps)
    n_sub = scenario.substeps or max(choose_substeps(dict(p, mass=m, com=c, inertia=i), arm,
                                                     surf, float(fscale.max()))
                                     for _, m, c, i in segments)

    x1_0 = ref_pos[0].copy()
    x2_0 = _static_link_position(x1_0, p, arm.gravity)
    v0 = (np.zeros(n) if scenario.initial_link_velocity is None
          else np.asarray(scenario.initial_link_velocity, dtype=np.float64))
    s0 = np.concatenate([x1_0, x2_0, v0, v0])

    n_src = surf.shape[0] + forces.shape[0]
    o_state = np.empty((n_samples, 4 * n))
    o_u = np.empty((n_samples, n))
    o_pos = np.empty((n_samples, n))
    o_vel = np.empty((n_samples, n))
    o_cur = np.empty((n_samples, n))
    o_tau_ext = np.empty((n_samples, n))
    o_src = np.empty((n_samples, n_src))
    o_pen = np.empty((n_samples, surf.shape[0]))
    o_tip = np.empty((n_samples, 2))
    alpha = 1.0 - math.exp(-2 * math.pi * arm.velocity_cutoff_hz * ts)
    seg_start = np.array([seg[0] for seg in segments], dtype=np.int64)
    seg_mass, seg_com, seg_inertia = (np.ascontiguousarray(np.array([seg[i] for seg in segments]))
                                      for i in (1, 2, 3))
    kern.run(
        s0, ts, n_sub, n_samples, p["lengths"], seg_mass, seg_com, seg_inertia, seg_start,
        float(arm.gravity[0]), float(arm.gravity[1]), p["i_mot"], p["stiff"], p["damp"],
        p["fv_m"], p["fc_m"], p["fv_a"], p["fc_a"], float(arm.coulomb_velocity_eps), fscale,
        surf, forces, bool(scenario.control), np.asarray(arm.kp, dtype=np.float64),
        np.asarray(arm.kd, dtype=np.float64), alpha, nom["mass"], nom["com"],
        np.ascontiguousarray(ref_pos), np.ascontiguousarray(ref_vel),
        arm.encoder_resolution, arm.torque_scale, cur_noise,
        np.asarray(arm.current_lsb_a, dtype=np.float64),
        o_state, o_u, o_pos, o_vel, o_cur, o_tau_ext, o_src, o_pen, o_tip,
    )
    if not np.all(np.isfinite(o_state)):
        raise FloatingPointError(f"simulation of {scenario.name!r} diverged (seed {seed})")

    torque = o_cur * arm.torque_scale
    logged = [o_pos, torque, o_vel, o_cur, ref_pos, ref_vel, ref_acc]
    if scenario.log_decimals is not None:
        logged = [np.round(a, scenario.log_decimals) + 0.0 for a in logged]
    l_pos, l_tau, l_vel, l_cur, l_rp, l_rv, l_ra = logged
    l_tm = l_te = None
    if scenario.controller_channels:  # from logged data only: nothing above changes
        tm, te = simulate_channels(
            l_pos, l_vel, l_tau, ts, nom, arm.gravity, gain=arm.observer_gain,
            accel_cutoff_hz=arm.accel_cutoff_hz, coulomb_eps=arm.controller_coulomb_eps,
            ext_cutoff_hz=arm.torque_ext_cutoff_hz)
        l_tm = quantise(tm, arm.controller_torque_lsb)
        l_te = quantise(te, arm.controller_torque_lsb)
        if scenario.log_decimals is not None:
            l_tm = np.round(l_tm, scenario.log_decimals) + 0.0
            l_te = np.round(l_te, scenario.log_decimals) + 0.0
    t_ns = scenario.t0_ns + np.arange(n_samples, dtype=np.int64) * ts_ns
    log = RobotLog(
        t_ns=t_ns, joint_names=arm.joint_names, position=l_pos, torque=l_tau,
        velocity=l_vel, current=l_cur, position_ref=l_rp, velocity_ref=l_rv,
        acceleration_ref=l_ra, torque_model=l_tm, torque_ext=l_te,
        source=LogSource(f"<sim {scenario.name} seed={seed}>", "", "memory"),
    )
    kinds = (["impact"] * len(scenario.surfaces) + ["push"] * len(scenario.pushes)
             + ["clamp"] * len(scenario.clamps))
    links = ([n] * len(scenario.surfaces) + [x.link for x in scenario.pushes]
             + [x.link for x in scenario.clamps])
    extras: list[dict[str, float]] = [
        {"stiffness_n_per_mm": s.stiffness_n_per_mm} for s in scenario.surfaces]
    extras += [{"duration_s": x.duration_s} for x in scenario.pushes]
    extras += [{"rise_s": x.rise_s, "hold_s": x.hold_s} for x in scenario.clamps]
    labels = label_contacts(t, o_src, kinds=kinds, links=links, extras=extras,
                            sample_rate_hz=1.0 / ts)
    # impact speed: end-effector speed at the first labelled sample
    tip_v = np.gradient(o_tip, ts, axis=0)
    evs = []
    for e in labels.events:
        if e.kind == "impact":
            k = round(e.start / ts)
            speed = float(np.hypot(*tip_v[max(k - 1, 0)]))
            evs.append(type(e)(e.start, e.end, e.peak_force, e.kind, e.link,
                               {**e.extra, "tip_speed_m_s": round(speed, 4)}))
        else:
            evs.append(e)
    # the loads picked and released: the change of the load carried at each step
    steps, kg_before = [], float(scenario.payload_kg)
    for t_s, kg in scenario.payload_changes:
        steps.append({"t_s": float(t_s), "mass_kg": float(kg) - kg_before})
        kg_before = float(kg)
    labels = Labels(events=tuple(evs), sample_rate=labels.sample_rate,
                    extra={"payload_changes": steps} if steps else {})

    truth = {
        "time_s": t,
        "x1": o_state[:, :n], "x2": o_state[:, n:2 * n],
        "x1_dot": o_state[:, 2 * n:3 * n], "x2_dot": o_state[:, 3 * n:],
        "tau": o_u, "tau_ext": o_tau_ext, "contact_force": o_src,
        "contact_force_total": o_src.sum(axis=1), "penetration": o_pen, "tip": o_tip,
        "friction_scale": fscale, "source_kind": np.array(kinds, dtype=str),
        "source_link": np.array(links, dtype=np.int64),
    }
    if l_tm is not None and l_te is not None:
        truth["torque_model_error"] = l_tm - (o_u + o_tau_ext)
        truth["torque_ext_error"] = l_te - o_tau_ext
    return SimResult(log=log, labels=labels, robot=arm.robot_description(), truth=truth,
                     params=p, substeps=n_sub, scenario=scenario, seed=seed)


def energy(p: dict[str, np.ndarray], state: np.ndarray, gravity: tuple[float, float]
           ) -> np.ndarray:
    """Total mechanical energy [J] of eq. 1–2 per row of ``state`` (N, 4n):
    ½ x2'ᵀ M(x2) x2' + ½ x1'ᵀ I_mot x1' + Σ m_i (−g · p_ci) + ½ Σ K (x2 − x1)²."""
    n = p["lengths"].size
    out = np.empty(state.shape[0])
    mm = np.empty((n, n))
    g = np.asarray(gravity)
    for k, s in enumerate(state):
        x1, x2, v1, v2 = s[:n], s[n:2 * n], s[2 * n:3 * n], s[3 * n:]
        kern.mass_matrix(x2, p["lengths"], p["mass"], p["com"], p["inertia"], mm)
        ke = 0.5 * v2 @ mm @ v2 + 0.5 * np.sum(p["i_mot"] * v1**2)
        phi = np.cumsum(x2)
        joints = np.concatenate(([[0.0, 0.0]], np.cumsum(
            p["lengths"][:, None] * np.c_[np.cos(phi), np.sin(phi)], axis=0)))[:-1]
        com = joints + p["com"][:, None] * np.c_[np.cos(phi), np.sin(phi)]
        pe = -float(np.sum(p["mass"] * (com @ g)))
        se = 0.5 * float(np.sum(p["stiff"] * (x2 - x1) ** 2))
        out[k] = ke + pe + se
    return out
