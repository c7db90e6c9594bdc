"""The repairs of :mod:`impactcli.io.repair` over the consecutive batches of a streamed log
(:mod:`impactcli.io.stream`): the same decisions, values and messages as on the whole file
— exact duplicate rows dropped, runs of at most ``MAX_GAP_SAMPLES`` non-finite values
interpolated (rows held back while a run is open), values beyond ``MAX_ABS_VALUE`` and rows
out of time order refused — with errors recorded and raised in the whole-file reader's
order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .stream_layout import StreamLayout, _Raw


class _NotStreamable(Exception):
    """The file needs the whole-file reader (module docstring)."""


@dataclass
class _Violation:
    """A run of non-finite values that is not interpolated (the first of its column)."""

    orig: int
    length: int
    kind: str
    at_start: bool
    at_end: bool


class _Repairer:
    """:func:`impactcli.io.repair.repair_matrix` over consecutive batches (the same
    decisions, values and messages as on the whole file).

    Rows are held back while a run of non-finite values (at most ``MAX_GAP_SAMPLES`` long,
    not at the start) is open; errors are recorded (the first of each kind) and raised by
    the scan in the whole-file reader's order.
    """

    def __init__(self, ctx: StreamLayout, allbad: frozenset[int] | None) -> None:
        from .repair import is_controller_column

        self.ctx = ctx
        self.names = list(ctx.names)
        c = len(self.names)
        self.label = ctx.label
        # a column that may hold no finite value (repair_matrix's keep_empty and controller
        # channels): not repaired then
        self.exempt = np.array([n in ctx.droppable or is_controller_column(n)
                                for n in self.names], dtype=bool)
        self.allbad = allbad  # known (second pass): set to NaN, not repaired
        self.prev_t: int | None = None  # the last raw row (duplicates)
        self.prev_vals = np.zeros(c)
        self.last_t: int | None = None  # the last kept row (order)
        self.last_orig = -1
        self.n_kept = 0
        self.n_dup = 0
        self.dup_first = -1
        self.order_error: str | None = None
        self.mag_error: str | None = None
        # rows held back: kept indices n_kept − held … n_kept − 1
        self.held_t = np.zeros(0, dtype=np.int64)
        self.held_m = np.zeros((0, c))
        self.held_o = np.zeros(0, dtype=np.int64)
        self.left_t = 0.0  # the last row given out (an interpolation's left neighbour)
        self.left_v = np.zeros(c)
        # per column: the open run of non-finite values
        self.scanned = np.zeros(c, dtype=np.int64)
        self.open_start = np.full(c, -1, dtype=np.int64)
        self.open_orig = np.zeros(c, dtype=np.int64)
        self.open_kind = ["NaN"] * c
        self.n_interp = np.zeros(c, dtype=np.int64)
        self.n_runs = np.zeros(c, dtype=np.int64)
        self.first_run = np.full(c, -1, dtype=np.int64)
        self.violation: list[_Violation | None] = [None] * c
        self.empty = np.zeros(c, dtype=bool)  # exempt columns without a finite value

    @property
    def failed(self) -> bool:
        """Whether an order or magnitude error was found (rows are no longer given out)."""
        return self.order_error is not None or self.mag_error is not None

    def push(self, raw: _Raw) -> tuple[np.ndarray, np.ndarray] | None:
        """Repair the next batch; the rows that are final: ``(t, mat)`` or None."""
        if self.order_error is not None:
            return None
        n = raw.t.shape[0]
        orig = np.arange(raw.row0, raw.row0 + n, dtype=np.int64)
        keep = self._not_duplicate(raw.t, raw.mat, orig)
        t, mat, orig = (raw.t, raw.mat, orig) if keep is None else (
            raw.t[keep], raw.mat[keep], orig[keep])
        if t.size == 0:
            return None
        self._check_order(t, orig)
        if self.order_error is not None:
            return None
        if self.mag_error is None:
            self._check_magnitudes(mat, orig)
        self.last_t, self.last_orig = int(t[-1]), int(orig[-1])
        k0 = self.n_kept
        self.n_kept += t.size
        if self.failed:
            return None
        return self._runs(t, mat, orig, k0)

    def finish(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The end of the file: close the open runs, give out the rows held."""
        if self.failed:
            return None
        for c in np.flatnonzero(self.open_start >= 0):
            s = int(self.open_start[c])
            if s == 0 and self.exempt[c]:
                self.empty[c] = True  # no finite value: not repaired (repair_matrix)
                continue
            self._violate(int(c), int(self.open_orig[c]), self.n_kept - s, self.open_kind[c],
                          s == 0, True)
        if self.held_t.size == 0:
            return None
        out = self.held_t, self.held_m
        self.held_t = self.held_t[:0]
        return out

    # -- steps
    def _not_duplicate(self, t: np.ndarray, mat: np.ndarray,
                       orig: np.ndarray) -> np.ndarray | None:
        """Mask of the rows that are not an exact duplicate of the row before (None: all)."""
        off = 0 if self.prev_t is None else 1
        tt = t if self.prev_t is None else np.concatenate((np.array([self.prev_t]), t))
        same = np.flatnonzero(np.diff(tt) == 0)
        self.prev_t = int(t[-1])
        prev_vals = self.prev_vals
        self.prev_vals = mat[-1].copy()
        if same.size == 0:
            return None
        ia = same - off
        a = np.empty((same.size, mat.shape[1]))
        a[ia >= 0] = mat[ia[ia >= 0]]
        a[ia < 0] = prev_vals
        b = mat[same + 1 - off]
        eq = np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1)
        if not eq.any():
            return None
        dup = (same + 1 - off)[eq]
        if self.dup_first < 0:
            self.dup_first = int(orig[dup[0]])
        self.n_dup += int(dup.size)
        keep = np.ones(t.size, dtype=bool)
        keep[dup] = False
        return keep

    def _check_order(self, t: np.ndarray, orig: np.ndarray) -> None:
        from .repair import _order_message

        tt = t if self.last_t is None else np.concatenate(([self.last_t], t))
        oo = orig if self.last_t is None else np.concatenate(([self.last_orig], orig))
        bad = np.flatnonzero(np.diff(tt) <= 0)
        if bad.size == 0:
            return
        if self.ctx.repair_order:
            raise _NotStreamable("rows out of time order to repair")
        k = int(bad[0]) + 1
        self.order_error = _order_message(tt[k - 1:k + 1], 1, oo[k - 1:k + 1],
                                          self.ctx.where, self.ctx.time_name, self.label)

    def _check_magnitudes(self, mat: np.ndarray, orig: np.ndarray) -> None:
        from .repair import MAX_ABS_VALUE, magnitude_message

        with np.errstate(invalid="ignore"):
            big = np.abs(mat) > MAX_ABS_VALUE
        big &= np.isfinite(mat)
        if big.any():
            r, c = np.argwhere(big)[0]
            self.mag_error = magnitude_message(self.ctx.where, self.names[int(c)],
                                               self.label(int(orig[int(r)])),
                                               float(mat[r, c]))

    def _violate(self, c: int, orig: int, length: int, kind: str, at_start: bool,
                 at_end: bool) -> None:
        if self.violation[c] is None:
            self.violation[c] = _Violation(orig, length, kind, at_start, at_end)

    def _runs(self, t: np.ndarray, mat: np.ndarray, orig: np.ndarray,
              k0_new: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Interpolate the runs of non-finite values that closed; give out the rows before
        the first open run."""
        from .repair import MAX_GAP_SAMPLES

        if self.held_t.size:
            t = np.concatenate((self.held_t, t))
            mat = np.concatenate((self.held_m, mat))
            orig = np.concatenate((self.held_o, orig))
        elif not mat.flags.writeable:
            mat = mat.copy()
        k0 = k0_new - self.held_t.size  # kept index of row 0 of the buffer
        k_end = self.n_kept
        if self.allbad:
            mat[:, sorted(self.allbad)] = np.nan
        fin = np.isfinite(mat)
        todo = ~fin.all(axis=0) | (self.open_start >= 0)
        if self.allbad:
            todo[sorted(self.allbad)] = False
        tf = t.astype(np.float64) if todo.any() else t
        for c in np.flatnonzero(todo):
            self._column(int(c), t, tf, mat, fin, orig, k0, k_end)
        holds = [int(s) for c, s in enumerate(self.open_start)
                 if s > 0 and k_end - s <= MAX_GAP_SAMPLES]
        hold = min(holds) - k0 if holds else t.size
        self.held_t, self.held_m, self.held_o = t[hold:], mat[hold:], orig[hold:]
        if hold == 0:
            return None
        self.left_t = float(t[hold - 1])
        self.left_v = mat[hold - 1].copy()
        return t[:hold], mat[:hold]

    def _column(self, c: int, t: np.ndarray, tf: np.ndarray, mat: np.ndarray,
                fin: np.ndarray, orig: np.ndarray, k0: int, k_end: int) -> None:
        """Runs of non-finite values of column ``c`` in buffer rows it has not seen."""
        from .repair import MAX_GAP_SAMPLES

        r0 = max(int(self.scanned[c]) - k0, 0)  # rows before were seen (or finite)
        mask = ~fin[r0:, c]
        was_open = self.open_start[c] >= 0
        ext = np.concatenate(([1 if was_open else 0], mask.astype(np.int8), [0]))
        d = np.diff(ext)
        starts = [int(s) for s in np.flatnonzero(d == 1) + r0 + k0]
        stops = [int(e) for e in np.flatnonzero(d == -1) + r0 + k0]
        runs_orig = [int(orig[s - k0]) for s in starts]
        kinds = ["NaN" if np.isnan(mat[s - k0, c]) else "infinite" for s in starts]
        if was_open:
            starts.insert(0, int(self.open_start[c]))
            runs_orig.insert(0, int(self.open_orig[c]))
            kinds.insert(0, self.open_kind[c])
        self.open_start[c] = -1
        for s, e, o, kind in zip(starts, stops, runs_orig, kinds, strict=True):
            if e == k_end:  # open at the end of what was read
                self.open_start[c], self.open_orig[c], self.open_kind[c] = s, o, kind
                continue
            if s == 0 or e - s > MAX_GAP_SAMPLES:
                self._violate(c, o, e - s, kind, s == 0, False)
                continue
            if s - 1 >= k0:
                tl, vl = tf[s - 1 - k0], mat[s - 1 - k0, c]
            else:
                tl, vl = self.left_t, self.left_v[c]
            rows = slice(s - k0, e - k0)
            mat[rows, c] = np.interp(tf[rows], [tl, tf[e - k0]], [vl, mat[e - k0, c]])
            self.n_interp[c] += e - s
            self.n_runs[c] += 1
            if self.first_run[c] < 0:
                self.first_run[c] = o
        self.scanned[c] = k_end

    # -- results
    def first_error(self) -> str | None:
        """The error the whole-file reader raises first, if any: rows out of order, a
        value beyond 1e12, a run of non-finite values (the first column's)."""
        from .repair import run_message

        if self.order_error is not None:
            return self.order_error
        if self.mag_error is not None:
            return self.mag_error
        for c, v in enumerate(self.violation):
            if v is not None:
                return run_message(self.ctx.where, self.names[c], self.label(v.orig),
                                   v.length, v.kind, v.at_start, v.at_end)
        return None

    def repairs(self) -> list[str]:
        """The repairs, in the whole-file reader's order."""
        from .repair import (
            duplicate_message,
            empty_controller_message,
            interpolated_message,
        )

        where = self.ctx.where
        out = []
        if self.n_dup:
            out.append(duplicate_message(where, self.n_dup, self.label(self.dup_first)))
        for c in np.flatnonzero(self.empty):
            if self.names[c] not in self.ctx.droppable:
                out.append(empty_controller_message(where, self.names[c]))
        for c in np.flatnonzero(self.n_runs):
            first = self.label(int(self.first_run[c]))
            out.append(interpolated_message(where, self.names[c], int(self.n_interp[c]),
                                            int(self.n_runs[c]), first))
        return out


