"""The replay of a log read in chunks gives the answer of the same log in memory (one chunk).

Byte-identical timelines and equal signals whatever the chunk size, with chunk boundaries
inside the warm-up, inside events and at a time gap; the CLI's detect writes those files and
leaves nothing half-written when the log turns bad midway.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import load_config
from impactcli.detect.thresholds import detector_ratios
from impactcli.logs import read_log
from impactcli.logs.reader import open_log
from impactcli.outputs.signals import SignalsWriter, read_signals
from impactcli.outputs.timeline import timeline_json
from impactcli.run.collect import detect_in_memory
from impactcli.run.one_log import RunSetup, detect_log
from impactcli.types import DetectionResult, LogHeader, SignalsChunk

from .helpers import bad_midway_csv, csv_with_gap, rrd_rows

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
ASSIST = SAMPLES / "assist_like.config.toml"
HEAVY = SAMPLES / "heavy_geared.config.toml"


def _in_memory(path: Path, cfg_path: Path) -> DetectionResult:
    """The log read whole and replayed as one chunk."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return detect_in_memory(read_log(path), config=load_config(cfg_path))[0]


def _chunked(path: Path, cfg_path: Path, rows: int, on_chunk: Any = None) -> DetectionResult:
    """The log read from its file in chunks of ``rows`` samples."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open_log(path) as reader:
            return detect_log(reader, RunSetup(config=load_config(cfg_path), chunk_rows=rows),
                              on_chunk=on_chunk)


def _signals_file(path: Path, cfg_path: Path, rows: int, out: Path) -> DetectionResult:
    with SignalsWriter(out, 0, "", str(path)) as w:
        return _chunked(path, cfg_path, rows,
                        lambda c: w.append(c.joints, c.time_s, c.signals, c.decisions))


@pytest.mark.parametrize(("log", "cfg", "rows"), [
    ("assist_impacts", ASSIST, 997),      # boundaries inside every event
    ("assist_impacts", ASSIST, 4096),     # a boundary inside the warm-up (16.4 s at 250 Hz)
    ("assist_clamps", ASSIST, 2500),
    ("heavy_impacts", HEAVY, 1500),
    ("assist_pushes", ASSIST, 10**7),     # one chunk
])
def test_chunked_timeline_is_byte_identical(log: str, cfg: Path, rows: int) -> None:
    path = SAMPLES / "csv" / f"{log}.csv.gz"
    whole = _in_memory(path, cfg)
    got = _chunked(path, cfg, rows)
    assert whole.events and whole.incidents
    assert isinstance(got.log, LogHeader) and not hasattr(got, "signals")
    assert timeline_json(got) == timeline_json(whole)


def test_chunked_signals_equal_one_chunks(tmp_path: Path) -> None:
    """The signals Parquet of 3001-sample chunks holds the values of one chunk's."""
    path = SAMPLES / "csv" / "assist_impacts.csv.gz"
    _signals_file(path, ASSIST, 10**7, tmp_path / "one.parquet")
    _signals_file(path, ASSIST, 3001, tmp_path / "chunks.parquet")
    a, _ = read_signals(tmp_path / "one.parquet")
    b, _ = read_signals(tmp_path / "chunks.parquet")
    assert a.keys() == b.keys()
    for k in a:
        assert np.array_equal(a[k], b[k], equal_nan=True), k


def test_chunks_carry_their_ratios() -> None:
    """Each chunk's ratios are the detectors' statistics over their thresholds (one
    expression, detector_ratios), computed once; the decisions are the statistics above
    the thresholds; the chunks tile the log."""
    path = SAMPLES / "csv" / "assist_pushes.csv.gz"
    chunks: list[SignalsChunk] = []
    res = _chunked(path, ASSIST, 2000, chunks.append)
    assert [c.start for c in chunks] == list(range(0, res.log.n_samples, 2000))
    v_l = np.array([[res.thresholds[j]["vL"] for j in res.log.joint_names]])
    v_0 = np.array([[res.thresholds[j]["v0"] for j in res.log.joint_names]])
    for c in chunks:
        s = c.signals
        want = detector_ratios(s["residual_rms"], s["threshold"], s["loading_statistic"],
                               np.abs(s["residual"]), v_l, v_0)
        assert c.ratios.keys() == want.keys()
        for d in want:
            assert np.array_equal(c.ratios[d], want[d]), d
        assert np.array_equal(c.decisions["static_loading"], s["loading_statistic"] > v_l)
        assert np.array_equal(c.decisions["adaptive"], s["residual_rms"] > s["threshold"])


def test_chunked_with_a_time_gap_at_a_chunk_boundary(tmp_path: Path) -> None:
    """A 0.4 s gap; chunks that end exactly at it and just after it."""
    path = tmp_path / "gap.csv"
    k = csv_with_gap(SAMPLES / "csv" / "assist_impacts.csv.gz", path, slice(9000, 9100))
    whole = _in_memory(path, ASSIST)
    assert any("time gap" in w for w in whole.warnings)
    for rows in (k, k + 1, k - 1):
        assert timeline_json(_chunked(path, ASSIST, rows)) == timeline_json(whole)


def test_detect_writes_the_timeline_and_signals_of_the_replay(tmp_path: Path) -> None:
    """detect --config --signals writes the timeline and signals of the log's replay in
    memory (one chunk); --rerun gives the same timeline."""
    log = SAMPLES / "csv" / "assist_pushes.csv.gz"
    r = CliRunner().invoke(main, ["detect", str(log), "--config", str(ASSIST), "--signals",
                                  "-o", str(tmp_path / "a")])
    assert r.exit_code == 0, r.output
    r2 = CliRunner().invoke(main, ["detect", str(log), "--config", str(ASSIST), "--rerun",
                                   "-o", str(tmp_path / "b")])
    assert r2.exit_code == 0, r2.output
    ta = (tmp_path / "a" / "assist_pushes.timeline.json").read_bytes()
    tb = (tmp_path / "b" / "assist_pushes.timeline.json").read_bytes()
    assert ta == tb
    assert ta.decode() == timeline_json(_in_memory(log, ASSIST))
    _signals_file(log, ASSIST, 10**7, tmp_path / "w.parquet")
    a, _ = read_signals(tmp_path / "a" / "assist_pushes.signals.parquet")
    b, _ = read_signals(tmp_path / "w.parquet")
    assert a.keys() == b.keys()
    assert all(np.array_equal(a[k], b[k], equal_nan=True) for k in b)


def test_a_log_bad_midway_leaves_no_output(tmp_path: Path) -> None:
    """A cell that is not a number far into the file: one line, exit 3, no file written."""
    bad = bad_midway_csv(tmp_path)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(bad), "--config", str(ASSIST), "--signals",
                                  "-o", str(out)])
    assert r.exit_code == 3, r.output
    assert "bad.csv" in r.output and "Traceback" not in r.output
    assert not list(out.glob("*")) if out.exists() else True


def _recording(path: Path, rows: int, out: Path) -> DetectionResult:
    from impactcli.outputs.rerun import RerunWriter

    with RerunWriter() as writer:
        got = _chunked(path, ASSIST, rows, writer)
        writer.write(got, out, max_points=1500, event_window_s=0.3, recording_id="same")
    return got


@pytest.fixture(scope="module")
def one_chunk_recording(tmp_path_factory: pytest.TempPathFactory
                        ) -> tuple[DetectionResult, dict[str, Any]]:
    """The sample log with impacts replayed in one chunk: its result and its recording's
    rows per entity (made once for the chunk sizes compared with it)."""
    out = tmp_path_factory.mktemp("one") / "one.rrd"
    one = _recording(SAMPLES / "csv" / "assist_impacts.csv.gz", 10**7, out)
    return one, rrd_rows(out, everything=True)


@pytest.mark.parametrize("rows", [997, 4096])
def test_chunked_rerun_holds_the_one_chunk_recordings_samples(
        tmp_path: Path, rows: int,
        one_chunk_recording: tuple[DetectionResult, dict[str, Any]]) -> None:
    """The recording of a replay in chunks holds the same rows per entity as the one of a
    single chunk, decimated (buckets across chunk boundaries), with event windows,
    markers, lanes, events and incidents."""
    one, a = one_chunk_recording
    _recording(SAMPLES / "csv" / "assist_impacts.csv.gz", rows, tmp_path / "chunks.rrd")
    b = rrd_rows(tmp_path / "chunks.rrd", everything=True)
    assert a.keys() == b.keys()
    assert one.incidents and "/incidents" in a
    decimated = [k for k, v in a.items() if "/rms" in k and not k.startswith("static")]
    assert decimated and all(len(a[k]) < one.log.n_samples for k in decimated)
    for k in a:
        if k.startswith("static /__properties") or "blueprint" in k:
            continue
        assert a[k] == b[k], k


@pytest.mark.parametrize(("n", "k", "max_points", "chunks"), [
    (100_000, 2, 3000, [997]), (20_000, 1, 1000, [1, 7, 4096]),
    (12_345, 3, 500, [100, 12_345]), (9_999, 2, 5000, [3000])])
def test_envelope_stream_selects_the_whole_series_envelope(
        n: int, k: int, max_points: int, chunks: list[int]) -> None:
    """EnvelopeStream over chunks selects exactly decimate.envelope_indices of the whole
    series (NaN, kept samples, a last bucket shorter than the others), each index once."""
    from impactcli.outputs.decimate import EnvelopeStream, bucket_size, envelope_indices

    rng = np.random.default_rng(n)
    v = rng.normal(size=(n, k))
    v[rng.random(n) < 0.01, 0] = np.nan
    keep = rng.random(n) < 0.001
    want = envelope_indices([v[:, i] for i in range(k)], bucket_size(n, k, max_points), keep)
    es = EnvelopeStream(n, k, max_points)
    got: list[int] = []
    a = i = 0
    while a < n:
        b = min(a + chunks[i % len(chunks)], n)
        sel, rows = es.update(v[a:b], keep[a:b], np.arange(a, b, dtype=np.float64)[:, None])
        assert np.array_equal(rows[:, 0].astype(np.int64), sel)
        got += sel.tolist()
        a, i = b, i + 1
    assert sorted(got) == want.tolist() and len(set(got)) == len(got)
