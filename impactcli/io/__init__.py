"""Readers and writers of robot logs; one entry point :func:`read_log`.

Formats: canonical wide CSV (``.csv``, ``.csv.gz``), any CSV or ``.npz`` through a
channel map, MCAP with impactcli's JSON joint-sample schema, MCAP with ROS 2
``sensor_msgs/msg/JointState``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..errors import LogFormatError
from ..types import RobotDescription, RobotLog

__all__ = ["LOG_SUFFIXES", "inspect_log", "log_stem", "read_log", "write_log"]

#: Recognised log suffixes (lower case), longest first.
LOG_SUFFIXES: tuple[str, ...] = (".csv.gz", ".csv", ".mcap", ".npz")


def _suffix(path: Path) -> str | None:
    name = path.name.lower()
    return next((s for s in LOG_SUFFIXES if name.endswith(s)), None)


def log_stem(path: str | os.PathLike[str]) -> str:
    """File name without its format extension (``.csv``, ``.csv.gz``, ``.mcap``, ``.npz``)."""
    p = Path(path)
    s = _suffix(p)
    return p.name[: -len(s)] if s else p.name


def read_log(
    path: str | os.PathLike[str],
    *,
    channel_map: str | os.PathLike[str] | Any | None = None,
    robot: RobotDescription | None = None,
    topic: str | None = None,
    reference_topic: str | None = None,
    time_source: str | None = None,
    torque_source: str | None = None,
) -> RobotLog:
    """Read a robot log into a validated :class:`~impactcli.types.RobotLog`.

    Args:
        path: ``.csv``/``.csv.gz`` (canonical, or any layout with ``channel_map``),
            ``.npz`` (needs ``channel_map``) or ``.mcap`` (JSON joint samples or ROS 2
            JointState); a local path or an fsspec URL (``file://``, ``s3://``, ...:
            see :mod:`impactcli.io.urls`; the URL is recorded as the source path).
        channel_map: a JSON/YAML channel map path, a shipped map's short name
            (``ur_ext_observer``, ``kuka_lwr4``) or a ChannelMap.
        robot: robot description; needed to convert a ``current`` without a map scale to
            torque (gear_ratio × torque_constant, per joint by name).
        topic: MCAP state topic (default: the only joint topic, else ``/joint_states``).
        reference_topic: MCAP ROS 2 reference topic (default ``<topic>_ref`` if present).
        time_source: MCAP ``log``, ``publish`` or ``header`` (default header when non-zero).
        torque_source: ``torque`` or ``current`` (default: torque when logged).

    Returns:
        The log, with ``source`` recording path, sha256, format, torque and time source,
        ignored channels and repairs (repairs are also warned about as ImpactWarning).

    Raises:
        LogFormatError: missing or unknown file, malformed content (naming the file).
        ChannelMapError: a channel map that is malformed or points at nothing.
    """
    from .._fs import sha256_file
    from .assemble import build_log, check_torque_source
    from .channel_map import load_channel_map
    from .urls import is_url, read_log_url

    if is_url(path):  # file://, s3://, ...: read a local copy, recorded under the URL
        return read_log_url(  # type: ignore[no-any-return]
            str(path), read_log, channel_map=channel_map, robot=robot, topic=topic,
            reference_topic=reference_topic, time_source=time_source,
            torque_source=torque_source)
    p = Path(path)
    where = str(path)
    check_torque_source(torque_source, where)
    if not p.exists():
        raise LogFormatError(f"{where}: log file not found")
    if not p.is_file():
        raise LogFormatError(f"{where}: not a file")
    suffix = _suffix(p)
    if suffix is None:
        raise LogFormatError(
            f"{where}: unknown log format (expected {', '.join(LOG_SUFFIXES)})"
        )
    if suffix != ".mcap" and (topic or reference_topic or time_source):
        raise LogFormatError(
            f"{where}: --topic, --reference-topic and --time-source apply to MCAP logs only"
        )
    cmap = load_channel_map(channel_map) if channel_map is not None else None
    tsrc = "column"
    # the file's sha256 is computed on a thread while the reader parses (hashlib releases
    # the GIL on large blocks): a 1 GB CSV is hashed for free instead of in 1.4 s
    from concurrent.futures import ThreadPoolExecutor

    hasher = ThreadPoolExecutor(max_workers=1)
    digest = hasher.submit(sha256_file, p)
    hasher.shutdown(wait=False)
    if suffix in (".csv", ".csv.gz"):
        if cmap is not None and cmap.format == "npz":
            raise LogFormatError(f"{where}: channel map {cmap.path} is for .npz archives")
        from .csv import read_csv_channels

        ch, fmt = read_csv_channels(p, cmap)
    elif suffix == ".npz":
        if cmap is None:
            raise LogFormatError(f"{where}: an .npz log needs a channel map (--channel-map)")
        if cmap.format == "csv":
            raise LogFormatError(f"{where}: channel map {cmap.path} is for CSV files")
        from .npz import read_npz_channels

        ch, fmt = read_npz_channels(p, cmap), "npz"
    else:
        if cmap is not None:
            raise LogFormatError(f"{where}: channel maps do not apply to MCAP logs")
        from .mcap_log import read_mcap_channels

        ch, fmt, tsrc = read_mcap_channels(
            p, topic=topic, reference_topic=reference_topic, time_source=time_source
        )
    return build_log(
        ch, path=where, fmt=fmt, robot=robot, torque_source=torque_source,
        time_source=tsrc, sha256=digest.result(),
    )


def write_log(log: RobotLog, path: str | os.PathLike[str], *, mcap_encoding: str = "json") -> None:
    """Write ``log`` by suffix, atomically (never a half-written file).

    Args:
        log: the log.
        path: ``.csv`` / ``.csv.gz`` (canonical wide CSV, exact round trip) or ``.mcap``.
        mcap_encoding: ``json`` (impactcli joint samples on ``/joint_samples``) or ``ros2``
            (JointState on ``/joint_states``, effort = torque; reference on
            ``/joint_states_ref``).

    Raises:
        LogFormatError: unknown suffix or encoding.
    """
    p = Path(path)
    suffix = _suffix(p)
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
        raise LogFormatError(f"{p}: cannot write this format (use .csv, .csv.gz or .mcap)")


def inspect_log(path: str | os.PathLike[str], **kwargs: Any) -> dict[str, Any]:
    """Read a log and describe it as a JSON-ready dict (``schemas/inspect.schema.json``).

    Takes the same keyword arguments as :func:`read_log`.
    """
    from .inspect import describe_log

    return describe_log(read_log(path, **kwargs))
