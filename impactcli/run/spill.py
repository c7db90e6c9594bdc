"""Temporary files of a replay (:mod:`impactcli.run.one_log`): the samples near an
alarm (:class:`Islands`) and a pass's per-sample arrays (:class:`ChunkSpill`), so that
memory holds only where things lie, whatever the log's length.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..files import temp_space, write_spill


class ColumnFiles:
    """Arrays appended row by row to a temporary file per name (memory holds only their
    layout), read back by rows: the one store of a replay's spills.

    Args:
        prefix: the temporary folder's name prefix.
    """

    def __init__(self, prefix: str) -> None:
        self.dir = tempfile.TemporaryDirectory(prefix=prefix)
        self.files: dict[str, Any] = {}
        self.layout: dict[str, tuple[np.dtype[Any], tuple[int, ...]]] = {}
        self.rows = 0

    def append(self, arrays: dict[str, np.ndarray]) -> None:
        """Append rows: name → (m, ...) array (the same m, and each name's dtype and row
        shape the same each time)."""
        m = 0
        for key, v in arrays.items():
            f = self.files.get(key)
            if f is None:
                f = self.files[key] = open(os.path.join(self.dir.name, key), "wb")  # noqa: SIM115
                self.layout[key] = (v.dtype, v.shape[1:])
            write_spill(f, v)
            m = int(v.shape[0])
        self.rows += m

    def flush(self) -> None:
        """What the write buffers hold to disk (:func:`temp_space`), the files kept open."""
        with temp_space():
            for f in self.files.values():
                f.flush()

    def finish(self) -> None:
        """Close the files for writing (:func:`temp_space`); their rows stay readable."""
        with temp_space():
            for f in self.files.values():
                f.close()

    def read(self, row_from: int, row_to: int, keys: tuple[str, ...] | None = None,
             ) -> dict[str, np.ndarray]:
        """Rows [row_from, row_to) of every array (``keys``: of these), written to disk
        (:meth:`flush` or :meth:`finish`)."""
        out = {}
        for key in (tuple(self.layout) if keys is None else keys):
            dtype, shape = self.layout[key]
            width = int(np.prod(shape)) if shape else 1
            with open(os.path.join(self.dir.name, key), "rb") as f:
                f.seek(row_from * dtype.itemsize * width)
                a = np.fromfile(f, dtype=dtype, count=(row_to - row_from) * width)
            out[key] = a.reshape((-1, *shape))
        return out

    def close(self) -> None:
        """Remove the files."""
        for f in self.files.values():
            f.close()
        self.dir.cleanup()


@dataclass
class Island:
    """Consecutive samples near an alarm (module docstring): the island's first sample in
    the log and its rows [row_from, row_to) in the spill files."""

    start: int
    row_from: int
    row_to: int


class Islands:
    """The islands of a replay (module docstring), their rows spilled to
    temporary files (:class:`ColumnFiles`: memory holds only where each island lies).

    A sample is kept when some detector fires on it, when it lies within the merge gap
    after one that fires, or when the contact still presses on it (the static-loading
    statistic of some joint at half its threshold) and the sample before it was kept —
    the stretch between two alarms that a pressing contact bridges. Pressing that does not
    follow an alarm is not kept: no event or incident reads it.
    """

    def __init__(self, merge_gap_s: float) -> None:
        self.reach_s = merge_gap_s + 1e-9
        self.last_t = -np.inf          # time of the last alarm so far
        self.kept_last = False         # whether the previous chunk's last sample was kept
        self.done: list[Island] = []
        self.open: Island | None = None
        self.store = ColumnFiles("impactcli-islands-")

    def update(self, k0: int, t: np.ndarray, alarm: np.ndarray, pressing: np.ndarray,
               arrays: dict[str, np.ndarray]) -> None:
        """Absorb a chunk starting at sample ``k0``: (n,) times [s], (n,) alarms, (n,)
        pressing, and the (n, ...) arrays to keep of the kept samples."""
        n = t.shape[0]
        idx = np.where(alarm, np.arange(n), -1)
        last = np.maximum.accumulate(idx)
        t_last = np.where(last >= 0, t[np.maximum(last, 0)], self.last_t)
        base = alarm | (t - t_last <= self.reach_s)
        if alarm.any():
            self.last_t = float(t[np.flatnonzero(alarm)[-1]])
        # kept = base, or pressing with the sample before kept: a pressing run continues
        # the state at its start; a sample neither base nor pressing resets it
        ar = np.arange(n)
        set_at = np.maximum.accumulate(np.where(base, ar, -1))
        reset_at = np.maximum.accumulate(np.where(~base & ~pressing, ar, -1))
        carried = self.kept_last & (reset_at < 0) & (set_at < 0)
        keep = base | (pressing & ((set_at > reset_at) | carried))
        self.kept_last = bool(keep[-1]) if n else self.kept_last
        if not keep.any():
            self._close()
            return
        edges = np.flatnonzero(np.diff(np.concatenate([[0], keep.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            if a > 0 or self.open is None:
                self._close()
                self.open = Island(k0 + int(a), self.store.rows, self.store.rows)
            self.store.append({key: v[a:b] for key, v in arrays.items()})
            self.open.row_to = self.store.rows
            if b < n:
                self._close()

    def _close(self) -> None:
        if self.open is not None:
            self.done.append(self.open)
            self.open = None

    def finish(self) -> list[Island]:
        """The islands, in time order (their rows readable until :meth:`close`)."""
        self._close()
        self.store.finish()  # what the write buffers still held goes to disk here
        return self.done

    def arrays(self, isl: Island) -> dict[str, np.ndarray]:
        """An island's arrays, read back from the spill files."""
        return self.store.read(isl.row_from, isl.row_to)

    def close(self) -> None:
        """Remove the spill files."""
        self.store.close()


class ChunkSpill(ColumnFiles):
    """Per-sample arrays of a pass, chunk by chunk, in a temporary file per array
    (:class:`ColumnFiles`), read back later chunk by chunk (the same chunks, in order)."""

    def __init__(self) -> None:
        super().__init__("impactcli-spill-")
        self.lengths: list[int] = []

    def write(self, arrays: dict[str, np.ndarray]) -> None:
        """Append one chunk: name → (m, ...) array (the same names and shapes each time)."""
        self.append(arrays)
        self.lengths.append(int(next(iter(arrays.values())).shape[0]))

    def read_chunks(self, keys: tuple[str, ...] | None = None,
                    ) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        """(first sample, arrays) per chunk as written; ``keys`` only these arrays."""
        self.flush()
        k0 = 0
        for m in self.lengths:
            yield k0, self.read(k0, k0 + m, keys)
            k0 += m
