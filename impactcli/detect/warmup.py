"""Warm-up of the adaptive evaluator (method.md §4 "zone I", §5b).

Per joint j, the warm-up lasts from the first sample until BOTH
  (a) the RLS has seen ``min_s`` seconds (k ≥ k_min = ceil(min_s · fs)), and
  (b) its a priori prediction error (eq. 40) has settled: the trailing RMS of eps0 over
      ``window_s``, e_rms(k), is at most (1 + tolerance) × L_j, where L_j — "its later
      level" — is the median of e_rms(k) over the later half of [k_min, N) (the median
      ignores the few seconds a contact can occupy; the later half excludes a slow
      convergence);
with an upper cap of ``max_s`` seconds (and the log's end). The warm-up end index is the
first k satisfying (a) and (b); samples before it are in the warm-up. ``warmup_end_s``
is the latest over joints. Condition (b) looks at the whole log's level: it labels
alarms for the report and is not part of the causal detection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import WarmupConfig


@dataclass(frozen=True)
class Warmup:
    """index: (J,) first sample after the warm-up per joint (0..N); end_index: max of
    index; end_s: time of sample ``end_index`` [s since the first sample] (the time just
    after the last sample if the warm-up covers the whole log)."""

    index: np.ndarray
    end_index: int
    end_s: float


def trailing_rms(x: np.ndarray, window: int) -> np.ndarray:
    """(N, J) RMS of x over samples k-window+1..k (fewer at the start)."""
    x = np.asarray(x, dtype=np.float64)
    c = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), x**2]), axis=0)
    k = np.arange(1, x.shape[0] + 1)
    lo = np.maximum(0, k - window)
    return np.sqrt(np.maximum(c[k] - c[lo], 0.0) / (k - lo)[:, None])


def warmup_end(
    prediction_error: np.ndarray, time_s: np.ndarray, cfg: WarmupConfig | None = None,
) -> Warmup:
    """Warm-up end per joint from the RLS a priori error.

    Args:
        prediction_error: (N, J) eps0 (eq. 40) [N·m].
        time_s: (N,) sample times [s since the first sample].
        cfg: min_s, window_s, tolerance, max_s.
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
        ok = np.flatnonzero(rms[k_min:, j] <= (1.0 + cfg.tolerance) * level)
        k = k_min + int(ok[0]) if ok.size else n
        idx[j] = min(k, max(k_cap, 0), n)
    end = int(idx.max())
    end_s = float(t[end] - t[0]) if end < n else float(t[-1] - t[0]) + (
        float(t[-1] - t[-2]) if n > 1 else 0.0)
    return Warmup(idx, end, end_s)
