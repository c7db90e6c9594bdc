"""Thresholds: per joint from collision-free logs (docs/method.md §5b, "Thresholds" and
"The uncalibrated rule"; §8).

The statistic each threshold must beat after warm-up: adaptive ``r_rms − v_rms`` (eq. 42
fires iff r_rms > v_stat + v_rms, for v_stat ≥ 0); static_loading ``|LP(r)|``;
static_baseline ``|r|``. Maxima are floored at 0, thresholds at ``MIN_THRESHOLD``. Rules:

- **leave-one-out** (≥ 2 logs or segments): the smallest margin m such that each one, left
  out of the maximum, stays silent; floored at ``min_margin``, capped at ``max_margin``
  (warned, flagged weak); threshold = m × the maximum over all.
- **fixed-single-log** (1 log): 1.5 × its maximum, flagged weak.
- **a robot's history** (:func:`segment_bounds`, :func:`suspect_blocks`): long logs cut
  into ``SEGMENT_S`` segments; labelled contacts cut out; in a log without labels, a 1 s
  block above ``SUSPECT_RATIO`` × the median of all blocks' maxima left out as a likely
  contact.
- **uncalibrated-block-quantile** (a log with no config): 3 × the 0.9-quantile of the
  statistic's 1 s block maxima after warm-up (:class:`BlockMaxima` over chunks); the run is
  marked uncalibrated.

The decision is each detector's statistic against its threshold (eq. 42 for the adaptive
detector; |LP(r)| > vL and |r| > v0 for the static ones); the ratio statistic / threshold,
computed once here (:func:`detector_ratios`), is what events report as their peak and what a
threshold sweep rescales (the decision at scale s is ``ratio > s``). Pure array functions.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ImpactWarning

MIN_MARGIN = 1.05
MAX_MARGIN = 3.0
SINGLE_LOG_MARGIN = 1.5
#: The uncalibrated rule (module doc): block length [s], quantile of the block maxima,
#: margin, fewest blocks (the block is shortened below ``UNCALIBRATED_BLOCK_S`` to get them).
UNCALIBRATED_BLOCK_S = 1.0
UNCALIBRATED_QUANTILE = 0.9
UNCALIBRATED_MARGIN = 3.0
UNCALIBRATED_MIN_BLOCKS = 10
UNCALIBRATED_RULE = "uncalibrated-block-quantile"
#: Smallest threshold ever returned [N·m] (keeps |v_stat + v_rms| and ratios finite).
MIN_THRESHOLD = 1e-6


@dataclass(frozen=True)
class ThresholdCalibration:
    """thresholds (J,) [N·m]; margins (J,); maxima (L, J) per log (or (1, J) quantile);
    rule: ``leave-one-out`` | ``fixed-single-log`` | ``uncalibrated-block-quantile``;
    weak: weaker than an uncapped leave-one-out."""

    thresholds: np.ndarray
    margins: np.ndarray
    maxima: np.ndarray
    rule: str
    weak: bool


def adaptive_statistic(r_rms: np.ndarray, v_rms: np.ndarray) -> np.ndarray:
    """(N, J) r_rms − v_rms: the quantity v_stat must exceed."""
    return np.asarray(r_rms) - np.asarray(v_rms)


def leave_one_out_margins(maxima: np.ndarray) -> np.ndarray:
    """Raw leave-one-out margin per joint from (L ≥ 2, J) maxima (≥ 0); inf if a log has
    a positive maximum while all the others are 0."""
    m = np.maximum(np.asarray(maxima, dtype=np.float64), 0.0)
    L = m.shape[0]
    out = np.ones(m.shape[1])
    for j in range(m.shape[1]):
        for l_out in range(L):
            others = np.max(np.delete(m[:, j], l_out))
            if m[l_out, j] > 0:
                need = np.inf if others <= 0 else m[l_out, j] / others
                out[j] = max(out[j], need)
    return out


def calibrate_thresholds(
    statistics: Sequence[np.ndarray], *, min_margin: float = MIN_MARGIN,
    max_margin: float = MAX_MARGIN, single_log_margin: float = SINGLE_LOG_MARGIN,
    joints: Sequence[str] | None = None, detector: str = "",
) -> ThresholdCalibration:
    """Thresholds from collision-free logs.

    Args:
        statistics: per log, the (N_l, J) statistic after warm-up (see module doc).
        min_margin, max_margin: floor and cap of the leave-one-out margin.
        single_log_margin: margin when only one log is given.
        joints, detector: names used in the capped-margin warning.
    """
    if not statistics:
        raise ValueError("calibration needs at least one log")
    maxima = np.array([np.max(np.asarray(s, dtype=np.float64), axis=0) for s in statistics])
    maxima_pos = np.maximum(maxima, 0.0)
    overall = maxima_pos.max(axis=0)
    if len(statistics) == 1:
        margins = np.full(maxima.shape[1], single_log_margin)
        rule, weak = "fixed-single-log", True
    else:
        raw = leave_one_out_margins(maxima_pos)
        margins = np.maximum(raw, min_margin)
        weak = bool(np.any(margins > max_margin))
        if weak:
            names = list(joints) if joints is not None else [f"joint {j}" for j in
                                                              range(len(raw))]
            bad = [f"{names[j]} {raw[j]:.3g}" for j in np.flatnonzero(margins > max_margin)]
            warnings.warn(
                f"{detector + ': ' if detector else ''}leave-one-out margin above "
                f"{max_margin:g} ({', '.join(bad)}); capped — the calibration logs disagree, "
                "add logs covering the robot's motions", ImpactWarning, stacklevel=2,
            )
            margins = np.minimum(margins, max_margin)
        rule = "leave-one-out"
    thr = np.maximum(margins * overall, MIN_THRESHOLD)
    return ThresholdCalibration(thr, margins, maxima, rule, weak)


def block_maxima(statistic: np.ndarray, block: int) -> np.ndarray:
    """(B, J) maxima of consecutive ``block``-sample blocks of (N, J) ``statistic`` (the
    last block may be shorter)."""
    s = np.asarray(statistic, dtype=np.float64)
    starts = np.arange(0, s.shape[0], max(1, int(block)))
    return np.maximum.reduceat(s, starts, axis=0)


def uncalibrated_block(n_after: int, sample_rate_hz: float, *,
                       block_s: float = UNCALIBRATED_BLOCK_S,
                       min_blocks: int = UNCALIBRATED_MIN_BLOCKS) -> int:
    """Samples per block of the uncalibrated rule for a statistic of ``n_after`` samples
    after warm-up: ``block_s`` shortened to give at least ``min_blocks`` blocks; 0 when the
    statistic is shorter than ``min_blocks`` samples (its maximum is used)."""
    return min(max(1, round(block_s * sample_rate_hz)), n_after // min_blocks)


def uncalibrated_span(n: int, warmup_end_index: int, sample_rate_hz: float
                      ) -> tuple[int, int]:
    """(first sample, samples per block) of the uncalibrated rule for a log of ``n``
    samples whose warm-up ends at ``warmup_end_index``: the statistics after it (all of
    them when the warm-up covers the log), in :func:`uncalibrated_block`'s blocks."""
    start = warmup_end_index if warmup_end_index < n - 10 else 0
    return start, uncalibrated_block(n - start, sample_rate_hz)


def uncalibrated_blocks(n: int, warmup_end_index: int, sample_rate_hz: float) -> int:
    """How many blocks the uncalibrated rule takes its quantile over
    (:func:`uncalibrated_span`; 1: the maximum)."""
    start, block = uncalibrated_span(n, warmup_end_index, sample_rate_hz)
    return (n - start) // block if block >= 1 else 1


def deciding_blocks(blocks: int) -> int:
    """How many of the largest block maxima the uncalibrated rule's quantile rests on
    (0 for one block, the maximum): the linear quantile lies at or above the
    floor(q (B − 1))-th sorted maximum, so the B − that largest decide it — on a short log
    an event that fills that many blocks sets its own thresholds."""
    return blocks - int(UNCALIBRATED_QUANTILE * (blocks - 1)) if blocks > 1 else 0


def self_set_text(blocks: int) -> str:
    """The words of a short uncalibrated log (:func:`deciding_blocks` at most 3): ``this log
    gives 11 blocks after warm-up, so its 2 largest block maxima set the quantile: an event
    that fills 2 blocks sets the thresholds at 3× itself and is not found``; "" else."""
    top = deciding_blocks(blocks)
    if not 0 < top <= 3:
        return ""
    return (f"this log gives {blocks} blocks after warm-up, so its {top} largest block "
            f"maxima set the quantile: an event that fills {top} blocks sets the thresholds "
            f"at {UNCALIBRATED_MARGIN:g}× itself and is not found")


class BlockMaxima:
    """:func:`block_maxima` of a statistic that arrives in chunks: blocks of ``block``
    samples from sample ``start`` of the log on (``block`` 0: one block, the maximum).
    State in, state out: :meth:`update` each chunk in order, then :meth:`finish`. The
    maxima are exactly those of the whole statistic at once (a maximum does not round)."""

    def __init__(self, start: int, block: int) -> None:
        self.start, self.block = start, block
        self.done: list[np.ndarray] = []
        self.part: np.ndarray | None = None     # the maximum of the open block so far
        self.filled = 0                         # samples in the open block

    def update(self, k0: int, statistic: np.ndarray) -> None:
        """Absorb (m, J) ``statistic`` of samples ``k0 .. k0 + m - 1`` of the log."""
        s = np.asarray(statistic, dtype=np.float64)[max(0, self.start - k0):]
        if s.shape[0] == 0:
            return
        if self.block <= 0:
            m = s.max(axis=0)
            self.part = m if self.part is None else np.maximum(self.part, m)
            return
        if self.part is not None:
            take = min(self.block - self.filled, s.shape[0])
            self.part = np.maximum(self.part, s[:take].max(axis=0))
            self.filled += take
            s = s[take:]
            if self.filled == self.block:
                self.done.append(self.part[None, :])
                self.part = None
        if s.shape[0] == 0:
            return
        full = s.shape[0] // self.block * self.block
        if full:
            self.done.append(block_maxima(s[:full], self.block))
        if full < s.shape[0]:
            self.part, self.filled = s[full:].max(axis=0), s.shape[0] - full

    def finish(self) -> np.ndarray:
        """(B, J) the blocks' maxima (the last block may be shorter; block 0: (1, J))."""
        rows = self.done + ([self.part[None, :]] if self.part is not None else [])
        return np.concatenate(rows, axis=0)


def thresholds_from_maxima(maxima: np.ndarray, block: int, *,
                           quantile: float = UNCALIBRATED_QUANTILE,
                           margin: float = UNCALIBRATED_MARGIN) -> ThresholdCalibration:
    """The uncalibrated rule's thresholds from :class:`BlockMaxima`'s (B, J) maxima."""
    level = np.quantile(maxima, quantile, axis=0) if block >= 1 else maxima[0]
    level = np.maximum(level, 0.0)
    thr = np.maximum(margin * level, MIN_THRESHOLD)
    return ThresholdCalibration(thr, np.full(maxima.shape[1], margin), level[None, :],
                                UNCALIBRATED_RULE, True)


# ------------------------------------------------------- calibration from a robot's history
#: Long calibration logs are cut into segments of this length after warm-up [s], so that
#: leave-one-out works on one long log (each segment is left out in turn); a log whose
#: part after warm-up is shorter than two segments stays one piece.
SEGMENT_S = 30.0
#: Without labels, a 1 s block of a calibration log whose maximum (a product detector's
#: statistic, on some joint) exceeds this many times the median of all calibration
#: blocks' maxima alone would set that threshold: it is reported as a likely contact in the
#: "free" logs and left out (with ``SUSPECT_GUARD_S`` around it). The median, not a higher
#: quantile, because a "free" log full of contacts may have them in a third of its seconds.
#: Logs with labels beside them are not searched: their labels say where the contacts are.
#: The ratio's measurement: docs/method.md §5b, "Thresholds".
SUSPECT_RATIO = 20.0
SUSPECT_BLOCK_S = 1.0
SUSPECT_QUANTILE = 0.5
SUSPECT_GUARD_S = 1.0
#: Fewest blocks for the rule (a shorter calibration has no distribution to compare with).
SUSPECT_MIN_BLOCKS = 10


def segment_bounds(n: int, sample_rate_hz: float, segment_s: float = SEGMENT_S
                   ) -> list[tuple[int, int]]:
    """[start, stop) sample ranges cutting ``n`` samples into segments of ``segment_s``
    (the last one absorbs the remainder); one range when ``n`` is under two segments."""
    seg = max(1, round(segment_s * sample_rate_hz))
    if n < 2 * seg:
        return [(0, n)]
    k = n // seg
    edges = [i * seg for i in range(k)] + [n]
    return list(itertools.pairwise(edges))


def suspect_blocks(block_max: np.ndarray, ratio: float = SUSPECT_RATIO,
                   quantile: float = SUSPECT_QUANTILE,
                   min_blocks: int = SUSPECT_MIN_BLOCKS) -> tuple[np.ndarray, np.ndarray]:
    """Blocks that alone would set a threshold (module doc).

    Args:
        block_max: (B, J) maxima of every calibration block (all logs pooled).
    Returns:
        (B,) bool: suspect blocks; (B,) float: the largest max / median over joints.
    """
    m = np.maximum(np.asarray(block_max, dtype=np.float64), 0.0)
    if m.shape[0] < min_blocks:
        return np.zeros(m.shape[0], dtype=bool), np.zeros(m.shape[0])
    level = np.quantile(m, quantile, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(level > 0, m / level, 0.0)
    worst = r.max(axis=1)
    return worst > ratio, worst



def detector_ratios(r_rms: np.ndarray, threshold_adaptive: np.ndarray, loading: np.ndarray,
                    baseline: np.ndarray, v_loading: np.ndarray | float,
                    v_baseline: np.ndarray | float) -> dict[str, np.ndarray]:
    """Each detector's statistic over its threshold: adaptive r_rms / |v_stat + v_rms|
    (eq. 42; inf where that threshold is 0), static_loading |LP(r)| / vL, static_baseline
    |r| / v0.

    Args:
        r_rms, threshold_adaptive, loading, baseline: (n, J) residual RMS, adaptive
            threshold, loading statistic and |r| [N·m] (or a joint's (n,) columns).
        v_loading, v_baseline: vL and v0 [N·m], broadcast against them ((1, J), or a
            joint's scalars).
    Returns:
        detector → ratio, shaped as the statistics.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return {"adaptive": np.where(threshold_adaptive > 0, r_rms / threshold_adaptive, np.inf),
                "static_loading": loading / v_loading,
                "static_baseline": baseline / v_baseline}


def compare_to_thresholds(
    thr: dict[str, np.ndarray], r_rms: np.ndarray, v_rms: np.ndarray, loading: np.ndarray,
    baseline: np.ndarray,
) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The thresholds applied to a replay's statistics.

    Args:
        thr: detector → (J,) threshold (v_stat, vL, v0) [N·m].
        r_rms, v_rms: (n, J) the adaptive evaluator's residual RMS and its dynamic part of
            the threshold; loading: (n, J) |LP(r)|; baseline: (n, J) |r| [N·m].
    Returns:
        ((n, J) adaptive threshold |v_stat + v_rms|, detector → (n, J) ratio
        (:func:`detector_ratios`), detector → (n, J) decision: statistic above threshold).
    """
    thr_ad = np.abs(thr["adaptive"][None, :] + v_rms)
    v_l, v_0 = thr["static_loading"][None, :], thr["static_baseline"][None, :]
    ratios = detector_ratios(r_rms, thr_ad, loading, baseline, v_l, v_0)
    decisions = {"adaptive": np.greater(r_rms, thr_ad), "static_loading": np.greater(loading, v_l),
                 "static_baseline": np.greater(baseline, v_0)}
    return thr_ad, ratios, decisions
