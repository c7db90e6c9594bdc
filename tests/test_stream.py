"""The streamed replay (impactcli.stream) gives the whole-log replay's answer.

Byte-identical timelines and equal signals whatever the chunk size, with chunk boundaries
inside the warm-up, inside events and at a time gap; the CLI takes the streamed path with
a calibrated config and leaves nothing half-written when the log turns bad midway.
"""

from __future__ import annotations

import gzip
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import load_config
from impactcli.io import read_log
from impactcli.outputs.signals import SignalsWriter, read_signals, write_signals
from impactcli.outputs.timeline import timeline_json
from impactcli.pipeline import analyze
from impactcli.stream import analyze_stream

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
ASSIST = SAMPLES / "assist_like.config.toml"
HEAVY = SAMPLES / "heavy_geared.config.toml"


def _whole(path: Path, cfg_path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return analyze(read_log(path), config=load_config(cfg_path), read_options={})


def _streamed(path: Path, cfg_path: Path, rows: int, signals: Path | None = None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if signals is None:
            return analyze_stream(str(path), config=load_config(cfg_path), read_options={},
                                  chunk_rows=rows)
        with SignalsWriter(signals, 0, "", str(path)) as w:
            return analyze_stream(
                str(path), config=load_config(cfg_path), read_options={}, chunk_rows=rows,
                on_chunk=lambda c: w.append(c.joints, c.time_s, c.signals, c.decisions))


@pytest.mark.parametrize(("log", "cfg", "rows"), [
    ("assist_impacts", ASSIST, 997),      # boundaries inside every event
    ("assist_impacts", ASSIST, 4096),     # a boundary inside the warm-up (16.4 s at 250 Hz)
    ("assist_clamps", ASSIST, 2500),
    ("heavy_impacts", HEAVY, 1500),
    ("assist_pushes", ASSIST, 10**7),     # one chunk
])
def test_streamed_timeline_is_byte_identical(log: str, cfg: Path, rows: int) -> None:
    path = SAMPLES / "csv" / f"{log}.csv.gz"
    whole = _whole(path, cfg)
    got = _streamed(path, cfg, rows)
    assert whole.events and whole.incidents
    assert timeline_json(got) == timeline_json(whole)


def test_streamed_signals_equal_the_whole_logs(tmp_path: Path) -> None:
    path = SAMPLES / "csv" / "assist_impacts.csv.gz"
    whole = _whole(path, ASSIST)
    write_signals(whole, tmp_path / "whole.parquet")
    _streamed(path, ASSIST, 3001, tmp_path / "stream.parquet")
    a, _ = read_signals(tmp_path / "whole.parquet")
    b, _ = read_signals(tmp_path / "stream.parquet")
    assert a.keys() == b.keys()
    for k in a:
        assert np.allclose(a[k], b[k], rtol=0, atol=1e-12, equal_nan=True), k


def _write_with_gap(src: Path, dst: Path, drop: slice) -> int:
    """The CSV without the rows of ``drop`` (a time gap); returns the gap's first row."""
    with gzip.open(src, "rt") as f:
        lines = f.read().splitlines(keepends=True)
    body = lines[1:]
    del body[drop]
    dst.write_text(lines[0] + "".join(body))
    return int(drop.start)


def test_streamed_with_a_time_gap_at_a_chunk_boundary(tmp_path: Path) -> None:
    """A 0.4 s gap; chunks that end exactly at it and just after it."""
    path = tmp_path / "gap.csv"
    k = _write_with_gap(SAMPLES / "csv" / "assist_impacts.csv.gz", path, slice(9000, 9100))
    whole = _whole(path, ASSIST)
    assert any("time gap" in w for w in whole.warnings)
    for rows in (k, k + 1, k - 1):
        assert timeline_json(_streamed(path, ASSIST, rows)) == timeline_json(whole)


def test_detect_streams_and_writes_the_same_files(tmp_path: Path) -> None:
    """detect --config --signals (streamed) writes the timeline and signals the whole-log
    replay writes; --rerun (whole log) gives the same timeline."""
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
    whole = _whole(log, ASSIST)
    write_signals(whole, tmp_path / "w.parquet")
    a, _ = read_signals(tmp_path / "a" / "assist_pushes.signals.parquet")
    b, _ = read_signals(tmp_path / "w.parquet")
    assert all(np.array_equal(a[k], b[k], equal_nan=True) for k in b)


def test_a_log_bad_midway_leaves_no_output(tmp_path: Path) -> None:
    """A cell that is not a number far into the file: one line, exit 3, no file written."""
    with gzip.open(SAMPLES / "csv" / "assist_impacts.csv.gz", "rt") as f:
        lines = f.read().splitlines(keepends=True)
    cells = lines[15000].split(",")
    cells[2] = "oops"
    lines[15000] = ",".join(cells)
    bad = tmp_path / "bad.csv"
    bad.write_text("".join(lines))
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(bad), "--config", str(ASSIST), "--signals",
                                  "-o", str(out)])
    assert r.exit_code == 3, r.output
    assert "bad.csv" in r.output and "Traceback" not in r.output
    assert not list(out.glob("*")) if out.exists() else True


def _rrd_rows(path: Path) -> dict[str, list[tuple[Any, ...]]]:
    """Non-static rows per entity as sorted tuples (time and every value), and the static
    entities' contents."""
    import rerun as rr

    out: dict[str, list[tuple[Any, ...]]] = {}
    for ch in rr.chunk.RrdReader(path).store().stream():
        cols = ch.to_record_batch().to_pydict()
        names = sorted(k for k in cols if "rowid" not in k.lower().replace("_", ""))
        rows = out.setdefault(("static " if ch.is_static else "") + ch.entity_path, [])
        for i in range(len(cols[names[0]]) if names else 0):
            rows.append(tuple(repr(cols[k][i]) for k in names))
    return {k: sorted(v) for k, v in out.items()}


@pytest.mark.parametrize("rows", [997, 4096])
def test_streamed_rerun_holds_the_whole_log_recordings_samples(tmp_path: Path,
                                                               rows: int) -> None:
    """The recording written from the spill file holds the same rows per entity as
    write_rrd of the whole-log result, decimated (buckets across chunk boundaries), with
    event windows, markers, lanes, events and incidents."""
    from impactcli.outputs.rerun import write_rrd
    from impactcli.outputs.rerun_stream import SpillWriter, spill_columns, write_rrd_from_spill

    path = SAMPLES / "csv" / "assist_impacts.csv.gz"
    whole = _whole(path, ASSIST)
    write_rrd(whole, tmp_path / "whole.rrd", max_points=1500, event_window_s=0.3,
              recording_id="same")
    spill = SpillWriter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            got = analyze_stream(str(path), config=load_config(ASSIST), read_options={},
                                 chunk_rows=rows, on_chunk=lambda c: spill.append(spill_columns(
                                     c.joints, c.t_ns, c.signals, c.decisions, c.position,
                                     c.position_ref)))
        write_rrd_from_spill(got, spill, tmp_path / "stream.rrd", max_points=1500,
                             event_window_s=0.3, recording_id="same")
    finally:
        spill.close()
    a, b = _rrd_rows(tmp_path / "whole.rrd"), _rrd_rows(tmp_path / "stream.rrd")
    assert a.keys() == b.keys()
    decimated = [k for k, v in a.items() if "/rms" in k and not k.startswith("static")]
    assert decimated and all(len(a[k]) < whole.log.n_samples for k in decimated)
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
    from impactcli.outputs.decimate import bucket_size, envelope_indices
    from impactcli.outputs.rerun_stream import EnvelopeStream

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
