"""Residual generators that read the controller's channels (formats.md, "Model and detector
config"): choice per joint, the logged_model correction, calibration freezing the choice,
and what detect, the timeline and the terminal say."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import DetectorConfig, load_config
from impactcli.errors import ConfigError, LogFormatError
from impactcli.logs import read_log, write_log
from impactcli.model.generators import choose_generators
from impactcli.outputs.timeline import timeline_dict
from impactcli.run.calibration import calibrate
from impactcli.run.collect import detect_in_memory
from impactcli.schema import validate
from impactcli.types import LogSource, RobotLog


def motion_log(seconds: float = 12.0, seed: int = 0, *, ext: bool = True, model: bool = True,
               push_at: float | None = None, push_nm: float = 2.0) -> RobotLog:
    """A 2-joint 250 Hz log whose torque is a known function of a known torque_model:
    tau = 0.9 τ_m + 0.2 q' + 0.3 tanh(q'/v_s) − 0.1 (+ a push on both joints' residual).

    torque_ext is the push (the true external torque) plus 0.01 N·m noise.
    """
    rng = np.random.default_rng(seed)
    dt = 0.004
    t = np.arange(round(seconds / dt)) * dt
    w = 2 * np.pi * np.array([0.4, 0.7])
    q = 0.6 * np.sin(np.outer(t, w))
    qd = 0.6 * w * np.cos(np.outer(t, w))
    qdd = -0.6 * w**2 * np.sin(np.outer(t, w))
    tm = 1.5 * qdd + 2.0 * np.cos(q)  # the controller's model torque
    ext_true = np.zeros_like(q)
    if push_at is not None:
        on = (t >= push_at) & (t < push_at + 0.3)
        ext_true[on] = push_nm * np.sin(np.pi * (t[on] - push_at) / 0.3)[:, None]
    tau = (0.9 * tm + 0.2 * qd + 0.3 * np.tanh(qd / 0.01) - 0.1 - ext_true
           + 0.005 * rng.standard_normal(q.shape))
    return RobotLog(
        t_ns=np.round(t * 1e9).astype(np.int64), joint_names=("shoulder", "elbow"),
        position=q + 1e-5 * rng.standard_normal(q.shape), torque=tau,
        position_ref=q, velocity_ref=qd, acceleration_ref=qdd,
        torque_model=tm if model else None,
        torque_ext=ext_true + 0.01 * rng.standard_normal(q.shape) if ext else None,
        source=LogSource(f"<motion seed={seed}>", "0" * 64, "memory"),
    )


def test_auto_takes_per_joint_the_best_channel_and_says_why() -> None:
    log = motion_log()
    te = np.array(log.torque_ext)
    te[:, 1] = np.nan  # the elbow does not log torque_ext
    log = dataclasses.replace(log, torque_ext=te)
    ch = choose_generators(log, "auto")
    assert [(c.joint, c.generator) for c in ch] == [("shoulder", "logged_external"),
                                                    ("elbow", "logged_model")]
    assert "torque_ext" in ch[0].reason and "torque_model" in ch[1].reason
    bare = dataclasses.replace(log, torque_ext=None, torque_model=None)
    assert {c.generator for c in choose_generators(bare, "auto")} == {"inverse_dynamics"}
    with pytest.raises(LogFormatError, match=r"joint 'elbow' has no torque_ext channel"):
        choose_generators(log, "logged_external")


def test_correction_removes_what_the_controller_model_leaves_out() -> None:
    """tau − τ_m = −0.1 τ_m + friction + offset is state-dependent model error: corrected,
    the logged_model residual in free motion is far below the plain one; a push still
    shows at its size."""
    plain_cfg = DetectorConfig()
    plain_cfg = dataclasses.replace(plain_cfg, residual=dataclasses.replace(
        plain_cfg.residual, logged_correction=False))
    log = motion_log(ext=False, push_at=8.0, push_nm=2.0)
    corrected = detect_in_memory(log, config=DetectorConfig())[1].signals["residual"]
    plain = detect_in_memory(log, config=plain_cfg)[1].signals["residual"]
    t = log.time_s
    free = (t > 1.0) & ((t < 7.9) | (t > 8.6))
    rms = lambda a: float(np.sqrt(np.mean(a[free] ** 2)))  # noqa: E731
    for k in range(2):
        assert rms(corrected[:, k]) < 0.2 * rms(plain[:, k]), k
        on = (t > 8.1) & (t < 8.2)
        assert np.max(np.abs(corrected[on, k])) == pytest.approx(2.0, rel=0.25)


def test_plain_logged_external_residual_is_the_logged_estimate_and_needs_no_model() -> None:
    log = motion_log(push_at=8.0)
    cfg = DetectorConfig()
    cfg = dataclasses.replace(cfg, residual=dataclasses.replace(cfg.residual,
                                                                logged_correction=False))
    res, sig = detect_in_memory(log, config=cfg)
    assert res.model is None and res.model_sha256 is None
    assert {g["generator"] for g in res.generators.values()} == {"logged_external"}
    np.testing.assert_array_equal(sig.signals["residual"], log.torque_ext)
    doc = timeline_dict(res)
    validate(doc, "timeline", AssertionError, "timeline")
    assert doc["schema_version"] == "2.12" and doc["model"] is None
    assert doc["replay"]["generator"]["elbow"]["generator"] == "logged_external"


def test_calibrate_freezes_generators_and_detect_needs_their_channels(tmp_path: Path) -> None:
    free = [motion_log(seed=s) for s in (1, 2)]
    cfg = calibrate(free)
    assert cfg.residual.generators == {"shoulder": "logged_external", "elbow": "logged_external"}
    assert cfg.model is not None and cfg.calibration.calibrated
    # a push of 2 N·m on the residual is caught by the calibrated config, nothing else
    res = detect_in_memory(motion_log(seed=3, push_at=8.0), config=cfg)[0]
    product = [e for e in res.events if e.detector in ("adaptive", "static_loading")
               and not e.in_warmup]
    assert product and all(7.9 <= e.t_start <= 8.4 for e in product)
    # the frozen channel is missing from the log: a data error naming joint and channel
    with pytest.raises(LogFormatError, match=r"joint 'shoulder' has no torque_ext channel"):
        detect_in_memory(motion_log(seed=3, ext=False), config=cfg)
    # another generator cannot use these thresholds
    with pytest.raises(ConfigError, match=r"calibrated with the logged_external generator"):
        detect_in_memory(motion_log(seed=3), config=cfg, generator="logged_model")
    # a calibration over logs that do not all carry torque_ext falls back to torque_model
    mixed = calibrate([motion_log(seed=1), motion_log(seed=2, ext=False)])
    assert set(mixed.residual.generators.values()) == {"logged_model"}
    res = detect_in_memory(motion_log(seed=3), config=mixed)[0]
    assert res.model_source == "config" and res.online_equivalent


def test_detect_cli_names_the_generator_and_old_configs_keep_theirs(tmp_path: Path) -> None:
    log_path = tmp_path / "pushed.csv"
    write_log(motion_log(seed=4, push_at=8.0), log_path)
    assert read_log(log_path).has_channel("torque_ext").all()
    r = CliRunner().invoke(main, ["detect", str(log_path), "-o", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    assert ("residual generator: logged_external (all joints; auto: the log carries "
            "torque_ext)") in r.output
    tl = json.loads((tmp_path / "out" / "pushed.timeline.json").read_text())
    assert tl["replay"]["generator"]["shoulder"]["reason"].startswith("auto")
    r = CliRunner().invoke(main, ["detect", str(log_path), "-o", str(tmp_path / "o2"),
                                  "--generator", "inverse_dynamics"])
    assert r.exit_code == 0, r.output
    assert "residual generator: inverse_dynamics (all joints; requested" in r.output
    # a config written before `auto` names its generator and keeps it
    old = tmp_path / "old.toml"
    old.write_text('[residual]\ngenerator = "inverse_dynamics"\n', encoding="utf-8")
    assert load_config(old).residual.generator == "inverse_dynamics"
    r = CliRunner().invoke(main, ["detect", str(log_path), "-o", str(tmp_path / "o3"),
                                  "--config", str(old)])
    assert r.exit_code == 0, r.output
    assert "residual generator: inverse_dynamics" in r.output


def test_calibrate_cli_prints_the_frozen_generator(tmp_path: Path) -> None:
    paths = []
    for s in (1, 2):
        p = tmp_path / f"free{s}.csv"
        write_log(motion_log(seed=s), p)
        paths.append(str(p))
    cfg_path = tmp_path / "c.toml"
    r = CliRunner().invoke(main, ["calibrate", *paths, "-o", str(cfg_path)])
    assert r.exit_code == 0, r.output
    assert any(line.split()[:2] == ["shoulder", "logged_external"]
               for line in r.output.splitlines())
    cfg = load_config(cfg_path)
    assert cfg.residual.generators["elbow"] == "logged_external"
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "free1.csv"), "-o",
                                  str(tmp_path / "o"), "--config", str(cfg_path),
                                  "--generator", "momentum_observer"])
    assert r.exit_code == 3
    assert "cannot use them" in r.output


def test_nan_torque_ext_column_is_read_as_not_logged(tmp_path: Path) -> None:
    log = motion_log()
    te = np.array(log.torque_ext)
    te[:, 0] = np.nan
    write_log(dataclasses.replace(log, torque_ext=te), tmp_path / "x.csv")
    text = (tmp_path / "x.csv").read_text().splitlines()
    head = text[0].split(",")
    assert "shoulder.torque_ext" not in head  # not written for a joint that lacks it
    # a file whose column exists but holds only NaN: warned, read as not logged
    k = head.index("elbow.torque_ext")
    rows = [line.split(",") for line in text[1:]]
    for row in rows:
        row[k] = "nan"
    (tmp_path / "y.csv").write_text("\n".join([",".join(head)] + [",".join(r) for r in rows]))
    with pytest.warns(Warning, match=r"'elbow.torque_ext' holds no finite value"):
        y = read_log(tmp_path / "y.csv")
    assert y.torque_ext is None
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "y.csv"), "-o", str(tmp_path / "o"),
                                  "--generator", "logged_external"])
    assert r.exit_code == 3
    assert "joint 'shoulder' has no torque_ext channel" in r.output
