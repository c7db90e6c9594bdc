"""A log's sample clock: the one rate estimator and the one gap rule of every format and check.

Real time stamps are rarely a clean grid. Host-stamped logs jitter; loggers drop a sample
now and then (a step of two periods), write a sample twice or stamp two samples alike (a
repeated stamp), or deliver a late sample together with the next one (a long step, then a
very short one). The median step, used before, is pulled off by such steps (a 1 kHz log
could read as 1020 Hz) and the fixed "1.5 median steps" gap rule then calls every dropped
or late sample a gap. Every consumer of a rate — :attr:`impactcli.types.RobotLog.sample_period_s`
and ``sample_rate_hz`` (hence the detectors' filters and windows, the timeline's
``input.sample_rate_hz``), :func:`impactcli.io.inspect.time_gaps` and ``inspect``'s rate,
jitter and gaps, the readers' time-unit check — uses :func:`sample_clock` below.

Estimator (:func:`sample_clock`), on the (N,) int64 stamps t [ns]:

1. Steps dt_i = t[i+1] − t[i]. Repeated stamps are merged: a zero step is not a step.
   (A :class:`~impactcli.types.RobotLog` never holds one: the readers' repair policy,
   :mod:`impactcli.io.repair`, drops exact duplicate rows and refuses a repeated stamp with
   other values unless ``--repair-order`` is given, which keeps the last row of a stamp.)
2. A first period P0: the median of the non-zero steps.
3. The period P: the mean of the steps that span one period — those within ±50 %
   (:data:`SINGLE_STEP_BAND`) of the estimate — re-centred on the new mean until it
   settles. This is the slope of time against sample index over the regular steps: a
   dropped sample or a gap (≥ 1.5 P), a very short step (a late stamp delivered with the
   next sample, an inserted row) fall outside the band and do not pull it; jitter inside
   the band averages out over the log (symmetric jitter, and a late stamp followed by an
   early one, cancel), where the median of all steps is pulled by the irregular ones. On a
   clean grid P is the grid's period (to the ns rounding of its stamps).
4. The jitter of the steps about P: ``jitter_s`` = 1.4826 × the median absolute deviation
   of dt − P (a robust standard deviation), and ``envelope_s`` = the 95th percentile of
   |dt − P|: 95 % of the steps lie within P ± envelope.

Gap rule (:func:`gap_steps`): the step t[i] → t[i+1] is a gap when

(a) it is longer than :data:`GAP_FACTOR` (1.5) × P, and
(b) it is clearly beyond the jitter: longer than P + :data:`ENVELOPE_FACTOR` (2) × envelope —
    a step length that more than 5 % of the log's steps reach (a logger that drops every
    17th sample) is the log's timing, not a gap; with Gaussian jitter of standard
    deviation σ this asks for about 4 σ — and
(c) the time is not given back: over the step and :data:`COMPENSATION_STEPS` (2) steps on
    each side, the log falls behind its clock by more than (threshold − P). A late stamp
    followed by an early one is jitter, not lost time.

The threshold of (a) and (b), max(1.5 P, P + 2 envelope), is ``gap_threshold_s``.
"""

from __future__ import annotations

from dataclasses import dataclass

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
#: The median start, the jitter and the envelope of longer logs use this many steps,
#: evenly strided (the period's mean uses every step).
MAX_STATS_STEPS = 1_000_000


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
    def rate_hz(self) -> float:
        """1 / period [Hz]."""
        return 1.0 / self.period_s if self.period_s > 0 else float("nan")


def _period(steps: np.ndarray) -> float:
    """Mean of the single-period steps, re-centred until it settles [ns] (module docstring)."""
    p = float(np.median(_sub(steps)))
    for _ in range(MAX_ITERATIONS):
        one = np.abs(steps - p) < SINGLE_STEP_BAND * p
        count = int(np.count_nonzero(one))
        if count == 0:
            break
        new = float(np.sum(steps, where=one)) / count
        if abs(new - p) <= 1e-9 * p:
            return new
        p = new
    return p


def _sub(a: np.ndarray) -> np.ndarray:
    """At most :data:`MAX_STATS_STEPS` evenly strided values of ``a`` (robust statistics of
    long logs: the same to well below their spread, in a fraction of the time)."""
    return a[:: max(1, a.shape[0] // MAX_STATS_STEPS)]


def sample_clock(t_ns: np.ndarray) -> SampleClock:
    """The sample clock of stamps ``t_ns`` (module docstring).

    Args:
        t_ns: (N,) int64 sample times [ns], non-decreasing (repeated stamps are merged).
    Returns:
        The :class:`SampleClock`; its period is NaN when there is no non-zero step.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    steps = np.diff(t).astype(np.float64)
    n_rep = int(steps.size - np.count_nonzero(steps))
    nan = float("nan")
    if n_rep == steps.size:
        return SampleClock(nan, nan, nan, nan, n_rep)
    if n_rep:  # a repeated stamp is merged with the one before: its zero step is not a step
        steps = steps[steps != 0]
    p = _period(steps)
    dev = _sub(steps) - p
    jitter = 1.4826 * float(np.median(np.abs(dev - np.median(dev))))
    envelope = float(np.quantile(np.abs(dev), ENVELOPE_QUANTILE))
    thr = max(GAP_FACTOR * p, p + ENVELOPE_FACTOR * envelope)
    return SampleClock(p * 1e-9, jitter * 1e-9, envelope * 1e-9, thr * 1e-9, n_rep)


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
    none = np.zeros(0, dtype=np.int64), np.zeros(0)
    if t.shape[0] < 2:
        return none
    c = clock if clock is not None else sample_clock(t)
    if not c.period_s > 0:
        return none
    p = c.period_s * 1e9
    thr = c.gap_threshold_s * 1e9
    dt = np.diff(t)
    cand = np.flatnonzero(dt > thr)
    if cand.size == 0:
        return none
    m = COMPENSATION_STEPS
    lo = np.maximum(cand - m, 0)
    hi = np.minimum(cand + 1 + m, t.shape[0] - 1)
    behind = (t[hi] - t[lo]).astype(np.float64) - p * (hi - lo)
    idx = cand[behind > thr - p]
    return idx, dt[idx].astype(np.float64) * 1e-9


#: A log whose rate differs from its config's calibration rate by more than this
#: fraction is warned about (:func:`check_calibrated_rate`).
RATE_TOLERANCE = 0.1


def check_calibrated_rate(rate_hz: float, calibrated_hz: float | None, where: str) -> None:
    """Warn (ImpactWarning) when a log's rate differs from the rate its config was
    calibrated at by more than :data:`RATE_TOLERANCE`: the thresholds belong to that rate
    (filters, windows and statistics are per sample).

    Args:
        rate_hz: the log's rate [Hz].  calibrated_hz: the config's
            ``calibration.sample_rate_hz`` (None: not recorded, nothing to check).
        where: the log, for the message.
    """
    import warnings

    from .errors import ImpactWarning

    if calibrated_hz is None or not (calibrated_hz > 0 and rate_hz > 0):
        return
    if abs(rate_hz - calibrated_hz) > RATE_TOLERANCE * calibrated_hz:
        warnings.warn(
            f"{where}: sampled at {rate_hz:.4g} Hz, but its config was calibrated at "
            f"{calibrated_hz:.4g} Hz: the thresholds belong to that rate (filters, windows "
            "and statistics are per sample); calibrate on logs at this rate",
            ImpactWarning, stacklevel=3)
