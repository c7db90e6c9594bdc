"""Batch jobs: transient-I/O retries, failure classes, the batch summary, atomic URL writes."""

from __future__ import annotations

import errno
import gzip
from pathlib import Path
from typing import Any

import pytest

from impactcli.errors import LogFormatError
from impactcli.logs import urls
from impactcli.run import batch
from impactcli.run.batch import DetectJob, JobOutcome, SummaryRow, batch_summary, run_detect_job


@pytest.fixture(autouse=True)
def _no_backoff(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(urls, "BACKOFF_S", 0.0)


@pytest.mark.parametrize(("err", "transient"), [
    (TimeoutError("read timed out"), True),
    (ConnectionResetError(errno.ECONNRESET, "reset"), True),
    (OSError(errno.EIO, "I/O error"), True),
    (FileNotFoundError(errno.ENOENT, "nope"), False),
    (PermissionError(errno.EACCES, "denied"), False),
    (gzip.BadGzipFile("Not a gzipped file"), False),  # an OSError, but the data is bad
    (OSError("Failed to interpret file as a pickle"), False),  # numpy: no errno, bad data
    (ValueError("bad"), False),
])
def test_is_transient(err: BaseException, transient: bool) -> None:
    assert urls.is_transient(err) is transient


def test_is_transient_looks_through_the_cause() -> None:
    try:
        try:
            raise TimeoutError("slow store")
        except TimeoutError as inner:
            raise LogFormatError("s3://b/x.mcap: cannot fetch: slow store") from inner
    except LogFormatError as err:
        assert urls.is_transient(err)


def test_retry_transient_retries_then_gives_up() -> None:
    calls: list[int] = []

    def flaky() -> str:
        calls.append(1)
        if len(calls) < 3:
            raise ConnectionResetError(errno.ECONNRESET, "reset")
        return "ok"

    assert urls.retry_transient(flaky) == "ok" and len(calls) == 3
    calls.clear()

    def dead() -> None:
        calls.append(1)
        raise TimeoutError("never")

    with pytest.raises(TimeoutError):
        urls.retry_transient(dead)
    assert len(calls) == urls.IO_RETRIES + 1
    calls.clear()

    def missing() -> None:
        calls.append(1)
        raise FileNotFoundError("gone")

    with pytest.raises(FileNotFoundError):
        urls.retry_transient(missing)
    assert len(calls) == 1  # never retried


def _job(tmp_path: Path) -> DetectJob:
    return DetectJob(str(tmp_path / "x.csv"), str(tmp_path / "out"))


def test_job_retries_transient_errors(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    calls: list[int] = []
    summary = _row("x", 7200.0, 0, 1, 0, 2)

    def run(job: DetectJob) -> Any:
        calls.append(1)
        if len(calls) < 3:
            raise LogFormatError(f"{job.log_path}: cannot fetch") from TimeoutError("slow")
        return ("a.timeline.json",), summary, (), findings

    findings = batch.Findings("x", 7200.0, 1.0, (), (), ())
    monkeypatch.setattr(batch, "_run", run)
    out = run_detect_job(_job(tmp_path))
    assert out.ok and out.attempts == 3 and out.summary == summary
    assert out.findings == findings


def test_job_failure_classes(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    def timeout(job: DetectJob) -> Any:
        raise TimeoutError(errno.ETIMEDOUT, "timed out")

    monkeypatch.setattr(batch, "_run", timeout)
    out = run_detect_job(_job(tmp_path))
    assert (out.ok, out.error_class, out.exit_code, out.attempts) == (
        False, "io", 3, urls.IO_RETRIES + 1)
    assert out.error.startswith(str(tmp_path / "x.csv")) and "retries" in out.error

    def bug(job: DetectJob) -> Any:
        raise KeyError("oops")

    monkeypatch.setattr(batch, "_run", bug)
    out = run_detect_job(_job(tmp_path))
    assert (out.error_class, out.exit_code, out.attempts) == ("internal", 70, 1)
    assert "KeyError" in out.error and "Traceback" in out.traceback


def test_a_missing_log_is_a_data_error(tmp_path: Path) -> None:
    out = run_detect_job(_job(tmp_path))
    assert (out.ok, out.error_class, out.exit_code) == (False, "data", 3)
    assert out.error == f"{tmp_path / 'x.csv'}: log file not found"


def _row(log: str, duration_s: float, incidents: int, adaptive: int, loading: int,
         baseline: int) -> SummaryRow:
    """A finished log's summary row with these counts (the rest as for a quiet log)."""
    return {"log": log, "sha256": "0" * 64, "model_source": "given", "model_sha256": None,
            "duration_s": duration_s, "joints": 2, "calibrated": True, "links": "robot",
            "torque_scale": "ok", "detection_floor": None, "warmup_end_s": 1.0,
            "generators": {}, "generator_reasons": {}, "incidents": incidents,
            "incident_list": [], "defect_incident_list": [], "lasting_load_list": [],
            "adaptive": adaptive, "static_loading": loading, "static_baseline": baseline}


def test_batch_summary_totals() -> None:
    rows = [JobOutcome("a.csv", True, _row("a.csv", 1800.0, 1, 2, 1, 0)),
            JobOutcome("b.csv", True, _row("b.csv", 5400.0, 2, 0, 3, 4)),
            JobOutcome("c.csv", False, error="c.csv: corrupt", exit_code=3, error_class="data")]
    doc = batch_summary(rows, wall_s=4.0)
    assert doc["logs"] == {"total": 3, "done": 2, "failed": 1, "not_run": 0}
    assert doc["events"] == {"adaptive": 2, "static_loading": 4, "static_baseline": 4}
    assert doc["incidents"] == 3
    assert [r["log"] for r in doc["results"]] == ["a.csv", "b.csv"]
    assert doc["hours_analysed"] == pytest.approx(2.0)
    assert doc["throughput"] == {"logs_per_s": 0.5, "log_hours_per_s": 0.5}
    assert doc["failures"] == [{"file": "c.csv", "reason": "c.csv: corrupt", "exit_code": 3,
                                "class": "data", "attempts": 1}]


def test_put_file_atomic_to_a_url_leaves_no_part(tmp_path: Path) -> None:
    import fsspec

    fs = fsspec.filesystem("memory")
    src = tmp_path / "a.json"
    src.write_text('{"a": 1}')
    try:
        urls.put_file_atomic(src, "memory://bkt/deep/a.json")
        assert fs.cat("/bkt/deep/a.json") == b'{"a": 1}'
        assert fs.ls("/bkt/deep", detail=False) == ["/bkt/deep/a.json"]
        urls.put_file_atomic(src, f"file://{tmp_path}/sub/b.json")
        assert (tmp_path / "sub" / "b.json").read_text() == '{"a": 1}'
        assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["b.json"]
    finally:
        fs.rm("/bkt", recursive=True)


def test_local_path_and_names() -> None:
    assert urls.local_path("file:///data/a%20b.csv") == Path("/data/a b.csv")
    assert urls.local_path("s3://bucket/a.csv") is None
    assert urls.local_path("rel/a.csv") == Path("rel/a.csv")
    assert batch.log_stem("s3://bucket/day1/run7.csv.gz") == "run7"
    assert urls.join_url("s3://b/out/", "x.json") == "s3://b/out/x.json"


def test_detect_out_that_is_a_file_is_a_usage_error(tmp_path: Path) -> None:
    """``-o`` naming an existing regular file: exit 2 naming -o, before any log is read,
    and the file is left as it was."""
    from click.testing import CliRunner

    from impactcli.cli import main

    target = tmp_path / "taken"
    target.write_text("keep", encoding="utf-8")
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "missing.csv"), "-o", str(target)])
    assert r.exit_code == 2
    assert "'-o'" in r.stderr and "exists and is not a folder" in r.stderr
    assert "missing.csv" not in r.stderr and "Traceback" not in r.stderr
    assert target.read_text(encoding="utf-8") == "keep"


def test_debug_shows_a_failed_logs_traceback_in_a_batch(tmp_path: Path) -> None:
    """A bad log in a batch: one error line without --debug; its traceback with it."""
    from click.testing import CliRunner

    from impactcli.cli import main

    bad = tmp_path / "bad.csv"
    bad.write_text("time,j1.position\nnot,a number\n", encoding="utf-8")
    args = ["detect", str(bad), str(tmp_path / "gone.csv"), "-o", str(tmp_path / "out")]
    plain = CliRunner().invoke(main, args)
    assert plain.exit_code == 3  # every log failed: the failures' own code
    assert "2 of 2 logs failed" in plain.stderr
    assert "Traceback" not in plain.stderr
    assert sum(line.startswith("impactcli: error: ") for line in plain.stderr.splitlines()) == 2
    ok = CliRunner().invoke(main, [*args, str(Path(__file__).resolve().parents[1]
                                            / "sample_logs/csv/assist_free_p2p.csv.gz")])
    assert ok.exit_code == 4 and "2 of 3 logs failed" in ok.stderr  # some failed
    debug = CliRunner().invoke(main, ["--debug", *args])
    assert debug.exit_code == 3
    assert debug.stderr.count("Traceback (most recent call last)") == 2


def test_a_time_gap_is_warned_about_in_the_terminal_and_the_timeline(tmp_path: Path) -> None:
    """25 samples cut out of a collision-free sample log (a 104 ms step at 4 ms): the run
    goes on, says where the gap is, and names the event that starts right after it. (A
    44 ms cut made an alarm with plain eq. 39; the regularised evaluator rides it out.)"""
    import json

    from click.testing import CliRunner

    from impactcli.cli import main

    repo = Path(__file__).resolve().parents[1]
    lines = gzip.decompress(
        (repo / "sample_logs/csv/assist_free_multisine.csv.gz").read_bytes()).split(b"\n")
    path = tmp_path / "gap.csv"
    path.write_bytes(b"\n".join(lines[:1999] + lines[2024:]))
    r = CliRunner().invoke(main, ["detect", str(path), "--config",
                                  str(repo / "sample_logs/assist_like.config.toml"),
                                  "-o", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    assert "1 time gap(s)" in r.stderr and "longest 104 ms after 7.988 s" in r.stderr
    tl = json.loads((tmp_path / "out" / "gap.timeline.json").read_text())
    assert any("time gap" in w for w in tl["warnings"])
    near = [e for e in tl["events"] if 8.092 <= e["t_start"] <= 8.592]
    assert near, "the cut makes an alarm right after the gap (what the warning is for)"
    assert f"{near[0]['detector']} at {near[0]['t_start']:.3f} s" in r.stderr


@pytest.mark.parametrize("verb", ["report", "identify", "calibrate", "report-json"])
def test_an_output_under_a_file_is_one_line_exit_2_and_nothing_written(
        tmp_path: Path, verb: str) -> None:
    """-o (or --json) whose folder path runs through a regular file: exit 2 before any
    work, one line naming the path, no traceback, no other output left behind."""
    from click.testing import CliRunner

    from impactcli.cli import main

    repo = Path(__file__).resolve().parents[1]
    log = str(repo / "sample_logs" / "csv" / "assist_free_p2p.csv.gz")
    block = tmp_path / "afile"
    block.write_text("", encoding="utf-8")
    args = {
        "report": ["report", log, "-o", str(block / "r.html")],
        "identify": ["identify", log, "-o", str(block / "m.json")],
        "calibrate": ["calibrate", log, "-o", str(block / "c.toml")],
        "report-json": ["report", log, "-o", str(tmp_path / "r.html"),
                        "--json", str(block / "r.json")],
    }[verb]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, r.output
    bad = args[-1]
    lines = [ln for ln in r.stderr.splitlines() if not ln.startswith("impactcli: warning")]
    assert lines == [f"impactcli: error: cannot write {bad}: "
                     "a part of its folder path is a file, not a folder"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_a_log_shorter_than_the_warm_up_is_a_data_error(tmp_path: Path) -> None:
    """10 samples: exit 3 naming the file, the length and the warm-up; nothing written."""
    from click.testing import CliRunner

    from impactcli.cli import main

    repo = Path(__file__).resolve().parents[1]
    text = gzip.decompress((repo / "sample_logs/csv/assist_free_p2p.csv.gz").read_bytes())
    short = tmp_path / "ten.csv"
    short.write_bytes(b"\n".join(text.split(b"\n")[:11]) + b"\n")
    r = CliRunner().invoke(main, ["detect", str(short), "-o", str(tmp_path / "out")])
    assert r.exit_code == 3
    assert f"{short}: 10 samples (0.036 s), shorter than the detectors' warm-up" in r.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("extra", [["-o", "{f}/sub"], ["-o", "{d}/out", "--summary", "{f}/s.json"]])
def test_detect_outputs_are_checked_before_any_log_is_read(tmp_path: Path,
                                                           extra: list[str]) -> None:
    from click.testing import CliRunner

    from impactcli.cli import main

    f = tmp_path / "afile"
    f.write_text("", encoding="utf-8")
    args = [a.format(f=f, d=tmp_path) for a in extra]
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "missing.csv"), *args])
    assert r.exit_code == 2, r.output
    assert "missing.csv" not in r.stderr and "Traceback" not in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_timeline_says_how_the_threshold_inputs_were_made() -> None:
    """The ROS 2 MCAP copy of a log has no acceleration reference: its inputs differ from
    the CSV copy's, and each timeline says how they were made."""
    from impactcli.logs import read_log
    from impactcli.outputs.timeline import timeline_dict
    from impactcli.run.collect import detect_in_memory

    repo = Path(__file__).resolve().parents[1] / "sample_logs"
    details = {}
    for fmt, name in (("csv", "assist_free_p2p.csv.gz"), ("mcap", "assist_free_p2p.mcap")):
        res, _ = detect_in_memory(read_log(repo / fmt / name))
        details[fmt] = timeline_dict(res)["replay"]["threshold_inputs"]
    assert details["csv"] == "velocity_ref and acceleration_ref as logged"
    assert details["mcap"].startswith("velocity_ref as logged; acceleration by causal")


def test_a_failed_remote_upload_leaves_no_outputs(monkeypatch: pytest.MonkeyPatch) -> None:
    """Outputs under a URL prefix: the timeline is uploaded last (its presence says the run
    is complete); when an upload fails, the files already uploaded are removed and the
    job fails with the upload's error."""
    import fsspec

    sample = Path(__file__).resolve().parents[1] / "sample_logs"
    real = urls.put_file_atomic

    def put(local: Any, target: str) -> None:
        if target.endswith(".timeline.json"):
            raise OSError(errno.EIO, "store went away")
        real(local, target)

    monkeypatch.setattr(urls, "put_file_atomic", put)
    fs = fsspec.filesystem("memory")
    job = DetectJob(log_path=str(sample / "csv" / "heavy_impacts.csv.gz"),
                    out_dir="memory://failing/out", robot_path=None, model_path=None,
                    config_path=str(sample / "heavy_geared.config.toml"), signals=True)
    out = run_detect_job(job)
    assert not out.ok and "store went away" in (out.error or "")
    assert not fs.exists("/failing/out") or fs.ls("/failing/out", detail=False) == []


def test_summary_row_is_the_schema_row() -> None:
    """The typed row the batch passes holds exactly the schema's per-log fields (but the
    two the batch adds), and a row of them validates."""
    import typing

    from impactcli.schema import load_schema, validate

    item = load_schema("batch_summary")["properties"]["results"]["items"]
    keys = set(typing.get_type_hints(SummaryRow))
    assert keys | {"outputs", "attempts"} == set(item["properties"])
    doc = batch_summary([JobOutcome("a.csv", True, _row("a.csv", 60.0, 0, 0, 0, 0))],
                        wall_s=1.0)
    validate(doc, "batch_summary", LogFormatError, "summary")
