"""Planar rigid model: regressor against the textbook 2-link arm, exact recovery, robustness."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.errors import ImpactWarning
from impactcli.model import IdentifyOptions, identify, identify_signals
from impactcli.model.structures import planar_inertial_regressor
from impactcli.types import JointSpec, LogSource, RobotDescription, RobotLog

from .reference.two_link_arm import TwoLinkArm, multisine

JOINTS = ("shoulder", "elbow")
ARM = TwoLinkArm()


def planar_robot(arm: TwoLinkArm = ARM) -> RobotDescription:
    return RobotDescription(
        joints=tuple(JointSpec(j) for j in JOINTS),
        kinematics={"type": "planar", "link_lengths": [arm.l1, arm.l2], "gravity": [0.0, -arm.g]},
        name="two-link",
    )


def exact_data(n: int = 3000, dt: float = 0.004, seed: int = 0):
    t = np.arange(n) * dt
    q, qd, qdd = multisine(t, 2, seed=seed)
    return t, q, qd, qdd, ARM.torque(q, qd, qdd)


def expected_theta(names: tuple[str, ...]) -> np.ndarray:
    bp = ARM.base_parameters()
    key = {"shoulder": "1", "elbow": "2"}
    return np.array([bp[f"{key[n.split('.')[0]]}.{n.split('.')[1]}"] for n in names])


def test_inertial_regressor_matches_textbook_on_random_states() -> None:
    rng = np.random.default_rng(1)
    q = rng.uniform(-np.pi, np.pi, (200, 2))
    qd = rng.normal(0, 2, (200, 2))
    qdd = rng.normal(0, 5, (200, 2))
    arm = TwoLinkArm(ia1=0, ia2=0, fv1=0, fv2=0, fc1=0, fc2=0, off1=0, off2=0)
    bp = arm.base_parameters()
    theta = np.array([bp[k] for k in ("1.ZZR", "1.MXR", "1.MYR", "2.ZZR", "2.MXR", "2.MYR")])
    y = planar_inertial_regressor(q, qd, qdd, [arm.l1, arm.l2], [0.0, -arm.g])
    np.testing.assert_allclose(y @ theta, arm.torque(q, qd, qdd), atol=1e-12)


def test_planar_recovers_base_parameters_exactly_from_rigid_data() -> None:
    _, q, qd, qdd, tau = exact_data()
    model = identify_signals(q, qd, qdd, tau, joint_names=JOINTS, kind="planar",
                             robot=planar_robot())
    want = expected_theta(model.param_names)
    err = np.abs(model.theta - want)
    # relative to each parameter, or to the vector's norm for the parameters that are 0
    scale = np.maximum(np.abs(want), 1e-3 * np.linalg.norm(want))
    assert np.max(err / scale) < 1e-6, dict(zip(model.param_names, err / scale, strict=True))
    assert model.fit["condition_number"] < 1e3
    for st in model.fit["joints"]["fit"].values():
        assert st["rms_rel_torque_rms"] < 1e-9


def test_contacts_do_not_bend_the_fit() -> None:
    _, q, qd, qdd, tau = exact_data(n=4000, seed=3)
    rng = np.random.default_rng(7)
    noisy = tau + rng.normal(0, 0.05, tau.shape)
    kw = {"joint_names": JOINTS, "kind": "planar", "robot": planar_robot()}
    clean = identify_signals(q, qd, qdd, noisy, **kw)
    hit = noisy.copy()
    for start in (500, 1700, 3100):  # three 60 ms pushes of 3 to 5 N·m on both joints
        bump = np.hanning(15)[:, None] * np.array([5.0, 3.0])
        hit[start:start + 15] += bump
    robust = identify_signals(q, qd, qdd, hit, **kw)
    plain = identify_signals(q, qd, qdd, hit, **kw, options=IdentifyOptions(robust="none"))
    tau_clean = clean.predict(q, qd, qdd)
    d_robust = np.sqrt(np.mean((robust.predict(q, qd, qdd) - tau_clean) ** 2, axis=0))
    d_plain = np.sqrt(np.mean((plain.predict(q, qd, qdd) - tau_clean) ** 2, axis=0))
    # the robust fit stays within the noise's own estimation scatter; plain LS is bent more
    assert np.all(d_robust < 0.005), d_robust
    assert np.all(d_plain > 3 * d_robust), (d_plain, d_robust)
    frac = robust.fit["robust"]["downweighted_fraction"]
    assert all(0.005 < f < 0.05 for f in frac.values()), frac


def make_log(q: np.ndarray, tau: np.ndarray, dt: float, joints=JOINTS) -> RobotLog:
    n = q.shape[0]
    return RobotLog(
        t_ns=np.round(np.arange(n) * dt * 1e9).astype(np.int64), joint_names=joints,
        position=q, torque=tau, source=LogSource("arm.csv", "ab" * 32, "memory"),
    )


def test_identify_from_log_with_filtered_derivatives_and_holdout() -> None:
    dt = 0.004
    _, q, _, _, tau = exact_data(n=5000, dt=dt, seed=5)  # 20 s
    rng = np.random.default_rng(2)
    log = make_log(q + rng.normal(0, 1e-5, q.shape), tau + rng.normal(0, 0.02, tau.shape), dt)
    model = identify(log, robot=planar_robot())
    assert model.kind == "planar"
    assert model.input_sha256 == "ab" * 32
    assert model.filter["holdout"]["start_s"] == pytest.approx(16.0, abs=0.01)  # last 20 %
    assert model.fit["n_samples_holdout"] > 0
    for name in JOINTS:
        for part in ("fit", "holdout"):
            st = model.fit["joints"][part][name]
            assert st["rms_rel_torque_rms"] < 0.01, (part, name, st)
    want = expected_theta(model.param_names)
    big = np.abs(want) > 0.05
    np.testing.assert_allclose(model.theta[big], want[big], rtol=0.03, atol=0.01)


def test_unexcited_parameter_is_warned_and_fixed_at_zero() -> None:
    # elbow moves but the shoulder's velocity never changes sign: its Coulomb column is
    # (almost) a copy of the offset column
    dt = 0.004
    t = np.arange(3000) * dt
    q, qd, qdd = multisine(t, 2, seed=4)
    q[:, 0], qd[:, 0], qdd[:, 0] = 0.2 * t, 0.2, 0.0
    tau = ARM.torque(q, qd, qdd)
    with pytest.warns(ImpactWarning, match="does not excite|excites the planar model poorly"):
        identify_signals(q, qd, qdd, tau, joint_names=JOINTS, kind="planar", robot=planar_robot())
