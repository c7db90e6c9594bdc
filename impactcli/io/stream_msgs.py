"""MCAP logs and ROS bags streamed (:mod:`impactcli.io.stream`): the path of
:mod:`impactcli.io.messages` — JointState or JSON JointSample state topics with their
companions, and any message type through a ``format: messages`` channel map — block by
block.

Two passes over the file, a block (an MCAP chunk, :mod:`impactcli.io.stream_blocks`) at a
time:

1. :func:`message_layout` — every joint topic's messages are decoded block by block, the
   map's fields read, and only counted (:class:`_TopicStats`: messages, joint names, which
   arrays every message fills, whether every header stamp is non-zero, whether each time
   source is in order); from those counts :mod:`impactcli.io.stream_msgs_plan` takes the
   whole-file reader's decisions: the state topic, its joints and signals, the companion
   (``_ref``/``_model``/``_ext``) and map topics and their columns, the ignored channels,
   the time source (header when every state stamp is non-zero, else log time) and each
   held topic's stamps. With a channel map the MCAP's topics are first read from its
   summary section (or, without one, by a pass that keeps only them): the map is checked
   against them, as the whole reader does.
2. :meth:`MessageLayout.raw_batches` — the state topic and the held topics decoded again,
   block by block, and merged by causal sample-and-hold (:class:`_Merge`): a state
   sample is given out once every held topic has either ended or shown a message stamped
   after it (a look-ahead of at most :data:`MAX_LOOKAHEAD` messages when stamps and file
   order disagree); the state samples before a held topic's first message are dropped
   (the warned repair). The rows then go through the scan's repairs, cache and
   statistics as a CSV's do.

Not streamed (``_NotStreamable``: the whole-file reader reads the log): state stamps out
of order in the file (the whole reader sorts them) or a held topic's; companion topics
whose messages name different joints, or a state topic whose messages lack some of its
first message's joints; JSON samples whose joints change between chunks; ROS 1 JointState
inside MCAP; a look-ahead beyond
:data:`MAX_LOOKAHEAD`; and anything the whole-file reader refuses (then it raises its own
error): a bad file, a topic it cannot choose or decode, a zero stamp with
``--time-source header``, messages lacking joints or arrays, a map that does not fit.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImpactError
from ._whole import NotStreamable as _NotStreamable
from .assemble import JointChannels
from .messages import joint_signals
from .stream_blocks import BagBlocks, McapBlocks
from .stream_layout import RawRows as _Raw
from .stream_layout import StreamLayout

#: Messages of one topic held back at most while the others catch up in the file (the
#: state's while a held topic's later messages are awaited, or a held topic's).
MAX_LOOKAHEAD = 200_000
_TIMES = ("log", "publish", "header")


@dataclass
class _TopicStats:
    """What the first pass counts of one topic (module docstring): its messages' times
    and, for a joint topic, its joint names and the arrays its messages fill."""

    kind: str
    n: int = 0
    has_header: bool | None = None  # its messages carry a header stamp
    header_nonzero: bool = True
    first: dict[str, int] = field(default_factory=dict)  # time source → first stamp
    last: dict[str, int] = field(default_factory=dict)
    ordered: dict[str, bool] = field(default_factory=lambda: dict.fromkeys(_TIMES, True))
    joints: tuple[str, ...] | None = None
    all_joints: bool = True  # every message names every joint of ``joints``
    extra: set[str] = field(default_factory=set)
    has_all: dict[str, bool] = field(default_factory=dict)
    has_any: dict[str, bool] = field(default_factory=dict)

    def add_times(self, log: np.ndarray, publish: np.ndarray, header: np.ndarray | None
                  ) -> None:
        """Count one block's messages by their times [ns] (``header`` None: no stamps)."""
        if self.has_header is not None and self.has_header != (header is not None):
            raise _NotStreamable("header stamps in some blocks only")
        self.has_header = header is not None
        self.n += log.shape[0]
        times = (log, publish, header if header is not None else np.zeros_like(log))
        self.header_nonzero &= bool(np.all(times[2] != 0))
        for src, t in zip(_TIMES, times, strict=True):
            self.first.setdefault(src, int(t[0]))
            prev = self.last.get(src)
            if (prev is not None and t[0] < prev) or np.any(np.diff(t) < 0):
                self.ordered[src] = False
            self.last[src] = int(t[-1])

    def add(self, arr: Any) -> None:
        """Count one block's decoded joint messages
        (:class:`~impactcli.io.mcap_ros2.TopicArrays`)."""
        if self.joints is None:
            self.joints = arr.joints
        elif arr.joints != self.joints:
            raise _NotStreamable("joint names differ between blocks")
        self.all_joints &= bool(arr.has_joints.all())
        self.extra |= arr.extra_names
        for s, h in joint_signals(arr)[1].items():
            self.has_all[s] = self.has_all.get(s, True) and bool(h.all())
            self.has_any[s] = self.has_any.get(s, False) or bool(h.any())
        self.add_times(arr.log_time, arr.publish_time, arr.header)


@dataclass
class _Part:
    """A topic the rows come from: the state topic (the first part), a companion, or a
    topic of channel-map fields. Its columns: ``cols`` — ``(signal, joint, key, column)``:
    the log's ``signal`` of ``joint`` is column ``column`` of the decoded joint messages'
    :func:`~impactcli.io.messages.joint_signals` ``key`` —, then ``fields``
    (:class:`~impactcli.io.messages._MapField`, scaled as the whole reader does)."""

    topic: str
    role: str
    kind: str  # ros2, ros1, json: joint messages decoded; "": fields only
    tsrc: str  # its time source
    total: int  # its messages
    joints: tuple[str, ...] | None = None  # the joints its messages are decoded for
    # (signal, joint of the log, key, the decoded array's column)
    cols: list[tuple[str, int, str, int]] = field(default_factory=list)
    fields: list[Any] = field(default_factory=list)

    @property
    def signals(self) -> list[tuple[str, int]]:
        """``(signal, joint)`` of its columns, in order."""
        return [(c[0], c[1]) for c in self.cols] + [(f.signal, f.joint) for f in self.fields]


class MessageLayout(StreamLayout):
    """An MCAP log or ROS bag streamed (module docstring)."""

    def __init__(self, p: Path, where: str, reader: Any, src: Any, options: dict[str, Any]
                 ) -> None:
        self.path, self.where, self.reader, self.src = p, where, reader, src
        self.repair_order = bool(options.get("repair_order", False))
        self.lead = 0
        self.lead_counts: list[int] = []
        self.truncated: list[str] = []
        self.state = ""
        self.parts: list[_Part] = []  # the state topic first, then the held topics
        self.ignored: list[str] = []
        self.current_scale: np.ndarray | None = None
        self.mapname = ""

    @property
    def held(self) -> list[_Part]:
        """The topics held onto the state samples."""
        return self.parts[1:]

    def label(self, i: int) -> str:
        return f"message {i + self.lead} of {self.state!r}"

    def channels(self, t: np.ndarray, mat: np.ndarray) -> JointChannels:
        """As :func:`impactcli.io.messages._assemble` stacks the repaired columns."""
        from .messages import stack_columns

        cols = [sig for part in self.parts for sig in part.signals]
        signals, missing = stack_columns(mat, cols, self.joints)
        return JointChannels(t_ns=t, joints=self.joints, signals=signals, missing=missing,
                             current_scale=self.current_scale, ignored=list(self.ignored))

    def pre_repairs(self) -> list[str]:
        out = list(self.truncated)
        lead = max(self.lead_counts, default=0)
        if lead:
            h = self.held[self.lead_counts.index(lead)]
            what = "reference " if h.role == "reference topic" else ""
            out.append(f"{self.where}: dropped the first {lead} state sample(s), recorded "
                       f"before the first {what}message on {h.topic!r}")
        return out

    # -- the second pass
    def raw_batches(self) -> Iterator[_Raw]:
        self.lead, self.lead_counts = 0, [0] * len(self.held)
        merge = _Merge(self)
        try:
            for block in self.reader.blocks([part.topic for part in self.parts]):
                for k, part in enumerate(self.parts):
                    if part.topic in block:
                        merge.add(k, *self._read(part, block[part.topic]))
                out = merge.ready(final=False)
                if out is not None:
                    yield out
        except ImpactError as err:  # the whole-file reader says what is wrong
            raise _NotStreamable(str(err)) from err
        out = merge.ready(final=True)
        if out is not None:
            yield out

    def _read(self, part: _Part, batches: list[Any]) -> tuple[np.ndarray, np.ndarray]:
        """A block's messages of one part: their times on its time source, its columns."""
        from .messages import _field_columns
        from .msgsource import TopicData

        mtype, enc = self.src.topics()[part.topic]
        td = TopicData(part.topic, mtype, enc, batches)
        cols: list[np.ndarray] = []
        header = None
        if part.kind:
            arr = _decode(self.src, td, part.kind, part.joints)
            vals = joint_signals(arr)[0]
            cols += [vals[key][:, c] for _, _, key, c in part.cols]
            header = arr.header
        if part.fields:
            fcols, fheader = _field_columns(self.src, td, part.fields, self.mapname)
            cols += [v for _, _, v in fcols]
            header = header if part.kind else fheader
        t = {"log": td.log_time, "publish": td.publish_time, "header": header}[part.tsrc]
        assert t is not None
        return t, np.column_stack(cols).astype(np.float64, copy=False)


class _Merge:
    """Causal sample-and-hold of the held topics onto the state samples, over blocks:
    part 0 is the state, parts 1… are held."""

    def __init__(self, lay: MessageLayout) -> None:
        self.lay = lay
        self.t = [np.zeros(0, dtype=np.int64) for _ in lay.parts]
        self.m = [np.zeros((0, len(part.signals))) for part in lay.parts]
        self.got = [0] * len(lay.parts)
        self.rows = 0

    def add(self, k: int, t: np.ndarray, m: np.ndarray) -> None:
        """Part ``k``'s next messages: times (n,) [ns], columns (n, C_k)."""
        self.t[k] = np.concatenate((self.t[k], t))
        self.m[k] = np.concatenate((self.m[k], m))
        self.got[k] += t.size
        if self.t[k].size > MAX_LOOKAHEAD:
            raise _NotStreamable("topics too far apart in the file")

    def ready(self, final: bool) -> _Raw | None:
        """The state samples every held topic's latest message is known for, as rows."""
        lay = self.lay
        limit = None
        if not final:
            for k, part in enumerate(lay.parts[1:], start=1):
                if self.got[k] < part.total:
                    if not self.t[k].size:
                        return None
                    last = int(self.t[k][-1])
                    limit = last if limit is None else min(limit, last)
        st = self.t[0]
        n = st.size if limit is None else int(np.searchsorted(st, limit, "left"))
        if n == 0:
            return None
        t, parts = st[:n], [self.m[0][:n]]
        drop = np.zeros(n, dtype=bool)
        for k in range(1, len(lay.parts)):
            idx = np.searchsorted(self.t[k], t, side="right") - 1
            before = idx < 0
            lay.lead_counts[k - 1] += int(before.sum())
            drop |= before
            parts.append(self.m[k][np.maximum(idx, 0)])
            keep_from = max(int(idx[-1]), 0)
            self.t[k], self.m[k] = self.t[k][keep_from:], self.m[k][keep_from:]
        self.t[0], self.m[0] = st[n:], self.m[0][n:]
        lay.lead = max(lay.lead_counts, default=0)
        if drop.all():
            return None
        mat = np.concatenate(parts, axis=1) if len(parts) > 1 else parts[0]
        if drop.any():
            t, mat = t[~drop], mat[~drop]
        raw = _Raw(self.rows, t, np.ascontiguousarray(mat, dtype=np.float64))
        self.rows += t.size
        return raw


# ------------------------------------------------------------------------ the first pass
def message_layout(p: Path, where: str, suffix: str, cmap: Any,
                   options: dict[str, Any]) -> MessageLayout:
    """The layout of an MCAP log or ROS bag (module docstring: the first pass).

    Raises:
        _NotStreamable: the log needs the whole-file reader.
    """
    from .messages import _field_columns, _map_fields, joint_kind
    from .msgsource import McapSource, TopicData
    from .stream_msgs_plan import decide

    src: Any = None
    try:
        if suffix == ".mcap":
            reader: Any = McapBlocks(p, where)
            if cmap is not None:  # the map's fields are checked against every topic first
                src = McapSource(_channels(reader), where)
        else:
            from .bags import BagSource

            src = BagSource(p, where)
            reader = BagBlocks(src)
        fields = _map_fields(src, cmap, src.topics()) if cmap is not None else []
    except ImpactError as err:  # the whole-file reader says what is wrong
        raise _NotStreamable(str(err)) from err
    mapname = "" if cmap is None else (cmap.path or cmap.name)
    by_topic: dict[str, list[Any]] = {}
    for f in fields:
        by_topic.setdefault(f.path.topic, []).append(f)
    stats: dict[str, _TopicStats] = {}  # joint topics
    fstats: dict[str, _TopicStats] = {}  # topics of map fields
    try:
        for block in reader.blocks():
            for topic, batches in block.items():
                if src is None or topic not in src.topics():
                    src = McapSource(reader.scan, where)  # the channels known so far
                mtype, enc = src.topics()[topic]
                td = TopicData(topic, mtype, enc, batches)
                st = stats.setdefault(topic, _TopicStats(joint_kind(mtype, enc) or ""))
                if st.kind in ("ros2", "json") or (st.kind == "ros1" and suffix != ".mcap"):
                    st.add(_decode(src, td, st.kind, st.joints))
                if topic in by_topic:
                    _, header = _field_columns(src, td, by_topic[topic], mapname)
                    fstats.setdefault(topic, _TopicStats("")).add_times(
                        td.log_time, td.publish_time, header)
    except ImpactError as err:
        raise _NotStreamable(str(err)) from err
    if suffix == ".mcap":
        if reader.scan.n_messages == 0:
            raise _NotStreamable("no messages")
        if cmap is None:
            src = McapSource(reader.scan, where)
    lay = MessageLayout(p, where, reader, src, options)
    lay.mapname = mapname
    if suffix == ".mcap" and reader.scan.truncated:
        lay.truncated = [f"{where}: MCAP file is truncated (records end early); read "
                         f"the {reader.scan.n_messages} complete message(s) before the cut"]
    decide(lay, stats, fstats, fields, cmap, options)
    return lay


def _channels(reader: McapBlocks) -> Any:
    """The MCAP's schemas and channels: its summary section, else (a truncated file) a
    pass over its records that keeps nothing else."""
    try:
        return reader.summary()
    except _NotStreamable:
        for _ in reader.blocks(()):
            pass
        return reader.scan


def _decode(src: Any, td: Any, kind: str, joints: tuple[str, ...] | None) -> Any:
    """A block's messages of one joint topic decoded (``joints``: None for its first
    message's, as :func:`impactcli.io.messages._joint_arrays` reads a whole topic)."""
    from .messages import _joint_arrays

    arr = _joint_arrays(src, td, kind, None if kind == "json" else joints)
    if kind == "json" and joints is not None and arr.joints != joints:
        raise _NotStreamable("JSON joint names differ between chunks")
    return arr
