"""Synthetic logs of the shipped robots, for tests/test_robots.py and
tests/test_published_arms.py: smooth sinusoids within the joint limits, the torque from
Pinocchio's RNEA on the URDF's own inertials (every other URDF joint at zero) plus noise,
with the reference logged."""

from __future__ import annotations

from typing import Any

import numpy as np

from impactcli.logs import robot_catalogue as robots
from impactcli.types import LogSource, RobotLog

FS = 200.0
DURATION_S = 12.0  # >= 10 s: identification holds back its last 20 % (at least 2 s)


def _pin() -> Any:
    import pinocchio

    return pinocchio


def full_model(name: str) -> Any:
    return _pin().buildModelFromXML(robots.urdf_text(name))


def synthetic_log(name: str, joints: tuple[str, ...] | None = None, *,
                  rename: dict[str, str] | None = None, extra: str | None = None,
                  drop: str | None = None, seed: int = 0) -> RobotLog:
    """A log of shipped robot ``name``'s arm joints (or ``joints``, URDF names): q(t) smooth
    sinusoids within the joint limits, tau = RNEA of the URDF (other joints at zero) plus
    noise, references logged. ``rename`` {URDF: log name}; ``extra``: one more logged joint
    the URDF lacks; ``drop``: a URDF joint left out of the log."""
    model = full_model(name)
    data = model.createData()
    arm = tuple(joints or robots.arm_joints(name))
    rng = np.random.default_rng(seed)
    t = np.arange(int(DURATION_S * FS)) / FS
    n, nj = t.size, len(arm)
    q = np.zeros((n, nj))
    qd = np.zeros((n, nj))
    qdd = np.zeros((n, nj))
    for c, jn in enumerate(arm):
        jm = model.joints[model.getJointId(jn)]
        if jm.nq == 1:
            lo = float(model.lowerPositionLimit[jm.idx_q])
            hi = float(model.upperPositionLimit[jm.idx_q])
        else:  # continuous: the limits are on (cos, sin)
            lo, hi = -np.pi, np.pi
        mid, amp = 0.5 * (lo + hi), min(0.3 * (hi - lo), 1.0)
        for k, f in enumerate((0.13 + 0.041 * c, 0.37 + 0.053 * c, 0.71 + 0.029 * c)):
            a = amp / (1.6 * (k + 1))
            w, ph = 2 * np.pi * f, rng.uniform(0, 2 * np.pi)
            q[:, c] += a * np.sin(w * t + ph)
            qd[:, c] += a * w * np.cos(w * t + ph)
            qdd[:, c] -= a * w * w * np.sin(w * t + ph)
        q[:, c] += mid
    tau = np.zeros((n, nj))
    q0 = _pin().neutral(model)
    jms = [model.joints[model.getJointId(j)] for j in arm]
    for k in range(n):
        qf, vf, af = q0.copy(), np.zeros(model.nv), np.zeros(model.nv)
        for c, jm in enumerate(jms):
            if jm.nq == 1:
                qf[jm.idx_q] = q[k, c]
            else:
                qf[jm.idx_q], qf[jm.idx_q + 1] = np.cos(q[k, c]), np.sin(q[k, c])
            vf[jm.idx_v], af[jm.idx_v] = qd[k, c], qdd[k, c]
        tau[k] = _pin().rnea(model, data, qf, vf, af)[[jm.idx_v for jm in jms]]
    tau += rng.normal(0.0, 1.0, tau.shape) * (0.003 * np.ptp(tau, axis=0) + 1e-5)
    names = [(rename or {}).get(j, j) for j in arm]
    cols = list(range(nj))
    if drop is not None:
        cols.remove(arm.index(drop))
    names = [names[c] for c in cols]
    pos, trq, ref_q, ref_v, ref_a = (x[:, cols] for x in (q, tau, q, qd, qdd))
    pos = pos + rng.normal(0.0, 1e-5, pos.shape)
    if extra is not None:  # a logged joint the URDF lacks (e.g. a gripper channel)
        e = 0.02 * np.sin(2 * np.pi * 0.3 * t)[:, None]
        names.append(extra)
        pos, ref_q = np.hstack([pos, e]), np.hstack([ref_q, e])
        ref_v = np.hstack([ref_v, np.gradient(e[:, 0], t)[:, None]])
        ref_a = np.hstack([ref_a, np.gradient(ref_v[:, -1], t)[:, None]])
        trq = np.hstack([trq, 0.05 * np.sin(2 * np.pi * 0.3 * t)[:, None]
                         + rng.normal(0, 1e-3, (n, 1))])
    return RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=tuple(names),
                    position=pos, torque=trq, position_ref=ref_q, velocity_ref=ref_v,
                    acceleration_ref=ref_a, source=LogSource(f"{name}.csv", "", "memory"))


def carrying_log(name: str, seed: int, duration_s: float, *,
                 load: tuple[float, float, float, tuple[float, float, float]] | None = None,
                 pushes: tuple[tuple[float, float, float], ...] = (), fs: float = 250.0,
                 ) -> RobotLog:
    """A log of shipped robot ``name`` (every URDF joint an arm joint, all logged) moving in
    multi-sines about a bent-arm pose, its torque the URDF's RNEA plus Coulomb friction of
    4 % of each joint's effort limit (a tenth of that viscous, per rad/s) and noise (0.5 %
    of each joint's range, and a tenth of its friction) — a motor-side log as a real arm
    gives.

    ``load`` (t_pick, t_place, mass [kg], centre of mass in the last link's frame [m]): a
    body carried between those times (its own inertia 1e-3·m kg·m² about each axis).
    ``pushes`` (t0, t1, force [N]): a half-sine force at the tip link along the base's −x.
    """
    pin = _pin()
    model = full_model(name)
    data = model.createData()
    loaded = model.copy()
    last = model.njoints - 1
    if load is not None:
        m, c = load[2], np.asarray(load[3], dtype=np.float64)
        loaded.inertias[last] = model.inertias[last] + pin.Inertia(m, c, np.eye(3) * 1e-3 * m)
    ldata = loaded.createData()
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * fs)) / fs
    n, nj = t.size, model.nv
    q = np.zeros((n, nj))
    qd = np.zeros((n, nj))
    qdd = np.zeros((n, nj))
    for c in range(nj):
        for k, f in enumerate((0.11 + 0.037 * c + 0.01 * seed, 0.29 + 0.043 * c,
                               0.53 + 0.029 * c)):
            a, w, ph = 0.5 / (k + 1), 2 * np.pi * f, rng.uniform(0, 2 * np.pi)
            q[:, c] += a * np.sin(w * t + ph)
            qd[:, c] += a * w * np.cos(w * t + ph)
            qdd[:, c] -= a * w * w * np.sin(w * t + ph)
    if nj >= 3:  # a bent arm, not a straight one
        q[:, 1] -= 1.2
        q[:, 2] += 1.0
    tau = np.zeros((n, nj))
    for k in range(n):
        carry = load is not None and load[0] <= t[k] < load[1]
        tau[k] = pin.rnea(*((loaded, ldata) if carry else (model, data)), q[k], qd[k], qdd[k])
    tip = model.getFrameId(robots.entry(name).tip)  # type: ignore[union-attr]
    for t0, t1, force in pushes:
        for k in np.flatnonzero((t >= t0) & (t < t1)):
            pin.computeJointJacobians(model, data, q[k])
            pin.updateFramePlacements(model, data)
            jac = pin.getFrameJacobian(model, data, tip, pin.LOCAL_WORLD_ALIGNED)[:3]
            tau[k] -= jac.T @ np.array([force * np.sin(np.pi * (t[k] - t0) / (t1 - t0)), 0, 0])
    fric = 0.04 * np.asarray(model.effortLimit, dtype=np.float64)
    tau += rng.normal(0.0, 1.0, tau.shape) * (0.005 * np.ptp(tau, axis=0) + 0.1 * fric)
    tau += fric * np.tanh(qd / 0.02) + 0.1 * fric * qd
    return RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=robots.arm_joints(name),
                    position=q + rng.normal(0.0, 1e-5, q.shape), torque=tau, position_ref=q,
                    velocity_ref=qd, acceleration_ref=qdd,
                    source=LogSource(f"{name}.csv", "", "memory"))
