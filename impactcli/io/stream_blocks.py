"""Message logs read block by block for :mod:`impactcli.io.stream_msgs`.

A *block* is ``{topic: [Batch, ...]}``: the messages of consecutive records, in file order
(:class:`~impactcli.io.mcap_scan.Batch`: bytes, times and each message's index in the
file's order), so the readers of :mod:`impactcli.io.messages` decode them as they decode
a whole topic.

- MCAP (:class:`McapBlocks`): the file is read record by record; each chunk is read,
  decompressed and walked by :mod:`impactcli.io.mcap_scan`'s own walker, alone (a block);
  loose message records between chunks are walked in runs of about 1 MiB. Schemas and
  channels are kept as they come. A file whose records stop early (no DataEnd or Footer,
  or a record running past the end) is ``truncated``, its complete records kept — as
  :func:`~impactcli.io.mcap_scan.scan_mcap` does. :meth:`McapBlocks.summary` reads the
  schemas and channels alone, from the summary section at the file's end.
- ROS bags (:class:`BagBlocks`): rosbags' ``AnyReader`` messages of the topics asked for,
  in the bag's order, :data:`BAG_BLOCK` messages a block.

Memory: one chunk (or one block of bag messages) at a time. What these readers cannot do
as the whole-file reader does raises ``_NotStreamable`` (an unknown compression, an error:
the whole-file reader then raises its own message).
"""

from __future__ import annotations

import struct
from collections.abc import Collection, Iterator
from pathlib import Path

import numpy as np

from ..errors import LogFormatError
from ._whole import NotStreamable as _NotStreamable
from .mcap_scan import MAGIC, OP_CHUNK, OP_DATA_END, OP_FOOTER, Batch, McapScan, UnsupportedMcap

#: Bag messages per block.
BAG_BLOCK = 8192
#: Loose MCAP records (outside chunks) walked together, up to about this many bytes.
LOOSE_BYTES = 1 << 20

Block = dict[str, list[Batch]]


class McapBlocks:
    """An MCAP file's messages, chunk by chunk (module docstring). After a pass over
    :meth:`blocks`: ``scan`` holds the schemas and channels, ``scan.n_messages`` and
    ``scan.truncated`` as :func:`~impactcli.io.mcap_scan.scan_mcap` gives them."""

    kind = "mcap"

    def __init__(self, path: Path, where: str) -> None:
        self.path, self.where = path, where
        self.scan = McapScan()

    def summary(self) -> McapScan:
        """The schemas and channels of the file's summary section (read from its end,
        without the messages).

        Raises:
            _NotStreamable: no footer or no summary (a truncated file, a writer that
                leaves it out): their channels are known after a pass only.
        """
        from .mcap_scan import _Collector

        scan = McapScan()
        try:
            with open(self.path, "rb") as f:
                f.seek(0, 2)
                size = f.tell()
                if size < 8 + 37:
                    raise _NotStreamable("no footer")
                f.seek(size - 37)
                tail = f.read(37)
                op, _, start = struct.unpack_from("<BQQ", tail)
                if tail[29:] != MAGIC or op != OP_FOOTER or not 8 <= start < size - 37:
                    raise _NotStreamable("no summary section")
                f.seek(start)
                buf = f.read(size - 37 - start)
            _Collector(scan).walk(buf, np.frombuffer(buf, dtype=np.uint8), 0, len(buf),
                                  self.where, inside_chunk=False)
        except (OSError, LogFormatError, ValueError, struct.error) as err:
            raise _NotStreamable(str(err)) from err
        return scan

    def blocks(self, topics: Collection[str] | None = None) -> Iterator[Block]:
        """The blocks of the messages of ``topics`` (None: every topic)."""
        from .mcap_scan import _Collector

        self.scan = scan = McapScan()
        col = _Collector(scan)
        try:
            with open(self.path, "rb") as f:
                f.seek(0, 2)
                size = f.tell()
                f.seek(0)
                if f.read(8) != MAGIC:
                    raise _NotStreamable("not an MCAP file")
                loose = bytearray()
                done = False
                while not done:
                    head = f.read(9)
                    body = b""
                    if len(head) == 9:
                        op, ln = struct.unpack("<BQ", head)
                        if f.tell() + ln > size:
                            break  # a record running past the end: truncated
                        body = f.read(ln)
                    if len(head) < 9 or len(body) < ln:
                        break  # the records stop early: truncated
                    done = op in (OP_DATA_END, OP_FOOTER)
                    if op == OP_CHUNK or done or len(loose) > LOOSE_BYTES:
                        yield from self._walk(col, bytes(loose), topics)
                        loose = bytearray()
                    if op == OP_CHUNK:
                        yield from self._walk(col, head + body, topics)
                    elif not done:
                        loose += head + body
                if not done:
                    yield from self._walk(col, bytes(loose), topics)
                scan.truncated = not done
        except (OSError, LogFormatError, UnsupportedMcap, ValueError, struct.error) as err:
            raise _NotStreamable(str(err)) from err
        scan.n_messages = col.count

    def _walk(self, col: object, buf: bytes, topics: Collection[str] | None
              ) -> Iterator[Block]:
        """Walk whole records ``buf`` (:class:`~impactcli.io.mcap_scan._Collector`); the
        messages found, by topic."""
        if not buf:
            return
        scan = self.scan
        col.walk(buf, np.frombuffer(buf, dtype=np.uint8), 0, len(buf), self.where,  # type: ignore[attr-defined]
                 inside_chunk=False)
        col.run_pending(buf, self.where)  # type: ignore[attr-defined]
        out: Block = {}
        for cid, batches in scan.batches.items():
            topic = scan.channels[cid][0]
            if topics is None or topic in topics:
                out.setdefault(topic, []).extend(batches)
        scan.batches = {}
        if out:
            yield out


class BagBlocks:
    """A ROS bag's messages (:class:`~impactcli.io.bags.BagSource`), :data:`BAG_BLOCK` at
    a time, in the bag's order."""

    def __init__(self, src: object) -> None:
        self.src = src

    def blocks(self, topics: Collection[str] | None = None) -> Iterator[Block]:
        src = self.src
        rows: list[tuple[str, int, int, bytes]] = []
        try:
            with src._open() as reader:  # type: ignore[attr-defined]
                conns = [c for c in reader.connections if topics is None or c.topic in topics]
                for k, (c, ts, raw) in enumerate(reader.messages(connections=conns)):
                    rows.append((c.topic, k, ts, bytes(raw)))
                    if len(rows) == BAG_BLOCK:
                        yield _bag_block(rows)
                        rows = []
        except LogFormatError as err:
            raise _NotStreamable(str(err)) from err
        except Exception as err:  # a damaged chunk or database page: the reader says so
            raise _NotStreamable(str(err)) from err
        if rows:
            yield _bag_block(rows)


def _bag_block(rows: list[tuple[str, int, int, bytes]]) -> Block:
    """Bag messages ``(topic, index, time, bytes)`` as one batch per topic
    (:func:`~impactcli.io.bags.bag_batch`)."""
    from .bags import bag_batch

    return {topic: [bag_batch([r[1:] for r in rows if r[0] == topic])]
            for topic in dict.fromkeys(r[0] for r in rows)}
