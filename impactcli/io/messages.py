"""Joint signals from a message log — MCAP or ROS bag — one implementation for both.

Works on a :class:`~impactcli.io.msgsource.MessageSource` (formats.md, "MCAP", "Channel maps").

State topic (no channel map, or a map that names no position field): ``topic`` when given;
else the only joint topic (ROS ``sensor_msgs/JointState`` in CDR or ROS 1, or impactcli's
JSON ``JointSample``); else ``/joint_states``; else an error listing the joint topics (or all
topics when there is none). JointState gives position, velocity, effort (= torque), joints
matched by ``name[]`` on every message (CDR decoded in bulk by
:func:`~impactcli.io.mcap_ros2.decode_batches`; ROS 1 one message at a time).

Default companion topics of a JointState state topic ``T`` (all JointState, joints matched
by name, each used when present):

- ``T_ref`` (or ``reference_topic``): ``position`` → ``position_ref``, ``velocity`` (when
  filled in every message) → ``velocity_ref``;
- ``T_model``: ``effort`` → ``torque_model``; ``T_ext``: ``effort`` → ``torque_ext``. A joint
  that no message names does not log that channel (its column is NaN, formats.md).

Channel map (``format: messages``, :mod:`impactcli.io.channel_map`): each per-joint signal
may be a field path (:mod:`impactcli.io.fields`), with the map's scale and offset. When the
map names every joint's ``position`` by field path, the state topic is the topic of those
fields (all on one topic), its messages give the sample times, and every signal comes from
the map (no JointState, no companion topics). Otherwise the state is the JointState topic
above, the log's joints are the map's joints (others are listed as ignored), and a signal
the map names replaces the one from the state or a companion topic. Fields of the state
topic are read row by row with it.

Time: the state topic's ``header`` stamp when its messages have a header and every stamp is
non-zero, else ``log`` time; ``time_source`` (``log``/``publish``/``header``) overrides. Every
other topic (companions and field topics) is stamped the same way — header when the state
uses header and that topic's stamps are all non-zero, publish time when the state uses
publish time, else log time — and aligned to the state samples by sample-and-hold of its
latest message at or before each one (causal). State samples before the first message of
such a topic are dropped (a warned repair). Then the repair policy
(:mod:`impactcli.io.repair`) applies to every column.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import ChannelMapError, ImpactWarning, LogFormatError
from ..types import CONTROLLER_CHANNELS
from .assemble import TIME_SOURCES, JointChannels
from .channel_map import SIGNALS, ChannelMap, ChannelRef
from .fields import FieldPath, check_ros_path, parse_field_path
from .mcap_ros2 import TopicArrays, arrays_from_messages, decode_batches
from .msgsource import JOINT_SAMPLE, JOINT_STATE, MessageSource, TopicData
from .repair import repair_matrix

DEFAULT_STATE_TOPIC = "/joint_states"
#: companion topic suffix → (JointState array, signal)
COMPANIONS: tuple[tuple[str, str, str], ...] = (
    ("_model", "effort", "torque_model"),
    ("_ext", "effort", "torque_ext"),
)


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


@dataclass
class _Times:
    log: np.ndarray
    publish: np.ndarray
    header: np.ndarray | None


@dataclass
class _Held:
    """A topic aligned to the state samples by sample-and-hold."""

    topic: str
    role: str
    times: _Times
    cols: list[tuple[str, int, np.ndarray]] = field(default_factory=list)


def _state_time(tm: _Times, time_source: str | None, where: str,
                topic: str) -> tuple[np.ndarray, str]:
    zero = None if tm.header is None or np.all(tm.header != 0) else int(
        np.argmax(tm.header == 0))
    tsrc = choose_time_source(time_source, tm.header is not None, zero, where, topic)
    if tsrc == "header":
        assert tm.header is not None
        return tm.header, tsrc
    return (tm.publish if tsrc == "publish" else tm.log), tsrc


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


def _held_time(tm: _Times, tsrc: str) -> np.ndarray:
    if tsrc == "header" and tm.header is not None and np.all(tm.header != 0):
        return tm.header
    return tm.publish if tsrc == "publish" else tm.log


def json_topic_arrays(src: MessageSource, td: TopicData) -> TopicArrays:
    """Decode impactcli JSON joint samples into TopicArrays, every signal in ``json_extra``."""
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
        joints, td.log_time.copy(), td.publish_time.copy(), header,
        vals["position"], vals["velocity"], vals["torque"], has_joints,
        has["position"], has["velocity"], has["torque"], extra, np.ones(jn, dtype=bool),
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


def _joint_arrays(src: MessageSource, td: TopicData, kind: str,
                  joints: tuple[str, ...] | None = None) -> TopicArrays:
    if td.n == 0:
        raise LogFormatError(f"{src.where}: topic {td.topic!r} holds no messages")
    if kind == "ros2":
        return decode_batches(td.batches, src.where, td.topic, joints)
    if kind == "ros1":
        msgs = src.decode_all(td)
        if joints is None and not list(msgs[0].name):
            raise LogFormatError(
                f"{src.where}: topic {td.topic!r}: first message has no joint names")
        return arrays_from_messages(msgs, td.log_time, td.publish_time, joints)
    return json_topic_arrays(src, td)


@dataclass
class _MapField:
    signal: str
    joint: int
    ref: ChannelRef
    path: FieldPath


def _map_fields(src: MessageSource, cmap: ChannelMap,
                topics: dict[str, tuple[str, str]]) -> list[_MapField]:
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
        out.append(_MapField(sig, j, ref, fp))
    return out


def _field_columns(src: MessageSource, td: TopicData, fields: list[_MapField],
                   mapname: str) -> tuple[list[tuple[str, int, np.ndarray]], np.ndarray | None]:
    """The map's field columns on ``td``'s topic (scaled; currents raw) and its header stamps."""
    from .fieldread import read_fields

    vals, header = read_fields(src, td, [f.path for f in fields],
                               f"{src.where}: channel map {mapname}")
    out = []
    for c, f in enumerate(fields):
        v = vals[:, c]
        if f.signal != "current":  # a current's scale converts it to torque (build_log)
            if f.ref.scale is not None:
                v = v * f.ref.scale
            if f.ref.offset:
                v = v + f.ref.offset
        out.append((f.signal, f.joint, v))
    return out, header


def read_message_channels(
    src: MessageSource, *, cmap: ChannelMap | None, topic: str | None,
    reference_topic: str | None, time_source: str | None,
) -> tuple[JointChannels, str, str]:
    """Read a message log into :class:`JointChannels` (module docstring).

    Returns:
        ``(channels, format, time_source)``; format ``mcap-ros2``, ``mcap-ros1`` or
        ``mcap-json`` for MCAP (by the state topic's encoding), else the source's kind
        (``rosbag2``, ``rosbag1``).

    Raises:
        LogFormatError: topics missing or unusable, messages that do not decode or lack
            joints, times that cannot be repaired.
        ChannelMapError: a map that does not fit the log (fields, types, joints).
    """
    where = src.where
    if time_source is not None and time_source not in TIME_SOURCES:
        raise LogFormatError(f"{where}: unknown time source {time_source!r} (log, publish, header)")
    topics = src.topics()
    mapname = "" if cmap is None else (cmap.path or cmap.name)
    if cmap is not None and cmap.format != "messages":
        kind_txt = {"csv": "CSV files", "npz": ".npz archives"}.get(cmap.format or "",
                                                                    "CSV files or .npz archives")
        raise ChannelMapError(f"{where}: channel map {mapname} is for {kind_txt}; a map for "
                              "MCAP or ROS bags says 'format: messages' and names fields")
    fields = _map_fields(src, cmap, topics) if cmap is not None else []
    mapped = {f.signal for f in fields}
    pos_fields = [f for f in fields if f.signal == "position"]
    held: list[_Held] = []
    state_cols: list[tuple[str, int, np.ndarray]] = []
    ignored: list[str] = []
    missing: dict[str, list[str]] = {}
    repairs = list(src.repairs)
    if pos_fields:
        assert cmap is not None
        if len(pos_fields) != len(cmap.joints):
            have = {f.joint for f in pos_fields}
            j = next(cmap.joints[k] for k in range(len(cmap.joints)) if k not in have)
            raise ChannelMapError(f"{where}: channel map {mapname}: joint {j!r} has no position "
                                  "field while others have: name every joint's position")
        ptopics = sorted({f.path.topic for f in pos_fields})
        if len(ptopics) > 1:
            raise ChannelMapError(f"{where}: channel map {mapname}: the position fields are on "
                                  f"several topics ({', '.join(ptopics)}); they must share one")
        state_topic = ptopics[0]
        if topic is not None and topic != state_topic:
            raise LogFormatError(f"{where}: --topic {topic!r} differs from the topic of the "
                                 f"channel map's position fields ({state_topic!r})")
        if reference_topic is not None:
            raise LogFormatError(f"{where}: --reference-topic does not apply when the channel "
                                 "map names the positions; name position_ref in the map")
        joints = cmap.joints
        td = src.load([state_topic])[state_topic]
        if td.n == 0:
            raise LogFormatError(f"{where}: topic {state_topic!r} holds no messages")
        state_cols, header = _field_columns(
            src, td, [f for f in fields if f.path.topic == state_topic], mapname)
        stimes = _Times(td.log_time, td.publish_time, header)
        kind = {"cdr": "ros2", "ros1": "ros1"}.get(td.encoding, "json")
    else:
        state_topic, kind = pick_state_topic(topics, topic, where)
        td = src.load([state_topic])[state_topic]
        arr = _joint_arrays(src, td, kind)
        if cmap is not None:
            joints = cmap.joints
            absent = [j for j in joints if j not in arr.joints]
            if absent:
                raise ChannelMapError(
                    f"{where}: channel map {mapname}: joint {absent[0]!r} is not in name[] of "
                    f"{state_topic!r} (names: {', '.join(arr.joints)})"
                )
            if kind != "json" and set(joints) != set(arr.joints):
                arr = _joint_arrays(src, td, kind, joints)
        else:
            joints = arr.joints
        jidx = [arr.joints.index(j) for j in joints]
        stimes = _Times(arr.log_time, arr.publish_time, arr.header)  # JSON: stamp_ns or 0
        if not arr.has_joints.all():
            k = int(np.argmax(~arr.has_joints))
            raise LogFormatError(
                f"{where}: topic {state_topic!r}, message {k} lacks some of the joints "
                f"{', '.join(joints)}"
            )
        vals, has = joint_signals(arr)
        used: list[str] = []
        for s in SIGNALS:
            if s not in has or s in mapped:
                continue
            h = has[s]
            if h.all():
                used.append(s)
            elif h.any():
                if s in ("position", "torque"):
                    k = int(np.argmax(~h))
                    what = "effort (torque)" if s == "torque" and kind != "json" else s
                    raise LogFormatError(f"{where}: topic {state_topic!r}, message {k} has no "
                                         f"{what}")
                ignored.append(f"{state_topic}:{s} (not in every message)")
        if "position" not in used:
            raise LogFormatError(f"{where}: topic {state_topic!r} carries no joint positions")
        for s in used:
            for c, jx in enumerate(jidx):
                state_cols.append((s, c, vals[s][:, jx]))
        ignored += [f"{state_topic}:{nm}" for nm in sorted(arr.extra_names)]
        ignored += [f"{state_topic}:{nm}" for nm in arr.joints if nm not in joints]
        on_state = [f for f in fields if f.path.topic == state_topic]
        if on_state:
            state_cols += _field_columns(src, td, on_state, mapname)[0]
        if kind in ("ros2", "ros1"):
            held += _companions(src, topics, state_topic, reference_topic, joints, mapped)
        elif reference_topic is not None:
            raise LogFormatError(
                f"{where}: --reference-topic applies to ROS JointState; JSON samples carry "
                "their reference in each message"
            )
    # field topics other than the state topic
    by_topic: dict[str, list[_MapField]] = {}
    for f in fields:
        if f.path.topic != state_topic:
            by_topic.setdefault(f.path.topic, []).append(f)
    loaded = src.load(list(by_topic)) if by_topic else {}
    for t, fl in by_topic.items():
        ftd = loaded[t]
        if ftd.n == 0:
            raise LogFormatError(f"{where}: topic {t!r} (channel map {mapname}) holds no messages")
        cols, header = _field_columns(src, ftd, fl, mapname)
        held.append(_Held(t, "topic", _Times(ftd.log_time, ftd.publish_time, header), cols))
    used_topics = {state_topic} | {h.topic for h in held}
    ignored = [x for x in sorted(topics) if x not in used_topics] + ignored
    ch, tsrc = _assemble(where, state_topic, stimes, state_cols, held, joints, time_source,
                         ignored, repairs, missing, fields)
    fmt = f"mcap-{kind}" if src.kind == "mcap" else src.kind
    return ch, fmt, tsrc


def _companions(src: MessageSource, topics: dict[str, tuple[str, str]], state_topic: str,
                reference_topic: str | None, joints: tuple[str, ...],
                mapped: set[str]) -> list[_Held]:
    """The reference and controller topics of a JointState state topic (module docstring)."""
    where = src.where
    out: list[_Held] = []
    rtopic = reference_topic
    if rtopic is not None and ({"position_ref", "velocity_ref"} & mapped):
        raise LogFormatError(f"{where}: --reference-topic and the channel map's position_ref "
                             "both name the reference; give one")
    if rtopic is None and "position_ref" not in mapped:
        cand = f"{state_topic}_ref"
        if cand in topics and joint_kind(*topics[cand]) in ("ros2", "ros1"):
            rtopic = cand
    wanted: list[tuple[str, str, str]] = []  # (topic, role, kind)
    if rtopic is not None:
        if rtopic not in topics:
            raise LogFormatError(
                f"{where}: reference topic {rtopic!r} not found (topics: "
                f"{', '.join(sorted(topics))})"
            )
        rk = joint_kind(*topics[rtopic])
        if rk not in ("ros2", "ros1"):
            raise LogFormatError(f"{where}: reference topic {rtopic!r} is not a JointState topic")
        wanted.append((rtopic, "reference topic", rk))
    for suffix, _arr, sig in COMPANIONS:
        cand = f"{state_topic}{suffix}"
        if sig not in mapped and cand in topics:
            ck = joint_kind(*topics[cand])
            if ck in ("ros2", "ros1"):
                wanted.append((cand, f"{sig} topic", ck))
    loaded = src.load([w[0] for w in wanted]) if wanted else {}
    for t, role, k in wanted:
        arr = _joint_arrays(src, loaded[t], k, joints)
        h = _Held(t, role, _Times(arr.log_time, arr.publish_time, arr.header))
        if role == "reference topic":
            if not arr.has_joints.all():
                m = int(np.argmax(~arr.has_joints))
                raise LogFormatError(f"{where}: topic {t!r}, message {m} lacks some of the joints")
            if not arr.has_position.all():
                m = int(np.argmax(~arr.has_position))
                raise LogFormatError(f"{where}: topic {t!r}, message {m} has no position")
            if "position_ref" not in mapped:
                h.cols = [("position_ref", j, arr.position[:, j]) for j in range(len(joints))]
            if arr.has_velocity.all() and "velocity_ref" not in mapped:
                h.cols += [("velocity_ref", j, arr.velocity[:, j]) for j in range(len(joints))]
        else:
            # a joint no message names does not log the channel (_assemble: missing)
            sig = role.split()[0]
            h.cols = [(sig, j, arr.effort[:, j]) for j in range(len(joints))
                      if arr.joint_seen[j]]
        if not h.cols:
            continue
        out.append(h)
    return out


def _assemble(
    where: str, topic: str, stimes: _Times, state_cols: list[tuple[str, int, np.ndarray]],
    held: list[_Held], joints: tuple[str, ...], time_source: str | None, ignored: list[str],
    repairs: list[str], missing: dict[str, list[str]], fields: list[_MapField],
) -> tuple[JointChannels, str]:
    t, tsrc = _state_time(stimes, time_source, where, topic)
    sorted_already = bool(np.all(np.diff(t) >= 0))
    perm = np.arange(t.shape[0]) if sorted_already else np.argsort(t, kind="stable")
    t = t[perm]
    # sample-and-hold of every other topic: its latest message at or before each sample
    picks = []
    lead, lead_topic = 0, ""
    for h in held:
        tr = _held_time(h.times, tsrc)
        rp = np.argsort(tr, kind="stable")
        idx = np.searchsorted(tr[rp], t, side="right") - 1
        k = int(np.sum(idx < 0))
        if k == len(t):
            raise LogFormatError(f"{where}: {h.role} {h.topic!r} starts after the last state "
                                 "message")
        if k > lead:
            lead, lead_topic = k, h.topic
        picks.append((rp, idx))
    if lead:
        what = "reference " if any(h.topic == lead_topic and h.role == "reference topic"
                                   for h in held) else ""
        msg = (f"{where}: dropped the first {lead} state sample(s), recorded before the first "
               f"{what}message on {lead_topic!r}")
        warnings.warn(msg, ImpactWarning, stacklevel=4)
        repairs.append(msg)
    rows = perm[lead:]
    t = t[lead:]
    cols: list[tuple[str, int, np.ndarray]] = [(s, j, v[rows]) for s, j, v in state_cols]
    for h, (rp, idx) in zip(held, picks, strict=True):
        sel = rp[idx[lead:]]
        cols += [(s, j, v[sel]) for s, j, v in h.cols]
    names = [f"{joints[j]}.{s}" for s, j, _ in cols]
    mat = (np.column_stack([v for _, _, v in cols]).astype(np.float64, copy=False)
           if cols else np.empty((t.shape[0], 0)))

    def label(i: int) -> str:
        return f"message {int(rows[i])} of {topic!r}"

    t, mat, rep = repair_matrix(t, mat, names, where=where, time_name=f"{tsrc} time",
                                row_label=label)
    repairs += rep
    jn = len(joints)
    signals, lacking = stack_columns(mat, [(s, j) for s, j, _ in cols], joints)
    for s, lack in lacking.items():
        missing[s] = sorted(set(missing.get(s, [])) | set(lack), key=joints.index)
    for s in list(missing):
        if s not in signals and s in CONTROLLER_CHANNELS:
            del missing[s]
    current_scale = np.full(jn, np.nan)
    for f in fields:
        if f.signal == "current" and f.ref.scale is not None:
            current_scale[f.joint] = f.ref.scale
    ch = JointChannels(
        t_ns=t, joints=joints, signals=signals, missing=missing, current_scale=current_scale,
        ignored=ignored, repairs=repairs,
    )
    return ch, tsrc


def stack_columns(mat: np.ndarray, cols: list[tuple[str, int]], joints: tuple[str, ...]
                  ) -> tuple[dict[str, np.ndarray], dict[str, list[str]]]:
    """Repaired columns ``mat`` (n, C), column c being ``cols[c]`` = (signal, joint index),
    as signals (n, J) (NaN for the joints without the signal), and signal → the joints
    without it (only the signals some joint lacks)."""
    jn = len(joints)
    signals: dict[str, np.ndarray] = {}
    have: dict[str, set[int]] = {}
    for c, (s, j) in enumerate(cols):
        if s not in signals:
            signals[s] = np.full((mat.shape[0], jn), np.nan)
        signals[s][:, j] = mat[:, c]
        have.setdefault(s, set()).add(j)
    lacking = {s: [joints[j] for j in range(jn) if j not in have[s]] for s in signals}
    return signals, {s: lack for s, lack in lacking.items() if lack}
