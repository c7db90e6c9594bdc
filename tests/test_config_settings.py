"""A calibrated config records the detector settings its thresholds were set with
(``calibration.settings_sha256``); a config edited after ``calibrate`` says, where the user
reads the answer, that its thresholds and stated false-alarm rate are not for its settings
(a new user's trial, 2026-11-30: a hand-edited cut-off still read "calibrated: yes" with
the calibration's rate)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import (
    AdaptiveConfig,
    DetectorConfig,
    ResidualConfig,
    load_config,
    settings_changed,
    settings_sha256,
)
from impactcli.schema import validate

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
CONFIG = SAMPLES / "assist_like.config.toml"
LOG = SAMPLES / "csv" / "assist_free_p2p.csv.gz"


def test_the_fingerprint_follows_the_settings_and_nothing_else() -> None:
    cfg = load_config(CONFIG)
    assert cfg.calibration.settings_sha256 == settings_sha256(cfg)
    assert not settings_changed(cfg) and not settings_changed(cfg.to_dict())
    # a number written 2 or 2.0 is one setting; the generator choice is checked on its own
    d = cfg.to_dict()
    d["adaptive"]["eta"] = float(d["adaptive"]["eta"])
    d["residual"]["generator"] = "momentum_observer"
    assert settings_sha256(d) == settings_sha256(cfg)
    # thresholds and the calibration record are not settings
    assert settings_sha256(dataclasses.replace(cfg, calibration=DetectorConfig().calibration)) \
        == settings_sha256(cfg)
    edited = dataclasses.replace(cfg, adaptive=dataclasses.replace(cfg.adaptive, w2_hz=40.0))
    assert settings_sha256(edited) != settings_sha256(cfg) and settings_changed(edited)
    other = dataclasses.replace(cfg, residual=ResidualConfig(derivative_cutoff_hz=12.0))
    assert settings_changed(other)
    # an uncalibrated config, or one without the record, is never "changed"
    assert not settings_changed(DetectorConfig(adaptive=AdaptiveConfig(w2_hz=40.0)))
    old = dataclasses.replace(edited, calibration=dataclasses.replace(
        edited.calibration, settings_sha256=None))
    assert not settings_changed(old)


def test_a_config_edited_after_calibrate_says_its_rate_does_not_apply(tmp_path: Path) -> None:
    """The sample config with its F2 cut-off edited (50 → 40 Hz): detect warns, its
    thresholds line says they are not for these settings, and the report has the caveat
    and does not say that the stated rate applies; the unedited config says none of it."""
    text = CONFIG.read_text("utf-8")
    assert "w2_hz = 50.0" in text
    edited = tmp_path / "edited.toml"
    edited.write_text(text.replace("w2_hz = 50.0", "w2_hz = 40.0"), "utf-8")
    for cfg, changed in ((CONFIG, False), (edited, True)):
        out = tmp_path / f"o-{changed}"
        r = CliRunner().invoke(main, ["detect", str(LOG), "--config", str(cfg), "-o",
                                      str(out)])
        assert r.exit_code == 0, r.output
        assert ("edited after calibrate" in r.stderr) is changed, r.stderr
        line = next(ln for ln in r.stdout.splitlines() if ln.startswith("thresholds of"))
        assert ("NOT for these settings" in line) is changed, line
        # the table's calibrated column says it too (a trial read "calibrated yes" there)
        row = next(ln for ln in r.stdout.splitlines() if ln.startswith(LOG.name))
        assert row.split()[2] == ("edited" if changed else "yes"), row
        rep = tmp_path / f"r-{changed}.json"
        r = CliRunner().invoke(main, ["report", str(LOG), "--config", str(cfg), "-o",
                                      str(tmp_path / f"r-{changed}.html"), "--json",
                                      str(rep)])
        assert r.exit_code == 0, r.output
        doc = json.loads(rep.read_text("utf-8"))
        validate(doc, "report", AssertionError, "report")  # its caveat is the schema's
        codes = json.dumps(doc)
        assert ('"settings-changed"' in codes) is changed
        if changed:
            assert "stated false-alarm rate applies" not in codes


def test_a_threshold_edited_after_calibrate_says_its_rate_does_not_apply(
        tmp_path: Path) -> None:
    """A new user set one v_stat to 0 in a calibrated config: it ran, said "calibrated" and
    the predicted rate, and raised 11 adaptive events. The thresholds its calibration set
    are in its rate record: one that differs is said (which, and what it was), and the
    thresholds line says they are not for these settings. The unedited config says none of
    it, and a last-bit difference is no edit."""
    from impactcli.config import thresholds_edited

    cfg = load_config(CONFIG)
    assert thresholds_edited(cfg) == [] and not settings_changed(cfg)
    d = cfg.to_dict()
    was = d["thresholds"]["v_stat"]["elbow"]
    d["thresholds"]["v_stat"]["elbow"] = was * (1 + 1e-12)
    assert thresholds_edited(d) == []
    d["thresholds"]["v_stat"]["elbow"] = 0.0
    assert thresholds_edited(d) == [f"elbow v_stat 0 (calibrated {was:.4g})"]
    assert settings_changed(d)
    text = CONFIG.read_text("utf-8")
    line = next(ln for ln in text.splitlines() if ln.startswith("elbow = ")
                and abs(float(ln.split("=")[1]) - was) < 1e-15)
    edited = tmp_path / "zero.toml"
    edited.write_text(text.replace(line, "elbow = 0.0", 1), "utf-8")
    r = CliRunner().invoke(main, ["detect", str(LOG), "--config", str(edited), "-o",
                                  str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    assert (f"has thresholds other than those its calibration set (elbow v_stat 0 "
            f"(calibrated {was:.4g}): edited after calibrate)") in r.stderr, r.stderr
    head = next(ln for ln in r.stdout.splitlines() if ln.startswith("thresholds of"))
    assert "NOT for these settings" in head, head
