"""MCAP logs and ROS bags streamed (:mod:`impactcli.io.stream`): the JointState / JSON
JointSample path of :mod:`impactcli.io.messages`, block by block.

Two passes over the file, a block (an MCAP chunk, :mod:`impactcli.io.stream_blocks`) at a
time:

1. :func:`message_layout` — every joint topic's messages are decoded block by block and
   only counted (:class:`_TopicStats`: messages, joint names, which arrays every message
   fills, whether every header stamp is non-zero, whether each time source is in order);
   from those, the whole-file reader's decisions: the state topic, its signals, the
   companion topics ``_ref``/``_model``/``_ext`` and their columns, the ignored channels,
   the time source (header when every state stamp is non-zero, else log time) and each
   companion's stamps.
2. :meth:`MessageLayout.raw_batches` — the state topic and its companions decoded again,
   block by block, and merged by causal sample-and-hold: a state sample is given out once
   every companion has either ended or shown a message stamped after it (a bounded
   look-ahead, :data:`MAX_LOOKAHEAD` samples, when stamps and file order disagree); the
   state samples before a companion's first message are dropped (the warned repair).
   The rows then go through the scan's repairs, cache and statistics like a CSV's.

Not streamed (``_NotStreamable``: the whole-file reader reads the log): a channel map;
state stamps out of order in the file (the whole reader sorts them) or a companion's;
joint names that change between a topic's messages (beyond extra names on the state
topic) or between the JSON samples of two chunks; ROS 1 JointState inside MCAP; a look-ahead
beyond :data:`MAX_LOOKAHEAD`; and anything the whole-file reader refuses (then it raises
its own error): a bad file, a topic it cannot choose or decode, a zero stamp with
``--time-source header``, messages lacking joints or arrays.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImpactError
from .assemble import JointChannels
from .messages import joint_signals
from .stream_blocks import BagBlocks, McapBlocks
from .stream_layout import StreamLayout, _Raw, plan_of
from .stream_repair import _NotStreamable

#: State samples held back at most while waiting for a companion's later messages.
MAX_LOOKAHEAD = 200_000
_TIMES = ("log", "publish", "header")


@dataclass
class _TopicStats:
    """What the first pass counts of one joint topic (module docstring)."""

    kind: str
    n: int = 0
    joints: tuple[str, ...] | None = None
    all_joints: bool = True  # every message names every joint of ``joints``
    extra: set[str] = field(default_factory=set)
    seen: np.ndarray | None = None
    has_all: dict[str, bool] = field(default_factory=dict)
    has_any: dict[str, bool] = field(default_factory=dict)
    header_nonzero: bool = True
    first: dict[str, int] = field(default_factory=dict)  # time source → first stamp
    last: dict[str, int] = field(default_factory=dict)
    ordered: dict[str, bool] = field(default_factory=lambda: dict.fromkeys(_TIMES, True))

    def add(self, arr: Any) -> None:
        """Count one block's decoded messages (:class:`~impactcli.io.mcap_ros2.TopicArrays`)."""
        if self.joints is None:
            self.joints = arr.joints
            self.seen = np.zeros(len(arr.joints), dtype=bool)
        elif arr.joints != self.joints:
            raise _NotStreamable("joint names differ between blocks")
        assert self.seen is not None
        self.n += arr.log_time.shape[0]
        self.all_joints &= bool(arr.has_joints.all())
        self.extra |= arr.extra_names
        self.seen |= arr.joint_seen
        for s, h in joint_signals(arr)[1].items():
            self.has_all[s] = self.has_all.get(s, True) and bool(h.all())
            self.has_any[s] = self.has_any.get(s, False) or bool(h.any())
        self.header_nonzero &= bool(np.all(arr.header != 0))
        for src, t in zip(_TIMES, (arr.log_time, arr.publish_time, arr.header), strict=True):
            self.first.setdefault(src, int(t[0]))
            prev = self.last.get(src)
            if (prev is not None and t[0] < prev) or np.any(np.diff(t) < 0):
                self.ordered[src] = False
            self.last[src] = int(t[-1])


@dataclass
class _Companion:
    """A companion topic: its columns ``(signal, joint, array name)`` and time source."""

    topic: str
    role: str
    kind: str
    tsrc: str
    cols: list[tuple[str, int, str]]
    total: int  # its messages


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
        self.kind = ""
        self.state_cols: list[tuple[str, int]] = []
        self.held: list[_Companion] = []
        self.ignored: list[str] = []

    def label(self, i: int) -> str:
        return f"message {i + self.lead} of {self.state!r}"

    def channels(self, t: np.ndarray, mat: np.ndarray) -> JointChannels:
        """As :func:`impactcli.io.messages._assemble` stacks the repaired columns."""
        from .messages import stack_columns

        cols = self.state_cols + [(s, j) for h in self.held for s, j, _ in h.cols]
        signals, missing = stack_columns(mat, cols, self.joints)
        return JointChannels(t_ns=t, joints=self.joints, signals=signals, missing=missing,
                             current_scale=np.full(len(self.joints), np.nan),
                             ignored=list(self.ignored))

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
        want = [self.state, *(h.topic for h in self.held)]
        try:
            for block in self.reader.blocks(want):
                if self.state in block:
                    arr = _decode(self.src, self.state, self.kind, block[self.state], self.joints)
                    vals = joint_signals(arr)[0]
                    merge.add_state(_time(arr, self.time_source),
                                    _stack([vals[s][:, j] for s, j in self.state_cols]))
                for k, h in enumerate(self.held):
                    if h.topic in block:
                        arr = _decode(self.src, h.topic, h.kind, block[h.topic], self.joints)
                        merge.add_held(k, _time(arr, h.tsrc), _stack(
                            [getattr(arr, a)[:, j] for _, j, a in h.cols]))
                out = merge.ready(final=False)
                if out is not None:
                    yield out
        except ImpactError as err:  # the whole-file reader says what is wrong
            raise _NotStreamable(str(err)) from err
        out = merge.ready(final=True)
        if out is not None:
            yield out


def _time(arr: Any, tsrc: str) -> np.ndarray:
    return {"log": arr.log_time, "publish": arr.publish_time, "header": arr.header}[tsrc]


def _stack(cols: list[np.ndarray]) -> np.ndarray:
    return np.column_stack(cols).astype(np.float64, copy=False)


class _Merge:
    """Causal sample-and-hold of the companions onto the state samples, over blocks."""

    def __init__(self, lay: MessageLayout) -> None:
        self.lay = lay
        self.st = np.zeros(0, dtype=np.int64)
        self.sm = np.zeros((0, len(lay.state_cols)))
        self.ht = [np.zeros(0, dtype=np.int64) for _ in lay.held]
        self.hm = [np.zeros((0, len(h.cols))) for h in lay.held]
        self.got = [0] * len(lay.held)
        self.rows = 0

    def add_state(self, t: np.ndarray, m: np.ndarray) -> None:
        self.st = np.concatenate((self.st, t))
        self.sm = np.concatenate((self.sm, m))
        if self.st.size > MAX_LOOKAHEAD:
            raise _NotStreamable("companion topics lag too far behind the state topic")

    def add_held(self, k: int, t: np.ndarray, m: np.ndarray) -> None:
        self.ht[k] = np.concatenate((self.ht[k], t))
        self.hm[k] = np.concatenate((self.hm[k], m))
        self.got[k] += t.size
        if self.ht[k].size > MAX_LOOKAHEAD:
            raise _NotStreamable("the state topic lags too far behind a companion")

    def ready(self, final: bool) -> _Raw | None:
        """The state samples every companion's latest message is known for, as rows."""
        lay = self.lay
        limit = None
        if not final:
            for k, h in enumerate(lay.held):
                if self.got[k] < h.total:
                    last = int(self.ht[k][-1]) if self.ht[k].size else None
                    if last is None:
                        return None
                    limit = last if limit is None else min(limit, last)
        n = self.st.size if limit is None else int(np.searchsorted(self.st, limit, "left"))
        if n == 0:
            return None
        t, parts = self.st[:n], [self.sm[:n]]
        drop = np.zeros(n, dtype=bool)
        for k in range(len(lay.held)):
            idx = np.searchsorted(self.ht[k], t, side="right") - 1
            before = idx < 0
            lay.lead_counts[k] += int(before.sum())
            drop |= before
            parts.append(self.hm[k][np.maximum(idx, 0)])
            keep_from = max(int(idx[-1]), 0)
            self.ht[k], self.hm[k] = self.ht[k][keep_from:], self.hm[k][keep_from:]
        self.st, self.sm = self.st[n:], self.sm[n:]
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
    from .messages import joint_kind
    from .msgsource import McapSource

    if cmap is not None:
        raise _NotStreamable("a channel map")
    src: Any = None
    if suffix == ".mcap":
        reader: Any = McapBlocks(p, where)
    else:
        from .bags import BagSource

        try:
            src = BagSource(p, where)
        except ImpactError as err:
            raise _NotStreamable(str(err)) from err
        reader = BagBlocks(src)
    stats: dict[str, _TopicStats] = {}
    try:
        for block in reader.blocks():
            if suffix == ".mcap":
                src = McapSource(reader.scan, where)  # the channels known so far
            for topic, batches in block.items():
                st = stats.get(topic)
                if st is None:
                    st = stats[topic] = _TopicStats(joint_kind(*src.topics()[topic]) or "")
                if st.kind in ("ros2", "json") or (st.kind == "ros1" and suffix != ".mcap"):
                    st.add(_decode(src, topic, st.kind, batches, st.joints))
    except ImpactError as err:  # the whole-file reader says what is wrong
        raise _NotStreamable(str(err)) from err
    if suffix == ".mcap":
        if reader.scan.n_messages == 0:
            raise _NotStreamable("no messages")
        src = McapSource(reader.scan, where)
    lay = MessageLayout(p, where, reader, src, options)
    if suffix == ".mcap" and reader.scan.truncated:
        lay.truncated = [f"{where}: MCAP file is truncated (records end early); read "
                         f"the {reader.scan.n_messages} complete message(s) before the cut"]
    _decide(lay, stats, options)
    return lay


def _decode(src: Any, topic: str, kind: str, batches: list[Any],
            joints: tuple[str, ...] | None) -> Any:
    """A block's messages of one joint topic decoded (``joints``: None for its first
    message's, as :func:`impactcli.io.messages._joint_arrays` reads a whole topic)."""
    from .messages import _joint_arrays
    from .msgsource import TopicData

    mtype, enc = src.topics()[topic]
    arr = _joint_arrays(src, TopicData(topic, mtype, enc, batches), kind,
                        None if kind == "json" else joints)
    if kind == "json" and joints is not None and arr.joints != joints:
        raise _NotStreamable("JSON joint names differ between chunks")
    return arr


def _time_source(st: _TopicStats, given: str | None, where: str, topic: str) -> str:
    """The state's time source (:func:`impactcli.io.messages.choose_time_source`)."""
    from .messages import choose_time_source

    try:
        return choose_time_source(given, True, None if st.header_nonzero else 0, where, topic)
    except ImpactError as err:
        raise _NotStreamable(str(err)) from err


def _decide(lay: MessageLayout, stats: dict[str, _TopicStats], options: dict[str, Any]
            ) -> None:
    """The whole-file reader's decisions from the first pass's counts (module docstring;
    :func:`impactcli.io.messages.read_message_channels` without a channel map)."""
    from .channel_map import SIGNALS
    from .messages import pick_state_topic
    from .repair import DROPPABLE_SIGNALS

    where, topics = lay.where, lay.src.topics()
    try:
        state, kind = pick_state_topic(topics, options.get("topic"), where)
    except ImpactError as err:
        raise _NotStreamable(str(err)) from err
    st = stats.get(state)
    if st is None or st.n == 0 or not st.all_joints or st.joints is None:
        raise _NotStreamable("the state topic cannot be read")
    lay.state, lay.kind, lay.joints = state, kind, st.joints
    jn = len(st.joints)
    used, ignored = [], []
    for s in SIGNALS:
        if s not in st.has_all:
            continue
        if st.has_all[s]:
            used.append(s)
        elif st.has_any[s]:
            if s in ("position", "torque"):
                raise _NotStreamable("a message lacks position or torque")
            ignored.append(f"{state}:{s} (not in every message)")
    if "position" not in used:
        raise _NotStreamable("no positions")
    lay.state_cols = [(s, c) for s in used for c in range(jn)]
    ignored += [f"{state}:{nm}" for nm in sorted(st.extra)]
    lay.time_source = _time_source(st, options.get("time_source"), where, state)
    if not st.ordered[lay.time_source]:
        raise _NotStreamable("state stamps out of order (the whole-file reader sorts them)")
    for t, role, k in _companions(topics, state, kind, options.get("reference_topic")):
        hs = stats.get(t)
        if hs is None or hs.n == 0 or hs.joints is None or not hs.all_joints or hs.extra:
            raise _NotStreamable(f"companion {t!r}: empty, or joint names that change")
        named = set(hs.joints)
        if role == "reference topic":
            if not (set(st.joints) <= named and hs.has_all.get("position")):
                raise _NotStreamable("a reference message lacks joints or positions")
            cols = [("position_ref", j, "position") for j in range(jn)]
            if hs.has_all.get("velocity"):
                cols += [("velocity_ref", j, "velocity") for j in range(jn)]
        else:
            cols = [(role.split()[0], j, "effort") for j in range(jn) if st.joints[j] in named]
        if not cols:
            continue
        hsrc = ("header" if lay.time_source == "header" and hs.header_nonzero else
                "publish" if lay.time_source == "publish" else "log")
        if not hs.ordered[hsrc]:
            raise _NotStreamable(f"companion {t!r}: stamps out of order")
        lay.held.append(_Companion(t, role, k, hsrc, cols, hs.n))
    used_topics = {state} | {h.topic for h in lay.held}
    lay.ignored = [x for x in sorted(topics) if x not in used_topics] + ignored
    cols_all = lay.state_cols + [(s, j) for h in lay.held for s, j, _ in h.cols]
    lay.names = [f"{lay.joints[j]}.{s}" for s, j in cols_all]
    if len(set(lay.names)) != len(lay.names):
        raise _NotStreamable("a signal from two topics")
    lay.keys = {(s, j): f"{lay.joints[j]}.{s}" for s, j in cols_all}
    lay.droppable = {nm for nm in lay.names if nm.rsplit(".", 1)[-1] in DROPPABLE_SIGNALS}
    lay.time_name = f"{lay.time_source} time"
    lay.fmt = f"mcap-{kind}" if lay.src.kind == "mcap" else lay.src.kind
    lay.lead_counts = [0] * len(lay.held)
    lay.plan = plan_of(lay, options.get("robot"), options.get("torque_source"))


def _companions(topics: dict[str, tuple[str, str]], state: str, kind: str,
                rtopic: str | None) -> list[tuple[str, str, str]]:
    """``(topic, role, kind)`` of the state's companion topics
    (:func:`impactcli.io.messages._companions` without a channel map)."""
    from .messages import COMPANIONS, joint_kind

    if kind == "json":
        if rtopic is not None:
            raise _NotStreamable("--reference-topic on JSON samples")
        return []
    out = []
    if rtopic is None and joint_kind(*topics.get(f"{state}_ref", ("", ""))) in ("ros2", "ros1"):
        rtopic = f"{state}_ref"
    if rtopic is not None:
        rk = joint_kind(*topics[rtopic]) if rtopic in topics else None
        if rk not in ("ros2", "ros1"):
            raise _NotStreamable("reference topic missing or not JointState")
        out.append((rtopic, "reference topic", rk or ""))
    for suffix, _arr, sig in COMPANIONS:
        cand = f"{state}{suffix}"
        if cand in topics and (ck := joint_kind(*topics[cand])) in ("ros2", "ros1"):
            out.append((cand, f"{sig} topic", ck or ""))
    return out
