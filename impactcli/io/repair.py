"""The repair policy every reader applies (formats.md, "Canonical wide CSV").

Repairs are explicit and always warned about (:class:`~impactcli.errors.ImpactWarning`)
and recorded in ``RobotLog.source.repairs``:

* exact duplicate samples (same time, same values in every used channel, one after the
  other) are dropped;
* rows out of time order, only when asked (``read_log(..., repair_order=True)``, the
  command line's ``--repair-order``): the longest strictly increasing subsequence of the
  stamps is kept (O(N log N)) and the other rows are dropped, counted and warned about —
  what a logger that writes some rows late leaves on a clean time grid. Of rows sharing a
  stamp (a repeated stamp with other values) the last one written is kept;
* short gaps of non-finite values (NaN or ±inf) of at most :data:`MAX_GAP_SAMPLES`
  consecutive samples in one channel, with finite samples on both sides, are filled by
  linear interpolation in time.

A channel without a single finite value is not repaired: a controller channel
(``torque_model``, ``torque_ext``) is read as not logged for that joint; a position,
torque or current column (``keep_empty``) is passed on as NaN, and the joint is left out
of the log with a warning by :func:`impactcli.io.assemble.build_log`; so is an optional
signal's column (velocity, references), and the log is read without that signal, for
every joint, with a warning (:func:`impactcli.io.assemble.build_log`).

Anything else is a :class:`~impactcli.errors.LogFormatError` naming the file, the column
and the row: time that is not strictly increasing after dropping duplicates (without
``repair_order``; the message names the option — a repeated stamp with other values is
refused because which row is the sample is the user's call), a non-finite time, a longer
gap, a gap touching the start or end of the log, and a finite value beyond
±:data:`MAX_ABS_VALUE` (no joint measures that: a corrupt cell, which would overflow the
computation).
"""

from __future__ import annotations

import bisect
import contextlib
import warnings
from collections.abc import Callable, Collection, Iterator
from contextvars import ContextVar

import numpy as np

from ..errors import ImpactWarning, LogFormatError
from ..types import CONTROLLER_CHANNELS

#: Longest run of consecutive non-finite samples in one channel that is interpolated.
MAX_GAP_SAMPLES = 5
#: Largest magnitude of a value read (any channel, in its logged unit); beyond is an error.
MAX_ABS_VALUE = 1e12
#: Implied sample rates outside [MIN_RATE_HZ, MAX_RATE_HZ] are an error (formats.md).
MIN_RATE_HZ = 20.0
MAX_RATE_HZ = 100_000.0
#: Signals whose column may hold no finite value (passed on as NaN): a position or torque
#: (or current, the torque source) column leaves its joint out of the log; an optional
#: signal's column (velocity, current not the torque source, references) leaves that
#: signal out of the log (:func:`impactcli.io.assemble.build_log`).
DROPPABLE_SIGNALS = ("position", "torque", "current", "velocity", "position_ref",
                     "velocity_ref", "acceleration_ref")

_REPAIR_ORDER: ContextVar[bool] = ContextVar("impactcli_repair_order", default=False)


@contextlib.contextmanager
def repairing_order(on: bool) -> Iterator[None]:
    """Within the block, readers that do not pass ``repair_order`` themselves repair rows
    out of time order (:func:`impactcli.io.read_log`'s ``repair_order``)."""
    token = _REPAIR_ORDER.set(on)
    try:
        yield
    finally:
        _REPAIR_ORDER.reset(token)


def longest_increasing(t: np.ndarray) -> np.ndarray:
    """Indices of a longest strictly increasing subsequence of ``t`` (patience sorting,
    O(N log N)); of equal values the last one is kept.

    Args:
        t: (N,) int64 stamps.
    Returns:
        (M,) int64 increasing indices into ``t``.
    """
    vals = t.tolist()
    tails: list[int] = []  # smallest tail value of an increasing run of each length
    tail_idx: list[int] = []
    parent = [-1] * len(vals)
    for i, v in enumerate(vals):
        k = bisect.bisect_left(tails, v)
        if k == len(tails):
            tails.append(v)
            tail_idx.append(i)
        else:
            tails[k] = v
            tail_idx[k] = i
        parent[i] = tail_idx[k - 1] if k else -1
    out = []
    i = tail_idx[-1] if tail_idx else -1
    while i >= 0:
        out.append(i)
        i = parent[i]
    return np.asarray(out[::-1], dtype=np.int64)


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
    repair_order: bool | None = None,
    keep_empty: Collection[str] | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray], list[str]]:
    """Apply the repair policy to one log's samples.

    Args:
        t_ns: (N,) int64 sample times [ns], in file order.
        columns: channel name → (N,) float64 values (the channels actually used).
        where: the file, for messages.
        time_name: name of the time channel, for messages.
        row_label: maps an original sample index to the text used in messages
            (e.g. ``row 57 (line 58)`` for CSV).
        repair_order: keep the longest increasing run of stamps instead of refusing rows
            out of order (None: as :func:`repairing_order` says, default no).
        keep_empty: channels that may hold no finite value (passed on as NaN; None: those
            named ``<joint>.<signal>`` for a signal of :data:`DROPPABLE_SIGNALS`).

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
        t_ns, mat, names, where=where, time_name=time_name, row_label=row_label,
        repair_order=repair_order, keep_empty=keep_empty,
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
    repair_order: bool | None = None,
    keep_empty: Collection[str] | None = None,
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
                msg = duplicate_message(where, int(dup.sum()), row_label(int(np.argmax(dup)) + 1))
                repairs.append(msg)
                warnings.warn(msg, ImpactWarning, stacklevel=3)
                t, mat, orig = t[keep], mat[keep], orig[keep]
        dt = np.diff(t)
        if np.any(dt <= 0):
            if _REPAIR_ORDER.get() if repair_order is None else repair_order:
                t, mat, orig = _keep_increasing(t, mat, orig, repairs, where, row_label)
            else:
                k = int(np.argmax(dt <= 0)) + 1
                raise LogFormatError(_order_message(t, k, orig, where, time_name, row_label))
    _check_magnitudes(mat, names, orig, where, row_label)
    bad = ~np.isfinite(mat)
    allbad = np.flatnonzero(bad.all(axis=0)) if mat.shape[0] else np.zeros(0, dtype=np.int64)
    # a position/torque/current column with no finite value: passed on as NaN, the joint is
    # left out of the log; an optional signal's: the signal is (build_log, warned there)
    droppable = (set(keep_empty) if keep_empty is not None else
                 {c for c in names if c.rsplit(".", 1)[-1] in DROPPABLE_SIGNALS})
    for c in allbad:
        if names[c] in droppable:
            if not mat.flags.writeable:
                mat = mat.copy()
            mat[:, c] = np.nan
            bad[:, c] = False
    # a controller channel (formats.md: torque_model, torque_ext) with no finite value at all
    # was not logged for that joint: kept as NaN (the joint lacks it), said in a warning
    empty = [c for c in allbad if names[c] not in droppable and is_controller_column(names[c])]
    for c in empty:
        msg = empty_controller_message(where, names[c])
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
                    raise LogFormatError(run_message(where, names[c], row_label(int(orig[s])),
                                                     length, kind, s == 0, e == mat.shape[0]))
            good = ~mask
            col[mask] = np.interp(tf[mask], tf[good], col[good])
            msg = interpolated_message(where, names[c], int(mask.sum()), len(starts),
                                       row_label(int(orig[starts[0]])))
            repairs.append(msg)
            warnings.warn(msg, ImpactWarning, stacklevel=3)
    return t, mat, repairs


def _order_message(t: np.ndarray, k: int, orig: np.ndarray, where: str, time_name: str,
                   row_label: Callable[[int], str]) -> str:
    """The error for the first step t[k-1] → t[k] that does not increase."""
    here = row_label(int(orig[k]))
    if t[k] == t[k - 1]:
        return (f"{where}: column {time_name!r}, {here}: time is repeated ({int(t[k])} ns, "
                f"as on {row_label(int(orig[k - 1]))}) with other values; it must be "
                "strictly increasing: --repair-order keeps the last row of each stamp and "
                "drops rows out of time order (warned)")
    return (f"{where}: column {time_name!r}, {here}: time is decreasing ({int(t[k - 1])} ns "
            f"then {int(t[k])} ns); it must be strictly increasing: rows written out of order "
            "are repaired by --repair-order (keeps the longest increasing run of stamps, "
            "drops the other rows, warned)")


def _keep_increasing(
    t: np.ndarray, mat: np.ndarray, orig: np.ndarray, repairs: list[str], where: str,
    row_label: Callable[[int], str],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Keep the longest strictly increasing run of stamps; record and warn what was dropped."""
    keep = longest_increasing(t)
    mask = np.zeros(t.shape[0], dtype=bool)
    mask[keep] = True
    dropped = np.flatnonzero(~mask)
    repeated = int(np.count_nonzero(np.isin(t[dropped], t[keep])))
    what = []
    if dropped.size - repeated:
        what.append(f"{dropped.size - repeated} out of time order")
    if repeated:
        what.append(f"{repeated} with a repeated stamp")
    msg = (f"{where}: dropped {dropped.size} row(s) ({', '.join(what)}; first at "
           f"{row_label(int(orig[dropped[0]]))}), keeping the longest increasing run of "
           f"stamps ({keep.size} rows; --repair-order)")
    repairs.append(msg)
    warnings.warn(msg, ImpactWarning, stacklevel=4)
    return t[keep], mat[keep], orig[keep]


def _check_magnitudes(mat: np.ndarray, names: list[str], orig: np.ndarray, where: str,
                      row_label: Callable[[int], str]) -> None:
    """LogFormatError naming the first finite value beyond ±MAX_ABS_VALUE."""
    if mat.size == 0:
        return
    with np.errstate(invalid="ignore"):
        big = np.abs(mat) > MAX_ABS_VALUE
    big &= np.isfinite(mat)
    if not big.any():
        return
    r, c = np.argwhere(big)[0]
    raise LogFormatError(magnitude_message(where, names[int(c)], row_label(int(orig[int(r)])),
                                           float(mat[r, c])))


def magnitude_message(where: str, name: str, label: str, value: float) -> str:
    """The error for a finite value beyond ±:data:`MAX_ABS_VALUE`."""
    return (f"{where}: column {name!r}, {label}: value {value:g} is beyond "
            f"±{MAX_ABS_VALUE:g}: no joint measures that (a corrupt cell, or a unit far off)")


def duplicate_message(where: str, count: int, first_label: str) -> str:
    """The repair of ``count`` exact duplicate samples, the first at ``first_label``."""
    return f"{where}: dropped {count} exact duplicate sample(s) (first at {first_label})"


def is_controller_column(name: str) -> bool:
    """Whether a column named ``<joint>.torque_model`` or ``.torque_ext`` is a controller
    channel (read as not logged when it holds no finite value)."""
    return name.rsplit(".", 1)[-1] in CONTROLLER_CHANNELS


def empty_controller_message(where: str, name: str) -> str:
    """The repair of a controller column without a finite value."""
    return (f"{where}: column {name!r} holds no finite value: joint "
            f"{name.rsplit('.', 1)[0]!r} is read as not logging {name.rsplit('.', 1)[-1]}")


def interpolated_message(where: str, name: str, count: int, runs: int, first_label: str) -> str:
    """The repair of ``count`` non-finite values in ``runs`` gaps of column ``name``."""
    return (f"{where}: column {name!r}: interpolated {count} non-finite value(s) in {runs} "
            f"gap(s) (first at {first_label})")


def run_message(where: str, name: str, label: str, length: int, kind: str, at_start: bool,
                at_end: bool) -> str:
    """The error for a run of non-finite values that is not interpolated (one that spans
    the whole log: the column holds no finite value)."""
    if at_start and at_end:
        why = f"no finite value in the column (all {length} values are non-finite, {kind})"
    else:
        why = (f"a run of {length} non-finite ({kind}) value(s)"
               + (" at the start of the log" if at_start else "")
               + (" at the end of the log" if at_end else ""))
    return (f"{where}: column {name!r}, {label}: {why}; only gaps of at most "
            f"{MAX_GAP_SAMPLES} samples between finite values are interpolated")


def check_time_rate(t_ns: np.ndarray, where: str, what: str, unit: str | None) -> None:
    """LogFormatError when the rate implied by the stamps is outside
    [:data:`MIN_RATE_HZ`, :data:`MAX_RATE_HZ`] — a time column in another unit than read
    (formats.md) — naming the rate and the unit that would fit.

    Args:
        t_ns: (N,) int64 strictly increasing stamps [ns] as read.
        where: the file.  what: the time channel, e.g. ``column 'time'``.
        unit: the unit it was read in (``s``, ``ms``, ``us``, ``ns``; None: not a unit the
            user chooses, e.g. ISO-8601 stamps).
    """
    from ..sampling import MAX_STATS_STEPS, sample_clock

    rate = sample_clock(t_ns[:MAX_STATS_STEPS + 1]).rate_hz  # a unit is a unit from the start
    msg = rate_message(rate, where, what, unit)
    if msg is not None:
        raise LogFormatError(msg)


def rate_message(rate: float, where: str, what: str, unit: str | None) -> str | None:
    """The error of :func:`check_time_rate` for the rate ``rate`` [Hz] of the first
    :data:`~impactcli.sampling.MAX_STATS_STEPS` steps (None: within the range)."""
    if not np.isfinite(rate) or MIN_RATE_HZ <= rate <= MAX_RATE_HZ:
        return None
    return (f"{where}: {what}: the implied sample rate is {_hz(rate)}, outside "
            f"{_hz(MIN_RATE_HZ)} – {_hz(MAX_RATE_HZ)}{unit_hint(rate, unit)}: {GIVE_UNIT}")


#: How to give a time column's unit (the end of the time-unit errors).
GIVE_UNIT = ("give the time unit with --time-unit s|ms|us|ns (or 'unit' under 'time' in a "
             "channel map)")


def unit_hint(rate_hz: float, unit: str | None) -> str:
    """``; read in s, it looks like ms (250 Hz)``: the unit in which a time column read in
    ``unit`` at ``rate_hz`` would give a rate in the accepted range ("" without a unit)."""
    from .channel_map import TIME_UNITS

    if unit is None or not rate_hz > 0:
        return ""
    fits = [(u, rate_hz * TIME_UNITS[unit] / TIME_UNITS[u]) for u in TIME_UNITS if u != unit]
    fits = [(u, r) for u, r in fits if MIN_RATE_HZ <= r <= MAX_RATE_HZ]
    return (f"; read in {unit}, it looks like {fits[0][0]} ({_hz(fits[0][1])})" if fits
            else f"; read in {unit}")



def _hz(rate: float) -> str:
    """``250 Hz``, ``0.25 Hz``, ``4 MHz``, ``100 kHz``."""
    for scale, name in ((1e6, "MHz"), (1e3, "kHz")):
        if rate >= scale:
            return f"{rate / scale:.4g} {name}"
    return f"{rate:.4g} Hz"
