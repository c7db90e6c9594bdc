"""Warm-up of the adaptive evaluator (docs/method.md §4: Fig. 15's "zone I"; §5b).

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

When the load changed mid-log (a payload change found, ``until_s`` its onset), L_j is the
level the prediction error settles to under the load the log started with: the median over
the later half of [k_min, the change) — of the rows kept (those up to the cap and those of
the log's later half; at least a window of them, else the whole log's level). A load
changes the prediction error's level (on a simulated soft arm starting with a 1 kg load
its calibration carried, 0.5 N·m before the release at 40 s against 0.22 after it), and
measured against the later, lower level the warm-up ran to its 20 s cap.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

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


class WarmupTracker:
    """The warm-up rule (docs/method.md §5b, "Warm-up"), fed chunk by chunk (state in,
    state out: the tracker is the state); :meth:`finish` gives the same :class:`Warmup`
    as the rule on the whole log (``tests/reference/warmup.py``), bit for bit.

    Known before the first chunk (a first pass over the log's stamps): the sample count
    ``n`` and the first and last times, hence fs, the window and the later half's start.
    Carried: the running sum of squares eps0² (summed in the same order as the whole-log
    ``cumsum``) and its last ``window`` values; kept: the trailing RMS up to the cap
    (``max_s``: the warm-up cannot end later) in memory, and the later half's trailing RMS —
    whose median is each joint's settled level — spilled to the temporary store, a column per joint
    (8 bytes per joint and sample of the log's later half, on disk, not in memory).
    """

    def __init__(self, n: int, t_first_s: float, t_last_s: float, n_joints: int,
                 cfg: WarmupConfig | None = None) -> None:
        from ..spill import ColumnFiles

        self.cfg = cfg = cfg or WarmupConfig()
        self.n, self.J = int(n), int(n_joints)
        sample_rate_hz = (n - 1) / (t_last_s - t_first_s) if n > 1 and t_last_s > t_first_s else 1.0
        self.w = max(1, round(cfg.window_s * sample_rate_hz))
        self.t_first = t_first_s
        self.k = 0
        self.k_min: int | None = None
        self.k_cap: int | None = None
        self.c_last = np.zeros(self.J)
        self.c_ring = np.zeros((0, self.J))  # the last w cumulative sums (c[k-w+1..k])
        self.head: list[np.ndarray] = []     # rms rows before the cap (or all, until known)
        self.head_t: list[np.ndarray] = []
        self.head_n = 0
        self.spill = ColumnFiles("impactcli-warmup-")  # a column per joint (closed by finish)
        self.spill_start: int | None = None
        self.t_tail = np.zeros(0)
        self._end_s = float("nan")
        self.sparse: list[np.ndarray] = []  # (k, t) of every SPARSE-th sample: an index by time

    def _index_at(self, t: np.ndarray, offset: float) -> int | None:
        """Index of the first sample of the chunk at/after t_first + offset, or None."""
        i = int(np.searchsorted(t, self.t_first + offset - 1e-12))
        return self.k + i if i < t.shape[0] else None

    def update(self, prediction_error: np.ndarray, time_s: np.ndarray) -> None:
        """Absorb one chunk: (m, J) eps0 [N·m] at (m,) times [s since the first sample]."""
        e = np.asarray(prediction_error, dtype=np.float64)
        t = np.asarray(time_s, dtype=np.float64)
        m = e.shape[0]
        if m == 0:
            return
        if self.k_min is None:
            self.k_min = self._index_at(t, self.cfg.min_s)
        if self.k_cap is None:
            self.k_cap = self._index_at(t, self.cfg.max_s)
        c = np.cumsum(np.vstack([self.c_last[None, :], e ** 2]), axis=0)[1:]
        allc = np.vstack([self.c_ring, c])  # c[k0 - len(ring) .. k0 + m - 1]
        base = self.k - self.c_ring.shape[0]
        k = np.arange(self.k, self.k + m) + 1          # 1-based "k" of the rule's c index
        lo = np.maximum(0, k - self.w)
        c_lo = np.where((lo > 0)[:, None], allc[np.maximum(lo - 1 - base, 0)], 0.0)
        rms = np.sqrt(np.maximum(c - c_lo, 0.0) / (k - lo)[:, None])
        self.c_last = c[-1].copy()
        self.c_ring = allc[-self.w:].copy()
        cap = self.k_cap if self.k_cap is not None else self.k + m
        keep = max(0, min(m, cap + 1 - self.k))
        if keep:
            self.head.append(rms[:keep])
            self.head_t.append(t[:keep])
            self.head_n += keep
        if self.k_min is not None:
            start = (self.k_min + self.n) // 2
            self.spill_start = start
            a = max(0, start - self.k)
            if a < m:  # one column per joint: read alone later
                self.spill.append({str(j): rms[a:, j] for j in range(self.J)})
        ks = np.arange(self.k, self.k + m)
        every = ks % SPARSE == 0
        self.sparse.append(np.column_stack([ks[every], t[every]]))
        self.t_tail = np.concatenate([self.t_tail, t])[-2:]
        self.k += m

    def close(self) -> None:
        """Close (and so remove) the spill files; :meth:`finish` does it, a run that fails
        on the way calls it."""
        self.spill.close()

    def times_at(self, index: np.ndarray) -> list[float]:
        """Each joint's warm-up end time [s since the first sample] (``index`` from
        :meth:`finish`; the end of the warm-up covering the log for an index ≥ n)."""
        head_t = np.concatenate(self.head_t) if self.head_t else np.zeros(0)
        wu_end = self._end_s
        return [float(head_t[i] - self.t_first) if i < self.n else wu_end for i in index]

    def _index_of(self, t_s: float) -> int:
        """The first sample at or after ``t_s`` [s since the first sample], to
        :data:`SPARSE` samples (the sparse index's next entry)."""
        kt = np.vstack(self.sparse) if self.sparse else np.zeros((0, 2))
        i = int(np.searchsorted(kt[:, 1], self.t_first + t_s - 1e-12))
        return int(kt[i, 0]) if i < kt.shape[0] else self.n

    def _level_before(self, j: int, head: np.ndarray, k_min: int, until: int) -> float | None:
        """Joint ``j``'s level under the load the log started with: the median of the rows
        kept in the later half of [k_min, until) (module docstring), None when fewer than a
        window are kept there."""
        if until <= k_min:
            return None
        a = (k_min + until) // 2
        parts = [head[a:min(until, head.shape[0]), j]]
        start = self.spill_start if self.spill_start is not None else self.n
        lo = max(a, start, head.shape[0])  # the rows past the head's, once each
        if until > lo and self.spill.rows:
            self.spill.flush()
            lo -= start
            parts.append(self.spill.read(lo, until - start, [str(j)])[str(j)])
        rows = np.concatenate(parts)
        return float(np.median(rows)) if rows.size >= self.w else None

    def finish(self, until_s: float | None = None) -> Warmup:
        """The warm-up of the whole log (``until_s``: the onset of its first payload change
        [s], when the load changed: module docstring)."""
        n, J = self.n, self.J
        if self.k != n:
            raise ValueError(f"the tracker saw {self.k} samples, expected {n}")
        k_min = self.k_min if self.k_min is not None else n
        k_cap = self.k_cap if self.k_cap is not None else n
        head = np.vstack(self.head) if self.head else np.zeros((0, J))
        head_t = np.concatenate(self.head_t) if self.head_t else np.zeros(0)
        idx = np.empty(J, dtype=np.int64)
        until = None if until_s is None else self._index_of(until_s)
        for j in range(J):
            if k_min >= n or not self.spill.rows:
                idx[j] = n
                continue
            before = None if until is None else self._level_before(j, head, k_min, until)
            level = self.spill.median(str(j)) if before is None else before
            ok = np.flatnonzero(head[k_min:, j] <= (1.0 + self.cfg.tolerance) * level)
            k = k_min + int(ok[0]) if ok.size else n
            idx[j] = min(k, max(k_cap, 0), n)
        self.close()
        end = int(idx.max())
        t_last = float(self.t_tail[-1])
        end_s = float(head_t[end] - self.t_first) if end < n else t_last - self.t_first + (
            float(self.t_tail[-1] - self.t_tail[-2]) if n > 1 else 0.0)
        self._end_s = end_s
        return Warmup(idx, end, end_s)


#: The warm-up keeps the time of every SPARSE-th sample: where a payload change's onset
#: lies, to this many samples.
SPARSE = 64


def least_s(config: dict[str, Any] | None) -> float | None:
    """The warm-up's least length ``warmup.min_s`` [s] of a run's recorded config (its
    ``to_dict``), None when it records none."""
    value = ((config or {}).get("warmup") or {}).get("min_s")
    return None if value is None else float(value)


def past_least(findings: Sequence[Any], least: float | None) -> list[Any]:
    """The incidents (or lasting loads) in the warm-up that start at or after its least
    length ``least`` [s]: the warm-up ran on there because the evaluator's prediction
    error had not settled (condition (b)), not because the filters were starting, so an
    alarm there may be a contact that no figure of the run judges."""
    if least is None:
        return []
    return [x for x in findings if getattr(x, "in_warmup", False)
            and float(x.t_start) >= least - 1e-9]
