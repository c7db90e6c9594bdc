"""The replay without calibrated thresholds: the model identified from the log in chunks,
the uncalibrated thresholds from the replay's spilled statistics, and the answer of the log
in memory (one chunk), byte for byte, whatever the chunking."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli import files
from impactcli.cli import main
from impactcli.config import DetectorConfig, load_config
from impactcli.detect.thresholds import BlockMaxima, block_maxima
from impactcli.logs import read_log
from impactcli.logs.reader import open_log
from impactcli.model import rows as rows_mod
from impactcli.outputs.timeline import timeline_json
from impactcli.run.collect import detect_in_memory
from impactcli.run.one_log import RunSetup, detect_log
from impactcli.types import DetectionResult

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
ASSIST = SAMPLES / "assist_like.config.toml"


def _pair(path: Path, rows: int, config: DetectorConfig | None = None,
          model_from_log: bool = False) -> tuple[str, str, DetectionResult]:
    """The timelines of the log in memory (one chunk) and from its file in chunks."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole, _ = detect_in_memory(read_log(path), config=config,
                                    model_from_log=model_from_log)
        with open_log(path) as reader:
            got = detect_log(reader, RunSetup(config=config, model_from_log=model_from_log,
                                              chunk_rows=rows))
    return timeline_json(whole), timeline_json(got), whole


@pytest.mark.parametrize(("log", "rows", "events"), [
    ("assist_clamps", 997, True),       # boundaries inside every event
    ("assist_pushes", 4096, True),      # a boundary inside the warm-up
    ("assist_impacts", 997, False),     # no event uncalibrated (the rule's 3 × quantile)
    ("heavy_impacts", 1500, False),
    ("assist_pushes", 10**7, True),     # one chunk
    ("assist_clamps", 2048, True),
])
def test_no_config_chunked_is_byte_identical(log: str, rows: int, events: bool) -> None:
    a, b, whole = _pair(SAMPLES / "csv" / f"{log}.csv.gz", rows)
    assert whole.model_source == "identified-from-log"
    assert not whole.calibrated
    assert bool(whole.events) == events
    assert a == b


def test_identification_spans_many_chunks_and_windows(monkeypatch: pytest.MonkeyPatch) -> None:
    """Windows of the identification's filters smaller than the log, chunks smaller than
    the windows: still the whole-log answer (which uses the same windows)."""
    monkeypatch.setattr(rows_mod, "WINDOW", 2_000)
    monkeypatch.setattr(rows_mod, "ROW_WINDOW", 300)
    a, b, _ = _pair(SAMPLES / "csv" / "assist_impacts.csv.gz", 777)
    assert a == b


def test_model_from_log_with_a_calibrated_config_streams() -> None:
    cfg = load_config(ASSIST)   # logged channels with the correction model: identified
    a, b, whole = _pair(SAMPLES / "csv" / "assist_impacts.csv.gz", 1234, config=cfg,
                        model_from_log=True)
    assert whole.model_source == "identified-from-log"
    assert whole.calibrated
    assert any("--model-from-log" in w for w in whole.warnings)
    assert a == b


def test_everything_streams_but_model_with_model_from_log(tmp_path: Path) -> None:
    """``--model`` with ``--model-from-log`` is refused with one line, before the log is
    read: a ConfigError (exit 3) from the library and a batch job, a usage error (exit 2)
    from the command line."""
    from impactcli.errors import ConfigError
    from impactcli.model import identify
    from impactcli.run.batch import DetectJob, run_detect_job
    from impactcli.run.model_files import write_model

    log = SAMPLES / "csv" / "assist_impacts.csv.gz"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = identify(read_log(log))
    setup = RunSetup(config=load_config(ASSIST), model=model, model_from_log=True)
    with pytest.raises(ConfigError, match=r"^--model and --model-from-log exclude each other$"):
        detect_log(open_log(tmp_path / "not-read.csv"), setup)
    path = tmp_path / "m.json"
    write_model(model, path)
    out = run_detect_job(DetectJob(str(log), str(tmp_path / "out"), model_path=str(path),
                                   config_path=str(ASSIST), model_from_log=True))
    assert not out.ok and out.exit_code == 3 and out.error_class == "data"
    assert out.error == "--model and --model-from-log exclude each other"
    res = CliRunner().invoke(main, ["detect", str(log), "--model", str(path),
                                    "--model-from-log", "-o", str(tmp_path / "o2")])
    assert res.exit_code == 2 and "exclude each other" in res.stderr, res.output


def test_detect_without_config_reads_the_log_in_chunks(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """The CLI's detect without a config reads the log in chunks (read_log is never called
    on it, no log is held in memory) and writes what the replay of the log in memory
    gives."""
    import impactcli.logs as io_mod
    from impactcli.logs import reader
    from impactcli.run import collect

    log = SAMPLES / "csv" / "assist_impacts.csv.gz"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole, _ = detect_in_memory(read_log(log))

    def refuse(*a: object, **k: object) -> None:
        raise AssertionError("the log was read whole")

    monkeypatch.setattr(reader, "MemoryReader", refuse)
    monkeypatch.setattr(collect, "MemoryReader", refuse)
    monkeypatch.setattr(io_mod, "read_log", refuse)
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["detect", str(log), "--out", str(out), "--signals"])
    assert res.exit_code == 0, res.output
    got = (out / "assist_impacts.timeline.json").read_text()
    import json

    a, b = json.loads(got), json.loads(timeline_json(whole))
    for d in (a, b):   # provenance of the run itself (time, command line) differs
        d.pop("produced_by", None)
    assert a["events"] == b["events"] and a["incidents"] == b["incidents"]
    assert a["thresholds"] == b["thresholds"] and a["model"] == b["model"]
    assert (out / "assist_impacts.signals.parquet").exists()


def test_block_maxima_in_chunks_equal_the_whole_statistic() -> None:
    rng = np.random.default_rng(5)
    s = rng.standard_normal((10_007, 3))
    s[4_321, 1] = np.nan
    for start, block in ((0, 1000), (1_234, 1000), (17, 7), (5, 0)):
        whole = (block_maxima(s[start:], block) if block else
                 np.max(s[start:], axis=0)[None, :])
        for size in (1, 999, 1000, 4_096, 20_000):
            bm = BlockMaxima(start, block)
            for k in range(0, s.shape[0], size):
                bm.update(k, s[k:k + size])
            assert np.array_equal(bm.finish(), whole, equal_nan=True), (start, block, size)


_FULL_LINE = ("temporary folder {}: No space left on device while writing the replay's "
              "temporary files (a long log needs up to about 1 kB per sample for 7 joints "
              "there); set TMPDIR to a folder with room")


@pytest.mark.parametrize("verb", ["detect", "report", "view"])
def test_a_full_temporary_folder_is_one_line_exit_2(tmp_path: Path, verb: str,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """No room for the spill (TMPDIR full): one line naming the folder and what to do,
    exit 2, no output file, no temporary file left — in every verb that replays a log."""
    import errno
    import tempfile

    from impactcli.spill import ColumnFiles

    def full(f: object, v: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    # every write of the one temporary store fails: the scan's cache gives itself up, the
    # first spill stops the run
    monkeypatch.setattr(ColumnFiles, "_write", staticmethod(full))
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", None)               # read TMPDIR again
    out = tmp_path / "out"
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResourceWarning)          # nothing left unclosed
        log = str(SAMPLES / "csv" / "assist_impacts.csv.gz")
        args = {"detect": ["detect", log, "-o", str(out)],
                "report": ["report", log, "-o", str(out / "r.html")],
                "view": ["view", log, "--no-open", "--save", str(out / "r.rrd")]}[verb]
        res = CliRunner().invoke(main, args)
    assert res.exit_code == 2, res.output
    lines = [x for x in res.stderr.splitlines() if x.startswith("impactcli: error:")]
    assert lines == ["impactcli: error: " + _FULL_LINE.format(tmp_path)]
    assert "Traceback" not in res.stderr
    assert not out.exists() or not any(out.iterdir())
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith("impactcli-")]


def test_a_full_temporary_folder_under_the_reports_spill(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Only the report's own columns find no room (the replay's spills did): the same one
    line, and no report."""
    import errno
    import tempfile

    from impactcli.spill import ColumnFiles

    real = ColumnFiles.append

    def append(self: ColumnFiles, arrays: dict[str, object]) -> None:
        if "impactcli-report-" in str(self.folder.path):
            raise files.temp_space_error(OSError(errno.ENOSPC, "No space left on device"))
        real(self, arrays)  # type: ignore[arg-type]

    monkeypatch.setattr(ColumnFiles, "append", append)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr(tempfile, "tempdir", None)
    html = tmp_path / "r.html"
    res = CliRunner().invoke(main, ["report", str(SAMPLES / "csv" / "assist_impacts.csv.gz"),
                                    "--config", str(ASSIST), "-o", str(html)])
    assert res.exit_code == 2, res.output
    lines = [x for x in res.stderr.splitlines() if x.startswith("impactcli: error:")]
    assert lines == ["impactcli: error: " + _FULL_LINE.format(tmp_path)]
    assert not html.exists()


@pytest.mark.parametrize(("config", "passes"), [
    (None, 3),      # identification, replay, comparison over the spill
    (ASSIST, 2),    # calibrated: the replay compares as it goes (+ identification)
])
def test_progress_counts_every_pass_once_and_ends_at_its_total(
        config: Path | None, passes: int) -> None:
    calls: list[tuple[float, float]] = []
    path = SAMPLES / "csv" / "assist_impacts.csv.gz"
    setup = RunSetup(config=load_config(config) if config else None, chunk_rows=4096,
                     model_from_log=config is not None)
    with warnings.catch_warnings(), open_log(path) as reader:
        warnings.simplefilter("ignore")
        detect_log(reader, setup, progress=lambda d, t: calls.append((d, t)))
    totals = {t for _, t in calls}
    assert len(totals) == 1                      # known before the first report
    total = totals.pop()
    done = [d for d, _ in calls]
    assert done == sorted(done) and done[-1] == pytest.approx(total)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        duration = read_log(path).duration_s
    assert total == pytest.approx(passes * duration)
    assert len(calls) >= passes * 4              # reported chunk by chunk (18,176 samples)
