"""Common CSV variants read like the canonical file: a UTF-8 BOM (Excel), ';' and tab
separators, a decimal comma, ISO-8601 time stamps; binary content is "not a text CSV"; a
joint whose position or torque column holds no value is left out with a warning."""

from __future__ import annotations

import gzip
import json
import warnings
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from impactcli.errors import ImpactWarning, LogFormatError
from impactcli.logs import read_log
from impactcli.types import RobotLog

from .cli_run import cli

N = 300
PERIOD_NS = 4_000_000  # 250 Hz
HEADER = ["time", "j1.position", "j1.torque", "j2.position", "j2.torque"]


def _rows(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """N stamps [ns] and (N, 4) values (j1.position, j1.torque, j2.position, j2.torque)."""
    rng = np.random.default_rng(seed)
    t = np.arange(N, dtype=np.int64) * PERIOD_NS
    k = np.arange(N)
    vals = np.column_stack([np.sin(k / 40), 2 + np.cos(k / 30), np.cos(k / 50),
                            -1 + 0.5 * np.sin(k / 20)]) + 1e-3 * rng.standard_normal((N, 4))
    return t, np.round(vals, 6)


def _text(sep: str = ",", dec: str = ".", times: list[str] | None = None,
          cells: np.ndarray | None = None) -> str:
    t, vals = _rows()
    if cells is not None:
        vals = cells
    stamps = times if times is not None else [f"{x / 1e9:.3f}" for x in t]
    lines = [sep.join(HEADER)]
    for s, row in zip(stamps, vals, strict=True):
        lines.append(sep.join([s, *(repr(float(v)) for v in row)]).replace(".", dec)
                     if dec != "." else sep.join([s, *(repr(float(v)) for v in row)]))
    return "\n".join(lines) + "\n"


def _read(path: Path, **kw: object) -> RobotLog:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        return read_log(path, **kw)  # type: ignore[arg-type]


def _same(a: RobotLog, b: RobotLog) -> None:
    assert a.joint_names == b.joint_names
    np.testing.assert_array_equal(a.t_ns, b.t_ns)
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.torque, b.torque)


@pytest.fixture
def canonical(tmp_path: Path) -> RobotLog:
    path = tmp_path / "canonical.csv"
    path.write_text(_text(), encoding="utf-8")
    return _read(path)


def test_utf8_bom_excel_export(tmp_path: Path, canonical: RobotLog) -> None:
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf" + _text().encode())
    _same(_read(path), canonical)
    gz = tmp_path / "bom.csv.gz"
    gz.write_bytes(gzip.compress(b"\xef\xbb\xbf" + _text().encode()))
    _same(_read(gz), canonical)
    code, out, err = cli("inspect", str(path), "--json")
    assert code == 0, err
    assert json.loads(out)["joints"] == ["j1", "j2"]


@pytest.mark.parametrize(("sep", "dec"), [(";", "."), (";", ","), ("\t", "."), ("\t", ",")])
def test_semicolon_and_tab_separators_with_a_decimal_comma(
        tmp_path: Path, canonical: RobotLog, sep: str, dec: str) -> None:
    path = tmp_path / "excel.csv"
    path.write_text(_text(sep, dec), encoding="utf-8")
    if dec == ",":
        assert "0,004;" in path.read_text() or "0,004\t" in path.read_text()
    _same(_read(path), canonical)
    code, out, err = cli("inspect", str(path), "--json")
    assert code == 0, err
    assert json.loads(out)["sample_rate_hz"] == 250.0


def test_iso_8601_time_stamps_are_epoch_ns(tmp_path: Path, canonical: RobotLog) -> None:
    t0 = datetime(2024, 5, 1, 12, 0, 0, tzinfo=UTC)
    t0_ns = int(t0.timestamp()) * 10**9
    t, _ = _rows()
    z = [(datetime.fromtimestamp((t0_ns + x) / 1e9, UTC)).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
         for x in t]
    path = tmp_path / "iso.csv"
    path.write_text(_text(times=z), encoding="utf-8")
    log = _read(path)
    assert log.t0_ns == t0_ns and log.sample_rate_hz == 250.0
    np.testing.assert_array_equal(log.t_ns - log.t0_ns, canonical.t_ns)
    np.testing.assert_array_equal(log.position, canonical.position)
    # an offset says the zone; a stamp without one is UTC (here written with a space)
    plus2 = [s.replace("T12:", "T14:").replace("Z", "+02:00") for s in z]
    path.write_text(_text(times=plus2), encoding="utf-8")
    assert _read(path).t0_ns == t0_ns
    naive = [s.replace("T", " ").rstrip("Z") for s in z]
    path.write_text(_text(times=naive), encoding="utf-8")
    assert _read(path).t0_ns == t0_ns
    code, out, err = cli("inspect", str(path), "--json")
    assert code == 0, err
    assert json.loads(out)["t0_ns"] == t0_ns
    # a bad stamp names the row; --time-unit does not apply to stamps
    bad = list(z)
    bad[7] = "2024-05-01T12:00:99.000Z"
    path.write_text(_text(times=bad), encoding="utf-8")
    code, _, err = cli("inspect", str(path))
    assert code == 3
    assert err.splitlines()[-1] == (
        f"impactcli: error: {path}: column 'time', row 8 (line 9): "
        "'2024-05-01T12:00:99.000Z' is not an ISO-8601 time "
        "(YYYY-MM-DDThh:mm:ss[.f][Z|±hh:mm]) within 1677–2262")
    path.write_text(_text(times=z), encoding="utf-8")
    with pytest.raises(LogFormatError) as e:
        read_log(path, time_unit="ms")
    assert str(e.value) == (f"{path}: --time-unit ms does not apply: column 'time' holds "
                            "ISO-8601 stamps")


@pytest.mark.parametrize("garbage", ["random", "nul", "png"])
def test_binary_content_is_not_a_text_csv(tmp_path: Path, garbage: str) -> None:
    path = tmp_path / "x.csv"
    data = {"random": np.random.default_rng(3).integers(0, 256, 4000, dtype=np.uint8)
            .tobytes().replace(b"\x00", b"\x01"),
            "nul": _text().encode()[:500] + b"\x00\x00\x00" + _text().encode()[500:],
            "png": b"\x89PNG\r\n\x1a\n" + bytes(range(1, 256)) * 8}[garbage]
    path.write_bytes(data)
    code, _, err = cli("inspect", str(path))
    assert code == 3
    line = err.splitlines()[-1]
    assert line.startswith(f"impactcli: error: {path}: not a text CSV (binary content")
    if garbage == "nul":
        assert line == (f"impactcli: error: {path}: not a text CSV (binary content: a NUL "
                        "byte at byte 500)")
    assert "no time column" not in err


def test_latin1_header_text_is_still_text(tmp_path: Path) -> None:
    """A spreadsheet's Latin-1 comment column is text, not binary."""
    path = tmp_path / "latin.csv"
    t, vals = _rows()
    lines = [",".join([*HEADER, "note"])]
    lines += [",".join([f"{x / 1e9:.3f}", *map(repr, map(float, r)), "temp 20°C"])
              for x, r in zip(t, vals, strict=True)]
    path.write_bytes(("\n".join(lines) + "\n").encode("latin-1"))
    try:
        log = _read(path)
    except LogFormatError as err:  # pyarrow wants UTF-8 text cells: an error, not "binary"
        assert "not a text CSV" not in str(err)
    else:
        assert log.n_samples == N


@pytest.mark.parametrize("column", ["j2.torque", "j2.position"])
def test_a_joint_without_any_value_is_left_out_with_a_warning(
        tmp_path: Path, canonical: RobotLog, column: str) -> None:
    _, vals = _rows()
    vals = vals.copy()
    vals[:, HEADER.index(column) - 1] = np.nan
    path = tmp_path / "empty.csv"
    path.write_text(_text(cells=vals).replace("nan", ""), encoding="utf-8")
    what = column.split(".")[1]
    msg = (f"{path}: joint 'j2' left out of detection: its {what} column holds no finite "
           "value (not logged?)")
    with pytest.warns(ImpactWarning) as rec:
        log = read_log(path)
    assert msg in [str(w.message) for w in rec]
    assert log.joint_names == ("j1",)
    assert log.source.joints_dropped == (("j2", f"its {what} column holds no finite value "
                                                "(not logged?)"),)
    np.testing.assert_array_equal(log.torque[:, 0], canonical.torque[:, 0])
    code, out, err = cli("inspect", str(path), "--json")
    assert code == 0
    assert f"impactcli: warning: {msg}" in err.splitlines()
    assert json.loads(out)["joints_dropped"] == [
        {"name": "j2", "reason": f"its {what} column holds no finite value (not logged?)"}]


def test_no_joint_left_is_an_error(tmp_path: Path) -> None:
    _, vals = _rows()
    vals = vals.copy()
    vals[:, 1] = np.nan
    vals[:, 2] = np.nan
    path = tmp_path / "none.csv"
    path.write_text(_text(cells=vals), encoding="utf-8")
    code, _, err = cli("inspect", str(path))
    assert code == 3
    assert err.splitlines()[-1] == (
        f"impactcli: error: {path}: no joint has a finite position and torque: j1: its "
        "torque column holds no finite value (not logged?); j2: its position column holds "
        "no finite value (not logged?)")


def test_a_partly_empty_torque_column_is_still_the_documented_error(tmp_path: Path) -> None:
    """Only a column without a single value is read as not logged; a long hole in a
    logged column stays an error naming its first row (the repair policy)."""
    _, vals = _rows()
    vals = vals.copy()
    vals[100:120, 3] = np.nan
    path = tmp_path / "hole.csv"
    path.write_text(_text(cells=vals), encoding="utf-8")
    with pytest.raises(LogFormatError) as e:
        read_log(path)
    assert str(e.value) == (
        f"{path}: column 'j2.torque', row 101 (line 102): a run of 20 non-finite (NaN) "
        "value(s); only gaps of at most 5 samples between finite values are interpolated")


def _with_empty_column(tmp_path: Path, column: str, cell: str) -> Path:
    """A 3-joint log (velocity and references logged) whose ``column`` holds ``cell``
    (empty or NaN) in every row."""
    import dataclasses

    from impactcli.logs import write_log

    from .conftest import make_log

    log = make_log(n=2500, joints=("shoulder", "elbow", "wrist"))
    log = dataclasses.replace(log, velocity=np.gradient(log.position, 0.004, axis=0))
    path = tmp_path / "full.csv"
    write_log(log, path)
    head, *rows = path.read_text(encoding="utf-8").splitlines()
    k = head.split(",").index(column)
    out = tmp_path / f"empty_{column}.csv"
    out.write_text("\n".join([head] + [",".join(cell if i == k else c for i, c in
                                                 enumerate(r.split(","))) for r in rows])
                   + "\n", encoding="utf-8")
    return out


@pytest.mark.parametrize(("column", "cell"), [("elbow.velocity", ""),
                                               ("elbow.position_ref", "NaN")])
def test_an_optional_column_without_any_value_is_read_as_not_logged(
        tmp_path: Path, column: str, cell: str) -> None:
    """A whole optional column empty or NaN: the signal is left out for every joint (a
    log holds it for all joints or none), one warning naming the column; inspect and
    detect go on (they stopped with exit 3 on 'a run of 2500 ... at the start of the log
    at the end of the log')."""
    path = _with_empty_column(tmp_path, column, cell)
    sig = column.split(".")[1]
    msg = (f"{path}: column {column!r} holds no finite value: {sig} is read as not logged, "
           "for every joint (a log has a signal for all its joints or none)")
    with pytest.warns(ImpactWarning) as rec:
        log = read_log(path)
    assert [str(w.message) for w in rec] == [msg]
    assert getattr(log, sig) is None and log.joint_names == ("shoulder", "elbow", "wrist")
    assert log.source.ignored_channels == (f"shoulder.{sig}", f"wrist.{sig}")
    assert log.source.repairs == (msg,)
    code, out, err = cli("inspect", str(path), "--json")
    assert code == 0, err
    assert err.splitlines() == [f"impactcli: warning: {msg}"]
    d = json.loads(out)
    assert sig not in d["signals"] and d["repairs"] == [msg]
    assert d["channels"]["ignored"] == [f"shoulder.{sig}", f"wrist.{sig}"]
    code, out, err = cli("inspect", str(path))
    assert code == 0, err
    assert f"repair: {msg}" in out
    code, out, err = cli("detect", str(path), "-o", str(tmp_path / "out"))
    assert code == 0, err
    assert f"impactcli: warning: {msg}" in err.splitlines()


def test_every_joints_optional_column_empty_says_so_once(tmp_path: Path) -> None:
    _, vals = _rows()
    path = tmp_path / "v.csv"
    text = _text(cells=vals).splitlines()
    path.write_text("\n".join([text[0] + ",j1.velocity,j2.velocity"]
                              + [r + ",," for r in text[1:]]) + "\n", encoding="utf-8")
    with pytest.warns(ImpactWarning) as rec:
        log = read_log(path)
    assert [str(w.message) for w in rec] == [
        f"{path}: columns 'j1.velocity', 'j2.velocity' hold no finite value: velocity is "
        "read as not logged"]
    assert log.velocity is None and log.source.ignored_channels == ()


def test_a_column_without_any_finite_value_that_must_have_one_says_so() -> None:
    """The error of a non-finite run spanning the whole column says the column holds no
    finite value (it read '... at the start of the log at the end of the log')."""
    from impactcli.logs.layout import RawRows, StreamLayout
    from impactcli.logs.repair import Repairer

    class Two(StreamLayout):
        where, names, droppable = "f.csv", ["a.position", "x"], set()

    t = np.arange(10, dtype=np.int64) * PERIOD_NS
    mat = np.column_stack([np.zeros(10), np.full(10, np.nan)])
    rep = Repairer(Two(), None)
    rep.push(RawRows(0, t[:4], mat[:4]))  # in two blocks
    rep.push(RawRows(4, t[4:], mat[4:]))
    rep.finish()
    assert rep.first_error() == (
        "f.csv: column 'x', sample 0: no finite value in the column (all 10 values are "
        "non-finite, NaN); only gaps of at most 5 samples between finite values are "
        "interpolated")


def test_a_mapped_npz_optional_array_without_a_value_is_read_as_not_logged(
        tmp_path: Path) -> None:
    """The .npz reader's labels (``velocities[:, 1]``) do not name the signal: it tells
    the repair which may be empty, as the CSV reader does."""
    rng = np.random.default_rng(1)
    n = 40
    qd = rng.normal(size=(n, 2))
    qd[:, 1] = np.nan
    p = tmp_path / "m.npz"
    q = np.cumsum(0.004 * rng.normal(size=(n, 2)), axis=0)  # a motion, at about its speed
    np.savez(p, times=np.arange(n) * 0.004, positions=q,
             torques=rng.normal(size=(n, 2)), velocities=qd)
    cmap = tmp_path / "m.json"
    cmap.write_text(json.dumps({
        "format": "npz", "time": {"key": "times", "unit": "s"},
        "joints": [{"name": f"q{k}", "position": {"key": "positions", "index": k},
                    "velocity": {"key": "velocities", "index": k},
                    "torque": {"key": "torques", "index": k}} for k in range(2)],
    }))
    with pytest.warns(ImpactWarning) as rec:
        log = read_log(p, channel_map=cmap)
    assert [str(w.message) for w in rec] == [
        f"{p}: column 'q1.velocity' holds no finite value: velocity is read as not logged, "
        "for every joint (a log has a signal for all its joints or none)"]
    assert log.velocity is None and log.source.ignored_channels == ("q0.velocity",)
