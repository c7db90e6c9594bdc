"""The Rerun recording of a streamed replay, written chunk by chunk (bounded memory).

:func:`impactcli.outputs.rerun.write_rrd` needs the whole log's signals; a streamed replay
(:mod:`impactcli.stream`) keeps none. Instead it spills, per chunk, what the recording
plots (the signals, the positions, the decisions) to a temporary Parquet file, and
:func:`write_rrd_from_spill` reads it back row group by row group once the answer (events,
incidents, warm-up) is known. The recording holds the same samples as ``write_rrd``'s:

- the documented min/max envelope (:mod:`impactcli.outputs.decimate`), its buckets counted
  from the log's first sample (the total is known), a bucket that spans two row groups
  carried from one to the next (:class:`EnvelopeStream`);
- every sample within ``event_window_s`` of an event, the first and the last sample;
- the detection markers (the same rule on the fired samples, whose count a first pass
  over the decisions gives), every lane transition, the events, incidents and warm-up.

Memory: one row group, and the few candidate rows of each entity's open bucket.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..result import SIGNAL_NAMES
from ..types import DETECTORS
from .decimate import DEFAULT_EVENT_WINDOW_S, DEFAULT_MAX_POINTS, bucket_size


class EnvelopeStream:
    """:func:`impactcli.outputs.decimate.envelope_indices` over K series of N samples that
    arrive in consecutive chunks (state in the object).

    :meth:`update` takes a chunk's (n, K) values, its (n,) kept mask and its rows to emit
    ((n, R) of anything, e.g. the values and the time), and returns the rows selected so
    far that no later chunk can change: the chunk's kept samples, its completed buckets'
    extrema, and the extrema of a bucket carried in from earlier chunks once it completes.
    """

    def __init__(self, n: int, n_series: int, max_points: int = DEFAULT_MAX_POINTS) -> None:
        self.n, self.k = int(n), int(n_series)
        self.b = bucket_size(self.n, self.k, max_points)
        self.k0 = 0
        # the open bucket's candidates: per series (max value, index, row), (min value, ...)
        self.open_id = -1
        self.cand: list[list[Any]] = []
        self.emitted: set[int] = set()  # indices of the open bucket already emitted

    def update(self, values: np.ndarray, keep: np.ndarray, rows: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
        """(indices, rows) selected, for a chunk of (n, K) ``values``."""
        n = len(keep)
        if n == 0:
            return np.zeros(0, dtype=np.int64), rows[:0]
        v = np.asarray(values, dtype=np.float64).reshape(n, -1)
        k0, self.k0 = self.k0, self.k0 + n
        idx = np.arange(k0, k0 + n)
        sel = np.asarray(keep, dtype=bool).copy()
        sel[idx == 0] = True
        sel[idx == self.n - 1] = True
        if self.b <= 1 or self.n <= 2:
            sel[:] = True
            return idx[sel], rows[sel]
        out_idx: list[int] = []
        out_rows: list[Any] = []
        first_b, last_b = k0 // self.b, (k0 + n - 1) // self.b
        # the first and the last bucket touched, one at a time (carried, or left open)
        edges = [(0, min((first_b + 1) * self.b - k0, n), first_b)]
        if last_b > first_b:
            edges.append((last_b * self.b - k0, n, last_b))
            mid = (edges[0][1], edges[1][0])  # whole buckets inside the chunk
            if mid[1] > mid[0]:
                sel[mid[0] + self._middle(v[mid[0]:mid[1]])] = True
        for lo, hi, bid in edges:
            self._segment(v, rows, idx, sel, lo, hi, bid, k0, n, out_idx, out_rows)
        i_new, r_new = idx[sel], rows[sel]
        if out_idx:
            i_new = np.concatenate([np.array(out_idx, dtype=np.int64), i_new])
            r_new = np.concatenate([np.stack(out_rows), r_new])
        return i_new, r_new

    def _middle(self, v: np.ndarray) -> np.ndarray:
        """Chunk-relative indices of the extrema of whole buckets (as envelope_indices)."""
        nb = v.shape[0] // self.b
        base = np.arange(nb) * self.b
        out = []
        for s in range(v.shape[1]):
            c = v[:, s]
            nan = np.isnan(c)
            for fill, arg in ((-np.inf, np.argmax), (np.inf, np.argmin)):
                w = np.where(nan, fill, c) if nan.any() else c
                out.append(base + arg(w.reshape(nb, self.b), axis=1))
        return np.concatenate(out)

    def _segment(self, v: np.ndarray, rows: np.ndarray, idx: np.ndarray, sel: np.ndarray,
                 lo: int, hi: int, bid: int, k0: int, n: int, out_idx: list[int],
                 out_rows: list[Any]) -> None:
        """Merge the chunk's samples [lo, hi) of bucket ``bid`` into its candidates; select
        them when the bucket is complete."""
        local: list[tuple[float, int, float, int]] = []
        for s in range(v.shape[1]):
            c = v[lo:hi, s]
            nan = np.isnan(c)
            cmax, cmin = np.where(nan, -np.inf, c), np.where(nan, np.inf, c)
            i_max, i_min = int(np.argmax(cmax)), int(np.argmin(cmin))
            local.append((float(cmax[i_max]), lo + i_max, float(cmin[i_min]), lo + i_min))
        if bid == self.open_id:  # continue the carried bucket: earlier wins ties
            for s, (mx, imx, mn, imn) in enumerate(local):
                cd = self.cand[s]
                if mx > cd[0]:
                    cd[0], cd[1], cd[2] = mx, int(idx[imx]), rows[imx]
                if mn < cd[3]:
                    cd[3], cd[4], cd[5] = mn, int(idx[imn]), rows[imn]
        else:
            self.open_id = int(bid)
            self.emitted = set()
            self.cand = [[mx, int(idx[imx]), rows[imx], mn, int(idx[imn]), rows[imn]]
                         for mx, imx, mn, imn in local]
        self.emitted |= {int(i) for i in idx[lo:hi][sel[lo:hi]]}
        if min((bid + 1) * self.b, self.n) > k0 + hi:
            return  # the bucket goes on in the next chunk
        for cd in self.cand:
            for gi, row in ((cd[1], cd[2]), (cd[4], cd[5])):
                if gi in self.emitted:
                    continue
                self.emitted.add(gi)
                if k0 <= gi < k0 + n:
                    sel[gi - k0] = True
                else:  # a candidate from an earlier chunk
                    out_idx.append(gi)
                    out_rows.append(row)
        self.open_id = -1


def spill_columns(joints: tuple[str, ...], t_ns: np.ndarray, signals: dict[str, np.ndarray],
                  decisions: dict[str, np.ndarray], position: np.ndarray,
                  position_ref: np.ndarray | None) -> dict[str, np.ndarray]:
    """One chunk's columns of the spill file (module docstring)."""
    cols: dict[str, np.ndarray] = {"t_ns": np.asarray(t_ns, dtype=np.int64)}
    for j, joint in enumerate(joints):
        for name in SIGNAL_NAMES:
            cols[f"{joint}.{name}"] = np.asarray(signals[name][:, j], dtype=np.float64)
        cols[f"{joint}.position"] = np.asarray(position[:, j], dtype=np.float64)
        if position_ref is not None:
            cols[f"{joint}.position_ref"] = np.asarray(position_ref[:, j], dtype=np.float64)
        for det in DETECTORS:
            cols[f"{joint}.{det}"] = decisions[det][:, j].astype(np.uint8)
    return cols


class SpillWriter:
    """The spill file of a streamed replay (a temporary Parquet file, removed by
    :meth:`close`)."""

    def __init__(self, prefix: str = "impactcli-rrd-") -> None:
        from ..spill import temp_space

        with temp_space():
            fd, self.path = tempfile.mkstemp(prefix=prefix, suffix=".parquet")
        os.close(fd)
        self._writer: Any = None
        self.has_reference = False

    def append(self, cols: dict[str, np.ndarray]) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        from ..spill import temp_space

        table = pa.table(cols)
        with temp_space():
            if self._writer is None:
                self._writer = pq.ParquetWriter(self.path, table.schema, compression="zstd",
                                                compression_level=1, use_dictionary=False)
                self.has_reference = any(c.endswith(".position_ref") for c in cols)
            self._writer.write_table(table)

    def finish(self) -> None:
        from ..spill import temp_space

        if self._writer is not None:
            writer, self._writer = self._writer, None
            with temp_space():
                writer.close()

    def close(self) -> None:
        self.finish()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)


def _groups(path: str, columns: list[str] | None = None) -> Iterator[dict[str, np.ndarray]]:
    import pyarrow.parquet as pq

    f = pq.ParquetFile(path)
    for g in range(f.num_row_groups):
        t = f.read_row_group(g, columns=columns)
        yield {name: t.column(name).to_numpy() for name in t.column_names}


def write_rrd_from_spill(result: Any, spill: SpillWriter, path: str | os.PathLike[str], *,
                         max_points: int = DEFAULT_MAX_POINTS,
                         event_window_s: float = DEFAULT_EVENT_WINDOW_S,
                         recording_id: str | None = None) -> None:
    """Write the Rerun recording of a streamed ``result`` from its spill file (module
    docstring), atomically, as :func:`impactcli.outputs.rerun.write_rrd` would."""
    import rerun as rr

    from . import rerun as rrmod

    spill.finish()
    log = result.log
    joints = tuple(log.joint_names)
    n = int(log.n_samples)
    t0 = int(log.t0_ns)
    pad = round(event_window_s * 1e9)
    # first pass: the times the events and incidents stand at, the fired counts
    wanted = {0} | {int(min(max(e.i_start, 0), n - 1)) for e in result.events}
    wanted |= {int(min(e.i_end, n - 1)) for e in result.events}
    for inc in result.incidents:
        wanted |= {int(min(max(inc.i_start, 0), n - 1)),
                   int(min(max(inc.i_end, inc.i_start), n - 1)) + 1}
    w_end = {j: result.warmup_per_joint_s.get(j, result.warmup_end_s) for j in joints}
    i_warm = dict.fromkeys(joints, n)
    times: dict[int, int] = {}
    fired = {(j, d): 0 for j in joints for d in DETECTORS}
    k0 = 0
    dec_cols = [f"{j}.{d}" for j in joints for d in DETECTORS]
    for g in _groups(spill.path, ["t_ns", *dec_cols]):
        t = g["t_ns"]
        m = t.shape[0]
        for i in wanted:
            if k0 <= i < k0 + m:
                times[i] = int(t[i - k0])
        ts = (t - t0).astype(np.float64) * 1e-9
        for j in joints:
            if i_warm[j] == n:
                hit = np.flatnonzero(ts >= w_end[j])
                if hit.size:
                    i_warm[j] = k0 + int(hit[0])
                    times[i_warm[j]] = int(t[hit[0]])
            for d in DETECTORS:
                fired[(j, d)] += int(np.count_nonzero(g[f"{j}.{d}"]))
        k0 += m
    intervals = [(times[int(min(max(e.i_start, 0), n - 1))] - pad,
                  times[int(min(e.i_end, n - 1))] + pad) for e in result.events]

    def indexes_t(t_sel: np.ndarray) -> list[Any]:
        ts = np.asarray(t_sel, dtype=np.int64)
        return [rr.TimeColumn(rrmod.LOG_TIMELINE, timestamp=ts.view("datetime64[ns]")),
                rr.TimeColumn(rrmod.ELAPSED_TIMELINE, duration=(ts - t0).view("timedelta64[ns]"))]

    def indexes(sel: Any) -> list[Any]:
        return indexes_t(np.array([times[int(i)] for i in np.atleast_1d(sel)], dtype=np.int64))

    with rrmod.open_recording(path, result, spill.has_reference, recording_id) as rec:
        _write_samples(rec, result, spill, joints, n, intervals, fired, max_points,
                       indexes_t)
        for j in joints:
            rrmod.write_warmup_lane(rec, j, i_warm[j], n, indexes)
        rrmod._write_events_rows(rec, result, indexes, i_warm)
        rrmod._write_incidents(rec, result, indexes)


def _write_samples(rec: Any, result: Any, spill: SpillWriter, joints: tuple[str, ...],
                   n: int, intervals: list[tuple[int, int]], fired: dict[Any, int],
                   max_points: int, indexes_t: Any) -> None:
    """The plots, the markers and the lanes, one row group at a time."""
    import rerun as rr

    from . import rerun as rrmod

    plots = {
        "rms": [("residual RMS", "residual_rms"), ("threshold v_stat+v_rms", "threshold")],
        "loading": [("loading statistic", "loading_statistic")],
        "residual": [("residual r", "residual"), ("filtered residual", "filtered_residual")],
        "position": [("measured", "position")],
    }
    if spill.has_reference:
        plots["position"].insert(0, ("reference", "position_ref"))
    streams: dict[tuple[str, str], EnvelopeStream] = {}
    marks: dict[tuple[str, str], EnvelopeStream] = {}
    last: dict[tuple[str, str], bool | None] = {}
    for j in joints:
        root = rrmod.joint_entity(j)
        v_l = result.thresholds.get(j, {}).get("vL")
        for plot, series in plots.items():
            names = [s for s, _ in series] + (["vL"] if plot == "loading" and v_l is not None
                                              else [])
            rrmod.style_series(rec, f"{root}/{plot}", names)
            streams[(j, plot)] = EnvelopeStream(n, len(names), max_points)
        for det in DETECTORS:
            rrmod.style_lane(rec, j, det)
            last[(j, det)] = None
            plot, _ = rrmod._MARKED_ON[det]
            if fired[(j, det)]:
                rrmod.style_markers(rec, f"{root}/{plot}/{det}", det)
                marks[(j, det)] = EnvelopeStream(fired[(j, det)], 1, max_points)
    for g in _groups(spill.path):
        t = g["t_ns"]
        keep = np.zeros(t.shape[0], dtype=bool)
        for a, b in intervals:
            keep |= (t >= a) & (t <= b)
        for j in joints:
            root = rrmod.joint_entity(j)
            v_l = result.thresholds.get(j, {}).get("vL")
            for plot, series in plots.items():
                cols = [g[f"{j}.{key}"] for _, key in series]
                if plot == "loading" and v_l is not None:
                    cols.append(np.full(t.shape[0], float(v_l)))
                vals = np.column_stack(cols)
                # the time rides along bit for bit (an int64 ns seen as float64, not cast)
                rows = np.column_stack([vals, t.view(np.float64)])
                sel, r = streams[(j, plot)].update(vals, keep, rows)
                if sel.size:
                    rec.send_columns(f"{root}/{plot}",
                                     indexes=indexes_t(np.ascontiguousarray(r[:, -1]).view(
                                         np.int64)),
                                     columns=rr.Scalars.columns(scalars=r[:, :-1]), strict=True)
            lanes = rrmod.lanes_entity(j)
            for det in DETECTORS:
                d = g[f"{j}.{det}"].astype(bool)
                prev = last[(j, det)]
                change = np.flatnonzero(np.diff(d.astype(np.int8))) + 1
                first = [0] if prev is None or prev != bool(d[0]) else []
                at = np.concatenate([np.array(first, dtype=np.int64), change])
                last[(j, det)] = bool(d[-1])
                if at.size:
                    rec.send_columns(f"{lanes}/{det}", indexes=indexes_t(t[at]),
                                     columns=rr.StateChange.columns(
                                         state=np.where(d[at], "detected", "clear").tolist()),
                                     strict=True)
                if (j, det) not in marks:
                    continue
                plot, sig_name = rrmod._MARKED_ON[det]
                hit = np.flatnonzero(d)
                v = g[f"{j}.{sig_name}"][hit]
                sel, r = marks[(j, det)].update(
                    v, keep[hit], np.column_stack([v, t[hit].view(np.float64)]))
                if sel.size:
                    rec.send_columns(f"{root}/{plot}/{det}",
                                     indexes=indexes_t(np.ascontiguousarray(r[:, -1]).view(
                                         np.int64)),
                                     columns=rr.Scalars.columns(scalars=r[:, 0]), strict=True)
