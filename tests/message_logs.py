"""Message logs built in code for the tests of the message readers: a robot's joints and
companion topics, custom state messages (ros2msg text encoded with rosbags' typestore),
MCAP writing, and their canonical CSV copies (the reference reader's input)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from impactcli.logs import read_log, write_log
from impactcli.logs.messages.ros2_cdr import HEADER_DEFS, JOINT_STATE, JOINT_STATE_DEF
from impactcli.logs.messages.ros2_cdr import encode_jointstates as encode_js
from impactcli.types import RobotLog

from .conftest import make_log

JOINTS = ("shoulder", "elbow", "wrist")
T0 = 1_700_000_000_123_456_789
#: every per-joint signal RobotLog carries
ALL = ("position", "torque", "velocity", "current", "position_ref", "velocity_ref",
       "acceleration_ref", "torque_model", "torque_ext")

ARM = "my_msgs/msg/ArmState"
#: a custom state message: all a controller knows about 3 joints (ROS 1 style field names)
ARM_BODY = """std_msgs/Header header
float64[3] q
float64[3] dq
float64[3] q_d
float64[3] dq_d
float64[3] ddq_d
float64[3] tau_J
float64[3] tau_model
float64[3] tau_ext
uint8 robot_mode
string note
"""
ARM_DEF = ARM_BODY + HEADER_DEFS
#: the same without a header (stamped by log time)
BARE = "my_msgs/msg/BareState"
BARE_DEF = "float64[3] q\nfloat64[3] tau_J\n"


#: The ros2msg definitions :func:`write_mcap` registers by type name (a test adds its own
#: message types here).
DEFS: dict[str, str] = {JOINT_STATE: JOINT_STATE_DEF, ARM: ARM_DEF, BARE: BARE_DEF}


def fixture_log(n: int = 500, t0: int = T0, acc_ref: bool = False) -> RobotLog:
    """3 joints, jittered epoch times, every signal a JointState can carry; 'elbow' does not
    log torque_ext (an all-NaN column)."""
    base = make_log(n=n, joints=JOINTS, seed=11)
    rng = np.random.default_rng(12)
    t = t0 + np.cumsum(rng.integers(1_900_000, 2_100_000, n)).astype(np.int64)
    te = rng.normal(size=(n, 3))
    te[:, 1] = np.nan
    return RobotLog(
        t_ns=t, joint_names=JOINTS, position=base.position, torque=base.torque,
        velocity=rng.normal(size=(n, 3)), position_ref=base.position_ref,
        velocity_ref=base.velocity_ref, acceleration_ref=base.acceleration_ref if acc_ref else None,
        torque_model=rng.normal(size=(n, 3)), torque_ext=te,
    )


def csv_copy(log: RobotLog, tmp: Path) -> RobotLog:
    """The log as read back from its canonical CSV (the reference every format must equal)."""
    p = tmp / "ref.csv"
    write_log(log, p)
    return read_log(p)


def assert_same(back: RobotLog, ref: RobotLog, signals: tuple[str, ...] = ALL) -> None:
    assert back.joint_names == ref.joint_names
    np.testing.assert_array_equal(back.t_ns, ref.t_ns)
    for s in signals:
        a, b = getattr(back, s), getattr(ref, s)
        if b is None:
            assert a is None, s
        else:
            assert a is not None, s
            np.testing.assert_array_equal(a, b, err_msg=s)


def store_with(*defs: tuple[str, str], base: str = "empty") -> Any:
    """A rosbags Typestore holding the given (type name, ros2msg text) definitions."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore({"empty": Stores.EMPTY, "ros2": Stores.ROS2_HUMBLE,
                           "ros1": Stores.ROS1_NOETIC}[base])
    for name, text in defs:
        store.register(get_types_from_msg(text, name))
    return store


def arm_messages(store: Any, log: RobotLog, name: str = ARM) -> list[bytes]:
    """One ArmState CDR message per sample of ``log`` (tau_ext NaN where not logged)."""
    M = store.types[name]
    H, T = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    acc = log.acceleration_ref if log.acceleration_ref is not None else np.zeros_like(log.position)
    out = []
    for i, t in enumerate(log.t_ns.tolist()):
        sec, nsec = divmod(t, 10**9)
        m = M(header=H(stamp=T(sec=sec, nanosec=nsec), frame_id="base"),
              q=log.position[i].copy(), dq=log.velocity[i].copy(), q_d=log.position_ref[i].copy(),
              dq_d=log.velocity_ref[i].copy(), ddq_d=acc[i].copy(), tau_J=log.torque[i].copy(),
              tau_model=log.torque_model[i].copy(), tau_ext=log.torque_ext[i].copy(),
              robot_mode=2, note=f"sample {i}")
        out.append(bytes(store.serialize_cdr(m, name)))
    return out


Channel = tuple[str, str, str, str, list[tuple[int, int, bytes]]]


def write_mcap(path: Path, channels: list[Channel], chunk_size: int = 4096) -> None:
    """channels: (topic, schema name, schema encoding, message encoding, [(log time, publish
    time, data)]); messages written in log-time order, in small chunks (many batches)."""
    with open(path, "wb") as f:
        w = McapWriter(f, compression=CompressionType.ZSTD, chunk_size=chunk_size)
        w.start("ros2", "test")
        msgs = []
        sids: dict[tuple[str, str], int] = {}
        for topic, sname, senc, menc, rows in channels:
            if (sname, senc) not in sids:
                text = DEFS.get(sname, "{}")
                sids[(sname, senc)] = w.register_schema(sname, senc, text.encode())
            cid = w.register_channel(topic, menc, sids[(sname, senc)])
            msgs += [(lt, k, cid, pt, data) for k, (lt, pt, data) in enumerate(rows)]
        for lt, k, cid, pt, data in sorted(msgs, key=lambda m: (m[0], m[2])):
            w.add_message(cid, log_time=lt, publish_time=pt, sequence=k, data=data)
        w.finish()


def jointstates(t: np.ndarray, names: list[str], position: np.ndarray | None,
                effort: np.ndarray | None, log_delay: int = 0) -> list[tuple[int, int, bytes]]:
    rows = encode_js(t, names, position, None, effort)
    return [(int(x) + log_delay, int(x) + log_delay, rows[i].tobytes())
            for i, x in enumerate(t.tolist())]


def arm_map(path: Path, topic: str = "/arm/state", acc: bool = True, **extra: Any) -> Path:
    """A messages map reading every signal of ArmState (torque_ext only where logged)."""
    joints = []
    for k, j in enumerate(JOINTS):
        d: dict[str, Any] = {
            "name": j, "position": f"{topic}/q[{k}]", "velocity": f"{topic}/dq[{k}]",
            "torque": f"{topic}/tau_J[{k}]", "position_ref": f"{topic}/q_d[{k}]",
            "velocity_ref": f"{topic}/dq_d[{k}]", "torque_model": f"{topic}/tau_model[{k}]",
        }
        if acc:
            d["acceleration_ref"] = f"{topic}/ddq_d[{k}]"
        if j != "elbow":
            d["torque_ext"] = {"field": f"{topic}/tau_ext[{k}]"}
        joints.append(d)
    cmap = {"schema_version": "1.0", "name": "arm", "format": "messages", "joints": joints,
            **extra}
    path.write_text(yaml.safe_dump(cmap, sort_keys=False))
    return path


def two_topics(tmp: Path, ext_names: list[str]) -> tuple[Path, np.ndarray, np.ndarray,
                                                            np.ndarray, RobotLog]:
    """State JointState at 500 Hz; /external_torque JointState at 100 Hz, starting late, its
    joints in another order (plus a gripper), received 3 ms after its stamp."""
    log = fixture_log(n=400)
    rng = np.random.default_rng(3)
    te_t = log.t_ns[0] + 7_500_000 + np.arange(75, dtype=np.int64) * 10_000_000
    te = rng.normal(size=(75, len(ext_names)))
    p = tmp / "two.mcap"
    write_mcap(p, [
        ("/joint_states", JOINT_STATE, "ros2msg", "cdr",
         [(lt, lt, d) for lt, _, d in jointstates(log.t_ns, list(JOINTS), log.position,
                                                  log.torque, log_delay=1_000_000)]),
        ("/external_torque", JOINT_STATE, "ros2msg", "cdr",
         jointstates(te_t, ext_names, None, te, log_delay=3_000_000)),
    ])
    return p, te_t, te, log.t_ns, log
