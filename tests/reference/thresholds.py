"""The uncalibrated rule on a whole (N, J) statistic: the product's chunked pieces
(:class:`~impactcli.detect.thresholds.BlockMaxima`,
:func:`~impactcli.detect.thresholds.thresholds_from_maxima`) fed one chunk."""

from __future__ import annotations

import numpy as np

from impactcli.detect.thresholds import (
    UNCALIBRATED_BLOCK_S,
    UNCALIBRATED_MARGIN,
    UNCALIBRATED_MIN_BLOCKS,
    UNCALIBRATED_QUANTILE,
    BlockMaxima,
    ThresholdCalibration,
    thresholds_from_maxima,
    uncalibrated_block,
)


def uncalibrated_thresholds(
    statistic: np.ndarray, sample_rate_hz: float, *, block_s: float = UNCALIBRATED_BLOCK_S,
    quantile: float = UNCALIBRATED_QUANTILE, margin: float = UNCALIBRATED_MARGIN,
    min_blocks: int = UNCALIBRATED_MIN_BLOCKS,
) -> ThresholdCalibration:
    """Robust thresholds from a log's own (N, J) statistic after warm-up (no config).

    ``margin`` × the ``quantile`` of the maxima of ``block_s`` blocks (module doc); the
    block is shortened to give at least ``min_blocks`` blocks, and a statistic shorter
    than ``min_blocks`` samples uses its maximum. ``maxima`` holds the level per joint.
    A statistic read in chunks: :class:`BlockMaxima` then :func:`thresholds_from_maxima`.
    """
    s = np.asarray(statistic, dtype=np.float64)
    if s.ndim != 2 or s.shape[0] == 0:
        raise ValueError(f"expected a non-empty (N, J) statistic, got shape {s.shape}")
    bm = BlockMaxima(0, uncalibrated_block(s.shape[0], sample_rate_hz, block_s=block_s,
                                           min_blocks=min_blocks))
    bm.update(0, s)
    return thresholds_from_maxima(bm.finish(), bm.block, quantile=quantile, margin=margin)
