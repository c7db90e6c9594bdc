"""Position units that cannot be right are told apart from real arms' radians."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impactcli.logs.plausibility import (
    DEG,
    JointLimits,
    MotionSketch,
    position_unit_verdict,
    urdf_joint_limits,
)

JOINTS = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")


def _arm_motion(seconds: float = 60.0, rate: float = 500.0, seed: int = 0) -> np.ndarray:
    """(N, 6) positions [rad] of a 6-joint arm doing point-to-point moves of up to ±1.5 rad
    at up to about 1.2 rad/s, with encoder noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate)) / rate
    q = np.zeros((t.size, 6))
    for j in range(6):
        for k in range(1, 4):
            q[:, j] += rng.uniform(0.1, 0.5) * np.sin(2 * math.pi * 0.05 * k * t
                                                      + rng.uniform(0, 6))
    return q + 1e-4 * rng.standard_normal(q.shape)


def _sketch(q: np.ndarray, rate: float = 500.0, chunk: int | None = None) -> MotionSketch:
    s = MotionSketch(q.shape[1], 1.0 / rate)
    step = chunk or q.shape[0]
    for a in range(0, q.shape[0], step):
        s.update(q[a:a + step])
    return s


def _verdict(q: np.ndarray, limits: dict[str, JointLimits] | None = None,
             joints: tuple[str, ...] = JOINTS) -> object:
    s = _sketch(q)
    return position_unit_verdict("arm.csv", joints, s.travel(), s.speed(), limits)


def test_an_arm_in_radians_passes() -> None:
    assert _verdict(_arm_motion()).kind == "ok"


def test_the_same_arm_in_degrees_is_refused_naming_the_option() -> None:
    v = _verdict(_arm_motion() / DEG)
    assert v.kind == "refuse"
    assert v.message.startswith("arm.csv: positions look like degrees: joint(s) shoulder_pan")
    assert "Give --position-unit deg" in v.message
    assert set(v.joints) == set(JOINTS)


def test_degrees_with_a_still_joint_are_still_refused() -> None:
    q = _arm_motion() / DEG
    q[:, 2] = 12.0  # the elbow stands still: it neither helps nor hides the others
    assert _verdict(q).kind == "refuse"


def test_one_joint_beyond_an_arm_is_a_warning_not_a_refusal() -> None:
    q = _arm_motion()
    q[:, 5] *= 40.0  # one joint's scale is wrong (a gear ratio?), the others are radians
    v = _verdict(q)
    assert v.kind == "warn" and v.joints == ("wrist_3",)
    assert "--position-unit deg|rad" in v.message and "gear ratio" in v.message


def test_a_continuous_wrist_turning_many_times_is_fine_with_its_urdf() -> None:
    q = _arm_motion()
    t = np.arange(q.shape[0]) / 500.0
    q[:, 5] = 3.0 * t  # 180 rad over a minute: 29 turns at 3 rad/s
    assert _verdict(q).kind == "warn"  # without a URDF: more than an arm's joint travels
    limits = {"wrist_3": JointLimits("continuous", velocity=6.28)}
    assert _verdict(q, limits).kind == "ok"


def test_urdf_limits_sharpen_the_check() -> None:
    q = _arm_motion()
    q[:, 1] *= 3.0  # shoulder_lift travels about 3× its ±0.5 rad limit
    limits = {"shoulder_lift": JointLimits("revolute", -0.5, 0.5, 2.0)}
    assert _verdict(q).kind == "ok"
    assert _verdict(q, limits).kind == "warn"


def test_wrapped_angles_are_not_speed_and_a_glitch_only_warns() -> None:
    """An angle wrapped at ±π jumps by 2π in one sample: not a speed (the speed is a high
    percentile over windows). A glitch of 50 rad for three samples is named, not refused."""
    q = _arm_motion()
    q[:, 0] = np.angle(np.exp(1j * (q[:, 0] + 0.4 * np.arange(q.shape[0]) / 500.0)))
    assert _verdict(q).kind == "ok"
    q[1000:1003, 3] += 50.0
    v = _verdict(q)
    assert v.kind == "warn" and v.joints == ("wrist_1",)


def test_the_sketch_does_not_depend_on_the_chunks() -> None:
    q = _arm_motion(seconds=10)
    whole = _sketch(q)
    for chunk in (1, 7, 1000):
        s = _sketch(q, chunk=chunk)
        np.testing.assert_array_equal(s.travel(), whole.travel())
        np.testing.assert_array_equal(s.speed(), whole.speed())
    assert np.all(whole.speed() < 2.0) and np.all(whole.speed() > 0.05)


def test_urdf_limits_are_read() -> None:
    xml = """<robot name="r">
      <joint name="a" type="revolute"><limit lower="-1.5" upper="2" velocity="3.1"/></joint>
      <joint name="b" type="continuous"><limit velocity="6.28" effort="1"/></joint>
      <joint name="c" type="fixed"/>
      <joint name="d" type="prismatic"><limit lower="0" upper="1" velocity="1"/></joint>
    </robot>"""
    assert urdf_joint_limits(xml) == {"a": JointLimits("revolute", -1.5, 2.0, 3.1),
                                      "b": JointLimits("continuous", None, None, 6.28)}
    assert urdf_joint_limits("<robot") == {}


@pytest.mark.real_logs
def test_real_arms_pass(real_logs: object) -> None:
    from pathlib import Path

    base = Path(str(real_logs))
    ur = np.loadtxt(base / "ur_ext_observer" / "link4.csv", delimiter=",")
    s = MotionSketch(6, float(np.median(np.diff(ur[:, 0]))))
    s.update(ur[:, 1:7])
    assert position_unit_verdict("link4.csv", JOINTS, s.travel(), s.speed()).kind == "ok"
    kuka = np.load(base / "kuka_lwr4" / "measurements_1.npz")
    q = kuka["positions"]
    s = MotionSketch(q.shape[1], float(np.median(np.diff(kuka["times"]))))
    s.update(q)
    names = tuple(f"j{k}" for k in range(q.shape[1]))
    assert position_unit_verdict("kuka.npz", names, s.travel(), s.speed()).kind == "ok"
    s = MotionSketch(q.shape[1], float(np.median(np.diff(kuka["times"]))))
    s.update(q / DEG)
    assert position_unit_verdict("kuka.npz", names, s.travel(), s.speed()).kind == "refuse"


def test_noise_is_no_motion_and_says_nothing_of_a_unit() -> None:
    """Positions that are noise (test fixtures, a sensor gone wrong) move 10× slower over
    200 ms than over 20 ms: they are not judged, whatever their numbers."""
    rng = np.random.default_rng(5)
    arm = _sketch(_arm_motion())
    assert arm.smooth().all()
    noise = 3.0 * rng.standard_normal((30_000, 6))  # travel ~25, speeds ~400 "rad/s"
    walk = np.cumsum(rng.standard_normal((30_000, 6)), axis=0)
    for q in (noise, walk):
        s = _sketch(q)
        assert not s.smooth().any()
        assert position_unit_verdict("x.csv", JOINTS, s.travel(), s.speed()).kind == "refuse"
        assert position_unit_verdict("x.csv", JOINTS, s.travel(), s.speed(),
                                     smooth=s.smooth()).kind == "ok"
    deg = _sketch(_arm_motion() / DEG)  # degrees are a motion: still refused
    assert deg.smooth().all()
    assert position_unit_verdict("x.csv", JOINTS, deg.travel(), deg.speed(),
                                 smooth=deg.smooth()).kind == "refuse"


def test_the_smoothness_does_not_depend_on_the_chunks() -> None:
    q = np.concatenate([_arm_motion(seconds=6), 0.5 * np.random.default_rng(2)
                        .standard_normal((3000, 6))])
    whole = _sketch(q)
    for chunk in (1, 7, 53, 1000):
        s = _sketch(q, chunk=chunk)
        np.testing.assert_array_equal(s.counts_long, whole.counts_long)
        np.testing.assert_array_equal(s.smooth(), whole.smooth())


def test_beyond_a_urdfs_velocity_limit_is_warned_never_refused() -> None:
    """A description may be wrong (or a simulated log faster than the arm): only what no
    arm's radians could be is refused."""
    q = _arm_motion()
    limits = {j: JointLimits("revolute", -3.0, 3.0, 0.1) for j in JOINTS}  # 0.1 rad/s
    v = _verdict(q, limits)
    assert v.kind == "warn" and set(v.joints) == set(JOINTS)
    assert "beyond the URDF's velocity limit or range" in v.message


def test_degrees_against_calibration_bounds() -> None:
    """Known truth at the bounds: a joint that travels 0.5 rad as logged against a 1 rad
    calibration range is radians read as degrees (0.0087 rad, 0.87 %); one that travels
    0.06 rad as degrees could be degrees (no word); one that would travel 4 rad as radians
    is beyond the calibration either way (no word); one that barely moves tells nothing."""
    from impactcli.logs.plausibility import DEG, degrees_against_calibration

    cal = {"a": (-0.5, 0.5), "b": (0.0, 1.0)}
    said = degrees_against_calibration("x.csv", ("a", "b"), np.array([0.5, 0.001]) * DEG,
                                       cal)
    assert said is not None and "x.csv" in said and "a 0.5 rad against 1" in said
    assert "at most 0.87 %" in said and "b " not in said
    assert degrees_against_calibration("x.csv", ("a", "b"), np.array([0.5 * DEG, 0.06]),
                                       cal) is None
    assert degrees_against_calibration("x.csv", ("a",), np.array([4.0 * DEG]), cal) is None
    assert degrees_against_calibration("x.csv", ("b",), np.array([0.1 * DEG]), cal) is None
    assert degrees_against_calibration("x.csv", ("c",), np.array([0.5 * DEG]), cal) is None
