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

    def jac(q: np.ndarray, i: int) -> np.ndarray | None:
        if i < 1 or i > len(ids):
            return None
        x = pin.neutral(model)
        for k, iq in enumerate(idx_q):
            if nq[k] == 1:
                x[iq] = q[k]
            else:  # a continuous joint: (cos, sin)
                x[iq], x[iq + 1] = np.cos(q[k]), np.sin(q[k])
        pin.forwardKinematics(model, data, x)
        pin.updateFramePlacements(model, data)
        full = pin.computeJointJacobians(model, data, x)
        if i < len(ids):
            p = np.array(data.oMi[ids[i]].translation)
        elif tip_frame is not None:
            p = np.array(data.oMf[tip_frame].translation)
        else:
            o = np.array(data.oMi[ids[-1]].translation)
            cands = [np.array(data.oMf[k].translation) for k in last_frames] or [o]
            p = max(cands, key=lambda c: float(np.linalg.norm(c - o)))
        cols = []
        for k in range(i):
            col = full[:, idx_v[k]]
            cols.append(col[:3] + np.cross(col[3:], p))
        return np.column_stack(cols)

    return jac
