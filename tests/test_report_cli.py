"""``impactcli report`` through click's CliRunner.

The wiring (labels pairing, batch failures, timeline re-runs, exit codes) is tested with a
stand-in for the replay (:func:`impactcli.run.job.run_log`) that returns the synthetic
result on the log actually read; one end-to-end test runs the real replay.
"""

from __future__ import annotations

import dataclasses
import json
import re
import types
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from click.testing import CliRunner, Result

from impactcli.cli import main
from impactcli.errors import LogFormatError
from impactcli.logs import read_log  # type: ignore[attr-defined]
from impactcli.logs.robot_files import write_labels
from impactcli.logs.write import write_csv
from impactcli.outputs.timeline import write_timeline
from impactcli.schema import load_schema
from impactcli.types import ContactLabel, Labels, ReadOptions

from .cli_run import invoke
from .conftest import make_log
from .fakes import collect, fake_result

N = 2500  # fake_result's length: its log is make_log(N)


def show(res: Result) -> str:
    return f"exit {res.exit_code}\nstdout:\n{res.stdout}\nstderr:\n{res.stderr}"


@pytest.fixture
def fake_pipeline(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """Replace the replay (impactcli.run.job.run_log): the synthetic result on the log it
    is given, read as the replay reads it (its sha256 checked as the scan's), and its
    report's samples collected from its chunks."""
    calls: list[dict[str, Any]] = []

    def stream_log(log_path: str, *, robot: Any = None, model: Any = None, config: Any = None,
                   read_options: ReadOptions | None = None, allow_slow: bool = False,
                   check: Any = None, **kw: Any) -> Any:
        log = read_log(Path(log_path), robot=robot, **(read_options or ReadOptions()).as_dict())
        if check is not None:
            check(types.SimpleNamespace(source=log.source))
        calls.append({"log": log, "model": model, "config": config, "robot": robot,
                      "read_options": read_options, "allow_slow": allow_slow})
        result = dataclasses.replace(fake_result(), log=log)
        return result, collect(result)  # its chunks collected as the replay's would be

    monkeypatch.setattr("impactcli.run.job.run_log", stream_log)
    return calls


def write_log(path: Path) -> Path:
    write_csv(make_log(n=N), path)
    return path


def test_report_on_logs_with_labels_and_json(tmp_path: Path, fake_pipeline: list) -> None:
    a = write_log(tmp_path / "arm_a.csv")
    sub = tmp_path / "b"
    sub.mkdir()
    b = write_log(sub / "arm_b.csv")
    # auto-discovered labels beside arm_b; none for arm_a
    truth = Labels((ContactLabel(3.99, 4.12, 12.0, "impact", 2),), 250.0)
    write_labels(truth, sub / "arm_b.labels.json")
    out, js = tmp_path / "out" / "report.html", tmp_path / "out" / "report.json"
    res = invoke(["report", str(a), str(b), "-o", str(out), "--json", str(js)])
    assert res.exit_code == 0, show(res)
    html = out.read_text("utf-8")
    doc = json.loads(js.read_text("utf-8"))
    jsonschema.validate(doc, load_schema("report"))
    assert [s["stem"] for s in doc["summary"]] == ["arm_a", "arm_b"]
    assert doc["logs"][0]["quality"] is None
    assert doc["logs"][1]["labels"]["path"].endswith("arm_b.labels.json")
    for log in doc["logs"]:
        assert log["input"]["sha256"] in html and len(log["input"]["sha256"]) == 64
    # the header's false alarms are alarm events, said as such (the incidents group them)
    prod = doc["logs"][1]["quality"]["evaluation"]["detectors"]["product"]
    assert (f'{prod["detected"]}/{prod["n_contacts"]} hit, {prod["false_alarms"]} '
            "false-alarm events (alarm events matching no contact") in html
    assert len(fake_pipeline) == 2
    # same command again: byte-identical JSON and HTML
    out2, js2 = tmp_path / "r2.html", tmp_path / "r2.json"
    assert invoke(["report", str(a), str(b), "-o", str(out2), "--json", str(js2)]).exit_code == 0
    assert js2.read_bytes() == js.read_bytes()
    assert out2.read_bytes() == out.read_bytes()
    # --no-auto-labels drops the discovered file
    res = invoke(["report", str(a), str(b), "-o", str(out2), "--json", str(js2),
                  "--no-auto-labels"])
    assert json.loads(js2.read_text())["logs"][1]["labels"] is None, show(res)


def test_labels_on_a_link_the_arm_lacks_are_bad_input(tmp_path: Path,
                                                      fake_pipeline: list) -> None:
    """A labelled contact on link 7 of the 2-joint arm: one line naming the labels file and
    both counts, exit 3, no report written (the trial's "7 / 2 WRONG")."""
    a = write_log(tmp_path / "arm_a.csv")
    lab = tmp_path / "arm_a.labels.json"
    write_labels(Labels((ContactLabel(3.99, 4.12, 12.0, "impact", 7),), 250.0), lab)
    out = tmp_path / "r.html"
    res = invoke(["report", str(a), "-o", str(out)])
    assert res.exit_code == 3, show(res)
    assert f"{lab}: event 0 (from 0) is on link 7, but {a}'s arm has 2 link(s)" in res.stderr
    assert not out.exists()


def test_labels_count_mismatch_is_a_usage_error(tmp_path: Path, fake_pipeline: list) -> None:
    a, b = write_log(tmp_path / "a.csv"), write_log(tmp_path / "b.csv")
    lab = tmp_path / "truth.json"
    write_labels(Labels((), 250.0), lab)
    res = invoke(["report", str(a), str(b), "-o", str(tmp_path / "r.html"), "--labels", str(lab)])
    assert res.exit_code == 2, show(res)
    assert "--labels" in res.stderr
    assert not fake_pipeline  # refused before any work


def test_batch_with_a_failing_input_exits_4(tmp_path: Path, fake_pipeline: list,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    good = write_log(tmp_path / "good.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("time,j1.position\n0,0\n")
    import impactcli.run.job

    real = impactcli.run.job.run_log

    def stream_log(path: str, **kw: Any) -> Any:
        if path.endswith("bad.csv"):
            raise LogFormatError(f"{path}: column 'j1.torque' missing")
        return real(path, **kw)

    monkeypatch.setattr(impactcli.run.job, "run_log", stream_log)
    out, js = tmp_path / "r.html", tmp_path / "r.json"
    res = invoke(["report", str(good), str(bad), "-o", str(out), "--json", str(js)])
    assert res.exit_code == 4, show(res)
    assert "column 'j1.torque' missing" in res.stderr
    doc = json.loads(js.read_text())
    assert [s["stem"] for s in doc["summary"]] == ["good"]
    assert doc["failed"][0]["path"].endswith("bad.csv")
    assert "could not be analysed" in out.read_text()
    # every input failing: the first error, exit 3, nothing written
    res = invoke(["report", str(bad), "-o", str(tmp_path / "none.html")])
    assert res.exit_code == 3, show(res)
    assert not (tmp_path / "none.html").exists()


def test_report_on_a_timeline_reruns_it(tmp_path: Path, fake_pipeline: list) -> None:
    (tmp_path / "logs").mkdir()
    log_path = write_log(tmp_path / "logs" / "run7.csv")
    first = dataclasses.replace(fake_result(), log=read_log(log_path))
    tl = tmp_path / "det" / "run7.timeline.json"
    tl.parent.mkdir()
    write_timeline(first, tl)
    out, js = tmp_path / "r.html", tmp_path / "r.json"
    res = invoke(["report", str(tl), "-o", str(out), "--json", str(js)])
    assert res.exit_code == 0, show(res)
    assert "warning" not in res.stderr, show(res)  # the re-run matches the recorded events
    doc = json.loads(js.read_text())
    assert doc["logs"][0]["stem"] == "run7"
    assert doc["logs"][0]["input"]["sha256"] == first.log.source.sha256
    recorded = json.loads(tl.read_text())["events"]
    assert [(e["t_start"], e["detector"]) for e in doc["logs"][0]["events"]] == \
        [(e["t_start"], e["detector"]) for e in recorded]
    assert fake_pipeline[-1]["config"] is not None  # the recorded config was used
    res = invoke(["report", str(tl), "-o", str(out), "--channel-map", "kuka_lwr4"])
    assert res.exit_code == 0, show(res)
    assert "--channel-map apply to LOG inputs only" in res.stderr
    assert fake_pipeline[-1]["read_options"] == ReadOptions()  # as recorded, not the command line's
    # the log changed since detection: refused, exit 3
    with log_path.open("a") as f:
        f.write("\n")
    res = invoke(["report", str(tl), "-o", str(out)])
    assert res.exit_code == 3, show(res)
    assert re.search(r"changed since detection", res.stderr), show(res)


def test_report_end_to_end_with_the_pipeline(tmp_path: Path) -> None:
    """LOG → report, and LOG → detect → TIMELINE → report: the same JSON, byte for byte."""
    log = write_log(tmp_path / "e2e.csv")
    out, js = tmp_path / "r.html", tmp_path / "r.json"
    res = CliRunner().invoke(main, ["report", str(log), "-o", str(out), "--json", str(js)])
    assert res.exit_code == 0, show(res)
    assert "uncalibrated" in res.stderr
    doc = json.loads(js.read_text())
    jsonschema.validate(doc, load_schema("report"))
    html = out.read_text()
    sec = doc["logs"][0]
    assert sec["input"]["sha256"] in html
    for k in range(1, len(sec["events"]) + 1):
        assert f'id="log1-ev{k}"' in html
    assert "uncalibrated" in {c["code"] for c in sec["caveats"]}
    assert sec["model"]["source"] == "identified-from-log"
    # through a timeline
    det = tmp_path / "det"
    res = CliRunner().invoke(main, ["detect", str(log), "-o", str(det)])
    assert res.exit_code == 0, show(res)
    js2 = tmp_path / "r2.json"
    res = CliRunner().invoke(main, ["report", str(det / "e2e.timeline.json"), "-o",
                                    str(tmp_path / "r2.html"), "--json", str(js2)])
    assert res.exit_code == 0, show(res)
    assert "re-running detection gave" not in res.stderr, show(res)
    # the same facts; only the origin says the second came from a timeline
    doc2 = json.loads(js2.read_text())
    assert doc["logs"][0]["origin"] is None
    origin = doc2["logs"][0].pop("origin")
    assert origin["timeline_schema_version"] == "2.12" and origin["timeline"].endswith(
        "e2e.timeline.json")
    doc["logs"][0].pop("origin")
    assert doc2 == doc


def test_report_on_a_1_0_timeline_says_what_it_cannot_tell(tmp_path: Path,
                                                          fake_pipeline: list) -> None:
    """A timeline written before incidents (schema 1.0) is re-run and reported; the report
    says the file itself records no incidents."""
    log_path = write_log(tmp_path / "old7.csv")
    tl = tmp_path / "old7.timeline.json"
    write_timeline(dataclasses.replace(fake_result(), log=read_log(log_path)), tl)
    doc = json.loads(tl.read_text())
    doc["schema_version"] = "1.0"
    doc["tool"]["version"] = "0.0.9"
    for key in ("incidents",):
        doc.pop(key, None)
    for key in ("joints_left_out", "abs_path"):
        doc["input"].pop(key, None)
    doc["replay"].pop("generator", None)
    tl.write_text(json.dumps(doc))
    out, js = tmp_path / "r.html", tmp_path / "r.json"
    res = invoke(["report", str(tl), "-o", str(out), "--json", str(js)])
    assert res.exit_code == 0, show(res)
    sec = json.loads(js.read_text())["logs"][0]
    assert sec["origin"]["timeline_schema_version"] == "1.0"
    assert sec["origin"]["recorded_by"] == "impactcli 0.0.9"
    assert sec["origin"]["recorded_incidents"] is None
    older = [c for c in sec["could_not_see"] if c["code"] == "older-timeline"]
    assert older and "records no incidents" in older[0]["text"]
    assert "This log came as a timeline of schema 1.0" in out.read_text()


@pytest.mark.parametrize(("args", "named"), [
    (["-o", "r.pdf"], "r.pdf: the report is HTML: name it .html"),
    (["-o", "r.html", "--json", "r2.html"], "r2.html: --json writes JSON: name it .json"),
])
def test_an_output_named_for_another_format_is_a_usage_error_before_any_work(
        tmp_path: Path, args: list[str], named: str) -> None:
    """A trial's `report ... -o r.pdf` wrote HTML into a .pdf file, exit 0. Now exit 2,
    one line naming the file, and nothing written."""
    r = invoke("report", "sample_logs/csv/assist_pushes.csv.gz",
               *[str(tmp_path / a) if a.endswith((".pdf", ".html")) else a for a in args])
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"impactcli: error: {tmp_path}/{named}")
    assert list(tmp_path.iterdir()) == []


def test_report_reads_the_folder_detect_wrote(tmp_path: Path) -> None:
    """A trial gave `report` the folder `detect -o` had written and read "a folder without
    any log" (exit 3). A folder with no log stands for the timelines in it; an empty one
    is still that error."""
    out = tmp_path / "out"
    r = invoke("detect", "sample_logs/csv/assist_pushes.csv.gz",
               "sample_logs/csv/assist_clamps.csv.gz", "--config",
               "sample_logs/assist_like.config.toml", "-o", str(out))
    assert r.exit_code == 0, r.output
    js = tmp_path / "r.json"
    r = invoke("report", str(out), "-o", str(tmp_path / "r.html"), "--json", str(js))
    assert r.exit_code == 0, r.output
    doc = json.loads(js.read_text("utf-8"))
    assert [x["stem"] for x in doc["logs"]] == ["assist_clamps", "assist_pushes"]
    empty = tmp_path / "empty"
    empty.mkdir()
    r = invoke("report", str(empty), "-o", str(tmp_path / "e.html"))
    assert r.exit_code == 3 and "a folder without any log" in r.stderr, r.output
