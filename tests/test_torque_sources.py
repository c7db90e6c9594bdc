"""Both torque sources judged alike (impactcli/run/torque_sources.py), through ``inspect``
and ``calibrate``: a log whose ``.torque`` is worse than its ``.current`` names
``--torque-source current``; one whose two sources differ only by what the model holds
(a torque sensor after the motor's friction) names nothing; one whose ``.torque`` is the
converted current says so and fits nothing."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import numpy as np
import pyarrow.csv as pacsv
import pytest

from .cli_run import cli

REPO = Path(__file__).resolve().parents[1]
LOG = REPO / "sample_logs" / "csv" / "assist_free_multisine.csv.gz"
ROBOT = REPO / "sample_logs" / "csv" / "assist_free_multisine.robot.json"
JOINTS = ("shoulder", "elbow")


def _variant(tmp_path: Path, name: str, change) -> Path:
    """The sample log with its ``.torque`` columns changed by ``change(table, joint)``."""
    table = pacsv.read_csv(LOG).to_pandas()
    for j in JOINTS:
        table[f"{j}.torque"] = change(table, j)
    out = tmp_path / f"{name}.csv"
    table.to_csv(out, index=False)
    return out


def _sources(log: Path, *extra: object) -> tuple[dict, str]:
    code, out, err = cli("inspect", log, "--robot", ROBOT, "--json", *extra)
    assert code == 0, err
    d = json.loads(out)
    jsonschema.validate(d, json.loads((REPO / "schemas" / "inspect.schema.json").read_text()))
    return d["torque_sources"], err


@pytest.fixture(scope="module")
def noisy(tmp_path_factory) -> Path:
    """``.torque`` = the converted current plus white noise of 2 N·m: a worse sensor."""
    rng = np.random.default_rng(7)
    return _variant(tmp_path_factory.mktemp("noisy"), "noisy", lambda t, j: t[f"{j}.torque"]
                    + rng.normal(0.0, 2.0, len(t)))


def test_a_worse_torque_names_the_current(noisy: Path) -> None:
    s, _ = _sources(noisy)
    assert (s["in_use"], s["other"], s["same"], s["reason"]) == ("torque", "current", False,
                                                                 None)
    assert set(s["joints"]) == set(JOINTS)
    for e in s["joints"].values():
        assert e["other_clearly_better"] and e["other_rms_nm"] < e["in_use_rms_nm"] / 5
    code, out, err = cli("inspect", noisy, "--robot", ROBOT)
    assert code == 0 and "--torque-source current" in err and ".current clearly better" in out


def _advice(log: Path, *extra: object) -> str:
    """inspect's stderr (its warnings) without --json."""
    code, _, err = cli("inspect", log, "--robot", ROBOT, *extra)
    assert code == 0, err
    return err


def test_reading_the_better_source_names_nothing(noisy: Path) -> None:
    s, _ = _sources(noisy, "--torque-source", "current")
    assert (s["in_use"], s["other"]) == ("current", "torque")
    assert set(s["joints"]) == set(JOINTS)
    assert not any(e["other_clearly_better"] for e in s["joints"].values())
    assert "--torque-source" not in _advice(noisy, "--torque-source", "current")


def test_calibrate_says_it_beside_its_fit(noisy: Path, tmp_path: Path) -> None:
    code, out, err = cli("calibrate", noisy, "--robot", ROBOT, "-o", tmp_path / "c.toml")
    assert code == 0, err
    assert "torque sources: .torque and .current are both logged" in out
    assert "consider --torque-source current" in err


def test_a_sensor_after_the_friction_is_not_judged_worse(tmp_path: Path) -> None:
    """A link-side sensor: the motor torque less a viscous and Coulomb friction of the
    model's own form (on the logged velocity, where the model uses its own estimate) —
    what the rigid model identifies either way, up to that difference; neither source is
    clearly better, read from either."""
    def link_side(t, j):
        qd = t[f"{j}.velocity"]
        return t[f"{j}.torque"] - 0.4 * qd - 0.3 * np.tanh(qd / 0.01)

    log = _variant(tmp_path, "link_side", link_side)
    for source in ("torque", "current"):
        s, _ = _sources(log, "--torque-source", source)
        assert not s["same"] and s["reason"] is None and set(s["joints"]) == set(JOINTS)
        assert not any(e["other_clearly_better"] for e in s["joints"].values()), s
        assert "--torque-source" not in _advice(log, "--torque-source", source)


def test_one_source_fits_nothing() -> None:
    s, _ = _sources(LOG)
    assert s["same"] and s["joints"] == {} and s["kind"] is None


def test_without_a_robot_it_says_what_is_needed() -> None:
    code, out, err = cli("inspect", LOG, "--json")
    assert code == 0, err
    reason = json.loads(out)["torque_sources"]["reason"]
    assert "--robot" in reason and "torque_constant" in reason


def test_a_joint_one_source_lacks_is_said_not_misread(tmp_path: Path) -> None:
    """A dead torque sensor (an all-NaN ``.torque`` column) drops its joint from the
    ``.torque`` read but not from the ``.current`` one: said, not fitted."""
    table = pacsv.read_csv(LOG).to_pandas()
    table["elbow.torque"] = np.nan
    log = tmp_path / "dead_sensor.csv"
    table.to_csv(log, index=False)
    s, _ = _sources(log)
    assert s["joints"] == {} and "a joint one source does not log" in s["reason"]


def test_a_long_log_is_not_read_whole_by_inspect(monkeypatch) -> None:
    from impactcli.run import torque_sources

    monkeypatch.setattr(torque_sources, "INSPECT_MAX_VALUES", 1000)
    s, _ = _sources(LOG)
    assert s["joints"] == {} and "too long to compare here" in s["reason"]


def test_a_log_with_one_source_says_nothing(tmp_path: Path) -> None:
    table = pacsv.read_csv(LOG).to_pandas()
    log = tmp_path / "torque_only.csv"
    table.drop(columns=[f"{j}.current" for j in JOINTS]).to_csv(log, index=False)
    code, out, err = cli("inspect", log, "--robot", ROBOT, "--json")
    assert code == 0, err
    assert "torque_sources" not in json.loads(out)


HEAVY = REPO / "sample_logs" / "csv"


@pytest.fixture(scope="module")
def on_current(tmp_path_factory) -> Path:
    """A config calibrated on the heavy arm's free logs read through ``.current`` (its
    residual is the tool's own model, which reads the torque)."""
    cfg = tmp_path_factory.mktemp("on_current") / "c.toml"
    code, _, err = cli("calibrate", HEAVY / "heavy_free_p2p.csv.gz",
                       HEAVY / "heavy_free_triangle.csv.gz", "--robot",
                       HEAVY / "heavy_free_p2p.robot.json", "--torque-source", "current",
                       "-o", cfg)
    assert code == 0, err
    return cfg


def test_the_config_records_each_logs_torque_source(on_current: Path) -> None:
    from impactcli.config import load_config

    logs = load_config(on_current).calibration.logs
    assert [lg.torque_source for lg in logs] == ["current", "current"]


def test_detect_warns_of_a_log_read_from_another_source(on_current: Path,
                                                        tmp_path: Path) -> None:
    """The default rule reads the audited log's ``.torque``; its thresholds were set on
    ``.current``: said, with the option that reads it as calibrated — and not said then."""
    log = HEAVY / "heavy_impacts.csv.gz"
    code, _, err = cli("detect", log, "--config", on_current, "-o", tmp_path / "a")
    assert code == 0, err
    said = [ln for ln in err.splitlines() if "calibrated on .current" in ln]
    assert len(said) == 1 and "its torque is read from .torque" in said[0]
    assert "both its calibration logs" in said[0] and "--torque-source current" in said[0]
    timeline = json.loads((tmp_path / "a" / "heavy_impacts.timeline.json").read_text())
    assert any("calibrated on .current" in w for w in timeline["warnings"])
    code, _, err = cli("detect", log, "--config", on_current, "--torque-source", "current",
                       "-o", tmp_path / "b")
    assert code == 0, err
    assert "calibrated on .current" not in err


def test_calibration_logs_read_from_two_sources_are_warned_of() -> None:
    import warnings

    from impactcli.errors import ImpactWarning
    from impactcli.run.run_warnings import warn_mixed_torque_sources

    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        warn_mixed_torque_sources([("a.csv", "torque"), ("b.csv", "torque")])
        assert got == []
        warn_mixed_torque_sources([("a.csv", "torque"), ("b.csv", "current"),
                                   ("c.csv", "torque")])
    assert len(got) == 1 and got[0].category is ImpactWarning
    text = str(got[0].message)
    assert ".current in b.csv; .torque in a.csv, c.csv" in text and "--torque-source" in text
