"""Through the CLI: a robot that shares no joint with the log is
exit 3 with a config as without one; a log without motion says what works instead."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from impactcli.logs import robot_catalogue as robots
from impactcli.logs import write_log
from impactcli.types import LogSource, RobotLog

from .cli_run import cli
from .reference.two_link_arm import TwoLinkArm, multisine

REPO = Path(__file__).resolve().parents[1]
P2P = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"
ARM = TwoLinkArm()


def one_error_line(err: str) -> str:
    lines = [x for x in err.splitlines() if x.startswith("impactcli: error:")]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


# ------------------------------------------------------------------ 3a: robot mismatch
needs_robots = pytest.mark.skipif(robots.data_dir() is None,
                                  reason="the robots extra (shipped URDFs) is not installed")


@needs_robots
@pytest.mark.parametrize("with_config", [True, False])
def test_panda_on_a_two_joint_log_is_exit_3_with_or_without_a_config(
        tmp_path: Path, with_config: bool) -> None:
    cfg = ["--config", str(CONFIG)] if with_config else []
    code, _, err = cli(["detect", str(P2P), "--robot", "panda", *cfg,
                        "-o", str(tmp_path / "out")])
    assert code == 3, err
    line = one_error_line(err)
    assert "robot 'panda'" in line                       # the robot
    assert "log: ['shoulder', 'elbow']" in line          # the log's joints
    assert "panda_joint1" in line and "panda_joint7" in line   # the robot's joints
    assert not (tmp_path / "out" / "assist_free_p2p.timeline.json").exists()


def test_a_log_naming_joints_otherwise_is_shown_the_joint_map(tmp_path: Path) -> None:
    """A log whose joints are the built UR10e's but named without ``_joint`` (as the
    ur_ext_observer channel map names them): exit 3, and the one line spells out the robot
    file's joint_map that names them; a log whose names match nothing gets the pointer
    alone."""
    from impactcli.logs.robot_files import joint_map_hint

    pytest.importorskip("pinocchio", reason="a built UR needs the urdf extra (pinocchio)")
    log = tmp_path / "ur.csv"
    joints = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
    t = np.arange(1500) / 250.0
    q = np.stack([0.3 * np.sin(0.5 * t + k) for k in range(6)], axis=1)
    write_log(RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=joints,
                       position=q, torque=np.random.default_rng(1).normal(size=q.shape),
                       source=LogSource("ur.csv", "", "memory")), log)
    code, _, err = cli(["detect", str(log), "--robot", "ur10e", "-o", str(tmp_path / "o")])
    assert code == 3, err
    line = one_error_line(err)
    assert ('e.g. {"kinematics": {"type": "urdf", "robot": "ur10e"}, "joint_map": '
            '{"shoulder_pan": "shoulder_pan_joint", "shoulder_lift": "shoulder_lift_joint", '
            '"elbow": "elbow_joint"') in line, line
    hint = joint_map_hint(("a", "b"), ("panda_joint1", "panda_joint2"), "panda")
    assert hint == "map the log's joint names onto the URDF's with a robot file's " \
        "joint_map (docs/robots.md)"


@needs_robots
def test_calibrate_with_a_robot_sharing_no_joint_is_exit_3(tmp_path: Path) -> None:
    code, _, err = cli(["calibrate", str(P2P), "--robot", "panda",
                        "-o", str(tmp_path / "c.toml")])
    assert code == 3, err
    assert "robot 'panda'" in one_error_line(err)
    assert not (tmp_path / "c.toml").exists()


@pytest.mark.parametrize("with_config", [True, False])
def test_a_robot_file_sharing_no_joint_is_exit_3_with_or_without_a_config(
        tmp_path: Path, with_config: bool) -> None:
    robot = tmp_path / "other.robot.json"
    robot.write_text(json.dumps({"name": "other", "joints": [{"name": "a1"}, {"name": "a2"}]}))
    cfg = ["--config", str(CONFIG)] if with_config else []
    code, _, err = cli(["detect", str(P2P), "--robot", str(robot), *cfg,
                        "-o", str(tmp_path / "out")])
    assert code == 3, err
    line = one_error_line(err)
    assert str(robot) in line
    assert "['shoulder', 'elbow']" in line and "['a1', 'a2']" in line


def test_a_robot_file_sharing_the_log_joints_still_runs_with_a_config(tmp_path: Path) -> None:
    robot = P2P.with_name("assist_free_p2p.robot.json")
    code, out, err = cli(["detect", str(P2P), "--robot", str(robot), "--config", str(CONFIG),
                          "-o", str(tmp_path / "out")])
    assert code == 0, err
    assert "assist_free_p2p.csv.gz" in out


# ------------------------------------------------------------------ 6b: a still arm
def arm_log(still: bool, n: int = 3000) -> RobotLog:
    t = np.arange(n) * 0.004
    q, qd, qdd = multisine(t, 2, seed=5)
    if still:
        q[:], qd[:], qdd[:] = 0.3, 0.0, 0.0
    tau = ARM.torque(q, qd, qdd) + np.random.default_rng(0).normal(0, 0.02, (n, 2))
    return RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=("shoulder", "elbow"),
                    position=q, torque=tau, source=LogSource("arm.csv", "", "memory"))


HINT = ("a config or a model from other logs of the same robot, with motion, works: "
        "--config CONFIG (from `impactcli calibrate` on logs with motion) or --model MODEL "
        "(from `impactcli identify` on a log with motion)")


@pytest.mark.parametrize("verb", ["detect", "identify"])
def test_a_still_arm_without_config_says_what_works(tmp_path: Path, verb: str) -> None:
    still = tmp_path / "still.csv"
    write_log(arm_log(still=True), still)
    out = ["-o", str(tmp_path / ("out" if verb == "detect" else "m.json"))]
    code, _, err = cli([verb, str(still), *out])
    assert code == 3, err
    line = one_error_line(err)
    assert f"{still}: the log has no motion" in line
    assert "a model cannot be identified from it" in line
    assert HINT in line


def test_what_the_still_arm_message_says_works(tmp_path: Path) -> None:
    """Its hint followed: a model from a log of the same arm with motion, then detect."""
    moving, still = tmp_path / "moving.csv", tmp_path / "still.csv"
    write_log(arm_log(still=False), moving)
    write_log(arm_log(still=True), still)
    code, _, err = cli(["identify", str(moving), "-o", str(tmp_path / "m.json")])
    assert code == 0, err
    code, _out, err = cli(["detect", str(still), "--model", str(tmp_path / "m.json"),
                          "-o", str(tmp_path / "out")])
    assert code == 0, err
    assert (tmp_path / "out" / "still.timeline.json").is_file()
