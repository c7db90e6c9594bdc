"""RobotLog, RobotDescription and Labels validate on construction."""

from __future__ import annotations

import json

import numpy as np
import pytest

from impactcli.errors import LabelsError, LogFormatError, RobotDescriptionError
from impactcli.logs.robot_files import read_labels, read_robot, robot_from_dict
from impactcli.types import RobotLog

from .conftest import make_log


def test_log_properties(small_log: RobotLog) -> None:
    assert small_log.n_samples == 500
    assert small_log.n_joints == 2
    assert small_log.sample_rate_hz == pytest.approx(250.0)
    assert small_log.duration_s == pytest.approx(499 * 0.004)
    assert small_log.time_s[0] == 0.0
    assert small_log.has_reference
    with pytest.raises(ValueError):  # arrays are frozen
        small_log.position[0, 0] = 1.0


def test_slice_keeps_channels(small_log: RobotLog) -> None:
    part = small_log.slice(100, 200)
    assert part.n_samples == 100
    np.testing.assert_array_equal(part.position_ref, small_log.position_ref[100:200])
    assert part.t0_ns == small_log.t_ns[100]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"t_ns": np.array([0, 2, 1], dtype=np.int64)}, "not strictly increasing at sample 2"),
        ({"t_ns": np.array([0, 1, 1], dtype=np.int64)}, "not strictly increasing"),
        ({"t_ns": np.array([0.0, 1.0, 2.0])}, "int64 nanoseconds"),
        ({"torque": np.zeros((3, 1))}, "torque has shape (3, 1)"),
        ({"position": np.array([[0.0, 1.0], [np.nan, 1.0], [0.0, 1.0]])},
         "position is not finite at sample 1"),
        ({"joint_names": ("a.b", "c")}, "invalid joint name"),
        ({"joint_names": ("a", "a")}, "duplicate joint names"),
        ({"position_ref": np.ones((2, 2))}, "position_ref has shape"),
    ],
)
def test_log_rejects_bad_arrays(change: dict, message: str) -> None:
    base = {
        "t_ns": np.array([0, 1, 2], dtype=np.int64), "joint_names": ("a", "b"),
        "position": np.zeros((3, 2)), "torque": np.zeros((3, 2)),
    }
    base.update(change)
    with pytest.raises(LogFormatError, match=message.replace("(", r"\(").replace(")", r"\)")):
        RobotLog(**base)


def test_log_needs_two_samples() -> None:
    with pytest.raises(LogFormatError, match="at least 2"):
        RobotLog(np.array([0], dtype=np.int64), ("a",), position=np.zeros((1, 1)),
                 torque=np.zeros((1, 1)))


def test_make_log_is_deterministic() -> None:
    a, b = make_log(seed=3), make_log(seed=3)
    np.testing.assert_array_equal(a.position, b.position)


def test_robot_description_roundtrip(tmp_path) -> None:
    d = {"name": "arm", "joints": [{"name": "s", "gear_ratio": 10, "torque_constant": 0.05},
                                   {"name": "e", "gear_ratio": 5, "torque_constant": 0.02}],
         "kinematics": {"type": "planar", "link_lengths": [0.4, 0.3]}}
    p = tmp_path / "r.json"
    p.write_text(json.dumps(d))
    robot = read_robot(p)
    assert robot.joint_names == ("s", "e")
    np.testing.assert_allclose(robot.torque_scale(), [0.5, 0.1])
    assert robot.kinematics == {"type": "planar", "link_lengths": [0.4, 0.3],
                                "gravity": [0.0, -9.81]}


@pytest.mark.parametrize(
    ("d", "message"),
    [
        ({"joints": []}, "non-empty list"),
        # a trial's robot file: a URDF by path with joint_map and no joints (only a named
        # robot lists its arm joints); the message says what to write
        ({"kinematics": {"type": "urdf", "path": "arm.urdf"}, "joint_map": {"a": "j1"}},
         "non-empty list — a URDF given by 'path' does not say which of its joints are the "
         "arm's: list the log's joints, base first"),
        ({"joints": [{"name": "a", "gear_ratio": -1}]}, "gear_ratio must be positive"),
        ({"joints": [{"name": "a"}], "kinematics": {"type": "planar", "link_lengths": [1, 2]}},
         "one link length per joint"),
        ({"joints": [{"name": "a"}], "kinematics": {"type": "scara"}}, "planar' or 'urdf"),
        ({"joints": [{"name": "a"}, {"name": "a"}]}, "duplicate"),
    ],
)
def test_robot_description_rejects(d: dict, message: str) -> None:
    with pytest.raises(RobotDescriptionError, match=message):
        robot_from_dict(d, "r.json")


def test_torque_scale_names_joint_without_constant() -> None:
    robot = robot_from_dict({"joints": [{"name": "a", "torque_constant": 1}, {"name": "b"}]})
    with pytest.raises(RobotDescriptionError, match="'b' has no torque_constant"):
        robot.torque_scale()


def test_robot_file_errors(tmp_path) -> None:
    with pytest.raises(RobotDescriptionError, match="not found"):
        read_robot(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("joints: [\n")
    with pytest.raises(RobotDescriptionError, match="does not parse"):
        read_robot(bad)


def test_labels(tmp_path) -> None:
    p = tmp_path / "l.json"
    p.write_text(json.dumps({"events": [{"start": 1.0, "end": 1.2, "peak_force": 12.5,
                                         "kind": "impact", "link": 2, "stiffness": 2.12}],
                             "sample_rate": 250}))
    labels = read_labels(p)
    assert labels.events[0].peak_force == 12.5
    assert labels.events[0].extra == {"stiffness": 2.12}
    assert labels.to_dict()["events"][0]["stiffness"] == 2.12
    p.write_text(json.dumps({"events": [{"start": 2, "end": 1, "peak_force": 1, "kind": "impact",
                                         "link": 1}], "sample_rate": 250}))
    with pytest.raises(LabelsError, match="ends before it starts"):
        read_labels(p)
    p.write_text(json.dumps({"events": [], "sample_rate": "fast"}))
    with pytest.raises(LabelsError, match="sample_rate"):
        read_labels(p)
