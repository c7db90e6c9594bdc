"""Position units that cannot be right, through the command line: a log
whose positions are degrees is refused by name unless ``--position-unit`` says the unit
(degrees are then read as radians, with the references and velocities), a merely
suspicious joint is warned of, ``inspect`` shows the verdict, and positions far outside a
URDF's joint limits are warned of by joint."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from impactcli.errors import ImpactError, ImpactWarning
from impactcli.logs import read_log, write_log
from impactcli.schema import validate
from impactcli.types import LogSource, RobotLog

from .cli_run import cli

JOINTS = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
RATE = 250.0
DEG = 180.0 / math.pi


def _arm(seconds: float = 24.0, seed: int = 0) -> RobotLog:
    """A 6-joint arm [rad] in slow multi-sine motion (up to ±1.5 rad, about 1 rad/s), its
    velocity and reference, and a torque its gravity and friction explain."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * RATE)) / RATE
    q = np.zeros((t.size, 6))
    qd = np.zeros((t.size, 6))
    for j in range(6):
        for k in range(1, 4):
            a, w, ph = rng.uniform(0.1, 0.5), 2 * math.pi * 0.1 * k, rng.uniform(0, 6)
            q[:, j] += a * np.sin(w * t + ph)
            qd[:, j] += a * w * np.cos(w * t + ph)
    tau = 8 * np.sin(q) + 0.5 * np.tanh(20 * qd) + 0.05 * rng.standard_normal(q.shape)
    return RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=JOINTS,
                    position=q + 1e-4 * rng.standard_normal(q.shape), torque=tau, velocity=qd,
                    position_ref=q, velocity_ref=qd,
                    source=LogSource("<arm>", "0" * 64, "memory"))


def _scaled(log: RobotLog, joints: list[int], factor: float) -> RobotLog:
    """``log`` with the angular arrays of ``joints`` multiplied by ``factor``."""
    out = {}
    for s in ("position", "velocity", "position_ref", "velocity_ref"):
        a = np.array(getattr(log, s))
        a[:, joints] *= factor
        out[s] = a
    return RobotLog(t_ns=log.t_ns, joint_names=log.joint_names, torque=log.torque,
                    source=log.source, **out)


def _errors(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ln.startswith("impactcli: error:")]


def _warnings(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ln.startswith("impactcli: warning:")]


@pytest.fixture(scope="module")
def arm() -> RobotLog:
    return _arm()


@pytest.fixture(scope="module")
def degrees(arm: RobotLog, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("deg") / "arm_deg.csv"
    write_log(_scaled(arm, list(range(6)), DEG), path)
    return path


def test_a_log_in_degrees_is_refused_naming_the_option(degrees: Path, tmp_path: Path) -> None:
    for verb in (["detect", "-o", tmp_path / "o"], ["identify", "-o", tmp_path / "m.json"],
                 ["calibrate", "-o", tmp_path / "c.toml"]):
        code, _, err = cli(verb[0], degrees, *verb[1:])
        assert code == 3, (verb, err)
        (line,) = _errors(err)
        assert line.startswith(f"impactcli: error: {degrees}: positions look like degrees: "
                               "joint(s) shoulder_pan, shoulder_lift, elbow, wrist_1, "
                               "wrist_2, wrist_3 travel "), line
        assert line.endswith("Give --position-unit deg (or --position-unit rad if they are "
                             "radians)")
    assert not (tmp_path / "o").exists() or not list((tmp_path / "o").iterdir())


def test_position_unit_deg_reads_degrees_as_radians(arm: RobotLog, degrees: Path,
                                                    tmp_path: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        log = read_log(degrees, position_unit="deg")
        as_read = read_log(degrees, position_unit="rad")
    for s in ("position", "velocity", "position_ref", "velocity_ref"):
        np.testing.assert_allclose(getattr(log, s), getattr(arm, s), rtol=1e-6, atol=1e-6,
                                   err_msg=s)
        np.testing.assert_array_equal(getattr(log, s), getattr(as_read, s) * (math.pi / 180))
    np.testing.assert_array_equal(log.torque, as_read.torque)
    code, _, err = cli("detect", degrees, "--position-unit", "deg", "-o", tmp_path / "o")
    assert code == 0, err
    tl = json.loads((tmp_path / "o" / "arm_deg.timeline.json").read_text())
    assert tl["input"]["read_options"] == {"position_unit": "deg"}
    assert not any("degrees" in w for w in _warnings(err))


def test_position_unit_rad_overrides_the_refusal_with_a_warning(degrees: Path) -> None:
    code, _, err = cli("inspect", degrees, "--position-unit", "rad")
    assert code == 0, err
    assert any("positions look like degrees" in w for w in _warnings(err))


def test_inspect_shows_the_verdict_and_the_ranges(degrees: Path, arm: RobotLog,
                                                  tmp_path: Path) -> None:
    code, out, err = cli("inspect", degrees, "--json")
    assert code == 0, err
    d = json.loads(out)
    validate(d, "inspect", ImpactError, "inspect --json")
    assert d["position_unit"]["verdict"] == "refuse"
    assert d["position_unit"]["joints"] == list(JOINTS)
    assert d["position_unit"]["message"] in d["warnings"]
    lo, hi = d["ranges"]["position"]["elbow"]
    assert lo == pytest.approx(float(np.min(arm.position[:, 2])) * DEG, rel=1e-5)
    assert hi == pytest.approx(float(np.max(arm.position[:, 2])) * DEG, rel=1e-5)
    code, out, _ = cli("inspect", degrees)
    assert code == 0
    assert any(ln.startswith("position unit    cannot be radians: ")
               for ln in out.splitlines())
    rad = tmp_path / "arm.csv"
    write_log(arm, rad)
    code, out, err = cli("inspect", rad, "--json")
    assert code == 0, err
    d = json.loads(out)
    validate(d, "inspect", ImpactError, "inspect --json")
    assert d["position_unit"] == {"verdict": "ok", "message": "", "joints": []}
    assert d["warnings"] == [] and _warnings(err) == []


def test_one_joint_beyond_an_arm_is_warned_of_not_refused(arm: RobotLog,
                                                          tmp_path: Path) -> None:
    path = tmp_path / "wrist.csv"
    write_log(_scaled(arm, [5], 40.0), path)  # one joint's scale is off (a gear ratio?)
    code, out, err = cli("inspect", path, "--json")
    assert code == 0, err
    (w,) = _warnings(err)
    assert w.startswith(f"impactcli: warning: {path}: joint(s) wrist_3 travels ")
    assert "check the position unit (--position-unit deg|rad) and the gear ratio" in w
    assert json.loads(out)["position_unit"]["verdict"] == "warn"


def test_an_mcap_in_degrees_is_refused_as_well(arm: RobotLog, tmp_path: Path) -> None:
    path = tmp_path / "arm_deg.mcap"
    write_log(_scaled(arm, list(range(6)), DEG), path, mcap_encoding="ros2")
    code, _, err = cli("detect", path, "-o", tmp_path / "o")
    assert code == 3
    assert _errors(err)[0].startswith(f"impactcli: error: {path}: positions look like degrees")
    code, _, err = cli("inspect", path, "--position-unit", "deg")
    assert code == 0, err


URDF = """<robot name="two">
  <link name="base"/><link name="l1"/><link name="l2"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <limit lower="-1.0" upper="1.0" velocity="3.0" effort="10"/></joint>
  <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>
    <limit velocity="6.0" effort="10"/></joint>
</robot>
"""


def test_positions_far_outside_a_urdfs_limits_are_warned_of_by_joint(tmp_path: Path) -> None:
    n = 2500
    t = np.arange(n) / RATE
    q = np.column_stack([2.5 + 0.3 * np.sin(t), 4.0 + 0.3 * np.sin(t)])  # j1 outside ±1
    log = RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=("a", "b"),
                   position=q, torque=np.column_stack([np.cos(t), np.sin(t)]),
                   source=LogSource("<x>", "0" * 64, "memory"))
    path = tmp_path / "two.csv"
    write_log(log, path)
    (tmp_path / "two.urdf").write_text(URDF)
    robot = tmp_path / "two.robot.json"
    robot.write_text(json.dumps({"name": "two", "joints": [{"name": "a"}, {"name": "b"}],
                                 "joint_map": {"a": "j1", "b": "j2"},
                                 "kinematics": {"type": "urdf", "path": "two.urdf"}}))
    code, out, err = cli("inspect", path, "--robot", robot, "--json")
    assert code == 0, err
    want = (f"{path}: joint a's positions 2.2…2.8 rad lie far outside its URDF limits -1…1 "
            "rad: check the position unit (--position-unit deg|rad), the joint's offset and "
            "sign, and the joint map")
    assert _warnings(err) == [f"impactcli: warning: {want}"]  # b is continuous: no limits
    assert json.loads(out)["warnings"] == [want]
    code, _, err = cli("inspect", path)  # without the robot: nothing to compare with
    assert code == 0 and _warnings(err) == []


SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def _detect_words(log: Path, tmp_path: Path) -> str:
    code, _, err = cli("detect", log, "--config", SAMPLES / "heavy_geared.config.toml",
                       "--position-unit", "deg", "-o", tmp_path / "out")
    assert code in (0, 1), err
    return err


def test_radians_given_as_degrees_are_held_against_the_calibration(tmp_path: Path) -> None:
    """The heavy arm's impacts log is in radians (j1 travels 0.190 rad; its config's
    calibration logs span 0.758 rad of j1): read as degrees, it travels 0.44 % of that —
    said, with the reading as radians; the same log written in degrees is not."""
    err = _detect_words(SAMPLES / "csv" / "heavy_impacts.csv.gz", tmp_path)
    said = [ln for ln in err.splitlines() if "reads its positions as degrees" in ln]
    assert len(said) == 1, err
    assert "at most 0.44 % of the calibration logs' range" in said[0]
    assert "j1 0.19 rad against 0.758" in said[0] and "j2" not in said[0]  # j2 barely moves

    import pyarrow.csv as pacsv

    table = pacsv.read_csv(SAMPLES / "csv" / "heavy_impacts.csv.gz").to_pandas()
    angular = [c for c in table.columns
               if c.rsplit(".", 1)[-1] in ("position", "velocity", "position_ref",
                                            "velocity_ref", "acceleration_ref")]
    table[angular] = table[angular] * DEG
    degrees = tmp_path / "heavy_impacts_deg.csv"
    table.to_csv(degrees, index=False)
    assert "reads its positions as degrees" not in _detect_words(degrees, tmp_path)
