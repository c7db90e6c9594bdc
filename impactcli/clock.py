"""A log's sample clock: the one rate estimator and the one gap rule of every format and check
(docs/method.md §5b gives the reasons and the cases they were built on).

Real time stamps are rarely a clean grid: host-stamped logs jitter, loggers drop a sample,
repeat a stamp or deliver a late sample with the next one. Every consumer of a rate
(:attr:`impactcli.types.RobotLog.sample_period_s`, the detectors' filters and windows, the
timeline's ``input.sample_rate_hz``, ``inspect``, the readers' time-unit check) uses
:func:`sample_clock`, on the histogram of ALL the steps (:func:`step_histogram`, exact and
additive over chunks: :class:`StepHistogram`): repeated stamps merged (a zero step is not a
step); a first period, the median step; the period P, the mean of the steps within ±50 %
(:data:`SINGLE_STEP_BAND`) of it, re-centred until it settles (dropped samples, gaps and
late stamps fall outside; jitter averages out); the jitter, 1.4826 × the MAD of dt − P
(``jitter_s``) and the 95th percentile of |dt − P| (``envelope_s``).

A step is a gap (:func:`gap_steps`) when it is longer than :data:`GAP_FACTOR` × P and than
P + :data:`ENVELOPE_FACTOR` × envelope (``gap_threshold_s``), and the time is not given
back over :data:`COMPENSATION_STEPS` steps on each side. Chunk by chunk the same gaps are
found (:func:`chunk_gap_steps` with the clock known, :class:`GapStream` before), whatever
the chunking.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: A step longer than this many periods may be a gap (rule (a)).
GAP_FACTOR = 1.5
#: A gap is also longer than the period plus this many jitter envelopes (rule (b)).
ENVELOPE_FACTOR = 2.0
#: The share of steps inside the jitter envelope.
ENVELOPE_QUANTILE = 0.95
#: Steps on each side of a long step over which a late stamp may be given back (rule (c)).
COMPENSATION_STEPS = 2
#: A step within this fraction of the period of it spans one period (estimator, step 3).
SINGLE_STEP_BAND = 0.5
#: Re-centrings of the period estimate at most (it settles in a few).
MAX_ITERATIONS = 50
#: :func:`impactcli.logs.repair.rate_message` judges a time column's unit on this many
#: steps from the start (a unit is a unit from the start).
MAX_STATS_STEPS = 1_000_000
#: Stamps a chunk of :func:`chunk_gap_steps` needs from before it: the step before the
#: chunk and its :data:`COMPENSATION_STEPS` neighbours on each side.
TAIL_STAMPS = 2 * COMPENSATION_STEPS + 1
#: :func:`step_histogram` counts the steps within a window of this many ns around their
#: typical value with one ``bincount`` (O(N)); the others by sorting.
_DENSE_WINDOW = 1 << 20
#: Fewer steps than this are counted by sorting.
_FEW_STEPS = 4096


@dataclass(frozen=True)
class SampleClock:
    """What :func:`sample_clock` found (module docstring).

    Attributes:
        period_s: estimated sample period P [s] (NaN with no non-zero step).
        jitter_s: robust standard deviation of the steps about P [s].
        envelope_s: 95th percentile of |step − P| [s].
        gap_threshold_s: max(1.5 P, P + 2 envelope) [s]: a longer step not given back by
            its neighbours is a gap.
        n_repeated: zero steps (repeated stamps) merged.
    """

    period_s: float
    jitter_s: float
    envelope_s: float
    gap_threshold_s: float
    n_repeated: int = 0

    @property
    def sample_rate_hz(self) -> float:
        """1 / period [Hz]."""
        return 1.0 / self.period_s if self.period_s > 0 else float("nan")


# ------------------------------------------------------------------ the step histogram
def _empty_histogram() -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)


def _unique_counts(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    v, c = np.unique(s, return_counts=True)
    return v.astype(np.int64), c.astype(np.int64)


def step_histogram(steps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact counts of integer steps.

    Args:
        steps: (M,) int64 steps [ns] (any order, any sign).
    Returns:
        ``(values, counts)``: (U,) int64 distinct steps, increasing, and (U,) int64 how
        many times each occurs (sum M).
    """
    s = np.asarray(steps, dtype=np.int64).ravel()
    if s.size <= _FEW_STEPS:
        return _unique_counts(s)
    # where the dense window goes only (any placement gives the same counts)
    centre = int(np.median(s[:: max(1, s.size // 1024)]))
    lo = max(centre - _DENSE_WINDOW // 2, -(2**63))
    hi = min(centre + _DENSE_WINDOW // 2, 2**63 - 1)
    inside = (s >= lo) & (s < hi)
    dense = s if inside.all() else s[inside]
    base = int(dense.min())
    cnt = np.bincount(dense - base)
    nz = np.flatnonzero(cnt)
    hist = (nz.astype(np.int64) + base, cnt[nz].astype(np.int64))
    if dense is s:
        return hist
    return merge_histograms(hist, _unique_counts(s[~inside]))


def merge_histograms(*hists: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The sum of step histograms ``(values, counts)`` (:func:`step_histogram`), exact."""
    v = np.concatenate([h[0] for h in hists]) if hists else np.zeros(0, dtype=np.int64)
    c = np.concatenate([h[1] for h in hists]) if hists else np.zeros(0, dtype=np.int64)
    if v.size == 0:
        return _empty_histogram()
    order = np.argsort(v, kind="stable")
    v, c = v[order], c[order]
    starts = np.flatnonzero(np.concatenate(([True], v[1:] != v[:-1])))
    return v[starts].astype(np.int64), np.add.reduceat(c, starts).astype(np.int64)


class StepHistogram:
    """The step histogram of a log read chunk by chunk: :meth:`add` each chunk's stamps
    in order; the steps across chunk boundaries are counted (the last stamp is carried),
    so the histogram, hence :meth:`clock`, is the whole log's whatever the chunking.

    Chunks' histograms are merged when they hold as many entries as the total (amortised
    O(U log U) for U distinct steps).

    Attributes:
        last: the last stamp added [ns] (None before the first).
        n_stamps: stamps added.
    """

    def __init__(self) -> None:
        self._hist = _empty_histogram()  # the steps outside the dense window
        self._pending: list[tuple[np.ndarray, np.ndarray]] = []
        self._pending_size = 0
        self._base = 0  # the dense window: counts of steps base … base + window − 1
        self._dense: np.ndarray | None = None
        self._used = (_DENSE_WINDOW, 0)  # the dense window's entries in use: [lo, hi)
        self._cache: tuple[np.ndarray, np.ndarray] | None = None
        self.last: int | None = None
        self.n_stamps = 0

    @property
    def values(self) -> np.ndarray:
        """(U,) int64 distinct steps [ns], increasing."""
        return self._all()[0]

    @property
    def counts(self) -> np.ndarray:
        """(U,) int64 how many times each step occurs."""
        return self._all()[1]

    def _all(self) -> tuple[np.ndarray, np.ndarray]:
        if self._cache is not None:
            return self._cache
        self._flush()
        if self._dense is None:
            return self._hist
        lo, hi = self._used
        nz = np.flatnonzero(self._dense[lo:hi]) + lo
        self._cache = merge_histograms(self._hist, (nz.astype(np.int64) + self._base,
                                                    self._dense[nz]))
        return self._cache

    def _flush(self) -> None:
        if self._pending:
            self._hist = merge_histograms(self._hist, *self._pending)
            self._pending, self._pending_size = [], 0

    def add(self, t_ns: np.ndarray) -> None:
        """Count the steps of the next chunk's stamps ``t_ns`` ((n,) int64 [ns]), and the
        one from the previous chunk's last stamp to its first."""
        t = np.asarray(t_ns, dtype=np.int64)
        if t.size == 0:
            return
        steps = np.diff(t) if self.last is None else np.diff(t, prepend=np.int64(self.last))
        self.add_steps(steps)
        self.last = int(t[-1])
        self.n_stamps += int(t.size)

    def add_steps(self, steps: np.ndarray) -> None:
        """Count (M,) int64 steps [ns]."""
        s = np.asarray(steps, dtype=np.int64).ravel()
        if s.size == 0:
            return
        self._cache = None
        if self._dense is None:  # where the window goes only (any placement counts exactly)
            centre = int(np.median(s[:: max(1, s.size // 1024)]))
            self._base = max(centre - _DENSE_WINDOW // 2, -(2**63))
            self._dense = np.zeros(_DENSE_WINDOW, dtype=np.int64)
        top = min(self._base + _DENSE_WINDOW, 2**63 - 1)
        inside = (s >= self._base) & (s < top)
        d = (s if inside.all() else s[inside]) - self._base
        if d.size:
            lo = int(d.min())
            cnt = np.bincount(d - lo)
            self._dense[lo: lo + cnt.size] += cnt
            self._used = (min(self._used[0], lo), max(self._used[1], lo + cnt.size))
        if d.size < s.size:
            h = step_histogram(s[~inside])
            self._pending.append(h)
            self._pending_size += h[0].size
            if self._pending_size > self._hist[0].size:
                self._flush()

    def clock(self) -> SampleClock:
        """The sample clock of the steps counted (:func:`clock_from_histogram`)."""
        return clock_from_histogram(self.values, self.counts)

    def period_ns(self) -> float:
        """The period of the steps counted so far [ns] (NaN without a non-zero step)."""
        v, c = _nonzero(self.values, self.counts)
        return _period(v, c) if v.size else float("nan")


# -------------------------------------------------------------- statistics of a histogram
def _nonzero(values: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    keep = values != 0
    return values[keep], counts[keep]


def _kth(sorted_values: np.ndarray, cum: np.ndarray, k: int) -> float:
    """The k-th (0-based) of the values in sorted order, each repeated per its count
    (``cum`` the cumulative counts)."""
    return float(sorted_values[int(np.searchsorted(cum, k, side="right"))])


def _median(sorted_values: np.ndarray, counts: np.ndarray) -> float:
    """``np.median`` of the values repeated per their counts (``sorted_values`` increasing)."""
    cum = np.cumsum(counts)
    n = int(cum[-1])
    if n % 2:
        return _kth(sorted_values, cum, n // 2)
    return (_kth(sorted_values, cum, n // 2 - 1) + _kth(sorted_values, cum, n // 2)) / 2


def _quantile(sorted_values: np.ndarray, counts: np.ndarray, q: float) -> float:
    """``np.quantile(..., q)`` (linear) of the values repeated per their counts."""
    cum = np.cumsum(counts)
    n = int(cum[-1])
    virtual = (n - 1) * q
    k = int(np.floor(virtual))
    gamma = virtual - k
    a = _kth(sorted_values, cum, k)
    b = _kth(sorted_values, cum, min(k + 1, n - 1))
    diff = b - a
    return b - diff * (1 - gamma) if gamma >= 0.5 else a + diff * gamma


def _exact_sum(values: np.ndarray, counts: np.ndarray) -> int:
    """Σ values × counts as an exact integer."""
    if values.size == 0:
        return 0
    if float(np.max(np.abs(values))) * float(np.sum(counts)) < 2.0**62:
        return int(np.dot(values, counts))
    return int(np.dot(values.astype(object), counts.astype(object)))


def _period(values: np.ndarray, counts: np.ndarray) -> float:
    """Mean of the single-period steps, re-centred until it settles [ns] (module docstring,
    step 3): exact sums of value × count, one division."""
    p = _median(values, counts)
    vf = values.astype(np.float64)
    for _ in range(MAX_ITERATIONS):
        one = np.abs(vf - p) < SINGLE_STEP_BAND * p
        count = int(np.sum(counts[one]))
        if count == 0:
            break
        new = _exact_sum(values[one], counts[one]) / count
        if abs(new - p) <= 1e-9 * p:
            return new
        p = new
    return p


def clock_from_histogram(values: np.ndarray, counts: np.ndarray) -> SampleClock:
    """The sample clock (module docstring) of the steps counted in a histogram.

    Args:
        values: (U,) int64 distinct steps [ns], increasing (:func:`step_histogram`).
        counts: (U,) int64 their numbers.
    Returns:
        The :class:`SampleClock`; its period is NaN when there is no non-zero step.
    """
    v = np.asarray(values, dtype=np.int64)
    c = np.asarray(counts, dtype=np.int64)
    n_rep = int(np.sum(c[v == 0]))
    v, c = _nonzero(v, c)  # a repeated stamp is merged with the one before: not a step
    nan = float("nan")
    if v.size == 0:
        return SampleClock(nan, nan, nan, nan, n_rep)
    p = _period(v, c)
    dev = v.astype(np.float64) - p  # increasing, as v
    spread = np.abs(dev - _median(dev, c))
    order = np.argsort(spread, kind="stable")
    jitter = 1.4826 * _median(spread[order], c[order])
    far = np.abs(dev)
    order = np.argsort(far, kind="stable")
    envelope = _quantile(far[order], c[order], ENVELOPE_QUANTILE)
    thr = max(GAP_FACTOR * p, p + ENVELOPE_FACTOR * envelope)
    return SampleClock(p * 1e-9, jitter * 1e-9, envelope * 1e-9, thr * 1e-9, n_rep)


def sample_clock(t_ns: np.ndarray) -> SampleClock:
    """The sample clock of stamps ``t_ns`` (module docstring): the
    :func:`clock_from_histogram` of the histogram of all their steps.

    Args:
        t_ns: (N,) int64 sample times [ns], non-decreasing (repeated stamps are merged).
    Returns:
        The :class:`SampleClock`; its period is NaN when there is no non-zero step.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    return clock_from_histogram(*step_histogram(np.diff(t)))


# ---------------------------------------------------------------------------- gap rule
@dataclass(frozen=True)
class GapWindows:
    """Long steps with what rule (c) needs of them: the candidates of the gap rule.

    Attributes:
        idx: (G,) int64 indices i of the steps t[i] → t[i+1] (whole log).
        dt: (G,) int64 their lengths [ns].
        span_ns: (G,) int64 t[hi] − t[lo] over the step and its neighbours, lo = max(i − 2,
            0), hi = min(i + 3, N − 1) (:data:`COMPENSATION_STEPS` = 2).
        span_steps: (G,) int64 hi − lo.
    """

    idx: np.ndarray
    dt: np.ndarray
    span_ns: np.ndarray
    span_steps: np.ndarray

    @staticmethod
    def empty() -> GapWindows:
        """No candidate."""
        z = np.zeros(0, dtype=np.int64)
        return GapWindows(z, z, z, z)

    @staticmethod
    def concat(parts: list[GapWindows]) -> GapWindows:
        """The candidates of consecutive parts, in order."""
        if not parts:
            return GapWindows.empty()
        return GapWindows(*(np.concatenate([getattr(w, f) for w in parts])
                            for f in ("idx", "dt", "span_ns", "span_steps")))


def gap_windows(t_ns: np.ndarray, first: int, floor_ns: float, steps: tuple[int, int],
                n_total: int | None) -> GapWindows:
    """The steps longer than ``floor_ns`` among ``steps`` of a run of stamps, with their
    windows (:class:`GapWindows`).

    Args:
        t_ns: (n,) int64 consecutive stamps of the log [ns], t_ns[0] being stamp ``first``.
        first: whole-log index of t_ns[0].
        floor_ns: keep the steps longer than this [ns] (at most the gap threshold).
        steps: ``(a, b)``: look at the steps i, a ≤ i < b (whole-log indices); each
            needs stamps max(i − 2, 0) … min(i + 3, N − 1) in ``t_ns``.
        n_total: N when known (the run reaches the log's end), else None.
    """
    m = COMPENSATION_STEPS
    a, b = max(steps[0], first), steps[1]
    if b <= a:
        return GapWindows.empty()
    t = np.asarray(t_ns, dtype=np.int64)
    dt = np.diff(t[a - first: b - first + 1])
    cand = np.flatnonzero(dt > floor_ns) + a
    if cand.size == 0:
        return GapWindows.empty()
    lo = np.maximum(cand - m, 0)
    hi = cand + 1 + m if n_total is None else np.minimum(cand + 1 + m, n_total - 1)
    return GapWindows(cand.astype(np.int64), dt[cand - a].astype(np.int64),
                      (t[hi - first] - t[lo - first]).astype(np.int64),
                      (hi - lo).astype(np.int64))


def select_gaps(w: GapWindows, clock: SampleClock) -> tuple[np.ndarray, np.ndarray]:
    """The gaps (rules (a)–(c)) among candidates ``w`` found with a floor at most the
    clock's gap threshold: ``(idx, lengths)`` as :func:`gap_steps`."""
    none = np.zeros(0, dtype=np.int64), np.zeros(0)
    if not clock.period_s > 0 or w.idx.size == 0:
        return none
    p = clock.period_s * 1e9
    thr = clock.gap_threshold_s * 1e9
    long = w.dt > thr
    behind = w.span_ns[long].astype(np.float64) - p * w.span_steps[long]
    keep = np.flatnonzero(long)[behind > thr - p]
    return w.idx[keep], w.dt[keep].astype(np.float64) * 1e-9


def gap_steps(t_ns: np.ndarray, clock: SampleClock | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The steps of ``t_ns`` that are gaps (module docstring, rules (a)–(c)).

    Args:
        t_ns: (N,) int64 sample times [ns], strictly increasing.
        clock: its :func:`sample_clock` (computed when not given).
    Returns:
        ``(idx, lengths)``: (G,) int64 indices i of the gap steps t[i] → t[i+1], and (G,)
        their lengths [s].
    """
    t = np.asarray(t_ns, dtype=np.int64)
    if t.shape[0] < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    c = clock if clock is not None else sample_clock(t)
    if not c.period_s > 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    w = gap_windows(t, 0, c.gap_threshold_s * 1e9, (0, t.shape[0] - 1), t.shape[0])
    return select_gaps(w, c)


def chunk_steps(start: int, n: int, last: bool) -> tuple[int, int]:
    """The steps a chunk of stamps start … start + n − 1 decides in chunked gap finding:
    those whose window (module docstring, rule (c)) ends in it, i.e. steps i with
    start ≤ i + 1 + :data:`COMPENSATION_STEPS` < start + n, and all the remaining steps
    when it is the last chunk."""
    m = COMPENSATION_STEPS
    return max(start - 1 - m, 0), (start + n - 1 if last else start + n - 1 - m)


def chunk_gap_steps(t_ns: np.ndarray, start: int, tail: np.ndarray, clock: SampleClock, *,
                    last: bool) -> tuple[np.ndarray, np.ndarray]:
    """:func:`gap_steps` chunk by chunk: over consecutive chunks (the last with
    ``last=True``) the results, concatenated, are the whole log's, whatever the chunking.

    Args:
        t_ns: (n,) int64 the chunk's stamps [ns], stamps start … start + n − 1 of the log.
        start: whole-log index of the chunk's first stamp.
        tail: the previous chunks' last min(start, :data:`TAIL_STAMPS`) stamps (int64 [ns];
            empty for the first chunk).
        clock: the whole log's clock (:class:`StepHistogram` over a first pass).
        last: whether this is the log's last chunk.
    Returns:
        ``(idx, lengths)``: (G,) int64 whole-log indices of the gap steps decided by this
        chunk (:func:`chunk_steps`), and (G,) their lengths [s].
    """
    tail = np.asarray(tail, dtype=np.int64)
    t = np.concatenate((tail, np.asarray(t_ns, dtype=np.int64)))
    first = start - tail.size
    if not clock.period_s > 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    w = gap_windows(t, first, clock.gap_threshold_s * 1e9, chunk_steps(start, len(t_ns), last),
                    start + len(t_ns) if last else None)
    return select_gaps(w, clock)


@dataclass
class GapStream:
    """Gap candidates of a log read chunk by chunk, before its clock is known: :meth:`add`
    each chunk's stamps with a floor at most the final gap threshold, then
    :meth:`gaps` with the whole log's clock gives :func:`gap_steps`' result exactly when
    :attr:`max_floor_ns` ≤ that clock's threshold (:meth:`exact_for`).

    Attributes:
        parts: the candidates found so far.
        tail: the last stamps seen (at most :data:`TAIL_STAMPS`).
        n_stamps: stamps seen.
        max_floor_ns: the largest floor used [ns].
    """

    parts: list[GapWindows] = field(default_factory=list)
    tail: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    n_stamps: int = 0
    max_floor_ns: float = float("-inf")

    def add(self, t_ns: np.ndarray, floor_ns: float, *, last: bool = False) -> None:
        """Look at the next chunk's stamps ((n,) int64 [ns]); candidates are the steps
        longer than ``floor_ns``. ``last``: the log ends with this chunk."""
        t_new = np.asarray(t_ns, dtype=np.int64)
        t = np.concatenate((self.tail, t_new))
        first = self.n_stamps - self.tail.size
        self.max_floor_ns = max(self.max_floor_ns, floor_ns)
        w = gap_windows(t, first, floor_ns, chunk_steps(self.n_stamps, t_new.size, last),
                        self.n_stamps + t_new.size if last else None)
        if w.idx.size:
            self.parts.append(w)
        self.n_stamps += t_new.size
        self.tail = t[-TAIL_STAMPS:]

    def exact_for(self, clock: SampleClock) -> bool:
        """Whether every step that is a gap under ``clock`` was kept as a candidate."""
        return not clock.period_s > 0 or self.max_floor_ns <= clock.gap_threshold_s * 1e9

    def gaps(self, clock: SampleClock) -> tuple[np.ndarray, np.ndarray]:
        """``(idx, lengths)`` of the gap steps, as :func:`gap_steps` on the whole log."""
        return select_gaps(GapWindows.concat(self.parts), clock)


#: A log whose rate differs from its config's calibration rate by more than this
#: fraction is refused (:func:`check_calibrated_rate`): the same logger, a little late or
#: early, stays inside it; another rate does not.
RATE_TOLERANCE = 0.1


def check_calibrated_rate(sample_rate_hz: float, calibrated_hz: float | None, where: str,
                          config_where: str = "config") -> None:
    """Refuse (ConfigError, exit 3) a log whose rate differs from the rate its config was
    calibrated at by more than :data:`RATE_TOLERANCE`: the thresholds belong to that rate
    (filters, RMS windows and the statistics they were set on are per sample).

    Args:
        sample_rate_hz: the log's rate [Hz].  calibrated_hz: the config's
            ``calibration.sample_rate_hz`` (None: not recorded, nothing to check).
        where: the log, config_where: the config, for the message.
    """
    from .errors import ConfigError

    if calibrated_hz is None or not (calibrated_hz > 0 and sample_rate_hz > 0):
        return
    if abs(sample_rate_hz - calibrated_hz) > RATE_TOLERANCE * calibrated_hz:
        raise ConfigError(
            f"{where}: sampled at {sample_rate_hz:.4g} Hz, but {config_where} was calibrated at "
            f"{calibrated_hz:.4g} Hz (tolerance ±{RATE_TOLERANCE:.0%}): its thresholds belong "
            f"to that rate; calibrate on logs at {sample_rate_hz:.4g} Hz, or run without --config "
            "(uncalibrated)")
