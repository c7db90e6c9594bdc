"""The threshold sweep of a streamed run, in bounded memory: the rows
:func:`impactcli.evaluate.sweep_thresholds` gives on the whole-log result.

The sweep re-extracts, per detector and threshold scale s, the events of the decision
``ratio > s`` (:func:`impactcli.evaluate.event_intervals`: runs of samples where some
joint's ratio exceeds s, merged across gaps of at most ``merge_gap_s``, the one merged
event that straddles the warm-up's end split there, those shorter than ``min_duration_s``
dropped) and scores them. The whole-log sweep holds the (N, J) ratios; here the ratios of
one row group of the report's spill (:mod:`impactcli.outputs.report_stream`) at a time
feed one :class:`_Intervals` per (detector, scale), which carries across row groups the
run still open at the group's end and the merged event still open. Splitting at the
warm-up is done on the runs: a run across the warm-up's first sample k_w is cut before it,
and a run at or after k_w never merges with one before it — which gives the same two parts
as :func:`impactcli.detect.events.split_at_warmup` (the part before ends at the last
firing sample before k_w, the part after starts at the first at or after it). Memory: the
events found (what the whole-log sweep scores too).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..types import DETECTORS, Labels


class _Intervals:
    """:func:`impactcli.evaluate.event_intervals` over consecutive row groups (module
    docstring), for one detector and scale; times are the sample times [s]."""

    def __init__(self, merge_gap_s: float, min_duration_s: float, eps_s: float, k_w: int,
                 t_kw: tuple[float, float]) -> None:
        self.gap, self.min_dur, self.eps = merge_gap_s + eps_s, min_duration_s - eps_s, eps_s
        self.k_w, self.t_kw = k_w, t_kw   # first sample at/after the warm-up; t[k_w-1], t[k_w]
        self.run: list[Any] | None = None   # the run open at the last group's end
        self.open: list[Any] | None = None  # merged event: [i0, t0, i1, t1]
        self.out: list[tuple[float, float]] = []

    def update(self, k0: int, t: np.ndarray, fire: np.ndarray) -> None:
        """Absorb a row group: its first index, (m,) times and (m,) decisions."""
        if not fire.any():
            if self.run is not None:
                self._runs([self.run])
                self.run = None
            return
        x = np.diff(fire.astype(np.int8), prepend=np.int8(0), append=np.int8(0))
        s = np.flatnonzero(x == 1)
        e = np.flatnonzero(x == -1) - 1
        runs = [[k0 + int(a), float(t[a]), k0 + int(b), float(t[b])] for a, b in zip(s, e,
                                                                                    strict=True)]
        if self.run is not None:
            if fire[0]:
                runs[0][0], runs[0][1] = self.run[0], self.run[1]
            else:
                runs.insert(0, self.run)
            self.run = None
        if fire[-1]:
            self.run = runs.pop()
        self._runs(runs)

    def _runs(self, runs: list[list[Any]]) -> None:
        kw = self.k_w
        for r in runs:
            if r[0] < kw <= r[2]:  # across the warm-up's end: two runs
                self._one([r[0], r[1], kw - 1, self.t_kw[0]])
                self._one([kw, self.t_kw[1], r[2], r[3]])
            else:
                self._one(r)

    def _one(self, r: list[Any]) -> None:
        o = self.open
        if o is not None and r[1] - o[3] <= self.gap and not (r[0] >= self.k_w > o[2]):
            o[2], o[3] = r[2], r[3]
            return
        self._close()
        self.open = list(r)

    def _close(self) -> None:
        o = self.open
        if o is not None and o[3] - o[1] >= self.min_dur:
            self.out.append((o[1], o[3]))
        self.open = None

    def finish(self) -> list[tuple[float, float]]:
        """The events' (t_start, t_end) [s], in time order."""
        if self.run is not None:
            self._runs([self.run])
            self.run = None
        self._close()
        return self.out


def sweep_streamed(samples: Any, result: Any, labels: Labels, scales: Sequence[float],
                   tolerance: Any = None) -> list[Any]:
    """The rows of :func:`impactcli.evaluate.sweep_thresholds` for a streamed ``result``
    whose per-sample ratios ``samples`` (a
    :class:`impactcli.outputs.report_stream.StreamedSamples`) reads from its spill."""
    from ..detect.events import _EPS_S
    from ..errors import ImpactWarning
    from ..scoring.match import EPS_S, EVALUATED, MatchTolerance, _Ev
    from ..scoring.sweep import _event_settings, add_rows, sorted_scales, warn_late_labels

    tol = tolerance if tolerance is not None else MatchTolerance()
    gap, min_dur = _event_settings(result.config, None, None)
    scales_sorted = sorted_scales(scales)
    wu = float(result.warmup_end_s)
    n = samples.col.n
    k_w = samples.index_at(wu - _EPS_S, "left")
    t_kw = (float(samples.rows(k_w - 1, k_w, ["t"])["t"][0]) if 0 < k_w <= n else math.nan,
            float(samples.rows(k_w, k_w + 1, ["t"])["t"][0]) if k_w < n else math.nan)
    machines = {(d, s): _Intervals(gap, min_dur, EPS_S, k_w, t_kw)
                for d in DETECTORS for s in scales_sorted}
    n_j = len(samples.joints)
    for k0, got in samples.groups(samples.ratio_columns()):
        t = got["t"]
        per = [samples.ratios(got, k) for k in range(n_j)]
        for d in DETECTORS:
            # some joint above s <=> the largest non-NaN ratio above s
            top = np.fmax.reduce(np.stack([p[d] for p in per], axis=1), axis=1)
            for s in scales_sorted:
                machines[(d, s)].update(k0, t, top > s)
    duration_s = float(samples.t_last[-1] - samples.t_first[0])
    rows_of: dict[str, list[Any]] = {d: [] for d in EVALUATED}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        for s in scales_sorted:
            evs = [_Ev(d, a, b, a < wu) for d in DETECTORS
                   for a, b in machines[(d, s)].finish()]
            add_rows(rows_of, s, evs, labels, duration_s=duration_s, warmup_end_s=wu,
                     tolerance=tol, merge_gap_s=gap)
    warn_late_labels(labels, duration_s, wu, tol)
    return [r for rows in rows_of.values() for r in rows]
