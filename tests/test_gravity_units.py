"""Units and scales against physics (issue "The answer states its own limits", item 1): the
description's gravity torque against an independent Newton–Euler of the same arm, the
scale verdict over the whole value space of scales, and through the CLI a log whose torque
is off by a unit factor (refused, exit 3), off otherwise (warned, recorded), or with no
masses to check it against (said to be unverified)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import example, given, settings
from hypothesis import strategies as st

from impactcli.cli import main
from impactcli.detect.incident_builder import HOLD_FACTOR, torque_capacity
from impactcli.logs import read_log, write_log
from impactcli.logs.robot_files import read_robot, robot_from_dict
from impactcli.model.gravity import (
    CERTAIN_FACTOR,
    CLOSE_FACTOR,
    WARN_FACTOR,
    clean_factors,
    nominal_gravity,
    scale_check,
)
from impactcli.sim import kernel as kern

REPO = Path(__file__).resolve().parents[1]
CSV = REPO / "sample_logs" / "csv"


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_planar_gravity_is_the_newton_euler_gravity_of_the_arm(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 3
    lengths, masses = rng.uniform(0.2, 0.8, n), rng.uniform(0.5, 5.0, n)
    frac = rng.uniform(0.2, 0.8, n)
    grav = rng.normal(0.0, 9.81, 2)
    robot = robot_from_dict({
        "joints": [{"name": f"j{k}"} for k in range(n)],
        "kinematics": {"type": "planar", "link_lengths": lengths.tolist(),
                       "gravity": grav.tolist()},
        "nominal": {"link_masses": masses.tolist(), "com_fractions": frac.tolist()}})
    q = rng.uniform(-math.pi, math.pi, (20, n))
    names = ("j2", "j0", "j1")  # the log's column order need not be the chain's
    got = nominal_gravity(robot, names, q[:, [2, 0, 1]])
    assert got is not None
    want = np.empty((20, n))
    for k in range(20):
        kern.rnea(q[k], np.zeros(n), np.zeros(n), lengths, masses, frac * lengths,
                  np.zeros(n), float(grav[0]), float(grav[1]), want[k])
    np.testing.assert_allclose(got, want[:, [2, 0, 1]], rtol=1e-10, atol=1e-10)


def test_no_masses_no_gravity() -> None:
    robot = read_robot(CSV / "assist_free_p2p.robot.json")
    d = robot.to_dict()
    assert d.pop("nominal")["link_masses"]
    assert nominal_gravity(robot, robot.joint_names, np.zeros((3, 2))) is not None
    assert nominal_gravity(robot_from_dict(d), robot.joint_names, np.zeros((3, 2))) is None


@pytest.fixture(scope="module")
def poses() -> tuple[tuple[str, ...], np.ndarray, np.ndarray, np.ndarray, list[float]]:
    """A collision-free sample log's poses: joints, gravity, torque, speed, gear ratios."""
    log = read_log(CSV / "heavy_free_p2p.csv.gz")
    robot = read_robot(CSV / "heavy_free_p2p.robot.json")
    q, tau = log.position[::10], log.torque[::10]
    speed = np.abs(np.gradient(log.position, log.sample_period_s, axis=0)[::10])
    g = nominal_gravity(robot, log.joint_names, q)
    assert g is not None
    return log.joint_names, g, tau, speed, [j.gear_ratio for j in robot.joints]


def test_the_true_scale_is_about_one(poses: tuple) -> None:
    joints, g, tau, speed, ratios = poses
    v = scale_check("log", joints, g, tau, speed, ratios)
    assert v.kind == "ok" and v.scale == pytest.approx(1.0, abs=0.1)
    assert len(v.per_joint) >= 1


@settings(max_examples=80, deadline=None)
@given(log10_scale=st.floats(-4.0, 4.0))
def test_the_verdict_follows_the_scale(poses: tuple, log10_scale: float) -> None:
    """A torque scaled by s: refused near a clean unit factor (naming its cause), warned
    when off otherwise, accepted near 1 — said to agree when every joint's scale is within
    CLOSE_FACTOR, to be of one order only otherwise (s multiplies the log's own ~1 scale;
    within 10 % of a boundary either side is allowed)."""
    joints, g, tau, speed, ratios = poses
    s = 10.0 ** log10_scale
    v = scale_check("log", joints, g, tau * s, speed, ratios)
    base = scale_check("log", joints, g, tau, speed, ratios).scale
    k = s * base
    near = [f for f, _ in clean_factors(ratios)
            if 1.0 / CERTAIN_FACTOR <= k / f <= CERTAIN_FACTOR]
    edges = [f * c for f, _ in clean_factors(ratios) for c in (CERTAIN_FACTOR,
                                                               1 / CERTAIN_FACTOR)]
    edges += [WARN_FACTOR, 1 / WARN_FACTOR, CLOSE_FACTOR, 1 / CLOSE_FACTOR]
    if any(abs(math.log(k / e)) < 0.1 for e in edges):
        return  # on a boundary
    assert v.scale == pytest.approx(k, rel=1e-9)
    if near:
        assert v.kind == "refuse", v
    elif not 1 / WARN_FACTOR <= k <= WARN_FACTOR:
        assert v.kind == "warn", v
    else:
        assert v.kind == "ok", v
        # "agrees" only when every judged joint's scale is within CLOSE_FACTOR
        close = all(1 / CLOSE_FACTOR <= x <= CLOSE_FACTOR for x in v.per_joint.values())
        assert ("agrees with" in v.message) is close, v
        assert ("not an agreement" in v.message) is not close, v
        assert v.order_only is not close, v  # said on the terminal too (the plan warns)


def test_a_still_log_is_not_verified(poses: tuple) -> None:
    joints, g, tau, speed, ratios = poses
    v = scale_check("log", joints, g, tau, speed + 10.0, ratios)  # never slow
    assert v.kind == "unverified" and "not verified" in v.message


def test_capacity_from_the_masses_before_the_logs_own_torque() -> None:
    efforts = np.array([np.nan, 50.0, np.nan, np.nan])
    peak = np.array([7.0, 7.0, 7.0, np.nan])
    hold = np.array([10.0, 10.0, 0.001, np.nan])  # joint 3: gravity does not load it
    cap, source = torque_capacity(efforts, peak, hold)
    np.testing.assert_array_equal(cap, [HOLD_FACTOR * 10.0, 50.0, 7.0, np.nan])
    assert "URDF's effort limit" in source and "description's masses" in source
    assert "not verified against physics" in source


def _run(tmp_path: Path, log_name: str, scale: float, column: str, *extra: str
         ) -> tuple[int, str, dict]:
    log = read_log(CSV / f"{log_name}.csv.gz")
    log = log.slice(0, round(30 * log.sample_rate_hz))
    arrays = {column: getattr(log, column) * scale}
    import dataclasses

    src = tmp_path / "log.csv"
    write_log(dataclasses.replace(log, **arrays), src)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(src), "-o", str(out), *extra])
    tl = out / "log.timeline.json"
    return r.exit_code, r.stderr, (json.loads(tl.read_text(encoding="utf-8"))
                                   if tl.exists() else {})


def test_currents_in_ma_are_refused_naming_the_cause(tmp_path: Path) -> None:
    robot = CSV / "heavy_free_p2p.robot.json"
    code, err, doc = _run(tmp_path, "heavy_free_p2p", 1000.0, "current", "--robot",
                          str(robot), "--torque-source", "current")
    assert code == 3 and not doc
    line = err.strip().splitlines()[-1]
    assert line.startswith(f"impactcli: error: {tmp_path / 'log.csv'}: the torque is off by ~")
    assert "mA logged as A" in line and "Traceback" not in err


def test_a_motor_side_torque_is_refused_naming_the_gear_ratio(tmp_path: Path) -> None:
    robot = read_robot(CSV / "heavy_free_p2p.robot.json")
    n = robot.joints[0].gear_ratio
    assert all(j.gear_ratio == n for j in robot.joints)
    code, err, _ = _run(tmp_path, "heavy_free_p2p", 1.0 / n, "torque", "--robot",
                        str(CSV / "heavy_free_p2p.robot.json"))
    assert code == 3
    assert f"motor-side (÷ the gear ratio {n:g})" in err


def test_an_odd_scale_is_warned_and_recorded(tmp_path: Path) -> None:
    code, err, doc = _run(tmp_path, "heavy_free_p2p", 4.0, "torque", "--robot",
                          str(CSV / "heavy_free_p2p.robot.json"))
    assert code == 0, err
    ts = doc["input"]["torque_scale"]
    assert ts["verdict"] == "warn" and ts["scale"] == pytest.approx(4.0, rel=0.15)
    assert "the torque may be off by ~" in err


def test_a_scale_of_one_order_only_is_said_on_the_terminal(tmp_path: Path) -> None:
    """1.8× the log's torque: no unit error, not an agreement either — forces are as good
    as that ratio, and the run says so where the user reads (a new user's trial saw it in
    the timeline only, with the wrong UR model's ~2.2× forces printed as they were)."""
    code, err, doc = _run(tmp_path, "heavy_free_p2p", 1.8, "torque", "--robot",
                          str(CSV / "heavy_free_p2p.robot.json"))
    assert code == 0, err
    ts = doc["input"]["torque_scale"]
    assert ts["verdict"] == "ok" and ts["scale"] == pytest.approx(1.8, rel=0.15)
    assert "not an agreement" in err and "forces in N are as good as that ratio" in err


def test_the_report_says_forces_are_as_good_as_a_scale_of_one_order_only(
        tmp_path: Path) -> None:
    """The sample payload log under the sample config: its torque scale is ~1.5× the
    description's gravity torque (its unknown load), no unit error and no agreement. Its
    report caveats say the forces are as good as that (before, "ok" gave no caveat), and
    a log whose scale agrees gets none."""
    from impactcli.schema import validate

    cfg = REPO / "sample_logs" / "assist_like.config.toml"
    for name, order in (("assist_payload", True), ("assist_pushes", False)):
        out = tmp_path / f"{name}.json"
        r = CliRunner().invoke(main, ["report", str(CSV / f"{name}.csv.gz"), "--config",
                                      str(cfg), "-o", str(tmp_path / f"{name}.html"),
                                      "--json", str(out)])
        assert r.exit_code == 0, r.output
        doc = json.loads(out.read_text("utf-8"))
        validate(doc, "report", AssertionError, "report")
        said = [c["text"] for c in doc["logs"][0]["caveats"] if c["code"] == "torque-scale"]
        assert bool(said) is order, said
        if order:
            assert said[0].startswith("The forces are as good as the log's torque scale")
            assert "~1.5×" in said[0] and "not an agreement" in said[0]


def test_the_right_scale_is_recorded_as_checked(tmp_path: Path) -> None:
    code, err, doc = _run(tmp_path, "heavy_free_p2p", 1.0, "torque", "--robot",
                          str(CSV / "heavy_free_p2p.robot.json"))
    assert code == 0, err
    assert doc["input"]["torque_scale"]["verdict"] == "ok"
    assert "torque may be off" not in err and "not an agreement" not in err


def test_without_masses_the_scale_is_said_to_be_unverified(tmp_path: Path) -> None:
    robot = read_robot(CSV / "heavy_free_p2p.robot.json").to_dict()
    robot.pop("nominal", None)
    path = tmp_path / "bare.robot.json"
    path.write_text(json.dumps(robot), encoding="utf-8")
    code, err, doc = _run(tmp_path, "heavy_free_p2p", 1000.0, "torque", "--robot", str(path))
    assert code == 0, err
    ts = doc["input"]["torque_scale"]
    assert ts["verdict"] == "unverified" and ts["scale"] is None
    assert "gives no masses" in ts["message"]


@settings(max_examples=6, deadline=None)
@given(log10_scale=st.floats(-3.5, 3.5))
@example(log10_scale=0.0)
@example(log10_scale=0.6)  # 4x: warned, its incidents' forces flagged
@example(log10_scale=3.0)  # 1000x: refused
def test_a_scaled_torque_never_gives_an_unflagged_force(tmp_path_factory: pytest.TempPathFactory,
                                                        log10_scale: float) -> None:
    """A contact log with its torque scaled by s, with its description: refused (exit 3),
    or its scale judged ok and near 1, or warned and every force flagged implausible."""
    import dataclasses

    tmp = tmp_path_factory.mktemp("scaled")
    log = read_log(CSV / "heavy_impacts.csv.gz")
    log = log.slice(0, round(30 * log.sample_rate_hz))
    s = 10.0 ** log10_scale
    src = tmp / "log.csv"
    write_log(dataclasses.replace(log, torque=log.torque * s), src)
    r = CliRunner().invoke(main, ["detect", str(src), "--robot",
                                  str(CSV / "heavy_impacts.robot.json"), "-o", str(tmp / "o")])
    if r.exit_code == 3:
        assert "the torque is off by ~" in r.stderr
        return
    assert r.exit_code == 0, r.stderr
    doc = json.loads((tmp / "o" / "log.timeline.json").read_text(encoding="utf-8"))
    ts = doc["input"]["torque_scale"]
    assert ts["verdict"] in ("ok", "warn")
    forces = [x for x in doc["incidents"] + doc["lasting_loads"] if x["force_n"] is not None]
    if ts["verdict"] == "ok":
        assert 1 / WARN_FACTOR <= s <= WARN_FACTOR * 1.1
    else:
        assert all(x["force_plausible"] is False and "off the description's gravity torque"
                   in x["force_check"] for x in forces)


@pytest.mark.parametrize("name", ["kinova", "panda"])
def test_urdf_gravity_is_the_gradient_of_the_arms_potential_energy(name: str) -> None:
    """A shipped URDF's gravity torque at random poses equals the numerical gradient of the
    arm's potential energy (Pinocchio's, each pose built by angle: revolute joints as they
    are, continuous ones — the Kinova's — as (cos, sin))."""
    pin = pytest.importorskip("pinocchio", reason="the urdf extra (pinocchio) is not installed")
    from impactcli.logs.robot_files import shipped_robot
    from impactcli.logs.urdf import reduced_model
    from impactcli.model.identification import urdf_source

    robot = shipped_robot(name)
    joints = robot.joint_names
    g_of = robot.kinematics or {}
    xml, label, _ = urdf_source(g_of)
    model = reduced_model(xml, tuple(joints), label)
    data = model.createData()

    def energy(qq: np.ndarray) -> float:
        x = pin.neutral(model)
        for c, j in enumerate(joints):
            jt = model.joints[model.getJointId(j)]
            if jt.nq == 1:
                x[jt.idx_q] = qq[c]
            else:
                x[jt.idx_q], x[jt.idx_q + 1] = math.cos(qq[c]), math.sin(qq[c])
        return float(pin.computePotentialEnergy(model, data, x))

    rng = np.random.default_rng(0)
    q = rng.uniform(-1.5, 1.5, (5, len(joints)))
    g = nominal_gravity(robot, joints, q)
    assert g is not None
    h = 1e-6
    for k in range(len(q)):
        grad = [(energy(q[k] + h * e) - energy(q[k] - h * e)) / (2 * h)
                for e in np.eye(len(joints))]
        np.testing.assert_allclose(g[k], grad, atol=1e-4, rtol=1e-5)


def test_a_torque_four_times_too_large_flags_its_forces(tmp_path: Path) -> None:
    """The contact log's torque ×4, with its description: warned, recorded, and each of its
    incidents' forces flagged implausible, naming the scale."""
    code, err, doc = _run(tmp_path, "heavy_impacts", 4.0, "torque", "--robot",
                          str(CSV / "heavy_impacts.robot.json"))
    assert code == 0, err
    assert doc["input"]["torque_scale"]["verdict"] == "warn"
    forces = [x for x in doc["incidents"] if x["force_n"] is not None]
    assert forces
    assert all(x["force_plausible"] is False and "off the description's gravity torque by ~3."
               in x["force_check"] for x in forces)
    out = CliRunner().invoke(main, [
        "detect", str(tmp_path / "log.csv"), "--robot", str(CSV / "heavy_impacts.robot.json"),
        "-o", str(tmp_path / "again")]).stdout
    # said where the answer is read: beside the detection floor's figures on stdout
    assert "torques and forces of log.csv cannot be trusted: the log's torque is off the " \
           "gravity torque" in out
    assert "force not plausible" not in out  # said once, below the table, not per row
    # a gate cannot pass a force no one can trust: it could not judge (exit 5), and its
    # note does not say it passed them; a force above the limit still fails (1 wins)
    cfg = REPO / "sample_logs" / "heavy_geared.config.toml"
    for limit, code_want in ((1e5, 5), (200.0, 1)):  # ≳114 and ≳332 N
        r = CliRunner().invoke(main, [
            "detect", str(tmp_path / "log.csv"), "--config", str(cfg), "--robot",
            str(CSV / "heavy_impacts.robot.json"), "-o", str(tmp_path / "g"),
            "--fail-on-force", f"{limit:g}"])
        assert r.exit_code == code_want, r.stderr
        line = next(ln for ln in r.stderr.splitlines() if " under the limit (the first" in ln)
        assert line.startswith(f"impactcli: log.csv: --fail-on-force {limit:g} N could not "
                               "judge ") and "the log's torque is off the description's " \
            "gravity torque by ~3." in line, line
        assert "the gate passed" not in r.stderr
    # the report's verdict does not blame units for the capacity, it says why not trusted
    r = CliRunner().invoke(main, ["report", str(tmp_path / "log.csv"), "--config", str(cfg),
                                  "--robot", str(CSV / "heavy_impacts.robot.json"), "-o",
                                  str(tmp_path / "r.html"), "--json", str(tmp_path / "r.json")])
    assert r.exit_code == 0, r.stderr
    verdict = json.loads((tmp_path / "r.json").read_text("utf-8"))["logs"][0]["verdict"]
    assert "beyond what the arm can exert" not in verdict
    assert "No force here can be trusted: the log's torque is off the description's " \
           "gravity torque by ~3." in verdict


def test_joints_that_disagree_are_not_said_to_agree() -> None:
    """Two loaded joints whose logged torques are 0.7× and 1.5× the description's gravity
    torque: the median (1.1) lies in the 'agrees' band, but the joints do not agree with
    the description; the scale is said to be of its order only. Both at 1.1×: agrees."""
    rng = np.random.default_rng(5)
    g = rng.uniform(5.0, 20.0, size=(200, 2)) * rng.choice([-1.0, 1.0], size=(200, 2))
    speed = np.zeros_like(g)
    for k, agrees in (((0.7, 1.5), False), ((1.1, 1.1), True)):
        v = scale_check("log", ("j1", "j2"), g, g * np.array(k), speed, (100.0, 100.0))
        assert v.kind == "ok" and len(v.per_joint) == 2, v
        assert ("agrees with" in v.message) is agrees, v
        assert ("not an agreement" in v.message) is not agrees, v


@pytest.mark.parametrize("verb", ["calibrate", "identify", "inspect"])
def test_calibrate_and_identify_refuse_currents_in_ma_as_detect_does(tmp_path: Path,
                                                                      verb: str) -> None:
    """A trial's calibrate accepted currents logged in mA (torque RMS 7.1e4 N·m, a
    "+1.5e+03 kg" load) and wrote a config, and inspect showed "j1 4.7e+04…8.5e+04" without
    a word; only detect, step 3, refused them. Now inspect --robot and the verbs that make
    a config or a model refuse them too: exit 3, one line, nothing written."""
    log = read_log(CSV / "heavy_free_p2p.csv.gz")
    log = log.slice(0, round(30 * log.sample_rate_hz))
    import dataclasses

    src = tmp_path / "log.csv"
    write_log(dataclasses.replace(log, current=log.current * 1000.0), src)
    out = tmp_path / ("c.toml" if verb == "calibrate" else "m.json")
    r = CliRunner().invoke(main, [verb, str(src), "--robot",
                                  str(CSV / "heavy_free_p2p.robot.json"), "--torque-source",
                                  "current", *(["-o", str(out)] if verb != "inspect" else [])])
    assert r.exit_code == 3, r.output
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith(f"impactcli: error: {src}: the torque is off by ~") and \
        "mA logged as A" in line and "Traceback" not in r.stderr
    assert not out.exists()


def test_a_load_taken_off_never_makes_a_valid_log_a_unit_error(tmp_path: Path) -> None:
    """A trial's log (assist-like robot 41, pick-and-place starting with 2 kg; the
    simulator's joint-side torque) read ~1.7× the description's gravity torque, of the
    order. Judged again with its weighed start load taken off, it read ~0.036×, near
    1/20, and detect refused it "motor-side (÷ the gear ratio 20)", exit 3. A judgement
    made after taking a weighed load off cannot refuse what the log's own torque passed:
    the log is audited, the load weighed (truth 2 kg) and the scale as logged stated."""
    def sim(name: str, scenario: str, seed: int, *extra: str) -> Path:
        r = CliRunner().invoke(main, [
            "simulate", "--arm", "assist_like", "--robot-seed", "41", "--scenario",
            scenario, "--seed", str(seed), "--no-controller-channels", "-o", str(tmp_path),
            "--name", name, *extra])
        assert r.exit_code == 0, r.output
        return tmp_path / f"{name}.csv.gz"

    free = [sim(f"f{s}", sc, s) for s, sc in ((1, "free_triangle"), (2, "free_p2p"),
                                               (3, "free_multisine"))]
    log = sim("pp", "pick_and_place", 16, "--payload-kg", "2")
    cfg = tmp_path / "c.toml"
    r = CliRunner().invoke(main, ["calibrate", *map(str, free), "--robot",
                                  str(tmp_path / "f1.robot.json"), "-o", str(cfg)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["detect", str(log), "--config", str(cfg), "-o",
                                  str(tmp_path / "out")])
    assert r.exit_code in (0, 1) and "motor-side" not in r.stderr, r.output
    tl = json.loads((tmp_path / "out" / "pp.timeline.json").read_text("utf-8"))
    assert tl["input"]["payload"]["verdict"] == "used"
    assert abs(tl["input"]["payload"]["mass_kg"] - 2.0) < 0.25 * 2.0
    scale = tl["input"]["torque_scale"]
    assert scale["verdict"] == "ok" and 1.2 < scale["scale"] < 2.5, scale
