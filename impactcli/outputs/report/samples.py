"""What a report reads of a run's samples, collected from its chunks in bounded memory.

The report reads per-sample data in six ways, each a method of :class:`Samples`: a time
window's samples (the plots around an incident), a detector's whole-log envelope, the
false-alarm margin's maxima, the clock's gaps, the median posture after warm-up and the
threshold sweep. :class:`ReportCollector` is the run's ``on_chunk``: per chunk it feeds the
whole-log envelopes (:class:`~impactcli.outputs.svgplot.EnvelopeAccumulator`, buckets fixed
by the scan's sample count; the constant static thresholds as one series of zeros, whose
points depend on the sample count alone, the value put in at the end), notes the times at
the scan's gaps and spills to the temporary store (:mod:`impactcli.spill`; one row group a
chunk) the time and per joint the residual RMS,
the adaptive threshold, the loading statistic, |r|, the position and the detectors' ratios.
:meth:`ReportCollector.finish` gives the :class:`Samples`, which answer from the spill what
is known only at the end: a window's rows found as ``np.searchsorted`` finds them on the
whole log (an index of each row group's first and last time), the margin in one pass, the
exact median posture (:func:`impactcli.spill.spilled_median`), the sweep
(:class:`impactcli.quality.sweep.ThresholdSweep`) row group by row group. Memory: one row
group and the envelope slots (4 J + 1 series × the buckets); disk up to 8 J + 1 float64 per
sample, uncompressed, removed by :meth:`Samples.close`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...detect.thresholds import detector_ratios
from ...quality.sweep import SweepRow, ThresholdSweep, event_settings
from ...spill import ColumnFiles
from ...types import DETECTORS, Labels
from ..svgplot import EnvelopeAccumulator
from .common import WHOLE_LOG_BUCKETS

#: The per-joint statistics spilled: residual RMS, adaptive threshold, loading, |r|.
STATISTICS = ("rms", "thr", "load", "res")


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


class ReportCollector:
    """A run's ``on_chunk`` for its report (module docstring).

    Args:
        n_samples: the log's sample count (the scan's).
        gaps: (G,) the scan's gap steps i (t[i] → t[i+1]); gap_lengths_s: (G,) [s].
        buckets: the whole-log envelope's buckets.
        plots: False keeps only what the threshold sweep reads (the ratios: no envelopes,
            no positions).
    """

    def __init__(self, n_samples: int, gaps: Sequence[int] | np.ndarray = (),
                 gap_lengths_s: Sequence[float] | np.ndarray = (),
                 buckets: int = WHOLE_LOG_BUCKETS, plots: bool = True) -> None:
        self.n, self.buckets, self.plots = int(n_samples), int(buckets), plots
        self.joints: tuple[str, ...] | None = None
        self.env: dict[tuple[str, int], EnvelopeAccumulator] = {}
        self.const = EnvelopeAccumulator(self.n, self.buckets)
        self.gaps = np.asarray(gaps, dtype=np.int64)
        self.gap_lengths = [float(x) for x in gap_lengths_s]
        self.gap_t = np.full(self.gaps.size, np.nan)
        self.groups: list[tuple[int, int, float, float]] = []  # (k0, rows, t first, t last)
        self.k0 = 0
        self.has_ratios = False  # the chunks carry their ratios (else rebuilt from the spill)
        self.spill = ColumnFiles("impactcli-report-")

    def __call__(self, c: Any) -> None:
        """Absorb one chunk of the replay (``joints``, ``time_s``, ``signals``,
        ``position``, and ``ratios`` when it carries them)."""
        t = np.asarray(c.time_s, dtype=np.float64)
        m = t.shape[0]
        if m == 0:
            return
        ratios = getattr(c, "ratios", None) or None  # {}: a chunk without them
        if self.joints is None:
            self.joints = tuple(c.joints)
            self.has_ratios = ratios is not None
            for k in range(len(self.joints) if self.plots else 0):
                for key in STATISTICS:
                    self.env[(key, k)] = EnvelopeAccumulator(self.n, self.buckets)
        cols: dict[str, np.ndarray] = {"t": t}
        sig = c.signals
        for k in range(len(self.joints)):
            if self.plots or not self.has_ratios:
                got = {"rms": sig["residual_rms"][:, k], "thr": sig["threshold"][:, k],
                       "load": sig["loading_statistic"][:, k],
                       "res": np.abs(sig["residual"][:, k])}
                for key, raw in got.items():
                    v = np.asarray(raw, dtype=np.float64)
                    cols[f"{k}.{key}"] = v
                    if self.plots:
                        self.env[(key, k)].update(t, v)
            if self.plots:
                cols[f"{k}.q"] = np.asarray(c.position[:, k], dtype=np.float64)
            if ratios is not None and self.has_ratios:
                for d in DETECTORS:
                    cols[f"{k}.x.{d}"] = np.asarray(ratios[d][:, k], dtype=np.float64)
        if self.plots:
            self.const.update(t, np.zeros(m))
        hit = (self.gaps >= self.k0) & (self.gaps < self.k0 + m)
        self.gap_t[hit] = t[self.gaps[hit] - self.k0]
        self.spill.append(cols)
        self.groups.append((self.k0, m, float(t[0]), float(t[-1])))
        self.k0 += m

    def finish(self, result: Any) -> Samples:
        """The report's samples of ``result``, the run the chunks came from."""
        self.spill.finish()
        return Samples(self, result)

    def close(self) -> None:
        """Remove the spill file."""
        self.spill.close()


class Samples:
    """What the report reads per sample (module docstring), from a run's
    :class:`ReportCollector`; :meth:`close` removes its spill file."""

    def __init__(self, col: ReportCollector, result: Any) -> None:
        if col.k0 != col.n or col.joints is None:
            raise ValueError(f"report: {col.k0} samples collected, the scan counted {col.n}")
        self.col, self.result = col, result
        self.joints = col.joints
        if tuple(result.log.joint_names) != self.joints:
            raise ValueError("report: the collected joints are not the result's")
        self.t_first = np.array([g[2] for g in col.groups])
        self.t_last = np.array([g[3] for g in col.groups])

    def close(self) -> None:
        """Remove the spill file."""
        self.col.close()

    # reading the spill -------------------------------------------------------------
    def _group(self, g: int, columns: list[str]) -> dict[str, np.ndarray]:
        return next(self.col.spill.groups(columns, which=[g]))

    def index_at(self, x: float, side: str) -> int:
        """``np.searchsorted(t, x, side)`` over the whole log's times."""
        last = self.t_last
        g = int(np.searchsorted(last, x, side="left" if side == "left" else "right"))
        if g >= len(last):
            return self.col.n
        k0 = self.col.groups[g][0]
        t = self._group(g, ["t"])["t"]
        return k0 + int(np.searchsorted(t, x, side=side))  # type: ignore[call-overload]

    def rows(self, lo: int, hi: int, columns: list[str]) -> dict[str, np.ndarray]:
        """Rows [lo, hi) of the spill's ``columns``."""
        which = [g for g, (k0, m, _, _) in enumerate(self.col.groups)
                 if k0 + m > lo and k0 < hi]
        parts: dict[str, list[np.ndarray]] = {c: [] for c in columns}
        for g, got in zip(which, self.col.spill.groups(columns, which=which), strict=True):
            k0, m = self.col.groups[g][0], self.col.groups[g][1]
            a, b = max(lo - k0, 0), min(hi - k0, m)
            for c in columns:
                parts[c].append(got[c][a:b])
        return {c: (np.concatenate(v) if v else np.zeros(0)) for c, v in parts.items()}

    def _thresholds(self, name: str) -> tuple[float, float]:
        th = self.result.thresholds[name]
        return th["vL"], th["v0"]

    def _ratio_columns(self) -> list[str]:
        keys = [f"x.{d}" for d in DETECTORS] if self.col.has_ratios else list(STATISTICS)
        return ["t", *[f"{k}.{c}" for k in range(len(self.joints)) for c in keys]]

    def _ratios(self, got: dict[str, np.ndarray], k: int) -> dict[str, np.ndarray]:
        """Joint k's ratios in a row group: the run's, or rebuilt from its statistics."""
        if self.col.has_ratios:
            return {d: got[f"{k}.x.{d}"] for d in DETECTORS}
        v_l, v_0 = self._thresholds(self.joints[k])
        return detector_ratios(got[f"{k}.rms"], got[f"{k}.thr"], got[f"{k}.load"],
                             got[f"{k}.res"], v_l, v_0)

    def _ratio_groups(self) -> Iterator[tuple[np.ndarray, list[dict[str, np.ndarray]]]]:
        """(times, per joint its ratios) of every row group, in order."""
        for got in self.col.spill.groups(self._ratio_columns()):
            yield got["t"], [self._ratios(got, k) for k in range(len(self.joints))]

    # what the report reads ------------------------------------------------------------
    def stretch(self, t_a: float, t_b: float) -> Stretch:
        """The samples with t_a <= t <= t_b (at least two)."""
        lo = self.index_at(t_a, "left")
        lo, hi = window_bounds(lo, self.index_at(t_b, "right"), self.col.n)
        keys = [f"{k}.{c}" for k in range(len(self.joints)) for c in STATISTICS]
        got = self.rows(lo, hi, ["t", *keys])
        m = hi - lo
        series = {}
        for k, name in enumerate(self.joints):
            v_l, v_0 = self._thresholds(name)
            series[("adaptive", k)] = (got[f"{k}.rms"], got[f"{k}.thr"])
            series[("static_loading", k)] = (got[f"{k}.load"], np.full(m, v_l))
            series[("static_baseline", k)] = (got[f"{k}.res"], np.full(m, v_0))
        return Stretch(got["t"], series)

    def whole_log(self, detector: str, j: int, buckets: int
                  ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray],
                             tuple[float, float]]:
        """((t, statistic), (t, threshold)) of ``detector`` on joint index ``j`` enveloped
        (:func:`impactcli.outputs.svgplot.envelope`), and (first, last time)."""
        if buckets != self.col.buckets:
            raise ValueError(f"report: envelopes of {self.col.buckets} buckets collected, "
                             f"{buckets} asked")
        v_l, v_0 = self._thresholds(self.joints[j])
        x_range = (float(self.t_first[0]), float(self.t_last[-1]))
        env = self.col.env
        if detector == "adaptive":
            return env[("rms", j)].result(), env[("thr", j)].result(), x_range
        stat = env[("load" if detector == "static_loading" else "res", j)].result()
        value = v_l if detector == "static_loading" else v_0
        tc, _ = self.col.const.result()
        if not np.isfinite(value):  # envelope() skips a bucket without a finite value
            tc = tc[:0] if not self.col.const.whole else tc
        return stat, (tc, np.full(tc.shape[0], float(value))), x_range

    def ratio_maxima(self, spans: Sequence[tuple[float, float]], after_s: float
                     ) -> tuple[int, dict[str, list[tuple[float, float] | None]]]:
        """Samples with t >= after_s outside every span [a, b], and per detector and joint
        the largest finite ratio there and its time (None: none)."""
        n_j = len(self.joints)
        best = {d: [(-np.inf, 0.0)] * n_j for d in DETECTORS}
        count = 0
        for t, per in self._ratio_groups():
            mask = t >= after_s
            for a, b in spans:  # on sorted times: the searchsorted mask of the whole log
                mask &= ~((t >= a) & (t <= b))
            count += int(np.count_nonzero(mask))
            for k in range(n_j):
                for d, r in per[k].items():
                    x = np.where(mask & np.isfinite(r), r, -np.inf)
                    i = int(np.argmax(x))
                    if x[i] > best[d][k][0]:  # strictly: the earlier sample wins a tie
                        best[d][k] = (float(x[i]), float(t[i]))
        return count, {d: [b if np.isfinite(b[0]) else None for b in best[d]]
                       for d in DETECTORS}

    def gaps(self) -> tuple[list[float], list[float]]:
        """The time [s] each gap starts at and its length [s]."""
        return [float(x) for x in self.col.gap_t], list(self.col.gap_lengths)

    def posture(self, after_s: float) -> np.ndarray:
        """(J,) each joint's median position after ``after_s`` (all samples when none)."""
        n_j = len(self.joints)
        any_after = self.index_at(after_s, "left") < self.col.n
        out = np.zeros(n_j)
        nan = [False] * n_j
        with contextlib.closing(ColumnFiles("impactcli-report-q-")) as store:
            for got in self.col.spill.groups(["t", *[f"{k}.q" for k in range(n_j)]]):
                sel = got["t"] >= after_s if any_after else slice(None)
                qs = {str(k): np.asarray(got[f"{k}.q"][sel], dtype=np.float64)
                      for k in range(n_j)}
                for k in range(n_j):
                    nan[k] |= bool(np.isnan(qs[str(k)]).any())
                store.append(qs)
            for k in range(n_j):
                out[k] = np.nan if nan[k] else store.median(str(k))
        return out

    def sweep(self, result: Any, labels: Labels, scales: Sequence[float],
              tolerance: Any = None) -> list[SweepRow]:
        """The threshold sweep of the run against ``labels`` (the run's event settings),
        fed row group by row group."""
        gap, min_dur = event_settings(result.config, None, None)
        sweep = ThresholdSweep(scales, warmup_end_s=result.warmup_end_s, merge_gap_s=gap,
                               min_duration_s=min_dur)
        for t, per in self._ratio_groups():
            sweep.update(t, {d: np.column_stack([p[d] for p in per]) for d in DETECTORS})
        return sweep.rows(labels, tolerance, list(result.payload_changes or ()))
