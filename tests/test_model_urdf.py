"""URDF model through Pinocchio: regressor vs RNEA, agreement with the planar model, bad URDF."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.errors import RobotDescriptionError
from impactcli.model import IdentifyOptions, RigidModel, identify_signals
from impactcli.model.structures import urdf_full_names, urdf_full_regressor, urdf_structure
from impactcli.types import JointSpec, RobotDescription

from .reference.two_link_arm import TwoLinkArm, multisine

pin = pytest.importorskip("pinocchio")
pytestmark = pytest.mark.urdf

JOINTS = ("shoulder", "elbow")
ARM = TwoLinkArm()
BASE = {"coulomb_slope_rad_s": ARM.vs, "offset": True, "motor_inertia": True}


def robot(kind: str, urdf_xml: str | None = None) -> RobotDescription:
    kin = ({"type": "planar", "link_lengths": [ARM.l1, ARM.l2], "gravity": [0.0, -ARM.g]}
           if kind == "planar" else {"type": "urdf", "path": "arm.urdf", "urdf_xml": urdf_xml})
    return RobotDescription(joints=tuple(JointSpec(j) for j in JOINTS), kinematics=kin)


def test_regressor_times_true_parameters_is_rnea() -> None:
    xml = ARM.urdf(JOINTS)
    s = urdf_structure(xml, JOINTS, dict(BASE), "arm.urdf")
    model = pin.buildModelFromXML(xml)
    data = model.createData()
    rng = np.random.default_rng(0)
    q = rng.uniform(-3, 3, (30, 2))
    qd = rng.normal(0, 2, (30, 2))
    qdd = rng.normal(0, 5, (30, 2))
    y = urdf_full_regressor(q, qd, qdd, JOINTS, s)
    names = urdf_full_names(JOINTS, s)
    theta = np.zeros(len(names))
    for i in (1, 2):
        dyn = model.inertias[i].toDynamicParameters()
        theta[10 * (i - 1):10 * i] = dyn
    rnea = np.array([pin.rnea(model, data, q[k], qd[k], qdd[k]) for k in range(30)])
    np.testing.assert_allclose(y @ theta, rnea, atol=1e-10)
    # and RNEA is the textbook arm (no motor inertia, friction, offset)
    bare = TwoLinkArm(ia1=0, ia2=0, fv1=0, fv2=0, fc1=0, fc2=0, off1=0, off2=0)
    np.testing.assert_allclose(rnea, bare.torque(q, qd, qdd), atol=1e-10)
    # base parameters: 3 per link + Ia of joint 2 + 3 friction columns per joint, like planar
    assert len(s["base_columns"]) == 13


def test_urdf_agrees_with_planar_on_the_same_arm() -> None:
    t = np.arange(3000) * 0.004
    q, qd, qdd = multisine(t, 2, seed=1)
    tau = ARM.torque(q, qd, qdd)
    m_urdf = identify_signals(q, qd, qdd, tau, joint_names=JOINTS, kind="urdf",
                              robot=robot("urdf", ARM.urdf(JOINTS)))
    m_plan = identify_signals(q, qd, qdd, tau, joint_names=JOINTS, kind="planar",
                              robot=robot("planar"))
    assert len(m_urdf.theta) == len(m_plan.theta)
    t2 = np.arange(1000) * 0.004
    q2, qd2, qdd2 = multisine(t2, 2, seed=9)  # a trajectory neither model saw
    truth = ARM.torque(q2, qd2, qdd2)
    tol = 1e-6 * np.abs(truth).max()
    np.testing.assert_allclose(m_urdf.predict(q2, qd2, qdd2), truth, atol=tol)
    np.testing.assert_allclose(m_plan.predict(q2, qd2, qdd2), truth, atol=tol)
    # same fitted friction (the friction columns are shared)
    for name in ("shoulder.fv", "elbow.fc", "elbow.offset", "elbow.Ia"):
        a = m_urdf.theta[m_urdf.param_names.index(name)]
        b = m_plan.theta[m_plan.param_names.index(name)]
        assert a == pytest.approx(b, rel=1e-6)
    # the model is self-contained: a round trip through its mapping predicts the same
    back = RigidModel.from_dict(m_urdf.to_dict())
    np.testing.assert_allclose(back.predict(q2, qd2, qdd2), m_urdf.predict(q2, qd2, qdd2))
    assert back.sha256 == m_urdf.sha256


def test_urdf_mass_matrix_is_pinocchio_crba() -> None:
    t = np.arange(2000) * 0.004
    q, qd, qdd = multisine(t, 2, seed=2)
    arm = TwoLinkArm(ia1=0, ia2=0)
    tau = arm.torque(q, qd, qdd)
    m = identify_signals(q, qd, qdd, tau, joint_names=JOINTS, kind="urdf",
                         robot=robot("urdf", arm.urdf(JOINTS)), options=_opts(False))
    model = pin.buildModelFromXML(arm.urdf(JOINTS))
    data = model.createData()
    mm = m.mass_matrix(q[:5])
    for k in range(5):
        crba = pin.crba(model, data, q[k])
        crba = np.triu(crba) + np.triu(crba, 1).T
        np.testing.assert_allclose(mm[k], crba, atol=1e-8)


def _opts(motor_inertia: bool) -> IdentifyOptions:
    return IdentifyOptions(motor_inertia=motor_inertia)


@pytest.mark.parametrize("xml", ["<robot name='x'><link name='a'/>", "not xml at all",
                                 "<robot name='r'><joint name='j' type='revolute'/></robot>"])
def test_bad_urdf_is_one_robot_description_error(xml: str) -> None:
    t = np.arange(1000) * 0.004
    q, qd, qdd = multisine(t, 2)
    with pytest.raises(RobotDescriptionError, match=r"arm\.urdf") as info:
        identify_signals(q, qd, qdd, q, joint_names=JOINTS, kind="urdf", robot=robot("urdf", xml))
    assert "\n" not in str(info.value)


def test_urdf_joint_missing_is_named() -> None:
    xml = ARM.urdf(("a", "b"))
    t = np.arange(1000) * 0.004
    q, qd, qdd = multisine(t, 2)
    with pytest.raises(RobotDescriptionError, match="shoulder"):
        identify_signals(q, qd, qdd, q, joint_names=JOINTS, kind="urdf", robot=robot("urdf", xml))
