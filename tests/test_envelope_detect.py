"""detect against the calibration's motion envelope: a log that moves
faster than the calibration logs did has its share outside in the timeline, a warning
naming it, and the incidents there marked; a log inside it has share 0 and no warning; a
slower log, inside every range, is outside where it moved slowly for longer than the
calibration logs ever did."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import load_config
from impactcli.logs import read_log, write_log
from impactcli.schema import validate
from impactcli.types import RobotLog

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
CONFIG = SAMPLES / "assist_like.config.toml"
LOG = SAMPLES / "csv" / "assist_impacts.csv.gz"


def _detect(log: Path, out: Path) -> tuple[dict, str]:
    r = CliRunner().invoke(main, ["detect", str(log), "--config", str(CONFIG), "-o", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / f"{log.name.split('.')[0]}.timeline.json").read_text())
    validate(doc, "timeline", AssertionError, "timeline")
    return doc, r.stderr


def test_a_log_inside_the_envelope_has_nothing_outside(tmp_path: Path) -> None:
    doc, err = _detect(LOG, tmp_path)
    env = doc["motion_envelope"]
    assert env["samples"] > 10_000 and env["outside"] == 0 and env["share"] == 0.0
    assert env["source"] == "position_ref"
    assert all(i["outside_envelope"] is False for i in doc["incidents"])
    assert "motion envelope" not in err


def test_a_faster_log_is_outside_and_says_so(tmp_path: Path) -> None:
    """The same log played 2.5× faster is refused (its rate is not the config's); the same
    log with 2.5× larger motion at its own rate lies partly outside the calibrated ranges:
    the share, the warning, the incidents touching it."""
    log = read_log(LOG)
    t0 = log.t_ns[0]
    fast = dataclasses.replace(log, t_ns=(t0 + (log.t_ns - t0) / 2.5).astype(np.int64),
                               velocity_ref=None if log.velocity_ref is None
                               else log.velocity_ref * 2.5,
                               acceleration_ref=None if log.acceleration_ref is None
                               else log.acceleration_ref * 6.25)
    path = tmp_path / "fast.csv"
    write_log(fast, path)
    cfg_rate = 250.0 * 2.5  # the config's calibration rate no longer matches: refused
    r = CliRunner().invoke(main, ["detect", str(path), "--config", str(CONFIG), "-o",
                                  str(tmp_path / "o")])
    assert r.exit_code == 3 and "Hz" in r.stderr, (cfg_rate, r.output)
    # same rate, larger motion: positions and references scaled by 2.5 about their mean
    path = _larger_motion(log, tmp_path / "big.csv")
    doc, err = _detect(path, tmp_path / "o2")
    env = doc["motion_envelope"]
    assert env["share"] > 0.1 and env["outside"] > 0 and env["stretches_s"]
    assert "outside the calibration's motion envelope" in err
    assert "stated false-alarm rate was not measured on such motion" in err
    touched = [i for i in doc["incidents"] if i["outside_envelope"]]
    counted = [i for i in touched if i["number"] is not None]  # the warm-up's not said
    assert counted and f"{len(counted)} counted incident(s) touch it" in err
    assert any("motion envelope" in w for w in doc["warnings"])
    # each counted incident that touches it says so on its row
    r = CliRunner().invoke(main, ["detect", str(path), "--config", str(CONFIG), "-o",
                                  str(tmp_path / "o3")])
    rows = [ln for ln in r.stdout.splitlines()
            if "outside the calibrated motion (outside_envelope in the timeline)" in ln]
    assert len(rows) == min(len(counted), 20)  # the terminal lists 20 at most


def test_the_report_says_what_moved_outside(tmp_path: Path) -> None:
    """The report's "what the audit could not see" names the share outside (and says the
    rate applies when nothing was)."""
    path = _larger_motion(read_log(LOG), tmp_path / "big.csv")
    for src, outside in ((LOG, False), (path, True)):
        out = tmp_path / f"{src.name}.json"
        r = CliRunner().invoke(main, ["report", str(src), "--config", str(CONFIG), "-o",
                                      str(tmp_path / f"{src.name}.html"), "--json", str(out)])
        assert r.exit_code == 0, r.output
        text = out.read_text()
        doc = json.loads(text)
        validate(doc, "report", AssertionError, "report")
        items = [i for i in _walk(doc) if isinstance(i, dict)
                 and i.get("code") == "motion-envelope"]
        assert len(items) == 1
        assert ("outside the calibration's motion envelope" in items[0]["text"]) is outside
        assert (items[0]["data"]["share"] > 0.1) is outside
        # 2.5× the motion about its mean leaves the calibrated poses too: said as a second
        # finding ("and"), not against the first ("but", a new user's trial)
        assert bool(items[0]["data"].get("posture_outside")) is outside
        assert ("; and its posture left the calibration logs' position range"
                in items[0]["text"]) is outside
        assert "; but" not in items[0]["text"]


def test_a_log_at_other_poses_says_its_posture_left_the_calibrated_range(
        tmp_path: Path) -> None:
    """The same motion with the shoulder turned beyond every pose the calibration logs
    held: velocity and acceleration stay inside the envelope (nothing counted outside), but
    the posture is named — in the timeline, the warning and the report, which then does not
    say that the stated false-alarm rate applies."""
    env = load_config(CONFIG).calibration.motion_envelope
    assert env is not None
    _, hi = env["joints"]["shoulder"]["position"]
    log = read_log(LOG)
    shift = np.zeros(log.position.shape[1])
    j = log.joint_names.index("shoulder")
    lowest = min(float(log.position[:, j].min()),
                 float(np.nanmin(log.position[:, j] if log.position_ref is None
                                 else log.position_ref[:, j])))
    shift[j] = hi - lowest + 0.2
    turned = dataclasses.replace(
        log, position=log.position + shift,
        position_ref=None if log.position_ref is None else log.position_ref + shift)
    path = tmp_path / "turned.csv"
    write_log(turned, path)
    doc, err = _detect(path, tmp_path / "o")
    me = doc["motion_envelope"]
    assert me["outside"] == 0 and me["posture_outside"] == {"shoulder": 1.0}, me
    assert "its posture left the calibration logs' position range on shoulder (100 %)" in err
    inside, _ = _detect(LOG, tmp_path / "o2")
    assert "posture_outside" not in inside["motion_envelope"]
    # a few hundredths of a radian past the calibrated range is within its margin
    from impactcli.detect.envelope import POSTURE_MARGIN_RAD

    highest = max(float(log.position[:, j].max()), float(np.nanmax(
        log.position[:, j] if log.position_ref is None else log.position_ref[:, j])))
    nudge = np.zeros_like(shift)
    nudge[j] = hi - highest + 0.6 * POSTURE_MARGIN_RAD
    near = tmp_path / "near.csv"
    write_log(dataclasses.replace(
        log, position=log.position + nudge,
        position_ref=None if log.position_ref is None else log.position_ref + nudge), near)
    assert "posture_outside" not in _detect(near, tmp_path / "o3")[0]["motion_envelope"]
    item = _report_item(path, tmp_path)
    assert "posture left the calibration logs' position range on shoulder" in item["text"]
    assert "rate applies" not in item["text"]


def test_a_slower_log_is_outside_only_through_its_slow_stretches(tmp_path: Path) -> None:
    """The calibration's multi-sine at a third of its frequencies, on the sample arm: its
    velocity and acceleration stay within the calibrated ranges (a third and a ninth of
    the calibration's), but each reversal keeps a joint below 0.02 rad/s about three times
    as long as any calibration log did. Those stretches, and only they, are outside: in
    the timeline, the warning and the report; the calibration's own log stays inside."""
    path = _slow_log(tmp_path)
    doc, err = _detect(path, tmp_path / "o")
    me = doc["motion_envelope"]
    assert me["outside"] > 0 and me["slow_outside"], me
    assert me["per_joint"] == {j: me["slow_outside"].get(j, 0.0) for j in me["per_joint"]}
    cal = load_config(CONFIG).calibration.motion_envelope
    assert cal is not None
    assert me["slow_dwell_s"] == {j: cal["slow_dwell_s"][j] for j in me["slow_outside"]}
    assert "slower than 0.02 rad/s for longer at a stretch than in the calibration" in err
    assert "velocity or acceleration beyond" not in err
    item = _report_item(path, tmp_path)
    assert "slower than 0.02 rad/s" in item["text"] and "rate applies" not in item["text"]
    own, _ = _detect(SAMPLES / "csv" / "assist_free_multisine.csv.gz", tmp_path / "o2")
    assert own["motion_envelope"]["outside"] == 0


def _slow_log(tmp_path: Path) -> Path:
    """The sample arm's multi-sine at a third of its frequencies (30 s)."""
    from impactcli.sim import scenario, simulate
    from impactcli.sim.sample_logs import ROBOT_SEEDS

    sc = scenario("free_multisine", "assist_like", 30.0, controller_channels=True,
                  robot_seed=ROBOT_SEEDS["assist_like"])
    ref = sc.reference
    sc = dataclasses.replace(sc, reference=dataclasses.replace(
        ref, f_min=ref.f_min / 3.0, f_max=ref.f_max / 3.0))
    path = tmp_path / "slow.csv.gz"
    write_log(simulate(sc, seed=303).log, path)
    return path


def test_the_slow_speed_follows_the_models_coulomb_scale(tmp_path: Path) -> None:
    """A model identified with a Coulomb scale of 0.05 rad/s turns its friction below
    ~0.1 rad/s, not 0.02: calibrate records slow stretches below twice its scale, says so,
    and detect reads the slow clock there and names that speed in its warning and the
    timeline."""
    csv = SAMPLES / "csv"
    robot = str(csv / "assist_free_multisine.robot.json")
    model, cfg = tmp_path / "m.json", tmp_path / "c.toml"
    r = CliRunner().invoke(main, ["identify", str(csv / "assist_free_multisine.csv.gz"),
                                  "--robot", robot, "--coulomb-slope", "0.05", "-o",
                                  str(model)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["calibrate", str(csv / "assist_free_multisine.csv.gz"),
                                  str(csv / "assist_free_p2p.csv.gz"), "--model", str(model),
                                  "--robot", robot, "-o", str(cfg)])
    assert r.exit_code == 0, r.output
    env = load_config(cfg).calibration.motion_envelope
    assert env is not None and env["slow_rad_s"] == 0.1 and env["slow_dwell_s"]
    assert "slower than 0.1 rad/s for at most" in r.stdout
    out = tmp_path / "o"
    r = CliRunner().invoke(main, ["detect", str(_slow_log(tmp_path)), "--config", str(cfg),
                                  "-o", str(out)])
    assert r.exit_code == 0, r.output
    me = json.loads((out / "slow.timeline.json").read_text())["motion_envelope"]
    assert me["slow_outside"] and me["slow_rad_s"] == 0.1, me
    assert "slower than 0.1 rad/s for longer at a stretch" in r.stderr
    assert "0.02 rad/s" not in r.stderr


def test_a_log_without_a_reference_says_its_slow_stretches_were_not_checked(
        tmp_path: Path) -> None:
    """The sample config records slow stretches of its logs' reference; a log without a
    reference cannot be checked for them (a measured position's noise at rest reads as slow
    motion): detect warns so even with nothing outside, the timeline's note says it, and
    the report does not say that the stated rate applies."""
    log = read_log(LOG)
    bare = dataclasses.replace(log, position_ref=None, velocity_ref=None,
                               acceleration_ref=None)
    path = tmp_path / "bare.csv"
    write_log(bare, path)
    doc, err = _detect(path, tmp_path / "o")
    me = doc["motion_envelope"]
    assert me["source"] == "position" and "slow_outside" not in me
    assert "slow stretches not checked: this log has no reference position" in me["note"]
    assert "slow stretches not checked" in err
    item = _report_item(path, tmp_path)
    assert "slow stretches not checked" in item["text"]
    assert "no slow stretch longer" not in item["text"]
    assert "rate applies" not in item["text"]


def _report_item(log: Path, tmp_path: Path) -> dict:
    """The report's "motion-envelope" item of ``log`` with the sample config."""
    out = tmp_path / "r.json"
    r = CliRunner().invoke(main, ["report", str(log), "--config", str(CONFIG), "-o",
                                  str(tmp_path / "r.html"), "--json", str(out)])
    assert r.exit_code == 0, r.output
    return next(i for i in _walk(json.loads(out.read_text())) if isinstance(i, dict)
                and i.get("code") == "motion-envelope")


def _larger_motion(log: RobotLog, path: Path) -> Path:
    """``log`` with 2.5× its motion about its mean posture, at its own rate, written to
    ``path``."""
    q = log.position.mean(axis=0)
    big = dataclasses.replace(
        log, position=q + 2.5 * (log.position - q),
        position_ref=None if log.position_ref is None else q + 2.5 * (log.position_ref - q),
        velocity_ref=None if log.velocity_ref is None else 2.5 * log.velocity_ref,
        acceleration_ref=None if log.acceleration_ref is None else 2.5 * log.acceleration_ref)
    write_log(big, path)
    return path


def _walk(x: object) -> list[object]:
    if isinstance(x, dict):
        return [x, *[y for v in x.values() for y in _walk(v)]]
    if isinstance(x, list):
        return [y for v in x for y in _walk(v)]
    return []
