"""The repair policy every reader applies (formats.md, "Canonical wide CSV").

Repairs are explicit and always warned about (:class:`~impactcli.errors.ImpactWarning`)
and recorded in ``RobotLog.source.repairs``:

* exact duplicate samples (same time, same values in every used channel) are dropped;
* short gaps of non-finite values (NaN or ±inf) of at most :data:`MAX_GAP_SAMPLES`
  consecutive samples in one channel, with finite samples on both sides, are filled by
  linear interpolation in time.

Anything else — time that is not strictly increasing after dropping duplicates, a
non-finite time, a longer gap, a gap touching the start or end of the log — is a
:class:`~impactcli.errors.LogFormatError` naming the file, the column and the row.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from ..errors import ImpactWarning, LogFormatError
from ..types import CONTROLLER_CHANNELS

#: Longest run of consecutive non-finite samples in one channel that is interpolated.
MAX_GAP_SAMPLES = 5


def default_row_label(i: int) -> str:
    """Label of sample ``i`` (0-based) in messages: ``sample i``."""
    return f"sample {i}"


def repair_samples(
    t_ns: np.ndarray,
    columns: dict[str, np.ndarray],
    *,
    where: str,
    time_name: str = "time",
    row_label: Callable[[int], str] = default_row_label,
) -> tuple[np.ndarray, dict[str, np.ndarray], list[str]]:
    """Apply the repair policy to one log's samples.

    Args:
        t_ns: (N,) int64 sample times [ns], in file order.
        columns: channel name → (N,) float64 values (the channels actually used).
        where: the file, for messages.
        time_name: name of the time channel, for messages.
        row_label: maps an original sample index to the text used in messages
            (e.g. ``row 57 (line 58)`` for CSV).

    Returns:
        ``(t_ns, columns, repairs)``: repaired copies and the list of repairs made
        (each also warned about).
    """
    names = list(columns)
    n = np.asarray(t_ns).shape[0]
    mat = (
        np.column_stack([np.asarray(columns[k], dtype=np.float64) for k in names])
        if names else np.empty((n, 0))
    )
    t, mat, repairs = repair_matrix(
        t_ns, mat, names, where=where, time_name=time_name, row_label=row_label
    )
    out = {k: np.ascontiguousarray(mat[:, i]) for i, k in enumerate(names)}
    return t, out, repairs


def repair_matrix(
    t_ns: np.ndarray,
    mat: np.ndarray,
    names: list[str],
    *,
    where: str,
    time_name: str = "time",
    row_label: Callable[[int], str] = default_row_label,
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """:func:`repair_samples` on an (N, C) float64 matrix whose columns are ``names``.

    Returns ``(t_ns, mat, repairs)``; ``mat`` may be the input array, modified in place.
    """
    repairs: list[str] = []
    t = np.asarray(t_ns, dtype=np.int64)
    n = t.shape[0]
    orig = np.arange(n)
    if n >= 2:
        dt = np.diff(t)
        same_t = dt == 0
        if same_t.any():
            a, b = mat[:-1], mat[1:]
            same_vals = np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1)
            dup = same_t & same_vals
            if dup.any():
                keep = np.ones(n, dtype=bool)
                keep[1:][dup] = False
                k = int(dup.sum())
                first = row_label(int(np.argmax(dup)) + 1)
                msg = f"{where}: dropped {k} exact duplicate sample(s) (first at {first})"
                repairs.append(msg)
                warnings.warn(msg, ImpactWarning, stacklevel=3)
                t, mat, orig = t[keep], mat[keep], orig[keep]
        dt = np.diff(t)
        if np.any(dt <= 0):
            k = int(np.argmax(dt <= 0)) + 1
            what = "repeated" if dt[k - 1] == 0 else "decreasing"
            raise LogFormatError(
                f"{where}: column {time_name!r}, {row_label(int(orig[k]))}: time is {what} "
                f"({int(t[k - 1])} ns then {int(t[k])} ns); it must be strictly increasing"
            )
    bad = ~np.isfinite(mat)
    # a controller channel (formats.md: torque_model, torque_ext) with no finite value at all
    # was not logged for that joint: kept as NaN (the joint lacks it), said in a warning
    empty = [c for c in np.flatnonzero(bad.all(axis=0))
             if names[c].rsplit(".", 1)[-1] in CONTROLLER_CHANNELS] if n else []
    for c in empty:
        msg = (f"{where}: column {names[c]!r} holds no finite value: joint "
               f"{names[c].rsplit('.', 1)[0]!r} is read as not logging "
               f"{names[c].rsplit('.', 1)[-1]}")
        repairs.append(msg)
        warnings.warn(msg, ImpactWarning, stacklevel=3)
        if not mat.flags.writeable:
            mat = mat.copy()
        mat[:, c] = np.nan
        bad[:, c] = False
    if bad.any():
        tf = t.astype(np.float64)
        if not mat.flags.writeable:
            mat = mat.copy()
        for c in np.flatnonzero(bad.any(axis=0)):
            col = mat[:, c]
            mask = bad[:, c]
            # runs of consecutive non-finite samples: [start, stop)
            edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
            starts = np.flatnonzero(edges == 1)
            stops = np.flatnonzero(edges == -1)
            for s, e in zip(starts, stops, strict=True):
                length = int(e - s)
                kind = "NaN" if np.isnan(col[s]) else "infinite"
                if s == 0 or e == mat.shape[0] or length > MAX_GAP_SAMPLES:
                    why = (
                        f"a run of {length} non-finite ({kind}) value(s)"
                        + (" at the start of the log" if s == 0 else "")
                        + (" at the end of the log" if e == mat.shape[0] else "")
                    )
                    raise LogFormatError(
                        f"{where}: column {names[c]!r}, {row_label(int(orig[s]))}: {why}; "
                        f"only gaps of at most {MAX_GAP_SAMPLES} samples between finite "
                        "values are interpolated"
                    )
            good = ~mask
            col[mask] = np.interp(tf[mask], tf[good], col[good])
            msg = (
                f"{where}: column {names[c]!r}: interpolated {int(mask.sum())} non-finite "
                f"value(s) in {len(starts)} gap(s) (first at {row_label(int(orig[starts[0]]))})"
            )
            repairs.append(msg)
            warnings.warn(msg, ImpactWarning, stacklevel=3)
    return t, mat, repairs
