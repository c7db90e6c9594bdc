"""A CSV cut short — a writer killed mid-line, a ``.csv.gz`` whose gzip stream ends early — is
read up to its last complete line, warned of and marked ``truncated``, as a cut MCAP is;
a last line with all its fields and no line end is a whole line."""

from __future__ import annotations

import gzip
import json
import zlib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from impactcli.cli import main
from impactcli.errors import ImpactWarning
from impactcli.logs import read_log, write_log

from .conftest import make_log

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _small_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Ranges of 4 KiB, so that a cut meets a file read in many ranges."""
    from impactcli.logs.csv import csv_read

    monkeypatch.setattr(csv_read, "BLOCK_SIZE", 4096)


def _read_cut(p: Path) -> tuple[object, list[str]]:
    """The log read from a cut file, and the warnings it gave."""
    with pytest.warns(ImpactWarning) as got:
        log = read_log(p)
    return log, [str(w.message) for w in got]


def _whole(tmp: Path, n: int = 2000) -> tuple[Path, bytes]:
    p = tmp / "whole.csv"
    write_log(make_log(n=n), p)
    return p, p.read_bytes()


def test_a_last_line_cut_mid_field_is_dropped_and_said(tmp_path: Path) -> None:
    whole, data = _whole(tmp_path)
    full = read_log(whole)
    last = data.rstrip(b"\n").rfind(b"\n") + 1
    cut = tmp_path / "cut.csv"
    cut.write_bytes(data[: last + data[last:].find(b",") + 3])  # inside its 2nd field
    log, warned = _read_cut(cut)
    n = full.n_samples - 1
    assert log.n_samples == n and log.source.truncated
    np.testing.assert_array_equal(log.t_ns, full.t_ns[:n])
    np.testing.assert_array_equal(log.position, full.position[:n])
    np.testing.assert_array_equal(log.torque, full.torque[:n])
    assert log.source.repairs[0] == warned[0] == (
        f"{cut}: the file is cut short (its last line ends after 2 of 11 fields, with no line "
        "end: the recording stopped while writing it?); read the complete lines before the "
        "cut"), warned
    assert not full.source.truncated


def test_a_last_line_whole_without_line_end_is_read(tmp_path: Path) -> None:
    whole, data = _whole(tmp_path)
    p = tmp_path / "no_end.csv"
    p.write_bytes(data.rstrip(b"\n"))
    log, full = read_log(p), read_log(whole)
    assert log.n_samples == full.n_samples and not log.source.truncated
    np.testing.assert_array_equal(log.torque, full.torque)


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(frac=st.floats(0.15, 0.98))
def test_a_gzip_stream_cut_anywhere_yields_its_complete_lines(tmp_path: Path,
                                                              frac: float) -> None:
    """Known truth: the complete lines a gzip decompressor gets from the cut bytes."""
    src = tmp_path / "whole.csv.gz"
    if not src.exists():
        write_log(make_log(n=4000), src)
    full = read_log(src)
    data = src.read_bytes()
    cut = tmp_path / "cut.csv.gz"
    cut.write_bytes(data[: int(len(data) * frac)])
    text = zlib.decompressobj(wbits=31).decompress(cut.read_bytes())
    rows = text.count(b"\n") - 1  # complete lines, less the header
    log, warned = _read_cut(cut)
    assert log.source.truncated and log.n_samples == rows
    np.testing.assert_array_equal(log.t_ns, full.t_ns[:rows])
    np.testing.assert_array_equal(log.torque, full.torque[:rows])
    assert "its gzip stream ends early" in warned[0] == log.source.repairs[0]
    with gzip.open(cut, "rb") as f, pytest.raises(EOFError):
        f.read()  # the file really is cut


def test_a_gzip_stream_cut_at_a_line_end_keeps_that_line_and_is_marked(tmp_path: Path,
                                                                       ) -> None:
    """Known truth: a gzip stream flushed after line k and cut there decompresses to lines
    up to k exactly, with no end of stream — the lines after it are lost."""
    whole, data = _whole(tmp_path)
    full = read_log(whole)
    lines = data.split(b"\n")
    keep = 1200  # the header and 1199 rows
    z = zlib.compressobj(wbits=31)
    cut = tmp_path / "cut.csv.gz"
    cut.write_bytes(z.compress(b"\n".join(lines[:keep]) + b"\n") + z.flush(zlib.Z_SYNC_FLUSH))
    log, warned = _read_cut(cut)
    assert log.source.truncated and log.n_samples == keep - 1
    np.testing.assert_array_equal(log.torque, full.torque[: keep - 1])
    assert warned[0] == log.source.repairs[0] == (
        f"{cut}: the file is cut short (its gzip stream ends early, at a line end: the "
        "recording stopped while writing it?); read the complete lines before the cut")


def test_a_cut_gzip_through_detect_is_judged_to_its_cut_and_gated(tmp_path: Path) -> None:
    """A sample log's gzip cut at half: detect warns in one line, the timeline says
    ``input.truncated`` with the duration of the complete lines, and the gate exits 5."""
    full = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
    config = REPO / "sample_logs" / "assist_like.config.toml"
    data = full.read_bytes()
    cut = tmp_path / "cut.csv.gz"
    cut.write_bytes(data[: len(data) // 2])
    text = zlib.decompressobj(wbits=31).decompress(cut.read_bytes())
    last_t = float(text[: text.rfind(b"\n")].rsplit(b"\n", 1)[1].split(b",")[0])
    first_t = float(text.split(b"\n")[1].split(b",")[0])
    r = CliRunner().invoke(main, ["detect", str(cut), "--config", str(config), "-o",
                                  str(tmp_path / "o"), "--fail-on-detect"])
    assert r.exit_code == 5, r.output
    warned = [ln for ln in r.stderr.splitlines() if "cut short" in ln]
    assert warned == [f"impactcli: warning: {cut}: the file is cut short (its gzip stream "
                      "ends early, inside its last line: the recording stopped while "
                      "writing it?); read the complete lines before the cut"], r.stderr
    tl = json.loads((tmp_path / "o" / "cut.timeline.json").read_text())
    assert tl["input"]["truncated"] is True
    assert tl["input"]["duration_s"] == pytest.approx(last_t - first_t, abs=1e-9)
    assert "Traceback" not in r.output
