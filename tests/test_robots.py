"""Named robots (the ``robots`` extra, PyPI ``example-robot-data``): ``impactcli robots``,
``--robot NAME`` end to end on every listed robot, a robot file naming a shipped robot with
a ``joint_map``, and what happens to joints the URDF and the log do not share.

Each robot's log is synthetic: smooth sinusoids within the joint limits, the torque from
Pinocchio's RNEA on the URDF's own inertials (every other URDF joint at zero) plus noise,
with the reference logged.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from impactcli.errors import RobotDescriptionError
from impactcli.logs import robot_catalogue as robots
from impactcli.logs import write_log
from impactcli.logs.robot_files import read_robot, robot_from_dict
from impactcli.run.model_files import read_model
from impactcli.schema import validate
from impactcli.types import LogSource, RobotLog

from .cli_run import cli

pin = pytest.importorskip("pinocchio", reason="the urdf extra (pinocchio) is not installed")
pytestmark = pytest.mark.urdf

needs_extra = pytest.mark.skipif(
    robots.data_dir() is None,
    reason="the robots extra is not installed (pip install 'impactcli[robots]': "
           "example-robot-data)")

#: Every name the tool knows; the listed ones are checked against the URDFs themselves.
ALL = [r.name for r in robots.CATALOGUE]
FS = 200.0
DURATION_S = 12.0  # >= 10 s: identification holds back its last 20 % (at least 2 s)


def full_model(name: str) -> Any:
    return pin.buildModelFromXML(robots.urdf_text(name))


def synthetic_log(name: str, joints: tuple[str, ...] | None = None, *,
                  rename: dict[str, str] | None = None, extra: str | None = None,
                  drop: str | None = None, seed: int = 0) -> RobotLog:
    """A log of shipped robot ``name``'s arm joints (or ``joints``, URDF names): q(t) smooth
    sinusoids within the joint limits, tau = RNEA of the URDF (other joints at zero) plus
    noise, references logged. ``rename`` {URDF: log name}; ``extra``: one more logged joint
    the URDF lacks; ``drop``: a URDF joint left out of the log."""
    model = full_model(name)
    data = model.createData()
    arm = tuple(joints or robots.arm_joints(name))
    rng = np.random.default_rng(seed)
    t = np.arange(int(DURATION_S * FS)) / FS
    n, nj = t.size, len(arm)
    q = np.zeros((n, nj))
    qd = np.zeros((n, nj))
    qdd = np.zeros((n, nj))
    for c, jn in enumerate(arm):
        jm = model.joints[model.getJointId(jn)]
        if jm.nq == 1:
            lo = float(model.lowerPositionLimit[jm.idx_q])
            hi = float(model.upperPositionLimit[jm.idx_q])
        else:  # continuous: the limits are on (cos, sin)
            lo, hi = -np.pi, np.pi
        mid, amp = 0.5 * (lo + hi), min(0.3 * (hi - lo), 1.0)
        for k, f in enumerate((0.13 + 0.041 * c, 0.37 + 0.053 * c, 0.71 + 0.029 * c)):
            a = amp / (1.6 * (k + 1))
            w, ph = 2 * np.pi * f, rng.uniform(0, 2 * np.pi)
            q[:, c] += a * np.sin(w * t + ph)
            qd[:, c] += a * w * np.cos(w * t + ph)
            qdd[:, c] -= a * w * w * np.sin(w * t + ph)
        q[:, c] += mid
    tau = np.zeros((n, nj))
    q0 = pin.neutral(model)
    jms = [model.joints[model.getJointId(j)] for j in arm]
    for k in range(n):
        qf, vf, af = q0.copy(), np.zeros(model.nv), np.zeros(model.nv)
        for c, jm in enumerate(jms):
            if jm.nq == 1:
                qf[jm.idx_q] = q[k, c]
            else:
                qf[jm.idx_q], qf[jm.idx_q + 1] = np.cos(q[k, c]), np.sin(q[k, c])
            vf[jm.idx_v], af[jm.idx_v] = qd[k, c], qdd[k, c]
        tau[k] = pin.rnea(model, data, qf, vf, af)[[jm.idx_v for jm in jms]]
    tau += rng.normal(0.0, 1.0, tau.shape) * (0.003 * np.ptp(tau, axis=0) + 1e-5)
    names = [(rename or {}).get(j, j) for j in arm]
    cols = list(range(nj))
    if drop is not None:
        cols.remove(arm.index(drop))
    names = [names[c] for c in cols]
    pos, trq, ref_q, ref_v, ref_a = (x[:, cols] for x in (q, tau, q, qd, qdd))
    pos = pos + rng.normal(0.0, 1e-5, pos.shape)
    if extra is not None:  # a logged joint the URDF lacks (e.g. a gripper channel)
        e = 0.02 * np.sin(2 * np.pi * 0.3 * t)[:, None]
        names.append(extra)
        pos, ref_q = np.hstack([pos, e]), np.hstack([ref_q, e])
        ref_v = np.hstack([ref_v, np.gradient(e[:, 0], t)[:, None]])
        ref_a = np.hstack([ref_a, np.gradient(ref_v[:, -1], t)[:, None]])
        trq = np.hstack([trq, 0.05 * np.sin(2 * np.pi * 0.3 * t)[:, None]
                         + rng.normal(0, 1e-3, (n, 1))])
    return RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=tuple(names),
                    position=pos, torque=trq, position_ref=ref_q, velocity_ref=ref_v,
                    acceleration_ref=ref_a, source=LogSource(f"{name}.csv", "", "memory"))


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


def test_robots_without_the_extra_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(robots, "data_dir", lambda: None)
    code, out, err = cli(["robots"])
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and "pip install 'impactcli[robots]'" in err


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
