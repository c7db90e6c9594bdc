"""The samples near an alarm of a replay (:mod:`impactcli.run.one_log`), kept in the one
temporary store (:class:`impactcli.spill.ColumnFiles`) so that memory holds only where they
lie, whatever the log's length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..spill import ColumnFiles


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
