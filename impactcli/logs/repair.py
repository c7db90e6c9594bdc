"""The repair policy every reader applies (docs/formats.md, "Canonical wide CSV"), over the
consecutive blocks of a log's rows (:class:`Repairer`): the decisions, values and messages
are those of the whole file at once.

Repairs are explicit, warned about (:class:`~impactcli.errors.ImpactWarning`) and recorded
in ``RobotLog.source.repairs``: exact duplicate samples (one after the other) are dropped;
with ``--repair-order`` only, rows out of time order are dropped, keeping the longest
strictly increasing run of stamps (:func:`longest_increasing`; of rows sharing a stamp the
last one written); runs of at most :data:`MAX_GAP_SAMPLES` non-finite values in a channel,
between finite values, are interpolated linearly in time. A column without a finite value
is not repaired: a controller channel's is read as not logged for that joint, a position,
torque or optional signal's is passed on as NaN (the joint, or the signal, is left out of
the log by the scan, warned).

Anything else is a :class:`~impactcli.errors.LogFormatError` naming the file, the column
and the row: time not strictly increasing (without ``--repair-order``: which row is the
sample is the user's call), a longer run of non-finite values or one touching the start or
end, a finite value beyond ±:data:`MAX_ABS_VALUE` (a corrupt cell), and a time column whose
implied rate says it is in another unit (:func:`rate_message`).
"""

from __future__ import annotations

import bisect
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import LogFormatError
from ..sample_channels import CONTROLLER_CHANNELS

if TYPE_CHECKING:
    from .layout import RawRows, StreamLayout

#: Longest run of consecutive non-finite samples in one channel that is interpolated.
MAX_GAP_SAMPLES = 5
#: Largest magnitude of a value read (any channel, in its logged unit); beyond is an error.
MAX_ABS_VALUE = 1e12
#: A step back in time of more than this many of the log's typical steps is a recording
#: starting again (files concatenated), not rows written out of order: refused, naming the
#: recordings; --repair-order does not merge them.
RESTART_STEPS = 50
#: Positive time steps kept to estimate the typical step.
PERIOD_STEPS = 1000
#: Implied sample rates outside [MIN_RATE_HZ, MAX_RATE_HZ] are an error (docs/formats.md).
MIN_RATE_HZ = 20.0
MAX_RATE_HZ = 100_000.0

def restart_message(where: str, time_name: str, rows: list[str]) -> str:
    """The error for a file whose time restarts at ``rows`` (their labels)."""
    shown = ", ".join(rows[:5]) + (f" and {len(rows) - 5} more" if len(rows) > 5 else "")
    return (f"{where}: column {time_name!r}: time starts again {len(rows)} time(s), at "
            f"{shown}: the file holds {len(rows) + 1} recordings one after another, not one "
            "log; split it at those rows and analyse each (--repair-order does not merge "
            "recordings)")


def restart_rows(t: np.ndarray, typical: float | None = None) -> np.ndarray:
    """Indices k where a recording starts again: t[k] lies more than :data:`RESTART_STEPS`
    typical steps before t[k − 1], and the next row goes on from it (t[k] < t[k + 1] <
    t[k − 1]) — one row far out of order is not a restart. The typical step: ``typical``,
    else the median of the first positive steps."""
    d = np.diff(t)
    if typical is None:
        pos = d[d > 0][:PERIOD_STEPS]
        if pos.size == 0:
            return np.zeros(0, dtype=np.int64)
        typical = float(np.median(pos))
    k = np.flatnonzero(d < -RESTART_STEPS * typical) + 1
    k = k[k + 1 < t.shape[0]]
    return k[(t[k + 1] > t[k]) & (t[k + 1] < t[k - 1])]


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


def order_message(t: np.ndarray, k: int, orig: np.ndarray, where: str, time_name: str,
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


def increasing_run(t: np.ndarray, orig: np.ndarray, where: str,
                   row_label: Callable[[int], str], time_name: str = "time"
                   ) -> tuple[np.ndarray, str]:
    """``--repair-order``: the rows kept (the longest strictly increasing run of stamps,
    :func:`longest_increasing`) and the repair's message.

    Args:
        t: (N,) int64 the stamps after dropping exact duplicates (some out of order).
        orig: (N,) int64 their rows in the file (for the message).

    Raises:
        LogFormatError: the time starts again (:func:`restart_rows`): recordings one after
            another are not merged.
    """
    restarts = restart_rows(t)
    if restarts.size:
        raise LogFormatError(restart_message(where, time_name, [row_label(int(orig[k]))
                                                                for k in restarts]))
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
    return keep, msg


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


#: A log's duration as read is plausible from this long [s] (a shorter one is no robot
#: log: warm-up alone takes seconds) ...
MIN_PLAUSIBLE_DURATION_S = 1.0
#: ... to this long [s]: a log read in a unit that makes it last longer than a day at a
#: rate below :data:`MIN_RATE_HZ` is most likely in a smaller unit (ms read as s).
MAX_PLAUSIBLE_DURATION_S = 86_400.0
#: The rates robot controllers log at [Hz] (UR 125/500, KUKA FRI and Franka 1 k, drives a
#: few k): another unit is suggested for a low rate only when it gives one of these.
TYPICAL_RATE_HZ = (50.0, 4_000.0)


def needed_rate_hz() -> tuple[float, float]:
    """The sample rate impact detection needs [Hz] and why: twice the upper corner w2 of
    the adaptive detector's band-pass (Table I's, docs/method.md §5b) — ``(2 × w2, w2)``."""
    from ..config import AdaptiveConfig

    w2 = float(AdaptiveConfig().w2_hz)
    return 2.0 * w2, w2


def rate_message(rate: float, where: str, what: str, unit: str | None,
                 duration_s: float | None = None) -> str | None:
    """The error for a log whose rate ``rate`` [Hz] (of its time column's first
    :data:`~impactcli.clock.MAX_STATS_STEPS` steps read in ``unit``; ``unit`` None: ISO
    stamps or ``--rate``, ``what`` naming which) is outside [:data:`MIN_RATE_HZ`,
    :data:`MAX_RATE_HZ`]; None when within the range (docs/formats.md, "Time").

    Above the range, or below it when another unit is far more likely than the rate
    (:func:`other_unit_likely`), the time is in another unit than read: the message names
    the rate and the unit that fits. Below it otherwise, the log is read right and its rate
    is too low for impact detection: the message names the rate, the duration read and the
    rate the detector needs (:func:`needed_rate_hz`).

    Args:
        duration_s: the log's duration as read [s], when known.
    """
    if not np.isfinite(rate) or MIN_RATE_HZ <= rate <= MAX_RATE_HZ:
        return None
    if rate > MAX_RATE_HZ or other_unit_likely(rate, unit, duration_s):
        return (f"{where}: {what}: the implied sample rate is {_hz(rate)}, outside "
                f"{_hz(MIN_RATE_HZ)} – {_hz(MAX_RATE_HZ)}{unit_hint(rate, unit)}: "
                f"{GIVE_UNIT}")
    need, w2 = needed_rate_hz()
    dur = f" (a log of {_duration(duration_s)}, read in {unit})" if duration_s and unit else ""
    other = (f"; if the time column is not in {unit}, give --time-unit s|ms|us|ns"
             if unit is not None else "")
    said = "the sample rate" if unit is not None or what != "--rate" else "the rate given"
    return (f"{where}: {what}: {said} is {_hz(rate)}{dur}: too low for impact detection, "
            f"which needs at least {_hz(need)} (twice the detector's band-pass corner w2 = "
            f"{w2:g} Hz): record the arm at {_hz(need)} or more{other}")


def other_unit_likely(rate: float, unit: str | None, duration_s: float | None) -> bool:
    """Whether a time column read in ``unit`` at ``rate`` < :data:`MIN_RATE_HZ` [Hz] is
    more likely in a smaller unit: read in it, the rate is a controller's
    (:data:`TYPICAL_RATE_HZ`) and the duration at least :data:`MIN_PLAUSIBLE_DURATION_S`;
    or read in ``unit`` the log would last beyond :data:`MAX_PLAUSIBLE_DURATION_S` while a
    smaller unit gives a rate in the accepted range (docs/formats.md, "Time")."""
    from .channel_map import TIME_UNITS

    if unit is None or not rate > 0:
        return False
    for size in TIME_UNITS.values():
        f = TIME_UNITS[unit] / size
        if f <= 1:
            continue
        r = rate * f
        long_enough = duration_s is None or duration_s / f >= MIN_PLAUSIBLE_DURATION_S
        if TYPICAL_RATE_HZ[0] <= r <= TYPICAL_RATE_HZ[1] and long_enough:
            return True
        if (duration_s is not None and duration_s > MAX_PLAUSIBLE_DURATION_S
                and MIN_RATE_HZ <= r <= MAX_RATE_HZ):
            return True
    return False


def _duration(seconds: float) -> str:
    """``26 s``, ``3.2 min``, ``5.1 h``, ``12 days``."""
    for scale, name in ((86_400.0, "days"), (3_600.0, "h"), (60.0, "min")):
        if seconds >= 2 * scale:
            return f"{seconds / scale:.3g} {name}"
    return f"{seconds:.3g} s"


#: How to give a time column's unit (the end of the time-unit errors).
GIVE_UNIT = ("give the time unit with --time-unit s|ms|us|ns (or 'unit' under 'time' in a "
             "channel map)")


def unit_hint(sample_rate_hz: float, unit: str | None) -> str:
    """``; read in s, it looks like ms (250 Hz)``: the unit in which a time column read in
    ``unit`` at ``sample_rate_hz`` would give a rate in the accepted range ("" without a unit)."""
    from .channel_map import TIME_UNITS

    if unit is None or not sample_rate_hz > 0:
        return ""
    fits = [(u, sample_rate_hz * TIME_UNITS[unit] / TIME_UNITS[u]) for u in TIME_UNITS if u != unit]
    fits = [(u, r) for u, r in fits if MIN_RATE_HZ <= r <= MAX_RATE_HZ]
    return (f"; read in {unit}, it looks like {fits[0][0]} ({_hz(fits[0][1])})" if fits
            else f"; read in {unit}")



def _hz(rate: float) -> str:
    """``250 Hz``, ``0.25 Hz``, ``4 MHz``, ``100 kHz``."""
    for scale, name in ((1e6, "MHz"), (1e3, "kHz")):
        if rate >= scale:
            return f"{rate / scale:.4g} {name}"
    return f"{rate:.4g} Hz"


class RepairOrderNeeded(Exception):
    """Rows out of time order met with ``--repair-order``: the scan finds the rows to keep
    over the whole file's stamps first (:class:`Repairer`)."""


@dataclass
class Violation:
    """A run of non-finite values that is not interpolated (the first of its column)."""

    orig: int
    length: int
    kind: str
    at_start: bool
    at_end: bool


class Repairer:
    """The repair policy (module docstring) over the consecutive blocks of a log's rows:
    the decisions, values and messages are those of the whole file at once.

    Rows are held back while a run of non-finite values (at most ``MAX_GAP_SAMPLES`` long,
    not at the start) is open; errors are recorded (the first of each kind) and raised by
    the scan in the order the whole file gives them (:meth:`first_error`).

    ``--repair-order`` needs the whole file's stamps: a first pass meeting rows out of
    order raises :class:`RepairOrderNeeded`; the scan then finds the rows to keep
    (:func:`increasing_run` over the stamps of :meth:`deduplicated`) and passes them in
    as ``order_keep`` (a bool per row of the file) with the repair's message.
    """

    def __init__(self, ctx: StreamLayout, allbad: frozenset[int] | None,
                 order_keep: np.ndarray | None = None, order_repair: str | None = None
                 ) -> None:
        self.ctx = ctx
        self.order_keep = order_keep  # --repair-order: the rows of the file kept
        self.order_repair = order_repair
        self.names = list(ctx.names)
        c = len(self.names)
        self.label = ctx.label
        # a column that may hold no finite value (droppable, and controller channels): not
        # repaired then
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
        self.steps: list[int] = []  # the first positive time steps (the typical step)
        self.restarts: list[int] = []  # rows of the file where the time starts again
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
        self.violation: list[Violation | None] = [None] * c
        self.empty = np.zeros(c, dtype=bool)  # exempt columns without a finite value

    @property
    def failed(self) -> bool:
        """Whether an order or magnitude error was found (rows are no longer given out)."""
        return (self.order_error is not None or self.mag_error is not None
                or bool(self.restarts))

    def deduplicated(self, raw: RawRows) -> tuple[np.ndarray, np.ndarray]:
        """A block's rows after dropping exact duplicates: their stamps and rows in the
        file (the pass that finds the rows ``--repair-order`` keeps)."""
        orig = np.arange(raw.row0, raw.row0 + raw.t.shape[0], dtype=np.int64)
        keep = self._not_duplicate(raw.t, raw.mat, orig)
        return (raw.t, orig) if keep is None else (raw.t[keep], orig[keep])

    def push(self, raw: RawRows) -> tuple[np.ndarray, np.ndarray] | None:
        """Repair the next batch; the rows that are final: ``(t, mat)`` or None."""
        if self.order_error is not None:
            return None
        if self.restarts:  # the file is refused: only the other restarts are counted
            orig = np.arange(raw.row0, raw.row0 + raw.t.shape[0], dtype=np.int64)
            self._check_order(raw.t, orig)
            return None
        n = raw.t.shape[0]
        orig = np.arange(raw.row0, raw.row0 + n, dtype=np.int64)
        keep = self._not_duplicate(raw.t, raw.mat, orig)
        if self.order_keep is not None:
            mine = self.order_keep[orig]
            keep = mine if keep is None else keep & mine
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
                self.empty[c] = True  # no finite value: not repaired
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
        tt = t if self.last_t is None else np.concatenate(([self.last_t], t))
        oo = orig if self.last_t is None else np.concatenate(([self.last_orig], orig))
        d = np.diff(tt)
        if len(self.steps) < PERIOD_STEPS:
            self.steps += d[d > 0][:PERIOD_STEPS - len(self.steps)].tolist()
        bad = np.flatnonzero(d <= 0)
        if bad.size:
            typical = float(np.median(self.steps)) if self.steps else np.inf
            big = restart_rows(tt, typical) - 1  # the steps into a recording starting again
            if big.size and (self.restarts or big[0] == bad[0]):
                self.restarts += [int(oo[k + 1]) for k in big]
        if self.restarts:  # refused: the next block's order is checked from this one's end
            self.last_t, self.last_orig = int(tt[-1]), int(oo[-1])
            return
        if bad.size == 0:
            return
        if self.ctx.repair_order:
            raise RepairOrderNeeded
        k = int(bad[0]) + 1
        self.order_error = order_message(tt[k - 1:k + 1], 1, oo[k - 1:k + 1],
                                          self.ctx.where, self.ctx.time_name, self.label)

    def _check_magnitudes(self, mat: np.ndarray, orig: np.ndarray) -> None:
        with np.errstate(invalid="ignore"):
            big = np.abs(mat) > MAX_ABS_VALUE
        if not big.any():
            return
        big &= np.isfinite(mat)
        if big.any():
            r, c = np.argwhere(big)[0]
            self.mag_error = magnitude_message(self.ctx.where, self.names[int(c)],
                                               self.label(int(orig[int(r)])),
                                               float(mat[r, c]))

    def _violate(self, c: int, orig: int, length: int, kind: str, at_start: bool,
                 at_end: bool) -> None:
        if self.violation[c] is None:
            self.violation[c] = Violation(orig, length, kind, at_start, at_end)

    def _runs(self, t: np.ndarray, mat: np.ndarray, orig: np.ndarray,
              k0_new: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Interpolate the runs of non-finite values that closed; give out the rows before
        the first open run."""
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
        """The error the whole file is refused with first, if any: rows out of order, a
        value beyond 1e12, a run of non-finite values (the first column's)."""
        if self.order_error is not None:
            return self.order_error
        if self.restarts:
            return restart_message(self.ctx.where, self.ctx.time_name,
                                   [self.label(r) for r in self.restarts])
        if self.mag_error is not None:
            return self.mag_error
        for c, v in enumerate(self.violation):
            if v is not None:
                return run_message(self.ctx.where, self.names[c], self.label(v.orig),
                                   v.length, v.kind, v.at_start, v.at_end)
        return None

    def repairs(self) -> list[str]:
        """The repairs, in the order the whole file gives them."""
        where = self.ctx.where
        out = []
        if self.n_dup:
            out.append(duplicate_message(where, self.n_dup, self.label(self.dup_first)))
        if self.order_repair is not None:
            out.append(self.order_repair)
        for c in np.flatnonzero(self.empty):
            if self.names[c] not in self.ctx.droppable:
                out.append(empty_controller_message(where, self.names[c]))
        for c in np.flatnonzero(self.n_runs):
            first = self.label(int(self.first_run[c]))
            out.append(interpolated_message(where, self.names[c], int(self.n_interp[c]),
                                            int(self.n_runs[c]), first))
        return out


