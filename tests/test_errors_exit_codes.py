"""Crashes are not collisions: exit 1 means "incidents found" to a CI gate. A value that
would overflow the computation is a data error naming the cell (exit 3); any internal
error (a bug) exits 70 (EX_SOFTWARE) with its traceback, in one-log runs and in batches."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from impactcli.errors import EXIT_SOFTWARE, LogFormatError
from impactcli.logs import describe as io_inspect
from impactcli.logs import read_log, write_log
from impactcli.run import batch
from impactcli.schema import validate

from .cli_run import cli

REPO = Path(__file__).resolve().parents[1]
LOG = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"


def _small_csv(tmp_path: Path, name: str = "x.csv") -> tuple[Path, list[str]]:
    path = tmp_path / name
    write_log(read_log(LOG).slice(0, 3000), path)
    return path, path.read_text(encoding="utf-8").splitlines(keepends=True)


def _set_cell(lines: list[str], row: int, column: str, value: str) -> None:
    """Set data row ``row`` (0-based) of ``column`` to ``value``."""
    col = lines[0].rstrip("\n").split(",").index(column)
    cells = lines[row + 1].rstrip("\n").split(",")
    cells[col] = value
    lines[row + 1] = ",".join(cells) + "\n"


def test_exit_70_is_documented_in_help() -> None:
    code, out, _ = cli("--help")
    assert code == 0
    assert "70 an internal error (a bug; its traceback is printed)" in " ".join(out.split())
    code, out, _ = cli("detect", "--help")
    assert "70 on an internal error (a bug, with its traceback) — never 1" in " ".join(
        out.split())


@pytest.mark.parametrize("value", ["1e300", "-2.5e13"])
def test_a_huge_torque_cell_is_a_data_error_naming_it(tmp_path: Path, value: str) -> None:
    path, lines = _small_csv(tmp_path)
    _set_cell(lines, 1234, "elbow.torque", value)
    path.write_text("".join(lines), encoding="utf-8")
    code, _, err = cli("detect", str(path), "--fail-on-detect", "-o", str(tmp_path / "out"))
    assert code == 3
    assert err.splitlines() == [
        f"impactcli: error: {path}: column 'elbow.torque', row 1235 (line 1236): value "
        f"{float(value):g} is beyond ±1e+12: no joint measures that (a corrupt cell, or a unit "
        "far off)"]
    assert not (tmp_path / "out" / "x.timeline.json").exists()


def test_a_huge_value_in_an_mcap_is_the_same_error(tmp_path: Path) -> None:
    log = read_log(LOG).slice(0, 3000)
    pos = np.array(log.position)
    pos[77, 0] = 3e15
    import dataclasses

    path = tmp_path / "big.mcap"
    write_log(dataclasses.replace(log, position=pos), path)
    with pytest.raises(LogFormatError) as e:
        read_log(path)
    assert str(e.value) == (
        f"{path}: column 'shoulder.position', message 77 of '/joint_samples': value 3e+15 is "
        "beyond ±1e+12: no joint measures that (a corrupt cell, or a unit far off)")


def test_the_short_nan_repair_stays(tmp_path: Path) -> None:
    path, lines = _small_csv(tmp_path)
    for r in (500, 501):
        _set_cell(lines, r, "shoulder.torque", "nan")
    path.write_text("".join(lines), encoding="utf-8")
    code, out, err = cli("inspect", str(path), "--json")
    assert code == 0, err
    assert json.loads(out)["repairs"] == [
        f"{path}: column 'shoulder.torque': interpolated 2 non-finite value(s) in 1 gap(s) "
        "(first at row 501 (line 502))"]


def _boom(*_: Any, **__: Any) -> Any:
    raise RuntimeError("boom")


def test_a_bug_in_a_one_log_run_exits_70_with_its_traceback(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from impactcli.run import job

    monkeypatch.setattr(job, "detect_log", _boom)   # the replay detect runs
    code, _, err = cli("detect", str(LOG), "--fail-on-detect", "-o", str(tmp_path / "out"))
    assert code == EXIT_SOFTWARE == 70
    lines = err.splitlines()
    assert f"impactcli: error: {LOG}: internal error (a bug): RuntimeError: boom" in lines
    assert "Traceback (most recent call last):" in lines and lines[-1] == "RuntimeError: boom"


def test_a_bug_in_a_verb_exits_70_with_its_traceback(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(io_inspect, "describe_log", _boom)
    for debug in ([], ["--debug"]):
        code, out, err = cli(*debug, "inspect", str(LOG))
        assert code == 70 and out == ""
        lines = err.splitlines()
        assert lines[0] == "impactcli: error: internal error (a bug): RuntimeError: boom"
        assert lines[1] == "Traceback (most recent call last):"
        assert lines[-1] == "RuntimeError: boom"


def test_a_data_error_with_debug_keeps_its_exit_code(tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time,j.position,j.torque\n0,1,2\n", encoding="utf-8")
    code, _, err = cli("--debug", "inspect", str(bad))
    assert code == 3
    assert "Traceback (most recent call last):" in err
    assert err.splitlines()[-1] == (f"impactcli: error: {bad}: holds 1 data row(s); at least "
                                    "2 are needed")


def test_a_bug_in_a_batch_is_70_in_the_summary_and_4_for_the_batch(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from impactcli.run import job

    other = tmp_path / "other.csv"
    write_log(read_log(LOG), other)
    real = job.detect_log

    def flaky(reader: Any, *a: Any, **kw: Any) -> Any:
        if reader.scan().source.path == str(other):
            raise ZeroDivisionError("division by zero")
        return real(reader, *a, **kw)

    monkeypatch.setattr(job, "detect_log", flaky)
    summary = tmp_path / "summary.json"
    code, _, err = cli("detect", str(LOG), str(other), "--config", str(CONFIG), "-o",
                       str(tmp_path / "out"), "--summary", str(summary))
    assert code == 4, err
    fail = json.loads(summary.read_text())["failures"]
    assert fail == [{"file": str(other), "attempts": 1, "class": "internal", "exit_code": 70,
                     "reason": f"{other}: internal error (a bug): ZeroDivisionError: division "
                               "by zero"}]
    # every log failed: the failure's own code, 70 (never 1)
    code, _, _ = cli("detect", str(other), "--config", str(CONFIG), "-o", str(tmp_path / "o"))
    assert code == 70


def test_a_lost_worker_is_70() -> None:
    job = batch.DetectJob("x.csv", "out")
    out = batch.lost_outcome(job, "its worker process died", "worker-lost")
    assert (out.exit_code, out.error_class) == (70, "worker-lost")
    assert batch.EXIT_CRASH == 70


# ------------------------------------------------------------------ gates fail closed
IMPACTS = REPO / "sample_logs" / "csv" / "assist_impacts.csv.gz"


def test_a_log_that_is_all_warm_up_is_not_judged_by_fail_on_detect() -> None:
    """A log whose warm-up covers all of it (its ``warmup_end_s`` past its duration:
    nothing after warm-up analysed) is named as not judged — exit 5 — not passed as "no
    incident"; one sample after warm-up is judged. (The CLI refuses logs shorter than
    ``warmup.min_s`` up front, exit 3; this is the gate's own rule for any other way.)"""
    from impactcli.run.gates import Findings, judge

    def lines(warmup_end_s: float, duration_s: float) -> tuple[list[str], list[str]]:
        f = Findings("/data/run7.csv", duration_s, warmup_end_s, (), (), ())
        return judge([f], fail_on_detect=True, fail_on_force=None)

    failing, [line] = lines(3.004, 3.0)
    assert not failing and "run7.csv: --fail-on-detect could not judge it" in line
    assert "no time after warm-up was analysed" in line and "exit 5" in line
    assert lines(3.0, 3.0) == ([], [])  # its last sample is after warm-up


def test_fail_on_force_says_when_no_single_force_fits() -> None:
    """An incident whose torques are no single force at its link's end has no force:
    --fail-on-force cannot judge it (exit 5), and its line says that reason beside the
    others (docs/incidents.md, "One force at the link's end?")."""
    from types import SimpleNamespace

    from impactcli.detect.force import NO_SINGLE_FORCE
    from impactcli.run.gates import Findings, judge

    unfit = SimpleNamespace(t_start=11.938, force_n=None,
                            force_method=f"{NO_SINGLE_FORCE} 3 gives the residuals: …")
    f = Findings("/data/run7.csv", 60.0, 3.0, (unfit,), (), ())
    failing, [line] = judge([f], fail_on_detect=False, fail_on_force=20.0)
    assert not failing and "could not judge 1 incident (the first at 11.938 s)" in line
    assert "for 1, no single force at the link's end gives the residuals" in line, line


def _config_without_kinematics(tmp_path: Path) -> Path:
    """The sample config with its robot's kinematics cut out: incidents get no force."""
    text = CONFIG.read_text(encoding="utf-8")
    a = text.index("[model.robot.kinematics]")
    b = text.index("\n[", a + 1)
    path = tmp_path / "nokin.config.toml"
    path.write_text(text[:a] + text[b + 1:], encoding="utf-8")
    return path


def test_fail_on_force_without_kinematics_is_5_and_a_judged_failure_wins(
        tmp_path: Path) -> None:
    """Incidents without a force estimate (a model without kinematics): --fail-on-force
    cannot judge them (5, the log and the first such incident named); with
    --fail-on-detect beside it the incidents are judged (1 wins); with the kinematics the
    forces are known and judged: 1 below them; above them all, 5 — every impact of the
    sample log, the arm near stretched, is marked ≳ (part of its force turns no joint),
    which no limit bounds."""
    out = str(tmp_path / "out")
    nokin = str(_config_without_kinematics(tmp_path))
    code, _, err = cli("detect", str(IMPACTS), "--config", nokin,
                       "--fail-on-force", "20", "-o", out)
    assert code == 5, err
    assert "assist_impacts.csv.gz: --fail-on-force 20 N could not judge" in err
    assert "no force estimate" in err
    code, _, err = cli("detect", str(IMPACTS), "--config", nokin,
                       "--fail-on-force", "20", "--fail-on-detect", "-o", out)
    assert code == 1, err
    assert "--fail-on-detect:" in err and "incidents after warm-up" in err
    code, _, err = cli("detect", str(IMPACTS), "--config", str(CONFIG),
                       "--fail-on-force", "1", "-o", out)
    assert code == 1, err
    code, _, err = cli("detect", str(IMPACTS), "--config", str(CONFIG),
                       "--fail-on-force", "1e6", "-o", out)
    assert code == 5 and "--fail-on-force 1e+06 N could not judge the forces of 15 " \
        "incidents (≳" in err, err


def test_exit_5_is_documented() -> None:
    _, out, _ = cli("--help")
    assert "5 a gate could not judge" in " ".join(out.split())
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert "| 5 | a gate could not judge" in readme


def test_a_truncated_recording_is_judged_up_to_its_cut_and_said(tmp_path: Path) -> None:
    """A sample MCAP cut at two thirds (a recorder killed): detect reads what came before
    the cut and warns; the timeline says ``input.truncated`` and the terminal's table row
    ``cut`` beside the duration; a gate could not judge what
    the file does not hold (exit 5, one line naming the cut); the report's verdict and its
    "could not see" list say so. The whole file says none of it."""
    from click.testing import CliRunner

    from impactcli.cli import main

    repo = Path(__file__).resolve().parents[1]
    full = repo / "sample_logs" / "mcap" / "assist_free_p2p.mcap"
    config = repo / "sample_logs" / "assist_like.config.toml"
    cut = tmp_path / "cut.mcap"
    data = full.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    r = CliRunner().invoke(main, ["detect", str(cut), "--config", str(config), "-o",
                                  str(tmp_path / "o"), "--fail-on-detect"])
    tl = json.loads((tmp_path / "o" / "cut.timeline.json").read_text())
    end = tl["input"]["duration_s"]
    assert tl["input"]["truncated"] is True and tl["counts"]["incidents"]["counted"] == 0
    assert r.exit_code == 5, r.output
    row = [ln for ln in r.stdout.splitlines() if ln.startswith("cut.mcap ")]
    assert len(row) == 1 and f"{end:.1f} cut" in row[0], r.stdout  # the table's row says it
    assert "(cut: the file is truncated — its recording went on after that;" in r.stdout
    assert (f"impactcli: cut.mcap: --fail-on-detect could not judge the recording after "
            f"{end:.3f} s: the file is truncated (its records end early), so what was "
            "recorded after that is not in it; exit 5") in r.stderr.splitlines()
    r = CliRunner().invoke(main, ["report", str(tmp_path / "o" / "cut.timeline.json"), "-o",
                                  str(tmp_path / "r.html"), "--json", str(tmp_path / "r.json")])
    assert r.exit_code == 0, r.output
    one = json.loads((tmp_path / "r.json").read_text())["logs"][0]
    assert one["verdict"].endswith(
        f"The file is truncated: its recording went on after {end:.1f} s, and what it held "
        "after that is not in it, so was not analysed.")
    assert [u["short"] for u in one["could_not_see"] if u["code"] == "truncated"] == [
        f"file cut at {end:.1f} s"]
    r = CliRunner().invoke(main, ["detect", str(full), "--config", str(config), "-o",
                                  str(tmp_path / "w"), "--fail-on-detect"])
    assert r.exit_code == 0, r.output
    whole = json.loads((tmp_path / "w" / "assist_free_p2p.timeline.json").read_text())
    assert "truncated" not in whole["input"] and "truncated" not in r.stderr
    assert "(cut:" not in r.stdout
    # a log with contacts before its cut fails the gate: exit 1, and the cut's line says
    # that a judged failure wins (it read "exit 5" beside exit 1)
    hits = tmp_path / "hits.mcap"
    data = (repo / "sample_logs" / "mcap" / "assist_impacts.mcap").read_bytes()
    hits.write_bytes(data[: len(data) * 2 // 3])
    r = CliRunner().invoke(main, ["detect", str(hits), "--config", str(config), "-o",
                                  str(tmp_path / "h"), "--fail-on-detect"])
    assert r.exit_code == 1, r.output
    cut_line = [ln for ln in r.stderr.splitlines() if "could not judge the recording" in ln]
    assert len(cut_line) == 1 and cut_line[0].endswith(
        "; exit 5 — a judged failure wins: exit 1"), cut_line


def test_evaluate_says_labels_after_a_cut_are_the_cut_s(tmp_path: Path) -> None:
    """A cut MCAP's labels after its end are the recording the file lost, not another
    log's: evaluate's warning says the file is truncated (it asked "labels of another
    log?"); the whole file's labels, shifted past its end, still ask."""
    from click.testing import CliRunner

    from impactcli.cli import main

    repo = Path(__file__).resolve().parents[1]
    mcap = repo / "sample_logs" / "mcap"
    config = repo / "sample_logs" / "assist_like.config.toml"
    hits = tmp_path / "hits.mcap"
    data = (mcap / "assist_impacts.mcap").read_bytes()
    hits.write_bytes(data[: len(data) * 2 // 3])
    labels = mcap / "assist_impacts.labels.json"
    r = CliRunner().invoke(main, ["detect", str(hits), "--config", str(config), "-o",
                                  str(tmp_path / "h")])
    timeline = tmp_path / "h" / "hits.timeline.json"
    r = CliRunner().invoke(main, ["evaluate", str(timeline), "--labels", str(labels)])
    assert r.exit_code == 0, r.output
    line = [ln for ln in r.stderr.splitlines() if "start after the log's end" in ln]
    assert len(line) == 1 and line[0].endswith(
        "not counted (the file is truncated: its recording went on after its end, and the "
        "file does not hold those contacts)"), r.stderr
    doc = json.loads(labels.read_text("utf-8"))
    for e in doc["events"]:
        e["start"] += 1000.0
        e["end"] += 1000.0
    moved = tmp_path / "moved.labels.json"
    moved.write_text(json.dumps(doc), "utf-8")
    whole = CliRunner().invoke(main, ["detect", str(mcap / "assist_impacts.mcap"), "--config",
                                      str(config), "-o", str(tmp_path / "w")])
    assert whole.exit_code == 0, whole.output
    r = CliRunner().invoke(main, ["evaluate", str(tmp_path / "w" / "assist_impacts.timeline.json"),
                                  "--labels", str(moved)])
    # every contact after the log's end: nothing to score, bad input (a trial's labels in
    # milliseconds passed as "0 counted", exit 0); one contact inside: the others warned of
    assert r.exit_code == 3, r.output
    assert r.stderr.strip().splitlines()[-1] == (
        f"impactcli: error: {moved}: every one of its 15 contact(s) starts after the log's "
        "end (72.7 s), first at 1012 s: the labels of another log, or times not in "
        "seconds since the log's first sample (milliseconds?) — nothing to score"), r.stderr
    doc["events"][0]["start"] -= 1000.0
    doc["events"][0]["end"] -= 1000.0
    moved.write_text(json.dumps(doc), "utf-8")
    r = CliRunner().invoke(main, ["evaluate", str(tmp_path / "w" / "assist_impacts.timeline.json"),
                                  "--labels", str(moved)])
    assert r.exit_code == 0, r.output
    assert "(labels of another log?)" in r.stderr and "truncated" not in r.stderr, r.stderr


def test_a_batch_with_a_failed_log_still_says_the_gate_the_others_tripped(
        tmp_path: Path) -> None:
    """A trial's batch of a log with incidents and a missing file under --fail-on-detect:
    exit 4 (a failed log wins), and before, stderr said only "1 of 2 logs failed" — not that
    the other log tripped the gate. Its line is now said, naming the code that won."""
    missing = tmp_path / "gone.csv"
    log = LOG.with_name("assist_pushes.csv.gz")
    summary = tmp_path / "s.json"
    code, _, err = cli("detect", str(log), str(missing), "--config", str(CONFIG), "-o",
                       str(tmp_path / "out"), "--fail-on-detect", "--summary", str(summary))
    assert code == 4, err
    # the summary holds what the gates found and the code (a trial found neither there)
    doc = json.loads(summary.read_text("utf-8"))
    validate(doc, "batch_summary", AssertionError, "summary")
    gates = doc["gates"]
    assert (gates["exit_code"], gates["fail_on_detect"], gates["fail_on_force_n"]) == (
        4, True, None)
    assert len(gates["failing"]) == 1 and "--fail-on-detect" in gates["failing"][0]
    assert doc["stopped"] is False and doc["logs"] == {"total": 2, "done": 1, "failed": 1,
                                                        "not_run": 0}
    tl = json.loads((tmp_path / "out" / "assist_pushes.timeline.json")
                    .read_text("utf-8"))
    n = sum(1 for i in tl["incidents"] if i["number"] is not None)
    assert n > 0
    assert (f"impactcli: {log.name}: --fail-on-detect: {n} incident{'s' if n > 1 else ''} "
            "after warm-up — a log that failed wins: exit 4") in err.splitlines(), err
    assert "1 of 2 logs failed" in err


def test_a_current_only_log_is_read_with_the_configs_robot(tmp_path: Path) -> None:
    """A trial's current-only log, detected with its config as README step 3 writes it,
    stopped with "joint 'j1' has only current; … needs a robot description (--robot)",
    though the config's model holds the robot with its gear ratios and torque constants.
    The model's robot now turns the current into torque: the same incidents as the log
    with its torque (the sample logs' current × gear ratio × torque constant is their
    torque)."""
    import pandas as pd

    src = tmp_path / "currents.csv"
    frame = pd.read_csv(IMPACTS)
    frame.drop(columns=[c for c in frame.columns if c.endswith(".torque")]).to_csv(
        src, index=False)
    code, _, err = cli("detect", str(src), "--config", str(CONFIG), "-o",
                       str(tmp_path / "c"))
    assert code == 0, err
    code, _, err = cli("detect", str(IMPACTS), "--config", str(CONFIG), "-o",
                       str(tmp_path / "t"))
    assert code == 0, err
    docs = [json.loads(p.read_text("utf-8")) for p in
            (tmp_path / "c" / "currents.timeline.json",
             tmp_path / "t" / "assist_impacts.timeline.json")]
    assert docs[0]["input"]["torque_source"] == "current"
    assert [round(i["t_start"], 3) for i in docs[0]["incidents"]] == \
        [round(i["t_start"], 3) for i in docs[1]["incidents"]]
