"""The one reader (impactcli.logs.reader) on CSV: for every chunk size the chunks are the same
arrays bit for bit (read_log collects them), the scan's clock, gaps and screens are those
of the whole log's arrays, the repairs are warned once by the scan, and a bad file fails
in the scan with one message naming the cell."""

from __future__ import annotations

import functools
import gzip
import json
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from impactcli import spill
from impactcli.errors import ImpactWarning, LogFormatError
from impactcli.logs import scan as scan_module
from impactcli.logs import write_log
from impactcli.logs.csv import csv_read as csv_reader
from impactcli.logs.reader import iter_chunks, scan_log
from impactcli.types import JointSpec, RobotDescription

from .stream_invariants import (
    assert_streams_exactly,
    read_error,
    read_warned,
    scan_warned,
)

N = 3000


#: Record batches of this many bytes: about 20 per 3000-row table, so that what a test
#: plants falls across their boundaries.
SMALL_BLOCK = 16384
#: Batches of a few dozen rows, for the tests of what happens at their boundaries (every
#: batch costs the scan its per-batch work: these tests are the slow ones).
TINY_BLOCK = 4096


@pytest.fixture(autouse=True)
def _small_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Many record batches per file: what a test plants falls across their boundaries."""
    monkeypatch.setattr(csv_reader, "BLOCK_SIZE", SMALL_BLOCK)


@pytest.fixture
def tiny_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Batches of a few dozen rows: runs, duplicates and line ends at many boundaries."""
    monkeypatch.setattr(csv_reader, "BLOCK_SIZE", TINY_BLOCK)


def _table(n: int = N, seed: int = 0, epoch: bool = False) -> dict[str, list[str]]:
    """A 3-joint canonical CSV as text columns: time (jittery), position, torque,
    references, a controller torque (a fresh copy: the tests edit it)."""
    return {k: list(v) for k, v in _made_table(n, seed, epoch).items()}


@functools.cache
def _made_table(n: int, seed: int, epoch: bool) -> dict[str, tuple[str, ...]]:
    rng = np.random.default_rng(seed)
    t_ns = np.cumsum(rng.integers(990_000, 1_010_000, n)) + (1_714_567_890 * 10**9 if epoch else 0)
    t_ns[n // 3:] += 40_000_000  # a gap
    cols: dict[str, list[str]] = {
        "time": [f"{v // 10**9}.{v % 10**9:09d}" for v in t_ns.tolist()]}
    for j in ("j1", "j2", "j3"):
        q = np.cumsum(rng.normal(0, 1e-3, n))
        cols[f"{j}.position"] = [repr(float(v)) for v in q]
        cols[f"{j}.torque"] = [repr(float(v)) for v in rng.normal(0, 5, n)]
        cols[f"{j}.position_ref"] = [repr(float(v)) for v in q + 1e-4]
        cols[f"{j}.torque_model"] = [repr(float(v)) for v in rng.normal(0, 5, n)]
    cols["note"] = ["x"] * n
    return {k: tuple(v) for k, v in cols.items()}


def _write(path: Path, cols: dict[str, list[str]], sep: str = ",") -> Path:
    n = len(cols["time"]) if "time" in cols else len(next(iter(cols.values())))
    lines = [sep.join(cols)] + [sep.join(c[i] for c in cols.values()) for i in range(n)]
    text = "\n".join(lines) + "\n"
    if path.name.endswith(".gz"):
        with gzip.open(path, "wt") as f:
            f.write(text)
    else:
        path.write_text(text)
    return path


# ------------------------------------------------------------------- clean files
@pytest.mark.parametrize("name", ["plain.csv", "zipped.csv.gz"])
def test_a_clean_log_streams_exactly(tmp_path: Path, name: str) -> None:
    scan = assert_streams_exactly(_write(tmp_path / name, _table()))
    assert scan.gaps.size == 1 and scan.log.n_samples == 2
    assert scan.source.ignored_channels == ("note",)


def test_epoch_times_and_the_default_block_size(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    path = _write(tmp_path / "epoch.csv", _table(epoch=True))
    assert_streams_exactly(path, chunks=(7, 65536))
    monkeypatch.setattr(csv_reader, "BLOCK_SIZE", 1 << 24)
    assert_streams_exactly(path, chunks=(1000,))


def test_the_shipped_sample_logs(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(csv_reader, "BLOCK_SIZE", 1 << 16)
    root = Path(__file__).resolve().parents[1] / "sample_logs" / "csv"
    for name in ("assist_impacts", "heavy_free_p2p"):
        assert_streams_exactly(root / f"{name}.csv.gz", chunks=(1000, 65536))


# ------------------------------------------------------------------------ repairs
def _punch(cols: dict[str, list[str]], rng: np.random.Generator, what: str, n_runs: int,
           max_len: int = 5) -> None:
    """Runs of ``what`` ("", "nan", "inf") of 1..max_len values in random value columns."""
    names = [c for c in cols if c not in ("time", "note")]
    n = len(cols["time"])
    for _ in range(n_runs):
        col = names[int(rng.integers(len(names)))]
        length = int(rng.integers(1, max_len + 1))
        s = int(rng.integers(1, n - length - 1))
        cols[col][s:s + length] = [what] * length


def test_non_finite_runs_and_duplicates_across_batches(tmp_path: Path,
                                                        tiny_blocks: None) -> None:
    rng = np.random.default_rng(5)
    cols = _table()
    _punch(cols, rng, "", 60)
    _punch(cols, rng, "nan", 20)
    _punch(cols, rng, "inf", 5, 3)
    # overlapping runs in two columns of one joint, and runs right next to each other
    cols["j1.torque"][500:505] = [""] * 5
    cols["j1.position"][503:506] = [""] * 3
    cols["j2.torque"][700:702] = [""] * 2
    cols["j2.torque"][703:708] = [""] * 5
    # exact duplicate rows (some twice, some with an empty cell in them)
    rows = sorted(rng.choice(np.arange(10, N - 10), 40, replace=False).tolist(), reverse=True)
    for i in rows:
        for c in cols.values():
            c.insert(i + 1, c[i])
    for c in cols.values():
        c.insert(2001, c[2000])
    path = _write(tmp_path / "repaired.csv", cols)
    scan = assert_streams_exactly(path)
    assert any("duplicate" in r for r in scan.source.repairs)
    assert sum("interpolated" in r for r in scan.source.repairs) >= 10


def test_channels_not_logged_and_joints_left_out(tmp_path: Path) -> None:
    cols = _table()
    cols["j2.torque_model"] = [""] * N  # the controller does not give it for j2
    cols["j3.position"] = ["nan"] * N  # a joint without position: left out
    cols["j3.torque"][5:8] = [""] * 3
    cols["j1.velocity"] = ["0.5"] * N  # a signal of one joint only: ignored
    scan = assert_streams_exactly(_write(tmp_path / "partial.csv", cols))
    assert scan.joint_names == ("j1", "j2")
    assert scan.source.joints_dropped and not scan.screens["torque_model"].logged[1]


def test_an_empty_torque_column_does_not_touch_a_torque_read_from_current(
        tmp_path: Path) -> None:
    """With --torque-source current, a joint whose .torque column holds no finite value (a
    dead sensor) keeps its torque from .current: the scan's first rows and the chunks
    alike (the scan once set them NaN and refused the log)."""
    cols = _table()
    rng = np.random.default_rng(4)
    for j in ("j1", "j2", "j3"):
        cols[f"{j}.current"] = [repr(float(v)) for v in rng.normal(0, 2, N)]
    cols["j2.torque"] = ["nan"] * N
    robot = RobotDescription(joints=tuple(JointSpec(j, 50.0, 0.1) for j in ("j1", "j2", "j3")))
    path = _write(tmp_path / "dead_sensor.csv", cols)
    scan = assert_streams_exactly(path, torque_source="current", robot=robot)
    assert scan.joint_names == ("j1", "j2", "j3")
    head = scan.log.torque[:, 1]  # the scan's first rows (the chunks equal them: above)
    current = np.array([float(v) for v in cols["j2.current"][:head.size]])
    np.testing.assert_allclose(head, current * 50.0 * 0.1, rtol=1e-12)


def test_an_optional_signal_without_a_value_is_read_as_not_logged(tmp_path: Path) -> None:
    """An all-empty j2.velocity and an all-NaN j3.velocity_ref (the other joints' finite):
    both signals are left out for every joint, with read_log's warning; j1's velocity and
    the other joints' velocity_ref are ignored. A joint left out (j3: no position) does not
    count: its empty acceleration_ref leaves the others' in the log."""
    cols = _table()
    for j in ("j1", "j2", "j3"):
        cols[f"{j}.velocity"] = [repr(0.01 * i) for i in range(N)]
        cols[f"{j}.velocity_ref"] = [repr(0.02 * i) for i in range(N)]
        cols[f"{j}.acceleration_ref"] = [repr(0.03 * i) for i in range(N)]
    cols["j2.velocity"] = [""] * N
    cols["j3.velocity_ref"] = ["NaN"] * N
    path = _write(tmp_path / "empty_optional.csv", cols)
    scan = assert_streams_exactly(path)
    assert scan.channels == ("position_ref", "acceleration_ref", "torque_model")
    assert scan.source.ignored_channels == ("note", "j1.velocity", "j3.velocity",
                                            "j1.velocity_ref", "j2.velocity_ref")
    msgs = [f"{path}: column 'j2.velocity' holds no finite value: velocity is read as not "
            "logged, for every joint (a log has a signal for all its joints or none)",
            f"{path}: column 'j3.velocity_ref' holds no finite value: velocity_ref is read as "
            "not logged, for every joint (a log has a signal for all its joints or none)"]
    assert [r for r in scan.source.repairs if "no finite value" in r] == msgs
    cols["j3.position"] = ["nan"] * N
    cols["j3.acceleration_ref"] = [""] * N
    scan = assert_streams_exactly(_write(tmp_path / "empty_optional_dropped.csv", cols))
    assert scan.joint_names == ("j1", "j2")
    assert scan.channels == ("position_ref", "velocity_ref", "acceleration_ref",
                             "torque_model")


def test_flat_and_unmeasured_torque_is_screened(tmp_path: Path) -> None:
    cols = _table()
    cols["j2.torque"] = ["0.25"] * N
    rng = np.random.default_rng(2)
    cols["j3.torque"] = [repr(float(v)) for v in rng.integers(-3, 4, N) * 0.001]
    cols["j1.torque_model"] = [repr(float(v)) for v in rng.integers(-3, 4, N) * 0.001]
    scan = assert_streams_exactly(_write(tmp_path / "screen.csv", cols))
    assert scan.torque_screen[1] is not None and scan.torque_screen[1].startswith("flat")
    assert scan.torque_screen[2] is not None and "unmeasured" in scan.torque_screen[2]
    assert scan.screens["torque_model"].unusable(scan.torque_ptp)[0] is not None


def test_time_units_and_integer_stamps(tmp_path: Path) -> None:
    cols = _table()
    t_ns = [int(s.replace(".", "")) for s in cols["time"]]
    ms = dict(cols, time=[f"{v // 10**6}.{v % 10**6:06d}" for v in t_ns])
    assert_streams_exactly(_write(tmp_path / "ms.csv", ms), chunks=(7, 65536), time_unit="ms")
    ns = {"time_ns": [str(v + 10**18) for v in t_ns], **{k: v for k, v in cols.items()
                                                         if k != "time"}}
    assert_streams_exactly(_write(tmp_path / "ns.csv", ns), chunks=(7, 65536))


def test_a_channel_mapped_csv_with_current(tmp_path: Path) -> None:
    rng = np.random.default_rng(9)
    t = np.arange(N) * 2 + 1000  # ms
    cols = {"ts": [str(v) for v in t]}
    for j in ("a", "b"):
        cols[f"q_{j}"] = [repr(float(v)) for v in rng.normal(size=N)]
        cols[f"i_{j}"] = [repr(float(v)) for v in rng.normal(size=N) * 1000]
        cols[f"tm_{j}"] = [repr(float(v)) for v in rng.normal(size=N)]
    cols["junk"] = ["1"] * N
    cols["i_b"][100:103] = ["", "", ""]
    path = _write(tmp_path / "dump.csv", cols, sep=";")
    cmap = tmp_path / "map.json"
    cmap.write_text(json.dumps({
        "csv": {"header": True, "delimiter": ";"},
        "time": {"column": "ts", "unit": "ms", "start_at_zero": True},
        "joints": [
            {"name": "a", "position": {"column": "q_a", "offset": 0.5},
             "current": {"column": "i_a", "scale": 0.002}, "torque_model": "tm_a"},
            {"name": "b", "position": {"column": "q_b", "scale": -1}, "current": "i_b",
             "torque_model": "tm_b"}]}))
    robot = RobotDescription(joints=(JointSpec("b", 100.0, 0.05), JointSpec("a", 50.0, 0.1)))
    scan = assert_streams_exactly(path, chunks=(7, 1000), channel_map=cmap, robot=robot)
    assert scan.source.format == "csv-mapped" and scan.t0_ns == 0


# -------------------------------------------------------------------------- errors
def _bad(tmp_path: Path, edit: Callable[[dict[str, list[str]]], None]) -> str:
    cols = _table()
    edit(cols)
    return read_error(_write(tmp_path / "bad.csv", cols))


def _set(col: str, i: int, v: str) -> Callable[[dict[str, list[str]]], None]:
    def edit(cols: dict[str, list[str]]) -> None:
        cols[col][i] = v
    return edit


def test_errors_name_the_cell_as_read_log_does(tmp_path: Path) -> None:
    assert "time is decreasing" in _bad(tmp_path, _set("time", 2500, "0.5"))
    assert "beyond ±1e+12" in _bad(tmp_path, _set("j2.torque", 2900, "1e13"))
    msg = _bad(tmp_path, lambda c: c["j1.torque"].__setitem__(slice(1200, 1206), [""] * 6))
    assert "a run of 6 non-finite" in msg
    assert "at the start" in _bad(tmp_path, _set("j3.position_ref", 0, ""))
    assert "at the end" in _bad(tmp_path, _set("j3.position_ref", N - 1, "nan"))
    assert "non-numeric" in _bad(tmp_path, _set("j1.position", 2999, "abc"))
    assert "not a finite number" in _bad(tmp_path, _set("time", 1500, "nan"))


def test_the_first_error_is_the_files_first_in_order(tmp_path: Path,
                                                      tiny_blocks: None) -> None:
    # a value too large early, rows out of order late: the order is checked first
    def both(cols: dict[str, list[str]]) -> None:
        cols["j1.torque"][10] = "5e12"
        cols["time"][2990] = cols["time"][2989]
        cols["j1.torque"][1000:1010] = [""] * 10
    assert "time is repeated" in _bad(tmp_path, both)

    def runs(cols: dict[str, list[str]]) -> None:  # the first column's run is named
        cols["j3.torque"][100:107] = [""] * 7
        cols["j1.torque"][2000:2008] = [""] * 8
    assert "'j1.torque'" in _bad(tmp_path, runs)


def test_a_time_unit_that_does_not_fit(tmp_path: Path) -> None:
    cols = _table()
    cols["time"] = [str(1000 * i) for i in range(N)]
    assert "implied sample rate" in read_error(_write(tmp_path / "ms.csv", cols))


def test_the_scan_warns_once_and_checks_its_options(tmp_path: Path) -> None:
    cols = _table()
    cols["j1.torque"][7] = ""
    path = _write(tmp_path / "x.csv", cols)
    scan, warned = scan_warned(path)
    assert len(warned) == 1
    with pytest.raises(ValueError):
        next(iter_chunks(path, scan, 0))
    with pytest.raises(ValueError):
        next(iter_chunks(path, scan, 10, time_unit="s"))


# ------------------------------------------------------------------------- variants
def test_iso_8601_time_streams(tmp_path: Path) -> None:
    rng = np.random.default_rng(9)
    cols = _table()
    _punch(cols, rng, "nan", 15)
    t_ns = 1_714_567_890 * 10**9 + np.array([round(float(v) * 1e9) for v in cols["time"]])
    stamps = np.datetime_as_string(t_ns.astype("datetime64[ns]"), unit="ns")
    for fmt in ("{}Z", "{}+02:00", "{}", " {} "):
        cols["time"] = [fmt.format(str(v)) for v in stamps]
        for c in cols.values():  # a duplicate row
            c.insert(1001, c[1000])
        scan = assert_streams_exactly(_write(tmp_path / "iso.csv", cols), chunks=(7, 1000))
        assert scan.t0_ns > 10**18
    assert "does not apply" in read_error(tmp_path / "iso.csv", time_unit="ms")
    cols["time"][2500] = "not a time"
    assert "is not an ISO-8601 time" in read_error(_write(tmp_path / "bad.csv", cols))


def test_repair_order_keeps_the_longest_increasing_run(tmp_path: Path) -> None:
    """Rows written late, a repeated stamp and duplicates across blocks: the rows kept are
    the longest increasing run of the stamps (repair.longest_increasing), dropped rows are
    counted in one repair, and the other repairs run over the rows kept."""
    from impactcli.logs.repair import longest_increasing

    rng = np.random.default_rng(3)
    cols = _table()
    _punch(cols, rng, "", 10)
    t = cols["time"][:]
    cols["time"][100], cols["time"][101] = cols["time"][101], cols["time"][100]
    cols["time"][2500] = cols["time"][1200]  # far out of order
    cols["time"][1700] = cols["time"][1699]  # a repeated stamp with other values
    for c in cols.values():  # an exact duplicate
        c.insert(901, c[900])
    path = _write(tmp_path / "late.csv", cols)
    scan = assert_streams_exactly(path, chunks=(7, 1000), repair_order=True)
    stamps = np.array([int(v.replace(".", "")) for v in cols["time"]])
    dedup = np.delete(stamps, 901)
    kept = dedup[longest_increasing(dedup)]
    assert np.array_equal(np.concatenate(
        [c.t_ns for c in iter_chunks(path, scan, 1000, repair_order=True)]), kept)
    assert t and scan.n_samples == kept.size == N - 3
    assert scan.source.repairs[:2] == (
        f"{path}: dropped 1 exact duplicate sample(s) (first at row 902 (line 903))",
        f"{path}: dropped 3 row(s) (1 out of time order, 2 with a repeated stamp; first at "
        f"row 101 (line 102)), keeping the longest increasing run of stamps ({N - 3} rows; "
        "--repair-order)")
    assert len([r for r in scan.source.repairs if "interpolated" in r]) == 8


def test_a_decimal_comma_and_a_byte_order_mark_stream(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    cols = _table()
    _punch(cols, rng, "", 20)  # short runs of empty cells
    for c in cols.values():  # duplicates
        c.insert(2001, c[2000])
    semi = {k: [v.replace(".", ",") for v in c] for k, c in cols.items()}
    assert_streams_exactly(_write(tmp_path / "semi.csv", semi, sep=";"), chunks=(7, 1000))
    for name in ("bom.csv", "bom.csv.gz"):
        text = _write(tmp_path / "b.csv", cols).read_bytes()
        bom = _write(tmp_path / name, {"x": ["0"]})
        if name.endswith(".gz"):
            bom.write_bytes(gzip.compress(b"\xef\xbb\xbf" + text))
        else:
            bom.write_bytes(b"\xef\xbb\xbf" + text)
        assert_streams_exactly(bom, chunks=(7, 1000))
    epoch = {k: [v.replace(".", ",") for v in c] for k, c in _table(epoch=True).items()}
    assert_streams_exactly(_write(tmp_path / "epoch_semi.csv", epoch, sep=";"), chunks=(1000,))


def test_message_logs_stream_too(tmp_path: Path) -> None:
    """MCAP and bags stream (tests/test_reader_formats.py has the cases)."""
    log, _ = read_warned(_write(tmp_path / "a.csv", _table()))
    for name in ("a.mcap", "a.db3", "a.bag"):
        write_log(log, tmp_path / name)
        assert_streams_exactly(tmp_path / name, chunks=(7, 1000))


def test_the_fast_decimal_time_is_decimal_text_to_ns() -> None:
    import pyarrow as pa
    import pyarrow.compute as pc

    from impactcli.logs.csv.csv_layout import decimal_text_to_ns
    from impactcli.logs.csv.csv_layout import decimal_to_ns as _decimal_ns

    rng = np.random.default_rng(4)
    ns = rng.integers(-10**18, 9 * 10**18, 2000)
    many = [f"{'-' if v < 0 else ''}{abs(v) // 10**9}.{abs(v) % 10**9:09d}" for v in ns]
    for texts in (many, ["-0.5", "007.5", "12", "0", "-0", "1.5"],
                  ["0.1234567891", "1714567890.1234567899"], ["8999999999.999999999"],
                  ["9300000000.5"]):
        for unit in (10**9, 10**6):
            arr = pa.array(texts)[1:] if len(texts) > 1 else pa.array(texts)
            tf = pc.cast(arr, pa.float64()).to_numpy()
            want, got = decimal_text_to_ns(arr, unit), _decimal_ns(arr, unit, tf)
            assert (want is None and got is None) or np.array_equal(want, got), texts[:3]


def test_a_rate_that_drops_after_the_start_takes_a_second_gap_pass(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Early batches at 4 ms steps set a floor above the final 1.5 ms threshold: the gaps
    are found again at the threshold, and equal the whole log's."""
    cols = _table()
    steps = np.where(np.arange(N) < 120, 4_000_000, 1_000_000)
    t_ns = np.cumsum(steps)
    cols["time"] = [f"{v // 10**9}.{v % 10**9:09d}" for v in t_ns.tolist()]
    calls = []
    real = scan_module._gap_pass
    monkeypatch.setattr(scan_module, "_gap_pass", lambda *a: calls.append(1) or real(*a))
    scan = assert_streams_exactly(_write(tmp_path / "drift.csv", cols), chunks=(1000,))
    assert calls and scan.gaps.size > 100


# ----------------------------------------------------------------- the scan's cache
def _scan_dirs(root: Path) -> list[Path]:
    return sorted(root.glob("impactcli-scan-*"))


@pytest.fixture
def _tmp_root(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Temporary files (the scan's cache) go to a folder of the test's own."""
    import tempfile

    root = tmp_path / "tmp"
    root.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(root))
    return root


def _inf_controller(tmp_path: Path) -> Path:
    """Non-finite runs, duplicates, and a controller column of infinities only (set to
    NaN by the passes after the scan, not by the scan's repairs)."""
    rng = np.random.default_rng(7)
    cols = _table()
    _punch(cols, rng, "", 30)
    _punch(cols, rng, "inf", 5, 3)
    cols["j2.torque_model"] = ["inf"] * N
    for c in cols.values():
        c.insert(1501, c[1500])
    return _write(tmp_path / "inf_controller.csv", cols)


@pytest.mark.parametrize("cached", ["yes", "disk full", "no temporary folder"])
def test_the_passes_after_the_scan_read_its_cache_or_the_file(
        tmp_path: Path, _tmp_root: Path, monkeypatch: pytest.MonkeyPatch,
        cached: str) -> None:
    """The chunks are read_log's whether they come from the scan's cache of the repaired
    rows or (a disk too full for it, no temporary folder) from parsing the file again."""
    import tempfile

    if cached == "disk full":
        monkeypatch.setattr(spill, "MIN_FREE_BYTES", float("inf"))
    elif cached == "no temporary folder":
        monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "missing"))
    scan = assert_streams_exactly(_inf_controller(tmp_path))
    ps = scan.reader._pass  # type: ignore[union-attr]
    assert (ps is not None and ps.cache is not None) is (cached == "yes")
    assert len(_scan_dirs(_tmp_root)) == int(cached == "yes")
    scan.close()
    assert not _scan_dirs(_tmp_root)
    assert ps is not None and ps.cache is None


def test_the_cache_is_deleted_with_the_scan_and_on_errors(
        tmp_path: Path, _tmp_root: Path) -> None:
    import gc

    path = _inf_controller(tmp_path)
    with scan_warned(path)[0] as scan:
        assert len(_scan_dirs(_tmp_root)) == 1
        first = list(iter_chunks(path, scan, 1000))
    assert not _scan_dirs(_tmp_root)
    after = list(iter_chunks(path, scan, 1000))  # closed: the file is parsed again
    for a, b in zip(first, after, strict=True):
        assert np.array_equal(a.torque, b.torque, equal_nan=True)
    scan = scan_warned(path)[0]
    it = iter_chunks(path, scan, 100)
    next(it)
    del scan, it
    gc.collect()
    assert not _scan_dirs(_tmp_root)
    cols = _table()
    cols["j1.torque"][2500] = "1e13"
    with pytest.raises(LogFormatError), warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        scan_log(_write(tmp_path / "bad.csv", cols))
    assert not _scan_dirs(_tmp_root)


@pytest.mark.parametrize("end", ["\r\n", "\r"])
def test_line_ends_across_the_parsed_ranges(tmp_path: Path, end: str,
                                            tiny_blocks: None) -> None:
    """The text is cut into ranges at line ends (io/csv.py, 4 KiB here): with
    CRLF and CR-only lines the rows are read_log's."""
    cols = _table()
    path = _write(tmp_path / "ends.csv", cols)
    path.write_bytes(path.read_bytes().replace(b"\n", end.encode()))
    assert_streams_exactly(path, chunks=(1000,))


@pytest.mark.parametrize("block", [7, 61, 4096])
def test_parsed_ranges_are_the_whole_files_rows(tmp_path: Path, block: int) -> None:
    """Ranges cut at every place, between a CR and its LF included (tiny blocks): the
    batches concatenated are the whole file parsed at once."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from impactcli.logs.csv.csv_layout import csv_layout
    from impactcli.logs.csv.csv_read import parsed_ranges

    cols = {k: v[:300] for k, v in _table().items()}
    path = _write(tmp_path / "crlf.csv", cols)
    path.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))
    lay = csv_layout(path, None)
    names = list(cols)
    copts = pacsv.ConvertOptions(column_types={"time": pa.string()})
    tables = parsed_ranges(lay, names, block, lambda parse, first: parse(copts))
    got = pa.concat_tables([t for t in tables if t.num_rows])
    assert got.equals(pacsv.read_csv(path, convert_options=copts))
