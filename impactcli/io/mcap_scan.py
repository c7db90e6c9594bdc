"""A fast record-level MCAP scanner: schemas, channels and message locations, in bulk.

The official ``mcap`` reader yields one Python object per message (~130k msg/s here,
performance.md). This scanner reads the file once, decompresses each chunk itself (zstd,
lz4 or none) and locates message records without building per-message objects: a chunk
whose records all have the same size (one channel, fixed-size messages — the common case
for JointState) is viewed as a NumPy structured array; any other chunk is walked record by
record. The result gives, per channel, the message times and the byte offsets and lengths
of the message data, for bulk decoding (:mod:`impactcli.io.mcap_ros2`).

Truncation: a file with a valid magic whose records stop early (no DataEnd/Footer, or a
record running past the end) is reported with ``truncated=True``; the complete records
before the cut are kept. Unknown record types are skipped, as the MCAP spec requires.
"""

from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import LogFormatError

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 1, 2, 3, 4, 5, 6
OP_DATA_END = 15
#: bytes of a message record before its data: opcode(1) length(8) channel(2) seq(4) times(16)
MSG_PREFIX = 31
#: The longest period of record sizes located in bulk (:meth:`_Collector._periodic`).
MAX_PERIOD = 8


class UnsupportedMcap(Exception):
    """Something the scanner does not handle (an unknown compression): use the official reader."""


@dataclass
class Batch:
    """Messages of one channel found in one chunk (or between chunks).

    Attributes:
        buf: (B,) uint8, the decompressed chunk (or the file).
        data_off: (n,) int64 offsets of each message's data in ``buf``.
        data_len: (n,) int64 data lengths [bytes].
        log_time, publish_time: (n,) int64 [ns].
        order: (n,) int64 index of each message in file order (over all channels).
    """

    buf: np.ndarray
    data_off: np.ndarray
    data_len: np.ndarray
    log_time: np.ndarray
    publish_time: np.ndarray
    order: np.ndarray


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


class _Collector:
    def __init__(self, scan: McapScan) -> None:
        self.scan = scan
        self.count = 0
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
                    raise LogFormatError(f"{where}: corrupt message record at byte {pos}")
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
        """Decompress the chunks found at top level (in threads: zstd/lz4 release the GIL),
        then walk them and the loose messages in file order."""
        chunks = [a for kind, a in self.pending if kind == "chunk"]
        workers = max(1, min(4, os.cpu_count() or 1, len(chunks)))
        if workers > 1:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(workers) as ex:
                raws = list(ex.map(lambda se: _chunk_bytes(buf, se[0], se[1], where), chunks))
        else:
            raws = [_chunk_bytes(buf, a, b, where) for a, b in chunks]
        it = iter(raws)
        for kind, args in self.pending:
            if kind == "chunk":
                raw = next(it)
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



def _chunk_bytes(buf: bytes, start: int, end: int, where: str) -> bytes:
    """The decompressed records of the chunk record whose body is ``buf[start:end]``."""
    try:
        _st, _et, usize, crc = struct.unpack_from("<QQQI", buf, start)
        kind, p = _string(buf, start + 28)
        (rl,) = struct.unpack_from("<Q", buf, p)
        if p + 8 + rl > end:
            raise LogFormatError(f"{where}: corrupt chunk at byte {start}")
        raw = _decompress(kind, buf[p + 8 : p + 8 + rl], usize)
    except (UnsupportedMcap, LogFormatError):
        raise
    except Exception as err:  # zstd/lz4/struct errors: the chunk is damaged
        raise LogFormatError(f"{where}: corrupt chunk at byte {start}: {err}") from err
    if len(raw) != usize:
        raise LogFormatError(f"{where}: corrupt chunk at byte {start}: wrong size")
    if crc and zlib.crc32(raw) != crc:
        raise LogFormatError(f"{where}: corrupt chunk at byte {start}: CRC mismatch")
    return raw


def scan_mcap(path: Path) -> McapScan:
    """Scan an MCAP file (see the module docstring).

    Raises:
        LogFormatError: not an MCAP file, or a damaged chunk.
        UnsupportedMcap: a feature the scanner does not handle (use the official reader).
    """
    where = str(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise LogFormatError(f"{where}: cannot read: {err}") from err
    if len(data) < 8 or data[:8] != MAGIC:
        raise LogFormatError(f"{where}: not an MCAP file (bad magic bytes)")
    scan = McapScan()
    col = _Collector(scan)
    arr = np.frombuffer(data, dtype=np.uint8)
    _, done = col.walk(data, arr, 8, len(data), where, inside_chunk=False)
    col.run_pending(data, where)
    if not done:
        scan.truncated = True
    scan.n_messages = col.count
    return scan


def scan_mcap_official(path: Path) -> McapScan:
    """The same as :func:`scan_mcap` through the official ``mcap`` reader (NonSeekingReader),
    for files the scanner does not handle; one batch per channel. A file whose records end
    early yields the messages before the cut with ``truncated=True``.

    Raises:
        LogFormatError: not readable, or no complete message.
    """
    from mcap.reader import NonSeekingReader

    where = str(path)
    scan = McapScan()
    rows: dict[int, list[tuple[int, int, int, bytes]]] = {}
    count = 0
    try:
        with open(path, "rb") as f:
            reader = NonSeekingReader(f)
            try:
                for schema, channel, msg in reader.iter_messages(log_time_order=False):
                    if schema is not None and schema.id not in scan.schemas:
                        scan.schemas[schema.id] = (schema.name, schema.encoding, schema.data)
                    scan.channels.setdefault(channel.id, (
                        channel.topic, schema.id if schema is not None else 0,
                        channel.message_encoding))
                    rows.setdefault(channel.id, []).append(
                        (count, msg.log_time, msg.publish_time, msg.data))
                    count += 1
            except Exception:  # the cut of a truncated file: keep what came before
                if not count:
                    raise
                scan.truncated = True
    except OSError as err:
        raise LogFormatError(f"{where}: cannot read: {err}") from err
    except Exception as err:
        first = (str(err).splitlines() or [type(err).__name__])[0]
        raise LogFormatError(f"{where}: corrupt MCAP: {first}") from err
    for cid, rs in rows.items():
        buf = np.frombuffer(b"".join(r[3] for r in rs), dtype=np.uint8)
        lens = np.array([len(r[3]) for r in rs], dtype=np.int64)
        offs = np.concatenate(([0], np.cumsum(lens)[:-1])).astype(np.int64)
        scan.batches[cid] = [Batch(
            buf, offs, lens, np.array([r[1] for r in rs], dtype=np.int64),
            np.array([r[2] for r in rs], dtype=np.int64),
            np.array([r[0] for r in rs], dtype=np.int64))]
    scan.n_messages = count
    return scan
