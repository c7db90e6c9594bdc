"""The whole-file reader's decisions for a streamed message log, from the first pass's
counts (:mod:`impactcli.io.stream_msgs`): what
:func:`impactcli.io.messages.read_message_channels` decides from the whole topics — the
state topic, the joints, the signals every message fills, the companion and field topics
and their columns, the ignored channels, the time sources — decided from
:class:`~impactcli.io.stream_msgs._TopicStats` instead. Whatever the whole reader would
refuse, or what the counts cannot decide exactly, raises ``_NotStreamable`` (the whole
reader then reads the log and raises its own error where it has one).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ImpactError
from ._whole import NotStreamable as _NotStreamable
from .stream_msgs import MessageLayout, _Part, _TopicStats


def decide(lay: MessageLayout, stats: dict[str, _TopicStats], fstats: dict[str, _TopicStats],
           fields: list[Any], cmap: Any, options: dict[str, Any]) -> None:
    """Fill ``lay``'s parts, joints, columns, ignored channels and plan (module docstring)."""
    if options.get("time_source") not in (None, "log", "publish", "header"):
        raise _NotStreamable("an unknown time source")
    topics = lay.src.topics()
    mapped = {f.signal for f in fields}
    pos = [f for f in fields if f.signal == "position"]
    if pos:
        state, kind, state_part, ignored = _field_state(lay, fstats, fields, pos, cmap, options)
    else:
        state, kind, state_part, ignored = _joint_state(lay, stats, cmap, mapped, options)
    on_state = [f for f in fields if f.path.topic == state]
    state_part.fields = on_state if state_part.kind else state_part.fields
    lay.parts = [state_part]
    if kind in ("ros2", "ros1") and not pos:
        lay.parts += _companions(lay, stats, topics, state, options.get("reference_topic"),
                                 mapped)
    elif options.get("reference_topic") is not None:
        raise _NotStreamable("--reference-topic that does not apply")
    by_topic: dict[str, list[Any]] = {}
    for f in fields:
        if f.path.topic != state:
            by_topic.setdefault(f.path.topic, []).append(f)
    for t, fl in by_topic.items():
        fs = fstats.get(t)
        if fs is None or fs.n == 0:
            raise _NotStreamable(f"topic {t!r} holds no messages")
        lay.parts.append(_Part(t, "topic", "", _held_source(lay.time_source, fs), fs.n,
                               fields=fl))
    for part in lay.parts[1:]:
        if not (stats if part.kind else fstats)[part.topic].ordered[part.tsrc]:
            raise _NotStreamable(f"topic {part.topic!r}: stamps out of order")
    used = {p.topic for p in lay.parts}
    lay.ignored = [x for x in sorted(topics) if x not in used] + ignored
    lay.fmt = f"mcap-{kind}" if lay.src.kind == "mcap" else lay.src.kind
    plan_of_messages(lay, fields, options)


def _state_source(lay: MessageLayout, st: _TopicStats, options: dict[str, Any]) -> str:
    """The state's time source (:func:`impactcli.io.messages.choose_time_source`); its
    stamps must be in order in the file (the whole reader sorts them)."""
    from .messages import choose_time_source

    try:
        tsrc = choose_time_source(options.get("time_source"), bool(st.has_header),
                                  None if st.header_nonzero else 0, lay.where, lay.state)
    except ImpactError as err:
        raise _NotStreamable(str(err)) from err
    if not st.ordered[tsrc]:
        raise _NotStreamable("state stamps out of order (the whole-file reader sorts them)")
    return tsrc


def _held_source(state_source: str, st: _TopicStats) -> str:
    """A held topic's time source (:func:`impactcli.io.messages._held_time`)."""
    if state_source == "header" and st.has_header and st.header_nonzero:
        return "header"
    return "publish" if state_source == "publish" else "log"


def _field_state(lay: MessageLayout, fstats: dict[str, _TopicStats], fields: list[Any],
                 pos: list[Any], cmap: Any, options: dict[str, Any]
                 ) -> tuple[str, str, _Part, list[str]]:
    """The state topic of a map naming every joint's position by field path."""
    ptopics = sorted({f.path.topic for f in pos})
    if len(pos) != len(cmap.joints) or len(ptopics) > 1:
        raise _NotStreamable("the map's positions do not name one state topic")
    state = ptopics[0]
    if options.get("topic") not in (None, state) or options.get("reference_topic"):
        raise _NotStreamable("--topic or --reference-topic against the map")
    fs = fstats.get(state)
    if fs is None or fs.n == 0:
        raise _NotStreamable("the state topic holds no messages")
    lay.state, lay.joints = state, tuple(cmap.joints)
    lay.time_source = _state_source(lay, fs, options)
    enc = lay.src.topics()[state][1]
    kind = {"cdr": "ros2", "ros1": "ros1"}.get(enc, "json")
    part = _Part(state, "state", "", lay.time_source, fs.n,
                 fields=[f for f in fields if f.path.topic == state])
    return state, kind, part, []


def _joint_state(lay: MessageLayout, stats: dict[str, _TopicStats], cmap: Any,
                 mapped: set[str], options: dict[str, Any]
                 ) -> tuple[str, str, _Part, list[str]]:
    """The JointState (or JSON JointSample) state topic, its joints and signals."""
    from .channel_map import SIGNALS
    from .messages import pick_state_topic

    try:
        state, kind = pick_state_topic(lay.src.topics(), options.get("topic"), lay.where)
    except ImpactError as err:
        raise _NotStreamable(str(err)) from err
    st = stats.get(state)
    if st is None or st.n == 0 or not st.all_joints or st.joints is None:
        raise _NotStreamable("the state topic cannot be read")
    first = st.joints
    joints = tuple(cmap.joints) if cmap is not None else first
    if not set(joints) <= set(first):
        raise _NotStreamable("a map joint the state topic does not name")
    lay.state, lay.joints = state, joints
    lay.time_source = _state_source(lay, st, options)
    jidx = [first.index(j) for j in joints] if kind == "json" else list(range(len(joints)))
    used, ignored = [], []
    for s in SIGNALS:
        if s not in st.has_all or s in mapped:
            continue
        if st.has_all[s]:
            used.append(s)
        elif st.has_any[s]:
            if s in ("position", "torque"):
                raise _NotStreamable("a message lacks position or torque")
            ignored.append(f"{state}:{s} (not in every message)")
    if "position" not in used:
        raise _NotStreamable("no positions")
    if kind == "json":  # decoded for its first message's joints, mapped by name
        ignored += [f"{state}:{nm}" for nm in sorted(st.extra)]
        ignored += [f"{state}:{nm}" for nm in first if nm not in joints]
    else:  # decoded for the log's joints: the others are extra names
        ignored += [f"{state}:{nm}" for nm in sorted((set(first) | st.extra) - set(joints))]
    part = _Part(state, "state", kind, lay.time_source, st.n,
                 joints=first if kind == "json" else joints,
                 cols=[(s, c, s, jx) for s in used for c, jx in enumerate(jidx)])
    return state, kind, part, ignored


def _companions(lay: MessageLayout, stats: dict[str, _TopicStats],
                topics: dict[str, tuple[str, str]], state: str, rtopic: str | None,
                mapped: set[str]) -> list[_Part]:
    """The state's companion topics (:func:`impactcli.io.messages._companions`), their
    columns from the counts (a companion's messages must all name the same joints)."""
    from .messages import COMPANIONS, joint_kind

    ros = ("ros2", "ros1")
    if rtopic is not None and {"position_ref", "velocity_ref"} & mapped:
        raise _NotStreamable("--reference-topic and a mapped reference")
    if rtopic is None and "position_ref" not in mapped and joint_kind(
            *topics.get(f"{state}_ref", ("", ""))) in ros:
        rtopic = f"{state}_ref"
    wanted: list[tuple[str, str]] = []
    if rtopic is not None:
        if rtopic not in topics or joint_kind(*topics[rtopic]) not in ros:
            raise _NotStreamable("reference topic missing or not JointState")
        wanted.append((rtopic, "reference topic"))
    for suffix, _arr, sig in COMPANIONS:
        cand = f"{state}{suffix}"
        if sig not in mapped and cand in topics and joint_kind(*topics[cand]) in ros:
            wanted.append((cand, f"{sig} topic"))
    out = []
    joints = lay.joints
    for t, role in wanted:
        hs = stats.get(t)
        if hs is None or hs.n == 0 or hs.joints is None or not hs.all_joints or hs.extra:
            raise _NotStreamable(f"companion {t!r}: empty, or joint names that change")
        named = set(hs.joints)
        cols: list[tuple[str, int, str, int]] = []
        if role == "reference topic":
            if not (set(joints) <= named and hs.has_all.get("position")):
                raise _NotStreamable("a reference message lacks joints or positions")
            if "position_ref" not in mapped:
                cols = [("position_ref", j, "position", j) for j in range(len(joints))]
            if hs.has_all.get("velocity") and "velocity_ref" not in mapped:
                cols += [("velocity_ref", j, "velocity", j) for j in range(len(joints))]
        else:
            cols = [(role.split()[0], j, "torque", j) for j in range(len(joints))
                    if joints[j] in named]
        if cols:
            out.append(_Part(t, role, hs.kind, _held_source(lay.time_source, hs), hs.n,
                             joints=joints, cols=cols))
    return out


def plan_of_messages(lay: MessageLayout, fields: list[Any], options: dict[str, Any]) -> None:
    """The layout's column names, keys, current scale and plan."""
    from .repair import DROPPABLE_SIGNALS
    from .stream_layout import plan_of

    cols = [sig for part in lay.parts for sig in part.signals]
    lay.names = [f"{lay.joints[j]}.{s}" for s, j in cols]
    if len(set(lay.names)) != len(lay.names):
        raise _NotStreamable("a signal from two topics")
    lay.keys = {(s, j): f"{lay.joints[j]}.{s}" for s, j in cols}
    lay.droppable = {nm for nm in lay.names if nm.rsplit(".", 1)[-1] in DROPPABLE_SIGNALS}
    lay.time_name = f"{lay.time_source} time"
    lay.lead_counts = [0] * len(lay.held)
    scale = np.full(len(lay.joints), np.nan)
    for f in fields:
        if f.signal == "current" and f.ref.scale is not None:
            scale[f.joint] = f.ref.scale
    lay.current_scale = scale
    lay.plan = plan_of(lay, options.get("robot"), options.get("torque_source"))
