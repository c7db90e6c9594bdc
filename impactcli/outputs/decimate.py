"""Peak-preserving decimation of long per-sample series for display (Rerun recording).

Pure functions, no I/O. The rule (documented in the README's "Viewing a run"):

* A series of N samples is written at full rate while ``N <= max_points``
  (:data:`DEFAULT_MAX_POINTS` = 200 000 samples per series, what the Rerun viewer plots
  comfortably; a 1 kHz log reaches it after 200 s).
* Above that, the samples are cut into consecutive buckets of ``b`` samples and only
  the sample holding each bucket's minimum and the one holding its maximum are kept,
  per series (a min/max envelope, never plain subsampling: a one-sample spike always
  survives). ``b = ceil(2·K·N / max_points)`` for K series sharing one time column, so
  an entity keeps at most about ``max_points`` rows outside the kept windows.
* Samples inside a kept window — every event ± :data:`DEFAULT_EVENT_WINDOW_S` — are all
  kept (full rate), as are the first and last samples.

The result is a sorted array of sample indices, so every series of an entity (and its
time columns) is indexed by the same selection.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

#: Above this many samples per series, a series is decimated (min/max envelope).
DEFAULT_MAX_POINTS: int = 200_000
#: Full-rate window kept on each side of every event [s].
DEFAULT_EVENT_WINDOW_S: float = 2.0


def window_mask(t_ns: np.ndarray, intervals_ns: Iterable[tuple[int, int]],
                pad_ns: int) -> np.ndarray:
    """Mark the samples inside any padded interval.

    Args:
        t_ns: (N,) int64 sample times, strictly increasing [ns].
        intervals_ns: (start, end) pairs, both inclusive, on the same clock [ns].
        pad_ns: padding added on both sides of each interval [ns], >= 0.

    Returns:
        (N,) bool, True for samples with ``start - pad <= t <= end + pad`` for some interval.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    n = t.shape[0]
    delta = np.zeros(n + 1, dtype=np.int64)
    for start, end in intervals_ns:
        lo = int(np.searchsorted(t, int(start) - pad_ns, side="left"))
        hi = int(np.searchsorted(t, int(end) + pad_ns, side="right"))
        if hi > lo:
            delta[lo] += 1
            delta[hi] -= 1
    return np.cumsum(delta[:n]) > 0


def bucket_size(n: int, n_series: int = 1, max_points: int = DEFAULT_MAX_POINTS) -> int:
    """Samples per bucket for ``n`` samples of ``n_series`` series (1 = no decimation).

    Args:
        n: number of samples N.
        n_series: number of series K sharing the time column (each keeps 2 samples per bucket).
        max_points: the per-series size above which decimation starts.
    """
    if max_points < 1:
        raise ValueError(f"max_points must be positive, got {max_points}")
    if n <= max_points:
        return 1
    return max(2, -(-2 * max(n_series, 1) * n // max_points))


def _columns(values: np.ndarray | Sequence[np.ndarray]) -> list[np.ndarray]:
    """The series as (N,) float arrays (views where possible, no copies of (N, K) input)."""
    if isinstance(values, np.ndarray):
        v = values if values.dtype.kind == "f" else values.astype(np.float64)
        return [v] if v.ndim == 1 else [v[:, i] for i in range(v.shape[1])]
    cols = [np.asarray(c) for c in values]
    return [c if c.dtype.kind == "f" else c.astype(np.float64) for c in cols]


def envelope_indices(values: np.ndarray | Sequence[np.ndarray], bucket: int,
                     keep: np.ndarray | None = None) -> np.ndarray:
    """Indices of a min/max envelope of ``values``, plus every kept sample.

    Args:
        values: (N,) or (N, K) samples, or a sequence of K (N,) series (NaN allowed:
            ignored when finding extrema).
        bucket: samples per bucket b (>= 1); 1 returns every index.
        keep: optional (N,) bool, samples always kept (e.g. event windows).

    Returns:
        (M,) int64 sorted unique indices: for each bucket of b consecutive samples and each
        series, the index of its minimum and of its maximum; every index with ``keep``; and
        0 and N-1. Hence, for every bucket, the max and min over the selected samples
        equal the max and min over all its samples.
    """
    cols = _columns(values)
    n = cols[0].shape[0]
    if bucket <= 1 or n <= 2:
        return np.arange(n, dtype=np.int64)
    sel = np.zeros(n, dtype=bool)
    sel[[0, n - 1]] = True
    if keep is not None:
        sel |= np.asarray(keep, dtype=bool)
    n_full = n // bucket
    for c in cols:
        nan = np.isnan(c)
        has_nan = bool(nan.any())
        for lo, hi in ((0, n_full * bucket), (n_full * bucket, n)):
            if hi <= lo:
                continue
            b = min(bucket, hi - lo)
            nb = (hi - lo) // b
            base = lo + np.arange(nb) * b
            for fill, arg in ((-np.inf, np.argmax), (np.inf, np.argmin)):
                # without NaN: a strided view, no copy; with NaN: NaN never wins
                w = np.where(nan[lo:hi], fill, c[lo:hi]) if has_nan else c[lo:hi]
                sel[base + arg(w.reshape(nb, b), axis=1)] = True
    return np.flatnonzero(sel)


def select_samples(values: np.ndarray | Sequence[np.ndarray], keep: np.ndarray | None = None,
                   max_points: int = DEFAULT_MAX_POINTS) -> np.ndarray:
    """The samples of ``values`` to display: all of them, or the documented envelope.

    Args:
        values: (N,) or (N, K) samples, or K (N,) series, sharing one time column.
        keep: optional (N,) bool, samples kept at full rate (event windows).
        max_points: per-series size above which the envelope is used.

    Returns:
        (M,) int64 sorted indices into the N samples.
    """
    cols = _columns(values)
    return envelope_indices(cols, bucket_size(cols[0].shape[0], len(cols), max_points), keep)
