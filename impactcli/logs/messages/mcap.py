"""MCAP files read record by record, chunk by chunk (:class:`McapBlocks`): schemas,
channels and the messages of each chunk located in bulk, for the message reader
(:mod:`impactcli.logs.messages.message_read`).

The official ``mcap`` reader yields one Python object per message. This walker reads the
file's records in order, decompresses each chunk once (zstd, lz4 or none) and locates its
message records without building per-message objects: a chunk whose records all have the
same size (one channel, fixed-size messages — the common case for JointState), or whose
sizes repeat with a short period (a state topic and its companions written in turn), is
viewed as a NumPy structured array; any other is walked record by record. A *block* is the
messages of one chunk (or of a run of records outside chunks), by topic, as
:class:`~impactcli.logs.messages.message_source.Batch` es: bytes, times and each message's
index in the file's order. Files with a compression the walker does not know are read through the
official reader (:class:`OfficialBlocks`, the same blocks).

Truncation: a file with a valid magic whose records stop early (no DataEnd/Footer, or a
record running past the end) is ``truncated``; the complete records before the cut are
kept. Unknown record types are skipped, as the MCAP spec requires.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import LogFormatError
from .message_source import Batch, MessageSource, TopicData, normalize_type

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 1, 2, 3, 4, 5, 6
OP_DATA_END = 15
#: bytes of a message record before its data: opcode(1) length(8) channel(2) seq(4) times(16)
MSG_PREFIX = 31
#: The longest period of record sizes located in bulk (:meth:`RecordWalker._periodic`).
MAX_PERIOD = 8


#: Loose records (outside chunks) walked together, up to about this many bytes.
LOOSE_BYTES = 1 << 20
#: Messages of a block read through the official reader.
OFFICIAL_BLOCK = 8192

Block = dict[str, list[Batch]]
#: What parsing a damaged record's fields raises (a length past the record, a name that is
#: not UTF-8, a size no memory holds): the file is corrupt (a LogFormatError naming it).
RECORD_ERRORS = (struct.error, UnicodeDecodeError, IndexError, OverflowError, MemoryError)


class UnsupportedMcap(Exception):
    """Something the walker does not handle (an unknown compression): use the official
    reader."""


@dataclass
class McapScan:
    """What :func:`scan_mcap` found."""

    schemas: dict[int, tuple[str, str, bytes]] = field(default_factory=dict)
    channels: dict[int, tuple[str, int, str]] = field(default_factory=dict)
    batches: dict[int, list[Batch]] = field(default_factory=dict)
    truncated: bool = False
    n_messages: int = 0

    def topics(self) -> dict[str, list[int]]:
        """Topic → channel ids."""
        out: dict[str, list[int]] = {}
        for cid, (topic, _, _) in self.channels.items():
            out.setdefault(topic, []).append(cid)
        return out


def _string(buf: bytes, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    return bytes(buf[pos + 4 : pos + 4 + n]).decode("utf-8"), pos + 4 + n


def _decompress(kind: str, data: bytes, size: int) -> bytes:
    if kind == "":
        return bytes(data)
    if kind == "zstd":
        import zstandard

        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if kind == "lz4":
        import lz4.frame

        return bytes(lz4.frame.decompress(data))
    raise UnsupportedMcap(f"compression {kind!r}")


_MSG_DTYPE_FIELDS = {
    "names": ["op", "len", "ch", "lt", "pt"],
    "formats": ["u1", "<u8", "<u2", "<u8", "<u8"],
    "offsets": [0, 1, 9, 15, 23],
}


class RecordWalker:
    """Walks MCAP records into an :class:`McapScan` (schemas, channels, and the
    messages' batches by channel), counting the messages in file order; ``offset`` is the
    file position of the buffers walked (errors name file positions)."""

    def __init__(self, scan: McapScan) -> None:
        self.scan = scan
        self.count = 0
        self.offset = 0
        self.pending: list[tuple[str, Any]] = []

    def add(self, buf: np.ndarray, ch: np.ndarray, off: np.ndarray, ln: np.ndarray,
            lt: np.ndarray, pt: np.ndarray) -> None:
        n = off.shape[0]
        order = np.arange(self.count, self.count + n, dtype=np.int64)
        self.count += n
        uniq = [int(ch[0])] if n and bool(np.all(ch == ch[0])) else np.unique(ch).tolist()
        for cid in uniq:
            sel = slice(None) if len(uniq) == 1 else ch == cid
            self.scan.batches.setdefault(int(cid), []).append(Batch(
                buf, off[sel].astype(np.int64), ln[sel].astype(np.int64),
                lt[sel].astype(np.int64), pt[sel].astype(np.int64), order[sel],
            ))

    def walk(self, buf: bytes, arr: np.ndarray, start: int, end: int, where: str,
             inside_chunk: bool) -> tuple[int, bool]:
        """Walk records in ``buf[start:end]``; returns (stop position, reached DataEnd/Footer)."""
        scan = self.scan
        # fast path: a run of equal-size message records
        if inside_chunk and end - start >= 9 and buf[start] == OP_MESSAGE:
            (ln0,) = struct.unpack_from("<Q", buf, start + 1)
            stride = 9 + ln0
            total = end - start
            if ln0 >= 22 and total % stride == 0:
                dt = np.dtype({**_MSG_DTYPE_FIELDS, "itemsize": stride})  # type: ignore[call-overload]
                rec = np.frombuffer(buf, dtype=dt, count=total // stride, offset=start)
                if np.all(rec["op"] == OP_MESSAGE) and np.all(rec["len"] == ln0):
                    n = rec.shape[0]
                    off = start + np.arange(n, dtype=np.int64) * stride + MSG_PREFIX
                    self.add(arr, rec["ch"].astype(np.int64), off,
                             np.full(n, ln0 - 22, dtype=np.int64), rec["lt"], rec["pt"])
                    return end, False
        if inside_chunk:  # records whose sizes repeat: located in bulk, the rest walked
            start = self._periodic(buf, arr, start, end)
        chs: list[int] = []
        offs: list[int] = []
        lens: list[int] = []
        lts: list[int] = []
        pts: list[int] = []
        pos = start
        unpack = struct.unpack_from
        done = False
        while pos < end:
            if pos + 9 > end:
                if inside_chunk:
                    raise LogFormatError(f"{where}: corrupt chunk: record header cut at byte {pos}")
                scan.truncated = True
                break
            op, ln = unpack("<BQ", buf, pos)
            body = pos + 9
            if body + ln > end:
                if inside_chunk:
                    raise LogFormatError(f"{where}: corrupt chunk: record runs past the chunk")
                scan.truncated = True
                break
            if op == OP_MESSAGE:
                if ln < 22:
                    raise LogFormatError(f"{where}: corrupt message record at byte "
                                         f"{pos + self.offset}")
                ch, lt, pt = unpack("<H4xQQ", buf, body)
                chs.append(ch)
                offs.append(body + 22)
                lens.append(ln - 22)
                lts.append(lt)
                pts.append(pt)
            elif op == OP_CHUNK and not inside_chunk:
                if chs:
                    self.pending.append(("msgs", (arr, chs, offs, lens, lts, pts)))
                    chs, offs, lens, lts, pts = [], [], [], [], []
                self.pending.append(("chunk", (body, body + ln)))
            elif op == OP_SCHEMA:
                (sid,) = unpack("<H", buf, body)
                name, p = _string(buf, body + 2)
                enc, p = _string(buf, p)
                (dl,) = unpack("<I", buf, p)
                scan.schemas[sid] = (name, enc, bytes(buf[p + 4 : p + 4 + dl]))
            elif op == OP_CHANNEL:
                cid, sid = unpack("<HH", buf, body)
                topic, p = _string(buf, body + 4)
                menc, p = _string(buf, p)
                scan.channels[cid] = (topic, sid, menc)
            elif op in (OP_DATA_END, OP_FOOTER) and not inside_chunk:
                done = True
                pos = body + ln
                break
            pos = body + ln
        if chs:
            if inside_chunk:
                self._flush(arr, chs, offs, lens, lts, pts)
            else:
                self.pending.append(("msgs", (arr, chs, offs, lens, lts, pts)))
        return pos, done

    def _periodic(self, buf: bytes, arr: np.ndarray, start: int, end: int) -> int:
        """Add the message records from ``start`` on whose sizes repeat with a period of
        at most :data:`MAX_PERIOD` records (a state topic and its companions written in
        turn), found with NumPy and checked record by record; returns where the records
        not added start (``start`` when the chunk has no such run)."""
        lens: list[int] = []
        pos = start
        while len(lens) < 2 * MAX_PERIOD and pos + 9 <= end and buf[pos] == OP_MESSAGE:
            (ln,) = struct.unpack_from("<Q", buf, pos + 1)
            lens.append(ln)
            pos += 9 + ln
        period = next((p for p in range(1, len(lens) // 2 + 1)
                       if lens[p:2 * p] == lens[:p]), 0)
        if not period or min(lens[:period]) < 22:
            return start
        rel = np.cumsum([0] + [9 + ln for ln in lens[:period]])
        stride = int(rel[-1])
        m = (end - start) // stride
        if m < 2:
            return start
        at = (start + np.arange(m, dtype=np.int64)[:, None] * stride + rel[None, :-1]).ravel()

        def field(off: int, dtype: str, size: int) -> np.ndarray:
            return arr[at[:, None] + np.arange(off, off + size)].view(dtype).ravel()

        want = np.tile(np.asarray(lens[:period], dtype=np.uint64), m)
        if not (np.all(arr[at] == OP_MESSAGE) and np.array_equal(field(1, "<u8", 8), want)):
            return start
        self.add(arr, field(9, "<u2", 2).astype(np.int64), at + MSG_PREFIX,
                 want.astype(np.int64) - 22, field(15, "<u8", 8), field(23, "<u8", 8))
        return start + m * stride

    def run_pending(self, buf: bytes, where: str) -> None:
        """Decompress the chunks found at top level (once each) and walk them, and the
        loose messages, in file order."""
        for kind, args in self.pending:
            if kind == "chunk":
                raw = _chunk_bytes(buf, args[0], args[1], where, self.offset)
                self.walk(raw, np.frombuffer(raw, dtype=np.uint8), 0, len(raw), where,
                          inside_chunk=True)
            else:
                self._flush(*args)
        self.pending = []

    def _flush(self, arr: np.ndarray, chs: list[int], offs: list[int], lens: list[int],
               lts: list[int], pts: list[int]) -> None:
        self.add(arr, np.asarray(chs, dtype=np.int64), np.asarray(offs, dtype=np.int64),
                 np.asarray(lens, dtype=np.int64), np.asarray(lts, dtype=np.uint64),
                 np.asarray(pts, dtype=np.uint64))



def _chunk_bytes(buf: bytes, start: int, end: int, where: str, offset: int = 0) -> bytes:
    """The decompressed records of the chunk record whose body is ``buf[start:end]``
    (``offset``: the file position of ``buf``, for errors)."""
    at = start + offset
    try:
        _st, _et, usize, crc = struct.unpack_from("<QQQI", buf, start)
        kind, p = _string(buf, start + 28)
        (rl,) = struct.unpack_from("<Q", buf, p)
        if p + 8 + rl > end:
            raise LogFormatError(f"{where}: corrupt chunk at byte {at}")
        raw = _decompress(kind, buf[p + 8 : p + 8 + rl], usize)
    except (UnsupportedMcap, LogFormatError):
        raise
    except Exception as err:  # zstd/lz4/struct errors: the chunk is damaged
        raise LogFormatError(f"{where}: corrupt chunk at byte {at}: {err}") from err
    if len(raw) != usize:
        raise LogFormatError(f"{where}: corrupt chunk at byte {at}: wrong size")
    if crc and zlib.crc32(raw) != crc:
        raise LogFormatError(f"{where}: corrupt chunk at byte {at}: CRC mismatch")
    return raw


class McapBlocks:
    """An MCAP file's messages, block by block (module docstring). After a pass over
    :meth:`blocks`: ``scan`` holds the schemas and channels, ``scan.n_messages`` and
    ``scan.truncated``."""

    kind = "mcap"

    def __init__(self, path: Path, where: str) -> None:
        self.path, self.where = path, where
        self.scan = McapScan()

    def summary(self) -> McapScan | None:
        """The schemas and channels of the file's summary section (read from its end,
        without the messages); None without a footer or summary (a truncated file, a
        writer that leaves it out)."""
        scan = McapScan()
        try:
            with open(self.path, "rb") as f:
                f.seek(0, 2)
                size = f.tell()
                if size < 8 + 37:
                    return None
                f.seek(size - 37)
                tail = f.read(37)
                op, _, start = struct.unpack_from("<BQQ", tail)
                if tail[29:] != MAGIC or op != OP_FOOTER or not 8 <= start < size - 37:
                    return None
                f.seek(start)
                buf = f.read(size - 37 - start)
            RecordWalker(scan).walk(buf, np.frombuffer(buf, dtype=np.uint8), 0, len(buf),
                                    self.where, inside_chunk=False)
        except (OSError, LogFormatError, ValueError, struct.error):
            return None
        return scan if scan.channels else None

    def blocks(self, topics: Collection[str] | None = None) -> Iterator[Block]:
        """The blocks of the messages of ``topics`` (None: every topic).

        Raises:
            LogFormatError: not an MCAP file, not readable, a damaged chunk.
            UnsupportedMcap: a compression the walker does not handle.
        """
        self.scan = scan = McapScan()
        walker = RecordWalker(scan)
        where = self.where
        try:
            f = open(self.path, "rb")  # noqa: SIM115
        except OSError as err:
            raise LogFormatError(f"{where}: cannot read: {err}") from err
        with f:
            try:
                f.seek(0, 2)
                size = f.tell()
                f.seek(0)
                magic = f.read(8)
            except OSError as err:
                raise LogFormatError(f"{where}: cannot read: {err}") from err
            if len(magic) < 8 or magic != MAGIC:
                raise LogFormatError(f"{where}: not an MCAP file (bad magic bytes)")
            loose = bytearray()
            loose_at = 8
            done = False
            while not done:
                at = f.tell()
                head = f.read(9)
                if len(head) < 9:
                    break  # the records stop early: truncated
                op, ln = struct.unpack("<BQ", head)
                if at + 9 + ln > size:
                    break  # a record running past the end: truncated
                body = f.read(ln)
                done = op in (OP_DATA_END, OP_FOOTER)
                if op == OP_CHUNK or done or len(loose) > LOOSE_BYTES:
                    yield from self._walk(walker, bytes(loose), loose_at, topics)
                    loose = bytearray()
                    loose_at = at
                if op == OP_CHUNK:
                    yield from self._walk(walker, head + body, at, topics)
                    loose_at = at + 9 + ln
                elif not done:
                    loose += head + body
            if not done:
                yield from self._walk(walker, bytes(loose), loose_at, topics)
            scan.truncated = not done
        scan.n_messages = walker.count

    def _walk(self, walker: RecordWalker, buf: bytes, at: int, topics: Collection[str] | None
              ) -> Iterator[Block]:
        """Walk whole records ``buf`` (at file position ``at``); the messages found, by
        topic."""
        if not buf:
            return
        scan = self.scan
        walker.offset = at
        try:
            walker.walk(buf, np.frombuffer(buf, dtype=np.uint8), 0, len(buf), self.where,
                        inside_chunk=False)
            walker.run_pending(buf, self.where)
        except RECORD_ERRORS as err:  # a record whose fields do not fit it: damaged
            why = ("a name that is not UTF-8" if isinstance(err, UnicodeDecodeError) else
                   "a field running past its record" if isinstance(err, struct.error | IndexError)
                   else "a size beyond memory")
            raise LogFormatError(f"{self.where}: corrupt MCAP: a damaged record between "
                                 f"bytes {at} and {at + len(buf)} ({why})") from err
        out: Block = {}
        for cid, batches in scan.batches.items():
            topic = scan.channels[cid][0] if cid in scan.channels else ""
            if topics is None or topic in topics:
                out.setdefault(topic, []).extend(batches)
        scan.batches = {}
        if out:
            yield out


class OfficialBlocks:
    """An MCAP file's messages through the official ``mcap`` reader (NonSeekingReader),
    :data:`OFFICIAL_BLOCK` messages a block, for files the walker does not handle; a file
    whose records end early yields the messages before the cut (``scan.truncated``)."""

    kind = "mcap"

    def __init__(self, path: Path, where: str) -> None:
        self.path, self.where = path, where
        self.scan = McapScan()

    def summary(self) -> McapScan | None:
        return None

    def blocks(self, topics: Collection[str] | None = None) -> Iterator[Block]:
        """The blocks of the messages of ``topics`` (None: every topic).

        Raises:
            LogFormatError: not readable, or no complete message.
        """
        from mcap.reader import NonSeekingReader

        self.scan = scan = McapScan()
        where = self.where
        rows: list[tuple[int, int, int, int, bytes]] = []
        count = 0
        try:
            with open(self.path, "rb") as f:
                reader = NonSeekingReader(f)
                try:
                    for schema, channel, msg in reader.iter_messages(log_time_order=False):
                        if schema is not None and schema.id not in scan.schemas:
                            scan.schemas[schema.id] = (schema.name, schema.encoding,
                                                       schema.data)
                        scan.channels.setdefault(channel.id, (
                            channel.topic, schema.id if schema is not None else 0,
                            channel.message_encoding))
                        if topics is None or channel.topic in topics:
                            rows.append((channel.id, count, msg.log_time, msg.publish_time,
                                         msg.data))
                        count += 1
                        if len(rows) == OFFICIAL_BLOCK:
                            yield _official_block(scan, rows)
                            rows = []
                except Exception:  # the cut of a truncated file: keep what came before
                    if not count:
                        raise
                    scan.truncated = True
        except OSError as err:
            raise LogFormatError(f"{where}: cannot read: {err}") from err
        except LogFormatError:
            raise
        except Exception as err:
            first = (str(err).splitlines() or [type(err).__name__])[0]
            raise LogFormatError(f"{where}: corrupt MCAP: {first}") from err
        if rows:
            yield _official_block(scan, rows)
        scan.n_messages = count


def _official_block(scan: McapScan, rows: list[tuple[int, int, int, int, bytes]]) -> Block:
    """Messages ``(channel, index, log time, publish time, bytes)`` as a batch per
    topic."""
    out: Block = {}
    for cid in dict.fromkeys(r[0] for r in rows):
        rs = [r for r in rows if r[0] == cid]
        buf = np.frombuffer(b"".join(r[4] for r in rs), dtype=np.uint8)
        lens = np.array([len(r[4]) for r in rs], dtype=np.int64)
        offs = np.concatenate(([0], np.cumsum(lens)[:-1])).astype(np.int64)
        out.setdefault(scan.channels[cid][0], []).append(Batch(
            buf, offs, lens, np.array([r[2] for r in rs], dtype=np.int64),
            np.array([r[3] for r in rs], dtype=np.int64),
            np.array([r[1] for r in rs], dtype=np.int64)))
    return out


def collect_scan(reader: Any) -> McapScan:
    """Every block of a block source in one :class:`McapScan` (its messages by channel):
    a whole file in memory, for tests and small files."""
    batches: dict[str, list[Batch]] = {}
    for block in reader.blocks():
        for topic, bs in block.items():
            batches.setdefault(topic, []).extend(bs)
    scan: McapScan = reader.scan
    by_topic = scan.topics()
    scan.batches = {by_topic[t][0]: bs for t, bs in batches.items() if t in by_topic}
    return scan


def scan_mcap(path: Path) -> McapScan:
    """An MCAP file's messages in one :class:`McapScan` (:class:`McapBlocks`, collected).

    Raises:
        LogFormatError: not an MCAP file, or a damaged chunk.
        UnsupportedMcap: a compression the walker does not handle.
    """
    return collect_scan(McapBlocks(path, str(path)))


def scan_mcap_official(path: Path) -> McapScan:
    """:func:`scan_mcap` through the official reader (:class:`OfficialBlocks`)."""
    return collect_scan(OfficialBlocks(path, str(path)))


class McapSource(MessageSource):
    """An MCAP file's topics and message definitions (its schemas and channels)."""

    kind = "mcap"

    def __init__(self, scan: McapScan, where: str) -> None:
        super().__init__()
        self.scan = scan
        self.where = where
        self._topics: dict[str, tuple[str, str]] = {}
        self._cids: dict[str, list[int]] = {}
        for cid, (topic, sid, menc) in sorted(scan.channels.items()):
            name, senc, _ = scan.schemas.get(sid, ("", "", b""))
            mtype = normalize_type(name) if senc in ("ros2msg", "ros1msg", "ros2idl") else name
            self._topics.setdefault(topic, (mtype, menc))
            self._cids.setdefault(topic, []).append(cid)

    def topics(self) -> dict[str, tuple[str, str]]:
        return dict(self._topics)

    def channel_ids(self, topic: str) -> list[int]:
        """The MCAP channels of ``topic``."""
        return list(self._cids[topic])

    def load(self, topics: Collection[str]) -> dict[str, TopicData]:
        out = {}
        for t in topics:
            mtype, enc = self._topics[t]
            batches = [b for c in self._cids[t] for b in self.scan.batches.get(c, [])]
            out[t] = TopicData(t, mtype, enc, batches)
        return out

    def definitions(self) -> list[tuple[str, str, str]]:
        return [(name, enc, data.decode("utf-8", errors="replace"))
                for name, enc, data in self.scan.schemas.values()
                if enc in ("ros2msg", "ros1msg", "ros2idl")]
