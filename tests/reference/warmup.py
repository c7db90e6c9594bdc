"""The warm-up rule on a whole log (docs/method.md §5b, "Warm-up"): the reference
:class:`impactcli.detect.warmup.WarmupTracker` is checked against, chunk by chunk."""

from __future__ import annotations

import numpy as np

from impactcli.config import WarmupConfig
from impactcli.detect.warmup import Warmup


def trailing_rms(x: np.ndarray, window: int) -> np.ndarray:
    """(N, J) RMS of x over samples k-window+1..k (fewer at the start)."""
    x = np.asarray(x, dtype=np.float64)
    c = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), x**2]), axis=0)
    k = np.arange(1, x.shape[0] + 1)
    lo = np.maximum(0, k - window)
    return np.sqrt(np.maximum(c[k] - c[lo], 0.0) / (k - lo)[:, None])


def warmup_end(
    prediction_error: np.ndarray, time_s: np.ndarray, cfg: WarmupConfig | None = None,
    until_s: float | None = None,
) -> Warmup:
    """Warm-up end per joint from the RLS a priori error.

    Args:
        prediction_error: (N, J) eps0 (eq. 40) [N·m].
        time_s: (N,) sample times [s since the first sample].
        cfg: min_s, window_s, tolerance, max_s.
        until_s: a payload change's onset [s]: the level is the median over the later half
            of [k_min, its sample) of the rows the tracker keeps (up to the cap, and the
            log's later half), when a window of them is kept there; its sample is the first
            of every 64th at or after it (the tracker's sparse index).
    """
    cfg = cfg or WarmupConfig()
    e = np.asarray(prediction_error, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    n, J = e.shape
    fs = (n - 1) / (t[-1] - t[0]) if n > 1 and t[-1] > t[0] else 1.0
    w = max(1, round(cfg.window_s * fs))
    k_min = int(np.searchsorted(t, t[0] + cfg.min_s - 1e-12))
    k_cap = int(np.searchsorted(t, t[0] + cfg.max_s - 1e-12))
    rms = trailing_rms(e, w)
    idx = np.empty(J, dtype=np.int64)
    for j in range(J):
        if k_min >= n:
            idx[j] = n
            continue
        level = float(np.median(rms[(k_min + n) // 2 :, j]))
        if until_s is not None:
            sparse = np.arange(0, n, 64)
            i = int(np.searchsorted(t[sparse], t[0] + until_s - 1e-12))
            until = int(sparse[i]) if i < sparse.size else n
            k = np.arange(n)
            kept = (k >= (k_min + until) // 2) & (k < until) & (
                (k <= k_cap) | (k >= (k_min + n) // 2))
            if until > k_min and kept.sum() >= w:
                level = float(np.median(rms[kept, j]))
        ok = np.flatnonzero(rms[k_min:, j] <= (1.0 + cfg.tolerance) * level)
        k = k_min + int(ok[0]) if ok.size else n
        idx[j] = min(k, max(k_cap, 0), n)
    end = int(idx.max())
    end_s = float(t[end] - t[0]) if end < n else float(t[-1] - t[0]) + (
        float(t[-1] - t[-2]) if n > 1 else 0.0)
    return Warmup(idx, end, end_s)
