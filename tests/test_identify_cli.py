"""``impactcli identify`` and identification's input errors, through the API and CliRunner."""

from __future__ import annotations

import dataclasses
import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from impactcli.cli.fit_table import format_fit_table
from impactcli.errors import ImpactWarning, ModelError, RobotDescriptionError
from impactcli.logs import write_log
from impactcli.model import IdentifyOptions, identify
from impactcli.run.model_files import read_model
from impactcli.types import JointSpec, LogSource, RobotDescription, RobotLog

from .cli_run import cli
from .conftest import read_kuka
from .reference.two_link_arm import TwoLinkArm, multisine

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
    code, stdout, stderr = cli(["identify", str(files["log"]), "--robot", str(files["robot"]),
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
    _assert_one_line_error(*cli(["identify", str(p), "-o", str(tmp_path / "m.json")]),
                           "still.csv", "no motion")
    assert not (tmp_path / "m.json").exists()


def test_cli_constant_joint_exit_3_when_still_joints_are_not_allowed(tmp_path: Path) -> None:
    p = tmp_path / "const.csv"
    write_log(arm_log(still=(0,)), p)
    _assert_one_line_error(*cli(["identify", str(p), "--no-allow-still-joints",
                                 "-o", str(tmp_path / "m.json")]), "const.csv", "shoulder")


def test_cli_still_joint_is_allowed_by_default_as_in_calibrate(tmp_path: Path) -> None:
    """identify treats a joint that never moves as calibrate and detect do: its constant
    torque only, one warning naming it, and ``still`` in the fit table."""
    p = tmp_path / "const.csv"
    write_log(arm_log(still=(0,)), p)
    out = tmp_path / "m.json"
    code, stdout, stderr = cli(["identify", str(p), "-o", str(out)])
    assert code == 0, (stdout, stderr)
    assert (f"impactcli: warning: {p}: joint(s) stay constant (shoulder 0 rad): only their "
            "constant torque is modelled") in stderr.splitlines()
    m = read_model(out)
    assert m.fit["still_joints"] == ["shoulder"]
    assert "still joints (constant torque only): shoulder" in stdout
    row = next(ln for ln in stdout.splitlines() if ln.startswith("shoulder "))
    assert row.split()[-2:] == ["still", "still"]


def test_cli_mismatched_robot_exit_3(files: dict[str, Path], tmp_path: Path) -> None:
    bad = tmp_path / "other.json"
    bad.write_text(json.dumps({**ROBOT, "joints": [{"name": "a"}, {"name": "b"}],
                               "kinematics": None}))
    _assert_one_line_error(*cli(["identify", str(files["log"]), "--robot", str(bad),
                                 "-o", str(tmp_path / "m.json")]), "does not match")


@pytest.mark.urdf
def test_cli_unparsable_urdf_exit_3(files: dict[str, Path], tmp_path: Path) -> None:
    pytest.importorskip("pinocchio")
    (tmp_path / "arm.urdf").write_text("<robot name='x'><link name='a'>")
    desc = tmp_path / "urdf_robot.json"
    desc.write_text(json.dumps({**ROBOT, "kinematics": {"type": "urdf", "path": "arm.urdf"}}))
    code, stdout, stderr = cli(["identify", str(files["log"]), "--robot", str(desc),
                                "-o", str(tmp_path / "m.json")])
    _assert_one_line_error(code, stdout, stderr, "arm.urdf", "does not parse")


@pytest.mark.urdf
def test_cli_urdf_model(files: dict[str, Path], tmp_path: Path) -> None:
    pytest.importorskip("pinocchio")
    (tmp_path / "arm.urdf").write_text(ARM.urdf(JOINTS))
    desc = tmp_path / "urdf_robot.json"
    desc.write_text(json.dumps({**ROBOT, "kinematics": {"type": "urdf", "path": "arm.urdf"}}))
    out = tmp_path / "m.json"
    code, stdout, stderr = cli(["identify", str(files["log"]), "--robot", str(desc),
                                "-o", str(out)])
    assert code == 0, (stdout, stderr)
    m = read_model(out)
    assert m.kind == "urdf"
    assert m.fit["joints"]["holdout"]["shoulder"]["rms_rel_torque_rms"] < 0.02


def test_cli_bad_option_is_usage_error(files: dict[str, Path], tmp_path: Path) -> None:
    code, _, stderr = cli(["identify", str(files["log"]), "--cutoff", "-1", "-o",
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
    log = read_kuka(real_logs)
    with pytest.warns(ImpactWarning) as record:
        m = identify(log)
    # the per-joint model cannot describe the base joint's coupling: worse than zero there
    where = str(real_logs / "kuka_lwr4" / "measurements_1.npz")
    assert any(str(w.message).startswith(f"{where}: joint a1: predicted worse than zero "
                                         "torque on the held-back part") for w in record)
    assert m.kind == "decoupled" and m.n_joints == 7
    hold = m.fit["joints"]["holdout"]
    # the gravity-loaded joints are fitted to a fraction of their torque even by a
    # per-joint model; the full table is in the report, measured, not asserted
    assert hold["a2"]["rms_rel_torque_rms"] < 0.2
    assert hold["a4"]["rms_rel_torque_rms"] < 0.3


# ---------------------------------------------------------------- fit sanity
NUM = r"-?[0-9.]+(?:e[-+]?[0-9]+)?"


def _sanity_log(n: int = 4000, flip: int | None = None, noise_joint: int | None = None,
                still_from: float | None = None, seed: int = 2,
                friction_flip: int | None = None) -> RobotLog:
    """A 2-joint arm whose joints each follow tau = I q'' + fv q' + fc sign(q') + offset;
    ``friction_flip``: that joint's friction torque has the wrong sign (it drives the joint)."""
    t = np.arange(n) * 0.004
    q, qd, qdd = multisine(t, 2, seed=seed)
    if still_from is not None:  # the arm stops (smoothly) and stays still
        k = int(still_from * n)
        ramp = np.clip((np.arange(n) - k + 50) / 50.0, 0.0, 1.0)
        q = q[k] + (q - q[k]) * (1.0 - ramp[:, None]) ** 3
        q[k:] = q[k]
    dt = 0.004
    qd, qdd = np.gradient(q, dt, axis=0), np.gradient(np.gradient(q, dt, axis=0), dt, axis=0)
    rng = np.random.default_rng(seed)
    fsign = np.ones(2)
    if friction_flip is not None:
        fsign[friction_flip] = -1.0
    tau = (np.array([0.8, 0.3]) * qdd + fsign * (np.array([0.5, 0.2]) * qd
                                                  + np.array([0.6, 0.3]) * np.tanh(qd / 0.01))
           + np.array([0.2, -0.1]) + rng.normal(0, 0.01, (n, 2)))
    if flip is not None:
        tau[:, flip] = -tau[:, flip]
    if noise_joint is not None:  # a model fitted to noise predicts it worse than zero
        # (here by 2.7 %: the expected excess is small, this seed shows it)
        tau[:, noise_joint] = np.random.default_rng(0).normal(0, 1.0, n)
    return RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=JOINTS, position=q,
                    torque=tau, source=LogSource("sane.csv", "", "memory"))


def _messages(record: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in record]


@pytest.mark.parametrize("kind", ["decoupled", "coupled"])
def test_a_joint_whose_torque_sign_is_flipped_gets_a_negative_inertia_warning(kind: str) -> None:
    with pytest.warns(ImpactWarning) as record:
        m = identify(_sanity_log(flip=1), kind=kind)
    msgs = [s for s in _messages(record) if "negative" in s]
    assert len(msgs) == 1, msgs
    assert re.fullmatch(
        rf"sane\.csv: joint elbow: negative inertia and friction \(elbow\.inertia = {NUM} "
        rf"kg·m²; elbow\.fv = {NUM} N·m·s/rad, elbow\.fc = {NUM} N·m drive the joint instead "
        r"of braking it\): a torque \(or current\) of the wrong sign, or a model that does "
        r"not describe this joint", msgs[0]), msgs[0]
    assert m.fit["sanity"] == [s for s in _messages(record) if s in m.fit["sanity"]]
    assert msgs[0] in m.fit["sanity"]


NEGATIVE_FRICTION = (
    rf"joint elbow: negative friction \(elbow\.fv = ({NUM}) N·m·s/rad, elbow\.fc = ({NUM}) N·m "
    r"drive the joint instead of braking it\): a torque \(or current\) of the wrong sign, or "
    r"a model that does not describe this joint")


@pytest.mark.parametrize("kind", ["decoupled", "coupled"])
def test_friction_of_the_wrong_sign_alone_gets_a_negative_friction_warning(kind: str) -> None:
    """Inertia right, friction reversed (the torque pushes the joint along its motion):
    the warning names friction alone, with both parameters negative."""
    with pytest.warns(ImpactWarning) as record:
        m = identify(_sanity_log(friction_flip=1), kind=kind)
    msgs = [s for s in _messages(record) if "negative" in s]
    assert len(msgs) == 1, msgs
    found = re.fullmatch(rf"sane\.csv: {NEGATIVE_FRICTION}", msgs[0])
    assert found, msgs[0]
    fv, fc = float(found.group(1)), float(found.group(2))
    assert fv == pytest.approx(-0.2, abs=0.02) and fc == pytest.approx(-0.3, abs=0.03)
    assert m.fit["sanity"] == msgs
    assert "inertia" not in msgs[0]


def test_negative_friction_warning_through_the_cli(tmp_path: Path) -> None:
    """``impactcli identify``: the warning is one stderr line, the model still written
    (exit 0): a warning, not an error."""
    path = tmp_path / "reversed.csv"
    write_log(_sanity_log(friction_flip=1), path)
    code, out, err = cli(["identify", str(path), "-o", str(tmp_path / "m.json")])
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if "negative" in ln]
    assert len(lines) == 1, err
    assert re.fullmatch(rf"impactcli: warning: {re.escape(str(path))}: {NEGATIVE_FRICTION}",
                        lines[0]), lines[0]
    assert (tmp_path / "m.json").is_file() and f"wrote {tmp_path / 'm.json'}" in out


def test_the_same_log_unflipped_raises_no_sanity_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = identify(_sanity_log())
    assert m.fit["sanity"] == []


def test_planar_negative_zzr_is_named() -> None:
    log = arm_log()
    log = dataclasses.replace(log, torque=log.torque * np.array([1.0, -1.0]))
    with pytest.warns(ImpactWarning) as record:
        identify(log, robot=robot(kin=ROBOT["kinematics"]))  # type: ignore[arg-type]
    msgs = [s for s in _messages(record) if "negative" in s]
    assert msgs and all(s.startswith("arm.csv: joint elbow: negative inertia") for s in msgs)
    assert re.search(rf"elbow\.ZZR = {NUM} kg·m²", msgs[0]), msgs[0]


def test_a_joint_whose_torque_is_noise_is_worse_than_zero() -> None:
    with pytest.warns(ImpactWarning) as record:
        m = identify(_sanity_log(noise_joint=1))
    h = m.fit["joints"]["holdout"]["elbow"]
    expected = (f"sane.csv: joint elbow: predicted worse than zero torque on the held-back part "
                f"(RMS error {h['rms_nm']:.3g} N·m >= the torque's own RMS "
                f"{h['torque_rms_nm']:.3g} N·m): do not rely on its model")
    assert expected in _messages(record)
    assert not any("joint shoulder" in s for s in _messages(record))
    assert "held back worse than zero torque: elbow" in format_fit_table(m)


def test_a_held_back_part_at_standstill_gets_no_relative_error(tmp_path: Path) -> None:
    with pytest.warns(ImpactWarning) as record:
        m = identify(_sanity_log(still_from=0.75))
    assert _messages(record) == [
        "sane.csv: the arm stands still in the held-back part (every joint, in at least 100 % "
        "of it; |q'| < 0.01 rad/s, where friction is stiction: any torque within it): relative "
        "errors there are not meaningful and are not given"]
    hold = m.fit["joints"]["holdout"]
    for j in JOINTS:
        assert hold[j]["still"] is True and hold[j]["rms_rel_torque_rms"] is None
        assert hold[j]["rms_nm"] >= 0
    table = format_fit_table(m)
    assert "still in the held-back part (no relative error there): shoulder, elbow" in table
    assert "%" not in next(ln for ln in table.splitlines() if ln.startswith("elbow")).split(
        "  ")[-1]


def test_one_joint_still_in_the_held_back_part_is_named() -> None:
    log = _sanity_log()
    k = int(0.75 * log.n_samples)
    q = np.array(log.position)
    q[k - 100:, 1] = q[k - 100, 1]  # elbow stops before the held-back part; shoulder moves on
    with pytest.warns(ImpactWarning) as record:
        m = identify(dataclasses.replace(log, position=q))
    msgs = [s for s in _messages(record) if "stands still" in s]
    assert len(msgs) == 1 and re.fullmatch(
        r"sane\.csv: joint elbow stands still in [0-9]+ % of the held-back part \(\|q'\| < "
        r"0\.01 rad/s, where friction is stiction: any torque within it\): its held-back "
        r"relative error is not meaningful and is not given", msgs[0]), msgs
    assert m.fit["joints"]["holdout"]["elbow"]["still"] is True
    assert "still" not in m.fit["joints"]["holdout"]["shoulder"]


def test_calibrate_prints_the_fit_table_identify_prints(files: dict[str, Path],
                                                        tmp_path: Path) -> None:
    out = tmp_path / "m.json"
    code, ident, stderr = cli(["identify", str(files["log"]), "--robot", str(files["robot"]),
                               "-o", str(out)])
    assert code == 0, stderr
    table = ident.split("\nmodel kind: ")[0]  # the selection's lines follow the table
    assert "model kind: planar: the robot's kinematics (--robot), used as named" in ident
    code, cal, stderr = cli(["calibrate", str(files["log"]), "--model", str(out),
                             "--generator", "inverse_dynamics", "-o", str(tmp_path / "c.toml")])
    assert code == 0, (cal, stderr)
    assert table in cal
    assert format_fit_table(read_model(out)) == table
