"""MCAP logs (formats.md, "MCAP"): impactcli's JSON joint samples, ROS 2 JointState, and any
message type through a channel map.

Reading: the file is scanned in bulk (:mod:`impactcli.io.mcap_scan`; the official ``mcap``
reader for what the scanner does not handle) and read by
:func:`impactcli.io.messages.read_message_channels`, shared with ROS bags: topic choice
(``topic``; the only joint topic; ``/joint_states``), default companion topics
``<topic>_ref`` (reference), ``<topic>_model`` (effort = torque_model) and ``<topic>_ext``
(effort = torque_ext) aligned by causal sample-and-hold, time source (``header`` stamp when
every stamp is non-zero, else ``log``; ``time_source`` overrides), and channel maps with
``format: messages`` naming message fields (ROS 2 CDR with the ``ros2msg``/``ros2idl``
schemas stored in the file, ROS 1 with ``ros1msg``, JSON).

Writing: :func:`write_mcap_json` (one JSON JointSample per sample, every signal) and
:func:`write_mcap_ros2` (JointState state, ``_ref``, ``_model`` and ``_ext`` topics).
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
from .channel_map import SIGNALS, ChannelMap
from .mcap_ros2 import JOINT_STATE, JOINT_STATE_DEF
from .mcap_scan import UnsupportedMcap, scan_mcap, scan_mcap_official
from .messages import read_message_channels
from .msgsource import JOINT_SAMPLE, McapSource

JSON_TOPIC = "/joint_samples"
ROS2_TOPIC = "/joint_states"
ROS2_REF_TOPIC = "/joint_states_ref"


def read_mcap_channels(
    path: Path, *, topic: str | None, reference_topic: str | None, time_source: str | None,
    cmap: ChannelMap | None = None,
) -> tuple[JointChannels, str, str]:
    """Read an MCAP log into :class:`JointChannels` (:mod:`impactcli.io.messages`).

    Returns:
        ``(channels, format, time_source)``, format ``mcap-json``, ``mcap-ros2`` or
        ``mcap-ros1`` (by the state topic's encoding).
    """
    where = str(path)
    if time_source is not None and time_source not in TIME_SOURCES:
        raise LogFormatError(f"{where}: unknown time source {time_source!r} (log, publish, header)")
    try:
        scan = scan_mcap(path)
    except UnsupportedMcap:
        # the official reader, for what the scanner does not handle
        scan = scan_mcap_official(path)
    if scan.n_messages == 0:
        what = ("truncated before its first complete message" if scan.truncated
                else "holds no messages")
        raise LogFormatError(f"{where}: corrupt or empty MCAP: {what}")
    src = McapSource(scan, where)
    if scan.truncated:
        msg = (
            f"{where}: MCAP file is truncated (records end early); read the "
            f"{scan.n_messages} complete message(s) before the cut"
        )
        warnings.warn(msg, ImpactWarning, stacklevel=4)
        src.repairs.append(msg)
    return read_message_channels(src, cmap=cmap, topic=topic, reference_topic=reference_topic,
                                 time_source=time_source)


def _check_times(log: RobotLog, path: Path) -> None:
    if log.t_ns[0] < 0:
        raise LogFormatError(
            f"{path}: MCAP cannot hold negative times (first sample {log.t_ns[0]} ns)"
        )


def _nan_as_none(a: np.ndarray) -> list[Any]:
    obj = a.astype(object)
    obj[np.isnan(a)] = None
    out: list[Any] = obj.tolist()
    return out


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
    lists = {s: _nan_as_none(a) if s in CONTROLLER_CHANNELS else a.tolist() for s, a in sigs}
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

    effort = torque; velocity filled when the log has it. At the same times: the reference
    (``position_ref``, ``velocity_ref``) on ``/joint_states_ref``, ``torque_model`` as the
    effort of ``/joint_states_model`` and ``torque_ext`` as the effort of
    ``/joint_states_ext`` — each naming only the joints that log the channel. Header stamp =
    log_time = publish_time = t_ns. ``pad`` appends that many zero bytes to every message
    (as some real recorders do; for tests); ``chunk_size`` [bytes] is the MCAP chunk size.
    Current and acceleration_ref are not carried.
    """
    from .._fs import atomic_output

    p = Path(path)
    _check_times(log, p)
    topics = jointstate_topics(log, ROS2_TOPIC)
    zeros = b"\x00" * pad
    with atomic_output(p, "wb") as f:
        w, sid = ros2_writer(f, chunk_size)
        cids = [w.register_channel(topic=name, message_encoding="cdr", schema_id=sid)
                for name, _ in topics]
        for i, t in enumerate(log.t_ns.tolist()):
            # companions first: a state sample never precedes its reference at equal times
            for cid, (_, rows) in reversed(list(zip(cids, topics, strict=True))):
                w.add_message(cid, log_time=t, publish_time=t, sequence=i,
                              data=rows[i].tobytes() + zeros)
        w.finish()  # type: ignore[no-untyped-call]


def ros2_writer(f: Any, chunk_size: int = 1 << 20) -> tuple[Any, int]:
    """An MCAP writer started on the open binary file ``f`` (zstd chunks of
    ``chunk_size`` bytes, ``ros2`` profile) and the id of its JointState schema
    (``ros2msg``): register channels on it, add messages, ``finish()``."""
    from mcap.writer import CompressionType, Writer

    w = Writer(f, compression=CompressionType.ZSTD, chunk_size=chunk_size)
    w.start(profile="ros2", library="impactcli")
    sid = w.register_schema(name=JOINT_STATE, encoding="ros2msg",
                            data=JOINT_STATE_DEF.encode())
    return w, sid


def jointstate_topics(log: RobotLog, state_topic: str) -> list[tuple[str, np.ndarray]]:
    """The JointState topics that carry ``log`` and their CDR messages, state topic first.

    Returns:
        ``[(topic, (N, L) uint8 rows of CDR bytes)]``: ``state_topic`` (position, velocity,
        effort = torque), ``<state_topic>_ref`` (position_ref, velocity_ref) when the log has
        a reference, ``_model`` / ``_ext`` (effort = torque_model / torque_ext, naming only
        the joints that log it) when the log has the channel.
    """
    from .mcap_ros2 import encode_jointstates

    out = [(state_topic, encode_jointstates(log.t_ns, log.joint_names, log.position,
                                            log.velocity, log.torque))]
    if log.position_ref is not None:
        out.append((f"{state_topic}_ref", encode_jointstates(
            log.t_ns, log.joint_names, log.position_ref, log.velocity_ref, None)))
    for suffix, sig in (("_model", "torque_model"), ("_ext", "torque_ext")):
        arr = getattr(log, sig)
        if arr is None:
            continue
        has = log.has_channel(sig)
        names = [nm for nm, h in zip(log.joint_names, has, strict=True) if h]
        out.append((f"{state_topic}{suffix}",
                    encode_jointstates(log.t_ns, names, None, None, arr[:, has])))
    return out
