"""``impactcli identify`` and identification's input errors, through the API and CliRunner."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.errors import ImpactWarning, ModelError, RobotDescriptionError
from impactcli.io import read_log, write_log
from impactcli.model import IdentifyOptions, identify, read_model
from impactcli.model.textbook import TwoLinkArm, multisine
from impactcli.types import JointSpec, LogSource, RobotDescription, RobotLog

JOINTS = ("shoulder", "elbow")
ARM = TwoLinkArm()
ROBOT = {"name": "two", "joints": [{"name": "shoulder"}, {"name": "elbow"}],
         "kinematics": {"type": "planar", "link_lengths": [ARM.l1, ARM.l2],
                        "gravity": [0.0, -ARM.g]}}


def arm_log(n: int = 3000, still: tuple[int, ...] = (),
            joints: tuple[str, ...] = JOINTS) -> RobotLog:
    t = np.arange(n) * 0.004
    q, qd, qdd = multisine(t, 2, seed=5)
    for j in still:
        q[:, j], qd[:, j], qdd[:, j] = 0.3, 0.0, 0.0
    tau = ARM.torque(q, qd, qdd) + np.random.default_rng(0).normal(0, 0.02, (n, 2))
    return RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=joints, position=q,
                    torque=tau, source=LogSource("arm.csv", "", "memory"))


def robot(joints: tuple[str, ...] = JOINTS, kin: dict | None = None) -> RobotDescription:  # type: ignore[type-arg]
    return RobotDescription(joints=tuple(JointSpec(j) for j in joints), kinematics=kin,
                            path="robot.json")


def run(args: list[str]) -> tuple[int, str, str]:
    res = CliRunner().invoke(main, args)
    return res.exit_code, res.stdout, res.stderr


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    out = {"log": tmp_path / "arm.csv", "robot": tmp_path / "robot.json"}
    write_log(arm_log(), out["log"])
    out["robot"].write_text(json.dumps(ROBOT))
    return out


# ---------------------------------------------------------------- API errors
def test_no_motion_is_a_model_error() -> None:
    with pytest.raises(ModelError, match="no motion") as info:
        identify(arm_log(still=(0, 1)))
    assert "arm.csv" in str(info.value)


def test_constant_joint_is_named() -> None:
    with pytest.raises(ModelError, match="elbow") as info:
        identify(arm_log(still=(1,)))
    assert "shoulder" not in str(info.value)


def test_robot_that_does_not_match_the_log() -> None:
    with pytest.raises(RobotDescriptionError, match=r"\['wrist'\].*\['elbow'\]"):
        identify(arm_log(), robot=robot(("shoulder", "wrist")))


def test_planar_kind_without_kinematics() -> None:
    with pytest.raises(RobotDescriptionError, match="planar kinematics"):
        identify(arm_log(), robot=robot(), kind="planar")


def test_default_kind_follows_the_robot() -> None:
    kin = ROBOT["kinematics"]
    assert identify(arm_log(), robot=robot(kin=kin)).kind == "planar"  # type: ignore[arg-type]
    m = identify(arm_log(), robot=robot(JOINTS[::-1]))
    assert m.kind == "decoupled" and m.joint_names == JOINTS[::-1]  # robot chain order


# ---------------------------------------------------------------- CLI
def test_cli_writes_a_model_and_prints_the_fit_table(files: dict[str, Path],
                                                     tmp_path: Path) -> None:
    out = tmp_path / "model.json"
    code, stdout, stderr = run(["identify", str(files["log"]), "--robot", str(files["robot"]),
                                "-o", str(out)])
    assert code == 0, (stdout, stderr)
    m = read_model(out)
    assert m.kind == "planar"
    for j in JOINTS:
        assert j in stdout
        assert m.fit["joints"]["holdout"][j]["rms_rel_torque_rms"] < 0.02
    assert "held-back" in stdout


def _assert_one_line_error(code: int, stdout: str, stderr: str, *needles: str) -> None:
    assert code == 3, (stdout, stderr)
    lines = [ln for ln in stderr.splitlines() if ln.startswith("impactcli: error:")]
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    for n in needles:
        assert n in lines[0], lines[0]


def test_cli_still_log_exit_3(tmp_path: Path) -> None:
    p = tmp_path / "still.csv"
    write_log(arm_log(still=(0, 1)), p)
    _assert_one_line_error(*run(["identify", str(p), "-o", str(tmp_path / "m.json")]),
                           "still.csv", "no motion")
    assert not (tmp_path / "m.json").exists()


def test_cli_constant_joint_exit_3(tmp_path: Path) -> None:
    p = tmp_path / "const.csv"
    write_log(arm_log(still=(0,)), p)
    _assert_one_line_error(*run(["identify", str(p), "-o", str(tmp_path / "m.json")]),
                           "const.csv", "shoulder")


def test_cli_mismatched_robot_exit_3(files: dict[str, Path], tmp_path: Path) -> None:
    bad = tmp_path / "other.json"
    bad.write_text(json.dumps({**ROBOT, "joints": [{"name": "a"}, {"name": "b"}],
                               "kinematics": None}))
    _assert_one_line_error(*run(["identify", str(files["log"]), "--robot", str(bad),
                                 "-o", str(tmp_path / "m.json")]), "does not match")


@pytest.mark.urdf
def test_cli_unparsable_urdf_exit_3(files: dict[str, Path], tmp_path: Path) -> None:
    pytest.importorskip("pinocchio")
    (tmp_path / "arm.urdf").write_text("<robot name='x'><link name='a'>")
    desc = tmp_path / "urdf_robot.json"
    desc.write_text(json.dumps({**ROBOT, "kinematics": {"type": "urdf", "path": "arm.urdf"}}))
    code, stdout, stderr = run(["identify", str(files["log"]), "--robot", str(desc),
                                "-o", str(tmp_path / "m.json")])
    _assert_one_line_error(code, stdout, stderr, "arm.urdf", "does not parse")


@pytest.mark.urdf
def test_cli_urdf_model(files: dict[str, Path], tmp_path: Path) -> None:
    pytest.importorskip("pinocchio")
    (tmp_path / "arm.urdf").write_text(ARM.urdf(JOINTS))
    desc = tmp_path / "urdf_robot.json"
    desc.write_text(json.dumps({**ROBOT, "kinematics": {"type": "urdf", "path": "arm.urdf"}}))
    out = tmp_path / "m.json"
    code, stdout, stderr = run(["identify", str(files["log"]), "--robot", str(desc),
                                "-o", str(out)])
    assert code == 0, (stdout, stderr)
    m = read_model(out)
    assert m.kind == "urdf"
    assert m.fit["joints"]["holdout"]["shoulder"]["rms_rel_torque_rms"] < 0.02


def test_cli_bad_option_is_usage_error(files: dict[str, Path], tmp_path: Path) -> None:
    code, _, stderr = run(["identify", str(files["log"]), "--cutoff", "-1", "-o",
                           str(tmp_path / "m.json")])
    assert code == 2, stderr


def test_still_joint_allowed_keeps_only_its_constant_torque() -> None:
    with pytest.warns(ImpactWarning, match="elbow"):
        m = identify(arm_log(still=(1,)), options=IdentifyOptions(allow_still_joints=True))
    values = dict(zip(m.param_names, m.theta, strict=True))
    assert all(values[f"elbow.{p}"] == 0.0 for p in ("inertia", "gcos", "gsin", "fv", "fc"))
    assert values["elbow.offset"] != 0.0
    assert m.fit["still_joints"] == ["elbow"]


@pytest.mark.real_logs
def test_decoupled_fit_on_the_real_kuka_log(real_logs: Path) -> None:
    log = read_log(real_logs / "kuka_lwr4" / "measurements_1.npz", channel_map="kuka_lwr4")
    m = identify(log)
    assert m.kind == "decoupled" and m.n_joints == 7
    hold = m.fit["joints"]["holdout"]
    # the gravity-loaded joints are fitted to a fraction of their torque even by a
    # per-joint model; the full table is in the report, measured, not asserted
    assert hold["a2"]["rms_rel_torque_rms"] < 0.2
    assert hold["a4"]["rms_rel_torque_rms"] < 0.3
