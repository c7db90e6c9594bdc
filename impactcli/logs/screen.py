"""Which joints and channels a detector can use at all (real-log hygiene), decided from
what the scan of a log gathers chunk by chunk (:class:`ColumnScreen`).

A real log may carry a torque channel that is not measured: a wrist effort stuck at zero,
or one that only shows a few dozen distinct values around zero while the other joints
carry tens of N·m. Calibrated as it is, such a channel gets a threshold of a hundredth of
a N·m and raises every alarm on that robot. So before anything else a joint whose torque
is **flat** or **unmeasured** is left out of detection, with a warning and a record in the
timeline (``input.joints_left_out``):

* flat — its torque takes one value only (peak-to-peak ≤ :data:`FLAT_NM`);
* unmeasured — fewer than :data:`FEW_VALUES` distinct values *and* a peak-to-peak below
  :data:`SMALL_FRACTION` of the largest peak-to-peak among the log's torque channels (a
  quantised but real channel has either many values or a comparable range) *and*, for the
  torque of a log whose poses the scan sampled, no variation with the arm's poses (its own
  signal: a still joint still carries a gravity torque that moves with the other joints'
  poses, :func:`impactcli.logs.poses.pose_explained`).

The controller's channels (``torque_model``, ``torque_ext``) are screened the same way; a
flat or unmeasured one is read as not logged for that joint. Per column the screen needs
whether it holds a finite value, its range, its first value and up to ``FEW_VALUES``
distinct values: gathered chunk by chunk, so the scan decides as the whole log would.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..columns import by_column, column_range

__all__ = ["FEW_VALUES", "FLAT_NM", "SMALL_FRACTION", "ColumnScreen", "LeftOut",
           "ScreenAccumulator", "unusable_columns"]

#: A channel with fewer distinct values than this may be unmeasured (module docstring).
FEW_VALUES = 64
#: ... when its peak-to-peak is also below this fraction of the log's largest.
SMALL_FRACTION = 0.01
#: Peak-to-peak [N·m] at or below which a channel is flat.
FLAT_NM = 1e-12


@dataclass(frozen=True)
class LeftOut:
    """A joint left out of detection and why (timeline ``input.joints_left_out`` item)."""

    name: str
    reason: str

    def to_dict(self) -> dict[str, str]:
        """JSON-ready mapping."""
        return {"name": self.name, "reason": self.reason}


def unusable_columns(values: np.ndarray, reference_ptp: float | None = None) -> list[str | None]:
    """Per column of ``values`` (N, J): None if usable, else why not (``flat`` or
    ``unmeasured`` with the figures; module docstring).

    Args:
        values: (N, J) a torque-like channel [N·m]; columns without a finite value are
            skipped (None).
        reference_ptp: the largest peak-to-peak to compare with [N·m]; default the largest
            among ``values``' own columns.
    """
    return ColumnScreen.of(np.asarray(values, dtype=np.float64)).unusable(reference_ptp)


@dataclass(frozen=True)
class ColumnScreen:
    """What the screen needs of a channel's columns, gathered chunk by chunk.

    Attributes:
        logged: (J,) bool, whether the column holds a finite value.
        ptp: (J,) float64 peak-to-peak of its finite values [N·m] (0 when not logged).
        first: (J,) float64 its first finite value (NaN when not logged).
        n_distinct: (J,) int64 its distinct finite values, counted up to
            :data:`FEW_VALUES` (that many: that many or more).
        lo, hi: (J,) float64 its smallest and largest finite value (NaN when not logged).
    """

    logged: np.ndarray
    ptp: np.ndarray
    first: np.ndarray
    n_distinct: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def unusable(self, reference_ptp: float | None = None,
                 posed: np.ndarray | None = None) -> list[str | None]:
        """Per column None, or why it is not usable (module docstring); against
        ``reference_ptp``, by default the largest peak-to-peak among these columns.
        ``posed``: (J,) whether each column varies with the arm's poses
        (:func:`impactcli.logs.poses.pose_explained`): such a column is measured, however
        few values it shows and however small its range beside the other joints'."""
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
            elif not (ref > 0 and ptp < SMALL_FRACTION * ref) or (
                    posed is not None and posed[j]):  # a range of its own, or it moves
                out.append(None)                      # with the arm's poses: measured
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
                            self.n_distinct[keep], self.lo[keep], self.hi[keep])


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
            lo, hi = column_range(v)
        else:
            c, f = by_column(v), by_column(fin)
            lo = np.where(f, c, np.inf).min(axis=1)
            hi = np.where(f, c, -np.inf).max(axis=1)
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
        return ColumnScreen(logged, ptp, self.first.copy(), n,
                            np.where(logged, self.lo, np.nan), np.where(logged, self.hi, np.nan))
