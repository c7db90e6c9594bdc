"""Kinematics the incidents need: the Jacobian of a link's end point (docs/incidents.md,
"The rules": the force at the isolated link). Planar arms: :func:`impactcli.detect.incidents.
planar_jacobian`; URDF arms (Pinocchio, the ``urdf`` extra): :func:`urdf_link_end_jacobian`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..logs.urdf import pinocchio, reduced_model, urdf_joint_order


def urdf_link_end_jacobian(
    structure: dict[str, Any], joints: tuple[str, ...],
) -> Any:
    """A function (q (J,) in ``joints`` order [rad], link i 1-based) → (3, i) Jacobian of the
    point at the end of link i — the origin of joint i+1, or for the last joint its
    farthest frame (the shipped robot's tip link when the model names one) — for the force
    estimate of :mod:`impactcli.detect.incidents`. ``joints``: the model's (log) joints in
    chain order. Linear velocity of a point p: v + ω × p from Pinocchio's world-frame joint
    Jacobians."""
    pin = pinocchio()
    ujoints = urdf_joint_order(joints, structure)
    model = reduced_model(structure["urdf_xml"], ujoints, structure.get("urdf_path", "URDF"))
    data = model.createData()
    ids = [model.getJointId(j) for j in ujoints]
    idx_v = [model.joints[i].idx_v for i in ids]
    idx_q = [model.joints[i].idx_q for i in ids]
    nq = [model.joints[i].nq for i in ids]
    tip_frame = None
    robot = structure.get("urdf_robot")
    if robot:
        from ..logs.robot_catalogue import entry

        e = entry(str(robot))
        if e is not None and model.existFrame(e.tip, pin.FrameType.BODY):
            tip_frame = model.getFrameId(e.tip, pin.FrameType.BODY)
    last_frames = [k for k, f in enumerate(model.frames) if f.parentJoint == ids[-1]]

    last: dict[str, Any] = {}  # the posture asked last: every link at it costs one pass

    def at(q: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """The world-frame joint Jacobians and each link's end point at posture ``q``."""
        key = np.asarray(q, dtype=np.float64).tobytes()
        if last.get("key") != key:
            x = pin.neutral(model)
            for k, iq in enumerate(idx_q):
                if nq[k] == 1:
                    x[iq] = q[k]
                else:  # a continuous joint: (cos, sin)
                    x[iq], x[iq + 1] = np.cos(q[k]), np.sin(q[k])
            pin.forwardKinematics(model, data, x)
            pin.updateFramePlacements(model, data)
            full = np.array(pin.computeJointJacobians(model, data, x))
            ends = [np.array(data.oMi[ids[i]].translation) for i in range(1, len(ids))]
            if tip_frame is not None:
                ends.append(np.array(data.oMf[tip_frame].translation))
            else:
                o = np.array(data.oMi[ids[-1]].translation)
                cands = [np.array(data.oMf[k].translation) for k in last_frames] or [o]
                ends.append(max(cands, key=lambda c: float(np.linalg.norm(c - o))))
            last.update(key=key, full=full, ends=ends)
        return last["full"], last["ends"]

    def jac(q: np.ndarray, i: int) -> np.ndarray | None:
        if i < 1 or i > len(ids):
            return None
        full, ends = at(q)
        cols = full[:, idx_v[:i]]  # (6, i): linear over angular velocity of joints 1..i
        return cols[:3] + np.cross(cols[3:].T, ends[i - 1]).T  # v + ω × p, column by column

    return jac
