"""What a log path is: its format by suffix, its stem, its sha256, and the read options
that apply to it (:func:`open_log_options`).

A log is a file, or a rosbag2 folder (a folder holding ``metadata.yaml``): its stem is the
folder's name and its sha256 that of its files' sha256s in name order
(:func:`folder_sha256`). Any other folder stands for the logs in it (:func:`folder_logs`:
the files of a recognised format and the rosbag2 folders directly inside, by name): the
verbs that take many logs read them all (:func:`impactcli.logs.urls.expand_inputs`, as a
glob), a verb that takes one reads a folder's one log (:func:`one_log_in`); several are a
usage error (exit 2) listing them, none a data error (exit 3) naming what was looked for.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
from pathlib import Path
from typing import Any

from ..errors import EXIT_USAGE, ImpactError, LogFormatError
from ..types import ReadOptions

#: Recognised log suffixes (lower case), longest first.
LOG_SUFFIXES: tuple[str, ...] = (".csv.gz", ".csv", ".mcap", ".npz", ".bag", ".db3")
#: Suffixes of message logs (topics, --time-source, channel maps naming fields).
MESSAGE_SUFFIXES: tuple[str, ...] = (".mcap", ".bag", ".db3")
#: The file that makes a folder a rosbag2.
ROSBAG2_METADATA = "metadata.yaml"
#: The read options a log reader takes (``read_log``'s keyword arguments).
READ_OPTIONS: tuple[str, ...] = ("robot", *(f.name for f in dataclasses.fields(ReadOptions)))
#: The read options a timeline records (``input.read_options``) and ``report`` reads a
#: timeline's log again with: all but the robot (``--robot``, given as itself).
RECORDED_READ_OPTIONS: tuple[str, ...] = tuple(k for k in READ_OPTIONS if k != "robot")
#: ``--position-unit``: the unit of a log's positions (and their references, velocities
#: and accelerations, per second): converted to radians as they are read.
POSITION_UNITS: tuple[str, ...] = ("rad", "deg")


#: At most this many logs are named when a folder holds several for a verb reading one.
MAX_LISTED = 10
#: What a folder is searched for, in messages.
LOOKED_FOR = (f"{', '.join(LOG_SUFFIXES)} files or rosbag2 folders (with metadata.yaml), "
              "directly inside it")


class SeveralLogsError(ImpactError):
    """A folder of several logs given to a verb that reads one: a usage error (exit 2)."""

    exit_code = EXIT_USAGE


def log_suffix(path: Path) -> str | None:
    """The format suffix of ``path`` (one of :data:`LOG_SUFFIXES`), None when unknown."""
    name = path.name.lower()
    return next((s for s in LOG_SUFFIXES if name.endswith(s)), None)


#: What a detection timeline's (or another JSON output's) name ends with, longest first.
JSON_SUFFIXES: tuple[str, ...] = (".timeline.json", ".json")


def log_stem(path: str | os.PathLike[str]) -> str:
    """The stem every output is named by — the one stem function of the package: the file
    name (of a path or a URL, ``s3://b/x/run.csv.gz`` → ``run``) without its format
    extension (``.csv``, ``.csv.gz``, ``.mcap``, ``.npz``, ``.bag``, ``.db3``), a rosbag2
    folder's own name (``run/`` → ``run``), a timeline's (``x.timeline.json`` → ``x``)."""
    name = os.path.basename(str(path).rstrip("/\\")) or str(path)
    lower = name.lower()
    for ext in JSON_SUFFIXES:
        if lower.endswith(ext):
            return name[: -len(ext)]
    s = log_suffix(Path(name))
    return name[: -len(s)] if s else name


def is_rosbag2_folder(path: Path) -> bool:
    """Whether ``path`` is a folder holding a rosbag2 ``metadata.yaml``."""
    return path.is_dir() and (path / ROSBAG2_METADATA).is_file()


def is_log_path(path: Path) -> bool:
    """Whether ``path`` can be a local log: a file, or a rosbag2 folder (``metadata.yaml``)."""
    return path.is_file() or is_rosbag2_folder(path)


def folder_logs(path: Path) -> list[Path]:
    """The logs in a folder that is not a rosbag2 folder, by name: its files of a
    recognised format (:data:`LOG_SUFFIXES`) and the rosbag2 folders directly inside it
    (hidden entries, ``.name``, left out; not recursive)."""
    try:
        entries = sorted(path.iterdir(), key=lambda p: p.name)
    except OSError as err:
        raise LogFormatError(f"{path}: cannot list the folder: {err.strerror or err}") from err
    return [p for p in entries if not p.name.startswith(".") and (
        (p.is_file() and log_suffix(p) is not None) or is_rosbag2_folder(p))]


def one_log_in(path: Path, where: str | None = None) -> Path:
    """The log a verb that reads one log reads for ``path``: ``path`` itself (a file, a
    rosbag2 folder), or the one log of a folder that is no rosbag2 folder.

    Raises:
        LogFormatError: a folder without a log (naming what was looked for).
        SeveralLogsError: a folder of several logs (listing them; exit 2).
    """
    if not path.is_dir() or is_rosbag2_folder(path):
        return path
    where = where or str(path)
    logs = folder_logs(path)
    if not logs:
        raise LogFormatError(f"{where}: a folder without any log (looked for {LOOKED_FOR})")
    if len(logs) > 1:
        names = [p.name + ("/" if p.is_dir() else "") for p in logs[:MAX_LISTED]]
        more = f", … and {len(logs) - MAX_LISTED} more" if len(logs) > MAX_LISTED else ""
        raise SeveralLogsError(
            f"{where}: a folder of {len(logs)} logs ({', '.join(names)}{more}), and this verb "
            "reads one: name the log (detect and report read every log of a folder)")
    return logs[0]


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
    sha256 of its files' hex sha256s in name order (a file's from
    :func:`prefetch_sha256` when it was started for the same file, unchanged since)."""
    from ..files import sha256_file

    p = Path(path)
    if p.is_dir():
        return folder_sha256(p)
    pending = _PREFETCHED.pop(_file_key(p), None)
    if pending is not None:
        pending.done.wait()
        if pending.sha256 is not None:
            return pending.sha256
    return sha256_file(p)  # not prefetched, or the prefetch failed: its error, raised here


class _Hashing:
    """A file's sha256 being made on a daemon thread (:func:`prefetch_sha256`)."""

    def __init__(self, path: Path) -> None:
        import threading

        self.path = path
        self.sha256: str | None = None
        self.done = threading.Event()
        threading.Thread(target=self._work, name="impactcli-sha256", daemon=True).start()

    def _work(self) -> None:
        from ..files import sha256_file

        try:
            self.sha256 = sha256_file(self.path)
        except OSError:
            pass  # log_sha256 reads it again and raises
        finally:
            self.done.set()


#: (resolved path, size, mtime) → the hash :func:`prefetch_sha256` started for it
_PREFETCHED: dict[tuple[str, int, int], _Hashing] = {}


def _file_key(p: Path) -> tuple[str, int, int]:
    try:
        st = p.stat()
        return (str(p.resolve()), st.st_size, st.st_mtime_ns)
    except OSError:
        return (str(p), -1, -1)


def prefetch_sha256(path: str | os.PathLike[str]) -> None:
    """Start hashing a local log file on a daemon thread now: a run's start-up (its
    imports) leaves a core idle, and the scan's hash (about 3 s per GB on a core without
    SHA extensions) then costs the scan less. :func:`log_sha256` takes the result when the
    file's size and modification time are still the same. Folders, URLs and missing
    files are left to the scan."""
    p = Path(path)
    if not p.is_file():
        return
    key = _file_key(p)
    if key not in _PREFETCHED:
        _PREFETCHED[key] = _Hashing(p)


def check_read_options(options: dict[str, Any]) -> None:
    """TypeError naming the keyword arguments that are not read options."""
    unknown = set(options) - set(READ_OPTIONS)
    if unknown:
        raise TypeError(f"unknown read options: {', '.join(sorted(unknown))}")


def check_time_options(where: str, time_unit: str | None, time_column: str | None,
                       rate: Any, position_unit: str | None) -> float | None:
    """The values of ``--time-unit``, ``--time-column``, ``--rate`` and
    ``--position-unit`` checked (``--rate`` excludes the other two): the rate [Hz] as a
    float (None without one); LogFormatError naming the bad one."""
    import math

    from .channel_map import TIME_UNITS

    if time_unit is not None and time_unit not in TIME_UNITS:
        raise LogFormatError(f"{where}: unknown time unit {time_unit!r} (s, ms, us or ns)")
    if position_unit is not None and position_unit not in POSITION_UNITS:
        raise LogFormatError(f"{where}: unknown position unit {position_unit!r} (rad or deg)")
    if time_column is not None and not str(time_column).strip():
        raise LogFormatError(f"{where}: --time-column needs a column's name")
    if rate is None:
        return None
    try:
        hz = float(rate)
    except (TypeError, ValueError):
        raise LogFormatError(f"{where}: --rate {rate!r} is not a number of Hz") from None
    if not (math.isfinite(hz) and hz > 0):
        raise LogFormatError(f"{where}: --rate {rate!r} must be a positive number of Hz")
    if time_unit is not None or time_column is not None:
        raise LogFormatError(f"{where}: --rate places sample i at i / rate: it excludes "
                             "--time-unit and --time-column")
    return hz


def _map_time(cmap: Any, where: str, time_unit: str | None, time_column: str | None,
              rate: float | None) -> Any:
    """A CSV or .npz channel map with ``--time-column`` / ``--time-unit`` applied to its
    time (``--time-column`` replaces its column or key, in the unit ``--time-unit``, else
    the unit its name says, else the map's); with ``--rate``, the map's time is not read as
    the clock (warned when it names one; the layout compares it with the rate)."""
    from .channel_map import ChannelRef, TimeSpec
    from .csv.csv_header import name_unit

    mapname = cmap.path or cmap.name
    if rate is not None:
        if cmap.time is not None:  # the user's rate wins over the map's clock, warned
            import warnings

            from ..errors import ImpactWarning

            warnings.warn(
                f"{where}: --rate {rate:g} given: sample i is placed at i / {rate:g} s and "
                f"the time channel map {mapname} names ({cmap.time.ref.label()}) is not read "
                "as the log's clock (compared with it, where the file has it)", ImpactWarning,
                stacklevel=2)
        return cmap  # the layouts read no clock under --rate; they compare the map's time
    if time_column is not None:
        src: str | int = time_column
        if cmap.format != "npz" and not cmap.header and str(time_column).isdigit():
            src = int(time_column)  # a headerless CSV's columns are numbered
        old = cmap.time or TimeSpec(ChannelRef(src))
        unit = time_unit or name_unit(str(time_column)) or old.unit
        return dataclasses.replace(cmap, time=dataclasses.replace(
            old, ref=ChannelRef(src), unit=unit))
    if time_unit is not None and cmap.time is not None:
        return dataclasses.replace(cmap, time=dataclasses.replace(cmap.time, unit=time_unit))
    return cmap


def open_log_options(
    path: str | os.PathLike[str], *, channel_map: Any = None, topic: str | None = None,
    reference_topic: str | None = None, time_source: str | None = None,
    torque_source: str | None = None, time_unit: str | None = None,
    time_column: str | None = None, rate: Any = None, position_unit: str | None = None,
) -> tuple[Path, str, str, bool, Any]:
    """Check a local log path and the read options that apply to it; load the channel map.

    Returns:
        ``(path, where, suffix, folder, cmap)``: the path, it as text for messages, its
        format suffix (``rosbag2`` for a folder), whether it is a folder, the channel map
        (None without one; ``--time-unit`` and ``--time-column`` applied to its time).

    Raises:
        LogFormatError: a missing or unknown file, or options that do not apply to it.
        ChannelMapError: a channel map that does not load.
    """
    from .channel_map import load_channel_map
    from .channels import check_torque_source

    p = Path(path)
    where = str(path)
    check_torque_source(torque_source, where)
    hz = check_time_options(where, time_unit, time_column, rate, position_unit)
    if not p.exists():
        if any(c in where for c in "*?["):
            raise LogFormatError(f"{where}: the pattern matches no file")
        raise LogFormatError(f"{where}: log file not found")
    if p.is_dir() and not is_rosbag2_folder(p):  # a folder of logs: its one log
        p = one_log_in(p, where)
        where = str(p)
    folder = p.is_dir()
    if folder:
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
    if messages:
        given = [opt for opt, v in (("--time-unit", time_unit), ("--time-column", time_column),
                                    ("--rate", rate)) if v is not None]
        if given:
            raise LogFormatError(f"{where}: {', '.join(given)} appl"
                                 f"{'ies' if len(given) == 1 else 'y'} to CSV and .npz logs "
                                 "only (MCAP and bag stamps are ns)")
    cmap = load_channel_map(channel_map) if channel_map is not None else None
    if cmap is not None and not messages and cmap.format == "messages":
        raise LogFormatError(f"{where}: channel map {cmap.path or cmap.name} names message "
                             "fields (format: messages): it is for MCAP logs and ROS bags")
    if cmap is not None and not messages:
        cmap = _map_time(cmap, where, time_unit, time_column, hz)
    return p, where, suffix, folder, cmap
