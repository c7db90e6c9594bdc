"""Readers and writers of robot logs; one entry point :func:`read_log`.

Formats: canonical wide CSV (``.csv``, ``.csv.gz``), any CSV or ``.npz`` through a
channel map, MCAP with impactcli's JSON joint-sample schema, MCAP with ROS 2
``sensor_msgs/msg/JointState``, ROS bags through ``rosbags`` (rosbag2 ``.db3`` files and
folders with ``metadata.yaml``, ROS 1 ``.bag``), and MCAP or bags of any message type
through a channel map naming message fields (``format: messages``). MCAP and bags are read
by one implementation (:mod:`impactcli.io.messages`), with ``_ref``/``_model``/``_ext``
companion topics of a JointState state topic read by default.

A log is a file, or a rosbag2 folder: its stem is the folder's name and its sha256 that of
its files' sha256s in name order (:func:`impactcli.io.bags.folder_sha256`). Any other
folder given as a log is a LogFormatError ("not a rosbag2 folder (no metadata.yaml)").
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..errors import LogFormatError
from ..types import RobotDescription, RobotLog

__all__ = ["LOG_SUFFIXES", "MESSAGE_SUFFIXES", "inspect_log", "log_sha256", "log_stem",
           "read_log", "write_log"]

#: Recognised log suffixes (lower case), longest first.
LOG_SUFFIXES: tuple[str, ...] = (".csv.gz", ".csv", ".mcap", ".npz", ".bag", ".db3")
#: Suffixes of message logs (topics, --time-source, channel maps naming fields).
MESSAGE_SUFFIXES: tuple[str, ...] = (".mcap", ".bag", ".db3")


def _suffix(path: Path) -> str | None:
    name = path.name.lower()
    return next((s for s in LOG_SUFFIXES if name.endswith(s)), None)


def log_stem(path: str | os.PathLike[str]) -> str:
    """File name without its format extension (``.csv``, ``.csv.gz``, ``.mcap``, ``.npz``,
    ``.bag``, ``.db3``); a rosbag2 folder's own name (``run/`` → ``run``)."""
    p = Path(path)
    s = _suffix(p)
    return p.name[: -len(s)] if s else p.name


def log_sha256(path: str | os.PathLike[str]) -> str:
    """The sha256 recorded for a local log: a file's bytes, or for a rosbag2 folder the
    sha256 of its files' hex sha256s in name order (formats.md)."""
    from .._fs import sha256_file
    from .bags import folder_sha256

    p = Path(path)
    return folder_sha256(p) if p.is_dir() else sha256_file(p)


def read_log(
    path: str | os.PathLike[str],
    *,
    channel_map: str | os.PathLike[str] | Any | None = None,
    robot: RobotDescription | None = None,
    topic: str | None = None,
    reference_topic: str | None = None,
    time_source: str | None = None,
    torque_source: str | None = None,
    time_unit: str | None = None,
    repair_order: bool = False,
) -> RobotLog:
    """Read a robot log into a validated :class:`~impactcli.types.RobotLog`.

    Args:
        path: ``.csv``/``.csv.gz`` (canonical, or any layout with ``channel_map``),
            ``.npz`` (needs ``channel_map``), ``.mcap`` (JSON joint samples, ROS 2
            JointState, or any message type with a ``messages`` channel map), ``.bag``
            (ROS 1), ``.db3`` or a rosbag2 folder (``metadata.yaml``); a local path or an
            fsspec URL (``file://``, ``s3://``, ...: see :mod:`impactcli.io.urls`; the URL is
            recorded as the source path; a folder only as a local path or ``file://``).
        channel_map: a JSON/YAML channel map path, a shipped map's short name
            (``ur_ext_observer``, ``kuka_lwr4``, ``franka_state_example``, ...) or a ChannelMap.
        robot: robot description; needed to convert a ``current`` without a map scale to
            torque (gear_ratio × torque_constant, per joint by name).
        topic: MCAP/bag state topic (default: the only joint topic, else ``/joint_states``).
        reference_topic: MCAP/bag reference topic (default ``<topic>_ref`` if present).
        time_source: MCAP/bag ``log``, ``publish`` or ``header`` (default header when
            non-zero; a bag's publish time is its log time).
        torque_source: ``torque`` or ``current`` (default: torque when logged).
        time_unit: unit of the time column of a CSV or ``.npz`` log (``s``, ``ms``, ``us``,
            ``ns``; ``--time-unit``): a canonical ``time`` column's, or the channel map's
            time (replacing its ``unit``). Default: seconds, or the map's unit. A column
            time implying a rate outside 20 Hz – 100 kHz is an error saying to give it.
        repair_order: keep the longest increasing run of stamps when rows are out of time
            order or share a stamp (``--repair-order``), dropping the other rows with a
            warning (:mod:`impactcli.io.repair`); without it such a log is an error.

    Returns:
        The log, with ``source`` recording path, sha256, format, torque and time source,
        ignored channels and repairs (repairs are also warned about as ImpactWarning).

    Raises:
        LogFormatError: missing or unknown file, malformed content (naming the file).
        ChannelMapError: a channel map that is malformed or points at nothing.
    """
    from .assemble import build_log
    from .repair import repairing_order
    from .urls import is_url, read_log_url

    if is_url(path):  # file://, s3://, ...: read a local copy, recorded under the URL
        return read_log_url(  # type: ignore[no-any-return]
            str(path), read_log, channel_map=channel_map, robot=robot, topic=topic,
            reference_topic=reference_topic, time_source=time_source,
            torque_source=torque_source, time_unit=time_unit, repair_order=repair_order)
    p, where, suffix, folder, cmap = open_log_options(
        path, channel_map=channel_map, topic=topic, reference_topic=reference_topic,
        time_source=time_source, torque_source=torque_source, time_unit=time_unit)
    with repairing_order(repair_order):
        ch, fmt, tsrc, sha = _read_channels(p, where, suffix, folder, cmap, topic,
                                            reference_topic, time_source, time_unit)
    return build_log(
        ch, path=where, fmt=fmt, robot=robot, torque_source=torque_source,
        time_source=tsrc, sha256=sha,
    )


def open_log_options(
    path: str | os.PathLike[str], *, channel_map: Any = None, topic: str | None = None,
    reference_topic: str | None = None, time_source: str | None = None,
    torque_source: str | None = None, time_unit: str | None = None,
) -> tuple[Path, str, str, bool, Any]:
    """Check a local log path and :func:`read_log`'s options, load the channel map.

    Returns:
        ``(path, where, suffix, folder, cmap)``: the path, it as text for messages, its
        format suffix (``rosbag2`` for a folder), whether it is a folder, the channel map
        (None without one; ``--time-unit`` applied to its time).

    Raises:
        LogFormatError: as :func:`read_log` does for the path and the options.
    """
    from .assemble import check_torque_source
    from .channel_map import load_channel_map

    p = Path(path)
    where = str(path)
    check_torque_source(torque_source, where)
    if not p.exists():
        if any(c in where for c in "*?["):
            raise LogFormatError(f"{where}: the pattern matches no file")
        raise LogFormatError(f"{where}: log file not found")
    folder = p.is_dir()
    if folder:
        from .bags import is_rosbag2_folder

        if not is_rosbag2_folder(p):
            raise LogFormatError(f"{where}: not a rosbag2 folder (no metadata.yaml)")
        suffix: str | None = "rosbag2"
    elif not p.is_file():
        raise LogFormatError(f"{where}: not a file")
    else:
        suffix = _suffix(p)
    if suffix is None:
        raise LogFormatError(
            f"{where}: unknown log format (expected {', '.join(LOG_SUFFIXES)}, or a rosbag2 "
            "folder)"
        )
    messages = suffix in MESSAGE_SUFFIXES or folder
    if not messages and (topic or reference_topic or time_source):
        raise LogFormatError(
            f"{where}: --topic, --reference-topic and --time-source apply to MCAP logs and "
            "ROS bags only"
        )
    if time_unit is not None:
        from .channel_map import TIME_UNITS

        if time_unit not in TIME_UNITS:
            raise LogFormatError(f"{where}: unknown time unit {time_unit!r} (s, ms, us or ns)")
        if messages:
            raise LogFormatError(f"{where}: --time-unit applies to CSV and .npz logs only "
                                 "(MCAP and bag stamps are ns)")
    cmap = load_channel_map(channel_map) if channel_map is not None else None
    if cmap is not None and not messages and cmap.format == "messages":
        raise LogFormatError(f"{where}: channel map {cmap.path or cmap.name} names message "
                             "fields (format: messages): it is for MCAP logs and ROS bags")
    if cmap is not None and time_unit is not None and cmap.time is not None:
        import dataclasses

        cmap = dataclasses.replace(cmap, time=dataclasses.replace(cmap.time, unit=time_unit))
    return p, where, suffix, folder, cmap


def _read_channels(p: Path, where: str, suffix: str, folder: bool, cmap: Any,
                   topic: str | None, reference_topic: str | None, time_source: str | None,
                   time_unit: str | None) -> tuple[Any, str, str, str]:
    """The reader of ``suffix`` on ``p``: ``(channels, format, time source, sha256)``."""
    from .._fs import sha256_file
    tsrc = "column"
    # the file's sha256 is computed on a thread while the reader parses (hashlib releases
    # the GIL on large blocks): a 1 GB CSV is hashed for free instead of in 1.4 s
    from concurrent.futures import ThreadPoolExecutor

    hasher = ThreadPoolExecutor(max_workers=1)
    digest = hasher.submit(log_sha256 if folder else sha256_file, p)
    hasher.shutdown(wait=False)
    if suffix in (".csv", ".csv.gz"):
        if cmap is not None and cmap.format == "npz":
            raise LogFormatError(f"{where}: channel map {cmap.path} is for .npz archives")
        from .csv import read_csv_channels

        ch, fmt = read_csv_channels(p, cmap, time_unit=time_unit)
    elif suffix == ".npz":
        if cmap is None:
            raise LogFormatError(f"{where}: an .npz log needs a channel map (--channel-map)")
        if cmap.format == "csv":
            raise LogFormatError(f"{where}: channel map {cmap.path} is for CSV files")
        from .npz import read_npz_channels
        from .repair import check_time_rate

        ch, fmt = read_npz_channels(p, cmap), "npz"
        tspec = cmap.time
        if tspec is not None:
            check_time_rate(ch.t_ns, where, f"array {tspec.ref.source!r}", tspec.unit)
    elif suffix == ".mcap":
        from .mcap_log import read_mcap_channels

        ch, fmt, tsrc = read_mcap_channels(
            p, topic=topic, reference_topic=reference_topic, time_source=time_source,
            cmap=cmap,
        )
    else:  # .bag, .db3, rosbag2 folder
        from .bags import read_bag_channels

        ch, fmt, tsrc = read_bag_channels(
            p, topic=topic, reference_topic=reference_topic, time_source=time_source,
            cmap=cmap, where=where,
        )
    return ch, fmt, tsrc, digest.result()


def write_log(log: RobotLog, path: str | os.PathLike[str], *, mcap_encoding: str = "json") -> None:
    """Write ``log`` by suffix, atomically (never a half-written file).

    Args:
        log: the log.
        path: ``.csv`` / ``.csv.gz`` (canonical wide CSV, exact round trip), ``.mcap``,
            ``.db3`` (rosbag2 SQLite file) or ``.bag`` (ROS 1); the bags hold JointState
            topics as ``mcap_encoding="ros2"`` does (:mod:`impactcli.io.bags`; a rosbag2
            folder: :func:`impactcli.io.bags.write_rosbag2`).
        mcap_encoding: ``json`` (impactcli joint samples on ``/joint_samples``) or ``ros2``
            (JointState on ``/joint_states``, effort = torque; reference on
            ``/joint_states_ref``; effort = torque_model on ``/joint_states_model`` and
            torque_ext on ``/joint_states_ext``).

    Raises:
        LogFormatError: unknown suffix or encoding.
    """
    p = Path(path)
    suffix = _suffix(p)
    if suffix == ".db3":
        from .bags import write_rosbag2

        write_rosbag2(log, p)
        return
    if suffix == ".bag":
        from .bags import write_rosbag1

        write_rosbag1(log, p)
        return
    if suffix in (".csv", ".csv.gz"):
        from .csv import write_csv

        write_csv(log, p)
    elif suffix == ".mcap":
        from .mcap_log import write_mcap_json, write_mcap_ros2

        if mcap_encoding == "json":
            write_mcap_json(log, p)
        elif mcap_encoding == "ros2":
            write_mcap_ros2(log, p)
        else:
            raise LogFormatError(f"{p}: unknown MCAP encoding {mcap_encoding!r} (json or ros2)")
    else:
        raise LogFormatError(
            f"{p}: cannot write this format (use .csv, .csv.gz, .mcap, .db3 or .bag)")


def inspect_log(path: str | os.PathLike[str], **kwargs: Any) -> dict[str, Any]:
    """Read a log and describe it as a JSON-ready dict (``schemas/inspect.schema.json``).

    Takes the same keyword arguments as :func:`read_log`.
    """
    from .assemble import describing
    from .inspect import describe_log

    with describing():  # a log it cannot convert yet is still described
        return describe_log(read_log(path, **kwargs))
