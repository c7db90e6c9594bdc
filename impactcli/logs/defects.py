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

from dataclasses import dataclass, field

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
STATS_EVERY = 8
BINS_PER_DECADE = 10
LOWEST_LOG10 = -10.0
N_BINS = 130
#: At most this many jump candidates are kept with their place.
MAX_KEPT = 10_000


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


def _histogram(x: np.ndarray) -> np.ndarray:
    """(J, N_BINS) counts of (m, J) non-negative values in log-spaced bins (bin 0: below
    1e-10, NaN left out)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.floor((np.log10(x) - LOWEST_LOG10) * BINS_PER_DECADE) + 1
    b = np.clip(np.where(np.isfinite(b), b, 0), 0, N_BINS - 1).astype(np.int64)
    b[~np.isfinite(x)] = -1
    out = np.zeros((x.shape[1], N_BINS), dtype=np.int64)
    for j in range(x.shape[1]):
        col = b[:, j]
        out[j] = np.bincount(col[col >= 0], minlength=N_BINS)
    return out


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
    n: int = 0  # samples seen
    steps: int = 0  # steps judged
    n_jumps: int = 0  # (step, joint) jumps (after finish)
    jump_steps: int = 0  # steps with a jump on some joint (after finish)
    jumps: list[Jump] = field(default_factory=list)
    wraps: list[Wrap] = field(default_factory=list)
    offset: np.ndarray = field(init=False)  # (J,) turns removed so far [rad]
    _tail_q: np.ndarray = field(init=False)  # the last raw sample (wrap steps)
    _tail_u: np.ndarray = field(init=False)  # the last 3 unwrapped samples
    _tail_t: np.ndarray = field(init=False)
    _h_apart: np.ndarray = field(init=False)  # (J, bins) the step differences' histogram
    _h_step: np.ndarray = field(init=False)  # (J, bins) the |steps|' histogram
    _lo: np.ndarray = field(init=False)  # (J,) the unwrapped positions' range
    _hi: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        j = self.n_joints
        self.offset = np.zeros(j)
        self._tail_q = np.zeros((0, j))
        self._tail_u = np.zeros((0, j))
        self._tail_t = np.zeros(0, dtype=np.int64)
        self._h_apart = np.zeros((j, N_BINS), dtype=np.int64)
        self._h_step = np.zeros((j, N_BINS), dtype=np.int64)
        self._lo, self._hi = np.full(j, np.inf), np.full(j, -np.inf)

    def add(self, t_ns: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Judge the next (n,) times [ns] and (n, J) positions [rad]; return them
        unwrapped (a new array when a turn was removed, else ``q``)."""
        if not len(t_ns):
            return q
        u = self._unwrap(t_ns, q)
        self._jumps(t_ns, u)
        self._lo = np.fmin(self._lo, np.fmin.reduce(u, axis=0))  # NaN: not logged
        self._hi = np.fmax(self._hi, np.fmax.reduce(u, axis=0))
        self.n += len(t_ns)
        return u

    def _unwrap(self, t_ns: np.ndarray, q: np.ndarray) -> np.ndarray:
        both = np.concatenate((self._tail_q, q))
        self._tail_q = q[-1:].copy()
        with np.errstate(invalid="ignore"):
            d = np.diff(both, axis=0)
            turns = np.rint(d / (2.0 * np.pi))
            wrap = (turns != 0) & (np.abs(d - 2.0 * np.pi * turns) < WRAP_TOL_RAD)
        if not wrap.any() and not self.offset.any():
            return q
        shift = np.zeros_like(q)
        if wrap.any():
            first = len(both) - len(q)  # index in `both` of q's first sample
            steps = np.where(wrap, turns, 0.0)
            for s, j in zip(*np.nonzero(wrap), strict=True):
                self.wraps.append(Wrap(int(self.n + s + 1 - first), int(j), int(turns[s, j]),
                                       int(t_ns[s + 1 - first])))
            cum = np.cumsum(steps, axis=0)
            if len(cum) < len(q):  # the log's first sample: no step into it
                cum = np.concatenate((np.zeros((1, q.shape[1])), cum))
            shift = cum * (2.0 * np.pi)
        out = q - self.offset - shift
        self.offset = self.offset + shift[-1]
        return out

    def _jumps(self, t_ns: np.ndarray, u: np.ndarray) -> None:
        uu = np.concatenate((self._tail_u, u))
        tt = np.concatenate((self._tail_t, t_ns))
        base = self.n - len(self._tail_u)  # the log's index of uu[0]
        self._tail_u, self._tail_t = uu[-3:].copy(), tt[-3:].copy()
        if len(uu) < 3:
            return
        with np.errstate(invalid="ignore"):
            d = np.diff(uu, axis=0)
        dt = np.diff(tt).astype(np.float64) * 1e-9
        # judge steps 1 .. len(d) - 2 (both neighbours known); step 0 was judged with the
        # block before, or is the log's first step (no neighbour before it)
        lo = 1
        mid = d[lo:-1]
        if not len(mid):
            return
        with np.errstate(invalid="ignore"):
            apart = np.minimum(np.abs(mid - d[lo - 1:-2]), np.abs(mid - d[lo + 1:]))
        every = slice((-(base + lo)) % STATS_EVERY, None, STATS_EVERY)  # the log's strides
        self._h_apart += _histogram(apart[every])
        self._h_step += _histogram(np.abs(mid[every]))
        dts = dt[lo:-1]
        limit = np.maximum(JUMP_RAD, MAX_ACCEL_RAD_S2 * dts ** 2)[:, None]
        regular = dts <= GAP_FACTOR * np.minimum(dt[lo - 1:-2], dt[lo + 1:])
        with np.errstate(invalid="ignore"):
            bad = (apart > limit) & regular[:, None]
        self.steps += len(mid)
        if not bad.any():
            return
        for s in np.flatnonzero(bad.any(axis=1)):
            for j in np.flatnonzero(bad[s]):
                if len(self.jumps) < MAX_KEPT:
                    self.jumps.append(Jump(base + lo + int(s) + 1, int(j), float(apart[s, j]),
                                           int(tt[lo + s + 1])))

    def finish(self) -> None:
        """Keep the jumps that stand out of their joint's noise (module docstring)."""
        floor = np.nan_to_num(np.maximum(NOISE_FACTOR * _median(self._h_apart),
                                         TAIL_FACTOR * _median(self._h_apart, TAIL_Q)),
                              nan=0.0)
        self.jumps = [x for x in self.jumps if x.size > floor[x.joint]]
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
