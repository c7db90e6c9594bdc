"""MCAP with ROS 2 ``sensor_msgs/msg/JointState`` (CDR): bulk decoder, encoder (docs/formats.md).

Decoding (:func:`decode_batches`, a block's messages of one topic as
:class:`~impactcli.logs.messages.mcap.McapBlocks` locates them): messages of one batch with the
same size are decoded together: the first is parsed field by field to learn its layout
(offsets of the stamp and of the position/velocity/effort float64 arrays, its joint
names), every other message of the group is checked to have the same bytes everywhere
except the stamp and the float64 arrays, and the values are read with NumPy views.
Messages that differ (other names, order or frame id) are parsed one by one. Joints are
matched by ``name[]`` on every message. Trailing CDR padding is ignored.
:func:`decode_topic_official` is the official ``mcap`` + ``mcap_ros2`` decoder (the
tests' reference).

CDR layout of JointState (little endian, alignment relative to the byte after the 4-byte
encapsulation header): ``int32 sec, uint32 nanosec, string frame_id, sequence<string> name,
sequence<float64> position, velocity, effort`` — a sequence is a uint32 count followed by its
elements, aligned to the element size only when it has elements.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import LogFormatError
from .message_source import Batch

JOINT_STATE = "sensor_msgs/msg/JointState"
#: The definitions a ROS 2 message with a ``std_msgs/Header`` appends to its own (ros2msg).
HEADER_DEFS = """================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
JOINT_STATE_DEF = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
""" + HEADER_DEFS


@dataclass(frozen=True)
class Layout:
    """One JointState message's decoded content and field offsets (bytes from data start).

    Attributes:
        stamp_ns: header stamp [ns].
        names: joint names in message order.
        arrays: (offset, count) of position, velocity, effort.
        little: little-endian CDR.
    """

    stamp_ns: int
    names: tuple[str, ...]
    arrays: tuple[tuple[int, int], tuple[int, int], tuple[int, int]]
    little: bool

    def values(self, data: bytes | memoryview) -> list[np.ndarray]:
        """The three float64 arrays of ``data`` (same layout)."""
        dt = "<f8" if self.little else ">f8"
        return [np.frombuffer(data, dtype=dt, count=c, offset=o) for o, c in self.arrays]


def parse_jointstate(data: bytes | memoryview) -> Layout:
    """Parse one CDR JointState message (either endianness; trailing padding ignored).

    Raises:
        ValueError: the bytes are not a JointState.
    """
    buf = bytes(data)
    if len(buf) < 4:
        raise ValueError("message shorter than its CDR header")
    little = buf[1] in (1, 3)
    if buf[0] != 0 or buf[1] not in (0, 1, 2, 3):
        raise ValueError(f"unknown CDR encapsulation {buf[:2].hex()}")
    e = "<" if little else ">"
    pos = 4

    def align(p: int, size: int) -> int:
        return 4 + (-(-(p - 4) // size)) * size

    def u32(p: int) -> tuple[int, int]:
        p = align(p, 4)
        if p + 4 > len(buf):
            raise ValueError("message ends early")
        return struct.unpack_from(e + "I", buf, p)[0], p + 4

    sec = struct.unpack_from(e + "i", buf, pos)[0]
    nsec = struct.unpack_from(e + "I", buf, pos + 4)[0]
    pos += 8
    n, pos = u32(pos)
    pos += n  # frame_id
    count, pos = u32(pos)
    names = []
    for _ in range(count):
        n, pos = u32(pos)
        if n < 1 or pos + n > len(buf):
            raise ValueError("bad string in name[]")
        names.append(buf[pos : pos + n - 1].decode("utf-8"))
        pos += n
    arrays = []
    for _ in range(3):
        c, pos = u32(pos)
        if c:
            pos = align(pos, 8)
        if pos + 8 * c > len(buf):
            raise ValueError("float64 array runs past the message")
        arrays.append((pos, c))
        pos += 8 * c
    return Layout(sec * 10**9 + nsec, tuple(names), tuple(arrays), little)  # type: ignore[arg-type]


def encode_jointstates(
    t_ns: np.ndarray,
    names: Iterable[str],
    position: np.ndarray | None,
    velocity: np.ndarray | None,
    effort: np.ndarray | None,
    frame_id: str = "",
) -> np.ndarray:
    """Encode N JointState messages of a fixed joint set at once.

    Args:
        t_ns: (N,) header stamps [ns].
        names: J joint names.
        position, velocity, effort: (N, J) values, or ``None`` for an empty array.

    Returns:
        (N, L) uint8: row k is message k's CDR bytes.
    """
    names = list(names)
    parts: list[tuple[str, Any]] = []  # layout in bytes, built once
    head = bytearray(b"\x00\x01\x00\x00")
    head += b"\x00" * 8  # stamp placeholder
    fid = frame_id.encode() + b"\x00"
    head += struct.pack("<I", len(fid)) + fid

    def pad(b: bytearray, size: int) -> None:
        b += b"\x00" * ((-(len(b) - 4)) % size)

    pad(head, 4)
    head += struct.pack("<I", len(names))
    for nm in names:
        pad(head, 4)
        s = nm.encode() + b"\x00"
        head += struct.pack("<I", len(s)) + s
    layout = bytearray(head)
    offsets = []
    for arr in (position, velocity, effort):
        pad(layout, 4)
        c = 0 if arr is None else len(names)
        layout += struct.pack("<I", c)
        if c:
            pad(layout, 8)
        offsets.append(len(layout))
        layout += b"\x00" * (8 * c)
    n = len(t_ns)
    out = np.empty((n, len(layout)), dtype=np.uint8)
    out[:] = np.frombuffer(bytes(layout), dtype=np.uint8)
    t = np.asarray(t_ns, dtype=np.int64)
    sec, nsec = np.divmod(t, 10**9)
    out[:, 4:8] = sec.astype("<i4").view(np.uint8).reshape(n, 4)
    out[:, 8:12] = nsec.astype("<u4").view(np.uint8).reshape(n, 4)
    del parts
    for arr, off in zip((position, velocity, effort), offsets, strict=True):
        if arr is not None:
            a = np.ascontiguousarray(arr, dtype="<f8")
            out[:, off : off + 8 * len(names)] = a.view(np.uint8).reshape(n, -1)
    return out


@dataclass
class TopicArrays:
    """One JointState topic decoded into arrays, in file order.

    Attributes:
        joints: J joint names (those of the first message unless given).
        log_time, publish_time, header: (n,) int64 [ns].
        position, velocity, effort: (n, J) float64, NaN where a message lacks the value.
        has_joints: (n,) every joint present in the message.
        has_velocity, has_effort, has_position: (n,) the array is filled.
        extra_names: names seen in messages but not in ``joints``.
        joint_seen: (J,) the joint is named in at least one message.
        named: (n, J) the joint is named in the message.
    """

    joints: tuple[str, ...]
    log_time: np.ndarray
    publish_time: np.ndarray
    header: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
    has_joints: np.ndarray
    has_position: np.ndarray
    has_velocity: np.ndarray
    has_effort: np.ndarray
    extra_names: set[str]
    joint_seen: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    named: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))


def _rows(b: Batch, sel: np.ndarray, length: int) -> np.ndarray:
    off = b.data_off[sel]
    if off.shape[0] > 1:
        d = np.diff(off)
        if np.all(d == d[0]) and d[0] >= length:
            return np.lib.stride_tricks.as_strided(
                b.buf[off[0]:], shape=(off.shape[0], length), strides=(int(d[0]), 1),
                writeable=False,
            )
    rows: np.ndarray = b.buf[off[:, None] + np.arange(length)]
    return rows


def _static_ranges(lay: Layout, length: int) -> list[tuple[int, int]]:
    """Byte ranges of a message that must equal the group's first message (all but the
    stamp and the float64 arrays)."""
    cuts = sorted([(4, 12)] + [(o, o + 8 * c) for o, c in lay.arrays if c])
    out, pos = [], 0
    for a, z in cuts:
        if a > pos:
            out.append((pos, a))
        pos = max(pos, z)
    if pos < length:
        out.append((pos, length))
    return out


def _empty(n: int, j: int, names: tuple[str, ...]) -> TopicArrays:
    nan = np.full((n, j), np.nan)
    z = np.zeros(n, dtype=bool)
    return TopicArrays(
        names, np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64),
        nan, nan.copy(), nan.copy(), z, z.copy(), z.copy(), z.copy(), set(),
        np.zeros(j, dtype=bool), np.zeros((n, j), dtype=bool),
    )


def decode_topic(
    scan: Any, channel_ids: list[int], where: str, topic: str,
    joints: tuple[str, ...] | None = None,
) -> TopicArrays:
    """Decode every JointState message of ``channel_ids`` of an
    :class:`~impactcli.logs.messages.mcap.McapScan` into :class:`TopicArrays` (file order)."""
    batches = [b for c in channel_ids for b in scan.batches.get(c, [])]
    return decode_batches(batches, where, topic, joints)


def decode_batches(
    batches: list[Batch], where: str, topic: str, joints: tuple[str, ...] | None = None,
    offset: int = 0,
) -> TopicArrays:
    """Decode the CDR JointState messages of ``batches`` (one topic) into :class:`TopicArrays`
    in file order (by each batch's ``order``); joints are those of the first message unless
    given. ``offset``: the topic's messages before these (errors name messages by their
    number in the topic)."""
    if not batches:
        raise LogFormatError(f"{where}: topic {topic!r} holds no messages")
    orders = np.sort(np.concatenate([b.order for b in batches]))
    n = orders.shape[0]

    def bad(k: int, err: Exception) -> LogFormatError:
        return LogFormatError(f"{where}: topic {topic!r}, message {k + offset}: not a "
                              f"JointState: {err}")

    if joints is None:
        first = min(batches, key=lambda b: int(b.order[0]))
        o, ln = int(first.data_off[0]), int(first.data_len[0])
        try:
            joints = parse_jointstate(first.buf[o : o + ln].tobytes()).names
        except (ValueError, struct.error) as err:
            raise bad(0, err) from None
        if not joints:
            raise LogFormatError(f"{where}: topic {topic!r}: first message has no joint names")
    jn = len(joints)
    jidx = {nm: i for i, nm in enumerate(joints)}
    out = _empty(n, jn, joints)
    for b in batches:
        idx_all = np.searchsorted(orders, b.order)
        out.log_time[idx_all] = b.log_time
        out.publish_time[idx_all] = b.publish_time
        for length in np.unique(b.data_len).tolist():
            sel = np.flatnonzero(b.data_len == length)
            rows = _rows(b, sel, length)
            try:
                lay = parse_jointstate(rows[0].tobytes())
            except (ValueError, struct.error) as err:
                raise bad(int(idx_all[sel[0]]), err) from None
            if not lay.little:
                ok = np.zeros(len(sel), dtype=bool)
            else:
                ok = np.ones(len(sel), dtype=bool)
                for a, z in _static_ranges(lay, length):
                    ok &= np.all(rows[:, a:z] == rows[0, a:z], axis=1)
            good = sel[ok]
            gi = idx_all[good]
            if good.size:
                r = rows[ok] if not ok.all() else rows
                sec = np.ascontiguousarray(r[:, 4:8]).view("<i4").ravel().astype(np.int64)
                nsec = np.ascontiguousarray(r[:, 8:12]).view("<u4").ravel().astype(np.int64)
                out.header[gi] = sec * 10**9 + nsec
                self_cols = [jidx.get(nm, -1) for nm in lay.names]
                out.extra_names.update(nm for nm in lay.names if nm not in jidx)
                src = np.array([k for k, c in enumerate(self_cols) if c >= 0], dtype=np.int64)
                dst = np.array([c for c in self_cols if c >= 0], dtype=np.int64)
                out.has_joints[gi] = len(set(dst.tolist())) == jn
                out.joint_seen[dst] = True
                out.named[np.ix_(gi, dst)] = True
                targets = (out.position, out.velocity, out.effort)
                flags = (out.has_position, out.has_velocity, out.has_effort)
                identity = len(lay.names) == jn and bool(np.all(dst == np.arange(jn)))
                contiguous = bool(gi[-1] - gi[0] == gi.shape[0] - 1 and np.all(np.diff(gi) == 1))
                for (o, c), tgt, flag in zip(lay.arrays, targets, flags, strict=True):
                    if c == len(lay.names) and c > 0:
                        vals = np.ascontiguousarray(r[:, o : o + 8 * c]).view("<f8")
                        if identity and contiguous:
                            tgt[gi[0] : gi[-1] + 1] = vals
                        else:
                            tgt[np.ix_(gi, dst)] = vals[:, src]
                        flag[gi] = True
            for k in sel[~ok].tolist():
                o, ln = int(b.data_off[k]), int(b.data_len[k])
                i = int(idx_all[k])
                data = b.buf[o : o + ln].tobytes()
                try:
                    m = parse_jointstate(data)
                except (ValueError, struct.error) as err:
                    raise bad(i, err) from None
                _fill_one(out, i, m, m.values(data), jidx)
    return out


def _fill_one(out: TopicArrays, i: int, m: Layout, vals: list[np.ndarray],
              jidx: dict[str, int]) -> None:
    out.header[i] = m.stamp_ns
    seen = set()
    flags = (out.has_position, out.has_velocity, out.has_effort)
    for (_, c), v, tgt, flag in zip(
        m.arrays, vals, (out.position, out.velocity, out.effort), flags, strict=True
    ):
        if c == len(m.names) and c > 0:
            flag[i] = True
            for k, nm in enumerate(m.names):
                if nm in jidx:
                    tgt[i, jidx[nm]] = v[k]
    for nm in m.names:
        if nm in jidx:
            seen.add(nm)
            out.joint_seen[jidx[nm]] = True
            out.named[i, jidx[nm]] = True
        else:
            out.extra_names.add(nm)
    out.has_joints[i] = len(seen) == len(jidx)


def decode_topic_official(
    path: Path, topic: str, where: str, joints: tuple[str, ...] | None = None,
) -> TopicArrays:
    """The same as :func:`decode_topic` with the official ``mcap`` + ``mcap_ros2`` decoder.

    Used as the fallback for files the scanner does not handle and as the tests' oracle.
    A truncated file yields the messages before the cut (NonSeekingReader).
    """
    from mcap.reader import NonSeekingReader
    from mcap_ros2.decoder import DecoderFactory

    rows: list[tuple[int, int, Any]] = []
    try:
        with open(path, "rb") as f:
            reader = NonSeekingReader(f, decoder_factories=[DecoderFactory()])
            try:
                for _s, ch, msg, dec in reader.iter_decoded_messages(
                    topics=[topic], log_time_order=False
                ):
                    del ch
                    rows.append((msg.log_time, msg.publish_time, dec))
            except Exception:  # the cut of a truncated file: keep what came before
                if not rows:
                    raise
    except OSError as err:
        raise LogFormatError(f"{where}: cannot read: {err}") from err
    except Exception as err:
        first = (str(err).splitlines() or [type(err).__name__])[0]
        raise LogFormatError(f"{where}: corrupt MCAP: {first}") from err
    if not rows:
        raise LogFormatError(f"{where}: topic {topic!r} holds no messages")
    return arrays_from_messages(
        [m for _, _, m in rows], np.array([r[0] for r in rows], dtype=np.int64),
        np.array([r[1] for r in rows], dtype=np.int64), joints)


def arrays_from_messages(
    msgs: list[Any], log_time: np.ndarray, publish_time: np.ndarray,
    joints: tuple[str, ...] | None = None,
) -> TopicArrays:
    """:class:`TopicArrays` from decoded JointState messages (objects with ``header.stamp``,
    ``name``, ``position``, ``velocity``, ``effort``: mcap_ros2's or rosbags' classes, ROS 1
    or ROS 2), in the given order; joints are those of the first message unless given."""
    if joints is None:
        joints = tuple(str(s) for s in msgs[0].name)
    jidx = {nm: i for i, nm in enumerate(joints)}
    out = _empty(len(msgs), len(joints), joints)
    out.log_time[:] = log_time
    out.publish_time[:] = publish_time
    for i, m in enumerate(msgs):
        stamp = m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
        lay = Layout(stamp, tuple(m.name), ((0, len(m.position)), (0, len(m.velocity)),
                                            (0, len(m.effort))), True)
        vals = [np.asarray(m.position, float), np.asarray(m.velocity, float),
                np.asarray(m.effort, float)]
        _fill_one(out, i, lay, vals, jidx)
    return out
