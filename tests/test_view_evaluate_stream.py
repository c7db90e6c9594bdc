"""`impactcli view LOG` and `impactcli evaluate LOG` replay the log chunk by chunk
(impactcli.run.job.run_log_from_paths, bounded memory) and give what the writers fed the replay's
chunks give, whatever the chunk size: the same Rerun recording's rows, the same evaluation
and sweep, with and without a config; the run never reads the log whole, leaves no spill
file behind, and writes nothing when the log turns bad midway."""

from __future__ import annotations

import json
import tempfile
import warnings
from pathlib import Path
from typing import Any

import pytest

from .cli_run import invoke
from .helpers import bad_midway_csv, rrd_rows

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
ASSIST = SAMPLES / "assist_like.config.toml"
HEAVY = SAMPLES / "heavy_geared.config.toml"


def _replayed(path: Path, cfg: Path | None, on_chunk: Any, rows: int = 997) -> Any:
    """The replay of ``path`` in chunks of ``rows`` (not the CLI's), its chunks handed to
    ``on_chunk``: the reference."""
    from impactcli.config import load_config
    from impactcli.logs.reader import open_log
    from impactcli.run.one_log import RunSetup, detect_log

    setup = RunSetup(config=None if cfg is None else load_config(cfg), chunk_rows=rows)
    with warnings.catch_warnings(), open_log(path) as reader:
        warnings.simplefilter("ignore")
        return detect_log(reader, setup, on_chunk=on_chunk)


def _warned(result: Any) -> str:
    """The stderr of a verb that prints the run's warnings and nothing else."""
    return "".join(f"impactcli: warning: {w}\n" for w in result.warnings)


def _forbid_whole_log(monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib

    def refuse(*a: object, **k: object) -> None:
        raise AssertionError("whole-log path taken")

    for mod, name in (("impactcli.run.collect", "detect_in_memory"),
                      ("impactcli.logs", "read_log")):
        try:
            m = importlib.import_module(mod)
        except ImportError:
            continue
        if hasattr(m, name):
            monkeypatch.setattr(m, name, refuse)


@pytest.fixture
def private_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A temporary folder of this test's own (others' runs write spills to /tmp too)."""
    d = tmp_path / "tmp"
    d.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(d))
    return d


@pytest.mark.parametrize(("log", "cfg"), [("assist_impacts", ASSIST), ("assist_pushes", None)])
def test_view_streams_the_recording(tmp_path: Path, private_tmp: Path,
                                    monkeypatch: pytest.MonkeyPatch, log: str,
                                    cfg: Path | None) -> None:
    from impactcli.outputs.rerun import RerunWriter

    path = SAMPLES / "csv" / f"{log}.csv.gz"
    opts = ["--no-open", "--max-points", "1500", "--event-window", "0.3"]
    opts += ["--config", str(cfg)] if cfg is not None else []
    with RerunWriter() as w:
        ref = _replayed(path, cfg, w)
        w.write(ref, tmp_path / "ref.rrd", max_points=1500, event_window_s=0.3)
    with monkeypatch.context() as m:
        _forbid_whole_log(m)
        r2 = invoke(["view", str(path), *opts, "--save", str(tmp_path / "stream.rrd")])
        assert r2.exit_code == 0, r2.output
    assert r2.stdout == f"{tmp_path / 'stream.rrd'}\n"
    assert r2.stderr == _warned(ref)  # the run's warnings
    a, b = rrd_rows(tmp_path / "ref.rrd"), rrd_rows(tmp_path / "stream.rrd")
    decimated = [k for k in a if "/rms" in k and not k.startswith("static")]
    assert decimated and all(len(a[k]) < 20_000 for k in decimated)  # --max-points reached
    assert any(k.startswith("/joints/") and k.endswith(("/adaptive", "/static_loading"))
               for k in a)  # markers
    assert a == b
    assert not list(private_tmp.glob("impactcli-*"))


@pytest.mark.parametrize(("log", "cfg", "scales"), [
    ("assist_impacts", ASSIST, None),            # the default scales
    ("heavy_impacts", HEAVY, "0.5:3:x1.1"),
    ("assist_clamps", None, "0.2:3:x1.1"),       # uncalibrated: the model from the log
])
def test_evaluate_streams_the_evaluation(tmp_path: Path, private_tmp: Path,
                                                   monkeypatch: pytest.MonkeyPatch, log: str,
                                                   cfg: Path | None,
                                                   scales: str | None) -> None:
    path = SAMPLES / "csv" / f"{log}.csv.gz"
    args = ["evaluate", str(path), "--json", "--sweep"]
    args += ["--config", str(cfg)] if cfg is not None else []
    args += ["--scales", scales] if scales is not None else []
    from impactcli.cli.evaluate import DEFAULT_SCALES, parse_scales
    from impactcli.logs.reader import scan_log
    from impactcli.logs.robot_files import read_labels
    from impactcli.outputs.report.samples import ReportCollector
    from impactcli.quality.evaluation import evaluate_result
    from impactcli.quality.match import MatchTolerance
    from impactcli.quality.text import format_evaluation
    from impactcli.quality.verdict import format_sweep, sweep_to_dict

    scan = scan_log(str(path))
    col = ReportCollector(scan.n_samples, plots=False)
    getattr(scan, "close", lambda: None)()  # the scan's cache of the rows, if any
    ref = _replayed(path, cfg, col)
    samples = col.finish(ref)
    labels = read_labels(SAMPLES / "csv" / f"{log}.labels.json")
    tol = MatchTolerance(pre_s=0.02, post_s=0.25)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ev = evaluate_result(ref, labels, tolerance=tol)
            rows = samples.sweep(ref, labels, parse_scales(scales or DEFAULT_SCALES),
                                 tolerance=tol)
    finally:
        samples.close()
    doc = {**ev.to_dict(), "input": str(path), "sweep": sweep_to_dict(rows)}
    want_stdout = json.dumps(doc, sort_keys=True, indent=1, allow_nan=False) + "\n"
    want_text = format_evaluation(ev) + "\n" + format_sweep(rows)
    with monkeypatch.context() as m:
        _forbid_whole_log(m)
        got = invoke(args)
        got_text = invoke([a for a in args if a != "--json"])
        plain = invoke([a for a in args if a != "--sweep"])
    assert got.exit_code == 0, got.output
    doc = json.loads(got.stdout)
    assert doc["sweep"]["rows"] and doc["n_contacts"]["counted"] > 0
    assert got.stdout == want_stdout
    assert got.stderr == _warned(ref)
    assert got_text.stdout == want_text
    # without --sweep: no collector, the same evaluation
    assert plain.exit_code == 0, plain.output
    doc.pop("sweep")
    assert json.loads(plain.stdout) == doc
    assert not list(private_tmp.glob("impactcli-*"))  # the spill files are removed


def test_a_log_bad_midway_leaves_nothing(tmp_path: Path, private_tmp: Path) -> None:
    """A cell that is not a number far into the file: one line, exit 3, no recording kept
    and no spill file left (view --save; evaluate --sweep)."""
    bad = bad_midway_csv(tmp_path)
    out = tmp_path / "bad.rrd"
    r = invoke(["view", str(bad), "--config", str(ASSIST), "--no-open", "--save", str(out)])
    assert r.exit_code == 3, r.output
    assert "bad.csv" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists() and not list(tmp_path.glob("*.rrd*"))
    r = invoke(["evaluate", str(bad), "--config", str(ASSIST), "--sweep", "--labels",
              str(SAMPLES / "csv" / "assist_impacts.labels.json")])
    assert r.exit_code == 3, r.output
    assert not list(private_tmp.glob("impactcli-*"))
