"""One reader per log: a scan (:class:`LogScan`), then the samples in chunks.

:func:`open_log` gives a :class:`LogReader` for a path (any format, or a URL);
:class:`MemoryReader` is a log already in memory seen the same way. ``reader.scan()`` is
the first pass: everything that needs the whole log before a replay — the header and
provenance, the number of samples, the sample clock (:mod:`impactcli.sampling`), the
gaps, the screens of the torque-like channels; the repairs are warned about once, here,
and a file that cannot be read fails here with one LogFormatError. ``reader.chunks(rows)``
then yields :class:`~impactcli.io.stream_layout.LogChunk` s of the repaired samples, as
many times as asked. Reading a short log whole (:func:`impactcli.io.read_log`) is
collecting its chunks (:func:`collect`).

Every format goes through the same scan: its layout (:mod:`impactcli.io.stream_layout`)
gives the file's rows in blocks, which are repaired across block boundaries
(:class:`~impactcli.io.repair.Repairer`), converted by the layout's plan, counted
(clock, gaps, screens) and kept in a cache of the repaired rows
(:mod:`impactcli.io.stream_cache`) that the chunks are read from. Memory holds a few
blocks whatever the log's length, but for ``--repair-order`` (the stamps of the file,
:func:`~impactcli.io.repair.increasing_run`) and message stamps out of order in the file
(:mod:`impactcli.io.messages`).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ImpactWarning, LogFormatError
from ..sampling import GAP_FACTOR, MAX_STATS_STEPS, GapStream, SampleClock, StepHistogram
from ..types import CONTROLLER_CHANNELS, LogSource, RobotLog
from .repair import Repairer, RepairOrderNeeded, increasing_run
from .stream_cache import RowCache
from .stream_layout import OPTIONAL, LogChunk, ScanPass, StreamLayout, chunked
from .stream_screen import ColumnScreen, ScreenAccumulator

__all__ = ["ColumnScreen", "LogChunk", "LogReader", "LogScan", "MemoryReader", "collect",
           "iter_chunks", "open_log", "scan_log", "scan_memory"]

#: The first pass keeps the steps longer than this fraction of 1.5 provisional periods as
#: gap candidates (exact while the final threshold is above; else a second pass).
FLOOR_FRACTION = 0.8
#: Samples per chunk when a log is collected whole.
COLLECT_ROWS = 1 << 16


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class LogScan:
    """The first pass over a log (:meth:`LogReader.scan`): what needs the whole log.

    Attributes:
        log: the log's header: a :class:`~impactcli.types.RobotLog` of its first 2 samples
            with the whole log's ``joint_names``, ``source`` (sha256 of the whole file,
            format, torque and time source, repairs, ignored channels, joints dropped) and
            optional channels (an array where the whole log has one).
        n_samples: N, the log's samples.
        t0_ns, t_last_ns: its first and last sample time [ns].
        clock: its sample clock (``RobotLog.sample_clock``).
        gaps: (G,) int64 the gap steps i (t[i] → t[i+1]), and ``gap_lengths_s`` (G,) their
            lengths [s], as :func:`impactcli.io.inspect.time_gaps` on the whole log.
        torque_screen: ``unusable_columns(log.torque)`` of the whole log.
        screens: ``torque`` and each controller channel the log has → its
            :class:`ColumnScreen` (``screens[ch].unusable(ref)`` is
            ``unusable_columns(getattr(log, ch), ref)``).
        options: the read options the scan was made with.
    """

    log: RobotLog
    n_samples: int
    t0_ns: int
    t_last_ns: int
    clock: SampleClock
    gaps: np.ndarray
    gap_lengths_s: np.ndarray
    torque_screen: list[str | None]
    screens: dict[str, ColumnScreen]
    options: dict[str, Any] = field(default_factory=dict, repr=False)
    reader: LogReader | None = field(default=None, repr=False, compare=False)

    def close(self) -> None:
        """Close the reader the scan was made by (its cache of the repaired rows, a URL's
        local copy; deleted anyway when the scan is garbage collected or at exit)."""
        if self.reader is not None:
            self.reader.close()

    def __enter__(self) -> LogScan:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The log's J joints."""
        return self.log.joint_names

    @property
    def source(self) -> LogSource:
        """The log's provenance."""
        return self.log.source

    @property
    def channels(self) -> tuple[str, ...]:
        """The optional arrays the log has (names of :data:`OPTIONAL`)."""
        return tuple(s for s in OPTIONAL if getattr(self.log, s) is not None)

    @property
    def sample_period_s(self) -> float:
        """``RobotLog.sample_period_s`` of the whole log [s]."""
        return self.clock.period_s

    @property
    def sample_rate_hz(self) -> float:
        """``RobotLog.sample_rate_hz`` of the whole log [Hz]."""
        return 1.0 / self.clock.period_s

    @property
    def duration_s(self) -> float:
        """From the first to the last sample [s]."""
        return float(self.t_last_ns - self.t0_ns) * 1e-9

    @property
    def torque_ptp(self) -> float:
        """The largest peak-to-peak of the log's torque columns [N·m] (the reference of
        the screen)."""
        s = self.screens["torque"]
        return float(np.max(s.ptp)) if s.ptp.size else 0.0


# --------------------------------------------------------------------------- readers
class LogReader:
    """A log seen as a scan and chunks (module docstring); a context manager (closes)."""

    options: dict[str, Any]

    def scan(self) -> LogScan:
        """The first pass (made once; later calls return it)."""
        raise NotImplementedError

    def chunks(self, rows: int) -> Iterator[LogChunk]:
        """The log's samples in chunks of ``rows`` (the last one shorter), after the scan."""
        raise NotImplementedError

    def close(self) -> None:
        """Delete what the reader keeps (its cache, a URL's local copy)."""

    def __enter__(self) -> LogReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_log(path: str | os.PathLike[str], **read_options: Any) -> LogReader:
    """The reader of a log file, folder or URL (nothing is read before :meth:`~LogReader.scan`).

    Args:
        path: the log, as for :func:`~impactcli.io.read_log`.
        read_options: :func:`~impactcli.io.read_log`'s keyword arguments.
    Raises:
        TypeError: an unknown read option.
    """
    from .paths import check_read_options

    check_read_options(read_options)
    return FileReader(path, read_options)


class FileReader(LogReader):
    """A log file, rosbag2 folder or URL (a URL's local copy is kept until :meth:`close`;
    its ``source.path`` is the URL and its errors name it)."""

    def __init__(self, path: str | os.PathLike[str], options: dict[str, Any]) -> None:
        self.path = path
        self.options = dict(options)
        self._scan: LogScan | None = None
        self._pass: ScanPass | None = None
        self._copy: Any = None  # a URL's local copy (an ExitStack)
        self._finalizers: list[Any] = []
        self._mem: MemoryReader | None = None

    def scan(self) -> LogScan:
        if self._scan is None:
            from .urls import is_url

            self._scan = self._scan_url() if is_url(self.path) else self._scan_local(self.path)
        return self._scan

    def _scan_local(self, path: str | os.PathLike[str]) -> LogScan:
        from ._whole import NotStreamable  # stage 1 only: variants read whole

        try:
            layout = layout_of(path, self.options)
        except NotStreamable:
            return self._whole(path)
        try:
            scan, ps = scan_layout(layout, self.options, self)
        except NotStreamable:
            layout.close()
            return self._whole(path)
        except BaseException:
            layout.close()
            raise
        self._pass = ps
        return scan

    def _whole(self, path: str | os.PathLike[str]) -> LogScan:
        """Stage 1 only: a message log the message layout cannot read yet, read whole."""
        import dataclasses

        from ._whole import read_whole

        self._mem = MemoryReader(read_whole(path, self.options), self.options)
        return dataclasses.replace(self._mem.scan(), reader=self)

    def _scan_url(self) -> LogScan:
        """The scan of a URL's local copy (:func:`impactcli.io.urls.fetched`), kept for
        the reader's lifetime; ``source.path`` is the URL and errors name it."""
        import contextlib
        import dataclasses
        import sys
        import weakref

        from .urls import fetched, refuse_remote_folder

        url = str(self.path)
        refuse_remote_folder(url)
        stack = contextlib.ExitStack()
        lp = stack.enter_context(fetched(url, "log file"))
        try:
            scan = self._scan_local(lp)
        except BaseException:
            stack.__exit__(*sys.exc_info())  # raises the error renamed after the URL
            raise
        self._copy = stack
        self._finalizers.append(weakref.finalize(self, stack.close))
        log = scan.log
        return dataclasses.replace(scan, log=dataclasses.replace(
            log, source=dataclasses.replace(log.source, path=url)))

    def chunks(self, rows: int) -> Iterator[LogChunk]:
        if rows < 1:
            raise ValueError(f"chunk_rows must be at least 1, got {rows}")
        self.scan()
        if self._mem is not None:
            return self._mem.chunks(rows)
        assert self._pass is not None
        return pass_chunks(self._pass, rows)

    def times(self) -> Iterator[np.ndarray]:
        """The log's sample times [ns] in blocks (one pass over the scan's rows)."""
        self.scan()
        if self._mem is not None:
            yield from self._mem.times()
            return
        assert self._pass is not None
        ps = self._pass
        if ps.cache is not None and ps.cache.usable:
            for t, _ in ps.cache.blocks(1 << 20, times_only=True):
                yield t - ps.t_shift if ps.t_shift else t
            return
        for ch in pass_chunks(ps, 1 << 20):
            yield ch.t_ns

    def close(self) -> None:
        ps = self._pass
        if ps is not None:
            if ps.cache is not None:
                ps.cache.close()
                ps.cache = None
            ps.layout.close()
        if self._copy is not None:
            self._copy.close()


class MemoryReader(LogReader):
    """A log in memory as a reader: its scan is computed from its arrays (the same clock,
    gaps and screens a file's scan gives), its chunks are slices of it."""

    def __init__(self, log: RobotLog, options: dict[str, Any] | None = None) -> None:
        self.log = log
        self.options = dict(options or {})
        self._scan: LogScan | None = None

    def scan(self) -> LogScan:
        if self._scan is None:
            from .inspect import time_gaps

            log = self.log
            screens = {s: ColumnScreen.of(getattr(log, s))
                       for s in ("torque", *CONTROLLER_CHANNELS) if getattr(log, s) is not None}
            idx, lengths = time_gaps(log)
            self._scan = LogScan(
                log=log.slice(0, 2), n_samples=log.n_samples, t0_ns=log.t0_ns,
                t_last_ns=int(log.t_ns[-1]), clock=log.sample_clock, gaps=idx,
                gap_lengths_s=lengths, torque_screen=screens["torque"].unusable(),
                screens=screens, options=self.options, reader=self)
        return self._scan

    def chunks(self, rows: int) -> Iterator[LogChunk]:
        if rows < 1:
            raise ValueError(f"chunk_rows must be at least 1, got {rows}")
        log = self.log
        for a in range(0, log.n_samples, rows):
            b = min(a + rows, log.n_samples)
            opt = {s: None if getattr(log, s) is None else getattr(log, s)[a:b]
                   for s in OPTIONAL}
            yield LogChunk(start=a, t_ns=log.t_ns[a:b], position=log.position[a:b],
                           torque=log.torque[a:b], **opt)

    def times(self) -> Iterator[np.ndarray]:
        """The log's sample times [ns] (one block)."""
        yield self.log.t_ns


def scan_memory(log: RobotLog, options: dict[str, Any] | None = None) -> LogScan:
    """The scan of a log in memory (:class:`MemoryReader`): its chunks are slices of it."""
    return MemoryReader(log, options).scan()


def collect(reader: LogReader) -> RobotLog:
    """The whole log of a reader: its scan's header and source with every chunk's samples
    (:func:`impactcli.io.read_log`)."""
    if isinstance(reader, MemoryReader):
        return reader.log
    scan = reader.scan()
    mem = getattr(reader, "_mem", None)  # stage 1 only
    if mem is not None:
        import dataclasses

        return dataclasses.replace(mem.log, source=scan.source)
    n, j = scan.n_samples, len(scan.joint_names)
    t = np.empty(n, dtype=np.int64)
    arrays = {s: np.empty((n, j)) for s in ("position", "torque", *scan.channels)}
    for ch in reader.chunks(COLLECT_ROWS):
        t[ch.start:ch.stop] = ch.t_ns
        for s, a in arrays.items():
            a[ch.start:ch.stop] = getattr(ch, s)
    return RobotLog(t_ns=t, joint_names=scan.joint_names, source=scan.source, **arrays)


# ---------------------------------------------------------------- the former entry points
def scan_log(path: str | os.PathLike[str], **read_options: Any) -> LogScan:
    """The scan of :func:`open_log` (``scan.close()`` closes the reader), warning about the
    repairs once.

    Raises:
        LogFormatError, ChannelMapError: as :func:`~impactcli.io.read_log` would.
    """
    return open_log(path, **read_options).scan()


def iter_chunks(path: str | os.PathLike[str], scan: LogScan, chunk_rows: int,
                **read_options: Any) -> Iterator[LogChunk]:
    """The chunks of the log scanned (:meth:`LogReader.chunks` of the scan's reader).

    Args:
        path: the log scanned.  scan: its :func:`scan_log`.
        chunk_rows: samples per chunk (≥ 1).
        read_options: the options given to :func:`scan_log` (checked).
    Raises:
        ValueError: ``chunk_rows`` < 1 or other options than the scan's.
        LogFormatError: the file changed since the scan.
    """
    if chunk_rows < 1:
        raise ValueError(f"chunk_rows must be at least 1, got {chunk_rows}")
    if read_options != scan.options:
        raise ValueError("iter_chunks: read options differ from the scan's")
    assert scan.reader is not None
    yield from scan.reader.chunks(chunk_rows)


# ---------------------------------------------------------------------- the one scan
def layout_of(path: str | os.PathLike[str], options: dict[str, Any]) -> StreamLayout:
    """The layout of a local log by its format (CSV, ``.npz``, MCAP or ROS bag).

    Raises:
        LogFormatError, ChannelMapError: the path, its options or its channel map refused.
    """
    from .paths import open_log_options

    opts = {k: v for k, v in options.items() if k not in ("robot", "repair_order")}
    p, where, suffix, _folder, cmap = open_log_options(path, **opts)
    from ._whole import NotStreamable

    if suffix in (".csv", ".csv.gz"):
        if cmap is not None and cmap.format == "npz":
            raise NotStreamable
        from .stream_csv import csv_stream_layout

        lay = csv_stream_layout(p, cmap, options)
        if lay is None:
            raise NotStreamable
        return lay
    if suffix == ".npz":
        from .stream_npz import npz_stream_layout

        nlay = npz_stream_layout(p, where, cmap, options)
        if nlay is None:
            raise NotStreamable
        return nlay
    from .stream_msgs import message_layout

    return message_layout(p, where, suffix, cmap, options)


def _blocks(ctx: StreamLayout, rep: Repairer) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The repaired rows of one pass over the layout's rows, in blocks ``(t, mat)``."""
    for raw in ctx.raw_batches():
        out = rep.push(raw)
        if out is not None:
            yield out
    out = rep.finish()
    if out is not None:
        yield out


def _order_pass(ctx: StreamLayout) -> tuple[np.ndarray, str]:
    """``--repair-order``: the rows of the file kept (a bool per row) and the repair's
    message, from the stamps of a pass without exact duplicates."""
    rep = Repairer(ctx, None)
    ts, origs = [], []
    n = 0
    for raw in ctx.raw_batches():
        t, orig = rep.deduplicated(raw)
        ts.append(t)
        origs.append(orig)
        n = raw.row0 + raw.t.shape[0]
    t_all = np.concatenate(ts) if ts else np.zeros(0, np.int64)
    o_all = np.concatenate(origs) if origs else np.zeros(0, np.int64)
    keep, msg = increasing_run(t_all, o_all, ctx.where, ctx.label)
    mask = np.zeros(n, dtype=bool)
    mask[o_all[keep]] = True
    return mask, msg


def scan_layout(ctx: StreamLayout, options: dict[str, Any], reader: LogReader
                ) -> tuple[LogScan, ScanPass]:
    """The scan of a layout's rows (module docstring): passes over them until the layout
    has read them as the whole file must be read, then the statistics, checks and cache.

    Raises:
        LogFormatError: the first error the whole file is refused with.
    """
    from concurrent.futures import ThreadPoolExecutor

    from .paths import log_sha256

    hasher = ThreadPoolExecutor(max_workers=1)
    digest = hasher.submit(log_sha256, ctx.path)
    hasher.shutdown(wait=False)
    order_keep: np.ndarray | None = None
    order_repair: str | None = None
    while True:
        rep = Repairer(ctx, None, order_keep, order_repair)
        acc = _ScanAcc(ctx)
        cache = RowCache(len(ctx.names)) if not ctx.reuse_rows else None
        try:
            try:
                for t, mat in _blocks(ctx, rep):
                    acc.add(t, mat)
                    if cache is not None:
                        cache.add(t, mat)
            except RepairOrderNeeded:
                if cache is not None:
                    cache.close()
                order_keep, order_repair = _order_pass(ctx)
                continue
            if ctx.pass_again():
                if cache is not None:
                    cache.close()
                continue
            if cache is not None:
                cache.finish()
            if rep.n_kept < 2:
                from ._whole import NotStreamable

                raise NotStreamable("fewer than 2 rows")  # stage 1 only
            if ctx.read_error is not None:
                raise ctx.read_error
            err = rep.first_error() or acc.rate_error()
            if err is not None:
                raise LogFormatError(err)
            if isinstance(ctx.plan, LogFormatError):
                raise ctx.plan
            return acc.finish(rep, digest.result(), options, cache, reader)
        except BaseException:
            if cache is not None:
                cache.close()
            raise


class _ScanAcc:
    """The first pass's statistics over the repaired rows."""

    def __init__(self, ctx: StreamLayout) -> None:
        self.ctx = ctx
        self.hist = StepHistogram()
        self.rate = StepHistogram()  # the first MAX_STATS_STEPS steps: the unit check
        self.gaps = GapStream()
        self.n = 0
        self.head_t = np.zeros(0, dtype=np.int64)
        self.head: dict[str, np.ndarray] = {}
        j = len(ctx.joints)
        self.pos_finite = np.zeros(j, dtype=bool)
        self.torque_finite = np.zeros(j, dtype=bool)
        # optional signal → (J,) whether each joint's column holds a finite value
        self.opt_finite: dict[str, np.ndarray] = {}
        self.screens = {s: ScreenAccumulator(j) for s in ("torque", *CONTROLLER_CHANNELS)}
        self.floor = float("-inf")
        self.bad_row: dict[str, np.ndarray] = {}  # signal → (J,) first non-finite sample

    def _first_bad(self, signal: str, a: np.ndarray) -> None:
        """Note each column's first non-finite sample (RobotLog refuses it)."""
        fin = np.isfinite(a)
        if fin.all():
            return
        rows = self.bad_row.setdefault(signal, np.full(a.shape[1], -1, dtype=np.int64))
        new = (rows < 0) & ~fin.all(axis=0)
        rows[new] = self.n - a.shape[0] + np.argmax(~fin, axis=0)[new]

    def check_finite(self, keep: list[int], gone: list[str]) -> None:
        """RobotLog's error for a non-finite value left in a kept joint's column (a value
        scaled out of range); the signals ``gone`` are not in the log."""
        for s in ("position", "torque", *OPTIONAL):
            rows = self.bad_row.get(s) if s not in gone else None
            if rows is None or not (rows[keep] >= 0).any():
                continue
            r = rows[keep]
            row = int(np.min(r[r >= 0]))
            j = int(np.flatnonzero(r == row)[0])
            raise LogFormatError(f"{self.ctx.where}: {s} is not finite at sample {row} "
                                 f"of joint {j}")

    def add(self, t: np.ndarray, mat: np.ndarray) -> None:
        """Count repaired rows ``t`` (n,) int64 [ns], ``mat`` (n, C)."""
        from .assemble import assemble

        if self.rate.n_stamps < MAX_STATS_STEPS + 1:
            self.rate.add(t[: MAX_STATS_STEPS + 1 - self.rate.n_stamps])
        self.hist.add(t)
        period = self.hist.period_ns()
        self.floor = FLOOR_FRACTION * GAP_FACTOR * period if period > 0 else float("-inf")
        self.gaps.add(t, self.floor)
        self.n += t.size
        if isinstance(self.ctx.plan, LogFormatError):
            return
        arrays = assemble(self.ctx.plan, self.ctx.channels(t, mat))
        if self.head_t.size < 2:
            k = 2 - self.head_t.size
            self.head_t = np.concatenate((self.head_t, t[:k]))
            self.head = {s: np.concatenate((self.head[s], a[:k])) if s in self.head else a[:k]
                         for s, a in arrays.items()}
        self.pos_finite |= np.isfinite(arrays["position"]).any(axis=0)
        self.torque_finite |= np.isfinite(arrays["torque"]).any(axis=0)
        for s in self.ctx.plan.optional:
            fin = np.isfinite(arrays[s]).any(axis=0)
            self.opt_finite[s] = self.opt_finite[s] | fin if s in self.opt_finite else fin
        for s, a in arrays.items():
            if s not in CONTROLLER_CHANNELS:
                self._first_bad(s, a)
        for s, acc in self.screens.items():
            if s in arrays:
                acc.add(arrays[s])

    def rate_error(self) -> str | None:
        """The time-unit check on the first steps."""
        return self.ctx.rate_error(self.rate.clock().rate_hz)

    def finish(self, rep: Repairer, sha256: str, options: dict[str, Any],
               cache: RowCache | None, reader: LogReader) -> tuple[LogScan, ScanPass]:
        """The scan: drop the joints without data, warn, the header, clock, gaps, screen."""
        from .assemble import (
            drop_empty_signals,
            drop_message,
            empty_joint_reasons,
            warn_dropped,
        )

        ctx, plan = self.ctx, self.ctx.plan
        joints = ctx.joints
        dropped = empty_joint_reasons(joints, self.pos_finite, self.torque_finite,
                                      plan.torque_source)
        if len(dropped) == len(joints):
            raise LogFormatError(drop_message(ctx.where, dropped, plan.torque_source))
        repairs = ctx.pre_repairs() + rep.repairs()
        for msg in repairs:
            warnings.warn(msg, ImpactWarning, stacklevel=3)
        warn_dropped(ctx.where, dropped)
        out = {j for j, _ in dropped}
        keep = [k for k, j in enumerate(joints) if j not in out]
        kept = tuple(joints[k] for k in keep)
        gone, ignored, msgs = drop_empty_signals(
            ctx.where, kept, {s: self.opt_finite[s][keep] for s in plan.optional})
        allbad = frozenset(int(c) for c in np.flatnonzero(rep.empty))
        shift = int(self.head_t[0]) if ctx.start_at_zero and self.head_t.size else 0
        source = LogSource(path=ctx.where, sha256=sha256, format=ctx.fmt,
                           torque_source=plan.torque_source,
                           time_source=ctx.time_source,  # type: ignore[arg-type]
                           ignored_channels=plan.ignored + tuple(ignored),
                           repairs=tuple(repairs) + tuple(msgs),
                           notes=plan.notes, joints_dropped=tuple(dropped))
        head = {s: _nan_where_empty(a, s, ctx, allbad)[:, keep] for s, a in self.head.items()
                if s not in gone}
        log = RobotLog(t_ns=self.head_t - shift, joint_names=kept, source=source, **head)
        self.check_finite(keep, gone)
        clock = self.hist.clock()
        optional = tuple(s for s in OPTIONAL if getattr(log, s) is not None)
        ps = ScanPass(ctx, allbad, keep, optional, shift, self.n, rep.order_keep,
                      cache if cache is not None and cache.usable else None,
                      rep.order_repair)
        self.gaps.add(np.zeros(0, dtype=np.int64), self.floor, last=True)
        if not self.gaps.exact_for(clock):  # the rate moved: a second pass at the threshold
            self.gaps = _gap_pass(ps, clock)
        idx, lengths = self.gaps.gaps(clock)
        screens = {s: self.screens[s].result().select(keep) for s in self.screens
                   if getattr(log, s) is not None}
        scan = LogScan(log=log, n_samples=self.n, t0_ns=int(self.head_t[0]) - shift,
                       t_last_ns=int(self.hist.last or 0) - shift, clock=clock, gaps=idx,
                       gap_lengths_s=lengths, torque_screen=screens["torque"].unusable(),
                       screens=screens, options=dict(options), reader=reader)
        return scan, ps


def _nan_where_empty(a: np.ndarray, signal: str, ctx: StreamLayout,
                     allbad: frozenset[int]) -> np.ndarray:
    """``a`` with NaN in the columns of joints whose column holds no finite value (such a
    column is NaN in the log; a ±inf would survive in the first rows)."""
    names = ctx.names
    out = np.array(a, dtype=np.float64)
    for (sig, j), key in ctx.keys.items():
        if names.index(key) in allbad and (sig == signal or (
                signal == "torque" and sig == ctx.plan.torque_source)):
            out[:, j] = np.nan
    return out


def _repaired(ps: ScanPass) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The repaired rows of a pass over the layout's rows after the scan (as the scan's)."""
    rep = Repairer(ps.layout, ps.allbad, ps.order_keep, ps.order_repair)
    n = 0
    try:
        for t, mat in _blocks(ps.layout, rep):
            n += t.size
            yield t, mat
    except RepairOrderNeeded:
        raise LogFormatError(f"{ps.layout.where}: changed since it was scanned") from None
    if rep.first_error() is not None or n != ps.n_samples:
        raise LogFormatError(f"{ps.layout.where}: changed since it was scanned")


def _gap_pass(ps: ScanPass, clock: SampleClock) -> GapStream:
    """Gap candidates at the final threshold: a second pass over the times (the scan's
    cache, else the layout's rows)."""
    gs = GapStream()
    cache = ps.cache
    if cache is not None and cache.usable:
        times: Iterator[tuple[np.ndarray, Any]] = cache.blocks(1 << 20, times_only=True)
    else:
        times = _repaired(ps)
    for t, _ in times:
        gs.add(t, clock.gap_threshold_s * 1e9)
    gs.add(np.zeros(0, dtype=np.int64), clock.gap_threshold_s * 1e9, last=True)
    return gs


def pass_chunks(ps: ScanPass, chunk_rows: int) -> Iterator[LogChunk]:
    """A pass after the scan: chunks of ``chunk_rows`` repaired samples, from the scan's
    cache of the repaired rows (:mod:`impactcli.io.stream_cache`), else from the layout."""
    from . import stream_cache

    if ps.cache is not None and ps.cache.usable:
        return stream_cache.chunks(ps, ps.cache, chunk_rows)
    return chunked((ps.arrays(t, mat) for t, mat in _repaired(ps)), chunk_rows)
