"""Logs as loggers write them, through the command line: time
columns by their common names (their unit from the name), blanks around separators,
``--time-column`` and ``--rate`` through the one read-option path (recorded in the
timeline, read again by ``report``), the separator of a mapped CSV detected, and a low
rate told apart from a time unit."""

from __future__ import annotations

import functools
import gzip
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.errors import ImpactWarning, LogFormatError
from impactcli.logs import read_log
from impactcli.logs.repair import rate_message
from impactcli.types import RobotLog

from .cli_run import cli

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"  # 40 s, 250 Hz, 2 joints
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"
# a light layout of the sample: time, then position, torque and the external torque the
# config's generator reads, of its two joints
COLUMNS = ("time", "shoulder.position", "shoulder.torque", "shoulder.torque_ext",
           "elbow.position", "elbow.torque", "elbow.torque_ext")


@functools.cache
def _sample() -> tuple[tuple[str, ...], tuple[tuple[str, ...], ...]]:
    """The sample log's header and rows (text cells) of :data:`COLUMNS`."""
    lines = gzip.decompress(SAMPLE.read_bytes()).decode().splitlines()
    head = lines[0].split(",")
    idx = [head.index(c) for c in COLUMNS]
    rows = tuple(tuple(r.split(",")[i] for i in idx) for r in lines[1:] if r)
    return COLUMNS, rows


def _write(path: Path, header: list[str], rows: list[list[str]], sep: str = ",") -> Path:
    path.write_text("".join(sep.join(r) + "\n" for r in [header, *rows]), encoding="utf-8")
    return path


def _times_in(unit: str) -> list[str]:
    """The sample's times (4 ms steps) as text in ``unit``."""
    n = len(_sample()[1])
    if unit == "s":
        return [f"{4 * i / 1000:.3f}" for i in range(n)]
    step = {"ms": 4, "us": 4_000, "ns": 4_000_000}[unit]
    return [str(step * i) for i in range(n)]


def _with_time(path: Path, name: str | None, unit: str = "s", sep: str = ",") -> Path:
    """The sample with its time column named ``name`` in ``unit`` (None: no time column)."""
    header, rows = _sample()
    times = _times_in(unit)
    if name is None:
        return _write(path, list(header[1:]), [list(r[1:]) for r in rows], sep)
    return _write(path, [name, *header[1:]], [[t, *r[1:]] for t, r in zip(times, rows,
                                                                        strict=True)], sep)


def _errors(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ln.startswith("impactcli: error:")]


def _inspect(path: Path, *opts: str) -> dict[str, object]:
    code, out, err = cli("inspect", str(path), "--json", *opts)
    assert code == 0, err
    d: dict[str, object] = json.loads(out)
    return d


def _read(path: Path, **kw: object) -> RobotLog:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        return read_log(path, **kw)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def canonical(tmp_path_factory: pytest.TempPathFactory) -> RobotLog:
    return _read(_with_time(tmp_path_factory.mktemp("c") / "c.csv", "time"))


# ---------------------------------------------------------------------- time columns
@pytest.mark.parametrize(("name", "unit"), [
    ("Time", "s"), ("timestamp", "s"), ("t", "s"), ("stamp", "s"), ("TIME", "s"),
    ("time_ms", "ms"), ("time_us", "us"), ("Timestamp_ns", "ns"), ("stamp_ms", "ms"),
    ("t_s", "s"), ("__time", "s"),
])
def test_time_columns_by_their_common_names_with_the_unit_of_their_suffix(
        tmp_path: Path, canonical: RobotLog, name: str, unit: str) -> None:
    path = _with_time(tmp_path / "log.csv", name, unit)
    d = _inspect(path)
    assert d["sample_rate_hz"] == 250.0 and d["duration_s"] == 40.0
    assert d["n_samples"] == canonical.n_samples
    log = _read(path)
    np.testing.assert_array_equal(log.t_ns, canonical.t_ns)
    np.testing.assert_array_equal(log.position, canonical.position)


def test_a_unit_given_against_the_name_wins_warned_and_one_the_name_lacks_applies(
        tmp_path: Path) -> None:
    """The user's --time-unit wins over the column's name (a column named time_ms that
    holds microseconds), with a warning naming what it replaced; a wrong one is then
    caught by the rate check, naming the unit that fits."""
    us = _with_time(tmp_path / "us.csv", "time_ms", "us")  # mislabelled: us, named ms
    code, out, err = cli("inspect", str(us), "--json", "--time-unit", "us")
    assert code == 0, err
    assert json.loads(out)["sample_rate_hz"] == 250.0
    assert (f"impactcli: warning: {us}: --time-unit us given: column 'time_ms' is read in "
            "us, not in ms as its name says") in err
    ms = _with_time(tmp_path / "ms.csv", "time_ms", "ms")
    code, _, err = cli("inspect", str(ms), "--time-unit", "us")
    assert code == 3
    assert "read in us, it looks like ms (250 Hz)" in _errors(err)[0]
    stamp = _with_time(tmp_path / "stamp.csv", "Stamp", "ms")
    assert _inspect(stamp, "--time-unit", "ms")["sample_rate_hz"] == 250.0


def test_no_time_column_names_the_ways_out(tmp_path: Path) -> None:
    path = _with_time(tmp_path / "elapsed.csv", "elapsed")
    code, _, err = cli("detect", str(path), "--config", str(CONFIG), "-o", str(tmp_path / "o"))
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {path}: no time column (recognised: time, timestamp, stamp, t or "
        "PlotJuggler's __time, any case, with an optional unit suffix _s, _ms, _us or _ns): "
        "name yours with --time-column NAME, give --rate HZ for a log without one, or pass a "
        "channel map (--channel-map) for other layouts"]


def test_time_column_option_names_any_column(tmp_path: Path, canonical: RobotLog) -> None:
    path = _with_time(tmp_path / "elapsed.csv", "elapsed")
    d = _inspect(path, "--time-column", "elapsed")
    assert d["sample_rate_hz"] == 250.0 and d["duration_s"] == 40.0
    np.testing.assert_array_equal(_read(path, time_column="elapsed").t_ns, canonical.t_ns)
    ms = _with_time(tmp_path / "elapsed_ms.csv", "Elapsed_ms", "ms")  # the unit of its suffix
    assert _inspect(ms, "--time-column", "elapsed_ms")["duration_s"] == 40.0
    code, _, err = cli("inspect", str(path), "--time-column", "clock")
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {path}: --time-column 'clock' is not a column of the file (its "
        "columns: elapsed, shoulder.position, shoulder.torque, shoulder.torque_ext, "
        "elbow.position, elbow.torque, elbow.torque_ext)"]


@pytest.mark.parametrize("sep", [", ", " ,", ";  ", "\t ", " , "])
def test_blanks_around_separators_are_not_part_of_names_or_cells(
        tmp_path: Path, canonical: RobotLog, sep: str) -> None:
    """``printf("%f, %f\\n")`` loggers write a blank after each separator (this header used
    to crash with exit 70, KeyError 'Field "shoulder.position" does not exist in schema');
    every verb reads such a file as the plain one."""
    path = _with_time(tmp_path / "printf.csv", "time", sep=sep)
    log = _read(path)
    assert log.joint_names == canonical.joint_names
    np.testing.assert_array_equal(log.t_ns, canonical.t_ns)
    np.testing.assert_array_equal(log.torque, canonical.torque)
    code, _, err = cli("labels", str(path), "--from-channel", "elbow.torque", "--above",
                       "1e9", "--link", "2", "-o", str(tmp_path / "l.json"))
    assert code == 0, err


def test_a_printf_log_is_detected_as_the_plain_one(tmp_path: Path) -> None:
    plain = _with_time(tmp_path / "plain.csv", "time")
    header, rows = _sample()
    quoted = tmp_path / "quoted.csv"
    quoted.write_text(", ".join(f'"{h}"' for h in header) + "\n"
                      + "".join(", ".join(r) + "\n" for r in rows), encoding="utf-8")
    tls = {}
    for path in (plain, quoted):
        code, _, err = cli("detect", str(path), "--config", str(CONFIG), "-o",
                           str(tmp_path / "out"))
        assert code == 0, err
        tls[path.stem] = json.loads((tmp_path / "out" / f"{path.stem}.timeline.json")
                                    .read_text())
    for key in ("events", "incidents", "thresholds", "summary", "warmup_end_s"):
        assert tls["quoted"][key] == tls["plain"][key], key


# ---------------------------------------------------------------------------- --rate
def test_rate_reads_a_log_without_time_and_is_recorded_and_read_again(
        tmp_path: Path, canonical: RobotLog) -> None:
    path = _with_time(tmp_path / "norate.csv", None)
    code, _, err = cli("detect", str(path), "--rate", "250", "--config", str(CONFIG),
                       "-o", str(tmp_path / "out"))
    assert code == 0, err
    note = (f"{path}: sample i is at i / 250 Hz (--rate 250), not at a logged time, so gaps "
            "and jitter cannot be seen")
    assert f"impactcli: warning: {note}" in err.splitlines()
    tl = json.loads((tmp_path / "out" / "norate.timeline.json").read_text())
    assert tl["input"]["read_options"] == {"rate": 250.0}
    assert tl["input"]["sample_rate_hz"] == 250.0 and tl["input"]["duration_s"] == 40.0
    assert note in tl["input"]["repairs"]
    np.testing.assert_array_equal(_read(path, rate=250).t_ns, canonical.t_ns)
    # the report reads the log again with the timeline's read options
    tl_path = tmp_path / "out" / "norate.timeline.json"
    code, _, err = cli("report", str(tl_path), "-o", str(tmp_path / "r.html"), "--json",
                       str(tmp_path / "r.json"))
    assert code == 0, err
    assert (tmp_path / "r.json").is_file()


def test_time_column_is_recorded_and_report_reads_the_log_again_with_it(
        tmp_path: Path) -> None:
    path = _with_time(tmp_path / "elapsed.csv", "elapsed")
    code, _, err = cli("detect", str(path), "--time-column", "elapsed", "--config",
                       str(CONFIG), "-o", str(tmp_path / "out"))
    assert code == 0, err
    tl_path = tmp_path / "out" / "elapsed.timeline.json"
    assert json.loads(tl_path.read_text())["input"]["read_options"] == {
        "time_column": "elapsed"}
    code, _, err = cli("report", str(tl_path), "-o", str(tmp_path / "r.html"))
    assert code == 0, err


def test_a_bad_cell_in_a_log_read_with_rate_is_one_line(tmp_path: Path) -> None:
    """No time column (--rate) and a non-numeric cell: the exact reader's error (exit 3
    naming the cell), not pyarrow's TypeError on a time column that does not exist."""
    rows = ["j1.position,j1.torque", "0.1,1.0", "0.2,abc"]
    rows += [f"0.{k},1.{k}" for k in range(3, 200)]
    log = tmp_path / "norate.csv"
    log.write_text("\n".join(rows) + "\n")
    r = CliRunner().invoke(main, ["inspect", str(log), "--rate", "500"])
    assert r.exit_code == 3, r.output
    assert r.stderr.strip().splitlines() == [
        f"impactcli: error: {log}: column 'j1.torque', row 2 (line 3): non-numeric value 'abc'"]


def test_rate_wins_over_a_time_column_warned(tmp_path: Path) -> None:
    """--rate on a log that has a time column places sample i at i / rate (the user's
    option wins), warned, naming the column not read as the clock; with --time-unit it
    stays a usage error (they contradict each other)."""
    timed = _with_time(tmp_path / "timed.csv", "Time")  # 250 Hz by its column
    code, out, err = cli("inspect", str(timed), "--json", "--rate", "500")
    assert code == 0, err
    assert json.loads(out)["sample_rate_hz"] == 500.0
    assert (f"impactcli: warning: {timed}: --rate 500 given: sample i is placed at i / 500 s "
            "and the time column 'Time' is not read as the log's clock") in err
    code, _, err = cli("inspect", str(timed), "--rate", "250", "--time-unit", "ms")
    assert code == 2
    assert "--rate places sample i at i / rate: it excludes --time-unit and " \
           "--time-column" in err

def test_rate_reads_an_npz_whose_map_names_no_time(tmp_path: Path, canonical: RobotLog) -> None:
    npz = tmp_path / "ident.npz"
    np.savez(npz, q=canonical.position, tau=canonical.torque)
    cmap = tmp_path / "ident.yaml"
    cmap.write_text("format: npz\njoints:\n"
                    "  - {name: shoulder, position: {key: q, index: 0}, "
                    "torque: {key: tau, index: 0}}\n"
                    "  - {name: elbow, position: {key: q, index: 1}, "
                    "torque: {key: tau, index: 1}}\n")
    code, _, err = cli("inspect", str(npz), "--channel-map", str(cmap))
    assert code == 3
    assert _errors(err) == [f"impactcli: error: {npz}: channel map {cmap} has no time channel: "
                            "give --rate HZ for a log without one, or --time-column NAME"]
    d = _inspect(npz, "--channel-map", str(cmap), "--rate", "250")
    assert d["sample_rate_hz"] == 250.0 and d["n_samples"] == canonical.n_samples
    log = _read(npz, channel_map=str(cmap), rate=250.0)
    np.testing.assert_array_equal(log.t_ns, canonical.t_ns)
    np.testing.assert_array_equal(log.torque, canonical.torque)


# ---------------------------------------------------------------------------- low rates
def _low_rate_csv(path: Path, n: int = 260, step_s: float = 0.1, t0: float = 3262.0) -> Path:
    rng = np.random.default_rng(3)
    lines = ["timestamp,j1.position,j1.torque"]
    for i in range(n):
        lines.append(f"{t0 + step_s * i:.3f},{np.sin(i / 20):.5f},{rng.normal():.4f}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_a_low_rate_log_read_right_is_told_its_rate_is_too_low_not_another_unit(
        tmp_path: Path) -> None:
    """A real UR RTDE export at 10 Hz was told 'it looks like ms (10 kHz)': following that
    gave a 26 ms log. Read in seconds it is a plausible 26 s log at a rate too low."""
    path = _low_rate_csv(tmp_path / "rtde10.csv")
    for verb in (["inspect"], ["detect", "-o", str(tmp_path / "o")]):
        code, _, err = cli(verb[0], str(path), *verb[1:])
        assert code == 3
        assert _errors(err) == [
            f"impactcli: error: {path}: column 'timestamp': the sample rate is 10 Hz (a log "
            "of 25.9 s, read in s): too low for impact detection, which needs at least "
            "100 Hz (twice the detector's band-pass corner w2 = 50 Hz): record the arm at "
            "100 Hz or more; if the time column is not in s, give --time-unit s|ms|us|ns"]
    code, _, err = cli("inspect", str(_with_time(tmp_path / "n.csv", None)), "--rate", "10")
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {tmp_path / 'n.csv'}: --rate: the rate given is 10 Hz: too low "
        "for impact detection, which needs at least 100 Hz (twice the detector's band-pass "
        "corner w2 = 50 Hz): record the arm at 100 Hz or more"]


def test_a_time_in_ms_read_as_seconds_is_still_told_its_unit(tmp_path: Path) -> None:
    """1 kHz stamps in ms read as s: 1 Hz over 16 h, while ms gives 1 kHz over a minute."""
    path = _low_rate_csv(tmp_path / "ms.csv", n=60_000, step_s=1.0, t0=0.0)
    code, _, err = cli("inspect", str(path))
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {path}: column 'timestamp': the implied sample rate is 1 Hz, "
        "outside 20 Hz – 100 kHz; read in s, it looks like ms (1 kHz): give the time unit "
        "with --time-unit s|ms|us|ns (or 'unit' under 'time' in a channel map)"]
    assert _inspect(path, "--time-unit", "ms")["sample_rate_hz"] == 1000.0


def test_what_plausible_means_for_a_low_rate() -> None:
    """Another unit is suggested when it gives a controller's rate over at least a second,
    or when the unit read makes the log last beyond a day (docs/formats.md, "Time")."""
    def says_unit(rate: float, dur: float | None, unit: str | None = "s") -> bool:
        msg = rate_message(rate, "x.csv", "column 't'", unit, dur)
        assert msg is not None
        return "it looks like" in msg

    assert not says_unit(10.0, 26.0)  # 10 Hz RTDE: ms would be 10 kHz over 26 ms
    assert not says_unit(10.0, 3600.0)  # an hour at 10 Hz: ms would be 10 kHz, not typical
    assert says_unit(0.25, 40_000.0)  # 250 Hz in ms over 40 s
    assert says_unit(1.0, 5_000.0)  # 1 kHz in ms over 5 s
    assert not says_unit(1.0, 500.0)  # ms would give 0.5 s: no log, so a rate too low
    assert says_unit(8.0, 200_000.0)  # 8 kHz in ms (not typical), but 2.3 days read in s
    assert says_unit(2.5e-7, 4e6)  # ns read as s
    assert not says_unit(5.0, 60.0, None)  # ISO stamps: no unit to suggest
    assert rate_message(25.0, "x.csv", "column 't'", "s", 60.0) is None


# --------------------------------------------------------------- mapped CSV separators
def _rtde_export(path: Path, sep: str, n: int = 1000) -> Path:
    """A UR RTDE recorder's columns (``ur_rtde_example``'s) separated by ``sep``."""
    fields = ("actual_q", "actual_qd", "actual_current", "target_q", "target_qd",
              "target_qdd", "target_moment")
    cols = ["timestamp"] + [f"{f}_{k}" for f in fields for k in range(6)]
    t = 1000.0 + 0.002 * np.arange(n)
    data = [t] + [np.sin(0.5 * t + k + 0.1 * i) for i in range(len(fields)) for k in range(6)]
    rows = [sep.join(f"{v:.6f}" for v in r) for r in np.column_stack(data)]
    path.write_text(sep.join(cols) + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize("sep", [" ", ",", ";", "\t"])
def test_the_ur_rtde_map_reads_its_columns_whatever_the_separator(
        tmp_path: Path, sep: str) -> None:
    space = _read(_rtde_export(tmp_path / "space.csv", " "), channel_map="ur_rtde_example")
    path = _rtde_export(tmp_path / "export.csv", sep)
    code, out, err = cli("inspect", str(path), "--channel-map", "ur_rtde_example", "--json")
    assert code == 0, err
    assert json.loads(out)["n_samples"] == 1000
    log = _read(path, channel_map="ur_rtde_example")
    np.testing.assert_array_equal(log.t_ns, space.t_ns)
    np.testing.assert_array_equal(log.position, space.position)
    np.testing.assert_array_equal(log.torque_model, space.torque_model)


def test_a_map_may_still_force_its_separator(tmp_path: Path) -> None:
    path = _rtde_export(tmp_path / "comma.csv", ",")
    forced = tmp_path / "forced.yaml"
    forced.write_text("format: csv\ncsv: {header: true, delimiter: ';'}\n"
                      "time: {column: timestamp}\n"
                      "joints:\n  - {name: a, position: actual_q_0, torque: target_moment_0}\n")
    code, _, err = cli("inspect", str(path), "--channel-map", str(forced))
    assert code == 3
    assert _errors(err)[0].startswith(
        f"impactcli: error: {path}: channel map {forced}: time points at column 'timestamp', "
        "which is not in the file (its columns split at ';': timestamp,actual_q_0,")


def test_a_headerless_map_finds_a_semicolon_separator(tmp_path: Path) -> None:
    path = tmp_path / "dump.csv"
    k = np.arange(2000)
    path.write_text("".join(f"{0.004 * i:.3f};{np.sin(i / 50):.5f};{np.cos(i / 40):.4f}\n"
                            for i in k), encoding="utf-8")
    cmap = tmp_path / "dump.yaml"
    cmap.write_text("format: csv\ncsv: {header: false}\ntime: 0\n"
                    "joints:\n  - {name: a, position: 1, torque: 2}\n")
    log = _read(path, channel_map=str(cmap))
    assert log.n_samples == 2000 and log.sample_rate_hz == 250.0
    np.testing.assert_allclose(log.torque[:, 0], np.round(np.cos(k / 40), 4))


def test_a_map_for_a_log_without_time_with_rate_and_a_map_with_time_without(
        tmp_path: Path) -> None:
    path = _rtde_export(tmp_path / "e.csv", " ")
    code, out, err = cli("inspect", str(path), "--json", "--channel-map", "ur_rtde_example",
                         "--rate", "500")
    assert code == 0, err  # the user's rate wins over the map's time, warned
    assert json.loads(out)["sample_rate_hz"] == 500.0
    assert f"impactcli: warning: {path}: --rate 500 given: sample i is placed at i / 500 s" \
        in err and "(timestamp) is not read as the log's clock" in err


def test_time_column_replaces_a_maps_time(tmp_path: Path) -> None:
    path = _rtde_export(tmp_path / "e.csv", ",")
    text = path.read_text().replace("timestamp", "controller_time_ms", 1)
    lines = text.splitlines()
    ms = [lines[0]] + [",".join([f"{float(r.split(',')[0]) * 1000:.3f}", *r.split(",")[1:]])
                       for r in lines[1:]]
    path.write_text("\n".join(ms) + "\n")
    d = _inspect(path, "--channel-map", "ur_rtde_example", "--time-column",
                 "controller_time_ms")
    assert d["sample_rate_hz"] == pytest.approx(500.0) and d["n_samples"] == 1000


def test_the_read_option_errors_of_the_api_are_log_format_errors(tmp_path: Path) -> None:
    path = _with_time(tmp_path / "x.csv", "time")
    with pytest.raises(LogFormatError, match="excludes --time-unit and --time-column"):
        _read(path, rate=250.0, time_column="time")
    with pytest.raises(LogFormatError, match="unknown position unit 'grad'"):
        _read(path, position_unit="grad")


def test_ros_effort_columns_read_as_torque_and_a_torque_column_wins(tmp_path: Path) -> None:
    """ROS JointState's ``<joint>.effort`` is the joint's torque when it has no
    ``.torque``; with both, ``.torque`` is read and the effort column is named, warned."""
    header, rows = _sample()
    canonical = _read(_write(tmp_path / "c.csv", list(header), [list(r) for r in rows]))
    effort = [h.removesuffix(".torque") + ".effort" if h.endswith(".torque") else h
              for h in header]
    log = _read(_write(tmp_path / "e.csv", effort, [list(r) for r in rows]))
    np.testing.assert_array_equal(log.torque, canonical.torque)
    torque_cols = [i for i, h in enumerate(header) if h.endswith(".torque")]
    both = [*header, *(effort[i] for i in torque_cols)]
    doubled = [[*r, *("999" for _ in torque_cols)] for r in rows]
    path = _write(tmp_path / "b.csv", both, doubled)
    with pytest.warns(ImpactWarning, match=r"has both '\w+\.torque' and '\w+\.effort': "
                                           r"'\w+\.torque' is read as its torque"):
        log = read_log(path)
    np.testing.assert_array_equal(log.torque, canonical.torque)
