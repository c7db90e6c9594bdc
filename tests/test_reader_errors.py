"""Every bad input gives a LogFormatError naming the file — and through the CLI exit 3, one line."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.errors import ChannelMapError, LogFormatError
from impactcli.logs import read_log, write_log

from .conftest import make_log

CSV_HEAD = "time,j1.position,j1.torque,j2.position,j2.torque\n"


def _csv(tmp: Path, body: str, head: str = CSV_HEAD, name: str = "bad.csv") -> Path:
    p = tmp / name
    p.write_text(head + body)
    return p


def _rows(n: int, dt: float = 0.01) -> list[list[float]]:
    return [[i * dt, 0.1 * i, 1.0 + i, -0.1 * i, 2.0 - i] for i in range(n)]


def _fmt(rows: list[list[float]]) -> str:
    return "".join(",".join("nan" if np.isnan(v) else repr(v) for v in r) + "\n" for r in rows)


def _npz_mismatch(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = tmp / "bad.npz"
    np.savez(p, times=np.arange(10) * 0.01, positions=np.zeros((10, 2)), torques=np.zeros((9, 2)))
    return p, {"channel_map": _npz_map(tmp)}


def _npz_map(tmp: Path) -> Path:
    m = tmp / "map.yaml"
    m.write_text(
        "time: {key: times}\njoints:\n"
        "  - {name: a, position: {key: positions, index: 0}, torque: {key: torques, index: 0}}\n"
        "  - {name: b, position: {key: positions, index: 1}, torque: {key: torques, index: 1}}\n"
    )
    return m


def _case_missing(tmp: Path) -> tuple[Path, dict[str, object]]:
    return tmp / "nope.csv", {}


def _case_unknown(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = tmp / "log.parquet"
    p.write_bytes(b"PAR1")
    return p, {}


def _case_no_time(tmp: Path) -> tuple[Path, dict[str, object]]:
    head = "j1.position,j1.torque,j2.position,j2.torque\n"
    return _csv(tmp, "0.1,1,0.2,2\n0.2,1,0.3,2\n", head=head), {}


def _case_non_monotonic(tmp: Path) -> tuple[Path, dict[str, object]]:
    r = _rows(10)
    r[5][0] = r[3][0]
    return _csv(tmp, _fmt(r)), {}


def _case_duplicate_time(tmp: Path) -> tuple[Path, dict[str, object]]:
    r = _rows(10)
    r[5][0] = r[4][0]  # same time, different values: not an exact duplicate
    return _csv(tmp, _fmt(r)), {}


def _case_missing_torque(tmp: Path) -> tuple[Path, dict[str, object]]:
    head = "time,j1.position,j1.torque,j2.position\n"
    return _csv(tmp, "".join(f"{i * 0.01},{i},{i},{i}\n" for i in range(5)), head=head), {}


def _case_nan_run(tmp: Path) -> tuple[Path, dict[str, object]]:
    r = _rows(30)
    for i in range(10, 17):  # 7 > MAX_GAP_SAMPLES
        r[i][2] = float("nan")
    return _csv(tmp, _fmt(r)), {}


def _case_inf_run(tmp: Path) -> tuple[Path, dict[str, object]]:
    r = _rows(30)
    for i in range(3, 12):
        r[i][1] = float("inf")
    return _csv(tmp, _fmt(r)), {}


def _case_nan_at_start(tmp: Path) -> tuple[Path, dict[str, object]]:
    r = _rows(30)
    r[0][4] = float("nan")
    return _csv(tmp, _fmt(r)), {}


def _case_non_numeric(tmp: Path) -> tuple[Path, dict[str, object]]:
    lines = _fmt(_rows(10)).splitlines(keepends=True)
    cells = lines[4].split(",")
    cells[2] = "abc"  # j1.torque of data row 5 (file line 6)
    lines[4] = ",".join(cells)
    return _csv(tmp, "".join(lines)), {}


def _case_map_points_at_nothing(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = _csv(tmp, _fmt(_rows(5)), head="", name="raw.csv")
    m = tmp / "map.json"
    m.write_text('{"csv": {"header": false}, "time": 0, "joints": '
                 '[{"name": "a", "position": 1, "torque": 42}]}')
    return p, {"channel_map": m}


def _case_map_bad_key(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = tmp / "x.npz"
    np.savez(p, t=np.arange(5.0), q=np.zeros((5, 2)))
    return p, {"channel_map": _npz_map(tmp)}


def _case_corrupt_mcap(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = tmp / "bad.mcap"
    p.write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 4)
    return p, {}


def _case_not_mcap(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = tmp / "bad.mcap"
    p.write_bytes(b"hello, this is not an mcap file at all")
    return p, {}


def _case_corrupt_chunk(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = tmp / "bad.mcap"
    write_log(make_log(n=200, with_ref=False), p, mcap_encoding="ros2")
    data = bytearray(p.read_bytes())
    mid = len(data) // 3
    data[mid : mid + 64] = b"\xff" * 64  # inside the zstd chunk
    p.write_bytes(bytes(data))
    return p, {}


def _case_missing_topic(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = tmp / "ok.mcap"
    write_log(make_log(n=50, with_ref=False), p, mcap_encoding="ros2")
    return p, {"topic": "/no_such_topic"}


def _case_empty(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = tmp / "empty.csv"
    p.write_text("")
    return p, {}


def _case_npz_without_map(tmp: Path) -> tuple[Path, dict[str, object]]:
    p = tmp / "x.npz"
    np.savez(p, t=np.arange(5.0))
    return p, {}


def _case_ragged_line(tmp: Path) -> tuple[Path, dict[str, object]]:
    r = _fmt(_rows(10)).splitlines(keepends=True)
    return _csv(tmp, "".join(r[:4]) + "garbage,line,here\n" + "".join(r[4:])), {}


CASES: dict[str, tuple[Callable[[Path], tuple[Path, dict[str, object]]], str]] = {
    "missing file": (_case_missing, "not found"),
    "unknown format": (_case_unknown, "unknown log format"),
    "csv without time": (_case_no_time, "no time column"),
    "non-monotonic time": (_case_non_monotonic, r"column 'time', row 6 .*decreasing"),
    "duplicated timestamp": (_case_duplicate_time, r"column 'time', row 6 .*repeated"),
    "joint missing torque": (_case_missing_torque, "joint 'j2' has neither a torque nor a current"),
    "mismatched npz lengths": (_npz_mismatch, "mismatched channel lengths"),
    "NaN run": (_case_nan_run, r"column 'j1.torque', row 11 .*7 non-finite \(NaN\)"),
    "inf run": (_case_inf_run, r"column 'j1.position', row 4 .*infinite"),
    "NaN at start": (_case_nan_at_start, r"column 'j2.torque', row 1 .*start of the log"),
    "non-numeric cell": (_case_non_numeric,
                         r"column 'j1.torque', row 5 \(line 6\): non-numeric value 'abc'"),
    "map points at nothing": (_case_map_points_at_nothing, "points at column 42"),
    "map key not in npz": (_case_map_bad_key, "points at array 'times'"),
    "corrupt mcap": (_case_corrupt_mcap, "corrupt"),
    "not an mcap": (_case_not_mcap, "not an MCAP file"),
    "corrupt chunk": (_case_corrupt_chunk, "corrupt chunk"),
    "mcap topic missing": (_case_missing_topic,
                           r"topic '/no_such_topic' not found \(topics: /joint_states\)"),
    "empty csv": (_case_empty, "empty file"),
    "ragged line": (_case_ragged_line,
                    r"cannot parse CSV: line 6: 3 fields where the header has 5: garbage"
                    r"[^—]*$"),
    "npz without map": (_case_npz_without_map, "needs a channel map"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_is_a_log_format_error_naming_the_file(tmp_path: Path, case: str) -> None:
    make, pattern = CASES[case]
    path, kwargs = make(tmp_path)
    with pytest.raises(LogFormatError) as info:
        read_log(path, **kwargs)  # type: ignore[arg-type]
    msg = str(info.value)
    assert msg.startswith(str(path)), msg
    assert "\n" not in msg
    assert re.search(pattern, msg), msg


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_through_cli_exit_3_one_line(tmp_path: Path, case: str) -> None:
    make, pattern = CASES[case]
    path, kwargs = make(tmp_path)
    args = ["inspect", str(path)]
    if "channel_map" in kwargs:
        args += ["--channel-map", str(kwargs["channel_map"])]
    if "topic" in kwargs:
        args += ["--topic", str(kwargs["topic"])]
    res = CliRunner().invoke(main, args)
    detail = f"stdout={res.stdout!r} stderr={res.stderr!r}"
    assert res.exit_code == 3, detail
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, detail
    assert lines[0].startswith(f"impactcli: error: {path}"), detail
    assert re.search(pattern, lines[0]), detail
    assert "Traceback" not in res.stderr + res.stdout
    assert res.stdout == ""


def test_channel_map_errors_are_channel_map_errors(tmp_path: Path) -> None:
    path, kwargs = _case_map_points_at_nothing(tmp_path)
    with pytest.raises(ChannelMapError):
        read_log(path, **kwargs)  # type: ignore[arg-type]
    bad = tmp_path / "bad_map.yaml"
    bad.write_text("time: 0\njoints: [{name: a}]\n")  # no position
    with pytest.raises(ChannelMapError, match=r"bad_map.yaml.*position"):
        read_log(path, channel_map=bad)
    with pytest.raises(ChannelMapError, match=r"channel map not found.*shipped: .*kuka_lwr4"):
        read_log(path, channel_map="no_such_map")


def test_bad_option_value_is_usage_error(tmp_path: Path) -> None:
    p = tmp_path / "x.csv"
    write_log(make_log(n=20), p)
    res = CliRunner().invoke(main, ["inspect", str(p), "--time-source", "wall"])
    assert res.exit_code == 2


def test_current_without_robot_names_the_joint(tmp_path: Path) -> None:
    p = tmp_path / "c.csv"
    p.write_text("time,a.position,a.current,b.position,b.current\n0,0,1,0,1\n0.01,0,1,0,1\n")
    with pytest.raises(LogFormatError, match=r"c.csv: joint 'a' has only current.*--robot"):
        read_log(p)
    res = CliRunner().invoke(main, ["identify", str(p), "-o", str(tmp_path / "m.json")])
    assert res.exit_code == 3 and "joint 'a' has only current" in res.stderr
    # inspect still describes it and says what is missing
    res = CliRunner().invoke(main, ["inspect", str(p)])
    assert res.exit_code == 0 and "current of a, b not converted to torque" in res.stdout
