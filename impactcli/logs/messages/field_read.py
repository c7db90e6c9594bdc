"""Reading field paths from the raw messages of one topic, in bulk where the layout allows.

:func:`read_fields` returns the values of
:class:`~impactcli.logs.messages.fields.FieldPath` s (and the header stamps) of every
message. JSON messages are decoded one by one
(:func:`impactcli.logs.messages.fields.extract`). ROS messages (CDR or ROS 1) are read in bulk:

1. Messages of one batch with the same length form a group. The first is walked field by
   field over its type definition (:class:`_Locator`: CDR alignment relative to the byte
   after the encapsulation header, strings and sequences prefixed by a uint32 length; ROS
   1 without alignment or header), which gives the offset and type of every wanted number
   and the byte ranges its offsets depend on.
2. Every message of the group whose bytes equal the first's on those ranges has the same
   offsets: its numbers are read with NumPy views of all such messages at once.
3. The first message's numbers are checked against rosbags' own decoder; any message that
   differs on the ranges, any group whose check fails and any path that does not fit is
   decoded one message at a time by rosbags, which also names the message in errors.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from .fields import FieldPath, extract
from .message_source import MessageSource, TopicData, header_stamps

_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4
#: numeric base types read in bulk: size [bytes] and NumPy kind (endianness added)
_NUMERIC: dict[str, tuple[int, str]] = {
    "bool": (1, "u1"), "int8": (1, "i1"), "uint8": (1, "u1"), "int16": (2, "i2"),
    "uint16": (2, "u2"), "int32": (4, "i4"), "uint32": (4, "u4"), "int64": (8, "i8"),
    "uint64": (8, "u8"), "float32": (4, "f4"), "float64": (8, "f8"),
}
_SIZES: dict[str, int] = {**{k: v[0] for k, v in _NUMERIC.items()}, "byte": 1, "char": 1}
_STAMP = (("header", None), ("stamp", None))


class _Unsupported(Exception):
    """A layout or a message the locator does not handle: decode one by one."""


class _Done(Exception):
    """Every wanted number is located."""


class _Wanted:
    """The numbers to locate, by address (field steps below the message)."""

    def __init__(self) -> None:
        self.scalars: dict[tuple[tuple[str, int | None], ...], int] = {}
        self.elements: dict[tuple[tuple[str, int | None], ...], list[tuple[int, int]]] = {}
        self.by_name: dict[tuple[tuple[str, int | None], ...], list[tuple[int, str]]] = {}
        self.count = 0

    def add(self, steps: tuple[tuple[str, int | None], ...], col: int,
            joint: str | None = None) -> None:
        self.count += 1
        name, idx = steps[-1]
        if joint is not None:
            self.by_name.setdefault(steps, []).append((col, joint))
        elif idx is not None:
            self.elements.setdefault((*steps[:-1], (name, None)), []).append((idx, col))
        else:
            self.scalars[steps] = col


class _Locator:
    """Walk one message, locating wanted numbers (module docstring, step 1)."""

    def __init__(self, defs: dict[str, Any], data: bytes, ros1: bool, wanted: _Wanted) -> None:
        self.defs = defs
        self.data = data
        self.ros1 = ros1
        self.scalars = wanted.scalars  # address of a number → column
        self.elements = wanted.elements  # address of an array → [(index, column)]
        self.by_name = wanted.by_name  # address of an array → [(column, joint)]
        self.left = wanted.count
        self.found: dict[int, tuple[int, str]] = {}
        self.ranges: list[tuple[int, int]] = [] if ros1 else [(0, 4)]
        self.base = 0 if ros1 else 4
        self.little = True if ros1 else bool(data[1] & 1)
        self.pos = self.base

    def align(self, n: int) -> None:
        if not self.ros1 and n > 1:
            self.pos = self.base + -(-(self.pos - self.base) // n) * n

    def u32(self) -> int:
        self.align(4)
        if self.pos + 4 > len(self.data):
            raise _Unsupported("message ends early")
        v = int(struct.unpack_from("<I" if self.little else ">I", self.data, self.pos)[0])
        self.ranges.append((self.pos, self.pos + 4))
        self.pos += 4
        return v

    def hit(self, col: int, kind: str, size: int) -> None:
        if self.pos + size > len(self.data):
            raise _Unsupported("message ends early")
        self.found[col] = (self.pos, kind)
        self.left -= 1
        if self.left == 0:
            raise _Done

    def strings(self, count: int) -> list[str]:
        out = []
        for _ in range(count):
            n = self.u32()
            start = self.pos
            self.pos += n
            if self.pos > len(self.data):
                raise _Unsupported("message ends early")
            raw = self.data[start : self.pos]
            out.append(raw[:-1].decode() if not self.ros1 and raw.endswith(b"\x00")
                       else raw.decode())
        return out

    def walk(self, typename: str, prefix: tuple[tuple[str, int | None], ...]) -> None:
        names: list[str] | None = None
        for fname, (node, detail) in self.defs[typename][1]:
            addr = (*prefix, (fname, None))
            if node == _NAME:
                self.walk(detail, addr)
                continue
            if node == _BASE:
                self.scalar(detail[0], addr)
                continue
            (enode, edetail), size = detail
            count = size if node == _ARRAY else self.u32()
            if enode == _NAME:
                for k in range(count):
                    self.walk(edetail, (*prefix, (fname, k)))
                continue
            base = edetail[0]
            if base in ("string", "wstring"):
                start = self.pos
                got = self.strings(count)
                if fname == "name":
                    names = got
                    self.ranges.append((start, self.pos))  # the joints' order must match
                continue
            if base not in _SIZES:
                raise _Unsupported(f"type {base}")
            sz = _SIZES[base]
            if count:
                self.align(sz)
            start = self.pos
            picks = list(self.elements.get(addr, []))
            if any(k >= count for k, _ in picks):
                raise _Unsupported("index past the end")
            for joint_col, joint in self.by_name.get(addr, []):
                if names is None or joint not in names or names.index(joint) >= count:
                    raise _Unsupported("joint not in name[]")
                picks.append((names.index(joint), joint_col))
            if picks and base not in _NUMERIC:
                raise _Unsupported(f"type {base}")
            end = start + count * sz
            if end > len(self.data):
                raise _Unsupported("message ends early")
            for k, col in sorted(picks, key=lambda x: x[0]):
                self.pos = start + k * sz
                try:
                    self.hit(col, _NUMERIC[base][1], sz)
                except _Done:
                    self.pos = end
                    raise
            self.pos = end

    def scalar(self, base: str, addr: tuple[tuple[str, int | None], ...]) -> None:
        if base in ("string", "wstring"):
            self.strings(1)
            return
        if base not in _SIZES:
            raise _Unsupported(f"type {base}")
        sz = _SIZES[base]
        self.align(sz)
        col = self.scalars.get(addr)
        if col is not None:
            if base not in _NUMERIC:
                raise _Unsupported(f"type {base}")
            self.hit(col, _NUMERIC[base][1], sz)
        self.pos += sz


def _locate(defs: dict[str, Any], first: bytes, ros1: bool, wanted: _Wanted,
            msgtype: str) -> _Locator | None:
    """The layout of one message, or None when the locator does not handle it."""
    if not ros1 and (len(first) < 4 or first[0] != 0 or first[1] not in (0, 1)):
        return None
    loc = _Locator(defs, first, ros1, wanted)
    try:
        loc.walk(msgtype, ())
    except _Done:
        pass
    except (_Unsupported, struct.error, UnicodeDecodeError, KeyError):
        return None
    return None if loc.left else loc


def _message(parts: list[tuple[Any, np.ndarray, np.ndarray]], i: int) -> bytes:
    """The bytes of the ``i``-th message of a group (counting over its batches)."""
    for b, sel, _ in parts:
        if i < sel.shape[0]:
            o, ln = int(b.data_off[sel[i]]), int(b.data_len[sel[i]])
            return bytes(b.buf[o : o + ln].tobytes())
        i -= sel.shape[0]
    raise IndexError(i)


def _has_header(defs: dict[str, Any], msgtype: str) -> bool:
    fields = dict(defs[msgtype][1])
    h = fields.get("header")
    if h is None or h[0] != _NAME:
        return False
    st = dict(defs[h[1]][1]).get("stamp")
    return st is not None and st[0] == _NAME and {"sec", "nanosec"} <= {
        n for n, _ in defs[st[1]][1]}


def read_fields(src: MessageSource, td: TopicData, paths: list[FieldPath],
                where: str | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Values of ``paths`` (all on ``td``'s topic) and the header stamps, in file order.

    ``where`` starts error messages (default: the log's path).

    Returns:
        ``(values (n, len(paths)) float64, header (n,) int64 [ns] or None without header)``.

    Raises:
        LogFormatError, ChannelMapError: as :func:`impactcli.logs.messages.fields.extract` (from the
            one-by-one decoder, which names the message).
    """
    if td.encoding not in ("cdr", "ros1"):
        msgs = src.decode_all(td)
        index = np.arange(td.first, td.first + len(msgs)) if td.first else None
        return extract(msgs, paths, where or src.where, index=index), header_stamps(msgs)
    defs = src.typestore().fielddefs
    with_header = _has_header(defs, td.msgtype)
    wanted = _Wanted()
    for c, fp in enumerate(paths):
        wanted.add(fp.steps, c, fp.joint)
    k = len(paths)
    if with_header:
        wanted.add((*_STAMP, ("sec", None)), k)
        wanted.add((*_STAMP, ("nanosec", None)), k + 1)
    ncol = k + (2 if with_header else 0)
    vals = np.empty((td.n, ncol))  # every row is filled: in bulk or one by one below
    done = np.zeros(td.n, dtype=bool)
    ros1 = td.encoding == "ros1"
    order = (np.sort(np.concatenate([b.order for b in td.batches])) if td.batches
             else np.zeros(0, np.int64))
    # messages of one length, from every batch: (batch, positions in it, numbers in topic)
    groups: dict[int, list[tuple[Any, np.ndarray, np.ndarray]]] = {}
    for b in td.batches:
        idx_all = np.searchsorted(order, b.order)
        for length in np.unique(b.data_len).tolist():
            sel = np.flatnonzero(b.data_len == length)
            groups.setdefault(length, []).append((b, sel, idx_all[sel]))
    for parts in groups.values():
        num = np.concatenate([i for _, _, i in parts])
        pending = np.ones(num.shape[0], dtype=bool)
        while pending.any():
            # the layout of the first message not read yet, and every message it fits
            first = _message(parts, int(np.argmax(pending)))
            loc = _locate(defs, first, ros1, wanted, td.msgtype)
            if loc is None:
                break
            check = np.concatenate([np.arange(a, z) for a, z in loc.ranges] or
                                   [np.zeros(0, np.int64)]).astype(np.int64)
            cols = sorted(loc.found.items())
            sizes = [np.dtype(kind).itemsize for _, (_, kind) in cols]
            take = np.concatenate([check] + [np.arange(off, off + sz) for (_, (off, _)), sz
                                             in zip(cols, sizes, strict=True)]).astype(np.int64)
            # only the bytes that matter, gathered from every batch at once per batch
            got = np.concatenate([b.buf[b.data_off[sel][:, None] + take[None, :]]
                                  for b, sel, _ in parts])
            tmpl = np.frombuffer(first, dtype=np.uint8)[take]
            ok = pending & np.all(got[:, : check.size] == tmpl[: check.size], axis=1)
            pending &= ~ok
            block = np.empty((int(ok.sum()), ncol))  # every column is located
            pos = check.size
            end = "<" if loc.little else ">"
            mine = got[ok]
            for (col, (_, kind)), sz in zip(cols, sizes, strict=True):
                dt = np.dtype(end + kind)
                block[:, col] = np.ascontiguousarray(mine[:, pos : pos + sz]).view(dt)[:, 0]
                pos += sz
            # its numbers must be what rosbags decodes (else: one by one)
            i0 = num[int(np.argmax(ok))]
            ref = extract(src.decode_all(td, np.array([i0])), paths, src.where,
                          miss_is_error=False)[0]
            if not np.array_equal(ref, block[0, :k], equal_nan=True):
                continue
            vals[num[ok]] = block
            done[num[ok]] = True
    header: np.ndarray | None = None
    if with_header:
        header = np.zeros(td.n, dtype=np.int64)
        header[done] = (vals[done, k].astype(np.int64) * 10**9
                        + vals[done, k + 1].astype(np.int64))
    rest = np.flatnonzero(~done)
    if rest.size:
        msgs = src.decode_all(td, rest)
        vals[rest, :k] = extract(msgs, paths, where or src.where, index=rest + td.first)
        if with_header:
            h = header_stamps(msgs)
            assert header is not None and h is not None
            header[rest] = h
    return vals[:, :k], header
