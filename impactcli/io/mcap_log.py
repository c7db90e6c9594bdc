"""MCAP logs (formats.md, "MCAP"): impactcli's JSON joint samples and ROS 2 JointState.

Topic choice: ``topic`` when given; else the only joint topic (JointState or JointSample);
else ``/joint_states``; else an error listing the topics. The ROS 2 reference topic is
``reference_topic`` when given, else ``<topic>_ref`` when present; it is aligned to the state
messages by sample-and-hold of the latest reference at or before each state message
(causal); state samples before the first reference are dropped (a warned repair).

Time source: ``header`` (the message's stamp: ROS 2 ``header.stamp``, JSON ``stamp_ns``)
when every stamp is non-zero, else ``log`` (the recorder's log time); ``time_source``
(``log``/``publish``/``header``) overrides. Messages are ordered by the chosen time.
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImpactWarning, LogFormatError
from ..types import CONTROLLER_CHANNELS, RobotLog
from .assemble import TIME_SOURCES, JointChannels
from .channel_map import SIGNALS
from .mcap_ros2 import (
    JOINT_STATE,
    JOINT_STATE_DEF,
    TopicArrays,
    decode_topic,
    decode_topic_official,
)
from .mcap_scan import McapScan, UnsupportedMcap, scan_mcap
from .repair import repair_matrix

JOINT_SAMPLE = "impactcli/JointSample"
JSON_TOPIC = "/joint_samples"
ROS2_TOPIC = "/joint_states"
ROS2_REF_TOPIC = "/joint_states_ref"


def _kind(scan: McapScan, cid: int) -> str | None:
    _topic, sid, menc = scan.channels[cid]
    name = scan.schemas.get(sid, ("", "", b""))[0]
    if name in (JOINT_STATE, "sensor_msgs/JointState") and menc == "cdr":
        return "ros2"
    if name == JOINT_SAMPLE and menc == "json":
        return "json"
    return None


def _pick_topic(scan: McapScan, topic: str | None, where: str) -> tuple[str, str]:
    topics = scan.topics()
    joint_topics = {
        t: k for t, cids in topics.items() if (k := _kind(scan, cids[0])) is not None
    }
    listing = ", ".join(sorted(topics)) or "none"
    if topic is not None:
        if topic not in topics:
            raise LogFormatError(f"{where}: topic {topic!r} not found (topics: {listing})")
        if topic not in joint_topics:
            raise LogFormatError(
                f"{where}: topic {topic!r} is not JointState (CDR) nor impactcli JointSample "
                f"(JSON) (topics: {listing})"
            )
        return topic, joint_topics[topic]
    if len(joint_topics) == 1:
        t = next(iter(joint_topics))
        return t, joint_topics[t]
    if ROS2_TOPIC in joint_topics:
        return ROS2_TOPIC, joint_topics[ROS2_TOPIC]
    raise LogFormatError(
        f"{where}: cannot choose the joint-state topic; pass --topic (topics: {listing})"
    )


def _choose_time(
    arr: TopicArrays, time_source: str | None, where: str, topic: str
) -> tuple[np.ndarray, str]:
    if time_source is None:
        if np.all(arr.header != 0):
            return arr.header, "header"
        return arr.log_time, "log"
    if time_source == "header":
        if np.any(arr.header == 0):
            k = int(np.argmax(arr.header == 0))
            raise LogFormatError(
                f"{where}: topic {topic!r}, message {k}: header stamp is zero; use "
                "--time-source log or publish"
            )
        return arr.header, "header"
    if time_source == "publish":
        return arr.publish_time, "publish"
    return arr.log_time, "log"


def _json_topic(scan: McapScan, cids: list[int], where: str, topic: str) -> TopicArrays:
    """Decode impactcli JSON joint samples into TopicArrays (+ extra signals in attributes)."""
    batches = [b for c in cids for b in scan.batches.get(c, [])]
    if not batches:
        raise LogFormatError(f"{where}: topic {topic!r} holds no messages")
    items: list[tuple[int, int, int, bytes]] = []
    for b in batches:
        for o, ln, lt, pt, od in zip(b.data_off.tolist(), b.data_len.tolist(),
                                     b.log_time.tolist(), b.publish_time.tolist(),
                                     b.order.tolist(), strict=True):
            items.append((od, lt, pt, b.buf[o : o + ln].tobytes()))
    items.sort(key=lambda x: x[0])
    msgs = []
    for k, (_, _, _, data) in enumerate(items):
        try:
            m = json.loads(data)
            if not isinstance(m, dict) or not isinstance(m.get("name"), list):
                raise ValueError("no 'name' list")
        except ValueError as err:
            raise LogFormatError(
                f"{where}: topic {topic!r}, message {k}: bad JSON sample: {err}"
            ) from None
        msgs.append(m)
    joints = tuple(str(s) for s in msgs[0]["name"])
    jidx = {nm: i for i, nm in enumerate(joints)}
    n, jn = len(msgs), len(joints)
    vals = {s: np.full((n, jn), np.nan) for s in SIGNALS}
    has = {s: np.zeros(n, dtype=bool) for s in SIGNALS}
    has_joints = np.zeros(n, dtype=bool)
    header = np.zeros(n, dtype=np.int64)
    extra: set[str] = set()
    for i, m in enumerate(msgs):
        names = m["name"]
        cols = [jidx.get(nm, -1) for nm in names]
        extra.update(nm for nm in names if nm not in jidx)
        has_joints[i] = len({c for c in cols if c >= 0}) == jn
        header[i] = int(m.get("stamp_ns", 0) or 0)
        for s in SIGNALS:
            v = m.get(s)
            if isinstance(v, list) and len(v) == len(names) and v:
                has[s][i] = True
                for c, x in zip(cols, v, strict=True):
                    if c >= 0:
                        vals[s][i, c] = np.nan if x is None else float(x)
    out = TopicArrays(
        joints, np.array([x[1] for x in items], dtype=np.int64),
        np.array([x[2] for x in items], dtype=np.int64), header,
        vals["position"], vals["velocity"], vals["torque"], has_joints,
        has["position"], has["velocity"], has["torque"], extra,
    )
    out.json_extra = (vals, has)  # type: ignore[attr-defined]
    return out


def read_mcap_channels(
    path: Path, *, topic: str | None, reference_topic: str | None, time_source: str | None,
) -> tuple[JointChannels, str, str]:
    """Read an MCAP log into :class:`JointChannels`.

    Returns:
        ``(channels, format, time_source)``, format ``mcap-json`` or ``mcap-ros2``.
    """
    where = str(path)
    if time_source is not None and time_source not in TIME_SOURCES:
        raise LogFormatError(f"{where}: unknown time source {time_source!r} (log, publish, header)")
    try:
        scan: McapScan | None = scan_mcap(path)
    except UnsupportedMcap:
        scan = None
    if scan is None:
        # the official reader, for what the scanner does not handle (ROS 2 only)
        t = topic or ROS2_TOPIC
        state = decode_topic_official(path, t, where)
        rt = reference_topic or f"{t}_ref"
        try:
            ref = decode_topic_official(path, rt, where, state.joints)
        except LogFormatError as err:
            if reference_topic is not None or "holds no messages" not in str(err):
                raise
            ref = None
        rtopic = rt if ref is not None else None
        return _assemble(state, ref, "ros2", where, t, rtopic, time_source, [], [])
    if scan.n_messages == 0:
        what = ("truncated before its first complete message" if scan.truncated
                else "holds no messages")
        raise LogFormatError(f"{where}: corrupt or empty MCAP: {what}")
    repairs: list[str] = []
    if scan.truncated:
        msg = (
            f"{where}: MCAP file is truncated (records end early); read the "
            f"{scan.n_messages} complete message(s) before the cut"
        )
        warnings.warn(msg, ImpactWarning, stacklevel=4)
        repairs.append(msg)
    t, kind = _pick_topic(scan, topic, where)
    topics = scan.topics()
    cids = topics[t]
    if kind == "json":
        state = _json_topic(scan, cids, where, t)
        ref = None
        rtopic = None
        if reference_topic is not None:
            raise LogFormatError(
                f"{where}: --reference-topic applies to ROS 2 JointState; JSON samples carry "
                "their reference in each message"
            )
    else:
        state = decode_topic(scan, cids, where, t)
        rtopic = reference_topic
        if rtopic is None and f"{t}_ref" in topics and _kind(scan, topics[f"{t}_ref"][0]) == "ros2":
            rtopic = f"{t}_ref"
        ref = None
        if rtopic is not None:
            if rtopic not in topics:
                raise LogFormatError(
                    f"{where}: reference topic {rtopic!r} not found (topics: "
                    f"{', '.join(sorted(topics))})"
                )
            if _kind(scan, topics[rtopic][0]) != "ros2":
                raise LogFormatError(
                    f"{where}: reference topic {rtopic!r} is not a JointState topic"
                )
            ref = decode_topic(scan, topics[rtopic], where, rtopic, state.joints)
    ignored = [x for x in sorted(topics) if x not in (t, rtopic)]
    return _assemble(state, ref, kind, where, t, rtopic, time_source, ignored, repairs)


def _assemble(
    state: TopicArrays, ref: TopicArrays | None, kind: str, where: str, topic: str,
    rtopic: str | None, time_source: str | None, ignored: list[str], repairs: list[str],
) -> tuple[JointChannels, str, str]:
    t, tsrc = _choose_time(state, time_source, where, topic)
    sorted_already = bool(np.all(np.diff(t) >= 0))
    perm = np.arange(t.shape[0]) if sorted_already else np.argsort(t, kind="stable")
    if not sorted_already:
        t = t[perm]
    missing_joint = ~state.has_joints
    if missing_joint.any():
        k = int(np.argmax(missing_joint))
        raise LogFormatError(
            f"{where}: topic {topic!r}, message {k} lacks some of the joints "
            f"{', '.join(state.joints)}"
        )
    joints = state.joints
    jn = len(joints)
    extra = getattr(state, "json_extra", None)
    if extra is not None:
        vals, has = extra
    else:
        vals = {"position": state.position, "velocity": state.velocity, "torque": state.effort}
        has = {"position": state.has_position, "velocity": state.has_velocity,
               "torque": state.has_effort}
    used: list[str] = []
    for s in SIGNALS:
        if s not in has:
            continue
        h = has[s]
        if h.all():
            used.append(s)
        elif h.any():
            if s in ("position", "torque"):
                k = int(np.argmax(~h))
                what = "effort (torque)" if s == "torque" and kind == "ros2" else s
                raise LogFormatError(f"{where}: topic {topic!r}, message {k} has no {what}")
            ignored.append(f"{topic}:{s} (not in every message)")
    if "position" not in used:
        raise LogFormatError(f"{where}: topic {topic!r} carries no joint positions")
    ignored += [f"{topic}:{nm}" for nm in sorted(state.extra_names)]
    mat = np.concatenate([vals[s] for s in used], axis=1)
    if not sorted_already:
        mat = mat[perm]
    names = [f"{nm}.{s}" for s in used for nm in joints]

    def label(i: int) -> str:
        return f"message {int(perm[i])} of {topic!r}"

    t, mat, rep = repair_matrix(t, mat, names, where=where, time_name=f"{tsrc} time",
                                row_label=label)
    repairs += rep
    signals = {s: mat[:, k * jn : (k + 1) * jn] for k, s in enumerate(used)}
    if ref is not None and rtopic is not None:
        if not ref.has_joints.all():
            k = int(np.argmax(~ref.has_joints))
            raise LogFormatError(
                f"{where}: topic {rtopic!r}, message {k} lacks some of the joints"
            )
        if not ref.has_position.all():
            k = int(np.argmax(~ref.has_position))
            raise LogFormatError(f"{where}: topic {rtopic!r}, message {k} has no position")
        if tsrc == "header" and np.all(ref.header != 0):
            tr = ref.header
        else:
            tr = ref.publish_time if tsrc == "publish" else ref.log_time
        rp = np.argsort(tr, kind="stable")
        tr = tr[rp]
        idx = np.searchsorted(tr, t, side="right") - 1
        lead = int(np.sum(idx < 0))
        if lead == len(t):
            raise LogFormatError(
                f"{where}: reference topic {rtopic!r} starts after the last state message"
            )
        if lead:
            msg = (
                f"{where}: dropped the first {lead} state sample(s), recorded before the "
                f"first reference message on {rtopic!r}"
            )
            warnings.warn(msg, ImpactWarning, stacklevel=4)
            repairs.append(msg)
            t = t[lead:]
            signals = {k: v[lead:] for k, v in signals.items()}
            idx = idx[lead:]
        sel = rp[idx]
        signals["position_ref"] = ref.position[sel]
        if ref.has_velocity.all():
            signals["velocity_ref"] = ref.velocity[sel]
        for sig in ("position_ref", "velocity_ref"):
            if sig in signals and not np.all(np.isfinite(signals[sig])):
                raise LogFormatError(f"{where}: reference {sig!r} on {rtopic!r} is not finite")
    ch = JointChannels(
        t_ns=t, joints=joints, signals=signals, missing={}, current_scale=None,
        ignored=ignored, repairs=repairs,
    )
    return ch, f"mcap-{kind}", tsrc


def _check_times(log: RobotLog, path: Path) -> None:
    if log.t_ns[0] < 0:
        raise LogFormatError(
            f"{path}: MCAP cannot hold negative times (first sample {log.t_ns[0]} ns)"
        )


def write_mcap_json(log: RobotLog, path: str | os.PathLike[str]) -> None:
    """Write ``log`` as MCAP with impactcli JSON joint samples on ``/joint_samples`` (atomic).

    One message per sample: ``stamp_ns`` and, per signal the log has, a list over ``name``.
    log_time = publish_time = stamp_ns = t_ns.
    """
    from mcap.writer import CompressionType, Writer

    from .._fs import atomic_output
    from ..schema import schema_dir

    p = Path(path)
    _check_times(log, p)
    sigs = [(s, getattr(log, s)) for s in SIGNALS if getattr(log, s) is not None]
    names = list(log.joint_names)
    lists = {s: np.where(np.isnan(a), None, a).tolist() if s in CONTROLLER_CHANNELS else a.tolist()
             for s, a in sigs}
    with atomic_output(p, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="", library="impactcli")
        sid = w.register_schema(
            name=JOINT_SAMPLE, encoding="jsonschema",
            data=(schema_dir() / "joint_sample.schema.json").read_bytes(),
        )
        cid = w.register_channel(topic=JSON_TOPIC, message_encoding="json", schema_id=sid)
        for i, t in enumerate(log.t_ns.tolist()):
            msg: dict[str, Any] = {"stamp_ns": t, "name": names}
            for s, _ in sigs:
                msg[s] = lists[s][i]
            w.add_message(cid, log_time=t, publish_time=t, sequence=i,
                          data=json.dumps(msg, separators=(",", ":")).encode())
        w.finish()  # type: ignore[no-untyped-call]


def write_mcap_ros2(
    log: RobotLog, path: str | os.PathLike[str], *, pad: int = 0, chunk_size: int = 1 << 20,
) -> None:
    """Write ``log`` as MCAP with ROS 2 JointState (CDR) on ``/joint_states`` (atomic).

    effort = torque; velocity filled when the log has it. The reference (``position_ref``,
    ``velocity_ref``) goes to ``/joint_states_ref`` at the same times. Header stamp =
    log_time = publish_time = t_ns. ``pad`` appends that many zero bytes to every message
    (as some real recorders do; for tests); ``chunk_size`` [bytes] is the MCAP chunk size.
    Current and acceleration_ref are not carried.
    """
    from mcap.writer import CompressionType, Writer

    from .._fs import atomic_output
    from .mcap_ros2 import encode_jointstates

    p = Path(path)
    _check_times(log, p)
    state = encode_jointstates(log.t_ns, log.joint_names, log.position, log.velocity, log.torque)
    refs = None
    if log.position_ref is not None:
        refs = encode_jointstates(log.t_ns, log.joint_names, log.position_ref,
                                  log.velocity_ref, None)
    zeros = b"\x00" * pad
    with atomic_output(p, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD, chunk_size=chunk_size)
        w.start(profile="ros2", library="impactcli")
        sid = w.register_schema(name=JOINT_STATE, encoding="ros2msg",
                                data=JOINT_STATE_DEF.encode())
        cid = w.register_channel(topic=ROS2_TOPIC, message_encoding="cdr", schema_id=sid)
        rid = (w.register_channel(topic=ROS2_REF_TOPIC, message_encoding="cdr", schema_id=sid)
               if refs is not None else None)
        for i, t in enumerate(log.t_ns.tolist()):
            if refs is not None and rid is not None:
                w.add_message(rid, log_time=t, publish_time=t, sequence=i,
                              data=refs[i].tobytes() + zeros)
            w.add_message(cid, log_time=t, publish_time=t, sequence=i,
                          data=state[i].tobytes() + zeros)
        w.finish()  # type: ignore[no-untyped-call]
