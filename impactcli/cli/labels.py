"""``impactcli labels LOG --from-channel NAME --above X --link N -o labels.json``: ground-truth
labels from a logged switch or force sensor (docs/formats.md, "Ground-truth labels").

The channel is read through the log's own reader, whatever the log's channels make of it:
``<joint>.<signal>`` of a joint the log has (its values after the map's scale and offset);
a CSV column by name (one the reader ignores) or, headerless, by 0-based index, read with
the log's time column and repairs; an ``.npz`` array (``key`` or ``key[i]``) with the map's
time; in an MCAP file or a ROS bag, a message field ``/topic/field/sub[i]`` or
``/topic/array[joint]`` (:mod:`impactcli.logs.fields`), stamped as the log's samples are.

Contiguous stretches where the channel is above X become contacts (``start``/``end`` the
first and last sample above, seconds since the log's first sample), merged when closer
than ``--merge-gap``, dropped when shorter than ``--min-duration``. ``peak_force`` is the
channel's peak for a force; a *switch* (two values, or ``--channel-kind switch``) knows no
force (``peak_force`` 0, ``peak_force_known`` false). ``--link`` is required: a label names
the link touched (1-based). The file (schemas/labels.schema.json, validated) is written
atomically with its ``source``. Exit 0; 2 bad options; 3 a log or channel that cannot be
read (one line naming the file and what it has).
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click
import numpy as np

from ..errors import ImpactWarning, LogFormatError
from .options import (
    ROBOT_METAVAR,
    check_log_path,
    handle_errors,
    log_read_options,
    read_options_from,
    robot_help,
)

#: How a channel's contacts are labelled.
CHANNEL_KINDS: tuple[str, ...] = ("auto", "force", "switch")
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


def read_channel(path: Path, name: str, log: Any, read_options: dict[str, Any]) -> Channel:
    """The channel ``name`` of the log at ``path`` (module docstring), timed on ``log``'s
    clock (``log`` is the log as :func:`impactcli.logs.read_log` reads it).

    Raises:
        LogFormatError: no such channel (one line naming the file and listing what it has),
            or a channel that cannot be read.
    """
    from ..logs.channel_map import SIGNALS

    joint, dot, sig = name.partition(".")
    if dot and joint in log.joint_names and sig in SIGNALS:
        arr = getattr(log, sig)
        j = log.joint_names.index(joint)
        if arr is None or not bool(log.has_channel(sig)[j]):
            raise LogFormatError(f"{path}: joint {joint!r} does not log {sig!r}")
        return Channel(name, f"the log's {name} (through its reader and channel map)",
                       np.asarray(log.time_s, dtype=np.float64),
                       np.asarray(arr[:, j], dtype=np.float64))
    from ..logs import MESSAGE_SUFFIXES, log_stem

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
    from ..logs.channel_map import SIGNALS

    have = [f"{j}.{s}" for s in SIGNALS if getattr(log, s) is not None
            for j, ok in zip(log.joint_names, log.has_channel(s), strict=True) if ok]
    return ", ".join(have)


def _csv_channel(path: Path, name: str, log: Any, ropts: dict[str, Any]) -> Channel:
    """A CSV column, read by the CSV reader with the log's own time (its layout as the log
    was read: separator, header, time column and unit, or ``--rate``)."""
    from ..logs.channel_map import ChannelMap, ChannelRef
    from ..logs.csv_layout import csv_layout
    from ..logs.paths import open_log_options
    from ..logs.reader import read_columns

    opts = {k: v for k, v in ropts.items()
            if k not in ("robot", "repair_order", "position_unit")}
    _p, _where, _suffix, _folder, cmap = open_log_options(path, **opts)
    canonical = cmap is None
    lay = csv_layout(path, cmap, time_unit=opts.get("time_unit") if canonical else None,
                     time_column=opts.get("time_column") if canonical else None,
                     rate=ropts.get("rate"))
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
    read = {"channel_map": one, "repair_order": bool(ropts.get("repair_order"))}
    if ropts.get("rate") is not None:
        read["rate"] = ropts["rate"]
    with warnings.catch_warnings():
        # the log's own repairs were warned about when it was read
        warnings.simplefilter("ignore", ImpactWarning)
        t_ns, values = read_columns(path, read)
    col = name if isinstance(source, str) else f"column {source}"
    return Channel(name, f"CSV {col}", _relative(t_ns, log),
                   np.asarray(values[:, 0], dtype=np.float64))


def _npz_channel(path: Path, name: str, log: Any, ropts: dict[str, Any]) -> Channel:
    """An ``.npz`` array (``key`` or ``key[i]``) with the channel map's time (with
    ``--time-unit`` / ``--time-column`` applied), or ``--rate``'s."""
    from ..logs.channel_map import ChannelMap, ChannelRef
    from ..logs.paths import open_log_options
    from ..logs.reader import read_columns

    opts = {k: v for k, v in ropts.items()
            if k not in ("robot", "repair_order", "position_unit")}
    cmap = open_log_options(path, **opts)[4] if ropts.get("channel_map") else None
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
            {"rate": ropts["rate"]} if ropts.get("rate") is not None else {})},
            check_rate=False)
    return Channel(name, f"array {name}", _relative(t_ns, log),
                   np.asarray(values[:, 0], dtype=np.float64))


def _message_channel(path: Path, name: str, log: Any) -> Channel:
    """A message field, stamped like the log's samples, through the message reader."""
    from ..logs.message_plan import field_channel

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


#: What --link is, in its help and in the message when it is missing.
LINK_HELP = ("the link the contacts are on: 1-based, counted from the base along the robot's "
             "chain (1: the link the first joint moves); a label names the link touched, and "
             "evaluate scores the incidents' link against it")


class _ExplainedOption(click.Option):
    """A required option whose "Missing option" message also says what it is."""

    def __init__(self, *args: Any, missing: str = "", **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.missing = missing

    def process_value(self, ctx: click.Context, value: Any) -> Any:
        try:
            return super().process_value(ctx, value)
        except click.MissingParameter:
            raise click.MissingParameter(message=self.missing, ctx=ctx, param=self) from None


@click.command("labels")
@click.argument("log", type=click.Path(path_type=Path))
@click.option("--from-channel", "channel", required=True, metavar="NAME",
              help="The switch or force channel: a CSV column (one the reader ignores, or "
                   "any), <joint>.<signal>, an .npz array (key or key[i]), or in an MCAP / "
                   "bag a message field /topic/field[i] (or /topic/array[joint]).")
@click.option("--above", type=float, required=True, metavar="X",
              help="A contact is where the channel is above X (in its own unit).")
@click.option("--link", type=click.IntRange(min=1), required=True, metavar="N",
              cls=_ExplainedOption, missing=f"--link N is {LINK_HELP}",
              help=f"The {LINK_HELP[4:]}.")
@click.option("--kind", type=click.Choice(["impact", "push", "clamp"]), default="push",
              show_default=True, help="The contacts' kind.")
@click.option("--channel-kind", "channel_is", type=click.Choice(CHANNEL_KINDS),
              default="auto", show_default=True,
              help="force: peak_force is the channel's peak [N]; switch: no force "
                   "(peak_force_known false); auto: a switch when the channel has two values.")
@click.option("--min-duration", type=click.FloatRange(min=0.0), default=0.0, show_default=True,
              help="Drop stretches shorter than this [s].")
@click.option("--merge-gap", type=click.FloatRange(min=0.0), default=0.0, show_default=True,
              help="Merge stretches this close (last sample to next first sample) [s].")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              required=True, help="The labels JSON to write.")
@click.option("--robot", metavar=ROBOT_METAVAR, type=click.Path(dir_okay=False, path_type=Path),
              default=None, help=robot_help("for a log whose torque comes from currents"))
@log_read_options
@handle_errors
def labels_cmd(log: Path, channel: str, above: float, link: int, kind: str, channel_is: str,
               min_duration: float, merge_gap: float, output: Path, robot: Path | None,
               channel_map: str | None, topic: str | None, reference_topic: str | None,
               time_source: str | None, torque_source: str | None) -> None:
    """Make ground-truth labels from a logged switch or force channel.

    Contiguous stretches where the channel is above X become contacts (start and end in
    seconds since the log's first sample); peak_force is the channel's peak for a force,
    unknown for a switch. Writes LABELS.json (schemas/labels.schema.json) for
    `impactcli evaluate LOG --labels LABELS.json`.
    """
    from ..errors import LabelsError
    from ..files import prepare_output
    from ..logs import read_log
    from ..logs.robot_files import labels_from_dict, read_robot, write_labels
    from ..schema import validate

    if not np.isfinite(above):
        raise click.BadParameter(f"{above!r} is not a finite number", param_hint="'--above'")
    prepare_output(output)
    log = check_log_path(log)  # a folder's one log
    ropts = read_options_from(channel_map, topic, reference_topic, time_source, torque_source)
    desc = read_robot(robot) if robot is not None else None
    data = read_log(log, robot=desc, **ropts)
    ch = read_channel(log, channel, data, ropts)
    if ch.t_s.size == 0:
        raise LogFormatError(f"{log}: channel {channel!r} holds no samples")
    doc = labels_doc(ch, above=above, kind=kind, link=link, channel_is=channel_is,
                     merge_gap_s=merge_gap, min_duration_s=min_duration,
                     sample_rate=data.sample_rate_hz, log_path=str(log))
    validate(doc, "labels", LabelsError, str(output))
    labels = labels_from_dict(doc, str(output))  # the checks evaluate makes (end >= start)
    if not doc["events"]:
        finite = ch.values[np.isfinite(ch.values)]
        top = f"{float(finite.max()):.4g}" if finite.size else "no finite value"
        warnings.warn(f"{log}: {channel} is never above {above:g} (its largest value: {top}): "
                      "the labels hold no contact", ImpactWarning, stacklevel=2)
    write_labels(labels, output)
    src = doc["source"]
    click.echo(f"{len(doc['events'])} contact(s) where {channel} > {above:g} "
               f"({ch.what}; a {src['channel_kind']}), kind {kind}, link {link}:")
    for k, e in enumerate(doc["events"]):
        force = (f"peak {e['peak_force']:.4g} N" if src["channel_kind"] == "force"
                 else f"switch value {e['peak_value']:.4g}")
        click.echo(f"  #{k}  {e['start']:.3f}–{e['end']:.3f} s  {force}")
    click.echo(f"wrote {output}")
