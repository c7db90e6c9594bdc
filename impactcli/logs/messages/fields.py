"""Message fields named PlotJuggler-style (docs/formats.md, "Channel maps", last paragraph).

A field path is ``/topic/field/subfield[i]``: the longest topic of the log that prefixes the
path is the topic, the rest names a field of its message type, one ``/`` per level of
nesting, ``[i]`` (0-based) picking an element of an array or sequence (``/robot/poses[2]/x``).
A path that ends in an array *without* an index picks the element of a joint by name: the
array's struct must have a ``name`` string sequence beside it (``sensor_msgs/JointState``:
``/external_torque/effort`` with joint ``panda_joint4`` is ``effort[name.index(...)]``),
matched on every message.

Checks, each a :class:`~impactcli.errors.ChannelMapError` of one line naming the log, the
map and the path: no topic prefixes the path (the topics are listed), a field that is not in
the type (its fields are listed), an index past a fixed-size array, an index or joint on a
field that is not an array, an array without an index in a struct without ``name``, a field
that is not a number (a string, or a whole message). ROS types (CDR and ROS 1) are checked
against their definitions before any message is read; JSON messages on the first message
where the path does not fit. Indices past a sequence's length and joints missing from a
message's ``name[]`` are found while reading (a LogFormatError naming the message).

:func:`extract` reads every path of one topic with one decode per message
(:func:`impactcli.logs.messages.message_source.MessageSource.decode`); numbers are float64
(booleans 0/1, JSON null is NaN).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import ChannelMapError, LogFormatError

_STEP = re.compile(r"^([^/\[\]]+)(?:\[(\d+)\])?$")
#: rosbags base types that are numbers (``string`` and ``wstring`` are not)
NUMERIC_BASES = frozenset({
    "bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
    "uint64", "float32", "float64", "float128",
})
# rosbags.interfaces.Nodetype values (not imported: rosbags is imported lazily)
_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4


@dataclass(frozen=True)
class FieldPath:
    """A parsed field path.

    Attributes:
        text: the path as written (``/franka_states/q[3]``).
        topic: the topic it names.
        steps: (field name, index or None) per level below the message.
        joint: the joint picked by name from a ``name``-indexed array (None: by index or a
            scalar).
    """

    text: str
    topic: str
    steps: tuple[tuple[str, int | None], ...]
    joint: str | None = None

    def label(self) -> str:
        """The path for messages, with the joint when picked by name (``/t/effort[j4]``)."""
        return self.text if self.joint is None else f"{self.text}[{self.joint!r}]"

    def field(self) -> str:
        """The part below the topic (``q[3]``)."""
        return "/".join(n if i is None else f"{n}[{i}]" for n, i in self.steps)


def parse_field_path(text: str, topics: list[str], joint: str | None, where: str) -> FieldPath:
    """Split ``text`` into topic and field steps.

    Args:
        text: ``/topic/field/sub[i]``.
        topics: the log's topics.
        joint: joint name for a by-name pick (used only when the path ends in an array
            without an index; checked by :func:`check_ros_path`).
        where: ``"<log>: channel map <map>: <joint>.<signal>"`` for messages.

    Raises:
        ChannelMapError: no topic prefixes the path, it names only a topic, or a step is
            malformed.
    """
    cands = [t for t in topics if text.startswith(t.rstrip("/") + "/")]
    if not cands:
        listing = ", ".join(sorted(topics)) or "none"
        if text in topics:
            raise ChannelMapError(f"{where}: {text!r} is a topic; name a field of its "
                                  "messages (/topic/field)")
        raise ChannelMapError(f"{where}: field path {text!r} names no topic of the log "
                              f"(topics: {listing})")
    topic = max(cands, key=len)
    rest = text[len(topic.rstrip("/")) + 1:]
    steps: list[tuple[str, int | None]] = []
    for part in rest.split("/"):
        m = _STEP.match(part)
        if not m:
            raise ChannelMapError(f"{where}: field path {text!r}: cannot read {part!r} "
                                  "(expected field or field[i])")
        steps.append((m.group(1), None if m.group(2) is None else int(m.group(2))))
    return FieldPath(text, topic, tuple(steps), joint)


def _fields_of(fielddefs: dict[str, Any], typename: str) -> list[tuple[str, Any]]:
    return list(fielddefs[typename][1])


def check_ros_path(fp: FieldPath, msgtype: str, fielddefs: dict[str, Any],
                   where: str) -> FieldPath:
    """Check ``fp`` against a ROS message definition; returns it with ``joint`` kept only
    when the path ends in an array without an index (a pick by name).

    Raises:
        ChannelMapError: see the module docstring.
    """
    cur = msgtype
    keep_joint: str | None = None
    for k, (name, idx) in enumerate(fp.steps):
        last = k == len(fp.steps) - 1
        fields = _fields_of(fielddefs, cur)
        byname = dict(fields)
        sofar = "/".join(n for n, _ in fp.steps[: k + 1])
        if name not in byname:
            raise ChannelMapError(
                f"{where}: field {sofar!r} of {fp.text!r} does not exist in {cur} "
                f"(fields: {', '.join(n for n, _ in fields)})"
            )
        node, detail = byname[name]
        if node in (_ARRAY, _SEQUENCE):
            (elem_node, elem_detail), size = detail
            if idx is None:
                if not last:
                    raise ChannelMapError(f"{where}: field {sofar!r} of {fp.text!r} is an "
                                          f"array: give an index ({name}[0])")
                names = byname.get("name")
                is_names = (names is not None and names[0] == _SEQUENCE
                            and names[1][0][0] == _BASE and names[1][0][1][0] == "string")
                if not is_names:
                    what = f"an array of {size}" if node == _ARRAY else "a sequence"
                    raise ChannelMapError(
                        f"{where}: field {sofar!r} of {fp.text!r} is {what}: give an index "
                        f"({name}[0]); picking by joint name needs a 'name' string array "
                        f"beside it, which {cur} has not"
                    )
                if fp.joint is None:
                    raise ChannelMapError(f"{where}: field {sofar!r} of {fp.text!r} is an "
                                          "array: give an index or a joint")
                keep_joint = fp.joint
            elif node == _ARRAY and idx >= size:
                raise ChannelMapError(
                    f"{where}: index {idx} of {fp.text!r} is out of range: {name} has {size} "
                    f"elements (0–{size - 1})"
                )
            node, detail = elem_node, elem_detail
        elif idx is not None:
            raise ChannelMapError(f"{where}: field {sofar!r} of {fp.text!r} is not an array: "
                                  f"drop the index [{idx}]")
        if node == _NAME:
            if last:
                sub = ", ".join(n for n, _ in _fields_of(fielddefs, detail))
                raise ChannelMapError(f"{where}: field {sofar!r} of {fp.text!r} is a "
                                      f"{detail} message, not a number (its fields: {sub})")
            cur = detail
            continue
        base = detail[0]
        if not last:
            raise ChannelMapError(f"{where}: field {sofar!r} of {fp.text!r} is a {base}: it "
                                  "has no fields")
        if base not in NUMERIC_BASES:
            raise ChannelMapError(f"{where}: field {sofar!r} of {fp.text!r} is a {base}, "
                                  "not a number")
    return FieldPath(fp.text, fp.topic, fp.steps, keep_joint)


def _attr(obj: Any, name: str) -> Any:
    if isinstance(obj, dict):
        return obj[name]
    try:
        return getattr(obj, name)
    except AttributeError:
        return getattr(obj, name + "_")  # rosbags renames fields that are Python keywords


def _keys(obj: Any) -> str:
    if isinstance(obj, dict):
        return ", ".join(str(k) for k in obj)
    return ", ".join(getattr(obj, "__dataclass_fields__", {}) or dir(obj))


class _Miss(Exception):
    """A path does not fit one message: the text says why."""


def _value(msg: Any, fp: FieldPath) -> float:
    cur = msg
    for k, (name, idx) in enumerate(fp.steps):
        last = k == len(fp.steps) - 1
        try:
            parent, cur = cur, _attr(cur, name)
        except (KeyError, AttributeError, TypeError):
            sofar = "/".join(n for n, _ in fp.steps[: k + 1])
            have = _keys(cur) if isinstance(cur, dict) else ""
            raise _Miss(f"has no field {sofar!r}" + (f" (fields: {have})" if have else "")
                        ) from None
        if idx is not None:
            try:
                n = len(cur)
            except TypeError:
                raise _Miss(f"field {name!r} is not an array") from None
            if idx >= n:
                raise _Miss(f"index {idx} of {name!r} is out of range ({n} elements)")
            cur = cur[idx]
        elif last and fp.joint is not None and isinstance(cur, list | tuple | np.ndarray):
            try:
                names = list(_attr(parent, "name"))
            except (KeyError, AttributeError, TypeError):
                raise _Miss(f"field {name!r} has no 'name' array beside it") from None
            if fp.joint not in names:
                raise _Miss(f"joint {fp.joint!r} is not in name[] "
                            f"(names: {', '.join(map(str, names))})")
            k2 = names.index(fp.joint)
            if k2 >= len(cur):
                raise _Miss(f"{name!r} has {len(cur)} values for {len(names)} names")
            cur = cur[k2]
    if cur is None:
        return float("nan")
    if isinstance(cur, bool | int | float | np.number | np.bool_):
        return float(cur)
    if isinstance(cur, list | tuple | np.ndarray):
        raise _Miss(f"{fp.field()!r} is an array: give an index or a joint")
    raise _Miss(f"{fp.field()!r} is not a number ({type(cur).__name__})")


def extract(msgs: list[Any], paths: list[FieldPath], where: str,
            miss_is_error: bool = True, index: np.ndarray | None = None) -> np.ndarray:
    """Values of ``paths`` (all on one topic) in decoded messages ``msgs``.

    Args:
        msgs: decoded messages of the topic, in file order.
        paths: field paths on that topic.
        where: ``<log>`` for messages.
        miss_is_error: a path that does not fit a message raises (else NaN there).
        index: (n,) the messages' numbers in the topic, for errors (default 0..n-1).

    Returns:
        (n, len(paths)) float64.

    Raises:
        LogFormatError: a path that does not fit message k (index past a sequence's end,
            joint not in its name[], not a number), naming the message.
        ChannelMapError: the first message already does not fit (the map is wrong for
            this log: a JSON field that does not exist, a joint no message names).
    """
    out = np.full((len(msgs), len(paths)), np.nan)
    for c, fp in enumerate(paths):
        for i, m in enumerate(msgs):
            try:
                out[i, c] = _value(m, fp)
            except _Miss as err:
                if not miss_is_error:
                    continue
                num = i if index is None else int(index[i])
                err_cls = ChannelMapError if num == 0 else LogFormatError
                raise err_cls(f"{where}: field path {fp.text}: message {num} on "
                              f"{fp.topic!r}: {err}") from None
    return out
