"""MCAP logs (formats.md, "MCAP"): impactcli's JSON joint samples, ROS 2 JointState, and any
message type through a channel map.

Reading: the file is scanned in bulk (:mod:`impactcli.io.mcap_scan`; the official ``mcap``
reader for what the scanner does not handle) and read by
:func:`impactcli.io.messages.read_message_channels`, shared with ROS bags: topic choice
(``topic``; the only joint topic; ``/joint_states``), default companion topics
``<topic>_ref`` (reference), ``<topic>_model`` (effort = torque_model) and ``<topic>_ext``
(effort = torque_ext) aligned by causal sample-and-hold, time source (``header`` stamp when
every stamp is non-zero, else ``log``; ``time_source`` overrides), and channel maps with
``format: messages`` naming message fields (ROS 2 CDR with the ``ros2msg``/``ros2idl``
schemas stored in the file, ROS 1 with ``ros1msg``, JSON).

Writing: :func:`write_mcap_json` (one JSON JointSample per sample, every signal) and
:func:`write_mcap_ros2` (JointState state, ``_ref``, ``_model`` and ``_ext`` topics).
"""

from __future__ import annotations

import warnings
from pathlib import Path

from ..errors import ImpactWarning, LogFormatError
from .assemble import TIME_SOURCES, JointChannels
from .channel_map import ChannelMap
from .mcap_scan import UnsupportedMcap, scan_mcap, scan_mcap_official
from .messages import read_message_channels
from .msgsource import McapSource


def read_mcap_channels(
    path: Path, *, topic: str | None, reference_topic: str | None, time_source: str | None,
    cmap: ChannelMap | None = None,
) -> tuple[JointChannels, str, str]:
    """Read an MCAP log into :class:`JointChannels` (:mod:`impactcli.io.messages`).

    Returns:
        ``(channels, format, time_source)``, format ``mcap-json``, ``mcap-ros2`` or
        ``mcap-ros1`` (by the state topic's encoding).
    """
    where = str(path)
    if time_source is not None and time_source not in TIME_SOURCES:
        raise LogFormatError(f"{where}: unknown time source {time_source!r} (log, publish, header)")
    try:
        scan = scan_mcap(path)
    except UnsupportedMcap:
        # the official reader, for what the scanner does not handle
        scan = scan_mcap_official(path)
    if scan.n_messages == 0:
        what = ("truncated before its first complete message" if scan.truncated
                else "holds no messages")
        raise LogFormatError(f"{where}: corrupt or empty MCAP: {what}")
    src = McapSource(scan, where)
    if scan.truncated:
        msg = (
            f"{where}: MCAP file is truncated (records end early); read the "
            f"{scan.n_messages} complete message(s) before the cut"
        )
        warnings.warn(msg, ImpactWarning, stacklevel=4)
        src.repairs.append(msg)
    return read_message_channels(src, cmap=cmap, topic=topic, reference_topic=reference_topic,
                                 time_source=time_source)
