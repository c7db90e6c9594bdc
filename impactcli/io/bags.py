"""ROS bags (formats.md, "MCAP", last bullets), read and written through ``rosbags``.

Inputs:

- rosbag2: a folder with ``metadata.yaml`` (its split files, SQLite ``.db3`` or MCAP
  storage, read as one log in time order) or a ``.db3`` file alone (rosbags reads the
  metadata stored in the database). Format ``rosbag2``; messages are ROS 2 CDR.
- ROS 1: a ``.bag`` file (format ``rosbag1``; messages in ROS 1 serialization).

They are read exactly as MCAP logs (:func:`impactcli.io.messages.read_message_channels`):
the same topic choice, ``_ref``/``_model``/``_ext`` companion topics, time sources and
channel maps with message fields. A bag stores one time per message, the recorder's
receive time: it is the ``log`` time, and ``publish`` time is the same (bags hold no
publish time). Message types are decoded with the definitions stored in the bag; a bag
without any (old rosbag2 databases) is read with rosbags' latest ROS 2 (or ROS 1 Noetic)
types.

A folder's identity (``LogSource.sha256``) is :func:`folder_sha256`: the sha256 of the
concatenated hex sha256 digests of its files, in name order. Its stem
(:func:`impactcli.io.log_stem`) is the folder's own name.

A corrupt or truncated bag is one :class:`~impactcli.errors.LogFormatError` naming the file
(rosbags reads a bag's index, which a truncated ``.bag`` lacks; SQLite refuses a cut
database).

Writers (for tests and conversions): :func:`write_rosbag2` (a ``.db3`` file, or a folder,
optionally split into several files) and :func:`write_rosbag1`, with the JointState topics of
:func:`impactcli.io.mcap_log.jointstate_topics` (``/joint_states``, ``_ref``, ``_model``,
``_ext``).
"""

from __future__ import annotations

import hashlib
import itertools
import os
import shutil
import tempfile
from collections.abc import Collection
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import LogFormatError, OutputError
from ..types import RobotLog
from .mcap_scan import Batch
from .msgsource import MessageSource, TopicData, normalize_type

ROSBAG2_METADATA = "metadata.yaml"


def is_rosbag2_folder(path: Path) -> bool:
    """Whether ``path`` is a folder holding a rosbag2 ``metadata.yaml``."""
    return path.is_dir() and (path / ROSBAG2_METADATA).is_file()


def folder_files(path: Path) -> list[Path]:
    """The regular files directly inside ``path``, in name order."""
    return sorted((p for p in path.iterdir() if p.is_file()), key=lambda p: p.name)


def folder_sha256(path: Path) -> str:
    """sha256 of the concatenated hex sha256 digests of the folder's files, in name order."""
    from .._fs import sha256_file

    h = hashlib.sha256()
    for f in folder_files(path):
        h.update(sha256_file(f).encode("ascii"))
    return h.hexdigest()


def _bag_error(where: str, kind: str, err: BaseException) -> LogFormatError:
    first = (str(err).splitlines() or [type(err).__name__])[0] or type(err).__name__
    what = "ROS 1 bag" if kind == "rosbag1" else "rosbag2"
    hint = (" (a recording cut short has no index: 'rosbag reindex' rebuilds it)"
            if kind == "rosbag1" and "index" in first.lower() else "")
    return LogFormatError(f"{where}: corrupt, truncated or unreadable {what}: {first}{hint}")


class BagSource(MessageSource):
    """A ROS bag through rosbags' ``AnyReader`` (see the module docstring)."""

    def __init__(self, path: Path, where: str) -> None:
        super().__init__()
        self.path = path
        self.where = where
        self.kind = "rosbag1" if path.suffix.lower() == ".bag" else "rosbag2"
        self._default: Any = None
        self._topics: dict[str, tuple[str, str]] = {}
        self._defs: list[tuple[str, str, str]] = []
        with self._open() as reader:
            enc = "ros1" if self.kind == "rosbag1" else "cdr"
            for c in reader.connections:
                ser = getattr(c.ext, "serialization_format", enc)
                self._topics.setdefault(c.topic, (normalize_type(c.msgtype),
                                                  "cdr" if ser == "cdr" else ser))
            self._store = reader.typestore

    def _open(self) -> Any:
        """An open AnyReader (a context manager); bag errors become LogFormatError."""
        from rosbags.highlevel import AnyReader, AnyReaderError

        def make(default: Any) -> Any:
            r = AnyReader([self.path], default_typestore=default)
            r.open()
            return r

        try:
            try:
                reader = make(self._default)
            except AnyReaderError as err:
                if "no type definitions" not in str(err) or self._default is not None:
                    raise
                from rosbags.typesys import Stores, get_typestore

                self._default = get_typestore(
                    Stores.ROS1_NOETIC if self.kind == "rosbag1" else Stores.LATEST)
                reader = make(self._default)
        except Exception as err:  # rosbags, apsw (SQLite), YAML and OS errors alike
            raise _bag_error(self.where, self.kind, err) from err
        return _Closing(reader)

    def topics(self) -> dict[str, tuple[str, str]]:
        return dict(self._topics)

    def definitions(self) -> list[tuple[str, str, str]]:
        return []  # the typestore comes from the reader

    def load(self, topics: Collection[str]) -> dict[str, TopicData]:
        want = set(topics)
        rows: dict[str, list[tuple[int, int, bytes]]] = {t: [] for t in want}
        with self._open() as reader:
            conns = [c for c in reader.connections if c.topic in want]
            try:
                for k, (c, ts, raw) in enumerate(reader.messages(connections=conns)):
                    rows[c.topic].append((k, ts, bytes(raw)))
            except Exception as err:  # a damaged chunk or database page
                raise _bag_error(self.where, self.kind, err) from err
        out = {}
        for t in want:
            rs = rows[t]
            mtype, enc = self._topics[t]
            out[t] = TopicData(t, mtype, enc, [bag_batch(rs)] if rs else [])
        return out


def bag_batch(rows: list[tuple[int, int, bytes]]) -> Batch:
    """Bag messages ``(index in the bag's order, time [ns], bytes)`` as one Batch (log
    time = publish time = the bag's time)."""
    lens = np.array([len(r[2]) for r in rows], dtype=np.int64)
    offs = np.concatenate(([0], np.cumsum(lens)[:-1])).astype(np.int64)
    times = np.array([r[1] for r in rows], dtype=np.int64)
    buf = np.frombuffer(b"".join(r[2] for r in rows), dtype=np.uint8)
    return Batch(buf, offs, lens, times, times.copy(), np.array([r[0] for r in rows],
                                                                dtype=np.int64))


class _Closing:
    def __init__(self, reader: Any) -> None:
        self.reader = reader

    def __enter__(self) -> Any:
        return self.reader

    def __exit__(self, *exc: object) -> None:
        self.reader.close()


def read_bag_channels(
    path: Path, *, topic: str | None, reference_topic: str | None, time_source: str | None,
    cmap: Any = None, where: str | None = None,
) -> tuple[Any, str, str]:
    """Read a ROS bag (``.bag``, ``.db3`` or rosbag2 folder) into JointChannels.

    Returns:
        ``(channels, format, time_source)`` with format ``rosbag1`` or ``rosbag2``.
    """
    from .messages import read_message_channels

    src = BagSource(path, where or str(path))
    if not src.topics():
        raise LogFormatError(f"{src.where}: the bag holds no topics")
    return read_message_channels(src, cmap=cmap, topic=topic, reference_topic=reference_topic,
                                 time_source=time_source)


# --------------------------------------------------------------------------- writers


def _check_ros_times(log: RobotLog, path: Path) -> None:
    if log.t_ns[0] < 0:
        raise LogFormatError(f"{path}: ROS bags cannot hold negative times "
                             f"(first sample {log.t_ns[0]} ns)")


def _ros2_store() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _write_rosbag2_folder(log: RobotLog, folder: Path, parts: list[slice],
                          storage: str) -> None:
    """Write the rosbag2 folder ``folder`` (must not exist) in ``len(parts)`` files."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from ruamel.yaml import YAML

    from .mcap_log import ROS2_TOPIC, jointstate_topics
    from .mcap_ros2 import JOINT_STATE

    topics = jointstate_topics(log, ROS2_TOPIC)
    store = _ros2_store()
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    t = log.t_ns.tolist()
    tmp = Path(tempfile.mkdtemp(prefix=".rosbag2-", dir=folder.parent))
    try:
        metas = []
        subs = []
        for k, part in enumerate(parts):
            # rosbags names the storage file after its folder: <name>_<k>.db3 as ros2 bag does
            sub = tmp / f"part{k}" / f"{folder.name}_{k}"
            subs.append(sub)
            with Writer(sub, version=9, storage_plugin=plugin) as w:
                conns = [w.add_connection(name, JOINT_STATE, typestore=store)
                         for name, _ in topics]
                for i in range(len(t))[part]:
                    # companions first: a state sample never precedes its reference
                    for c, (_, rows) in reversed(list(zip(conns, topics, strict=True))):
                        w.write(c, t[i], rows[i].tobytes())
            yaml = YAML(typ="safe")
            metas.append(yaml.load((sub / ROSBAG2_METADATA).read_text()))
        out = tmp / "bag"
        out.mkdir()
        info = metas[0]["rosbag2_bagfile_information"]
        if len(parts) == 1:
            for f in subs[0].iterdir():
                f.rename(out / f.name)
        else:
            files, rel = [], []
            counts: dict[str, int] = {}
            for k, m in enumerate(metas):
                mi = m["rosbag2_bagfile_information"]
                src = subs[k] / mi["relative_file_paths"][0]
                name = src.name
                src.rename(out / name)
                rel.append(name)
                fi = dict(mi["files"][0], path=name)
                files.append(fi)
                for tw in mi["topics_with_message_count"]:
                    nm = tw["topic_metadata"]["name"]
                    counts[nm] = counts.get(nm, 0) + int(tw["message_count"])
            last = metas[-1]["rosbag2_bagfile_information"]
            start = info["starting_time"]["nanoseconds_since_epoch"]
            end = (last["starting_time"]["nanoseconds_since_epoch"]
                   + last["duration"]["nanoseconds"])
            info = dict(info, relative_file_paths=rel, files=files,
                        message_count=sum(counts.values()),
                        duration={"nanoseconds": end - start})
            info["topics_with_message_count"] = [
                dict(tw, message_count=counts[tw["topic_metadata"]["name"]])
                for tw in info["topics_with_message_count"]
            ]
            yaml = YAML(typ="safe")
            yaml.default_flow_style = False
            with open(out / ROSBAG2_METADATA, "w", encoding="utf-8") as mf:
                yaml.dump({"rosbag2_bagfile_information": info}, mf)
        out.rename(folder)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def write_rosbag2(log: RobotLog, path: str | os.PathLike[str], *, split: int = 1,
                  storage: str = "sqlite3") -> None:
    """Write ``log`` as a rosbag2 (JointState topics, see the module docstring).

    Args:
        log: the log (times ≥ 0).
        path: a ``.db3`` file (written whole or not at all), or a folder that does not exist
            yet (made whole by a rename: a rosbag2 folder is never overwritten).
        split: number of files the folder is split into (consecutive samples; ``.db3``
            needs 1).
        storage: ``sqlite3`` (``.db3`` files) or ``mcap`` (folder only).

    Raises:
        LogFormatError: negative times, bad ``split`` or ``storage``.
        OutputError: the folder exists, or cannot be written.
    """
    p = Path(path)
    _check_ros_times(log, p)
    n = log.n_samples
    if storage not in ("sqlite3", "mcap"):
        raise LogFormatError(f"{p}: unknown rosbag2 storage {storage!r} (sqlite3 or mcap)")
    if not 1 <= split <= n:
        raise LogFormatError(f"{p}: cannot split {n} samples into {split} files")
    edges = np.linspace(0, n, split + 1).round().astype(int).tolist()
    parts = [slice(a, b) for a, b in itertools.pairwise(edges)]
    if p.suffix.lower() == ".db3":
        if split != 1 or storage != "sqlite3":
            raise LogFormatError(f"{p}: a .db3 file is one SQLite file: write a folder to "
                                 "split or to use MCAP storage")
        from .._fs import atomic_output

        with atomic_output(p, "wb") as f:  # checks the target; the .db3 is moved onto it
            tmp = Path(tempfile.mkdtemp(prefix=".rosbag2-", dir=p.parent))
            try:
                _write_rosbag2_folder(log, tmp / "bag", parts, storage)
                db = next((tmp / "bag").glob("*.db3"))
                with open(db, "rb") as src:
                    shutil.copyfileobj(src, f, 1 << 20)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
        return
    if p.exists():
        raise OutputError(f"cannot write {p}: it exists (a rosbag2 folder is never overwritten)")
    p.parent.mkdir(parents=True, exist_ok=True)
    _write_rosbag2_folder(log, p, parts, storage)


def write_rosbag1(log: RobotLog, path: str | os.PathLike[str]) -> None:
    """Write ``log`` as a ROS 1 ``.bag`` (atomically): ``sensor_msgs/JointState`` on
    ``/joint_states`` and the ``_ref``, ``_model``, ``_ext`` companions, as
    :func:`write_rosbag2`; header stamps = bag times = ``t_ns`` (≥ 0, below 2³² s)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from .._fs import atomic_output
    from .mcap_log import ROS2_TOPIC

    p = Path(path)
    _check_ros_times(log, p)
    if log.t_ns[-1] >= 2**32 * 10**9:
        raise LogFormatError(f"{p}: ROS 1 times end in 2106 (last sample {log.t_ns[-1]} ns)")
    store = get_typestore(Stores.ROS1_NOETIC)
    name = "sensor_msgs/msg/JointState"
    JointState = store.types[name]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    empty = np.zeros(0)
    topics: list[tuple[str, list[str], list[np.ndarray | None]]] = [
        (ROS2_TOPIC, list(log.joint_names), [log.position, log.velocity, log.torque])]
    if log.position_ref is not None:
        topics.append((f"{ROS2_TOPIC}_ref", list(log.joint_names),
                       [log.position_ref, log.velocity_ref, None]))
    for suffix, sig in (("_model", "torque_model"), ("_ext", "torque_ext")):
        arr = getattr(log, sig)
        if arr is not None:
            has = log.has_channel(sig)
            topics.append((f"{ROS2_TOPIC}{suffix}",
                           [nm for nm, h in zip(log.joint_names, has, strict=True) if h],
                           [None, None, np.ascontiguousarray(arr[:, has])]))
    with atomic_output(p, "wb") as f:
        fd, tmpname = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp.bag", dir=p.parent)
        os.close(fd)
        tmp = Path(tmpname)
        tmp.unlink()  # rosbags' writer makes the file itself
        try:
            with Writer(tmp) as w:
                conns = [w.add_connection(tn, name, typestore=store) for tn, _, _ in topics]
                for i, t in enumerate(log.t_ns.tolist()):
                    sec, nsec = divmod(t, 10**9)
                    for c, (_, names, arrs) in reversed(list(zip(conns, topics, strict=True))):
                        msg = JointState(
                            header=Header(seq=i, stamp=Time(sec=sec, nanosec=nsec), frame_id=""),
                            name=names,
                            position=empty if arrs[0] is None else arrs[0][i],
                            velocity=empty if arrs[1] is None else arrs[1][i],
                            effort=empty if arrs[2] is None else arrs[2][i],
                        )
                        w.write(c, t, store.serialize_ros1(msg, name))
            with open(tmp, "rb") as src:
                shutil.copyfileobj(src, f, 1 << 20)
        finally:
            tmp.unlink(missing_ok=True)
