"""One sample log carrying the controller's channels, in every format a robot writes —
canonical CSV, ROS 2 MCAP (JointState state and reference topics, torque_ext as the effort of
a JointState on a second topic, acceleration_ref and torque_model from further topics, all
through a channel map), MCAP with a custom state message read through field paths,
rosbag2 ``.db3`` and a ROS 1 ``.bag`` of that custom message — gives the same detection:
the same events (start and end within one sample) and the same thresholds (to 1e-9
relative), calibrated and uncalibrated. Also the shipped example maps of the recorders
documented in docs/controller_channels.md."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from impactcli.logs import read_log, write_log
from impactcli.logs.messages.ros2_cdr import (
    HEADER_DEFS,
    JOINT_STATE,
    JOINT_STATE_DEF,
    encode_jointstates,
)
from impactcli.run.calibration import calibrate
from impactcli.run.collect import detect_in_memory
from impactcli.types import DetectionResult, RobotLog

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs" / "csv"
STATE = "impactcli_test/msg/ArmSample"
#: a controller's state message holding everything, arrays sized by the arm
STATE_BODY = """std_msgs/Header header
float64[] q
float64[] dq
float64[] q_d
float64[] dq_d
float64[] ddq_d
float64[] tau
float64[] tau_model
float64[] tau_ext
"""
T0 = 1_763_900_000_000_000_000  # an epoch clock, as ROS stamps are
TOPIC = "/arm/state"


def sample(name: str, seconds: float) -> RobotLog:
    """The first ``seconds`` of a shipped ASSIST-like sample log, moved to an epoch clock."""
    import dataclasses

    log = read_log(SAMPLES / f"{name}.csv.gz")
    n = int(np.searchsorted(log.time_s, seconds)) + 1
    log = log.slice(0, n)
    return dataclasses.replace(log, t_ns=log.t_ns + T0, current=None)


def _store(base: str) -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if base == "ros1" else Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(STATE_BODY, STATE))
    return store


def _messages(store: Any, log: RobotLog, ros1: bool = False) -> list[bytes]:
    M = store.types[STATE]
    H, T = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    assert log.velocity is not None and log.position_ref is not None
    assert log.velocity_ref is not None and log.acceleration_ref is not None
    assert log.torque_model is not None and log.torque_ext is not None
    out = []
    for i, t in enumerate(log.t_ns.tolist()):
        sec, nsec = divmod(t, 10**9)
        head = (H(seq=i, stamp=T(sec=sec, nanosec=nsec), frame_id="") if ros1
                else H(stamp=T(sec=sec, nanosec=nsec), frame_id=""))
        m = M(header=head, q=log.position[i].copy(), dq=log.velocity[i].copy(),
              q_d=log.position_ref[i].copy(), dq_d=log.velocity_ref[i].copy(),
              ddq_d=log.acceleration_ref[i].copy(), tau=log.torque[i].copy(),
              tau_model=log.torque_model[i].copy(), tau_ext=log.torque_ext[i].copy())
        out.append(bytes(store.serialize_ros1(m, STATE) if ros1
                         else store.serialize_cdr(m, STATE)))
    return out


def state_map(path: Path, joints: tuple[str, ...]) -> Path:
    """Every signal from the custom state message, by field path."""
    fields = {"position": "q", "velocity": "dq", "position_ref": "q_d", "velocity_ref": "dq_d",
              "acceleration_ref": "ddq_d", "torque": "tau", "torque_model": "tau_model",
              "torque_ext": "tau_ext"}
    doc = {"schema_version": "1.0", "name": "arm_sample", "format": "messages",
           "joints": [{"name": j, **{s: f"{TOPIC}/{f}[{k}]" for s, f in fields.items()}}
                      for k, j in enumerate(joints)]}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def jointstate_map(path: Path, joints: tuple[str, ...]) -> Path:
    """State and reference from JointState topics (the fast path), torque_ext as the effort of
    /external_torque, torque_model as the effort of /model_torque and acceleration_ref as
    the position of /acceleration_ref — JointState topics matched by joint name."""
    doc = {"schema_version": "1.0", "name": "jointstate_topics", "format": "messages",
           "joints": [{"name": j,
                       "torque_ext": {"field": "/external_torque/effort"},
                       "torque_model": {"field": "/model_torque/effort"},
                       "acceleration_ref": {"field": "/acceleration_ref/position"}}
                      for j in joints]}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def write_custom_mcap(log: RobotLog, path: Path) -> None:
    from mcap.writer import CompressionType, Writer

    store = _store("ros2")
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start("ros2", "test")
        sid = w.register_schema(STATE, "ros2msg", (STATE_BODY + HEADER_DEFS).encode())
        cid = w.register_channel(TOPIC, "cdr", sid)
        for i, (t, data) in enumerate(zip(log.t_ns.tolist(), _messages(store, log), strict=True)):
            w.add_message(cid, log_time=t + 300_000, publish_time=t + 300_000, sequence=i,
                          data=data)
        w.finish()


def write_jointstate_mcap(log: RobotLog, path: Path) -> None:
    """/joint_states, /joint_states_ref and three JointState topics the map reads."""
    from mcap.writer import CompressionType, Writer

    names = log.joint_names
    topics = {
        "/joint_states": encode_jointstates(log.t_ns, names, log.position, log.velocity,
                                            log.torque),
        "/joint_states_ref": encode_jointstates(log.t_ns, names, log.position_ref,
                                                log.velocity_ref, None),
        "/external_torque": encode_jointstates(log.t_ns, names, None, None, log.torque_ext),
        "/model_torque": encode_jointstates(log.t_ns, names, None, None, log.torque_model),
        "/acceleration_ref": encode_jointstates(log.t_ns, names, log.acceleration_ref, None,
                                                None),
    }
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start("ros2", "test")
        sid = w.register_schema(JOINT_STATE, "ros2msg", JOINT_STATE_DEF.encode())
        cids = {t: w.register_channel(t, "cdr", sid) for t in topics}
        for i, t in enumerate(log.t_ns.tolist()):
            for topic, rows in topics.items():
                w.add_message(cids[topic], log_time=t, publish_time=t, sequence=i,
                              data=rows[i].tobytes())
        w.finish()


def write_db3(log: RobotLog, path: Path) -> Path:
    from rosbags.rosbag2 import Writer

    store = _store("ros2")
    with Writer(path, version=9) as w:
        c = w.add_connection(TOPIC, STATE, typestore=store)
        for t, m in zip(log.t_ns.tolist(), _messages(store, log), strict=True):
            w.write(c, t, m)
    return next(path.glob("*.db3"))  # the .db3 file alone, as a user may hand it over


def write_bag(log: RobotLog, path: Path) -> None:
    from rosbags.rosbag1 import Writer

    store = _store("ros1")
    with Writer(path) as w:
        c = w.add_connection(TOPIC, STATE, typestore=store)
        for t, m in zip(log.t_ns.tolist(), _messages(store, log, ros1=True), strict=True):
            w.write(c, t, m)


def copies(log: RobotLog, tmp: Path, stem: str) -> dict[str, RobotLog]:
    """``log`` written and read back in every format (the CSV copy first)."""
    d = tmp / stem
    d.mkdir()
    out: dict[str, RobotLog] = {}
    write_log(log, d / f"{stem}.csv")
    out["csv"] = read_log(d / f"{stem}.csv")
    write_jointstate_mcap(log, d / f"{stem}_js.mcap")
    out["mcap jointstate topics"] = read_log(
        d / f"{stem}_js.mcap", channel_map=jointstate_map(d / "js.yaml", log.joint_names))
    cmap = state_map(d / "state.yaml", log.joint_names)
    write_custom_mcap(log, d / f"{stem}.mcap")
    out["mcap custom message"] = read_log(d / f"{stem}.mcap", channel_map=cmap)
    db3 = write_db3(log, d / f"{stem}_bag")
    out["db3"] = read_log(db3, channel_map=cmap)
    write_bag(log, d / f"{stem}.bag")
    out["bag"] = read_log(d / f"{stem}.bag", channel_map=cmap)
    return out


def _same_detection(a: DetectionResult, b: DetectionResult, what: str) -> None:
    assert [e.detector for e in a.events] == [e.detector for e in b.events], what
    for ea, eb in zip(a.events, b.events, strict=True):
        assert abs(ea.i_start - eb.i_start) <= 1 and abs(ea.i_end - eb.i_end) <= 1, (what, ea)
    for j in a.thresholds:
        for k, v in a.thresholds[j].items():
            assert b.thresholds[j][k] == pytest.approx(v, rel=1e-9, abs=0.0), (what, j, k)


@pytest.mark.slow
def test_every_format_gives_the_same_detection(tmp_path: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the companion-topic hold drops nothing here
        pushes = copies(sample("assist_pushes", 14.0), tmp_path, "pushes")
        free = copies(sample("assist_free_p2p", 12.0), tmp_path, "free")
        ref = pushes["csv"]
        for name, log in pushes.items():
            for sig in ("position", "velocity", "torque", "position_ref", "velocity_ref",
                        "acceleration_ref", "torque_model", "torque_ext"):
                np.testing.assert_array_equal(getattr(log, sig), getattr(ref, sig),
                                              err_msg=f"{name}: {sig}")
            np.testing.assert_array_equal(log.t_ns, ref.t_ns, err_msg=name)
        # uncalibrated (thresholds from the log itself, correction identified on it)
        base = detect_in_memory(ref)[0]
        assert {g["generator"] for g in base.generators.values()} == {"logged_external"}
        assert len([e for e in base.events if not e.in_warmup]) > 0
        cfg = calibrate([free["csv"]])
        calibrated = detect_in_memory(ref, config=cfg)[0]
        assert any(e.detector == "static_loading" and not e.in_warmup
                   for e in calibrated.events)
        for name in pushes:
            if name == "csv":
                continue
            _same_detection(base, detect_in_memory(pushes[name])[0], f"{name}, uncalibrated")
            cfg_n = calibrate([free[name]])
            for d in ("v_stat", "vL", "v0"):
                for j, v in getattr(cfg.thresholds, d).items():
                    assert getattr(cfg_n.thresholds, d)[j] == pytest.approx(v, rel=1e-9), (
                        name, d, j)
            _same_detection(calibrated, detect_in_memory(pushes[name], config=cfg_n)[0],
                            f"{name}, calibrated on its own copy of the free log")


def test_ur_rtde_example_map(tmp_path: Path) -> None:
    """The shipped UR RTDE map: space-separated header CSV, one column per element;
    torque = scale × actual_current, target_moment → torque_model."""
    n = 300
    rng = np.random.default_rng(0)
    fields = ("actual_q", "actual_qd", "actual_current", "target_q", "target_qd",
              "target_qdd", "target_moment")
    cols = [f"{f}_{i}" for f in fields for i in range(6)]
    data = rng.standard_normal((n, len(cols)))
    data[:, :6] = np.cumsum(0.002 * data[:, 6:12], axis=0)  # actual_q moves at actual_qd
    t = 1234.5 + np.arange(n) * 0.002
    lines = [" ".join(["timestamp", *cols, "robot_mode"])]
    lines += [" ".join([f"{t[k]:.3f}", *(repr(float(x)) for x in data[k]), "7"])
              for k in range(n)]
    (tmp_path / "rtde.csv").write_text("\n".join(lines) + "\n")
    log = read_log(tmp_path / "rtde.csv", channel_map="ur_rtde_example")
    assert log.n_joints == 6 and log.source.ignored_channels == ("robot_mode",)
    k = {f: fields.index(f) * 6 for f in fields}
    np.testing.assert_allclose(log.torque[:, 1], data[:, k["actual_current"] + 1] * 10.6956)
    np.testing.assert_array_equal(log.torque_model, data[:, k["target_moment"]:][:, :6])
    np.testing.assert_array_equal(log.acceleration_ref, data[:, k["target_qdd"]:][:, :6])
    assert log.torque_ext is None


LBR = "lbr_fri_idl/msg/LBRState"
LBR_DEF = """float64 sample_time
int8 session_state
uint32 time_stamp_sec
uint32 time_stamp_nano_sec
float64[7] measured_joint_position
float64[7] commanded_joint_position
float64[7] measured_torque
float64[7] commanded_torque
float64[7] external_torque
float64[7] ipo_joint_position
float64 tracking_performance
"""


def test_kuka_lbr_fri_example_map(tmp_path: Path) -> None:
    """The shipped KUKA LBR map: LBRState (no header: stamped by log time), external_torque →
    torque_ext, ipo_joint_position → reference."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(LBR_DEF, LBR))
    M = store.types[LBR]
    n = 200
    rng = np.random.default_rng(1)
    q, tau, ext, ipo = (rng.standard_normal((n, 7)) for _ in range(4))
    q = np.cumsum(1e-3 * q, axis=0)  # positions that move, sample to sample
    ipo = q + 1e-4 * ipo  # the interpolated reference follows them
    z = np.zeros(7)
    p = tmp_path / "lbr.mcap"
    with open(p, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start("ros2", "test")
        cid = w.register_channel("/lbr/state", "cdr", w.register_schema(LBR, "ros2msg",
                                                                        LBR_DEF.encode()))
        for i in range(n):
            m = M(sample_time=0.005, session_state=4, time_stamp_sec=0, time_stamp_nano_sec=0,
                  measured_joint_position=q[i].copy(), commanded_joint_position=z,
                  measured_torque=tau[i].copy(), commanded_torque=z,
                  external_torque=ext[i].copy(), ipo_joint_position=ipo[i].copy(),
                  tracking_performance=1.0)
            t = T0 + i * 5_000_000
            w.add_message(cid, log_time=t, publish_time=t, sequence=i,
                          data=bytes(store.serialize_cdr(m, LBR)))
        w.finish()
    log = read_log(p, channel_map="kuka_lbr_fri_example")
    assert log.joint_names == tuple(f"A{k}" for k in range(1, 8))
    assert log.source.time_source == "log" and log.t0_ns == T0
    for got, want in ((log.position, q), (log.torque, tau), (log.torque_ext, ext),
                      (log.position_ref, ipo)):
        np.testing.assert_array_equal(got, want)
