"""Real-log hygiene: flat or unmeasured torque channels and joints the model or config does
not cover are left out of detection (warned, recorded in the timeline and the config);
flat controller channels are read as not logged (impactcli.logs.screen)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import DetectorConfig
from impactcli.errors import LogFormatError
from impactcli.logs import write_log
from impactcli.logs.screen import unusable_columns
from impactcli.outputs.timeline import timeline_dict
from impactcli.run.calibration import calibrate
from impactcli.run.collect import detect_in_memory
from impactcli.schema import validate
from impactcli.types import RobotLog

from .conftest import make_log


def three_joint_log(seed: int = 0, wrist: str = "real") -> RobotLog:
    """10 s at 250 Hz; j1, j2 carry N·m-scale torque; the wrist ``j3`` is ``real`` (small
    but measured), ``flat`` (zeros) or ``unmeasured`` (|e| < 0.03 on a 1e-3 grid)."""
    log = make_log(n=2500, joints=("j1", "j2", "j3"), seed=seed)
    rng = np.random.default_rng(100 + seed)
    tau = np.array(log.torque) * np.array([10.0, 5.0, 0.05])
    if wrist == "flat":
        tau[:, 2] = 0.0
    elif wrist == "unmeasured":
        tau[:, 2] = np.round(0.01 * rng.standard_normal(len(tau)), 3).clip(-0.029, 0.029)
    return dataclasses.replace(log, torque=tau)


def test_rule_tells_flat_unmeasured_and_small_but_real_channels() -> None:
    flat, unmeasured, real = (three_joint_log(wrist=w).torque for w in
                              ("flat", "unmeasured", "real"))
    assert unusable_columns(flat)[:2] == [None, None]
    assert unusable_columns(flat)[2] == "flat: its torque is constant (0 N·m)"
    why = unusable_columns(unmeasured)[2]
    assert why is not None and why.startswith("unmeasured: ")
    assert "distinct values spanning" in why and "under 1% of the largest joint's" in why
    assert unusable_columns(real) == [None, None, None]  # small, but many distinct values
    # a quantised channel with a range like the others' is kept
    coarse = np.round(real, 0)
    assert unusable_columns(coarse)[0] is None


def test_unmeasured_wrist_is_left_out_warned_and_recorded() -> None:
    log = three_joint_log(wrist="unmeasured")
    res = detect_in_memory(log)[0]
    assert res.log.joint_names == ("j1", "j2")
    assert [d["name"] for d in res.joints_left_out] == ["j3"]
    assert res.joints_left_out[0]["reason"].startswith("torque unmeasured: ")
    assert any("joint 'j3' left out of detection: torque unmeasured" in w for w in res.warnings)
    doc = timeline_dict(res)
    validate(doc, "timeline", AssertionError, "timeline")
    assert doc["input"]["joints_left_out"] == list(res.joints_left_out)
    assert set(doc["thresholds"]) == {"j1", "j2"}


def test_calibration_records_left_out_joints_and_detect_leaves_them_out() -> None:
    with pytest.warns(Warning, match=r"joint 'j3' left out of detection: torque flat"):
        cfg = calibrate([three_joint_log(seed=1, wrist="flat"), three_joint_log(seed=2)])
    rec = cfg.calibration.joints_left_out
    assert [d["name"] for d in rec] == ["j3"]
    assert rec[0]["reason"].startswith("torque flat: its torque is constant (0 N·m), in ")
    assert set(cfg.thresholds.v_stat) == {"j1", "j2"}
    again = DetectorConfig.from_dict(cfg.to_dict())
    assert again.calibration.joints_left_out == rec
    # the detected log's wrist is fine, but the config has no threshold for it
    res = detect_in_memory(three_joint_log(seed=3), config=again)[0]
    assert res.log.joint_names == ("j1", "j2")
    assert res.joints_left_out[0]["reason"].startswith("left out at calibration (torque flat")


def test_logged_joint_outside_the_config_is_left_out() -> None:
    cfg = calibrate([make_log(n=2500, seed=s) for s in (1, 2)])  # j1, j2
    res = detect_in_memory(three_joint_log(seed=3), config=cfg)[0]
    assert res.log.joint_names == ("j1", "j2")
    (left,) = res.joints_left_out
    assert {k: left[k] for k in ("name", "reason")} == {
        "name": "j3", "reason": "not in the model or the calibrated config"}
    # it moves (its sine spans about 1 rad): said as not checked, with its travel
    q = np.asarray(three_joint_log(seed=3).position)[:, 2]
    assert left["travel_rad"] == pytest.approx(float(q.max() - q.min()))
    assert any("moved but were not checked" in w and "j3 (travels" in w for w in res.warnings)


def test_flat_controller_channel_is_read_as_not_logged() -> None:
    log = three_joint_log()
    ext = np.zeros_like(log.torque)
    ext[:, 0] = 0.01 * np.random.default_rng(0).standard_normal(len(ext))
    res = detect_in_memory(dataclasses.replace(log, torque_ext=ext))[0]
    gens = {j: g["generator"] for j, g in res.generators.items()}
    assert gens == {"j1": "logged_external", "j2": "inverse_dynamics",
                    "j3": "inverse_dynamics"}
    assert any("joint 'j2': its torque_ext is flat: its torque is constant (0 N·m); read as "
               "not logged" in w for w in res.warnings)
    assert res.joints_left_out == ()


def test_no_joint_left_is_a_data_error(tmp_path: Path) -> None:
    log = make_log(n=2500, joints=("a",))
    flat = dataclasses.replace(log, torque=np.zeros_like(log.torque))
    with pytest.raises(LogFormatError, match=r"no joint left to detect on \(a: torque flat"):
        detect_in_memory(flat)
    write_log(flat, tmp_path / "flat.csv")
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "flat.csv"), "-o", str(tmp_path)])
    assert r.exit_code == 3
    assert "no joint left to detect on" in r.output


def test_cli_warns_about_the_left_out_joint(tmp_path: Path) -> None:
    write_log(three_joint_log(wrist="unmeasured"), tmp_path / "w.csv")
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "w.csv"), "-o", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "joint 'j3' left out of detection: torque unmeasured" in r.output
    doc = json.loads((tmp_path / "w.timeline.json").read_text())
    assert doc["input"]["joints_left_out"][0]["name"] == "j3"


def test_terminal_says_warmup_cap_and_lasting_alarm(tmp_path: Path) -> None:
    """A warm-up that reaches its cap, and an alarm of ≥ 10 s, are warned about (the CLI
    prints every warning), not only in the report."""
    cfg = calibrate([make_log(n=6250, seed=s) for s in (1, 2)])
    loaded = make_log(n=6250, seed=3)
    tau = np.array(loaded.torque)
    tau[2000:5250, 0] += 5.0  # a load held for 13 s
    res = detect_in_memory(dataclasses.replace(loaded, torque=tau), config=cfg)[0]
    assert any("alarm(s) last 10 s or more (the longest: static_loading 8.0–21.2 s)" in w
               for w in res.warnings), res.warnings
    short = dataclasses.replace(cfg, warmup=dataclasses.replace(
        cfg.warmup, min_s=3.0, max_s=3.5, tolerance=-0.999))
    res = detect_in_memory(make_log(n=2500, seed=4), config=short)[0]
    assert any("the warm-up reached its cap (warmup.max_s = 3.5 s) on joint(s) j1, j2" in w
               for w in res.warnings), res.warnings


def test_a_joint_a_config_model_needs_left_out_says_why_and_what_to_do(tmp_path: Path
                                                                      ) -> None:
    """A trial: the elbow's torque held constant in a log detected with a calibrated config
    read "joints ['shoulder'] do not match the model's ['shoulder', 'elbow'] (missing
    ['elbow'])", though the elbow is in the log. The error now names why the joint was left
    out and that the model needs it; without the config the log's own model checks the
    joints left."""
    cal = tmp_path / "cal.toml"
    for s in (1, 2):
        write_log(three_joint_log(seed=s), tmp_path / f"free{s}.csv")
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "free1.csv"),
                                  str(tmp_path / "free2.csv"), "-o", str(cal)])
    assert r.exit_code == 0, r.output
    write_log(three_joint_log(seed=3, wrist="flat"), tmp_path / "w.csv")
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "w.csv"), "--config", str(cal),
                                  "-o", str(tmp_path / "o")])
    assert r.exit_code == 3, r.output
    (err,) = [ln for ln in r.stderr.splitlines() if "error" in ln]
    assert err == (f"impactcli: error: {tmp_path / 'w.csv'}: joint 'j3' was left out (torque "
                   "flat: its torque is constant (0 N·m)), but the config model's residual "
                   "needs every joint it was identified with (['j1', 'j2', 'j3']), so with it "
                   "no joint can be checked: mend the channel, or detect without the model "
                   "(no --config or --model: the log's own model on the joints left)"), err
    assert not (tmp_path / "o" / "w.timeline.json").exists()
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "w.csv"), "-o",
                                  str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "o" / "w.timeline.json").read_text())
    assert doc["input"]["joints"] == ["j1", "j2"]
