"""Ground-truth labels from a logged switch or force channel (``impactcli labels``;
docs/formats.md, "Ground-truth labels").

The channel is read through the log's own reader, whatever the log's channels make of it:
``<joint>.<signal>`` of a joint the log has (its values after the map's scale and offset);
a CSV column by name (one the reader ignores) or, headerless, by 0-based index, read with
the log's time column and repairs; an ``.npz`` array (``key`` or ``key[i]``) with the map's
time; in an MCAP file or a ROS bag, a message field ``/topic/field/sub[i]`` or
``/topic/array[joint]`` (:mod:`impactcli.logs.messages.fields`), stamped as the log's samples are.

Contiguous stretches where the channel is above X become contacts (``start``/``end`` the
first and last sample above, seconds since the log's first sample), merged when closer
than ``merge_gap_s``, dropped when shorter than ``min_duration_s``. ``peak_force`` is the
channel's peak for a force; a *switch* (two values, or ``channel_is="switch"``) knows no
force (``peak_force`` 0, ``peak_force_known`` false). :func:`make_labels` reads the log and
the channel and returns the validated labels.
"""

from __future__ import annotations

import dataclasses
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImpactWarning, LabelsError, LogFormatError
from ..sample_channels import CHANNEL_NAMES
from ..types import ReadOptions
from .paths import MESSAGE_SUFFIXES, log_stem

#: Tolerance of time comparisons [s] (sample times are float sums of periods).
EPS_S = 1e-9
_JOINT_PICK = re.compile(r"^(?P<path>.*)\[(?P<joint>[^\]]*[^\]\d][^\]]*)\]$")
_NPZ_COLUMN = re.compile(r"^(?P<key>.+)\[(?P<index>\d+)\]$")


@dataclass(frozen=True)
class Channel:
    """A channel read for labelling.

    Attributes:
        name: as given. what: how it was found (for the record).
        t_s: (n,) seconds since the log's first sample, increasing.
        values: (n,) float64 (NaN where not logged).
    """

    name: str
    what: str
    t_s: np.ndarray
    values: np.ndarray


def read_channel(path: Path, name: str, log: Any, read_options: ReadOptions) -> Channel:
    """The channel ``name`` of the log at ``path`` (module docstring), timed on ``log``'s
    clock (``log`` is the log as :func:`impactcli.logs.read_log` reads it).

    Raises:
        LogFormatError: no such channel (one line naming the file and listing what it has),
            or a channel that cannot be read.
    """
    joint, dot, sig = name.partition(".")
    if dot and joint in log.joint_names and sig in CHANNEL_NAMES:
        arr = getattr(log, sig)
        j = log.joint_names.index(joint)
        if arr is None or not bool(log.has_channel(sig)[j]):
            raise LogFormatError(f"{path}: joint {joint!r} does not log {sig!r}")
        return Channel(name, f"the log's {name} (through its reader and channel map)",
                       np.asarray(log.time_s, dtype=np.float64),
                       np.asarray(arr[:, j], dtype=np.float64))
    lower = path.name.lower()
    if path.is_dir() or lower.endswith(MESSAGE_SUFFIXES):
        return _message_channel(path, name, log)
    if lower.endswith(".npz"):
        return _npz_channel(path, name, log, read_options)
    if lower.endswith((".csv", ".csv.gz")):
        return _csv_channel(path, name, log, read_options)
    raise LogFormatError(f"{path}: cannot read channels of this format ({log_stem(path)})")


def _relative(t_ns: np.ndarray, log: Any) -> np.ndarray:
    return np.asarray((np.asarray(t_ns, dtype=np.int64) - int(log.t0_ns)) / 1e9)


def _joint_channels_hint(log: Any) -> str:
    have = [f"{j}.{s}" for s in CHANNEL_NAMES if getattr(log, s) is not None
            for j, ok in zip(log.joint_names, log.has_channel(s), strict=True) if ok]
    return ", ".join(have)


def _locating(ropts: ReadOptions) -> dict[str, Any]:
    """The read options that locate a channel's columns and time (not the repairs and the
    unit the log's own samples are read with)."""
    return dataclasses.replace(ropts, repair_order=False, position_unit=None).as_dict()


def _csv_channel(path: Path, name: str, log: Any, ropts: ReadOptions) -> Channel:
    """A CSV column, read by the CSV reader with the log's own time (its layout as the log
    was read: separator, header, time column and unit, or ``--rate``)."""
    from .channel_map import ChannelMap, ChannelRef
    from .csv.csv_layout import csv_layout
    from .paths import open_log_options
    from .reader import read_columns

    opts = _locating(ropts)
    _p, _where, _suffix, _folder, cmap = open_log_options(path, **opts)
    canonical = cmap is None
    lay = csv_layout(path, cmap, time_unit=opts.get("time_unit") if canonical else None,
                     time_column=opts.get("time_column") if canonical else None,
                     rate=ropts.rate)
    header = lay.header
    names = lay.names if header else [str(i) for i in range(len(lay.names))]
    source: str | int
    if header and name in names:
        source = name
    elif name.isdigit() and int(name) < len(names):
        source = int(name)
    else:
        what = "columns" if header else f"columns 0–{len(names) - 1} (no header)"
        hint = _joint_channels_hint(log) if not canonical else ""
        raise LogFormatError(f"{path}: no channel {name!r}: its {what}: {', '.join(names)}"
                             + (f"; the map's joint channels: {hint}" if hint else ""))
    one = ChannelMap(
        name=f"--from-channel {name}", time=lay.tspec, joints=("channel",),
        signals={"position": (ChannelRef(source),)}, path=cmap.path if cmap else "",
        format="csv", header=header, delimiter=lay.delim, skip_rows=lay.skip,
    )
    read = {"channel_map": one, "repair_order": ropts.repair_order}
    if ropts.rate is not None:
        read["rate"] = ropts.rate
    with warnings.catch_warnings():
        # the log's own repairs were warned about when it was read
        warnings.simplefilter("ignore", ImpactWarning)
        t_ns, values = read_columns(path, read)
    col = name if isinstance(source, str) else f"column {source}"
    return Channel(name, f"CSV {col}", _relative(t_ns, log),
                   np.asarray(values[:, 0], dtype=np.float64))


def _npz_channel(path: Path, name: str, log: Any, ropts: ReadOptions) -> Channel:
    """An ``.npz`` array (``key`` or ``key[i]``) with the channel map's time (with
    ``--time-unit`` / ``--time-column`` applied), or ``--rate``'s."""
    from .channel_map import ChannelMap, ChannelRef
    from .paths import open_log_options
    from .reader import read_columns

    cmap = open_log_options(path, **_locating(ropts))[4] if ropts.channel_map else None
    if cmap is None:
        raise LogFormatError(f"{path}: an .npz log needs a channel map (--channel-map)")
    with np.load(path, allow_pickle=False) as archive:
        keys = list(archive.files)
    m = _NPZ_COLUMN.match(name)
    key, index = (m.group("key"), int(m.group("index"))) if m and name not in keys else (name,
                                                                                         None)
    if key not in keys:
        raise LogFormatError(
            f"{path}: no channel {name!r}: its arrays: {', '.join(keys)}"
            + (f"; joint channels: {hint}" if (hint := _joint_channels_hint(log)) else ""))
    one = ChannelMap(name=f"--from-channel {name}", time=cmap.time, joints=("channel",),
                     signals={"position": (ChannelRef(key, index=index),)}, path=cmap.path,
                     format="npz")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        t_ns, values = read_columns(path, {"channel_map": one, **(
            {"rate": ropts.rate} if ropts.rate is not None else {})},
            check_rate=False)
    return Channel(name, f"array {name}", _relative(t_ns, log),
                   np.asarray(values[:, 0], dtype=np.float64))


def _message_channel(path: Path, name: str, log: Any) -> Channel:
    """A message field, stamped like the log's samples, through the message reader."""
    from .messages.message_plan import field_channel

    text, joint = name, None
    m = _JOINT_PICK.match(name)
    if m:
        text, joint = m.group("path"), m.group("joint")
    tsrc = log.source.time_source
    t_ns, values, label = field_channel(path, name, text, joint, tsrc,
                                        _joint_channels_hint(log))
    return Channel(name, f"field {label} ({tsrc} time)", _relative(t_ns, log),
                   np.asarray(values, dtype=np.float64))


def stretches(t_s: np.ndarray, values: np.ndarray, above: float, *, merge_gap_s: float = 0.0,
              min_duration_s: float = 0.0) -> list[tuple[int, int]]:
    """``(first, last)`` sample indices (inclusive) of the stretches where ``values`` is
    above ``above`` (NaN is not): stretches whose gap (from one's last sample to the next's
    first) is at most ``merge_gap_s`` merged, those shorter than ``min_duration_s``
    (last − first) dropped."""
    with np.errstate(invalid="ignore"):
        on = np.isfinite(values) & (values > above)
    x = np.diff(on.astype(np.int8), prepend=np.int8(0), append=np.int8(0))
    starts = np.flatnonzero(x == 1).tolist()
    ends = (np.flatnonzero(x == -1) - 1).tolist()
    merged: list[tuple[int, int]] = []
    for a, b in zip(starts, ends, strict=True):
        if merged and t_s[a] - t_s[merged[-1][1]] <= merge_gap_s + EPS_S:
            merged[-1] = (merged[-1][0], b)
        else:
            merged.append((a, b))
    return [(a, b) for a, b in merged if t_s[b] - t_s[a] >= min_duration_s - EPS_S]


def channel_kind(values: np.ndarray) -> str:
    """``switch`` for a channel with at most two distinct finite values, else ``force``."""
    finite = values[np.isfinite(values)]
    return "switch" if np.unique(finite).size <= 2 else "force"


def labels_doc(ch: Channel, *, above: float, kind: str, link: int, channel_is: str,
               merge_gap_s: float, min_duration_s: float, sample_rate: float,
               log_path: str) -> dict[str, Any]:
    """The labels mapping (docs/formats.md) of the stretches of ``ch`` above ``above``."""
    resolved = channel_kind(ch.values) if channel_is == "auto" else channel_is
    events = []
    for a, b in stretches(ch.t_s, ch.values, above, merge_gap_s=merge_gap_s,
                          min_duration_s=min_duration_s):
        peak = float(np.nanmax(ch.values[a : b + 1]))
        ev: dict[str, Any] = {
            "start": round(float(ch.t_s[a]), 9), "end": round(float(ch.t_s[b]), 9),
            "peak_force": max(peak, 0.0) if resolved == "force" else 0.0,
            "kind": kind, "link": link, "peak_value": peak,
        }
        if resolved == "switch":
            ev["peak_force_known"] = False
        events.append(ev)
    return {
        "schema_version": "1.0",
        "sample_rate": float(sample_rate),
        "events": events,
        "source": {
            "tool": "impactcli labels", "log": log_path, "channel": ch.name,
            "read_as": ch.what, "channel_kind": resolved, "above": above,
            "merge_gap_s": merge_gap_s, "min_duration_s": min_duration_s,
            "peak_force": ("the channel's peak in each stretch [N]" if resolved == "force"
                           else "unknown: a switch says when, not how hard (peak_force 0, "
                                "peak_force_known false; peak_value is the switch's value)"),
        },
    }


def make_labels(log: Path, channel: str, *, above: float, kind: str, link: int,
                channel_is: str, merge_gap_s: float, min_duration_s: float,
                robot: Any, read_options: ReadOptions, output: Path
                ) -> tuple[dict[str, Any], Any, Channel]:
    """(the labels mapping, the :class:`~impactcli.types.Labels` it reads back as, the
    channel) for the stretches of ``channel`` above ``above`` in the log ``log`` (read with
    ``robot`` and ``read_options``); validated as ``output`` will be written. Warns when the
    channel is never above ``above``.

    Raises:
        LogFormatError: the log or the channel cannot be read, or the channel is empty.
    """
    from ..schema import validate
    from . import read_log
    from .robot_files import labels_from_dict

    data = read_log(log, robot=robot, **read_options.as_dict())
    ch = read_channel(log, channel, data, read_options)
    if ch.t_s.size == 0:
        raise LogFormatError(f"{log}: channel {channel!r} holds no samples")
    doc = labels_doc(ch, above=above, kind=kind, link=link, channel_is=channel_is,
                     merge_gap_s=merge_gap_s, min_duration_s=min_duration_s,
                     sample_rate=data.sample_rate_hz, log_path=str(log))
    validate(doc, "labels", LabelsError, str(output))
    labels = labels_from_dict(doc, str(output))  # the checks evaluate makes (end >= start)
    if not doc["events"]:
        finite = ch.values[np.isfinite(ch.values)]
        top = f"{float(finite.max()):.4g}" if finite.size else "no finite value"
        warnings.warn(f"{log}: {channel} is never above {above:g} (its largest value: {top}): "
                      "the labels hold no contact", ImpactWarning, stacklevel=3)
    return doc, labels, ch
