"""ROS bags through rosbags: rosbag2 .db3 files and (split) folders, ROS 1 .bag — read as the
canonical CSV copy of the same log; field paths, topic choice, time sources, bad input."""

from __future__ import annotations

import hashlib
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.errors import ImpactError, LogFormatError, OutputError
from impactcli.logs import LOG_SUFFIXES, inspect_log, log_stem, read_log, write_log
from impactcli.logs.paths import folder_sha256
from impactcli.logs.write import write_rosbag1, write_rosbag2
from impactcli.schema import validate
from impactcli.types import RobotLog

from .message_logs import (
    ALL,
    ARM,
    ARM_BODY,
    ARM_DEF,
    JOINTS,
    arm_map,
    arm_messages,
    assert_same,
    csv_copy,
    fixture_log,
    store_with,
)


def _write(log: RobotLog, tmp: Path, kind: str) -> Path:
    if kind == "db3":
        p = tmp / "run.db3"
        write_log(log, p)
    elif kind == "folder":
        p = tmp / "run_folder"
        write_rosbag2(log, p)
    elif kind == "split":
        p = tmp / "run_split"
        write_rosbag2(log, p, split=2)
    elif kind == "mcap-storage":
        p = tmp / "run_mcap"
        write_rosbag2(log, p, storage="mcap")
    else:
        p = tmp / "run.bag"
        write_log(log, p)
    return p


KINDS = ["db3", "folder", "split", "mcap-storage", "bag"]


@pytest.mark.parametrize("kind", KINDS)
def test_bag_reads_as_the_csv_copy(tmp_path: Path, kind: str) -> None:
    log = fixture_log()
    ref = csv_copy(log, tmp_path)
    p = _write(log, tmp_path, kind)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = read_log(p)
    assert back.source.format == ("rosbag1" if kind == "bag" else "rosbag2")
    assert back.source.time_source == "header"
    assert back.source.repairs == () and back.source.ignored_channels == ()
    assert back.source.path == str(p)
    assert_same(back, ref)
    assert back.has_channel("torque_ext").tolist() == [True, False, True]
    d = inspect_log(p)
    validate(d, "inspect", ImpactError, "inspect output")
    assert {"torque_model", "torque_ext"} <= set(d["signals"])


def test_split_folder_is_one_log_and_hashed_file_by_file(tmp_path: Path) -> None:
    log = fixture_log()
    p = _write(log, tmp_path, "split")
    files = sorted(x.name for x in p.iterdir())
    assert files == ["metadata.yaml", "run_split_0.db3", "run_split_1.db3"]
    meta = yaml.safe_load((p / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["relative_file_paths"] == ["run_split_0.db3", "run_split_1.db3"]
    assert [f["message_count"] for f in meta["files"]] == [1000, 1000]  # 4 topics × 250
    back = read_log(p)
    assert back.n_samples == 500
    np.testing.assert_array_equal(back.t_ns, log.t_ns)
    want = hashlib.sha256("".join(
        hashlib.sha256((p / f).read_bytes()).hexdigest() for f in files).encode()).hexdigest()
    assert back.source.sha256 == want == folder_sha256(p)
    assert log_stem(p) == "run_split" and log_stem(str(p) + "/") == "run_split"


def test_suffixes_and_stems() -> None:
    assert {".bag", ".db3"} <= set(LOG_SUFFIXES)
    assert log_stem("a/run.bag") == "run" and log_stem("a/run.DB3") == "run"
    assert log_stem("a/rosbag2_2026_01_01-10_00_00") == "rosbag2_2026_01_01-10_00_00"


def test_time_sources_of_a_bag(tmp_path: Path) -> None:
    log = fixture_log(n=40)
    for kind in ("db3", "bag"):
        p = _write(log, tmp_path / kind, kind)
        for src in ("log", "publish", "header"):
            back = read_log(p, time_source=src)
            assert back.source.time_source == src
            np.testing.assert_array_equal(back.t_ns, log.t_ns)
    # stamps of zero (a log starting at t=0): header cannot be used, the bag time is
    zero = fixture_log(n=40, t0=0)
    zero = RobotLog(t_ns=zero.t_ns - zero.t_ns[0], joint_names=zero.joint_names,
                    position=zero.position, torque=zero.torque)
    p = tmp_path / "zero.bag"
    write_rosbag1(zero, p)
    assert read_log(p).source.time_source == "log"
    with pytest.raises(LogFormatError, match=r"message 0: header stamp is zero; use "
                                             r"--time-source log or publish"):
        read_log(p, time_source="header")


def _bag_with_topics(path: Path, topics: list[tuple[str, str]], n: int = 20) -> None:
    """A rosbag2 .db3 folder file with JointState and String topics (n messages each)."""
    from rosbags.rosbag2 import Writer

    from impactcli.logs.messages.ros2_cdr import encode_jointstates

    store = store_with(base="ros2")
    String = store.types["std_msgs/msg/String"]
    t = 10**18 + np.arange(n, dtype=np.int64) * 10**7
    js = encode_jointstates(t, JOINTS, np.zeros((n, 3)), None, np.ones((n, 3)))
    tmp = path.parent / (path.stem + "_dir")
    with Writer(tmp, version=9) as w:
        conns = [(w.add_connection(name, kind, typestore=store), kind) for name, kind in topics]
        for i in range(n):
            for c, kind in conns:
                data = (js[i].tobytes() if kind.endswith("JointState")
                        else bytes(store.serialize_cdr(String(data="hi"), kind)))
                w.write(c, int(t[i]), data)
    next(tmp.glob("*.db3")).rename(path)


def test_topic_choice_lists_only_jointstate_topics(tmp_path: Path) -> None:
    p = tmp_path / "two.db3"
    js, s = "sensor_msgs/msg/JointState", "std_msgs/msg/String"
    _bag_with_topics(p, [("/left/joint_states", js), ("/right/joint_states", js),
                         ("/chatter", s)])
    with pytest.raises(LogFormatError, match=rf"^{p}: cannot choose the joint-state topic; pass "
                                             r"--topic \(topics: /left/joint_states, "
                                             r"/right/joint_states\)$"):
        read_log(p)
    log = read_log(p, topic="/right/joint_states")
    assert log.n_samples == 20 and log.joint_names == JOINTS
    assert log.source.ignored_channels == ("/chatter", "/left/joint_states")
    one = tmp_path / "one.db3"
    _bag_with_topics(one, [("/arm/joint_states", js), ("/chatter", s)])
    assert read_log(one).n_samples == 20  # the only JointState topic
    none = tmp_path / "none.db3"
    _bag_with_topics(none, [("/chatter", s)])
    with pytest.raises(LogFormatError, match=r"no JointState topic \(topics: /chatter\)"):
        read_log(none)


def _arm_bag(tmp: Path, kind: str, log: RobotLog) -> Path:
    """The ArmState custom message on /arm/state in a rosbag2 (CDR) or ROS 1 bag."""
    if kind == "bag":
        from rosbags.rosbag1 import Writer as Writer1

        # ROS 1: the definition refers to ROS 1's std_msgs/Header (with seq)
        store = store_with((ARM, ARM_BODY), base="ros1")
        p = tmp / "arm.bag"
        with Writer1(p) as w:
            c = w.add_connection("/arm/state", ARM, typestore=store)
            for t, m in zip(log.t_ns.tolist(), _ros1_arm(store, log), strict=True):
                w.write(c, t, m)
        return p
    from rosbags.rosbag2 import Writer as Writer2

    store = store_with((ARM, ARM_DEF), base="ros2")
    folder = tmp / "arm_bag"
    with Writer2(folder, version=9) as w:
        c = w.add_connection("/arm/state", ARM, typestore=store)
        for t, m in zip(log.t_ns.tolist(), arm_messages(store, log), strict=True):
            w.write(c, t, m)
    return folder


def _ros1_arm(store: Any, log: RobotLog) -> list[bytes]:
    M = store.types[ARM]
    H, T = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    out = []
    for i, t in enumerate(log.t_ns.tolist()):
        sec, nsec = divmod(t, 10**9)
        m = M(header=H(seq=i, stamp=T(sec=sec, nanosec=nsec), frame_id="base"),
              q=log.position[i].copy(), dq=log.velocity[i].copy(),
              q_d=log.position_ref[i].copy(), dq_d=log.velocity_ref[i].copy(),
              ddq_d=log.acceleration_ref[i].copy(), tau_J=log.torque[i].copy(),
              tau_model=log.torque_model[i].copy(), tau_ext=log.torque_ext[i].copy(),
              robot_mode=1, note="x")
        out.append(bytes(store.serialize_ros1(m, ARM)))
    return out


@pytest.mark.parametrize("kind", ["rosbag2", "bag"])
def test_custom_message_field_paths_in_bags(tmp_path: Path, kind: str) -> None:
    log = fixture_log(n=200, acc_ref=True)
    ref = csv_copy(log, tmp_path)
    p = _arm_bag(tmp_path, kind, log)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = read_log(p, channel_map=arm_map(tmp_path / "arm.yaml"))
    assert back.source.format == ("rosbag1" if kind == "bag" else "rosbag2")
    assert back.source.time_source == "header"
    assert_same(back, ref, ALL)
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: messages\njoints:\n  - {name: a, position: /arm/state/q[0], "
                   "torque: /arm/nothing}\n")
    with pytest.raises(LogFormatError, match=r"bad.yaml: channel map does not parse: while "
                                             r"parsing a flow mapping; in YAML, quote a field "
                                             r"path with \[i\] inside \{...\}"):
        read_log(p, channel_map=bad)
    bad.write_text("format: messages\njoints:\n  - {name: a, position: '/arm/state/q[0]', "
                   "torque: /arm/nothing}\n")
    with pytest.raises(LogFormatError, match=r"field path '/arm/nothing' names no topic of the "
                                             r"log \(topics: /arm/state\)"):
        read_log(p, channel_map=bad)


def test_file_url_of_a_folder_reads_remote_folder_is_refused(tmp_path: Path) -> None:
    log = fixture_log(n=30)
    p = _write(log, tmp_path, "folder")
    back = read_log(p.as_uri())
    assert back.source.path == p.as_uri()
    np.testing.assert_array_equal(back.t_ns, log.t_ns)
    fsspec = pytest.importorskip("fsspec")
    fs = fsspec.filesystem("memory")
    for f in p.iterdir():
        fs.pipe(f"/bags/run_folder/{f.name}", f.read_bytes())
    try:
        with pytest.raises(LogFormatError, match=r"^memory://bags/run_folder: a folder "
                                                 r"\(rosbag2\) is read from a local path or "
                                                 r"file:// URL only"):
            read_log("memory://bags/run_folder")
    finally:
        fs.rm("/bags", recursive=True)


def test_writers_are_atomic_and_never_overwrite_a_folder(tmp_path: Path) -> None:
    log = fixture_log(n=30)
    p = tmp_path / "x.db3"
    p.write_bytes(b"old")
    write_log(log, p)
    assert read_log(p).n_samples == 30
    write_log(log, tmp_path / "x.bag")
    write_log(log, tmp_path / "x.bag")  # replaces the file
    assert read_log(tmp_path / "x.bag").n_samples == 30
    (tmp_path / "f").mkdir()
    with pytest.raises(OutputError, match="it exists"):
        write_rosbag2(log, tmp_path / "f")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["f", "x.bag", "x.db3"]


# ------------------------------------------------------------------------------ bad input


def _truncated_bag(tmp: Path) -> tuple[Path, dict[str, Any]]:
    p = tmp / "cut.bag"
    write_log(fixture_log(n=100), p)
    data = p.read_bytes()
    p.write_bytes(data[: len(data) * 2 // 3])
    return p, {}


def _truncated_db3(tmp: Path) -> tuple[Path, dict[str, Any]]:
    p = tmp / "cut.db3"
    write_log(fixture_log(n=100), p)
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    return p, {}


def _garbage_db3(tmp: Path) -> tuple[Path, dict[str, Any]]:
    p = tmp / "junk.db3"
    p.write_bytes(b"this is not a database" * 100)
    return p, {}


def _garbage_bag(tmp: Path) -> tuple[Path, dict[str, Any]]:
    p = tmp / "junk.bag"
    p.write_bytes(b"#ROSBAG V2.0\n" + bytes(range(256)) * 8)
    return p, {}


def _no_topic(tmp: Path) -> tuple[Path, dict[str, Any]]:
    p = tmp / "ok.bag"
    write_log(fixture_log(n=20), p)
    return p, {"topic": "/no_such_topic"}


def _not_rosbag2(tmp: Path) -> tuple[Path, dict[str, Any]]:
    p = tmp / "plain_folder"
    p.mkdir()
    (p / "x.db3").write_bytes(b"")
    return p, {}


def _field_naming_nothing(tmp: Path) -> tuple[Path, dict[str, Any]]:
    p = tmp / "ok.db3"
    write_log(fixture_log(n=20), p)
    m = tmp / "map.yaml"
    m.write_text("format: messages\njoints:\n  - {name: shoulder, torque_ext: /nope/effort}\n")
    return p, {"channel_map": m}


BAD: dict[str, tuple[Any, str]] = {
    "truncated .bag": (_truncated_bag, r"corrupt, truncated or unreadable ROS 1 bag: "),
    "truncated .db3": (_truncated_db3, r"corrupt, truncated or unreadable rosbag2: "),
    "not a database": (_garbage_db3, r"corrupt, truncated or unreadable rosbag2: "),
    "garbage .bag": (_garbage_bag, r"corrupt, truncated or unreadable ROS 1 bag: "),
    "bag without the topic": (_no_topic, r"topic '/no_such_topic' not found \(topics: "
                                         r"/joint_states, /joint_states_ext, "
                                         r"/joint_states_model, /joint_states_ref\)$"),
    "folder without metadata.yaml": (_not_rosbag2, r"plain_folder/x.db3: corrupt, truncated "
                                                   r"or unreadable rosbag2"),
    "field path naming nothing": (_field_naming_nothing,
                                  r"shoulder.torque_ext: field path '/nope/effort' names no topic"
                                  r" of the log \(topics: /joint_states, "),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_bag_is_one_error_naming_the_file(tmp_path: Path, case: str) -> None:
    make, pattern = BAD[case]
    path, kwargs = make(tmp_path)
    with pytest.raises(LogFormatError) as info:
        read_log(path, **kwargs)
    msg = str(info.value)  # a folder's error names the log in it that failed
    assert msg.startswith((f"{path}: ", f"{path}/")) and "\n" not in msg, msg
    assert re.search(pattern, msg), msg


@pytest.mark.parametrize("case", list(BAD))
def test_bad_bag_through_the_cli_is_exit_3_one_line(tmp_path: Path, case: str) -> None:
    make, pattern = BAD[case]
    path, kwargs = make(tmp_path)
    # `inspect` takes files only (click.Path(dir_okay=False)): a folder goes through `detect`
    args = (["detect", str(path), "-o", str(tmp_path / "out")] if path.is_dir()
            else ["inspect", str(path)])
    if "channel_map" in kwargs:
        args += ["--channel-map", str(kwargs["channel_map"])]
    if "topic" in kwargs:
        args += ["--topic", kwargs["topic"]]
    res = CliRunner().invoke(main, args)
    detail = f"stdout={res.stdout!r} stderr={res.stderr!r}"
    assert res.exit_code == 3, detail
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(  # a folder: the log in it that failed
        (f"impactcli: error: {path}: ", f"impactcli: error: {path}/")), detail
    assert re.search(pattern, lines[0]), detail
    assert "Traceback" not in res.stderr + res.stdout
