"""Named robots (the ``robots`` extra, PyPI ``example-robot-data``): ``impactcli robots``,
``--robot NAME`` end to end on every listed robot, a robot file naming a shipped robot with
a ``joint_map``, and what happens to joints the URDF and the log do not share.

Each robot's log is synthetic (tests/robot_logs.py): smooth sinusoids within the joint
limits, the torque from Pinocchio's RNEA on the URDF's own inertials plus noise.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import pytest

from impactcli.errors import RobotDescriptionError
from impactcli.logs import robot_catalogue as robots
from impactcli.logs import write_log
from impactcli.logs.robot_files import read_robot, robot_from_dict
from impactcli.run.model_files import read_model
from impactcli.schema import validate

from .cli_run import cli
from .robot_logs import synthetic_log

pin = pytest.importorskip("pinocchio", reason="the urdf extra (pinocchio) is not installed")
pytestmark = pytest.mark.urdf

needs_extra = pytest.mark.skipif(
    robots.data_dir() is None,
    reason="the robots extra is not installed (pip install 'impactcli[robots]': "
           "example-robot-data)")

#: Every name the tool knows; the listed ones are checked against the URDFs themselves.
ALL = [r.name for r in robots.CATALOGUE]


def listed() -> dict[str, dict[str, Any]]:
    code, out, err = cli(["robots", "--json"])
    assert code == 0, err
    return {r["name"]: r for r in json.loads(out)["robots"]}


def holdout_errors(model_path: Path) -> dict[str, float]:
    fit = read_model(model_path).fit["joints"]["holdout"]
    assert fit is not None, "the log is long enough for a held-back part"
    return {j: s["rms_rel_range"] for j, s in fit.items()}


# ---------------------------------------------------------------- the list
@needs_extra
def test_robots_lists_only_loading_urdfs_with_pinocchios_joint_names() -> None:
    robots_listed = listed()
    assert set(robots_listed) == set(ALL), "every robot of the catalogue loads in 6.0.0"
    base = robots.data_dir()
    assert base is not None
    for name, r in robots_listed.items():
        if r["urdf"] is None:  # built from a published table (tests/test_published_arms.py)
            model = pin.buildModelFromXML(robots.urdf_text(name))
        else:
            model = pin.buildModelFromUrdf(str(base / r["urdf"]))  # meshes are never needed
        names = list(model.names)[1:]
        assert set(r["joints"]) <= set(names), name
        # chain order: each joint is a descendant of the one before it
        ids = [model.getJointId(j) for j in r["joints"]]
        for a, b in itertools.pairwise(ids):
            assert model.parents[b] == a, (name, r["joints"])
        assert all(model.joints[i].nv == 1 for i in ids)
    assert robots_listed["panda"]["joints"] == [f"panda_joint{k}" for k in range(1, 8)]
    assert robots_listed["tiago"]["joints"] == [f"arm_{k}_joint" for k in range(1, 8)]
    code, out, _ = cli(["robots"])
    assert code == 0
    assert "panda_description/urdf/panda.urdf" in out and "panda_joint7" in out


def test_without_pinocchio_each_robot_says_what_to_install(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """No Pinocchio (its import fails): ``robots`` and a package robot name the robots
    extra; a built arm, which needs only Pinocchio, names the urdf extra."""
    import sys

    monkeypatch.setitem(sys.modules, "pinocchio", None)  # import pinocchio: ImportError
    robots.arm_joints.cache_clear()
    try:
        code, out, err = cli(["robots"])
        assert code == 2 and out == ""
        assert err.count("\n") == 1 and "pip install 'impactcli[robots]'" in err, err
        log = tmp_path / "a.csv"
        log.write_text("time,a.position,a.torque\n0,0,0\n0.01,0,0\n")
        for name, extra in (("ur10e", "urdf"), ("ur10", "robots")):
            code, _, err = cli(["identify", str(log), "--robot", name,
                                "-o", str(tmp_path / "m.json")])
            assert code == 2, err
            assert err.count("\n") == 1 and f"pip install 'impactcli[{extra}]'" in err, err
    finally:
        robots.arm_joints.cache_clear()


# ---------------------------------------------------------------- every robot, end to end
@needs_extra
@pytest.mark.parametrize("name", ALL)
def test_robot_by_name_identifies_and_detects(name: str, tmp_path: Path) -> None:
    if name not in listed():
        pytest.skip(f"{name}: its URDF does not load here")
    log = tmp_path / f"{name}.csv"
    write_log(synthetic_log(name), log)
    code, _, err = cli(["identify", str(log), "--robot", name, "-o", str(tmp_path / "m.json")])
    assert code == 0, err
    model = read_model(tmp_path / "m.json")
    assert model.kind == "urdf"
    assert model.joint_names == robots.arm_joints(name)
    assert model.robot is not None and model.robot["kinematics"] == {"type": "urdf",
                                                                       "robot": name}
    assert model.structure["urdf_robot"] == name
    assert str(robots.data_dir()) not in json.dumps(model.to_dict()), "no path of this machine"
    errs = holdout_errors(tmp_path / "m.json")
    assert max(errs.values()) < 0.03, errs
    code, _, err = cli(["detect", str(log), "--robot", name, "-o", str(tmp_path / "out")])
    assert code == 0, err
    tl = json.loads((tmp_path / "out" / f"{name}.timeline.json").read_text())
    assert tl["model"]["model"]["kind"] == "urdf"


# ---------------------------------------------------------------- joints that do not match
@needs_extra
def test_logged_joint_not_in_the_urdf_is_left_out(tmp_path: Path) -> None:
    log = tmp_path / "panda.csv"
    write_log(synthetic_log("panda", extra="gripper_width"), log)
    code, _, err = cli(["detect", str(log), "--robot", "panda", "-o", str(tmp_path / "out")])
    assert code == 0, err
    tl = json.loads((tmp_path / "out" / "panda.timeline.json").read_text())
    left = tl["input"]["joints_left_out"]
    assert left == [{"name": "gripper_width", "reason": "not in the model"}]
    assert "gripper_width" not in tl["model"]["model"]["joint_names"]
    lines = [ln for ln in err.splitlines() if "gripper_width" in ln]
    assert len(lines) == 1 and "left out of detection" in lines[0], err


@needs_extra
def test_urdf_joint_not_in_the_log_is_held_at_zero(tmp_path: Path) -> None:
    log = tmp_path / "panda.csv"
    write_log(synthetic_log("panda", drop="panda_joint7"), log)
    code, _, err = cli(["identify", str(log), "--robot", "panda", "-o", str(tmp_path / "m.json")])
    assert code == 0, err
    held = [ln for ln in err.splitlines() if "held at zero" in ln]
    assert len(held) == 1 and "panda_joint7" in held[0], err
    model = read_model(tmp_path / "m.json")
    assert model.joint_names == tuple(f"panda_joint{k}" for k in range(1, 7))
    code, _, err = cli(["detect", str(log), "--robot", "panda", "-o", str(tmp_path / "out")])
    assert code == 0, err
    assert sum("held at zero" in ln for ln in err.splitlines()) == 1, err


@needs_extra
def test_robot_file_naming_a_shipped_robot_with_a_joint_map(tmp_path: Path) -> None:
    rename = {f"panda_joint{k}": f"j{k}" for k in range(1, 8)}
    log = tmp_path / "renamed.csv"
    write_log(synthetic_log("panda", rename=rename), log)
    desc = {"name": "my panda", "kinematics": {"type": "urdf", "robot": "panda"},
            "joint_map": {v: k for k, v in rename.items()},
            "joints": [{"name": f"j{k}", "gear_ratio": 100, "torque_constant": 0.1}
                       for k in range(1, 8)]}
    robot = tmp_path / "robot.json"
    robot.write_text(json.dumps(desc))
    validate(desc, "robot", RobotDescriptionError, str(robot))
    code, _, err = cli(["identify", str(log), "--robot", str(robot), "-o",
                        str(tmp_path / "m.json")])
    assert code == 0, err
    assert "held at zero" not in err and "left out" not in err, err
    model = read_model(tmp_path / "m.json")
    assert model.joint_names == tuple(f"j{k}" for k in range(1, 8))
    assert all(p.split(".")[0] in model.joint_names for p in model.param_names)
    assert model.structure["urdf_joint_map"] == desc["joint_map"]
    assert max(holdout_errors(tmp_path / "m.json").values()) < 0.03
    code, _, err = cli(["detect", str(log), "--robot", str(robot), "-o", str(tmp_path / "out")])
    assert code == 0, err


@needs_extra
def test_a_path_that_exists_wins_over_a_name(tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert read_robot("panda").kinematics == {"type": "urdf", "robot": "panda"}
    Path("panda").write_text(json.dumps({"name": "mine", "joints": [{"name": "a"}]}))
    assert read_robot("panda").name == "mine"


def test_unknown_name_is_one_line_listing_the_shipped_robots(tmp_path: Path) -> None:
    log = tmp_path / "panda.csv"
    log.write_text("time,a.position,a.torque\n0,0,0\n0.01,0,0\n")
    for verb in (["identify", str(log), "-o", str(tmp_path / "m.json")],
                 ["detect", str(log), "-o", str(tmp_path / "out")]):
        code, _, err = cli([*verb, "--robot", "pandaa"])
        assert code == 3, err
        assert err.count("\n") == 1, err
        assert "pandaa" in err and "not found" in err
        assert all(n in err for n in ("panda", "ur5", "tiago")), err


@needs_extra
def test_a_config_from_a_named_robot_resolves_the_name_again(tmp_path: Path) -> None:
    log = tmp_path / "ur5.csv"
    write_log(synthetic_log("ur5"), log)
    cfg = tmp_path / "ur5.config.json"
    code, _, err = cli(["calibrate", str(log), "--robot", "ur5", "-o", str(cfg)])
    assert code == 0, err
    model = json.loads(cfg.read_text())["model"]
    assert model["robot"]["kinematics"] == {"type": "urdf", "robot": "ur5"}
    assert str(robots.data_dir()) not in cfg.read_text(), "no path of this machine"
    for extra in ([], ["--model-from-log"]):  # the latter resolves "ur5" again
        code, _, err = cli(["detect", str(log), "--config", str(cfg), *extra,
                            "-o", str(tmp_path / f"out{len(extra)}")])
        assert code == 0, err


@pytest.mark.parametrize(
    ("d", "message"),
    [
        ({"joints": [{"name": "a"}], "kinematics": {"type": "urdf", "robot": "r2d2"}},
         "'r2d2' is not a shipped robot"),
        ({"joints": [{"name": "a"}],
          "kinematics": {"type": "urdf", "robot": "panda", "path": "p.urdf"}}, "not both"),
        ({"joints": [{"name": "a"}], "joint_map": {"a": "b"}}, "joint_map needs urdf"),
        ({"joints": [{"name": "a"}], "kinematics": {"type": "urdf", "path": "p.urdf"},
          "joint_map": {"x": "b"}}, r"log joint\(s\) \['x'\]"),
        ({"joints": [{"name": "a"}, {"name": "b"}], "kinematics": {"type": "urdf",
          "path": "p.urdf"}, "joint_map": {"a": "c", "b": "c"}}, "several log joints"),
        ({"joints": [{"name": "a"}], "kinematics": {"type": "urdf", "path": "p.urdf"},
          "joint_map": ["a"]}, "joint_map must map"),
    ],
)
def test_robot_file_errors(d: dict[str, Any], message: str) -> None:
    with pytest.raises(RobotDescriptionError, match=message) as info:
        robot_from_dict(d, "r.json")
    assert "\n" not in str(info.value)


@needs_extra
def test_a_robot_file_may_leave_the_joints_to_the_named_robot() -> None:
    r = robot_from_dict({"kinematics": {"type": "urdf", "robot": "UR5"},
                         "joint_map": {"base": "shoulder_pan_joint"}}, "r.json")
    assert r.kinematics == {"type": "urdf", "robot": "ur5"}
    assert r.joint_names == ("base", *robots.arm_joints("ur5")[1:])
    assert all(j.gear_ratio == 1.0 and j.torque_constant is None for j in r.joints)


def test_a_name_without_the_extra_says_how_to_install(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(robots, "data_dir", lambda: None)
    robots.arm_joints.cache_clear()
    log = tmp_path / "panda.csv"
    log.write_text("time,a.position,a.torque\n0,0,0\n0.01,0,0\n")
    for verb in (["identify", str(log), "-o", str(tmp_path / "m.json")],
                 ["detect", str(log), "-o", str(tmp_path / "out")]):
        code, _, err = cli([*verb, "--robot", "panda"])
        assert code == 2, err
        assert err.count("\n") == 1 and "pip install 'impactcli[robots]'" in err, err
    robots.arm_joints.cache_clear()


def test_detect_names_a_threshold_above_its_joints_effort_limit(tmp_path: Path) -> None:
    """A config whose loading threshold on the UR10e's shoulder_lift (effort limit 330 N·m)
    is 500 N·m checks that joint in name only: detect says so, naming joint, detector and
    both figures, on stderr and in the timeline; the config as calibrated says nothing."""
    log = tmp_path / "ur10e.csv"
    write_log(synthetic_log("ur10e"), log)
    cfg = tmp_path / "ur10e.config.json"
    code, _, err = cli(["calibrate", str(log), "--robot", "ur10e", "-o", str(cfg)])
    assert code == 0, err
    assert "effort limit" not in err
    d = json.loads(cfg.read_text())
    d["thresholds"]["vL"]["shoulder_lift_joint"] = 500.0
    high = tmp_path / "high.config.json"
    high.write_text(json.dumps(d))
    said = ("the config's thresholds above their joint's effort limit (the URDF's, N·m): "
            "shoulder_lift_joint static_loading 500 > 330: a contact would have to load")
    for c, out, warned in ((cfg, "a", False), (high, "b", True)):
        code, _, err = cli(["detect", str(log), "--config", str(c), "-o", str(tmp_path / out)])
        assert code == 0, err
        assert (said in err) is warned, err
        tl = json.loads((tmp_path / out / "ur10e.timeline.json").read_text())
        assert any(said in w for w in tl["warnings"]) is warned
