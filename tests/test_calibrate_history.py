"""Calibration from a robot's history: long logs cut into segments so leave-one-out works
on one log; labelled contacts in calibration logs left out; without labels, stretches that
alone would set a threshold reported as likely contacts and left out."""

from __future__ import annotations

import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import load_config
from impactcli.detect.thresholds import segment_bounds, suspect_blocks
from impactcli.logs import read_log
from impactcli.logs.robot_files import read_labels
from impactcli.run.calibration import calibrate
from impactcli.types import RobotLog

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs" / "csv"
FREE = ("assist_free_triangle", "assist_free_p2p", "assist_free_multisine")
NUM = r"[0-9]+(?:\.[0-9]+)?(?:e[-+]?[0-9]+)?"


def _read(name: str) -> RobotLog:
    return read_log(SAMPLES / f"{name}.csv.gz")


def test_segment_bounds_cut_long_stretches_only() -> None:
    assert segment_bounds(100, 1.0, 30.0) == [(0, 30), (30, 60), (60, 100)]
    assert segment_bounds(59, 1.0, 30.0) == [(0, 59)]
    bad, ratio = suspect_blocks(np.array([[1.0], [1.2], [0.8], [1.1], [25.0], [1.0], [0.9],
                                          [1.0], [1.05], [0.95]]))
    assert bad.tolist() == [False] * 4 + [True] + [False] * 5
    assert ratio[4] == pytest.approx(25.0 / 1.0)


def test_one_long_log_gets_a_leave_one_out_margin() -> None:
    import dataclasses

    a, b = _read("assist_free_p2p"), _read("assist_free_multisine")
    # one 80 s log: two free logs back to back on one clock
    cat = {f: np.concatenate([getattr(a, f), getattr(b, f)]) for f in
           ("position", "torque", "velocity", "current", "position_ref", "velocity_ref",
            "acceleration_ref", "torque_model", "torque_ext")}
    t = np.concatenate([a.t_ns, a.t_ns[-1] + 4_000_000 + (b.t_ns - b.t_ns[0])])
    long = dataclasses.replace(a, t_ns=t, **cat)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cfg = calibrate([long])
    c = cfg.calibration
    assert c.margin_rule == "leave-one-out" and c.segments == 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        one = calibrate([a]).calibration  # a 40 s log alone stays one piece
    assert one.margin_rule == "fixed-single-log" and one.segments == 1 and one.weak


def test_labels_beside_a_calibration_log_are_honoured(tmp_path: Path) -> None:
    free = [_read(n) for n in FREE]
    impacts = _read("assist_impacts")
    lab = read_labels(SAMPLES / "assist_impacts.labels.json")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        blind = calibrate([*free, impacts], drop_suspect=False)
        labelled = calibrate([*free, impacts], labels=[None, None, None, lab],
                             drop_suspect=False)
    ex = [x for x in labelled.calibration.excluded if x["reason"].startswith("labelled impact")]
    assert len(ex) == 15
    # unlabelled, the impacts set the thresholds (the detector goes blind); labelled, the
    # log's own free motion does, at a tenth or less
    for j in ("shoulder", "elbow"):
        assert labelled.thresholds.vL[j] < 0.1 * blind.thresholds.vL[j]


def test_contacts_in_free_logs_are_reported_and_left_out(tmp_path: Path) -> None:
    for n in FREE:
        shutil.copy(SAMPLES / f"{n}.csv.gz", tmp_path / f"{n}.csv.gz")
    shutil.copy(SAMPLES / "assist_pushes.csv.gz", tmp_path / "run7.csv.gz")  # no labels
    logs = [str(tmp_path / f"{n}.csv.gz") for n in FREE] + [str(tmp_path / "run7.csv.gz")]
    r = CliRunner().invoke(main, ["calibrate", *logs, "-o", str(tmp_path / "c.toml")])
    assert r.exit_code == 0, r.output
    warned = [ln for ln in r.stderr.splitlines() if "likely contact" in ln]
    assert warned, r.stderr
    for line in warned:  # the whole line; the numbers by pattern
        found = re.fullmatch(
            rf"impactcli: warning: {re.escape(logs[3])}: ({NUM})–({NUM}) s: alone it would "
            rf"set a threshold of (shoulder|elbow) ({NUM})× above the calibration's usual "
            r"level \(> 20×\): a likely contact; left out of the calibration \(give the "
            r"log's labels, or --keep-suspect to keep it\)", line)
        assert found, line
        start, end, ratio = float(found[1]), float(found[2]), float(found[4])
        assert 0 <= start < end <= 44.0 and ratio > 20
    assert "likely contact" not in r.stdout
    cfg = load_config(tmp_path / "c.toml")
    suspect = [x for x in cfg.calibration.excluded if "likely contact" in x["reason"]]
    assert suspect and all(x["log"].endswith("run7.csv.gz") for x in suspect)
    r = CliRunner().invoke(main, ["calibrate", *logs, "--keep-suspect",
                                  "-o", str(tmp_path / "k.toml")])
    assert r.exit_code == 0, r.output
    kept = load_config(tmp_path / "k.toml")
    for j in ("shoulder", "elbow"):  # kept, the pushes set the thresholds: the blind case
        assert kept.thresholds.vL[j] > 4 * cfg.thresholds.vL[j]
    # the committed calibration (three free logs) flags nothing
    r = CliRunner().invoke(main, ["calibrate", *logs[:3], "-o", str(tmp_path / "f.toml")])
    assert "likely contact" not in r.output


def test_labelled_contacts_beside_a_free_log_are_named(tmp_path: Path) -> None:
    """A labels file beside a calibration log (<stem>.labels.json, found without --labels):
    calibrate says how many contacts it leaves out and from which file, on stdout, and
    records the stretch in the config."""
    from impactcli.logs import write_log
    from impactcli.logs.robot_files import write_labels
    from impactcli.types import ContactLabel, Labels

    log_path = tmp_path / "shift3.csv"
    write_log(_read("assist_free_p2p").slice(0, 5000), log_path)  # 20 s
    labels_path = tmp_path / "shift3.labels.json"
    write_labels(Labels(events=(ContactLabel(start=8.0, end=8.3, peak_force=12.0, kind="push",
                                             link=2),), sample_rate=250.0), labels_path)
    r = CliRunner().invoke(main, ["calibrate", str(log_path), "-o", str(tmp_path / "c.toml")])
    assert r.exit_code == 0, r.output
    assert f"{log_path}: 1 labelled contact(s) left out ({labels_path})" in \
        r.stdout.splitlines()
    excluded = load_config(tmp_path / "c.toml").calibration.excluded
    assert [x["log"] for x in excluded if x["reason"].startswith("labelled")] == [str(log_path)]
