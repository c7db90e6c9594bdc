"""The reader of message logs — MCAP and ROS bags — one implementation for both
(docs/formats.md, "MCAP", "Channel maps").

State topic: the map's position fields' topic when a ``format: messages`` channel map names
every joint's position; else ``topic``, the only JointState / JSON JointSample topic, or
``/joint_states``. A JointState state ``T`` has companions (``T_ref`` or ``reference_topic``:
the reference; ``T_model``, ``T_ext``: the controller's torques), joints matched by
``name[]`` on every message; a map's fields replace the signals they name. Time: the
state's header stamps when every one is non-zero, else log time (``time_source``
overrides); every other topic is stamped alike and held onto the state samples (its latest
message at or before each), the samples before its first message dropped (a repair).

One pass over the file's blocks (:meth:`MessageLayout.read`) decodes each block once,
counts every topic the log may use and spills its decoded columns
(:mod:`impactcli.logs.messages.message_merge`, which merges them into rows); what the log is made of
is decided from the counts (:mod:`impactcli.logs.messages.message_plan`), a log that does not fit
refused with the first error in that order.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ChannelMapError, ImpactError, LogFormatError
from ...sample_channels import CHANNEL_NAMES
from ...spill import SpillFolder
from ..channel_map import ChannelMap, ChannelRef
from ..channels import JointChannels
from ..layout import RawRows, StreamLayout
from .fields import FieldPath, check_ros_path, parse_field_path
from .message_merge import Part, TopicSpill, merged_rows
from .message_source import JOINT_SAMPLE, JOINT_STATE, MessageSource, TopicData
from .ros2_cdr import TopicArrays, arrays_from_messages, decode_batches, parse_jointstate

DEFAULT_STATE_TOPIC = "/joint_states"
#: companion topic suffix → (JointState array, signal)
COMPANIONS: tuple[tuple[str, str, str], ...] = (
    ("_model", "effort", "torque_model"),
    ("_ext", "effort", "torque_ext"),
)
_TIMES = ("log", "publish", "header")


def joint_kind(msgtype: str, encoding: str) -> str | None:
    """``ros2`` (CDR JointState), ``ros1`` (ROS 1 JointState), ``json`` (JointSample) or None."""
    if msgtype == JOINT_STATE and encoding == "cdr":
        return "ros2"
    if msgtype == JOINT_STATE and encoding == "ros1":
        return "ros1"
    if msgtype == JOINT_SAMPLE and encoding == "json":
        return "json"
    return None


def pick_state_topic(topics: dict[str, tuple[str, str]], topic: str | None,
                     where: str) -> tuple[str, str]:
    """The state topic and its kind (module docstring). Raises LogFormatError."""
    joint_topics = {t: k for t, (mt, enc) in topics.items() if (k := joint_kind(mt, enc))}
    listing = ", ".join(sorted(topics)) or "none"
    if topic is not None:
        if topic not in topics:
            raise LogFormatError(f"{where}: topic {topic!r} not found (topics: {listing})")
        if topic not in joint_topics:
            raise LogFormatError(
                f"{where}: topic {topic!r} is not JointState (CDR or ROS 1) nor impactcli "
                f"JointSample (JSON) (topics: {listing})"
            )
        return topic, joint_topics[topic]
    if len(joint_topics) == 1:
        t = next(iter(joint_topics))
        return t, joint_topics[t]
    if DEFAULT_STATE_TOPIC in joint_topics:
        return DEFAULT_STATE_TOPIC, joint_topics[DEFAULT_STATE_TOPIC]
    if not joint_topics:
        raise LogFormatError(
            f"{where}: no JointState topic (topics: {listing}); a channel map "
            "(format: messages) can name the fields of other messages"
        )
    raise LogFormatError(
        f"{where}: cannot choose the joint-state topic; pass --topic (topics: "
        f"{', '.join(sorted(joint_topics))})"
    )


def choose_time_source(time_source: str | None, has_header: bool, zero_at: int | None,
                       where: str, topic: str) -> str:
    """The state topic's time source (module docstring): ``time_source``, else ``header``
    when every stamp is non-zero, else ``log``.

    Args:
        has_header: the messages have header stamps.  zero_at: the first message whose
            stamp is zero (None: none is).
    Raises:
        LogFormatError: ``header`` asked for messages without stamps, or with a zero stamp.
    """
    if time_source is None:
        return "header" if has_header and zero_at is None else "log"
    if time_source == "header":
        if not has_header:
            raise LogFormatError(f"{where}: topic {topic!r} has no header stamp; use "
                                 "--time-source log or publish")
        if zero_at is not None:
            raise LogFormatError(
                f"{where}: topic {topic!r}, message {zero_at}: header stamp is zero; use "
                "--time-source log or publish"
            )
        return "header"
    return "publish" if time_source == "publish" else "log"


def json_topic_arrays(src: MessageSource, td: TopicData,
                      joints: tuple[str, ...] | None = None) -> TopicArrays:
    """Decode impactcli JSON joint samples into TopicArrays (joints matched by name: those
    of the first message unless given), every signal in ``json_extra``."""
    where, topic = src.where, td.topic
    if td.n == 0:
        raise LogFormatError(f"{where}: topic {topic!r} holds no messages")
    msgs = []
    for k in range(td.n):
        try:
            m = json.loads(td.data(k))
            if not isinstance(m, dict) or not isinstance(m.get("name"), list):
                raise ValueError("no 'name' list")
        except ValueError as err:
            raise LogFormatError(
                f"{where}: topic {topic!r}, message {k + td.first}: bad JSON sample: {err}"
            ) from None
        msgs.append(m)
    if joints is None:
        joints = tuple(str(s) for s in msgs[0]["name"])
    jidx = {nm: i for i, nm in enumerate(joints)}
    n, jn = len(msgs), len(joints)
    vals = {s: np.full((n, jn), np.nan) for s in CHANNEL_NAMES}
    has = {s: np.zeros(n, dtype=bool) for s in CHANNEL_NAMES}
    named = np.zeros((n, jn), dtype=bool)
    header = np.zeros(n, dtype=np.int64)
    extra: set[str] = set()
    for i, m in enumerate(msgs):
        names = m["name"]
        cols = [jidx.get(nm, -1) for nm in names]
        extra.update(nm for nm in names if nm not in jidx)
        named[i, [c for c in cols if c >= 0]] = True
        header[i] = int(m.get("stamp_ns", 0) or 0)
        for s in CHANNEL_NAMES:
            v = m.get(s)
            if isinstance(v, list) and len(v) == len(names) and v:
                has[s][i] = True
                for c, x in zip(cols, v, strict=True):
                    if c >= 0:
                        vals[s][i, c] = np.nan if x is None else float(x)
    out = TopicArrays(
        joints, td.log_time.copy(), td.publish_time.copy(), header,
        vals["position"], vals["velocity"], vals["torque"], np.all(named, axis=1),
        has["position"], has["velocity"], has["torque"], extra, np.any(named, axis=0),
        named,
    )
    out.json_extra = (vals, has)  # type: ignore[attr-defined]
    return out


def joint_signals(arr: TopicArrays) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Signal → (n, J) values of a joint topic's decoded messages, and signal → (n,) whether
    each message fills it (JointState: position, velocity, effort as torque; JSON samples:
    every signal they carry)."""
    extra = getattr(arr, "json_extra", None)
    if extra is not None:
        return extra  # type: ignore[no-any-return]
    return ({"position": arr.position, "velocity": arr.velocity, "torque": arr.effort},
            {"position": arr.has_position, "velocity": arr.has_velocity,
             "torque": arr.has_effort})


@dataclass
class MapField:
    """A per-joint signal the channel map names by field path."""

    signal: str
    joint: int
    ref: ChannelRef
    path: FieldPath


def map_fields(src: MessageSource, cmap: ChannelMap,
               topics: dict[str, tuple[str, str]]) -> list[MapField]:
    """The map's field paths, checked against the topics' message definitions."""
    where = src.where
    mapname = cmap.path or cmap.name
    names = list(topics)
    out = []
    for sig, j, ref in cmap.refs():
        what = f"{where}: channel map {mapname}: {cmap.joints[j]}.{sig}"
        if not ref.is_field:
            raise ChannelMapError(f"{what}: {ref.label()} is not a field path "
                                  "(/topic/field); MCAP and ROS bag maps name message fields")
        fp = parse_field_path(str(ref.source), names, ref.joint or cmap.joints[j], what)
        mtype, enc = topics[fp.topic]
        if enc in ("cdr", "ros1") and not mtype:
            raise LogFormatError(f"{what}: topic {fp.topic!r} has no message definition in the "
                                 "file: its fields cannot be read")
        if enc in ("cdr", "ros1"):
            fp = check_ros_path(fp, mtype, src.fielddefs(mtype), what)
        elif enc != "json":
            raise ChannelMapError(f"{what}: topic {fp.topic!r} has message encoding {enc!r}, "
                                  "which cannot be decoded (cdr, ros1 or json)")
        out.append(MapField(sig, j, ref, fp))
    return out


def field_columns(src: MessageSource, td: TopicData, fields: list[MapField],
                  prefix: str) -> tuple[list[np.ndarray], np.ndarray | None]:
    """The map's field columns on ``td``'s topic (scaled; currents raw: their scale converts
    them to torque) and its header stamps; ``prefix`` starts the errors."""
    from .field_read import read_fields

    vals, header = read_fields(src, td, [f.path for f in fields], prefix)
    out = []
    for c, f in enumerate(fields):
        v = vals[:, c]
        if f.signal != "current":
            if f.ref.scale is not None:
                v = v * f.ref.scale
            if f.ref.offset:
                v = v + f.ref.offset
        out.append(v)
    return out, header


def stack_columns(mat: np.ndarray, cols: list[tuple[str, int]], joints: tuple[str, ...]
                  ) -> tuple[dict[str, np.ndarray], dict[str, list[str]]]:
    """Repaired columns ``mat`` (n, C), column c being ``cols[c]`` = (signal, joint index),
    as signals (n, J) (NaN for the joints without the signal), and signal → the joints
    without it (only the signals some joint lacks)."""
    jn = len(joints)
    signals: dict[str, np.ndarray] = {}
    have: dict[str, set[int]] = {}
    at: dict[str, list[tuple[int, int]]] = {}
    for c, (s, j) in enumerate(cols):
        at.setdefault(s, []).append((c, j))
    for s, cj in at.items():
        c0 = cj[0][0]
        if [(c - c0, j) for c, j in cj] == [(k, k) for k in range(jn)]:
            signals[s] = mat[:, c0:c0 + jn]  # every joint's column, in order: a view
        else:
            signals[s] = np.full((mat.shape[0], jn), np.nan)
            for c, j in cj:
                signals[s][:, j] = mat[:, c]
        have[s] = {j for _, j in cj}
    lacking = {s: [joints[j] for j in range(jn) if j not in have[s]] for s in signals}
    return signals, {s: lack for s, lack in lacking.items() if lack}


# ------------------------------------------------------------------- one pass: a topic
class TopicReader:
    """One topic through the pass over the blocks: its messages decoded (joints matched by
    name into every name seen, in order of appearance) or its map fields read, spilled,
    and counted (module docstring). The first error decoding it is kept, not raised:
    the log may not use the topic, and the log's errors have an order."""

    def __init__(self, topic: str, mtype: str, enc: str, kind: str, fields: list[MapField],
                 spill: TopicSpill) -> None:
        self.topic, self.mtype, self.enc, self.kind = topic, mtype, enc, kind
        self.fields = fields
        self.spill = spill
        self.names: list[str] = []  # every joint name seen (the first message's first)
        self.first_names: tuple[str, ...] | None = None
        self.first_error: ImpactError | None = None  # the first message does not parse
        self.error: ImpactError | None = None  # decoding its joint messages
        self.field_error: ImpactError | None = None  # reading the map's fields
        self.n = 0
        self.lo: dict[str, int] = {}  # time source → smallest stamp
        self.hi: dict[str, int] = {}
        self.ordered = dict.fromkeys(_TIMES, True)
        self.last: dict[str, int] = {}
        self.header_blocks = 0  # blocks whose messages have a header stamp
        self.blocks = 0
        self.first_zero: int | None = None  # first message whose header stamp is zero

    @property
    def has_header(self) -> bool:
        """Whether every message has a header stamp."""
        return self.blocks > 0 and self.header_blocks == self.blocks

    def add(self, src: MessageSource, batches: list[Any], prefix: str) -> None:
        """The topic's messages in one block."""
        td = TopicData(self.topic, self.mtype, self.enc, batches, first=self.n)
        cols: dict[str, np.ndarray] = {}
        header: np.ndarray | None = None
        if self.kind and self.error is None:
            try:
                header = self._joints(src, td, cols)
            except ImpactError as err:
                self.error = err
        if self.fields and self.field_error is None:
            try:
                fcols, fheader = field_columns(src, td, self.fields, prefix)
                cols.update({f"field:{k}": v for k, v in enumerate(fcols)})
                header = header if self.kind else fheader
            except ImpactError as err:
                self.field_error = err
        cols["log"], cols["publish"] = td.log_time, td.publish_time
        self.blocks += 1
        if header is not None:
            cols["header"] = header
            self.header_blocks += 1
            zero = np.flatnonzero(header == 0)
            if zero.size and self.first_zero is None:
                self.first_zero = self.n + int(zero[0])
        for s in _TIMES:
            t = cols.get(s)
            if t is None or not t.size:
                continue
            self.lo[s] = min(self.lo.get(s, int(t.min())), int(t.min()))
            self.hi[s] = max(self.hi.get(s, int(t.max())), int(t.max()))
            prev = self.last.get(s)
            if (prev is not None and t[0] < prev) or bool(np.any(np.diff(t) < 0)):
                self.ordered[s] = False
            self.last[s] = int(t[-1])
        self.spill.append(td.n, cols)
        self.n += td.n

    def _joints(self, src: MessageSource, td: TopicData, cols: dict[str, np.ndarray]
                ) -> np.ndarray:
        """Decode a block of joint messages into ``cols`` (values per joint name, the names
        each message gives, the arrays it fills); its header stamps."""
        if self.first_names is None:
            self.first_names, self.first_error = _first_names(src, td, self.kind)
            self.names = list(self.first_names)
        arr = self._decode(src, td)
        if arr.extra_names:  # names not seen before: decoded again with them
            self.names += sorted(arr.extra_names)
            arr = self._decode(src, td)
        vals, has = joint_signals(arr)
        for sig, v in vals.items():
            if has[sig].any():
                cols.update({f"{sig}:{nm}": v[:, k] for k, nm in enumerate(arr.joints)})
        cols.update({f"has:{sig}": h for sig, h in has.items()})
        cols.update({f"named:{nm}": arr.named[:, k] for k, nm in enumerate(arr.joints)})
        return arr.header

    def _decode(self, src: MessageSource, td: TopicData) -> TopicArrays:
        joints = tuple(self.names)
        if self.kind == "ros2":
            return decode_batches(td.batches, src.where, td.topic, joints, td.first)
        if self.kind == "ros1":
            msgs = src.decode_all(td)
            return arrays_from_messages(msgs, td.log_time, td.publish_time, joints)
        return json_topic_arrays(src, td, joints)


def _first_names(src: MessageSource, td: TopicData, kind: str
                 ) -> tuple[tuple[str, ...], ImpactError | None]:
    """The joint names of a topic's first message, and the error of a first message that
    does not parse (no names then)."""
    import struct

    try:
        if kind == "ros2":
            first = min(td.batches, key=lambda b: int(b.order[0]))
            o, ln = int(first.data_off[0]), int(first.data_len[0])
            try:
                return parse_jointstate(first.buf[o: o + ln].tobytes()).names, None
            except (ValueError, struct.error) as err:
                return (), LogFormatError(f"{src.where}: topic {td.topic!r}, message 0: not "
                                          f"a JointState: {err}")
        if kind == "ros1":
            return tuple(str(s) for s in src.decode_all(td, np.array([0]))[0].name), None
        m = json.loads(td.data(0))
        return (tuple(str(s) for s in m["name"]) if isinstance(m, dict) and isinstance(
            m.get("name"), list) else ()), None
    except (ValueError, ImpactError, KeyError, TypeError, AttributeError):
        return (), None


# ------------------------------------------------------------------------- the layout
class MessageLayout(StreamLayout):
    """A message log (module docstring): its blocks read once at construction
    (:meth:`read`), its rows merged from the spills (:meth:`raw_batches`; the passes after
    the scan read the scan's cache of the rows, the spills are deleted then:
    :meth:`release`)."""


    def __init__(self, p: Path, where: str, blocks: Any, src: MessageSource, kind: str,
                 options: dict[str, Any]) -> None:
        self.path, self.where, self.blocks, self.src = p, where, blocks, src
        self.source_kind = kind  # mcap, rosbag2, rosbag1
        self.options = options
        self.repair_order = bool(options.get("repair_order", False))
        self.folder = SpillFolder(required=False)
        self.readers: dict[str, TopicReader] = {}
        self.parts: list[Part] = []
        self.perm: np.ndarray | None = None
        self.lead = 0
        self.lead_counts: list[int] = []
        self.truncated: list[str] = []
        self.state = ""
        self.ignored: list[str] = []
        self.current_scale: np.ndarray | None = None
        self.mapname = ""
        self.prefix = ""  # starts the errors reading map fields

    def close(self) -> None:
        for r in self.readers.values():
            r.spill.close()
        self.folder.close()

    def rate_error(self, sample_rate_hz: float, duration_s: float | None = None) -> str | None:
        """A rate below :data:`~impactcli.logs.repair.MIN_RATE_HZ` is too low for impact
        detection (stamps in ns leave no unit to doubt; no upper bound)."""
        from ..repair import MIN_RATE_HZ, rate_message

        if not sample_rate_hz < MIN_RATE_HZ:
            return None
        return rate_message(sample_rate_hz, self.where, f"topic {self.state!r} ({self.time_name})",
                            None, duration_s)

    def release(self) -> None:
        """The scan keeps the rows: the spills are no longer needed."""
        self.close()

    def label(self, i: int) -> str:
        row = i + self.lead if self.perm is None else int(self.perm[i + self.lead])
        return f"message {row} of {self.state!r}"

    def channels(self, t: np.ndarray, mat: np.ndarray) -> JointChannels:
        """The merged columns stacked by signal (a joint without one holds NaN)."""
        cols = [c for part in self.parts for c in part.cols]
        signals, missing = stack_columns(mat, cols, self.joints)
        return JointChannels(t_ns=t, joints=self.joints, signals=signals, missing=missing,
                             current_scale=self.current_scale, ignored=list(self.ignored))

    def cut_short(self) -> bool:
        return bool(self.truncated)

    def pre_repairs(self) -> list[str]:
        out = list(self.truncated)
        lead = max(self.lead_counts, default=0)
        if lead:
            h = self.parts[1 + self.lead_counts.index(lead)]
            what = "reference " if h.role == "reference topic" else ""
            out.append(f"{self.where}: dropped the first {lead} state sample(s), recorded "
                       f"before the first {what}message on {h.topic!r}")
        return out

    def raw_batches(self) -> Iterator[RawRows]:
        self.lead_counts = [0] * (len(self.parts) - 1)
        row0 = 0
        first = True
        for t, mat in merged_rows(self.parts, self.perm, self.lead_counts):
            if first:
                self.lead = max(self.lead_counts, default=0)
                first = False
            yield RawRows(row0, t, mat)
            row0 += t.shape[0]

    # -- the pass over the blocks
    def read(self, topics: list[str], decode: set[str],
             fields: dict[str, list[MapField]]) -> None:
        """One pass over the file's blocks: the topics ``topics`` read and spilled (their
        joint messages decoded for those in ``decode``, their map fields read); an MCAP
        compression the walker does not know is read through the official reader."""
        from .mcap import OfficialBlocks, UnsupportedMcap

        mtypes = self.src.topics()
        for attempt in range(2):
            self.readers = {}
            for t in topics:
                mtype, enc = mtypes[t]
                kind = (joint_kind(mtype, enc) or "") if t in decode else ""
                spill = TopicSpill(self.folder, f"a{attempt}t{len(self.readers)}")
                self.readers[t] = TopicReader(t, mtype, enc, kind, fields.get(t, []), spill)
            try:
                for block in self.blocks.blocks(topics):
                    for topic, batches in block.items():
                        r = self.readers.get(topic)
                        if r is not None:
                            r.add(self.src, batches, self.prefix)
                break
            except UnsupportedMcap:
                for r in self.readers.values():
                    r.spill.close()
                self.blocks = OfficialBlocks(self.path, self.where)
        for r in self.readers.values():
            r.spill.finish()
