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
time columns) is indexed by the same selection; :class:`EnvelopeStream` selects the same
indices from a series that arrives in chunks.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

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


class EnvelopeStream:
    """:func:`envelope_indices` over K series of N samples that arrive in consecutive chunks
    (N known beforehand; state in the object), each index selected once.

    Buckets are counted from the first sample; a bucket that spans chunks keeps its
    candidates (per series the maximum and the minimum, the earlier sample winning a tie)
    until it completes. Memory: the open bucket's candidate rows.
    """

    def __init__(self, n: int, n_series: int, max_points: int = DEFAULT_MAX_POINTS) -> None:
        self.n, self.k = int(n), int(n_series)
        self.b = bucket_size(self.n, self.k, max_points)
        self.k0 = 0
        self.open_id = -1                  # the open bucket
        self.cand: list[list[Any]] = []    # per series [max, index, row, min, index, row]
        self.emitted: set[int] = set()     # indices of the open bucket already selected

    def select(self, columns: Sequence[np.ndarray], n_values: int, keep: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
        """The next chunk's selection.

        Args:
            columns: (m,) float64 columns of the chunk: the first ``n_values`` are the K
                series enveloped, the others ride along (e.g. the time, an int64 seen as
                float64: rows are copied bit for bit).
            n_values: K.
            keep: (m,) bool, samples kept whatever the envelope (event windows).
        Returns:
            ((M,) int64 indices in the whole series, (M, len(columns)) their rows): the
            chunk's kept samples, its completed buckets' extrema, and the extrema of a
            bucket carried in from earlier chunks once it completes; no later chunk changes
            them.
        """
        cols = [np.asarray(c) for c in columns]
        n = len(keep)
        if n == 0:
            return np.zeros(0, dtype=np.int64), np.zeros((0, len(cols)))
        k0, self.k0 = self.k0, self.k0 + n
        sel = np.asarray(keep, dtype=bool).copy()
        if k0 == 0:
            sel[0] = True
        if k0 <= self.n - 1 < k0 + n:
            sel[self.n - 1 - k0] = True
        out_idx: list[int] = []
        out_rows: list[np.ndarray] = []
        if self.b <= 1 or self.n <= 2:
            sel[:] = True
        else:
            vals = [np.asarray(c, dtype=np.float64) for c in cols[:n_values]]
            first_b, last_b = k0 // self.b, (k0 + n - 1) // self.b
            # the first and the last bucket touched, one at a time (carried, or left open)
            edges = [(0, min((first_b + 1) * self.b - k0, n), first_b)]
            if last_b > first_b:
                edges.append((last_b * self.b - k0, n, last_b))
                lo, hi = edges[0][1], edges[1][0]  # whole buckets inside the chunk
                if hi > lo:
                    sel[lo + self._middle(vals, lo, hi)] = True
            for lo, hi, bid in edges:
                self._segment(vals, cols, sel, lo, hi, bid, k0, n, out_idx, out_rows)
        local = np.flatnonzero(sel)
        i_new = local + k0
        r_new = np.column_stack([c[local] for c in cols]) if cols else np.zeros((local.size, 0))
        if out_idx:
            i_new = np.concatenate([np.array(out_idx, dtype=np.int64), i_new])
            r_new = np.concatenate([np.stack(out_rows), r_new])
        return i_new, r_new

    def update(self, values: np.ndarray, keep: np.ndarray, rows: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`select` of (m, K) ``values``, with (m, R) ``rows`` riding along: the
        indices selected and their rows."""
        v = np.asarray(values, dtype=np.float64).reshape(len(keep), -1)
        r = np.asarray(rows).reshape(len(keep), -1)
        cols = [v[:, s] for s in range(v.shape[1])] + [r[:, s] for s in range(r.shape[1])]
        idx, got = self.select(cols, v.shape[1], keep)
        return idx, got[:, v.shape[1]:]

    def _middle(self, vals: list[np.ndarray], lo: int, hi: int) -> np.ndarray:
        """Chunk-relative indices of the extrema of the whole buckets in [lo, hi)."""
        nb = (hi - lo) // self.b
        base = np.arange(nb) * self.b
        out = []
        for v in vals:
            c = v[lo:hi]
            nan = np.isnan(c)
            for fill, arg in ((-np.inf, np.argmax), (np.inf, np.argmin)):
                w = np.where(nan, fill, c) if nan.any() else c
                out.append(base + arg(w.reshape(nb, self.b), axis=1))
        return np.concatenate(out)

    def _segment(self, vals: list[np.ndarray], cols: list[np.ndarray], sel: np.ndarray,
                 lo: int, hi: int, bid: int, k0: int, n: int, out_idx: list[int],
                 out_rows: list[np.ndarray]) -> None:
        """Merge the chunk's samples [lo, hi) of bucket ``bid`` into its candidates; select
        them when the bucket is complete."""

        def row(i: int) -> np.ndarray:
            return np.concatenate([c[i:i + 1] for c in cols])

        local: list[tuple[float, int, float, int]] = []
        for v in vals:
            c = v[lo:hi]
            nan = np.isnan(c)
            cmax, cmin = np.where(nan, -np.inf, c), np.where(nan, np.inf, c)
            i_max, i_min = int(np.argmax(cmax)), int(np.argmin(cmin))
            local.append((float(cmax[i_max]), lo + i_max, float(cmin[i_min]), lo + i_min))
        if bid == self.open_id:  # continue the carried bucket: earlier wins ties
            for s, (mx, imx, mn, imn) in enumerate(local):
                cd = self.cand[s]
                if mx > cd[0]:
                    cd[0], cd[1], cd[2] = mx, k0 + imx, row(imx)
                if mn < cd[3]:
                    cd[3], cd[4], cd[5] = mn, k0 + imn, row(imn)
        else:
            self.open_id = int(bid)
            self.emitted = set()
            self.cand = [[mx, k0 + imx, row(imx), mn, k0 + imn, row(imn)]
                         for mx, imx, mn, imn in local]
        self.emitted |= {k0 + int(i) for i in np.flatnonzero(sel[lo:hi]) + lo}
        if min((bid + 1) * self.b, self.n) > k0 + hi:
            return  # the bucket goes on in the next chunk
        for cd in self.cand:
            for gi, r in ((cd[1], cd[2]), (cd[4], cd[5])):
                if gi in self.emitted:
                    continue
                self.emitted.add(gi)
                if k0 <= gi < k0 + n:
                    sel[gi - k0] = True
                else:  # a candidate from an earlier chunk
                    out_idx.append(gi)
                    out_rows.append(r)
        self.open_id = -1
