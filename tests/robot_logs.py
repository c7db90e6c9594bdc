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
