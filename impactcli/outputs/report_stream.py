"""The report of a streamed replay (:func:`impactcli.stream.analyze_stream`), in bounded
memory, with the content of the whole-log report.

A streamed result holds no per-sample signals; the report reads them in six ways
(:mod:`impactcli.outputs.report.samples`). :class:`ReportCollector` is the replay's
``on_chunk``: per :class:`~impactcli.stream.StreamChunk` it

- feeds the whole-log plots' min/max envelopes
  (:class:`impactcli.outputs.svgplot.EnvelopeAccumulator`: buckets fixed by the scan's
  sample count, one slot per bucket carried across chunks) — the statistic and the
  adaptive threshold of each joint, and one series of zeros that stands for the constant
  static thresholds (an envelope's points of a constant series depend on the sample
  count alone; the value, known from the result, is put in at the end);
- notes the time of the samples at the scan's gaps;
- appends to a temporary Parquet file (:class:`impactcli.outputs.rerun_stream.SpillWriter`,
  one row group per chunk) the columns the rest needs: the time [s], and per joint the
  residual RMS, the adaptive threshold, the loading statistic, |r| and the position.

Once the replay returns, :meth:`ReportCollector.finish` gives a :class:`StreamedSamples`,
which answers from the spill what is only known at the end:

- the samples of a window around each incident or alarm group (rows [lo, hi) found as
  the whole-log report finds them — first sample at or after the window's start, first
  after its end — in the one or two row groups they lie in, from an in-memory index of each
  row group's first and last time), enveloped there as in the whole-log report;
- the false-alarm margin: one pass over the row groups with the final events and labels;
  the ratios are the whole-log run's (same divisions of the same values), the mask
  ``t >= warm-up end`` and outside every widened span is the searchsorted mask of
  :func:`impactcli.outputs.report.collision_free_mask` on sorted times;
- the median posture after warm-up: each joint's positions after the warm-up copied to a
  raw file and their median selected exactly in bounded memory
  (:func:`impactcli.detect.warmup.spilled_median`, ``np.median``'s answer);
- the threshold sweep (:mod:`impactcli.outputs.sweep_stream`): per detector and scale the
  event intervals of :func:`impactcli.evaluate.event_intervals`, built row group by row
  group, then scored as :func:`impactcli.evaluate.sweep_ratios` scores them.

Memory: one row group (one replay chunk) and the envelope slots (4 J + 1 series × 700
buckets); disk: about 6 J + 1 float64 per sample, compressed, removed by :meth:`close`.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..types import DETECTORS, Labels
from .report.common import WHOLE_LOG_BUCKETS
from .report.samples import Stretch, window_bounds
from .rerun_stream import SpillWriter
from .svgplot import EnvelopeAccumulator

#: The per-joint columns of the spill: the statistics the report plots and ratios from.
COLUMNS = ("rms", "thr", "load", "res", "q")


class ReportCollector:
    """The streamed replay's ``on_chunk`` for a report (module docstring).

    Args:
        n_samples: the log's sample count (the scan's).
        gaps: (G,) the scan's gap steps i (t[i] → t[i+1]); gap_lengths_s: (G,) [s].
        buckets: the whole-log envelope's buckets.
        plots: False keeps only what the threshold sweep reads (the ratios' columns: no
            envelopes, no positions).
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
        self.spill = SpillWriter(prefix="impactcli-report-")

    def __call__(self, c: Any) -> None:
        """Absorb one :class:`~impactcli.stream.StreamChunk`."""
        t = np.asarray(c.time_s, dtype=np.float64)
        m = t.shape[0]
        if m == 0:
            return
        if self.joints is None:
            self.joints = tuple(c.joints)
            for k in range(len(self.joints) if self.plots else 0):
                for key in ("rms", "thr", "load", "res"):
                    self.env[(key, k)] = EnvelopeAccumulator(self.n, self.buckets)
        cols: dict[str, np.ndarray] = {"t": t}
        sig = c.signals
        for k in range(len(self.joints)):
            got = {"rms": sig["residual_rms"][:, k], "thr": sig["threshold"][:, k],
                   "load": sig["loading_statistic"][:, k], "res": np.abs(sig["residual"][:, k]),
                   "q": c.position[:, k]}
            for key, raw in got.items():
                if not self.plots and key == "q":
                    continue
                v = np.asarray(raw, dtype=np.float64)
                cols[f"{k}.{key}"] = v
                if self.plots and key != "q":
                    self.env[(key, k)].update(t, v)
        if self.plots:
            self.const.update(t, np.zeros(m))
        hit = (self.gaps >= self.k0) & (self.gaps < self.k0 + m)
        self.gap_t[hit] = t[self.gaps[hit] - self.k0]
        self.spill.append(cols)
        self.groups.append((self.k0, m, float(t[0]), float(t[-1])))
        self.k0 += m

    def finish(self, result: Any) -> StreamedSamples:
        """The report's samples of the streamed ``result`` (the replay is over)."""
        self.spill.finish()
        return StreamedSamples(self, result)

    def close(self) -> None:
        """Remove the spill file."""
        self.spill.close()


class StreamedSamples:
    """:class:`impactcli.outputs.report.samples.Samples` of a streamed run, from its
    :class:`ReportCollector` (module docstring); :meth:`close` removes the spill."""

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
        self.col.close()

    # reading the spill -------------------------------------------------------------
    def _group(self, g: int, columns: list[str]) -> dict[str, np.ndarray]:
        import pyarrow.parquet as pq

        tab = pq.ParquetFile(self.col.spill.path).read_row_group(g, columns=columns)
        return {name: tab.column(name).to_numpy() for name in tab.column_names}

    def groups(self, columns: list[str]) -> Any:
        """(k0, columns) of every row group, in order."""
        import pyarrow.parquet as pq

        f = pq.ParquetFile(self.col.spill.path)
        for g, (k0, _, _, _) in enumerate(self.col.groups):
            tab = f.read_row_group(g, columns=columns)
            yield k0, {name: tab.column(name).to_numpy() for name in tab.column_names}

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
        parts: dict[str, list[np.ndarray]] = {c: [] for c in columns}
        for g, (k0, m, _, _) in enumerate(self.col.groups):
            if k0 + m <= lo or k0 >= hi:
                continue
            got = self._group(g, columns)
            a, b = max(lo - k0, 0), min(hi - k0, m)
            for c in columns:
                parts[c].append(got[c][a:b])
        return {c: (np.concatenate(v) if v else np.zeros(0)) for c, v in parts.items()}

    # the Samples interface ---------------------------------------------------------
    def _thresholds(self, name: str) -> tuple[float, float]:
        th = self.result.thresholds[name]
        return th["vL"], th["v0"]

    def stretch(self, t_a: float, t_b: float) -> Stretch:
        lo = self.index_at(t_a, "left")
        lo, hi = window_bounds(lo, self.index_at(t_b, "right"), self.col.n)
        keys = [f"{k}.{c}" for k in range(len(self.joints)) for c in ("rms", "thr", "load",
                                                                        "res")]
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

    def ratios(self, got: dict[str, np.ndarray], k: int) -> dict[str, np.ndarray]:
        """A row group's ratios of joint k, as the whole-log replay computes them."""
        from ..pipeline import detector_ratios

        v_l, v_0 = self._thresholds(self.joints[k])
        return detector_ratios(got[f"{k}.rms"], got[f"{k}.thr"], got[f"{k}.load"],
                               got[f"{k}.res"], v_l, v_0)

    def ratio_columns(self) -> list[str]:
        return ["t", *[f"{k}.{c}" for k in range(len(self.joints))
                       for c in ("rms", "thr", "load", "res")]]

    def ratio_maxima(self, spans: Sequence[tuple[float, float]], after_s: float
                     ) -> tuple[int, dict[str, list[tuple[float, float] | None]]]:
        n_j = len(self.joints)
        best = {d: [(-np.inf, 0.0)] * n_j for d in DETECTORS}
        count = 0
        for _, got in self.groups(self.ratio_columns()):
            t = got["t"]
            mask = t >= after_s
            for a, b in spans:  # on sorted times: the searchsorted mask of the whole log
                mask &= ~((t >= a) & (t <= b))
            count += int(np.count_nonzero(mask))
            for k in range(n_j):
                for d, r in self.ratios(got, k).items():
                    x = np.where(mask & np.isfinite(r), r, -np.inf)
                    i = int(np.argmax(x))
                    if x[i] > best[d][k][0]:  # strictly: the earlier sample wins a tie
                        best[d][k] = (float(x[i]), float(t[i]))
        return count, {d: [b if np.isfinite(b[0]) else None for b in best[d]]
                       for d in DETECTORS}

    def gaps(self) -> tuple[list[float], list[float]]:
        return [float(x) for x in self.col.gap_t], list(self.col.gap_lengths)

    def posture(self, after_s: float) -> np.ndarray:
        from ..detect.warmup import spilled_median

        n_j = len(self.joints)
        any_after = self.index_at(after_s, "left") < self.col.n
        out = np.zeros(n_j)
        from ..spill import temp_space

        with temp_space(), tempfile.TemporaryDirectory(prefix="impactcli-report-q-") as tmp:
            files = [open(os.path.join(tmp, str(k)), "w+b") for k in range(n_j)]  # noqa: SIM115
            try:
                counts, nan = [0] * n_j, [False] * n_j
                for _, got in self.groups(["t", *[f"{k}.q" for k in range(n_j)]]):
                    sel = got["t"] >= after_s if any_after else slice(None)
                    for k in range(n_j):
                        q = np.ascontiguousarray(got[f"{k}.q"][sel], dtype=np.float64)
                        nan[k] |= bool(np.isnan(q).any())
                        files[k].write(q.tobytes())
                        counts[k] += q.size
                for k, f in enumerate(files):
                    f.flush()
                    out[k] = np.nan if nan[k] else spilled_median(f, counts[k])
            finally:
                for f in files:
                    f.close()
        return out

    def sweep(self, result: Any, labels: Labels, scales: Sequence[float]) -> Any:
        from .sweep_stream import sweep_streamed

        return sweep_streamed(self, result, labels, scales)
