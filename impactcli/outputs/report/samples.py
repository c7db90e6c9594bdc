"""The per-sample facts a report reads, behind one interface, so that a log's report can
be built from a whole-log result (:class:`ResultSamples`, the signals in memory) or from a
streamed replay that kept none (:class:`impactcli.outputs.report_stream.StreamedSamples`,
the same answers from a spill file).

The report reads per-sample data in six ways only; each is a method here:

- :meth:`stretch`: every sample of a time window (the plots around an incident);
- :meth:`whole_log`: the min/max envelope of a detector's statistic and threshold over the
  whole log (:func:`impactcli.outputs.svgplot.envelope`);
- :meth:`ratio_maxima`: the false-alarm margin's maxima (:mod:`.margins`);
- :meth:`gaps`: the gaps of the log's clock (:func:`impactcli.io.inspect.time_gaps`);
- :meth:`posture`: each joint's median position after warm-up (:mod:`.unseen`);
- :meth:`sweep`: the threshold sweep against labels (:mod:`impactcli.evaluate`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ...result import DetectionResult
from ...types import DETECTORS, Labels
from .. import svgplot


def statistic(result: DetectionResult, detector: str, j: int) -> tuple[np.ndarray, np.ndarray]:
    """(statistic, threshold) of ``detector`` on joint index ``j``, each (N,) [N·m].

    adaptive: residual_rms vs threshold (v_stat + v_rms, eq. 42); static_loading:
    loading_statistic vs vL; static_baseline: |residual| vs v0.
    """
    n = result.log.n_samples
    name = result.log.joint_names[j]
    if detector == "adaptive":
        return result.signals["residual_rms"][:, j], result.signals["threshold"][:, j]
    if detector == "static_loading":
        return result.signals["loading_statistic"][:, j], np.full(n, result.thresholds[name]["vL"])
    return np.abs(result.signals["residual"][:, j]), np.full(n, result.thresholds[name]["v0"])


@dataclass(frozen=True)
class Stretch:
    """Consecutive samples of a log: their (M,) times [s] and, per (detector, joint index),
    the (M,) statistic and threshold [N·m]."""

    t: np.ndarray
    series: dict[tuple[str, int], tuple[np.ndarray, np.ndarray]]


def window_bounds(lo: int, hi: int, n: int) -> tuple[int, int]:
    """A window [lo, hi) of at least two samples (when the log has them), within [0, n)."""
    hi = min(max(hi, lo + 2), n)
    return min(lo, hi - 2), hi


class Samples(Protocol):
    """What the report reads per sample (module docstring)."""

    def stretch(self, t_a: float, t_b: float) -> Stretch:
        """The samples with t_a <= t <= t_b (at least two)."""
        ...

    def whole_log(self, detector: str, j: int, buckets: int
                  ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray],
                             tuple[float, float]]:
        """((t, statistic), (t, threshold)) enveloped, and (first, last time)."""
        ...

    def ratio_maxima(self, spans: Sequence[tuple[float, float]], after_s: float
                     ) -> tuple[int, dict[str, list[tuple[float, float] | None]]]:
        """Samples with t >= after_s outside every span [a, b], and per detector and joint
        the largest finite ratio there and its time (None: none)."""
        ...

    def gaps(self) -> tuple[list[float], list[float]]:
        """The time [s] each gap starts at and its length [s]."""
        ...

    def posture(self, after_s: float) -> np.ndarray:
        """(J,) each joint's median position after ``after_s`` (all samples when none)."""
        ...

    def sweep(self, result: DetectionResult, labels: Labels, scales: Sequence[float]) -> Any:
        """:func:`impactcli.evaluate.sweep_thresholds` of the run."""
        ...


class ResultSamples:
    """:class:`Samples` of a whole-log result (its signals in memory)."""

    def __init__(self, result: DetectionResult) -> None:
        self.result = result

    def stretch(self, t_a: float, t_b: float) -> Stretch:
        r = self.result
        t = r.log.time_s
        lo = int(np.searchsorted(t, t_a, side="left"))
        lo, hi = window_bounds(lo, int(np.searchsorted(t, t_b, side="right")), len(t))
        series = {}
        for d in DETECTORS:
            for j in range(len(r.log.joint_names)):
                s, h = statistic(r, d, j)
                series[(d, j)] = (s[lo:hi], h[lo:hi])
        return Stretch(t[lo:hi], series)

    def whole_log(self, detector: str, j: int, buckets: int
                  ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray],
                             tuple[float, float]]:
        t = self.result.log.time_s
        stat, thr = statistic(self.result, detector, j)
        return (svgplot.envelope(t, stat, buckets), svgplot.envelope(t, thr, buckets),
                (float(t[0]), float(t[-1])))

    def mask(self, spans: Sequence[tuple[float, float]], after_s: float) -> np.ndarray:
        """(N,) bool: t >= after_s and outside every span."""
        t = self.result.log.time_s
        mask = t >= after_s
        for a, b in spans:
            lo = int(np.searchsorted(t, a, side="left"))
            hi = int(np.searchsorted(t, b, side="right"))
            mask[lo:hi] = False
        return mask

    def ratio_maxima(self, spans: Sequence[tuple[float, float]], after_s: float
                     ) -> tuple[int, dict[str, list[tuple[float, float] | None]]]:
        r = self.result
        t = r.log.time_s
        mask = self.mask(spans, after_s)
        out: dict[str, list[tuple[float, float] | None]] = {}
        for d in DETECTORS:
            if d not in r.ratios:
                continue
            ratios = np.asarray(r.ratios[d], dtype=np.float64)
            out[d] = []
            for j in range(len(r.log.joint_names)):
                x = np.where(mask & np.isfinite(ratios[:, j]), ratios[:, j], -np.inf)
                k = int(np.argmax(x)) if x.size else 0
                out[d].append(None if x.size == 0 or not np.isfinite(x[k])
                              else (float(x[k]), float(t[k])))
        return int(np.count_nonzero(mask)), out

    def gaps(self) -> tuple[list[float], list[float]]:
        from ...io.inspect import time_gaps

        idx, lengths = time_gaps(self.result.log)  # type: ignore[arg-type]
        t = self.result.log.time_s
        return [float(t[int(i)]) for i in idx], [float(x) for x in lengths]

    def posture(self, after_s: float) -> np.ndarray:
        log = self.result.log
        after = log.time_s >= after_s
        q_log = np.asarray(log.position)[after if after.any() else slice(None)]
        return np.array([float(np.median(q_log[:, k])) for k in range(q_log.shape[1])])

    def sweep(self, result: DetectionResult, labels: Labels, scales: Sequence[float]) -> Any:
        from ... import evaluate as ev

        return ev.sweep_thresholds(result, labels, scales)
