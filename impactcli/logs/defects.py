"""Data defects in a log's positions, found in the scan's one pass: steps of a whole turn
(unwrapped, and said) and jumps that no motion of the joint explains (a recording splice,
a glitch), or so many of them that the rows cannot be consecutive (refused).

A *wrap* is a step Δq within :data:`WRAP_TOL_RAD` of a non-zero multiple of 2π: a joint
logged modulo a turn. The positions after it are shifted by that many turns (the scan and
every pass after it see the unwrapped positions, :func:`unwrap_positions`).

A *jump* is a step that the samples around it cannot have made: one step i (from sample i
to i+1) that differs, for some joint, from both steps beside it by more than an arm's joint
can change its motion in one sample:

    min(|Δq_i − Δq_(i−1)|, |Δq_i − Δq_(i+1)|) > max(JUMP_RAD, MAX_ACCEL_RAD_S2 · Δt_i²)

on a step no longer than :data:`~impactcli.clock.GAP_FACTOR` times its neighbours (a longer
one is a time gap, counted as such). Two consecutive steps of a moving joint differ by its
acceleration times Δt² (a braking joint changes one step only, so one of the two
differences stays small); a splice of two recordings shifts one step against both its
neighbours, and a glitch of one sample makes two such steps. Its logged velocity is not
needed. A joint whose positions are noisy needs more: a jump also stands
:data:`NOISE_FACTOR` times above the median of those differences over the whole log, and
:data:`TAIL_FACTOR` times above their 99th percentile (a log in degrees read as radians is
noise, or quantisation, at 0.01 "rad"; a splice stands out of both).

A log has **rows that cannot be consecutive** — shuffled, or recordings interleaved — when
most of its moving joints (a range of :data:`MOVING_RANGE_RAD` or more) step, in the median,
by more than :data:`SHUFFLED_STEP_SHARE` of their range from one sample to the next (a
consecutive log steps by a small fraction of it: the median step of a shuffled one is about
a third of the range); it is refused (exit 3). The medians come from log-spaced histograms of
every :data:`STATS_EVERY`-th step (within a tenth of a decade).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba as nb
import numpy as np

from ..clock import GAP_FACTOR

#: A step this close to a non-zero multiple of 2π is a wrap of the logged angle [rad].
WRAP_TOL_RAD = 1.0
#: The smallest position step that can be a jump [rad] (0.57°).
JUMP_RAD = 0.01
#: An arm's joint accelerates at most about this much [rad/s²]: a step may differ from a
#: still joint's by this times Δt² (at 125 Hz, 0.016 rad; at 500 Hz, JUMP_RAD governs).
MAX_ACCEL_RAD_S2 = 250.0
#: A jump also stands this many times above the median of the joint's step differences,
#: and TAIL_FACTOR times above their TAIL_Q quantile (a quantised position's median is 0).
NOISE_FACTOR = 10.0
TAIL_FACTOR = 3.0
TAIL_Q = 0.99
#: A joint moves when its positions span this much [rad] ...
MOVING_RANGE_RAD = 0.1
#: ... and its rows cannot be consecutive when its median step exceeds this share of it.
SHUFFLED_STEP_SHARE = 0.2
#: The medians are taken over every STATS_EVERY-th step (cost), in bins of a tenth of a
#: decade from 1e-10 rad.
STATS_EVERY = 16
BINS_PER_DECADE = 10
LOWEST_LOG10 = -10.0
N_BINS = 130
#: At most this many jump candidates are kept per joint, the largest (a noisy joint's
#: candidates never crowd out another joint's splice).
MAX_KEPT = 2_000


@dataclass(frozen=True)
class Jump:
    """A step no motion explains: from sample ``i - 1`` to ``i`` (``i`` the sample after
    it) on ``joint`` (its index among the scan's joints); ``size`` [rad]: how far it is
    from the nearer of the steps beside it."""

    i: int
    joint: int
    size: float
    t_ns: int = 0


@dataclass(frozen=True)
class Wrap:
    """A whole-turn step unwrapped: ``turns`` (non-zero) removed from ``joint``'s positions
    from sample ``i`` on."""

    i: int
    joint: int
    turns: int
    t_ns: int = 0


@nb.njit(cache=True, error_model="numpy")
def _bin(x: float) -> int:  # pragma: no cover - compiled
    """The histogram bin of a value ≥ 0 (module docstring), -1 for NaN."""
    if math.isnan(x):
        return -1
    if math.isinf(x):
        return N_BINS - 1
    if x < 10.0 ** LOWEST_LOG10:
        return 0
    return min(int((math.log10(x) - LOWEST_LOG10) * BINS_PER_DECADE) + 1, N_BINS - 1)


@nb.njit(cache=True, error_model="numpy")
def _judge(dd: np.ndarray, dts: np.ndarray, lo: int, off: int, apart: np.ndarray,
           h_apart: np.ndarray, h_step: np.ndarray) -> np.ndarray:  # pragma: no cover
    """One pass over the steps ``dd`` (m, J) [rad] of lengths ``dts`` (m,) [s]: for each step
    i in lo .. m − 2 and joint, how far it is from the nearer of its neighbours; every
    STATS_EVERY-th step from ``lo + off`` counted in ``h_apart`` and (its size) ``h_step``;
    the steps with a jump (module docstring) returned, ``apart`` holding their size where a
    joint jumps and NaN elsewhere."""
    m, nj = dd.shape
    out = np.empty(max(m, 0), dtype=np.int64)
    n_out = 0
    for i in range(lo, m - 1):
        span = dts[i]
        limit = max(JUMP_RAD, MAX_ACCEL_RAD_S2 * span * span)
        regular = span <= GAP_FACTOR * min(dts[i - 1], dts[i + 1])
        counted = (i - lo - off) % STATS_EVERY == 0
        hit = False
        for j in range(nj):
            x = dd[i, j]
            a = abs(x - dd[i - 1, j])
            b = abs(x - dd[i + 1, j])
            d = a if a < b else b  # NaN neighbours: no comparison holds, never a jump
            hit |= d > limit and not math.isnan(a) and not math.isnan(b)
            if counted:
                k = _bin(d if not (math.isnan(a) or math.isnan(b)) else np.nan)
                if k >= 0:
                    h_apart[j, k] += 1
                k = _bin(abs(x))
                if k >= 0:
                    h_step[j, k] += 1
        if hit and regular:
            for j in range(nj):  # the row of the step that jumps: each joint's size or NaN
                x = dd[i, j]
                a = abs(x - dd[i - 1, j])
                b = abs(x - dd[i + 1, j])
                d = a if a < b else b
                apart[i, j] = d if d > limit and not (math.isnan(a) or math.isnan(b)) \
                    else np.nan
            out[n_out] = i
            n_out += 1
    return out[:n_out]


def _median(h: np.ndarray, q: float = 0.5) -> np.ndarray:
    """(J,) the median (or the ``q`` quantile) of each row's histogram (a bin's geometric
    centre; 0 in bin 0, NaN for an empty row)."""
    out = np.full(h.shape[0], np.nan)
    for j, row in enumerate(h):
        total = int(row.sum())
        if not total:
            continue
        k = int(np.searchsorted(np.cumsum(row), max(q * total, 0.5)))
        out[j] = 0.0 if k == 0 else 10.0 ** (LOWEST_LOG10 + (k - 0.5) / BINS_PER_DECADE)
    return out


@dataclass
class DefectScan:
    """The streaming finder (module docstring): :meth:`add` each block of positions [rad]
    in order (it returns them unwrapped), then :meth:`finish`."""

    n_joints: int
    unwrap_only: bool = False  # True: find the turns only (a reference's angles)
    n: int = 0  # samples seen
    steps: int = 0  # steps judged
    n_jumps: int = 0  # (step, joint) jumps (after finish)
    jump_steps: int = 0  # steps with a jump on some joint (after finish)
    jumps: list[Jump] = field(default_factory=list)
    wraps: list[Wrap] = field(default_factory=list)
    offset: np.ndarray = field(init=False)  # (J,) turns removed so far [rad]
    _last_q: np.ndarray | None = field(default=None, init=False)  # the last raw sample
    _last_t: int = field(default=0, init=False)
    _tail_d: np.ndarray = field(init=False)  # the last 2 (unwrapped) steps, not yet judged
    _tail_dt: np.ndarray = field(init=False)  # their lengths [s]
    _tail_t: np.ndarray = field(init=False)  # the times of the samples they lead to [ns]
    _kept: list[list[Jump]] = field(init=False)  # per joint, the largest candidates
    _h_apart: np.ndarray = field(init=False)  # (J, bins) the step differences' histogram
    _h_step: np.ndarray = field(init=False)  # (J, bins) the |steps|' histogram
    _lo: np.ndarray = field(init=False)  # (J,) the unwrapped positions' range
    _hi: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        j = self.n_joints
        self.offset = np.zeros(j)
        self._tail_d = np.zeros((0, j))
        self._tail_dt = np.zeros(0)
        self._tail_t = np.zeros(0, dtype=np.int64)
        self._kept = [[] for _ in range(j)]
        self._h_apart = np.zeros((j, N_BINS), dtype=np.int64)
        self._h_step = np.zeros((j, N_BINS), dtype=np.int64)
        self._lo, self._hi = np.full(j, np.inf), np.full(j, -np.inf)

    def add(self, t_ns: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Judge the next (n,) times [ns] and (n, J) positions [rad]; return them
        unwrapped (a new array when a turn was removed, else ``q``)."""
        n = len(t_ns)
        if not n:
            return q
        last = self._last_q
        first = last is None
        d = np.empty(q.shape)  # d[k]: the step into the block's sample k
        dt = np.empty(n)
        with np.errstate(invalid="ignore"):
            np.subtract(q[1:], q[:-1], out=d[1:])
            if last is None:
                d[0], dt[0] = np.nan, np.nan
            else:
                np.subtract(q[0], last, out=d[0])
                dt[0] = (int(t_ns[0]) - self._last_t) * 1e-9
        dt[1:] = np.diff(t_ns) * 1e-9
        self._last_q, self._last_t = q[-1].copy(), int(t_ns[-1])
        u = self._unwrap(t_ns, q, d)
        if self.unwrap_only:  # a reference's angle: its turns removed, nothing judged
            self.n += n
            return u
        self._jumps(t_ns, d, dt, first)
        every = u[(-self.n) % STATS_EVERY::STATS_EVERY]  # the range, on the strided samples
        if len(every):
            self._lo = np.fmin(self._lo, np.fmin.reduce(every, axis=0))  # NaN: not logged
            self._hi = np.fmax(self._hi, np.fmax.reduce(every, axis=0))
        self.n += n
        return u

    def _unwrap(self, t_ns: np.ndarray, q: np.ndarray, d: np.ndarray) -> np.ndarray:
        """``q`` with the turns so far and this block's removed; ``d`` unwrapped in place."""
        with np.errstate(invalid="ignore"):
            big = np.abs(d) >= 2.0 * np.pi - WRAP_TOL_RAD
        if not big.any():  # no step near a turn (the common case)
            return q if not self.offset.any() else q - self.offset
        with np.errstate(invalid="ignore"):
            turns = np.where(big, np.rint(d / (2.0 * np.pi)), 0.0)
            wrap = big & (np.abs(d - 2.0 * np.pi * turns) < WRAP_TOL_RAD)
        turns = np.where(wrap, turns, 0.0)
        for k, j in zip(*np.nonzero(wrap), strict=True):
            self.wraps.append(Wrap(self.n + int(k), int(j), int(turns[k, j]), int(t_ns[k])))
        d -= 2.0 * np.pi * turns
        shift = np.cumsum(turns, axis=0) * (2.0 * np.pi)
        out = q - self.offset - shift
        self.offset = self.offset + shift[-1]
        return out

    def _jumps(self, t_ns: np.ndarray, d: np.ndarray, dt: np.ndarray, first: bool) -> None:
        dd = np.concatenate((self._tail_d, d))
        dts = np.concatenate((self._tail_dt, dt))
        tt = np.concatenate((self._tail_t, t_ns))
        base = self.n - len(self._tail_d)  # the sample dd[0] leads to
        self._tail_d, self._tail_dt, self._tail_t = dd[-2:].copy(), dts[-2:].copy(), tt[-2:]
        # judge the steps with both neighbours known: dd[lo .. -2]; the log's first two steps
        # (into samples 0 and 1) have no step before them
        lo = 2 if base == 0 else 1
        if len(dd) - 1 <= lo:
            return
        apart = np.full(dd.shape, np.nan)
        found = _judge(dd, dts, lo, (-(base + lo)) % STATS_EVERY, apart, self._h_apart,
                       self._h_step)
        self.steps += len(dd) - 1 - lo
        for i in found:
            for j in np.flatnonzero(np.isfinite(apart[i])):
                kept = self._kept[int(j)]
                kept.append(Jump(base + int(i), int(j), float(apart[i, j]), int(tt[i])))
                if len(kept) > 2 * MAX_KEPT:
                    kept.sort(key=lambda x: -x.size)
                    del kept[MAX_KEPT:]

    def finish(self) -> None:
        """Keep the jumps that stand out of their joint's noise (module docstring)."""
        floor = np.nan_to_num(np.maximum(NOISE_FACTOR * _median(self._h_apart),
                                         TAIL_FACTOR * _median(self._h_apart, TAIL_Q)),
                              nan=0.0)
        kept = [x for per in self._kept for x in sorted(per, key=lambda y: -y.size)[:MAX_KEPT]]
        self.jumps = sorted((x for x in kept if x.size > floor[x.joint]),
                            key=lambda x: (x.i, x.joint))
        self.n_jumps = len(self.jumps)
        self.jump_steps = len({x.i for x in self.jumps})

    def describe(self, joints: tuple[str, ...]) -> str:
        """Each moving joint's median step and range, e.g. ``j1 0.8 of 2.4 rad``."""
        span = self._hi - self._lo
        med = _median(self._h_step)
        return ", ".join(f"{joints[j]} {med[j]:.2g} of {span[j]:.2g} rad"
                         for j in range(self.n_joints)
                         if np.isfinite(span[j]) and span[j] >= MOVING_RANGE_RAD)

    @property
    def shuffled(self) -> bool:
        """Whether the rows cannot be consecutive (module docstring)."""
        span = self._hi - self._lo
        moving = np.isfinite(span) & (span >= MOVING_RANGE_RAD)
        if not moving.any() or self.steps < 2 * STATS_EVERY:
            return False
        wide = _median(self._h_step)[moving] > SHUFFLED_STEP_SHARE * span[moving]
        return int(wide.sum()) * 2 > int(moving.sum())


def unwrap_positions(q: np.ndarray, start: int, wraps: list[Wrap] | tuple[Wrap, ...],
                     joints: list[int]) -> np.ndarray:
    """(n, J) positions of samples ``start`` … with the turns of ``wraps`` removed
    (``joints``: each column's index among the scan's joints); ``q`` when none applies."""
    if not wraps:
        return q
    col = {j: c for c, j in enumerate(joints)}
    out = q
    for w in wraps:
        c = col.get(w.joint)
        if c is None or w.i >= start + len(q):
            continue
        if out is q:
            out = q.copy()
        out[max(w.i - start, 0):, c] -= 2.0 * np.pi * w.turns
    return out
