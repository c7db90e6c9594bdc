"""DetectorConfig: defaults, round trip through TOML / YAML / JSON, validation errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from impactcli.config import (
    TABLE_I_V_STAT,
    CalibrationRecord,
    DetectorConfig,
    LogRecord,
    ThresholdsConfig,
    load_config,
    save_config,
)
from impactcli.errors import ConfigError

EXAMPLE = Path(__file__).resolve().parents[1] / "schemas" / "examples" / "config.example.toml"
MODEL = EXAMPLE.with_name("model.example.json")


def test_defaults_are_table_one() -> None:
    a = DetectorConfig().adaptive
    assert (a.eta, a.rho, a.p, a.w1_hz, a.w2_hz) == (2, (2, 4), 20, 10.0, 50.0)
    assert (a.n1_s, a.n2_s, a.forgetting_factor, a.p0, a.theta0) == (0.04, 0.16, 0.999, 10.0, 0)
    assert TABLE_I_V_STAT == (0.45, 0.2)
    assert DetectorConfig().thresholds.v_stat == {}          # uncalibrated by default
    assert DetectorConfig().calibration.calibrated is False


def _full() -> DetectorConfig:
    return DetectorConfig(
        thresholds=ThresholdsConfig(v_stat={"shoulder": 0.45, "elbow": 0.2},
                                    v0={"shoulder": 3.0, "elbow": 1.0},
                                    vL={"shoulder": 1.0, "elbow": 0.5}),
        calibration=CalibrationRecord(
            calibrated=True, margin_rule="leave-one-out",
            margins={"adaptive": {"shoulder": 1.3, "elbow": 1.1}},
            logs=(LogRecord("a.csv", "a" * 64), LogRecord("b.csv", "b" * 64)),
            model_sha256="c" * 64,
        ),
        model=json.loads(MODEL.read_text(encoding="utf-8")),
    )


def _no_none(x: object) -> object:
    if isinstance(x, dict):
        return {k: _no_none(v) for k, v in x.items() if v is not None}
    if isinstance(x, list):
        return [_no_none(v) for v in x]
    return x


@pytest.mark.parametrize("suffix", [".toml", ".yaml", ".yml", ".json"])
def test_round_trip(tmp_path: Path, suffix: str) -> None:
    cfg = _full()
    path = tmp_path / f"cfg{suffix}"
    save_config(cfg, path)
    assert cfg.model == _no_none(cfg.model)  # a field without a value is absent, as in TOML
    assert load_config(path) == cfg
    assert DetectorConfig.from_dict(cfg.to_dict()) == cfg
    save_config(DetectorConfig(), path)
    assert load_config(path) == DetectorConfig()


def test_generator_names_match_the_timeline_and_the_old_name_is_read(tmp_path: Path) -> None:
    """A new config's generator is ``auto`` (formats.md); ``rigid_model`` (the name
    configs were written with before) loads as ``inverse_dynamics`` and is written back as
    the new name, so existing configs keep their generator."""
    assert DetectorConfig().residual.generator == "auto"
    old = tmp_path / "old.toml"
    old.write_text('[residual]\ngenerator = "rigid_model"\n', encoding="utf-8")
    cfg = load_config(old)
    assert cfg.residual.generator == "inverse_dynamics"
    save_config(cfg, tmp_path / "new.toml")
    assert 'generator = "inverse_dynamics"' in (tmp_path / "new.toml").read_text("utf-8")


def test_embedded_model_without_robot_survives_toml(tmp_path: Path) -> None:
    """A model with ``robot: null`` (identified with no --robot) embedded in a TOML config
    (TOML has no null) loads back equal, and a broken embedded model names the file."""
    model = json.loads(MODEL.read_text(encoding="utf-8"))
    model["robot"] = None
    cfg = DetectorConfig(model=model)
    save_config(cfg, tmp_path / "c.toml")
    assert "robot" not in (tmp_path / "c.toml").read_text(encoding="utf-8").split("[model")[0]
    assert load_config(tmp_path / "c.toml").model == cfg.model == _no_none(model)
    bad = tmp_path / "bad.toml"
    bad.write_text('[model]\nkind = "decoupled"\n', encoding="utf-8")
    with pytest.raises(ConfigError, match=r"bad\.toml: model: "):
        load_config(bad)


def test_example_file_is_valid() -> None:
    cfg = load_config(EXAMPLE)
    assert cfg.thresholds.v_stat == {"shoulder": 0.45, "elbow": 0.2}
    assert cfg.calibration.calibrated


BAD = [
    ("adaptive", "eta", 0, "adaptive/eta"),
    ("adaptive", "eta", 1.5, "adaptive/eta"),
    ("adaptive", "rho", [], "adaptive/rho"),
    ("adaptive", "rho", [2, 0], "adaptive/rho/1"),
    ("adaptive", "p", -1, "adaptive/p"),
    ("adaptive", "w1_hz", 0, "adaptive/w1_hz"),
    ("adaptive", "w2_hz", 5.0, "adaptive/w2_hz"),            # below w1 = 10 Hz
    ("adaptive", "n1_s", -0.04, "adaptive/n1_s"),
    ("adaptive", "n2_s", 0.01, "adaptive/n2_s"),             # below n1 = 40 ms
    ("adaptive", "forgetting_factor", 1.2, "adaptive/forgetting_factor"),
    ("adaptive", "forgetting_factor", 0, "adaptive/forgetting_factor"),
    ("adaptive", "p0", "ten", "adaptive/p0"),
    ("adaptive", "estimate", "sometimes", "adaptive/estimate"),
    ("adaptive", "tanh_slope", -1, "adaptive/tanh_slope"),
    ("adaptive", "max_trace", 0, "adaptive/max_trace"),
    ("adaptive", "lambda", 0.99, "adaptive"),                 # unknown key
    ("thresholds", "v_stat", {"j1": -0.1}, "thresholds/v_stat/j1"),
    ("thresholds", "v0", {"j1": "high"}, "thresholds/v0/j1"),
    ("thresholds", "vL", [1.0], "thresholds/vL"),
    ("static_loading", "cutoff_hz", -2, "static_loading/cutoff_hz"),
    ("static_loading", "order", 3, "static_loading/order"),
    ("residual", "generator", "magic", "residual/generator"),
    ("residual", "filter_torque", "yes", "residual/filter_torque"),
    ("events", "merge_gap_s", -1, "events/merge_gap_s"),
    ("events", "min_duration_s", "0", "events/min_duration_s"),
    ("warmup", "min_s", -3, "warmup/min_s"),
    ("warmup", "window_s", 0, "warmup/window_s"),
    ("calibration", "calibrated", 1, "calibration/calibrated"),
    ("calibration", "margin_rule", "guess", "calibration/margin_rule"),
    ("calibration", "logs", [{"path": "a.csv", "sha256": "xyz"}], "calibration/logs/0/sha256"),
    ("calibration", "model_sha256", "abc", "calibration/model_sha256"),
    ("calibration", "margins", {"adaptive": {"j1": 0}}, "calibration/margins/adaptive/j1"),
    ("calibration", "motion_envelope",  # a reversed range: every sample would be out
     {"source": "position_ref", "samples": 10,
      "joints": {"j1": {"measured_acceleration": [3.6, -4.0]}}},
     "calibration/motion_envelope/joints/j1/measured_acceleration"),
]


@pytest.mark.parametrize(("section", "key", "value", "where"), BAD)
def test_every_bad_value_is_a_config_error_naming_file_and_field(
    tmp_path: Path, section: str, key: str, value: object, where: str
) -> None:
    d = _full().to_dict()
    d.setdefault(section, {})[key] = value
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(d), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: {where}"), msg
    assert "\n" not in msg
    assert info.value.exit_code == 3


def test_bad_top_level_and_unparsable(tmp_path: Path) -> None:
    p = tmp_path / "c.toml"
    p.write_text("[adaptive]\neta = \n", encoding="utf-8")
    with pytest.raises(ConfigError, match="does not parse"):
        load_config(p)
    p.write_text("[detectors]\nx = 1\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="Additional properties"):
        load_config(p)
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "missing.toml")


def test_threshold_vector_in_joint_order() -> None:
    th = _full().thresholds
    np.testing.assert_array_equal(th.vector("v_stat", ("elbow", "shoulder")), [0.2, 0.45])
    assert DetectorConfig().thresholds.vector("v0", ("shoulder",)) is None
    with pytest.raises(ConfigError, match=r"cfg.toml: thresholds/vL: no value for joint\(s\) j3"):
        th.vector("vL", ("shoulder", "j3"), "cfg.toml")


def test_an_empty_config_file_is_an_error(tmp_path: Path) -> None:
    for name, text in (("e.toml", ""), ("e.yaml", "# nothing\n"), ("e.json", "{}")):
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        with pytest.raises(ConfigError, match=rf"{name}: the config is empty"):
            load_config(path)


def test_a_model_given_as_config_and_a_config_as_model_say_so(tmp_path: Path) -> None:
    from impactcli.errors import ModelError
    from impactcli.run.model_files import read_model

    with pytest.raises(ConfigError, match=r"model\.example\.json: this is a model .* --model"):
        load_config(MODEL)
    with pytest.raises(ModelError, match=r"config\.example\.toml: a model is the JSON .* --config"):
        read_model(EXAMPLE)


def test_threshold_joints_must_match_the_embedded_model(tmp_path: Path) -> None:
    repo = Path(__file__).resolve().parents[1]
    cfg = load_config(repo / "sample_logs" / "assist_like.config.toml")
    d = cfg.to_dict()
    d["thresholds"]["vL"] = {"shulder": 1.0, "elbow": 0.5}
    bad = tmp_path / "typo.json"
    bad.write_text(json.dumps(d), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"typo\.json: thresholds/vL: .*unknown: \['shulder'\]"
                                          r".*missing: \['shoulder'\]"):
        load_config(bad)


@pytest.mark.parametrize("key", ["regularization", "forgetting_factor", "p0", "tanh_slope"])
def test_a_nan_in_a_config_is_one_line_exit_3_naming_the_field(
        tmp_path: Path, key: str) -> None:
    """TOML's ``nan`` passes JSON Schema's number bounds; it is refused before any replay
    (it was an internal error, exit 70, with a traceback), and nothing is written."""
    from click.testing import CliRunner

    from impactcli.cli import main

    repo = Path(__file__).resolve().parents[1]
    lines = (repo / "sample_logs" / "assist_like.config.toml").read_text().splitlines()
    cfg = tmp_path / "c.toml"
    cfg.write_text("\n".join(f"{key} = nan" if ln.startswith(f"{key} = ") else ln
                             for ln in lines) + "\n")
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(repo / "sample_logs/csv/assist_free_p2p.csv.gz"),
                                  "--config", str(cfg), "-o", str(out)])
    assert r.exit_code == 3, r.output
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("impactcli: error:")]
    assert errors == [f"impactcli: error: {cfg}: adaptive/{key}: nan is not a number this "
                      "field can take"]
    assert "Traceback" not in r.output
    assert not out.exists() or not any(out.iterdir())
