"""TEMPORARY (removed before the end of WP1): the whole-file readers the one reader still
falls back to for the variants it does not read yet."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..errors import LogFormatError
from ..types import RobotLog


class NotStreamable(Exception):
    """The file needs the whole-file reader."""


def read_whole(path: str | os.PathLike[str], options: dict[str, Any]) -> RobotLog:
    """The former read_log of a local file."""
    from .assemble import build_log
    from .paths import open_log_options
    from .repair import repairing_order

    opts = {k: v for k, v in options.items() if k not in ("robot", "repair_order")}
    p, where, suffix, folder, cmap = open_log_options(path, **opts)
    with repairing_order(bool(options.get("repair_order"))):
        ch, fmt, tsrc, sha = _read_channels(p, where, suffix, folder, cmap,
                                            options.get("topic"),
                                            options.get("reference_topic"),
                                            options.get("time_source"),
                                            options.get("time_unit"))
    return build_log(ch, path=where, fmt=fmt, robot=options.get("robot"),
                     torque_source=options.get("torque_source"), time_source=tsrc,
                     sha256=sha)


def _read_channels(p: Path, where: str, suffix: str, folder: bool, cmap: Any,
                   topic: str | None, reference_topic: str | None, time_source: str | None,
                   time_unit: str | None) -> tuple[Any, str, str, str]:
    from .paths import log_sha256

    tsrc = "column"
    sha = log_sha256(p)
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
    return ch, fmt, tsrc, sha
