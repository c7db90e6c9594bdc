"""The torque screen of a log read in chunks (:mod:`impactcli.io.stream`): per column what
:func:`impactcli.detect.screen.unusable_columns` needs — whether it holds a finite value,
its peak-to-peak, its first value and up to ``FEW_VALUES`` distinct values — gathered
chunk by chunk, so that the scan decides as the whole log would without holding it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..detect.screen import FEW_VALUES, FLAT_NM, SMALL_FRACTION

__all__ = ["ColumnScreen", "ScreenAccumulator"]


@dataclass(frozen=True)
class ColumnScreen:
    """What :func:`impactcli.detect.screen.unusable_columns` needs of a torque-like
    channel's columns, gathered chunk by chunk.

    Attributes:
        logged: (J,) bool, whether the column holds a finite value.
        ptp: (J,) float64 peak-to-peak of its finite values [N·m] (0 when not logged).
        first: (J,) float64 its first finite value (NaN when not logged).
        n_distinct: (J,) int64 its distinct finite values, counted up to
            :data:`~impactcli.detect.screen.FEW_VALUES` (that many: that many or more).
    """

    logged: np.ndarray
    ptp: np.ndarray
    first: np.ndarray
    n_distinct: np.ndarray

    def unusable(self, reference_ptp: float | None = None) -> list[str | None]:
        """``unusable_columns(values, reference_ptp)`` of the whole channel: per column None,
        or why it is not usable (the same messages)."""
        logged = self.logged
        ref = float(np.max(self.ptp[logged])) if reference_ptp is None and logged.any() else (
            reference_ptp or 0.0)
        out: list[str | None] = []
        for j in range(logged.size):
            ptp = float(self.ptp[j])
            if not logged[j]:
                out.append(None)
            elif ptp <= FLAT_NM:
                out.append(f"flat: its torque is constant ({float(self.first[j]):.6g} N·m)")
            elif not (ref > 0 and ptp < SMALL_FRACTION * ref):
                out.append(None)
            elif self.n_distinct[j] < FEW_VALUES:
                out.append(f"unmeasured: {int(self.n_distinct[j])} distinct values spanning "
                           f"{ptp:.3g} N·m, under {SMALL_FRACTION:.0%} of the largest "
                           f"joint's {ref:.3g} N·m")
            else:
                out.append(None)
        return out

    @staticmethod
    def of(values: np.ndarray) -> ColumnScreen:
        """The screen of a whole (N, J) channel."""
        acc = ScreenAccumulator(values.shape[1])
        acc.add(values)
        return acc.result()

    def select(self, keep: list[int]) -> ColumnScreen:
        """The columns ``keep``."""
        return ColumnScreen(self.logged[keep], self.ptp[keep], self.first[keep],
                            self.n_distinct[keep])


class ScreenAccumulator:
    """Accumulates :class:`ColumnScreen` over chunks of (n, J) values."""

    def __init__(self, n_cols: int) -> None:
        self.lo = np.full(n_cols, np.inf)
        self.hi = np.full(n_cols, -np.inf)
        self.first = np.full(n_cols, np.nan)
        self.distinct: list[np.ndarray | None] = [np.zeros(0)] * n_cols

    def add(self, values: np.ndarray) -> None:
        """Count an (n, J) chunk."""
        v = np.asarray(values, dtype=np.float64)
        fin = np.isfinite(v)
        if fin.all():
            lo, hi = v.min(axis=0), v.max(axis=0)
        else:
            lo = np.where(fin, v, np.inf).min(axis=0)
            hi = np.where(fin, v, -np.inf).max(axis=0)
        self.lo = np.minimum(self.lo, lo)
        self.hi = np.maximum(self.hi, hi)
        for j in range(v.shape[1]):
            d = self.distinct[j]
            if np.isnan(self.first[j]) or d is not None:
                col = v[:, j] if fin[:, j].all() else v[fin[:, j], j]
                if col.size and np.isnan(self.first[j]):
                    self.first[j] = col[0]
                if d is not None:
                    u = np.unique(np.concatenate((d, col)))
                    self.distinct[j] = u if u.size < FEW_VALUES else None

    def result(self) -> ColumnScreen:
        """The columns' :class:`ColumnScreen`."""
        logged = np.isfinite(self.lo)
        ptp = np.where(logged, self.hi - np.where(logged, self.lo, 0.0), 0.0)
        n = np.array([FEW_VALUES if d is None else d.size for d in self.distinct],
                     dtype=np.int64)
        return ColumnScreen(logged, ptp, self.first.copy(), n)
