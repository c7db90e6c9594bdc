"""What a log path is: its format by suffix, its stem, its sha256, and the read options
that apply to it (:func:`check_log_path`).

A log is a file, or a rosbag2 folder (a folder holding ``metadata.yaml``): its stem is the
folder's name and its sha256 that of its files' sha256s in name order
(:func:`folder_sha256`). Any other folder given as a log is refused.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
from pathlib import Path
from typing import Any

from ..errors import LogFormatError

#: Recognised log suffixes (lower case), longest first.
LOG_SUFFIXES: tuple[str, ...] = (".csv.gz", ".csv", ".mcap", ".npz", ".bag", ".db3")
#: Suffixes of message logs (topics, --time-source, channel maps naming fields).
MESSAGE_SUFFIXES: tuple[str, ...] = (".mcap", ".bag", ".db3")
#: The file that makes a folder a rosbag2.
ROSBAG2_METADATA = "metadata.yaml"
#: The read options a log reader takes (``read_log``'s keyword arguments).
READ_OPTIONS: tuple[str, ...] = ("channel_map", "robot", "topic", "reference_topic",
                                 "time_source", "torque_source", "time_unit", "repair_order")


def log_suffix(path: Path) -> str | None:
    """The format suffix of ``path`` (one of :data:`LOG_SUFFIXES`), None when unknown."""
    name = path.name.lower()
    return next((s for s in LOG_SUFFIXES if name.endswith(s)), None)


def log_stem(path: str | os.PathLike[str]) -> str:
    """File name without its format extension (``.csv``, ``.csv.gz``, ``.mcap``, ``.npz``,
    ``.bag``, ``.db3``); a rosbag2 folder's own name (``run/`` → ``run``)."""
    p = Path(path)
    s = log_suffix(p)
    return p.name[: -len(s)] if s else p.name


def is_rosbag2_folder(path: Path) -> bool:
    """Whether ``path`` is a folder holding a rosbag2 ``metadata.yaml``."""
    return path.is_dir() and (path / ROSBAG2_METADATA).is_file()


def folder_files(path: Path) -> list[Path]:
    """The regular files directly inside ``path``, in name order."""
    return sorted((p for p in path.iterdir() if p.is_file()), key=lambda p: p.name)


def folder_sha256(path: Path) -> str:
    """sha256 of the concatenated hex sha256 digests of the folder's files, in name order."""
    from ..files import sha256_file

    h = hashlib.sha256()
    for f in folder_files(path):
        h.update(sha256_file(f).encode("ascii"))
    return h.hexdigest()


def log_sha256(path: str | os.PathLike[str]) -> str:
    """The sha256 recorded for a local log: a file's bytes, or for a rosbag2 folder the
    sha256 of its files' hex sha256s in name order."""
    from ..files import sha256_file

    p = Path(path)
    return folder_sha256(p) if p.is_dir() else sha256_file(p)


def check_read_options(options: dict[str, Any]) -> None:
    """TypeError naming the keyword arguments that are not read options."""
    unknown = set(options) - set(READ_OPTIONS)
    if unknown:
        raise TypeError(f"unknown read options: {', '.join(sorted(unknown))}")


def open_log_options(
    path: str | os.PathLike[str], *, channel_map: Any = None, topic: str | None = None,
    reference_topic: str | None = None, time_source: str | None = None,
    torque_source: str | None = None, time_unit: str | None = None,
) -> tuple[Path, str, str, bool, Any]:
    """Check a local log path and the read options that apply to it; load the channel map.

    Returns:
        ``(path, where, suffix, folder, cmap)``: the path, it as text for messages, its
        format suffix (``rosbag2`` for a folder), whether it is a folder, the channel map
        (None without one; ``--time-unit`` applied to its time).

    Raises:
        LogFormatError: a missing or unknown file, or options that do not apply to it.
        ChannelMapError: a channel map that does not load.
    """
    from .channel_map import TIME_UNITS, load_channel_map
    from .channels import check_torque_source

    p = Path(path)
    where = str(path)
    check_torque_source(torque_source, where)
    if not p.exists():
        if any(c in where for c in "*?["):
            raise LogFormatError(f"{where}: the pattern matches no file")
        raise LogFormatError(f"{where}: log file not found")
    folder = p.is_dir()
    if folder:
        if not is_rosbag2_folder(p):
            raise LogFormatError(f"{where}: not a rosbag2 folder (no metadata.yaml)")
        suffix: str | None = "rosbag2"
    elif not p.is_file():
        raise LogFormatError(f"{where}: not a file")
    else:
        suffix = log_suffix(p)
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
        cmap = dataclasses.replace(cmap, time=dataclasses.replace(cmap.time, unit=time_unit))
    return p, where, suffix, folder, cmap
