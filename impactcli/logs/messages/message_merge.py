"""The decoded messages of a log's topics kept on disk (:class:`TopicSpill`), and their
merge into the log's rows (:func:`merged_rows`): the second half of the message reader
(:mod:`impactcli.logs.messages.message_read`).

Why: a message log is read in one pass over its blocks (MCAP chunks, bag messages), each
block decompressed and decoded once; what the log is made of (the state topic, its
joints, signals and time source, the companion and map topics) is decided from counts
only once the pass is over. So every topic the log may use keeps its decoded columns —
the three time stamps, each array's values per joint name, which joints and arrays each
message fills, the map's fields — in a spill of its own: a column per file in a temporary
folder, read back in ranges of rows or by row numbers (reads of the files, not maps of
them: the pages read do not stay in the process's memory).

The merge reads the spills, not the file: the state samples in time order (the stamps of a
topic written out of order are sorted by a stable argsort kept in memory, 8 bytes a
message) and, for each other topic, its latest message at or before each sample
(causal sample-and-hold); the state samples before a held topic's first message are
dropped. Memory holds a block of rows; the disk the decoded columns (no more than the
file decompressed). The spill is a cache of the one temporary store (:mod:`impactcli.spill`,
its folder and disk-full policy): without a temporary folder, or with its disk nearly full,
it is kept in memory instead.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np

from ...spill import SpillFolder

#: State samples merged at a time.
MERGE_ROWS = 65_536


_FILL = {np.dtype(np.float64): np.nan, np.dtype(np.int64): 0, np.dtype(np.bool_): False}


class TopicSpill:
    """One topic's decoded columns (module docstring): :meth:`append` blocks of named
    columns — a column first given later holds its fill value (NaN, 0, False) before —,
    :meth:`finish`, then :meth:`read` rows ``a:b`` or :meth:`take` rows by number."""

    def __init__(self, folder: SpillFolder, name: str) -> None:
        self.folder = folder
        self.name = name
        self.n = 0
        self.start: dict[str, int] = {}
        self.dtype: dict[str, np.dtype[Any]] = {}
        self._files: dict[str, IO[bytes]] = {}
        self._mem: dict[str, list[np.ndarray]] = {}
        self._arrays: dict[str, _Stored] = {}  # after finish
        self.on_disk = folder.path is not None

    def _path(self, key: str) -> str:
        assert self.folder.path is not None
        return os.path.join(self.folder.path, f"{self.name}.{len(self.start)}.bin")

    def append(self, n: int, cols: dict[str, np.ndarray]) -> None:
        """Add ``n`` rows: ``cols`` maps column keys to (n,) arrays (float64, int64, bool);
        a column not given holds its fill value in these rows."""
        for key, a in cols.items():
            if key not in self.start:
                self.start[key] = self.n
                self.dtype[key] = np.asarray(a).dtype
                self._mem[key] = []
                if self.on_disk:
                    self._files[key] = open(self._path(key), "wb")  # noqa: SIM115
        nbytes = sum(np.asarray(a).nbytes for a in cols.values())
        if self.on_disk and not self.folder.room(nbytes):
            self._to_memory()
        for key in self.start:
            given = cols.get(key)
            a = (np.full(n, _FILL[self.dtype[key]], dtype=self.dtype[key]) if given is None
                 else np.ascontiguousarray(given, dtype=self.dtype[key]))
            if self.on_disk:
                self._files[key].write(a.data.cast("B"))
            else:
                self._mem[key].append(a)
        self.n += n

    def _to_memory(self) -> None:
        """The disk is short: what was written is read back, the rest kept in memory."""
        for key, f in self._files.items():
            f.close()
            a = np.fromfile(f.name, dtype=self.dtype[key])
            self._mem[key] = [a]
            with contextlib.suppress(OSError):
                os.unlink(f.name)
        self._files = {}
        self.on_disk = False

    def finish(self) -> None:
        """The last block was added: the columns can be read."""
        for key in self.start:
            m = self.n - self.start[key]
            if self.on_disk:
                self._files[key].close()
                self._arrays[key] = _Stored(self.dtype[key], m, path=self._files[key].name)
            else:
                parts = self._mem[key]
                self._arrays[key] = _Stored(self.dtype[key], m, array=(
                    np.concatenate(parts) if parts else np.zeros(0, dtype=self.dtype[key])))
                self._mem[key] = []
        self._files = {}

    def has(self, key: str) -> bool:
        return key in self.start

    def read(self, key: str, a: int, b: int, out: np.ndarray | None = None) -> np.ndarray:
        """Rows ``a:b`` of column ``key``, into ``out`` when given (else a new array)."""
        dtype = self.dtype.get(key, np.dtype(np.float64))
        if out is None:
            out = np.empty(b - a, dtype=dtype)
        s = self.start.get(key, b)
        lo = min(max(a, s), b)
        if lo > a:
            out[: lo - a] = _FILL[dtype]
        if lo < b:
            self._arrays[key].read(lo - s, b - s, out[lo - a:])
        return out

    def take(self, key: str, rows: np.ndarray) -> np.ndarray:
        """Column ``key`` at rows ``rows`` (a new array)."""
        dtype = self.dtype.get(key, np.dtype(np.float64))
        if key not in self.start:
            return np.full(rows.shape[0], _FILL[dtype], dtype=dtype)
        s = self.start[key]
        if s == 0:
            return self._arrays[key].take(rows)
        out = np.full(rows.shape[0], _FILL[dtype], dtype=dtype)
        late = rows >= s
        if late.any():
            out[late] = self._arrays[key].take(rows[late] - s)
        return out

    def column(self, key: str) -> np.ndarray:
        """The whole column (in memory: 8 or 1 bytes a message)."""
        return self.read(key, 0, self.n)

    def first_false(self, keys: list[str], step: int = 1 << 20) -> int | None:
        """The first row where one of the bool columns ``keys`` is False (None: none; a
        column never given is False)."""
        if self.n and not all(self.has(k) for k in keys):
            return 0
        for a in range(0, self.n, step):
            b = min(a + step, self.n)
            ok = np.ones(b - a, dtype=bool)
            for k in keys:
                ok &= self.read(k, a, b)
            if not ok.all():
                return a + int(np.argmax(~ok))
        return None

    def close(self) -> None:
        for f in self._files.values():
            with contextlib.suppress(OSError):
                f.close()
        self._files = {}
        for a in self._arrays.values():
            a.close()
        self._arrays = {}


class _Stored:
    """A finished column: a file read with ``pread``, or an array in memory."""

    def __init__(self, dtype: np.dtype[Any], n: int, path: str | None = None,
                 array: np.ndarray | None = None) -> None:
        self.dtype, self.n, self.array = dtype, n, array
        self.fd = os.open(path, os.O_RDONLY) if path is not None else None

    def read(self, a: int, b: int, out: np.ndarray) -> None:
        """Rows ``a:b`` into ``out``."""
        if self.array is not None:
            out[:] = self.array[a:b]
            return
        assert self.fd is not None
        size = self.dtype.itemsize
        buf = out if out.flags.c_contiguous else np.empty(b - a, dtype=self.dtype)
        got = os.preadv(self.fd, [buf.data.cast("B")], a * size)
        if got != (b - a) * size:
            raise OSError(f"spill: {got} bytes read of {(b - a) * size}")
        if buf is not out:
            out[:] = buf

    def take(self, rows: np.ndarray) -> np.ndarray:
        """The rows ``rows`` (read as the span they cover)."""
        if self.array is not None:
            return np.asarray(self.array[rows])
        if rows.size == 0:
            return np.zeros(0, dtype=self.dtype)
        lo, hi = int(rows.min()), int(rows.max()) + 1
        span = np.empty(hi - lo, dtype=self.dtype)
        self.read(lo, hi, span)
        return span[rows - lo]

    def close(self) -> None:
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.close(self.fd)
            self.fd = None


@dataclass
class Part:
    """A topic the log's rows come from, as the merge reads it: the state topic (the
    first part) or a held one (a companion, a topic of map fields).

    Attributes:
        topic, role: the topic and what it is for (errors, the lead repair).
        spill: its decoded columns.  time_key: the column of its stamps (its time source).
        cols: ``(signal, joint)`` of the log's columns it gives, and ``keys`` the spill's
            columns of them.
    """

    topic: str
    role: str
    spill: TopicSpill
    time_key: str
    cols: list[tuple[str, int]] = field(default_factory=list)
    keys: list[str] = field(default_factory=list)
    ordered: bool = True  # its stamps never decrease in file order


class _Held:
    """A held topic's stamps as the merge reaches them: a window of its messages in file
    order (stamps in order), or its stamps sorted (a stable argsort in memory)."""

    def __init__(self, part: Part) -> None:
        self.part = part
        sp = part.spill
        self.sorted_t: np.ndarray | None = None
        self.rank: np.ndarray | None = None
        if not part.ordered:
            t = sp.column(part.time_key)
            self.rank = np.argsort(t, kind="stable")
            self.sorted_t = t[self.rank]
        self.win_t = np.zeros(0, dtype=np.int64)
        self.win0 = 0  # row of the window's first message
        self.next = 0  # rows read into the window
        self.lead = 0  # state samples before its first message

    def rows_at(self, t: np.ndarray) -> np.ndarray:
        """Its latest message at or before each sample time ``t`` (sorted): row numbers,
        −1 before its first message."""
        if self.sorted_t is not None:
            assert self.rank is not None
            idx = np.searchsorted(self.sorted_t, t, side="right") - 1
            return np.where(idx >= 0, self.rank[np.maximum(idx, 0)], -1)
        sp = self.part.spill
        last = int(t[-1])
        while self.next < sp.n and (self.win_t.size == 0 or int(self.win_t[-1]) <= last):
            b = min(self.next + MERGE_ROWS, sp.n)
            self.win_t = np.concatenate((self.win_t, sp.read(self.part.time_key, self.next, b)))
            self.next = b
        # the window starts at the message held for the previous sample: a later sample's
        # is that one or after (-1 only before the first message)
        idx = np.searchsorted(self.win_t, t, side="right") - 1
        rows = np.where(idx >= 0, idx + self.win0, -1)
        keep = max(int(idx[-1]), 0)
        self.win_t = self.win_t[keep:]
        self.win0 += keep
        return rows


def merged_rows(parts: list[Part], perm: np.ndarray | None, lead_counts: list[int]
                ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The log's rows: the state's samples in time order (``perm``: the state's rows in
    that order, None when its stamps never decrease in the file) and every held topic's
    latest message at or before each (module docstring); the samples before a held
    topic's first message are dropped, counted per topic in ``lead_counts``. Yields
    ``(t (n,) int64, values (n, C) float64)`` with the parts' columns in order."""
    state, held = parts[0], [_Held(p) for p in parts[1:]]
    sp = state.spill
    n = sp.n
    t_sorted = None
    if perm is not None:
        t_sorted = sp.column(state.time_key)[perm]
    ncols = sum(len(p.keys) for p in parts)
    for a in range(0, n, MERGE_ROWS):
        b = min(a + MERGE_ROWS, n)
        mat = np.empty((b - a, ncols))
        if perm is None:
            t = sp.read(state.time_key, a, b)
            for c, key in enumerate(state.keys):
                sp.read(key, a, b, mat[:, c])
        else:
            assert t_sorted is not None
            rows = perm[a:b]
            t = t_sorted[a:b]
            for c, key in enumerate(state.keys):
                mat[:, c] = sp.take(key, rows)
        c = len(state.keys)
        drop = np.zeros(b - a, dtype=bool)
        for i, h in enumerate(held):
            rows_h = h.rows_at(t)
            before = rows_h < 0
            lead_counts[i] += int(before.sum())
            drop |= before
            safe = np.maximum(rows_h, 0)
            for key in h.part.keys:
                mat[:, c] = h.part.spill.take(key, safe)
                c += 1
        if drop.all():
            continue
        if drop.any():
            t, mat = t[~drop], mat[~drop]
        yield t, mat
