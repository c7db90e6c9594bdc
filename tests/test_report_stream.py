"""A log's report from its replay's chunks (impactcli.outputs.report.samples): the same
HTML and JSON, byte for byte — verdict, incidents, events, margins, the plots' points, the
sweep — whatever the chunk size, and whether the chunks carry their ratios or the report
rebuilds them; `impactcli report` streams and leaves no spill file behind."""

from __future__ import annotations

import os
import tempfile
import warnings
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import load_config
from impactcli.logs.reader import open_log, scan_log
from impactcli.logs.robot_files import read_labels
from impactcli.outputs.report import assemble_report, render_log, report_json
from impactcli.outputs.report.samples import ReportCollector
from impactcli.outputs.svgplot import EnvelopeAccumulator, envelope
from impactcli.run.one_log import RunSetup, detect_log

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
ASSIST = SAMPLES / "assist_like.config.toml"
HEAVY = SAMPLES / "heavy_geared.config.toml"
#: Rows per chunk as the CLI replays (run.one_log.CHUNK_ROWS): one chunk per sample log.
CLI_ROWS = 65_536


def _report(result, labels, samples):
    html, doc = assemble_report([render_log(result, labels, 0, samples=samples)])
    return html, report_json(doc)


def _without_ratios(col: ReportCollector) -> Any:
    """``col`` fed the run's chunks without their ratios (the collector rebuilds them)."""
    def feed(c: Any) -> None:
        col(SimpleNamespace(**{**vars(c), "ratios": {}}))
    return feed


def _streamed_to(path: Path, cfg: Path, rows: int,
                 kinds: tuple[tuple[bool, bool], ...]) -> tuple[Any, list[Any]]:
    """(result, [samples]) of one replay in chunks of ``rows``, its chunks handed to one
    collector per (plots, ratios) kind: with or without the plots' envelopes, and with
    the ratios the run computed or without them (the collector rebuilds them)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scan = scan_log(str(path))
        try:
            cols = [ReportCollector(scan.n_samples, scan.gaps, scan.gap_lengths_s, plots=plots)
                    for plots, _ in kinds]
        finally:
            if hasattr(scan, "close"):
                scan.close()
        feeds = [col if ratios else _without_ratios(col)
                 for col, (_, ratios) in zip(cols, kinds, strict=True)]

        def feed(c: Any) -> None:
            for f in feeds:
                f(c)

        with open_log(path) as reader:
            result = detect_log(reader, RunSetup(config=load_config(cfg), chunk_rows=rows),
                                on_chunk=feed)
        return result, [col.finish(result) for col in cols]


def _streamed(path: Path, cfg: Path, rows: int, plots: bool = True, ratios: bool = True):
    """(result, samples) of the replay in chunks of ``rows``; the chunks carry their
    ratios (as the run computes them) unless ``ratios`` is False."""
    result, (samples,) = _streamed_to(path, cfg, rows, ((plots, ratios),))
    return result, samples


@pytest.mark.parametrize(("log", "cfg", "rows"), [
    ("assist_impacts", ASSIST, 997),     # chunk boundaries inside events and windows
    ("assist_clamps", ASSIST, 4096),
    ("heavy_impacts", HEAVY, 1500),
])
def test_the_report_whatever_the_chunks(log: str, cfg: Path, rows: int) -> None:
    path = SAMPLES / "csv" / f"{log}.csv.gz"
    labels = read_labels(SAMPLES / "csv" / f"{log}.labels.json")
    one = _streamed(path, cfg, CLI_ROWS)
    chunked, (rebuilt, carried) = _streamed_to(path, cfg, rows, ((True, False), (True, True)))
    runs = [one, (chunked, rebuilt), (chunked, carried)]  # one replay in chunks, two reports
    try:
        assert runs[0][0].incidents and runs[0][1].col.groups[0][1] == runs[0][1].col.n
        assert not runs[1][1].col.has_ratios and runs[2][1].col.has_ratios
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            want = _report(runs[0][0], labels, runs[0][1])
            # without labels too (no sweep; the margin's spans are the events alone)
            want_unlabelled = _report(runs[0][0], None, runs[0][1])
            for result, samples in runs[1:]:
                assert _report(result, labels, samples) == want
                assert _report(result, None, samples) == want_unlabelled
    finally:
        folders = [s.col.spill.folder.path for _, s in runs]
        for _, samples in runs:
            samples.close()
    assert all(f is not None for f in folders)
    assert not any(os.path.exists(str(f)) for f in folders)


def test_the_sweeps_collector_keeps_only_the_ratios_and_sweeps_alike() -> None:
    """evaluate --sweep's collector (plots=False): no envelopes, no positions in its spill,
    and the same sweep rows as the report's full collector; with chunks that carry their
    ratios it keeps only those."""
    path = SAMPLES / "csv" / "assist_impacts.csv.gz"
    labels = read_labels(SAMPLES / "csv" / "assist_impacts.labels.json")
    result, got = _streamed_to(path, ASSIST, 997, ((True, True), (False, False), (False, True)))
    full, lean, leaner = ((result, samples) for samples in got)  # one replay, three collectors
    try:
        assert not lean[1].col.env and full[1].col.env
        names = list(lean[1].col.spill.layout)
        assert names == ["t", *[f"{k}.{c}" for k in range(len(lean[0].log.joint_names))
                                for c in ("rms", "thr", "load", "res")]]
        names = list(leaner[1].col.spill.layout)
        assert names == ["t", *[f"{k}.x.{d}" for k in range(len(lean[0].log.joint_names))
                                for d in ("adaptive", "static_loading", "static_baseline")]]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scales = (0.5, 1.0, 1.5, 3.0)
            want = full[1].sweep(full[0], labels, scales)
            assert sum(r.detected for r in want) > 0
            assert lean[1].sweep(lean[0], labels, scales) == want
            assert leaner[1].sweep(leaner[0], labels, scales) == want
    finally:
        for _, samples in (full, lean, leaner):
            samples.close()


def test_the_report_with_a_time_gap(tmp_path: Path) -> None:
    """The gaps listed (their times from the chunks) and a window across a gap."""
    from .helpers import csv_with_gap

    src = SAMPLES / "csv" / "assist_impacts.csv.gz"
    path = tmp_path / "gap.csv"
    csv_with_gap(src, path, slice(6000, 6050))
    one, many = _streamed(path, ASSIST, CLI_ROWS), _streamed(path, ASSIST, 2000)
    try:
        at, lengths = many[1].gaps()
        assert at == one[1].gaps()[0] and len(at) == 1 and lengths[0] > 0.1
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert _report(many[0], None, many[1]) == _report(one[0], None, one[1])
    finally:
        one[1].close()
        many[1].close()


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


def test_report_cli_streams_with_a_calibrated_config(tmp_path: Path, monkeypatch) -> None:
    """`impactcli report LOG --config C` replays through batch.stream_log and writes the
    report of the replay's chunks; a timeline re-run streams too; no spill file is left."""
    import impactcli.run.job

    log = SAMPLES / "csv" / "assist_impacts.csv.gz"
    labels = read_labels(SAMPLES / "csv" / "assist_impacts.labels.json")
    result, samples = _streamed(log, ASSIST, CLI_ROWS)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            want_html, want_json = _report(result, labels, samples)
    finally:
        samples.close()
    tmp = tmp_path / "tmp"  # a temporary folder of this test's own (others' runs use /tmp)
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    runner = CliRunner()
    res = runner.invoke(main, ["detect", str(log), "--config", str(ASSIST), "-o",
                               str(tmp_path)])
    assert res.exit_code == 0, res.output
    calls: list[str] = []
    real = impactcli.run.job.run_log

    def stream_log(path: str, **kw: Any) -> Any:
        calls.append(kw.get("samples"))
        return real(path, **kw)

    monkeypatch.setattr(impactcli.run.job, "run_log", stream_log)
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
    assert calls == ["report", "report"]
    assert not list(tmp.iterdir())
