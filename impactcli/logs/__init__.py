"""Readers and writers of robot logs.

Formats: canonical wide CSV (``.csv``, ``.csv.gz``), any CSV or ``.npz`` through a
channel map, MCAP with impactcli's JSON joint-sample schema, MCAP with ROS 2
``sensor_msgs/msg/JointState``, ROS bags through ``rosbags`` (rosbag2 ``.db3`` files and
folders with ``metadata.yaml``, ROS 1 ``.bag``), and MCAP or bags of any message type
through a channel map naming message fields (``format: messages``).

Each format has one reader (:func:`open_log`, :mod:`impactcli.logs.reader`): a scan, then
the samples in chunks. :func:`read_log` collects the chunks of a log into a
:class:`~impactcli.types.RobotLog`; :func:`write_log` writes one (:mod:`impactcli.logs.write`).
"""

from __future__ import annotations

import os
from typing import Any

from ..types import RobotDescription, RobotLog
from .paths import LOG_SUFFIXES, MESSAGE_SUFFIXES, log_sha256, log_stem, open_log_options
from .reader import LogReader, MemoryReader, open_log

__all__ = ["LOG_SUFFIXES", "MESSAGE_SUFFIXES", "LogReader", "MemoryReader", "inspect_log",
           "log_sha256", "log_stem", "open_log", "open_log_options", "read_log", "write_log"]


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
    time_column: str | None = None,
    rate: float | None = None,
    position_unit: str | None = None,
    repair_order: bool = False,
) -> RobotLog:
    """Read a robot log into a validated :class:`~impactcli.types.RobotLog`: the chunks of
    its reader (:func:`open_log`) collected.

    Args:
        path: ``.csv``/``.csv.gz`` (canonical, or any layout with ``channel_map``),
            ``.npz`` (needs ``channel_map``), ``.mcap`` (JSON joint samples, ROS 2
            JointState, or any message type with a ``messages`` channel map), ``.bag``
            (ROS 1), ``.db3`` or a rosbag2 folder (``metadata.yaml``); a local path or an
            fsspec URL (``file://``, ``s3://``, ...: see :mod:`impactcli.logs.urls`; the URL is
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
            time implying a rate outside 20 Hz – 100 kHz is an error saying to give it (or,
            for a log read right at a rate below 20 Hz, that the rate is too low).
        time_column: the time column of a CSV (or array of an ``.npz``), ``--time-column``:
            default the one named ``time``, ``timestamp``, ``stamp``, ``t`` or ``__time``
            (any case; an optional unit suffix ``_s/_ms/_us/_ns`` gives its unit), or the
            channel map's.
        rate: ``--rate`` [Hz] of a CSV or ``.npz`` log without a time column: sample i is
            at i / rate s (recorded in the log's repairs, warned).
        position_unit: ``rad`` (default) or ``deg``: the positions' unit (``--position-unit``;
            degrees are converted to radians, with the references, velocities and
            accelerations). Positions that cannot be radians are refused.
        repair_order: keep the longest increasing run of stamps when rows are out of time
            order or share a stamp (``--repair-order``), dropping the other rows with a
            warning (:mod:`impactcli.logs.repair`); without it such a log is an error.

    Returns:
        The log, with ``source`` recording path, sha256, format, torque and time source,
        ignored channels and repairs (repairs are also warned about as ImpactWarning).

    Raises:
        LogFormatError: missing or unknown file, malformed content (naming the file).
        ChannelMapError: a channel map that is malformed or points at nothing.
    """
    from .reader import collect

    with open_log(path, channel_map=channel_map, robot=robot, topic=topic,
                  reference_topic=reference_topic, time_source=time_source,
                  torque_source=torque_source, time_unit=time_unit,
                  time_column=time_column, rate=rate, position_unit=position_unit,
                  repair_order=repair_order) as reader:
        return collect(reader)


def write_log(log: RobotLog, path: str | os.PathLike[str], *, mcap_encoding: str = "json") -> None:
    """Write ``log`` by suffix, atomically (:func:`impactcli.logs.write.write_log`)."""
    from .write import write_log as write

    write(log, path, mcap_encoding=mcap_encoding)


def inspect_log(path: str | os.PathLike[str], check: Any = None,
                **kwargs: Any) -> dict[str, Any]:
    """Describe a log as a JSON-ready dict (``schemas/inspect.schema.json``) from its scan
    and its sample times (:func:`impactcli.logs.describe.describe_log`; 8 bytes a sample in
    memory, not the samples). ``check(scan)``, when given, is called on the scan first
    (``inspect --robot``: the torque's scale against the description's gravity torque).

    Takes the same keyword arguments as :func:`read_log`.
    """
    import numpy as np

    from . import describe as inspect
    from .channels import describing

    with describing(), open_log(path, **kwargs) as reader:  # a log it cannot convert yet
        scan = reader.scan()                                  # is still described
        if check is not None:
            check(scan)
        t_ns = np.concatenate(list(reader.times()))
        return inspect.describe_log(scan, t_ns)
