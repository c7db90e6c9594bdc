"""Which joints and channels a detector can use at all (real-log hygiene).

A real log may carry a torque channel that is not measured: a wrist effort stuck at zero,
or one that only shows a few dozen distinct values around zero while the other joints
carry tens of N·m. Calibrated as it is, such a channel gets a threshold of a hundredth of
a N·m and raises every alarm on that robot. So before anything else a joint whose torque
is **flat** or **unmeasured** is left out of detection, with a warning and a record in the
timeline (``input.joints_left_out``):

* flat — its torque takes one value only (peak-to-peak ≤ 1e-12 N·m);
* unmeasured — fewer than :data:`FEW_VALUES` distinct values *and* a peak-to-peak below
  :data:`SMALL_FRACTION` of the largest peak-to-peak among the log's torque channels (a
  quantised but real channel has either many values or a comparable range).

The controller's channels (``torque_model``, ``torque_ext``) are screened the same way;
a flat or unmeasured one is read as not logged for that joint (its joint keeps the tool's
own model), with a warning.

Pure functions of arrays (no I/O); the pipeline applies them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A channel with fewer distinct values than this may be unmeasured (see module docstring).
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
    ``unmeasured`` with the figures).

    Args:
        values: (N, J) a torque-like channel [N·m]; all-NaN columns are skipped (None).
        reference_ptp: the largest peak-to-peak to compare with [N·m]; default the largest
            among ``values``' own columns.
    """
    v = np.asarray(values, dtype=np.float64)
    logged = ~np.all(np.isnan(v), axis=0)
    ptp = np.where(logged, np.nanmax(np.where(logged, v, 0.0), axis=0)
                   - np.nanmin(np.where(logged, v, 0.0), axis=0), 0.0)
    ref = float(np.max(ptp[logged])) if reference_ptp is None and logged.any() else (
        reference_ptp or 0.0)
    out: list[str | None] = []
    for j in range(v.shape[1]):
        if not logged[j]:
            out.append(None)
            continue
        col = v[:, j]
        col = col[np.isfinite(col)]
        if ptp[j] <= FLAT_NM:
            out.append(f"flat: its torque is constant ({float(col[0]):.6g} N·m)")
            continue
        if not (ref > 0 and ptp[j] < SMALL_FRACTION * ref):
            out.append(None)  # a range like the others': measured (no need to count values)
            continue
        n_distinct = int(np.unique(col).size)
        if n_distinct < FEW_VALUES:
            out.append(f"unmeasured: {n_distinct} distinct values spanning "
                       f"{ptp[j]:.3g} N·m, under {SMALL_FRACTION:.0%} of the largest "
                       f"joint's {ref:.3g} N·m")
            continue
        out.append(None)
    return out
