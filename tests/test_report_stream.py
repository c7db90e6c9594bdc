"""The report of a streamed replay (impactcli.outputs.report_stream) is the whole-log
report: the same HTML and JSON, byte for byte — verdict, incidents, events, margins, the
plots' points, the sweep — whatever the chunk size; and `impactcli report` streams with a
calibrated config, leaving no spill file behind."""

from __future__ import annotations

import glob
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import load_config
from impactcli.io import read_log
from impactcli.io.robot import read_labels
from impactcli.io.stream import scan_log
from impactcli.outputs.report import assemble_report, render_log, report_json
from impactcli.outputs.report_stream import ReportCollector
from impactcli.outputs.svgplot import EnvelopeAccumulator, envelope
from impactcli.pipeline import analyze
from impactcli.stream import analyze_stream

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
ASSIST = SAMPLES / "assist_like.config.toml"
HEAVY = SAMPLES / "heavy_geared.config.toml"


def _report(result, labels, samples=None):
    html, doc = assemble_report([render_log(result, labels, 0, samples=samples)])
    return html, report_json(doc)


def _whole(path: Path, cfg: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return analyze(read_log(path), config=load_config(cfg), read_options={})


def _streamed(path: Path, cfg: Path, rows: int, plots: bool = True):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scan = scan_log(str(path))
        col = ReportCollector(scan.n_samples, scan.gaps, scan.gap_lengths_s, plots=plots)
        try:
            result = analyze_stream(str(path), config=load_config(cfg), read_options={},
                                    chunk_rows=rows, scan=scan, on_chunk=col)
        finally:
            if hasattr(scan, "close"):
                scan.close()
        return result, col.finish(result)


@pytest.mark.parametrize(("log", "cfg", "rows"), [
    ("assist_impacts", ASSIST, 997),     # chunk boundaries inside events and windows
    ("assist_clamps", ASSIST, 4096),
    ("heavy_impacts", HEAVY, 1500),
])
def test_streamed_report_is_the_whole_log_report(log: str, cfg: Path, rows: int) -> None:
    path = SAMPLES / "csv" / f"{log}.csv.gz"
    labels = read_labels(SAMPLES / "csv" / f"{log}.labels.json")
    whole = _whole(path, cfg)
    result, samples = _streamed(path, cfg, rows)
    try:
        assert whole.incidents
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            want_html, want_json = _report(whole, labels)
            got_html, got_json = _report(result, labels, samples)
            assert got_json == want_json
            assert got_html == want_html
            # without labels too (no sweep; the margin's spans are the events alone)
            assert _report(result, None, samples) == _report(whole, None)
    finally:
        samples.close()
    assert not os.path.exists(samples.col.spill.path)


def test_the_sweeps_collector_keeps_only_the_ratios_and_sweeps_alike() -> None:
    """evaluate --sweep's collector (plots=False): no envelopes, no positions in its spill,
    and the same sweep rows as the report's full collector."""
    import pyarrow.parquet as pq

    from impactcli.outputs.sweep_stream import sweep_streamed

    path = SAMPLES / "csv" / "assist_impacts.csv.gz"
    labels = read_labels(SAMPLES / "csv" / "assist_impacts.labels.json")
    full, lean = _streamed(path, ASSIST, 997), _streamed(path, ASSIST, 997, plots=False)
    try:
        assert not lean[1].col.env and full[1].col.env
        names = pq.ParquetFile(lean[1].col.spill.path).schema_arrow.names
        assert names == lean[1].ratio_columns()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scales = (0.5, 1.0, 1.5, 3.0)
            assert sweep_streamed(lean[1], lean[0], labels, scales) == \
                sweep_streamed(full[1], full[0], labels, scales)
    finally:
        full[1].close()
        lean[1].close()


def test_streamed_report_with_a_time_gap(tmp_path: Path) -> None:
    """The gaps listed (their times from the chunks) and a window across a gap."""
    from tests.test_stream import _write_with_gap

    src = SAMPLES / "csv" / "assist_impacts.csv.gz"
    path = tmp_path / "gap.csv"
    _write_with_gap(src, path, slice(6000, 6050))
    whole = _whole(path, ASSIST)
    result, samples = _streamed(path, ASSIST, 2000)
    try:
        assert samples.gaps()[0]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert _report(result, None, samples) == _report(whole, None)
    finally:
        samples.close()


@pytest.mark.parametrize(("n", "chunk"), [
    (n, c) for n in (3, 1400, 1401, 2003, 50_000) for c in (1, 7, 997, 4096, 10**7)
    if not (c == 1 and n > 3000)])      # samples one by one: the short logs cover it
def test_envelope_accumulator_is_envelope(n: int, chunk: int) -> None:
    rng = np.random.default_rng(n + chunk)
    t = np.cumsum(rng.uniform(0.5, 1.5, n))
    y = rng.normal(size=n)
    y[rng.integers(0, n, n // 50 + 1)] = np.nan
    y[rng.integers(0, n, n // 80 + 1)] = np.inf
    y[rng.integers(0, n, n // 30 + 1)] = 1.0      # ties: the first one wins
    y[rng.integers(0, n, n // 30 + 1)] = -0.0
    if n > 10_000:
        y[5000:9000] = np.nan                      # whole buckets without a value
    acc = EnvelopeAccumulator(n, 700)
    for k in range(0, n, chunk):
        acc.update(t[k:k + chunk], y[k:k + chunk])
    ta, ya = acc.result()
    tb, yb = envelope(t, y, 700)
    assert np.array_equal(ta, tb)
    assert np.array_equal(ya, yb, equal_nan=True)
    assert np.array_equal(np.signbit(ya), np.signbit(yb))


def _spills() -> set[str]:
    return set(glob.glob(os.path.join(tempfile.gettempdir(), "impactcli-report-*")))


def test_report_cli_streams_with_a_calibrated_config(tmp_path: Path, monkeypatch) -> None:
    """`impactcli report LOG --config C` takes the streamed path (the whole-log replay is
    not called) and writes the whole-log report; a timeline re-run streams too."""
    from impactcli import pipeline

    log = SAMPLES / "csv" / "assist_impacts.csv.gz"
    labels = read_labels(SAMPLES / "csv" / "assist_impacts.labels.json")
    whole = _whole(log, ASSIST)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want_html, want_json = _report(whole, labels)
    before = _spills()
    runner = CliRunner()
    # the timeline to re-run, written before analyze is forbidden
    res = runner.invoke(main, ["detect", str(log), "--config", str(ASSIST), "-o",
                               str(tmp_path)])
    assert res.exit_code == 0, res.output

    def forbidden(*a, **k):
        raise AssertionError("the whole-log replay was called")

    monkeypatch.setattr(pipeline, "analyze", forbidden)
    for inp in (str(log), str(tmp_path / "assist_impacts.timeline.json")):
        out = tmp_path / "r.html"
        res = runner.invoke(main, ["report", inp, "--config", str(ASSIST), "-o", str(out),
                                   "--json", str(tmp_path / "r.json")])
        assert res.exit_code == 0, res.output
        got = (tmp_path / "r.json").read_text("utf-8")
        if inp.endswith(".gz"):
            assert out.read_text("utf-8") == want_html
            assert got == want_json
        else:  # the re-run of a timeline: its origin is said, the rest is the same
            assert '"timeline":' in got
    assert _spills() == before
