"""Channel maps (docs/formats.md, "Channel maps"): reading foreign CSV layouts and .npz files.

A channel map is a JSON or YAML file validated by ``schemas/channel_map.schema.json``. It
names the time channel (with its unit and epoch handling) and, per joint, where each signal
lives — a CSV column by name or 0-based index, or an ``.npz`` array key (with a column index
for 2-D arrays) — with an optional ``scale`` and ``offset`` (value = raw × scale + offset).

A map with ``format: messages`` is for MCAP files and ROS bags: it has no ``time`` (samples
are the state topic's messages, stamped by ``--time-source``) and its signals are message
fields, PlotJuggler-style: a bare string ``/topic/field/sub[i]`` or
``{field: /topic/field, joint: NAME, scale: ..., offset: ...}`` where ``joint`` picks a
JointState-like array by joint name (default: the map's joint name). ``position`` is optional
per joint: without it the positions come from the JointState state topic
(:mod:`impactcli.logs.messages.message_read`, :mod:`impactcli.logs.messages.fields`).

A ``current`` signal *with* a ``scale`` in the map is converted to torque by that scale
(N·m per logged unit: gear ratio × torque constant × any unit factor); a ``current`` without
a scale is converted with the robot description's gear ratio × torque constant.

Maps shipped in ``impactcli/data/channel_maps/`` can be named by their short name
(``ur_ext_observer``, ``kuka_lwr4``; the message examples ``franka_state_example`` and
``jointstate_external_torque_example``) instead of a path. In YAML, a field path with
``[i]`` inside ``{...}`` must be quoted (``{field: "/t/q[0]"}``): the parse error says so.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from ..errors import ChannelMapError
from ..files import load_mapping
from ..sample_channels import CHANNEL_NAMES

#: Time units and their size in ns.
TIME_UNITS: dict[str, int] = {"s": 10**9, "ms": 10**6, "us": 10**3, "ns": 1}


@dataclass(frozen=True)
class ChannelRef:
    """Where one signal of one joint lives.

    Attributes:
        source: CSV column name (str) or 0-based index (int), ``.npz`` array key, or a
            message field path (``/topic/field[i]``, when ``is_field``).
        index: column within a 2-D ``.npz`` array (``None`` for 1-D arrays and CSV).
        scale: multiplier applied to the raw values (``None``: not given, i.e. 1 except
            for ``current`` where the robot description's factor is used).
        offset: added after scaling, in the signal's unit.
        is_field: ``source`` is a message field path (maps with ``format: messages``).
        joint: for a field path ending in a JointState-like array: the joint whose element
            is picked by ``name[]`` (``None``: the map's joint name).
    """

    source: str | int
    index: int | None = None
    scale: float | None = None
    offset: float = 0.0
    is_field: bool = False
    joint: str | None = None

    def label(self) -> str:
        """Human name of the channel for messages (``column 3``, ``'a.b'``, ``positions[:, 2]``)."""
        if self.is_field:
            return str(self.source) if self.joint is None else f"{self.source}[{self.joint!r}]"
        if self.index is not None:
            return f"{self.source}[:, {self.index}]"
        if isinstance(self.source, int):
            return f"column {self.source}"
        return str(self.source)


@dataclass(frozen=True)
class TimeSpec:
    """The time channel: where it is, its unit, and epoch handling.

    Attributes:
        ref: the channel (scale is not used; use ``unit``).
        unit: ``s``, ``ms``, ``us`` or ``ns``.
        offset: added to the time, in ``unit`` (e.g. to move a controller clock to an epoch).
        start_at_zero: subtract the first sample's time (t0 becomes 0).
    """

    ref: ChannelRef
    unit: str = "s"
    offset: float = 0.0
    start_at_zero: bool = False


@dataclass(frozen=True)
class ChannelMap:
    """A validated channel map.

    Attributes:
        name: short name of the map.
        path: file it was read from ("" if made in code).
        format: ``csv``, ``npz`` or ``messages`` (MCAP and ROS bags; ``None``: decided by
            the log's suffix, CSV or .npz).
        header: whether the CSV has a header line.
        delimiter: CSV delimiter (None: detected,
            :func:`impactcli.logs.csv.csv_header.mapped_separator`).
        skip_rows: lines to skip before the header (or first data line).
        time: the time channel (``None`` for ``messages`` maps: the state topic's times).
        joints: joint names, in order.
        signals: signal → per-joint :class:`ChannelRef` (or ``None`` where absent).
    """

    name: str
    time: TimeSpec | None
    joints: tuple[str, ...]
    signals: dict[str, tuple[ChannelRef | None, ...]] = field(default_factory=dict)
    path: str = ""
    format: str | None = None
    header: bool = True
    delimiter: str | None = None
    skip_rows: int = 0

    def refs(self) -> list[tuple[str, int, ChannelRef]]:
        """All (signal, joint index, ref) triples."""
        return [
            (sig, j, r)
            for sig, per in self.signals.items()
            for j, r in enumerate(per)
            if r is not None
        ]


def require_time(cmap: ChannelMap, where: str) -> TimeSpec:
    """The map's time channel; ChannelMapError for a map without one (a ``messages`` map
    given for a CSV or .npz log)."""
    if cmap.time is None:
        raise ChannelMapError(
            f"{where}: channel map {cmap.path or cmap.name} has no time channel"
            + (" (it is for MCAP files and ROS bags: format: messages)"
               if cmap.format == "messages" else
               ": give --rate HZ for a log without one, or --time-column NAME")
        )
    return cmap.time


def shipped_maps_dir() -> Path:
    """Folder of the channel maps shipped with impactcli."""
    return Path(str(resources.files("impactcli") / "data" / "channel_maps"))


def shipped_map_names() -> list[str]:
    """Short names of the shipped channel maps."""
    d = shipped_maps_dir()
    if not d.is_dir():
        return []
    return sorted(p.stem for p in d.iterdir() if p.suffix in (".yaml", ".yml", ".json"))


def resolve_channel_map_path(spec: str | os.PathLike[str]) -> Path:
    """A channel map path: ``spec`` itself when it is a file, else a shipped map's short name."""
    p = Path(spec)
    if p.is_file():
        return p
    d = shipped_maps_dir()
    for ext in (".yaml", ".yml", ".json"):
        cand = d / f"{spec}{ext}"
        if cand.is_file():
            return cand
    names = ", ".join(shipped_map_names()) or "none"
    raise ChannelMapError(
        f"{spec}: channel map not found (neither a file nor a shipped map; shipped: {names})"
    )


def _ref(raw: Any, where: str, what: str, messages: bool = False) -> ChannelRef:
    if isinstance(raw, bool):
        raise ChannelMapError(f"{where}: {what}: expected a column or key, got {raw!r}")
    if messages:
        if isinstance(raw, str):
            raw = {"field": raw}
        if not isinstance(raw, dict) or "field" not in raw:
            raise ChannelMapError(f"{where}: {what}: a 'format: messages' map names message "
                                  f"fields (/topic/field or {{field: ...}}), got {raw!r}")
    if isinstance(raw, int | str):
        return ChannelRef(source=raw)
    if not isinstance(raw, dict):
        raise ChannelMapError(f"{where}: {what}: expected a column or key, got {raw!r}")
    scale = raw.get("scale")
    if "field" in raw:
        if not messages:
            raise ChannelMapError(f"{where}: {what}: a message field needs 'format: messages'")
        path = str(raw["field"])
        if not path.startswith("/"):
            raise ChannelMapError(f"{where}: {what}: field path {path!r} must start with "
                                  "/topic")
        return ChannelRef(source=path, scale=None if scale is None else float(scale),
                          offset=float(raw.get("offset", 0.0)), is_field=True,
                          joint=raw.get("joint"))
    if ("column" in raw) == ("key" in raw):
        raise ChannelMapError(f"{where}: {what}: give exactly one of 'column' or 'key'")
    src = raw["column"] if "column" in raw else raw["key"]
    return ChannelRef(
        source=src,
        index=raw.get("index"),
        scale=None if scale is None else float(scale),
        offset=float(raw.get("offset", 0.0)),
    )


def _explain_kind(d: dict[str, Any], where: str) -> None:
    """Clear one-line errors for maps that mix the message kind with the column kind (the
    schema says the same less readably)."""
    messages = d.get("format") == "messages"
    for key in ("time", "csv"):
        if messages and key in d:
            raise ChannelMapError(
                f"{where}: a 'format: messages' map has no '{key}': its samples are the state "
                "topic's messages, stamped by --time-source"
            )
    joints = d.get("joints")
    for i, jd in enumerate(joints if isinstance(joints, list) else []):
        for s in CHANNEL_NAMES:
            v = jd.get(s) if isinstance(jd, dict) else None
            if messages and ((isinstance(v, dict) and "field" not in v) or isinstance(v, int)):
                raise ChannelMapError(
                    f"{where}: joints[{i}].{s}: a 'format: messages' map names message fields "
                    f"(/topic/field or {{field: ...}}), got {v!r}"
                )
            if not messages and isinstance(v, dict) and "field" in v:
                raise ChannelMapError(
                    f"{where}: joints[{i}].{s}: a message field needs 'format: messages' "
                    "(such maps are for MCAP logs and ROS bags)"
                )


def channel_map_from_dict(d: dict[str, Any], where: str = "channel map") -> ChannelMap:
    """Build a :class:`ChannelMap` from its mapping form (validated against the schema)."""
    from ..schema import validate

    _explain_kind(d, where)
    validate(d, "channel_map", ChannelMapError, where)
    csv_opts = d.get("csv", {})
    messages = d.get("format") == "messages"
    t = d.get("time")
    time = None if t is None else TimeSpec(
        ref=_ref(t, where, "time"),
        unit=t.get("unit", "s") if isinstance(t, dict) else "s",
        offset=float(t.get("offset", 0.0)) if isinstance(t, dict) else 0.0,
        start_at_zero=bool(t.get("start_at_zero", False)) if isinstance(t, dict) else False,
    )
    joints: list[str] = []
    per_signal: dict[str, list[ChannelRef | None]] = {s: [] for s in CHANNEL_NAMES}
    for i, jd in enumerate(d["joints"]):
        joints.append(jd["name"])
        for s in CHANNEL_NAMES:
            per_signal[s].append(
                _ref(jd[s], where, f"joints[{i}].{s}", messages) if s in jd else None
            )
    if len(set(joints)) != len(joints):
        raise ChannelMapError(f"{where}: duplicate joint names {joints}")
    signals = {s: tuple(v) for s, v in per_signal.items() if any(r is not None for r in v)}
    return ChannelMap(
        name=str(d.get("name", Path(where).stem)),
        time=time,
        joints=tuple(joints),
        signals=signals,
        path=where,
        format=d.get("format"),
        header=bool(csv_opts.get("header", True)),
        delimiter=(None if csv_opts.get("delimiter") is None
                   else str(csv_opts["delimiter"])),
        skip_rows=int(csv_opts.get("skip_rows", 0)),
    )


def load_channel_map(spec: str | os.PathLike[str] | ChannelMap) -> ChannelMap:
    """Load a channel map from a JSON/YAML path or a shipped map's short name.

    Raises:
        ChannelMapError: not found, does not parse, or does not match the schema.
    """
    if isinstance(spec, ChannelMap):
        return spec
    p = resolve_channel_map_path(spec)
    try:
        d = load_mapping(p, ChannelMapError, "channel map")
    except ChannelMapError as err:
        if "does not parse" in str(err) and "flow" in str(err):
            # '{position: /t/q[0]}': YAML reads '[' inside {...} as the start of a list
            raise ChannelMapError(
                f"{err}; in YAML, quote a field path with [i] inside {{...}}: "
                "{position: '/topic/q[0]'}"
            ) from err.__cause__
        raise
    return channel_map_from_dict(d, str(p))
