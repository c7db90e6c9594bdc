"""The reader of a message log (:func:`message_layout`) and what the log is made of
(:mod:`impactcli.logs.messages.message_read`): the topics to read
(:func:`selection`, from the topics and the channel map, before the pass over the file),
then from their counts (:func:`decide`, after it) the state topic's joints, signals and
time source, the companion and map topics held onto it and their columns, the ignored
channels — and, for a log that does not fit, the first error in the order the module
docstring of :mod:`impactcli.logs.messages.message_read` gives.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ChannelMapError, ImpactError, LogFormatError
from ...sample_channels import CHANNEL_NAMES, CHANNELS, DROPPABLE_CHANNELS
from ..channels import TIME_SOURCES
from ..layout import plan_of
from .message_merge import Part
from .message_read import (
    COMPANIONS,
    MapField,
    MessageLayout,
    TopicReader,
    choose_time_source,
    joint_kind,
    map_fields,
    pick_state_topic,
)

_ROS = ("ros2", "ros1")

#: The channels a JointState message carries (position, velocity, and effort as torque).
JOINT_STATE_SIGNALS: tuple[str, ...] = tuple(c.name for c in CHANNELS
                                             if c.name in {"position", "velocity", "torque"})


@dataclass
class Selection:
    """The topics a message log may be made of, chosen before the pass over it.

    Attributes:
        topics: the topics read in the pass; ``decode``: those whose joint messages are
            decoded; ``by_topic``: the map's fields by topic.
        error: why no topic can be chosen (raised after the pass: a damaged file is said
            first).
        state, kind: the state topic and its kind (``ros2``, ``ros1``, ``json``).
        fields, mapped, pos: the map's fields, the signals they give, those of positions.
        wanted: the companions ``(topic, role, kind)``; ``companion_error``: why they
            cannot be (raised after the state topic's checks).
    """

    topics: list[str] = field(default_factory=list)
    decode: set[str] = field(default_factory=set)
    by_topic: dict[str, list[MapField]] = field(default_factory=dict)
    error: ImpactError | None = None
    state: str = ""
    kind: str = ""
    fields: list[MapField] = field(default_factory=list)
    mapped: set[str] = field(default_factory=set)
    pos: list[MapField] = field(default_factory=list)
    wanted: list[tuple[str, str, str]] = field(default_factory=list)
    companion_error: ImpactError | None = None
    mapname: str = ""
    cmap: Any = None

    def raise_error(self) -> None:
        if self.error is not None:
            raise self.error


def selection(lay: MessageLayout, cmap: Any, options: dict[str, Any]) -> Selection:
    """The topics the log may be made of (:class:`Selection`)."""
    where = lay.where
    topics = lay.src.topics()
    sel = Selection(cmap=cmap)
    sel.mapname = lay.mapname = "" if cmap is None else (cmap.path or cmap.name)
    lay.prefix = f"{where}: channel map {sel.mapname}"
    topic, rtopic = options.get("topic"), options.get("reference_topic")
    try:
        if cmap is not None and cmap.format != "messages":
            kind_txt = {"csv": "CSV files", "npz": ".npz archives"}.get(
                cmap.format or "", "CSV files or .npz archives")
            raise ChannelMapError(f"{where}: channel map {sel.mapname} is for {kind_txt}; a "
                                  "map for MCAP or ROS bags says 'format: messages' and "
                                  "names fields")
        sel.fields = map_fields(lay.src, cmap, topics) if cmap is not None else []
        sel.mapped = {f.signal for f in sel.fields}
        sel.pos = [f for f in sel.fields if f.signal == "position"]
        if sel.pos:
            sel.state, sel.kind = _field_state(lay, sel, cmap, topic, rtopic)
        else:
            sel.state, sel.kind = pick_state_topic(topics, topic, where)
            sel.decode.add(sel.state)
    except ImpactError as err:
        sel.error = err
        return sel
    if sel.kind in _ROS and not sel.pos:
        try:
            sel.wanted = _companions(lay, sel, topics, rtopic)
        except ImpactError as err:
            sel.companion_error = err
        sel.decode.update(t for t, _, _ in sel.wanted)
    for f in sel.fields:
        sel.by_topic.setdefault(f.path.topic, []).append(f)
    sel.topics = list(dict.fromkeys([sel.state, *(t for t, _, _ in sel.wanted),
                                     *sel.by_topic]))
    return sel


def _field_state(lay: MessageLayout, sel: Selection, cmap: Any, topic: str | None,
                 rtopic: str | None) -> tuple[str, str]:
    """The state topic of a map naming every joint's position by field path."""
    where, mapname = lay.where, sel.mapname
    if len(sel.pos) != len(cmap.joints):
        have = {f.joint for f in sel.pos}
        j = next(cmap.joints[k] for k in range(len(cmap.joints)) if k not in have)
        raise ChannelMapError(f"{where}: channel map {mapname}: joint {j!r} has no position "
                              "field while others have: name every joint's position")
    ptopics = sorted({f.path.topic for f in sel.pos})
    if len(ptopics) > 1:
        raise ChannelMapError(f"{where}: channel map {mapname}: the position fields are on "
                              f"several topics ({', '.join(ptopics)}); they must share one")
    state = ptopics[0]
    if topic is not None and topic != state:
        raise LogFormatError(f"{where}: --topic {topic!r} differs from the topic of the "
                             f"channel map's position fields ({state!r})")
    if rtopic is not None:
        raise LogFormatError(f"{where}: --reference-topic does not apply when the channel "
                             "map names the positions; name position_ref in the map")
    enc = lay.src.topics()[state][1]
    return state, {"cdr": "ros2", "ros1": "ros1"}.get(enc, "json")


def _companions(lay: MessageLayout, sel: Selection, topics: dict[str, tuple[str, str]],
                rtopic: str | None) -> list[tuple[str, str, str]]:
    """The reference and controller topics of a JointState state topic."""
    where, state, mapped = lay.where, sel.state, sel.mapped
    if rtopic is not None and ({"position_ref", "velocity_ref"} & mapped):
        raise LogFormatError(f"{where}: --reference-topic and the channel map's position_ref "
                             "both name the reference; give one")
    if rtopic is None and "position_ref" not in mapped:
        cand = f"{state}_ref"
        if cand in topics and joint_kind(*topics[cand]) in _ROS:
            rtopic = cand
    wanted: list[tuple[str, str, str]] = []
    if rtopic is not None:
        if rtopic not in topics:
            raise LogFormatError(f"{where}: reference topic {rtopic!r} not found (topics: "
                                 f"{', '.join(sorted(topics))})")
        rk = joint_kind(*topics[rtopic])
        if rk not in _ROS:
            raise LogFormatError(f"{where}: reference topic {rtopic!r} is not a JointState topic")
        wanted.append((rtopic, "reference topic", str(rk)))
    for suffix, _arr, sig in COMPANIONS:
        cand = f"{state}{suffix}"
        if sig not in mapped and cand in topics:
            ck = joint_kind(*topics[cand])
            if ck in _ROS:
                wanted.append((cand, f"{sig} topic", str(ck)))
    return wanted


# ----------------------------------------------------------------- after the pass
def _flags(r: TopicReader, key: str) -> tuple[bool, bool, int]:
    """Whether every message / some message has the bool column ``key`` set, and the
    first that has not (−1: none)."""
    first = r.spill.first_false([key])
    if first is None:
        return True, r.n > 0, -1
    return False, bool(np.any(r.spill.column(key))), first


def _lacking(r: TopicReader, joints: tuple[str, ...]) -> int | None:
    """The first message that does not name every joint of ``joints``."""
    return r.spill.first_false([f"named:{j}" for j in joints])


def decide(lay: MessageLayout, sel: Selection, options: dict[str, Any]) -> None:
    """Fill ``lay``'s parts, joints, columns, time source, ignored channels and format
    from the pass's counts; raise what does not fit (module docstring)."""
    where, state = lay.where, sel.state
    topics = lay.src.topics()
    r = lay.readers[state]
    if r.n == 0:
        raise LogFormatError(f"{where}: topic {state!r} holds no messages")
    if sel.pos:
        if r.field_error is not None:
            raise r.field_error
        joints = tuple(sel.cmap.joints)
        cols = [(f.signal, f.joint, f"field:{k}") for k, f in enumerate(sel.by_topic[state])]
        ignored: list[str] = []
    else:
        joints, cols, ignored = _joint_state(lay, sel, r)
    lay.joints = joints
    held: list[tuple[str, str, TopicReader, list[tuple[str, int, str]]]] = []
    if sel.kind in _ROS and not sel.pos:
        held += _held_companions(lay, sel, joints)
    elif options.get("reference_topic") is not None:
        raise LogFormatError(f"{where}: --reference-topic applies to ROS JointState; JSON "
                             "samples carry their reference in each message")
    for t, fl in sel.by_topic.items():
        if t == state:
            continue
        fr = lay.readers[t]
        if fr.n == 0:
            raise LogFormatError(f"{where}: topic {t!r} (channel map {sel.mapname}) holds no "
                                 "messages")
        if fr.field_error is not None:
            raise fr.field_error
        held.append((t, "topic", fr, [(f.signal, f.joint, f"field:{k}")
                                      for k, f in enumerate(fl)]))
    used = {state} | {h[0] for h in held}
    lay.ignored = [x for x in sorted(topics) if x not in used] + ignored
    lay.fmt = f"mcap-{sel.kind}" if lay.source_kind == "mcap" else lay.source_kind
    has_header = r.has_header
    tsrc = choose_time_source(options.get("time_source"), has_header,
                              r.first_zero if has_header else None, where, state)
    lay.time_source, lay.state = tsrc, state
    parts = [Part(state, "state", r.spill, tsrc, [(s, j) for s, j, _ in cols],
                  [k for _, _, k in cols], r.ordered[tsrc])]
    for t, role, hr, hcols in held:
        hsrc = ("header" if tsrc == "header" and hr.has_header and hr.first_zero is None
                else "publish" if tsrc == "publish" else "log")
        if hr.lo[hsrc] > r.hi[tsrc]:
            raise LogFormatError(f"{where}: {role} {t!r} starts after the last state message")
        parts.append(Part(t, role, hr.spill, hsrc, [(s, j) for s, j, _ in hcols],
                          [k for _, _, k in hcols], hr.ordered[hsrc]))
    lay.parts = parts
    if not r.ordered[tsrc]:
        lay.perm = np.argsort(r.spill.column(tsrc), kind="stable")
    _columns(lay, sel)


def _joint_state(lay: MessageLayout, sel: Selection, r: TopicReader
                 ) -> tuple[tuple[str, ...], list[tuple[str, int, str]], list[str]]:
    """The JointState (or JSON JointSample) state topic's joints, columns and ignored
    channels, checked as the whole topic would be."""
    where, state, kind = lay.where, sel.state, sel.kind
    if kind == "ros2" and r.first_error is not None:
        raise r.first_error
    if kind == "ros1" and r.error is not None:
        raise r.error
    first = r.first_names or ()
    if not first and kind in _ROS:
        raise LogFormatError(f"{where}: topic {state!r}: first message has no joint names")
    if r.error is not None:
        raise r.error
    cmap = sel.cmap
    joints = first
    decode_joints = first
    if cmap is not None:
        joints = tuple(cmap.joints)
        absent = [j for j in joints if j not in first]
        if absent:
            raise ChannelMapError(
                f"{where}: channel map {sel.mapname}: joint {absent[0]!r} is not in name[] of "
                f"{state!r} (names: {', '.join(first)})")
        if kind != "json" and set(joints) != set(first):
            decode_joints = joints
    k = _lacking(r, decode_joints)
    if k is not None:
        raise LogFormatError(f"{where}: topic {state!r}, message {k} lacks some of the joints "
                             f"{', '.join(joints)}")
    signals = CHANNEL_NAMES if kind == "json" else JOINT_STATE_SIGNALS
    used: list[str] = []
    ignored: list[str] = []
    for s in CHANNEL_NAMES:
        if s not in signals or s in sel.mapped:
            continue
        every, some, miss = _flags(r, f"has:{s}")
        if every:
            used.append(s)
        elif some:
            if s in ("position", "torque"):
                what = "effort (torque)" if s == "torque" and kind != "json" else s
                raise LogFormatError(f"{where}: topic {state!r}, message {miss} has no {what}")
            ignored.append(f"{state}:{s} (not in every message)")
    if "position" not in used:
        raise LogFormatError(f"{where}: topic {state!r} carries no joint positions")
    cols = [(s, c, f"{s}:{j}") for s in used for c, j in enumerate(joints)]
    extra = sorted(set(r.names) - set(decode_joints))
    ignored += [f"{state}:{nm}" for nm in extra]
    ignored += [f"{state}:{nm}" for nm in decode_joints if nm not in joints]
    on_state = sel.by_topic.get(state, [])
    if on_state:
        if r.field_error is not None:
            raise r.field_error
        cols += [(f.signal, f.joint, f"field:{k}") for k, f in enumerate(on_state)]
    return joints, cols, ignored


def _held_companions(lay: MessageLayout, sel: Selection, joints: tuple[str, ...]
                     ) -> list[tuple[str, str, TopicReader, list[tuple[str, int, str]]]]:
    """The companions held onto the state, checked as the whole topics would be."""
    where, mapped = lay.where, sel.mapped
    if sel.companion_error is not None:
        raise sel.companion_error
    out = []
    for t, role, _k in sel.wanted:
        hr = lay.readers[t]
        if hr.n == 0:
            raise LogFormatError(f"{where}: topic {t!r} holds no messages")
        if hr.error is not None:
            raise hr.error
        cols: list[tuple[str, int, str]] = []
        if role == "reference topic":
            m = _lacking(hr, joints)
            if m is not None:
                raise LogFormatError(f"{where}: topic {t!r}, message {m} lacks some of the "
                                     "joints")
            every, _some, miss = _flags(hr, "has:position")
            if not every:
                raise LogFormatError(f"{where}: topic {t!r}, message {miss} has no position")
            if "position_ref" not in mapped:
                cols = [("position_ref", j, f"position:{nm}") for j, nm in enumerate(joints)]
            if _flags(hr, "has:velocity")[0] and "velocity_ref" not in mapped:
                cols += [("velocity_ref", j, f"velocity:{nm}") for j, nm in enumerate(joints)]
        else:
            sig = role.split()[0]
            seen = [j for j, nm in enumerate(joints)
                    if hr.spill.has(f"named:{nm}") and bool(np.any(hr.spill.column(
                        f"named:{nm}")))]
            cols = [(sig, j, f"torque:{joints[j]}") for j in seen]
        if cols:
            out.append((t, role, hr, cols))
    return out


def _columns(lay: MessageLayout, sel: Selection) -> None:
    """The layout's column names and keys, repairs' droppable columns, current scale."""

    cols = [c for part in lay.parts for c in part.cols]
    lay.names = [f"{lay.joints[j]}.{s}" for s, j in cols]
    lay.keys = {(s, j): f"{lay.joints[j]}.{s}" for s, j in cols}
    lay.droppable = {nm for nm in lay.names if nm.rsplit(".", 1)[-1] in DROPPABLE_CHANNELS}
    lay.time_name = f"{lay.time_source} time"
    scale = np.full(len(lay.joints), np.nan)
    for f in sel.fields:
        if f.signal == "current" and f.ref.scale is not None:
            scale[f.joint] = f.ref.scale
    lay.current_scale = scale


# ------------------------------------------------------------------------ the reader
def message_layout(p: Path, where: str, suffix: str, cmap: Any,
                   options: dict[str, Any]) -> MessageLayout:
    """The reader of an MCAP log or ROS bag (module docstring): its pass over the file,
    and what the log is made of.

    Raises:
        LogFormatError, ChannelMapError: the first thing that does not fit, in the order
            of the module docstring.
    """
    time_source = options.get("time_source")
    bad_source = time_source is not None and time_source not in TIME_SOURCES
    if suffix == ".mcap":
        if bad_source:
            raise LogFormatError(f"{where}: unknown time source {time_source!r} (log, "
                                 "publish, header)")
        lay = _mcap_layout(p, where, options)
    else:
        from .bags import BagBlocks, BagSource

        src = BagSource(p, where)
        if not src.topics():
            raise LogFormatError(f"{where}: the bag holds no topics")
        lay = MessageLayout(p, where, BagBlocks(src), src, src.kind, options)
    if bad_source:
        raise LogFormatError(f"{where}: unknown time source {time_source!r} (log, publish, "
                             "header)")
    try:
        sel = selection(lay, cmap, options)
        lay.read(sel.topics, sel.decode, sel.by_topic)
        if lay.source_kind == "mcap":
            _mcap_checks(lay)
        sel.raise_error()
        decide(lay, sel, options)
        lay.plan = plan_of(lay, options)
    except BaseException:
        lay.close()
        raise
    return lay


def _mcap_layout(p: Path, where: str, options: dict[str, Any]) -> MessageLayout:
    """An MCAP file's layout: its channels from the summary section, else from a pass
    over its records (a truncated file); the official reader for a compression the
    walker does not know."""
    from .mcap import McapBlocks, McapSource, OfficialBlocks, UnsupportedMcap

    blocks: Any = McapBlocks(p, where)
    scan = blocks.summary()
    if scan is None:
        try:
            for _ in blocks.blocks(()):
                pass
        except UnsupportedMcap:
            blocks = OfficialBlocks(p, where)
            for _ in blocks.blocks(()):
                pass
        scan = blocks.scan
    return MessageLayout(p, where, blocks, McapSource(scan, where), "mcap", options)


def _mcap_checks(lay: MessageLayout) -> None:
    """After the pass: an MCAP without messages is refused; a truncated one is read up to
    the cut (a repair)."""
    scan = lay.blocks.scan
    if scan.n_messages == 0:
        what = ("truncated before its first complete message" if scan.truncated
                else "holds no messages")
        raise LogFormatError(f"{lay.where}: corrupt or empty MCAP: {what}")
    if scan.truncated:
        lay.truncated = [f"{lay.where}: MCAP file is truncated (records end early); read "
                         f"the {scan.n_messages} complete message(s) before the cut"]


def _source_layout(p: Path, where: str) -> MessageLayout:
    """The layout of an MCAP file or bag before its pass (its topics known)."""
    if p.name.lower().endswith(".mcap"):
        return _mcap_layout(p, where, {})
    from .bags import BagBlocks, BagSource

    src = BagSource(p, where)
    return MessageLayout(p, where, BagBlocks(src), src, src.kind, {})


def field_channel(p: Path, name: str, text: str, joint: str | None, time_source: str,
                  hint: str) -> tuple[np.ndarray, np.ndarray, str]:
    """One message field of an MCAP file or bag (``impactcli labels --from-channel``),
    read by the same pass over the file as a log: its values and stamps (stamped as a
    topic held onto the log's samples is, by the log's ``time_source``), in time order,
    and the field as it is named.

    Raises:
        LogFormatError, ChannelMapError: no such topic or field, a field that cannot be
            read (naming ``name`` and what the file has; ``hint``: the log's own channels).
    """
    from ..channel_map import ChannelRef
    from .fields import check_ros_path, parse_field_path

    lay = _source_layout(p, str(p))
    try:
        topics = lay.src.topics()
        where = f"{p}: --from-channel"
        if not text.startswith("/"):
            raise LogFormatError(
                f"{p}: no channel {name!r}: in an MCAP file or a bag name a message field "
                f"/topic/field (topics: {', '.join(sorted(topics)) or 'none'})"
                + (f"; or a joint channel: {hint}" if hint else ""))
        fp = parse_field_path(text, list(topics), joint, where)
        mtype, enc = topics[fp.topic]
        if enc in ("cdr", "ros1"):
            if not mtype:
                raise LogFormatError(f"{where}: topic {fp.topic!r} has no message definition "
                                     "in the file: its fields cannot be read")
            fp = check_ros_path(fp, mtype, lay.src.fielddefs(mtype), where)
        elif enc != "json":
            raise LogFormatError(f"{where}: topic {fp.topic!r} has message encoding {enc!r}, "
                                 "which cannot be decoded (cdr, ros1 or json)")
        lay.prefix = where
        lay.read([fp.topic], set(), {fp.topic: [MapField("position", 0, ChannelRef(text), fp)]})
        r = lay.readers[fp.topic]
        if r.n == 0:
            raise LogFormatError(f"{where}: topic {fp.topic!r} holds no messages")
        if r.field_error is not None:
            raise r.field_error
        key = ("header" if time_source == "header" and r.has_header and r.first_zero is None
               else "publish" if time_source == "publish" else "log")
        t = r.spill.column(key)
        order = np.argsort(t, kind="stable")
        return t[order], r.spill.column("field:0")[order], fp.label()
    finally:
        lay.close()
