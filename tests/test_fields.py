"""Message fields through channel maps (MCAP), companion topics _model/_ext, shipped maps.

Every log is built in code and compared with its canonical CSV copy (the reference reader):
a ROS 2 MCAP with the controller channels on ``_model``/``_ext`` JointState topics, and MCAPs
of custom message types (defined here as ros2msg text, encoded with rosbags' typestore) read
through field paths.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from mcap.writer import Writer as McapWriter

from impactcli.cli import main
from impactcli.errors import ChannelMapError, ImpactError, ImpactWarning, LogFormatError
from impactcli.logs import inspect_log, read_log, write_log
from impactcli.logs.messages.ros2_cdr import (
    HEADER_DEFS,
    JOINT_STATE,
    decode_topic_official,
)
from impactcli.schema import validate

from .conftest import make_log
from .message_logs import (
    ALL,
    ARM,
    ARM_BODY,
    ARM_DEF,
    BARE,
    BARE_DEF,
    DEFS,
    JOINTS,
    T0,
    arm_map,
    arm_messages,
    assert_same,
    csv_copy,
    fixture_log,
    jointstates,
    store_with,
    two_topics,
    write_mcap,
)

# --------------------------------------------------------------- equality with the CSV copy


def test_mcap_ros2_companion_topics_read_as_the_csv_copy(tmp_path: Path) -> None:
    log = fixture_log()
    ref = csv_copy(log, tmp_path)
    p = tmp_path / "log.mcap"
    write_log(log, p, mcap_encoding="ros2")
    ext = decode_topic_official(p, "/joint_states_ext", str(p), ("shoulder", "elbow", "wrist"))
    assert ext.joint_seen.tolist() == [True, False, True]  # 'elbow' is not named at all
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = read_log(p)
    assert back.source.format == "mcap-ros2" and back.source.time_source == "header"
    assert back.source.repairs == () and back.source.ignored_channels == ()
    assert_same(back, ref)
    assert back.has_channel("torque_ext").tolist() == [True, False, True]
    d = inspect_log(p)
    validate(d, "inspect", ImpactError, "inspect output")
    assert {"torque_model", "torque_ext"} <= set(d["signals"])


def test_custom_state_message_through_field_paths_reads_as_the_csv_copy(tmp_path: Path) -> None:
    log = fixture_log(acc_ref=True)
    ref = csv_copy(log, tmp_path)
    store = store_with((ARM, ARM_DEF))
    p = tmp_path / "arm.mcap"
    # the recorder's log time lags the header stamp: the header is the sample time
    write_mcap(p, [("/arm/state", ARM, "ros2msg", "cdr",
                    [(t + 700_000, t + 600_000, m) for t, m in
                     zip(log.t_ns.tolist(), arm_messages(store, log), strict=True)])])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = read_log(p, channel_map=arm_map(tmp_path / "arm.yaml"))
    assert back.source.format == "mcap-ros2" and back.source.time_source == "header"
    assert back.source.repairs == ()
    assert_same(back, ref)
    np.testing.assert_array_equal(back.acceleration_ref, log.acceleration_ref)
    for src, shift in (("log", 700_000), ("publish", 600_000)):
        np.testing.assert_array_equal(
            read_log(p, channel_map=tmp_path / "arm.yaml", time_source=src).t_ns,
            log.t_ns + shift)
    res = CliRunner().invoke(main, ["inspect", str(p), "--channel-map",
                                    str(tmp_path / "arm.yaml"), "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    validate(d, "inspect", ImpactError, "inspect output")
    assert set(d["signals"]) == set(ALL) - {"current"}


def test_state_without_header_is_stamped_by_log_time(tmp_path: Path) -> None:
    log = fixture_log(n=50)
    store = store_with((BARE, BARE_DEF))
    M = store.types[BARE]
    rows = [(t, t, bytes(store.serialize_cdr(M(q=log.position[i].copy(),
                                                 tau_J=log.torque[i].copy()), BARE)))
            for i, t in enumerate(log.t_ns.tolist())]
    p = tmp_path / "bare.mcap"
    write_mcap(p, [("/bare", BARE, "ros2msg", "cdr", rows)])
    m = tmp_path / "bare.yaml"
    m.write_text(yaml.safe_dump({"format": "messages", "joints": [
        {"name": j, "position": f"/bare/q[{k}]", "torque": f"/bare/tau_J[{k}]"}
        for k, j in enumerate(JOINTS)]}))
    back = read_log(p, channel_map=m)
    assert back.source.time_source == "log"
    np.testing.assert_array_equal(back.t_ns, log.t_ns)
    np.testing.assert_array_equal(back.torque, log.torque)
    with pytest.raises(LogFormatError, match=r"topic '/bare' has no header stamp; use "
                                             r"--time-source log or publish"):
        read_log(p, channel_map=m, time_source="header")


# ------------------------------------------------------------- second topics: hold, by name




def test_jointstate_effort_on_a_second_topic_by_joint_name_is_held_causally(
    tmp_path: Path,
) -> None:
    names = ["wrist", "gripper", "elbow_joint", "shoulder"]
    p, te_t, te, t, log = two_topics(tmp_path, names)
    m = tmp_path / "ext.yaml"
    m.write_text(
        "format: messages\njoints:\n"
        "  - {name: shoulder, torque_ext: {field: /external_torque/effort}}\n"
        "  - {name: elbow, torque_ext: {field: /external_torque/effort, joint: elbow_joint,"
        " scale: -2.0, offset: 0.5}}\n"
        "  - {name: wrist, torque_ext: {field: /external_torque/effort}}\n"
    )
    for tsrc, state_t, ext_t in (("header", t, te_t), ("log", t + 1_000_000, te_t + 3_000_000)):
        first = int(np.searchsorted(state_t, ext_t[0]))  # state samples before the first ext
        with pytest.warns(ImpactWarning, match=rf"dropped the first {first} state sample\(s\), "
                                               r"recorded before the first message on "
                                               r"'/external_torque'"):
            back = read_log(p, channel_map=m, time_source=None if tsrc == "header" else tsrc)
        assert back.source.time_source == tsrc
        np.testing.assert_array_equal(back.t_ns, state_t[first:])
        np.testing.assert_array_equal(back.position, log.position[first:])
        col = {"shoulder": 3, "elbow": 2, "wrist": 0}
        for i in range(back.n_samples):
            k = int(np.flatnonzero(ext_t <= back.t_ns[i])[-1])  # latest at or before
            for j, name in enumerate(JOINTS):
                want = te[k, col[name]]
                if name == "elbow":
                    want = want * -2.0 + 0.5
                assert back.torque_ext[i, j] == want
        assert "/joint_states:gripper" not in back.source.ignored_channels


def test_shipped_jointstate_external_torque_map(tmp_path: Path) -> None:
    panda = tuple(f"panda_joint{k}" for k in range(1, 8))
    base = make_log(n=300, joints=panda, seed=2)
    t = T0 + base.t_ns
    rng = np.random.default_rng(9)
    te = rng.normal(size=(300, 7))
    p = tmp_path / "panda.mcap"
    write_mcap(p, [
        ("/joint_states", JOINT_STATE, "ros2msg", "cdr",
         jointstates(t, [*panda, "panda_finger_joint1"], np.c_[base.position, np.zeros(300)],
                     np.c_[base.torque, np.zeros(300)])),
        ("/external_torque", JOINT_STATE, "ros2msg", "cdr",
         jointstates(t, list(panda[::-1]), None, te[:, ::-1])),
    ])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = read_log(p, channel_map="jointstate_external_torque_example")
    assert back.joint_names == panda
    np.testing.assert_array_equal(back.t_ns, t)
    np.testing.assert_array_equal(back.position, base.position)
    np.testing.assert_array_equal(back.torque, base.torque)
    np.testing.assert_array_equal(back.torque_ext, te)
    assert back.source.ignored_channels == ("/joint_states:panda_finger_joint1",)


FRANKA = "franka_msgs/msg/FrankaState"
#: the franka_ros FrankaState fields the shipped map reads, with others around them
FRANKA_DEF = """std_msgs/Header header
float64[6] cartesian_collision
float64[7] q
float64[7] q_d
float64[7] dq
float64[7] dq_d
float64[7] ddq_d
float64[7] theta
float64[7] tau_J
float64[7] dtau_J
float64[7] tau_J_d
float64[7] tau_ext_hat_filtered
float64[16] O_T_EE
float64 time
uint8 robot_mode
""" + HEADER_DEFS


DEFS[FRANKA] = FRANKA_DEF


def test_shipped_franka_state_map(tmp_path: Path) -> None:
    panda = tuple(f"panda_joint{k}" for k in range(1, 8))
    base = make_log(n=200, joints=panda, seed=4, dt=0.001)
    rng = np.random.default_rng(5)
    t = T0 + base.t_ns
    dq, te = rng.normal(size=(200, 7)), rng.normal(size=(200, 7))
    store = store_with((FRANKA, FRANKA_DEF))
    M = store.types[FRANKA]
    H, T = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    z6, z7, z16 = np.zeros(6), np.zeros(7), np.zeros(16)
    rows = []
    for i, ti in enumerate(t.tolist()):
        sec, nsec = divmod(ti, 10**9)
        m = M(header=H(stamp=T(sec=sec, nanosec=nsec), frame_id=""), cartesian_collision=z6,
              q=base.position[i].copy(), q_d=base.position_ref[i].copy(), dq=dq[i].copy(),
              dq_d=base.velocity_ref[i].copy(), ddq_d=base.acceleration_ref[i].copy(),
              theta=z7, tau_J=base.torque[i].copy(), dtau_J=z7, tau_J_d=z7,
              tau_ext_hat_filtered=te[i].copy(), O_T_EE=z16, time=i * 1e-3, robot_mode=2)
        rows.append((ti + 250_000, ti + 250_000, bytes(store.serialize_cdr(m, FRANKA))))
    p = tmp_path / "franka.mcap"
    write_mcap(p, [("/franka_state_controller/franka_states", FRANKA, "ros2msg", "cdr", rows)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = read_log(p, channel_map="franka_state_example")
    assert back.joint_names == panda and back.source.time_source == "header"
    np.testing.assert_array_equal(back.t_ns, t)
    for sig, want in (("position", base.position), ("velocity", dq), ("torque", base.torque),
                      ("position_ref", base.position_ref), ("velocity_ref", base.velocity_ref),
                      ("acceleration_ref", base.acceleration_ref), ("torque_ext", te)):
        np.testing.assert_array_equal(getattr(back, sig), want, err_msg=sig)
    assert back.torque_model is None


def test_field_of_the_state_topic_is_read_row_by_row(tmp_path: Path) -> None:
    log = fixture_log(n=60)
    p = tmp_path / "s.mcap"
    write_log(log, p, mcap_encoding="ros2")
    m = tmp_path / "m.yaml"
    m.write_text("format: messages\njoints:\n" + "".join(
        f"  - {{name: {j}, torque_model: {{field: /joint_states/effort, scale: 0.5}}}}\n"
        for j in JOINTS[::-1]))
    back = read_log(p, channel_map=m)
    assert back.joint_names == JOINTS[::-1]  # the map's joints, in its order
    np.testing.assert_array_equal(back.torque_model, 0.5 * log.torque[:, ::-1])
    np.testing.assert_array_equal(back.torque_ext, log.torque_ext[:, ::-1])  # the _ext default
    np.testing.assert_array_equal(back.position_ref, log.position_ref[:, ::-1])


def test_json_message_fields(tmp_path: Path) -> None:
    log = fixture_log(n=80)
    t = log.t_ns
    rows = []
    for i, ti in enumerate(t.tolist()):
        msg = {"stamp_ns": ti, "ext": log.torque_ext[i].tolist(),
               "model": {"name": list(JOINTS[::-1]), "effort": log.torque_model[i, ::-1].tolist()}}
        rows.append((ti, ti, json.dumps(msg).replace("NaN", "null").encode()))
    p = tmp_path / "j.mcap"
    write_mcap(p, [("/joint_states", JOINT_STATE, "ros2msg", "cdr",
                    jointstates(t, list(JOINTS), log.position, log.torque)),
                   ("/controller", "my/Controller", "jsonschema", "json", rows)])
    m = tmp_path / "m.yaml"
    m.write_text("format: messages\njoints:\n" + "".join(
        f"  - {{name: {j}, torque_ext: '/controller/ext[{k}]', "
        f"torque_model: {{field: /controller/model/effort}}}}\n" for k, j in enumerate(JOINTS)))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ImpactWarning)
        with pytest.warns(ImpactWarning, match=r"'elbow.torque_ext' holds no finite value"):
            back = read_log(p, channel_map=m)
    np.testing.assert_array_equal(back.t_ns, t)
    np.testing.assert_array_equal(back.torque_model, log.torque_model)
    np.testing.assert_array_equal(back.torque_ext, log.torque_ext)
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: messages\njoints:\n"
                   "  - {name: shoulder, torque_ext: /controller/nope}\n")
    with pytest.raises(ChannelMapError, match=r"field path /controller/nope: message 0 on "
                                              r"'/controller': has no field 'nope' \(fields: "
                                              r"stamp_ns, ext, model\)"):
        read_log(p, channel_map=bad)


# ------------------------------------------------------------------------------ bad input


def _arm_file(tmp: Path) -> Path:
    log = fixture_log(n=30)
    store = store_with((ARM, ARM_DEF))
    p = tmp / "arm.mcap"
    write_mcap(p, [
        ("/arm/state", ARM, "ros2msg", "cdr",
         [(t, t, m) for t, m in zip(log.t_ns.tolist(), arm_messages(store, log), strict=True)]),
        ("/external_torque", JOINT_STATE, "ros2msg", "cdr",
         jointstates(log.t_ns, ["a", "b"], None, np.zeros((30, 2)))),
    ])
    return p


def _one_joint_map(tmp: Path, torque: Any) -> Path:
    m = tmp / "bad_map.yaml"
    m.write_text(yaml.safe_dump({"format": "messages", "joints": [
        {"name": "shoulder", "position": "/arm/state/q[0]", "torque": torque}]}))
    return m


FIELDS = "header, q, dq, q_d, dq_d, ddq_d, tau_J, tau_model, tau_ext, robot_mode, note"
BAD_FIELDS: dict[str, tuple[Any, str]] = {
    "no such topic": ("/arm/nope/q[0]",
                      "field path '/arm/nope/q[0]' names no topic of the log "
                      "(topics: /arm/state, /external_torque)"),
    "a topic, no field": ("/external_torque",
                          "'/external_torque' is a topic; name a field of its messages "
                          "(/topic/field)"),
    "no such field": ("/arm/state/tau[0]",
                      f"field 'tau' of '/arm/state/tau[0]' does not exist in {ARM} "
                      f"(fields: {FIELDS})"),
    "no such subfield": ("/arm/state/header/stamp/secs",
                         "field 'header/stamp/secs' of '/arm/state/header/stamp/secs' does not "
                         "exist in builtin_interfaces/msg/Time (fields: sec, nanosec)"),
    "index out of range": ("/arm/state/tau_J[3]",
                           "index 3 of '/arm/state/tau_J[3]' is out of range: tau_J has 3 "
                           "elements (0–2)"),
    "array without index": ("/arm/state/tau_J",
                            "field 'tau_J' of '/arm/state/tau_J' is an array of 3: give an "
                            "index (tau_J[0]); picking by joint name needs a 'name' string "
                            f"array beside it, which {ARM} has not"),
    "not numeric": ("/arm/state/note", "field 'note' of '/arm/state/note' is a string, not a "
                                       "number"),
    "a message": ("/arm/state/header", "field 'header' of '/arm/state/header' is a "
                                       "std_msgs/msg/Header message, not a number (its fields: "
                                       "stamp, frame_id)"),
    "joint not in name[]": ({"field": "/external_torque/effort"},
                            "field path /external_torque/effort: message 0 on "
                            "'/external_torque': joint 'shoulder' is not in name[] "
                            "(names: a, b)"),
}


@pytest.mark.parametrize("case", list(BAD_FIELDS))
def test_bad_field_path_is_one_line_naming_file_map_and_field(tmp_path: Path, case: str) -> None:
    torque, detail = BAD_FIELDS[case]
    p = _arm_file(tmp_path)
    m = _one_joint_map(tmp_path, torque)
    want = f"{p}: channel map {m}: " + ("" if case == "joint not in name[]"
                                         else "shoulder.torque: ") + detail
    with pytest.raises(ChannelMapError) as info:
        read_log(p, channel_map=m)
    assert str(info.value) == want
    res = CliRunner().invoke(main, ["inspect", str(p), "--channel-map", str(m)])
    assert res.exit_code == 3, res.stderr
    assert res.stderr.strip().splitlines() == [f"impactcli: error: {want}"]
    assert res.stdout == ""


def test_map_joint_missing_from_the_state_topic(tmp_path: Path) -> None:
    log = fixture_log(n=20)
    p = tmp_path / "s.mcap"
    write_log(log, p, mcap_encoding="ros2")
    m = tmp_path / "m.yaml"
    m.write_text("format: messages\njoints:\n  - {name: knee, torque_ext: /joint_states/effort}\n")
    with pytest.raises(ChannelMapError, match=rf"^{p}: channel map {m}: joint 'knee' is not in "
                                              r"name\[\] of '/joint_states' \(names: shoulder, "
                                              r"elbow, wrist\)$"):
        read_log(p, channel_map=m)


def test_map_and_log_kinds_must_match(tmp_path: Path) -> None:
    log = fixture_log(n=20)
    csv, mc = tmp_path / "l.csv", tmp_path / "l.mcap"
    write_log(log, csv)
    write_log(log, mc, mcap_encoding="ros2")
    msgs = tmp_path / "msgs.yaml"
    msgs.write_text("format: messages\njoints:\n  - {name: shoulder, torque_ext: /x/y}\n")
    with pytest.raises(LogFormatError, match=r"names message fields \(format: messages\): it is "
                                             r"for MCAP logs and ROS bags"):
        read_log(csv, channel_map=msgs)
    cols = tmp_path / "cols.yaml"
    cols.write_text("time: time\njoints:\n  - {name: shoulder, position: shoulder.position}\n")
    with pytest.raises(ChannelMapError, match=r"is for CSV files or .npz archives; a map for "
                                              r"MCAP or ROS bags says 'format: messages'"):
        read_log(mc, channel_map=cols)
    timed = tmp_path / "timed.yaml"
    timed.write_text("format: messages\ntime: t\njoints:\n  - {name: a, torque: /x/y}\n")
    with pytest.raises(ChannelMapError, match=r"timed.yaml: a 'format: messages' map has no "
                                              r"'time': its samples are the state topic's"):
        read_log(mc, channel_map=timed)
    field_in_csv = tmp_path / "fic.yaml"
    field_in_csv.write_text("time: time\njoints:\n  - {name: a, position: {field: /x/y}}\n")
    with pytest.raises(ChannelMapError, match=r"fic.yaml: joints\[0\].position: a message "
                                              r"field needs 'format: messages'"):
        read_log(csv, channel_map=field_in_csv)
    col = tmp_path / "col.yaml"
    col.write_text("format: messages\njoints:\n  - {name: a, position: {column: 3}}\n")
    with pytest.raises(ChannelMapError, match=r"col.yaml: joints\[0\].position: a 'format: "
                                              r"messages' map names message fields"):
        read_log(mc, channel_map=col)
    half = tmp_path / "half.yaml"
    half.write_text("format: messages\njoints:\n  - {name: a, position: /joint_states/position}\n"
                    "  - {name: b, torque: /joint_states/effort}\n")
    with pytest.raises(ChannelMapError, match="joint 'b' has no position field while others"):
        read_log(mc, channel_map=half)


def test_schema_example_and_shipped_maps_validate() -> None:
    from impactcli.logs.channel_map import load_channel_map, shipped_map_names
    from impactcli.schema import schema_dir

    assert {"franka_state_example", "jointstate_external_torque_example"} <= set(
        shipped_map_names())
    ex = load_channel_map(schema_dir() / "examples" / "channel_map_messages.yaml")
    assert ex.format == "messages" and ex.time is None
    ref = ex.signals["torque_model"][1]
    assert ref is not None and ref.is_field and ref.joint == "arm_elbow"
    fr = load_channel_map("franka_state_example")
    assert len(fr.joints) == 7 and set(fr.signals) == {
        "position", "velocity", "torque", "position_ref", "velocity_ref", "acceleration_ref",
        "torque_ext"}


# ------------------------------------------------------- bulk reading vs one message at a time

ODD = "my_msgs/msg/Odd"
#: variable-length strings and sequences before the numbers, nested arrays, a JointState
#: inside, small integer types; the dependencies other than Point are not in the text: the
#: reader takes std_msgs/Header and sensor_msgs/JointState from rosbags' own store
ODD_DEF = """std_msgs/Header header
string label
float64[] tau
my_msgs/Point[] pts
sensor_msgs/JointState js
int16 small
bool flag
================================================================================
MSG: my_msgs/Point
float64 x
float32 y
"""
DEFS[ODD] = ODD_DEF


def _odd_file(tmp: Path, n: int = 300, short_at: int | None = None) -> tuple[Path, dict[str, Any]]:
    from rosbags.typesys import get_types_from_msg

    store = store_with(base="ros2")
    store.register(get_types_from_msg(ODD_DEF, ODD))
    M, P = store.types[ODD], store.types["my_msgs/msg/Point"]
    JS = store.types["sensor_msgs/msg/JointState"]
    H, T = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    rng = np.random.default_rng(21)
    t = T0 + np.arange(n, dtype=np.int64) * 2_000_000
    truth: dict[str, Any] = {k: np.zeros(n) for k in ("tau1", "pt2x", "pt2y", "b", "small",
                                                      "flag")}
    rows = []
    for i in range(n):
        # a few layouts: label and sequence lengths, joint order, endianness, padding vary
        ntau = 1 if i == short_at else 2 + (i // 2) % 2
        tau = rng.normal(size=ntau)
        pts = [P(x=float(rng.normal()), y=float(np.float32(rng.normal())))
               for _ in range(3 + (i // 60) % 2)]
        names = ["a", "b", "c"] if i < 150 else ["c", "a", "b", "d"]
        eff = rng.normal(size=len(names))
        small, flag = int(rng.integers(-30000, 30000)), bool(i % 3 == 0)
        sec, nsec = divmod(int(t[i]), 10**9)
        m = M(header=H(stamp=T(sec=sec, nanosec=nsec), frame_id="f" * (i // 100)),
              label="x" * (5 * (i % 2)), tau=tau, pts=pts,
              js=JS(header=H(stamp=T(sec=0, nanosec=0), frame_id=""), name=names,
                    position=np.zeros(0), velocity=np.zeros(0), effort=eff),
              small=small, flag=flag)
        data = bytes(store.serialize_cdr(m, ODD, little_endian=bool(i % 50)))  # big-endian too
        rows.append((int(t[i]), int(t[i]), data + b"\x00" * (4 if i % 50 == 1 else 0)))  # padded
        if ntau > 1:
            truth["tau1"][i] = tau[1]
        truth["pt2x"][i], truth["pt2y"][i] = pts[2].x, pts[2].y
        truth["b"][i] = eff[names.index("b")]
        truth["small"][i], truth["flag"][i] = small, flag
    truth["t"] = t
    p = tmp / "odd.mcap"
    write_mcap(p, [("/odd", ODD, "ros2msg", "cdr", rows)])
    return p, truth


def _odd_fields(p: Path) -> tuple[np.ndarray, np.ndarray | None]:
    from impactcli.logs.messages.field_read import read_fields
    from impactcli.logs.messages.fields import FieldPath
    from impactcli.logs.messages.mcap import McapSource, scan_mcap

    src = McapSource(scan_mcap(p), str(p))
    td = src.load(["/odd"])["/odd"]
    paths = [FieldPath("/odd/tau[1]", "/odd", (("tau", 1),)),
             FieldPath("/odd/pts[2]/x", "/odd", (("pts", 2), ("x", None))),
             FieldPath("/odd/pts[2]/y", "/odd", (("pts", 2), ("y", None))),
             FieldPath("/odd/js/effort", "/odd", (("js", None), ("effort", None)), "b"),
             FieldPath("/odd/small", "/odd", (("small", None),)),
             FieldPath("/odd/flag", "/odd", (("flag", None),))]
    return read_fields(src, td, paths)


def test_bulk_field_reading_equals_the_truth_and_the_one_by_one_decoder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
) -> None:
    import impactcli.logs.messages.field_read as fr

    p, truth = _odd_file(tmp_path)
    want = np.c_[truth["tau1"], truth["pt2x"], truth["pt2y"], truth["b"], truth["small"],
                 truth["flag"]]
    calls: list[int] = []
    decode = fr.MessageSource.decode_all

    def counting(self: Any, td: Any, rows: Any = None) -> Any:
        calls.append(td.n if rows is None else len(rows))
        return decode(self, td, rows)

    monkeypatch.setattr(fr.MessageSource, "decode_all", counting)
    vals, header = _odd_fields(p)
    np.testing.assert_array_equal(vals, want)
    np.testing.assert_array_equal(header, truth["t"])
    assert sum(calls) < 60  # most messages were read in bulk (one check per layout)
    monkeypatch.setattr(fr, "_locate", lambda *a: None)  # everything one by one
    calls.clear()
    vals1, header1 = _odd_fields(p)
    assert sum(calls) == 300
    np.testing.assert_array_equal(vals1, want)
    np.testing.assert_array_equal(header1, truth["t"])


def test_an_index_past_a_sequence_names_the_message(tmp_path: Path) -> None:
    p, _ = _odd_file(tmp_path, short_at=57)
    m = tmp_path / "m.yaml"
    m.write_text("format: messages\njoints:\n  - {name: a, position: '/odd/tau[1]', "
                 "torque: /odd/small}\n")
    with pytest.raises(LogFormatError) as info:
        read_log(p, channel_map=m)
    assert str(info.value) == (f"{p}: channel map {m}: field path /odd/tau[1]: message 57 on "
                               "'/odd': index 1 of 'tau' is out of range (1 elements)")
    assert not isinstance(info.value, ChannelMapError)  # the map fits; message 57 does not


def test_ros1_messages_in_mcap(tmp_path: Path) -> None:
    """An MCAP of ROS 1 messages (ros1msg schemas): JointState state and a custom message."""
    log = fixture_log(n=120)
    store = store_with((ARM, ARM_BODY), base="ros1")
    js = "sensor_msgs/msg/JointState"
    JS = store.types[js]
    H, T = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    rows_js, rows_arm = [], []
    for i, t in enumerate(log.t_ns.tolist()):
        sec, nsec = divmod(t, 10**9)
        h = H(seq=i, stamp=T(sec=sec, nanosec=nsec), frame_id="")
        rows_js.append((t, t, bytes(store.serialize_ros1(JS(
            header=h, name=list(JOINTS), position=log.position[i].copy(), velocity=np.zeros(0),
            effort=log.torque[i].copy()), js))))
        M = store.types[ARM]
        rows_arm.append((t, t, bytes(store.serialize_ros1(M(
            header=h, q=log.position[i].copy(), dq=log.velocity[i].copy(),
            q_d=log.position_ref[i].copy(), dq_d=log.velocity_ref[i].copy(), ddq_d=np.zeros(3),
            tau_J=log.torque[i].copy(), tau_model=log.torque_model[i].copy(),
            tau_ext=log.torque_ext[i].copy(), robot_mode=1, note="x"), ARM))))
    p = tmp_path / "ros1.mcap"
    with open(p, "wb") as f:
        w = McapWriter(f)
        w.start("ros1", "test")
        sj = w.register_schema("sensor_msgs/JointState", "ros1msg",
                               store.generate_msgdef(js, ros_version=1)[0].encode())
        sa = w.register_schema("my_msgs/ArmState", "ros1msg",
                               store.generate_msgdef(ARM, ros_version=1)[0].encode())
        cj = w.register_channel("/joint_states", "ros1", sj)
        ca = w.register_channel("/arm/state", "ros1", sa)
        for (t, _, dj), (_, _, da) in zip(rows_js, rows_arm, strict=True):
            w.add_message(cj, log_time=t, publish_time=t, data=dj)
            w.add_message(ca, log_time=t, publish_time=t, data=da)
        w.finish()
    back = read_log(p, topic="/joint_states")
    assert back.source.format == "mcap-ros1" and back.source.time_source == "header"
    np.testing.assert_array_equal(back.t_ns, log.t_ns)
    np.testing.assert_array_equal(back.torque, log.torque)
    assert back.source.ignored_channels == ("/arm/state",)
    m = tmp_path / "m.yaml"
    m.write_text("format: messages\njoints:\n" + "".join(
        f"  - {{name: {j}, torque_model: '/arm/state/tau_model[{k}]'}}\n"
        for k, j in enumerate(JOINTS)))
    back = read_log(p, channel_map=m)
    np.testing.assert_array_equal(back.torque_model, log.torque_model)


def test_map_signal_replaces_the_companion_topic_one(tmp_path: Path) -> None:
    log = fixture_log(n=60)
    p = tmp_path / "s.mcap"
    write_log(log, p, mcap_encoding="ros2")
    m = tmp_path / "m.yaml"
    m.write_text("format: messages\njoints:\n" + "".join(
        f"  - {{name: {j}, velocity_ref: {{field: /joint_states/velocity}}, "
        f"torque_ext: {{field: /joint_states_model/effort, scale: -1}}}}\n" for j in JOINTS))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = read_log(p, channel_map=m)
    np.testing.assert_array_equal(back.position_ref, log.position_ref)  # still from _ref
    np.testing.assert_array_equal(back.velocity_ref, log.velocity)  # the map's
    np.testing.assert_array_equal(back.torque_ext, -log.torque_model)  # not /joint_states_ext
    np.testing.assert_array_equal(back.torque_model, log.torque_model)  # the _model default
    assert back.source.ignored_channels == ("/joint_states_ext",)
