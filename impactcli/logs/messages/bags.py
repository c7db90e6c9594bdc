"""ROS bags (docs/formats.md, "MCAP", last bullets), read through ``rosbags``: rosbag2 (a
folder with ``metadata.yaml`` — its split files, SQLite ``.db3`` or MCAP storage, read as
one log in time order — or a ``.db3`` file alone; messages in ROS 2 CDR) and ROS 1
``.bag`` files.

They are read exactly as MCAP logs (:mod:`impactcli.logs.messages.message_read`), :data:`BAG_BLOCK`
messages a block (:class:`BagBlocks`). A bag stores one time per message, the recorder's
receive time: it is the ``log`` time, and ``publish`` time is the same. Message types are
decoded with the definitions stored in the bag; a bag without any (old rosbag2 databases)
with rosbags' latest ROS 2 (or ROS 1 Noetic) types. A corrupt or truncated bag is one
:class:`~impactcli.errors.LogFormatError` naming the file. A folder's identity and stem:
:mod:`impactcli.logs.paths`; the writers: :mod:`impactcli.logs.write`.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import LogFormatError
from .message_source import Batch, MessageSource, TopicData, normalize_type


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
        with self.open_reader() as reader:
            enc = "ros1" if self.kind == "rosbag1" else "cdr"
            for c in reader.connections:
                ser = getattr(c.ext, "serialization_format", enc)
                self._topics.setdefault(c.topic, (normalize_type(c.msgtype),
                                                  "cdr" if ser == "cdr" else ser))
            self._store = reader.typestore

    def open_reader(self) -> Any:
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
        with self.open_reader() as reader:
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


#: Bag messages per block.
BAG_BLOCK = 8192


class BagBlocks:
    """A ROS bag's messages (:class:`BagSource`), :data:`BAG_BLOCK` at a time, in the
    bag's order: blocks ``{topic: [Batch]}`` as :class:`~impactcli.logs.messages.mcap.McapBlocks`
    gives them."""

    kind = "bag"

    def __init__(self, src: BagSource) -> None:
        self.src = src

    def blocks(self, topics: Collection[str] | None = None) -> Iterator[dict[str, list[Batch]]]:
        """The blocks of the messages of ``topics`` (None: every topic).

        Raises:
            LogFormatError: a corrupt, truncated or unreadable bag.
        """
        src = self.src
        rows: list[tuple[str, int, int, bytes]] = []
        with src.open_reader() as reader:
            conns = [c for c in reader.connections if topics is None or c.topic in topics]
            try:
                for k, (c, ts, raw) in enumerate(reader.messages(connections=conns)):
                    rows.append((c.topic, k, ts, bytes(raw)))
                    if len(rows) == BAG_BLOCK:
                        yield _bag_block(rows)
                        rows = []
            except Exception as err:  # a damaged chunk or database page
                raise _bag_error(src.where, src.kind, err) from err
        if rows:
            yield _bag_block(rows)


def _bag_block(rows: list[tuple[str, int, int, bytes]]) -> dict[str, list[Batch]]:
    """Bag messages ``(topic, index, time, bytes)`` as one batch per topic."""
    return {topic: [bag_batch([r[1:] for r in rows if r[0] == topic])]
            for topic in dict.fromkeys(r[0] for r in rows)}
