"""Channel maps: headerless CSV by index, columns by name, scale/offset, time units and epochs,
.npz by key and column, current → torque via the map or the robot description, shipped maps
reading the two real logs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from impactcli.errors import ImpactWarning, LogFormatError
from impactcli.logs import read_log
from impactcli.logs.channel_map import load_channel_map, shipped_map_names
from impactcli.schema import validate
from impactcli.types import JointSpec, RobotDescription

from .conftest import read_kuka


def _yaml(tmp: Path, text: str, name: str = "map.yaml") -> Path:
    p = tmp / name
    p.write_text(text)
    return p


def test_headerless_csv_by_index_with_scale_offset_and_ms(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    n = 50
    t_ms = 5000 + np.arange(n) * 4  # controller clock in ms
    q = np.cumsum(rng.normal(scale=1e-3, size=(n, 2)), axis=0)  # a motion, not noise
    cur_ma = rng.normal(size=(n, 2)) * 1000
    junk = rng.normal(size=n)
    rows = np.column_stack([t_ms, q[:, 0], cur_ma[:, 0], junk, q[:, 1], cur_ma[:, 1]])
    log_path = tmp_path / "dump.csv"
    log_path.write_text("".join(";".join(repr(float(v)) for v in r) + "\n" for r in rows))
    cmap = _yaml(tmp_path, """
csv: {header: false, delimiter: ";"}
time: {column: 0, unit: ms, start_at_zero: true}
joints:
  - {name: a, position: {column: 1, offset: 0.5}, current: {column: 2, scale: 0.002}}
  - {name: b, position: {column: 4, scale: -1}, current: {column: 5, scale: 0.003}}
""")
    log = read_log(log_path, channel_map=cmap)
    assert log.source.format == "csv-mapped"
    assert log.source.torque_source == "current"
    np.testing.assert_array_equal(log.t_ns, (t_ms - t_ms[0]) * 1_000_000)
    np.testing.assert_allclose(log.position[:, 0], q[:, 0] + 0.5, rtol=0, atol=1e-15)
    np.testing.assert_allclose(log.position[:, 1], -q[:, 1], rtol=0, atol=0)
    np.testing.assert_allclose(log.torque, cur_ma * [0.002, 0.003], rtol=1e-15)
    assert log.source.ignored_channels == ("column 3",)


def test_columns_by_name_plotjuggler_style_and_robot_current(tmp_path: Path) -> None:
    n = 20
    t = 1_700_000_000.0 + np.arange(n) * 0.01
    lines = ["__time,/js/a/position,/js/a/current,/js/b/position,/js/b/current,/other"]
    for i in range(n):
        lines.append(f"{t[i]:.6f},{0.1 * i},{0.5 + i},{-0.1 * i},{2.0 - i},7")
    log_path = tmp_path / "pj.csv"
    log_path.write_text("\n".join(lines) + "\n")
    cmap = _yaml(tmp_path, """
time: {column: __time, unit: s}
joints:
  - {name: a, position: /js/a/position, current: /js/a/current}
  - {name: b, position: /js/b/position, current: /js/b/current}
""")
    with pytest.raises(LogFormatError, match="joint 'a' has only current"):
        read_log(log_path, channel_map=cmap)
    robot = RobotDescription(joints=(JointSpec("b", 100.0, 0.05), JointSpec("a", 50.0, 0.1)))
    log = read_log(log_path, channel_map=cmap, robot=robot)
    cur = np.array([[0.5 + i, 2.0 - i] for i in range(n)])
    np.testing.assert_allclose(log.torque, cur * [5.0, 5.0], rtol=1e-15)
    np.testing.assert_array_equal(log.current, cur)
    assert log.t_ns[0] == 1_700_000_000_000_000_000
    assert log.t_ns[1] - log.t_ns[0] == 10_000_000  # exact decimal parse, no float rounding
    # canonical CSV with current only: the robot converts it, per joint by name
    canon = tmp_path / "c.csv"
    canon.write_text("time,b.position,b.current,a.position,a.current\n0,0,1,0,2\n0.01,0,3,0,4\n")
    log = read_log(canon, robot=robot)
    assert log.joint_names == ("b", "a")
    np.testing.assert_allclose(log.torque, [[5.0, 10.0], [15.0, 20.0]])


def test_torque_source_override(tmp_path: Path) -> None:
    p = tmp_path / "both.csv"
    p.write_text("time,a.position,a.torque,a.current\n0,0,1.5,2\n0.01,0,2.5,4\n")
    robot = RobotDescription(joints=(JointSpec("a", 10.0, 0.2),))
    assert read_log(p).torque[:, 0].tolist() == [1.5, 2.5]
    log = read_log(p, robot=robot, torque_source="current")
    assert log.source.torque_source == "current"
    assert log.torque[:, 0].tolist() == [4.0, 8.0]
    with pytest.raises(LogFormatError, match="unknown torque source"):
        read_log(p, torque_source="voltage")


def test_npz_by_key_and_column(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    n = 40
    t = 1.46e9 + np.arange(n) * 0.005
    q, tau = np.cumsum(rng.normal(scale=1e-3, size=(n, 3)), axis=0), rng.normal(size=(n, 3))
    p = tmp_path / "m.npz"
    np.savez(p, times=t, positions=q, torques=tau, extra=np.zeros(n))
    cmap = tmp_path / "m.json"
    cmap.write_text(json.dumps({
        "format": "npz", "time": {"key": "times", "unit": "s"},
        "joints": [{"name": f"q{k}", "position": {"key": "positions", "index": k},
                    "torque": {"key": "torques", "index": k, "scale": 2.0}} for k in range(3)],
    }))
    log = read_log(p, channel_map=cmap)
    assert log.source.format == "npz"
    np.testing.assert_array_equal(log.position, q)
    np.testing.assert_array_equal(log.torque, 2.0 * tau)
    np.testing.assert_array_equal(log.t_ns, np.round(t * 1e9).astype(np.int64))
    assert log.source.ignored_channels == ("extra",)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"time": {"key": "times"}, "joints": [
        {"name": "x", "position": {"key": "positions", "index": 5}, "torque": "times"}]}))
    with pytest.raises(LogFormatError, match=r"column 5 does not exist in array 'positions'"):
        read_log(p, channel_map=bad)


def test_shipped_maps_validate_and_are_named_by_short_name() -> None:
    assert {"ur_ext_observer", "kuka_lwr4"} <= set(shipped_map_names())
    ur = load_channel_map("ur_ext_observer")
    assert ur.joints == ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
    scales = [r.scale for r in ur.signals["current"]]
    assert scales == [10, 10.6956, 8.4566, 9.0029, 9.48, 10.1232]
    kuka = load_channel_map("kuka_lwr4")
    assert len(kuka.joints) == 7 and kuka.format == "npz"


def test_schema_examples_validate() -> None:
    import yaml

    from impactcli.errors import ChannelMapError
    from impactcli.schema import schema_dir

    ex = schema_dir() / "examples"
    validate(yaml.safe_load((ex / "channel_map.yaml").read_text()), "channel_map",
             ChannelMapError, "example")
    validate(json.loads((ex / "joint_sample.json").read_text()), "joint_sample",
             LogFormatError, "example")


@pytest.mark.real_logs
@pytest.mark.parametrize(("name", "n", "seconds"), [("link4.csv", 1896, 19.7),
                                                     ("ur-static.csv", 4259, 45.4)])
def test_real_ur_logs_through_shipped_map(real_logs: Path, name: str, n: int,
                                          seconds: float) -> None:
    path = real_logs / "ur_ext_observer" / name
    log = read_log(path, channel_map="ur_ext_observer")
    assert log.n_joints == 6 and log.n_samples == n
    assert log.duration_s == pytest.approx(seconds, abs=0.1)
    # steps of 10 ms and (a fifth to a third of them) 12 ms: the mean spacing
    # (impactcli.clock), not the median step's 100 Hz
    assert log.sample_rate_hz == pytest.approx((n - 1) / log.duration_s, rel=1e-9)
    assert log.source.torque_source == "current" and log.source.repairs == ()
    raw = np.loadtxt(path, delimiter=",")
    k = np.array([10, 10.6956, 8.4566, 9.0029, 9.48, 10.1232])
    np.testing.assert_allclose(log.torque, raw[:, 13:19] * k, rtol=1e-15)
    np.testing.assert_array_equal(log.position, raw[:, 1:7])
    assert log.t0_ns == round(raw[0, 0] * 1e9)


@pytest.mark.real_logs
def test_real_kuka_log_through_shipped_map(real_logs: Path) -> None:
    path = real_logs / "kuka_lwr4" / "measurements_1.npz"
    log = read_kuka(real_logs)
    d = np.load(path)
    assert log.n_joints == 7 and log.n_samples == 5027
    assert log.source.torque_source == "torque"
    np.testing.assert_array_equal(log.torque, d["torques"])
    np.testing.assert_array_equal(log.position, d["positions"])
    assert log.sample_rate_hz == pytest.approx(200.0, rel=1e-3)
    assert "target_positions" in log.source.ignored_channels


def test_repairs_are_warned_and_recorded(tmp_path: Path) -> None:
    n = 40
    t = np.arange(n) * 0.01
    y = 3.0 * t + 1.0
    rows = [[float(t[i]), float(y[i]), float(-y[i])] for i in range(n)]
    rows[10][1] = float("nan")
    rows[11][1] = float("nan")
    rows[20][2] = float("inf")
    rows.insert(31, list(rows[30]))  # exact duplicate
    p = tmp_path / "r.csv"
    p.write_text("time,j.position,j.torque\n" + "".join(
        ",".join("nan" if np.isnan(v) else repr(v) for v in r) + "\n" for r in rows))
    with pytest.warns(ImpactWarning) as rec:
        log = read_log(p)
    msgs = [str(w.message) for w in rec]
    assert any("dropped 1 exact duplicate" in m and "row 32" in m for m in msgs), msgs
    assert any("'j.position': interpolated 2" in m for m in msgs), msgs
    assert any("'j.torque': interpolated 1" in m for m in msgs), msgs
    assert len(log.source.repairs) == 3
    assert log.n_samples == n
    np.testing.assert_allclose(log.position[:, 0], y, rtol=1e-12)  # linear in time: exact
    np.testing.assert_allclose(log.torque[:, 0], -y, rtol=1e-12)


def test_a_ragged_line_of_a_headerless_csv_is_measured_against_the_first_line(
        tmp_path: Path) -> None:
    rows = [f"{0.01 * i},{0.1 * i},{0.5 + i}\n" for i in range(20)]
    rows[7] = "1,2\n"
    log_path = tmp_path / "dump.csv"
    log_path.write_text("".join(rows))
    cmap = _yaml(tmp_path, """
csv: {header: false}
time: {column: 0, unit: s}
joints:
  - {name: a, position: {column: 1}, torque: {column: 2}}
""")
    with pytest.raises(LogFormatError, match="line 8: 2 fields where the first line has 3") as e:
        read_log(log_path, channel_map=cmap)
    assert "header" not in str(e.value).split("dump.csv", 1)[1]
