"""One reader per log: a scan (:class:`LogScan`), then the samples in chunks.

:func:`open_log` gives a :class:`LogReader` for a path (any format, or a URL);
:class:`MemoryReader` is a log already in memory seen the same way. ``reader.scan()`` is
the first pass: everything that needs the whole log before a replay — the header and
provenance, the number of samples, the sample clock (:mod:`impactcli.clock`), the
gaps, the screens of the torque-like channels; the repairs are warned about once, here,
and a file that cannot be read fails here with one LogFormatError. ``reader.chunks(rows)``
then yields :class:`~impactcli.logs.layout.LogChunk` s of the repaired samples, as
many times as asked. Reading a short log whole (:func:`impactcli.logs.read_log`) is
collecting its chunks (:func:`collect`).

Every format goes through the same scan: its layout (:mod:`impactcli.logs.layout`)
gives the file's rows in blocks, which are repaired across block boundaries
(:class:`~impactcli.logs.repair.Repairer`), converted by the layout's plan, counted
(clock, gaps, screens) and kept in a cache of the repaired rows
(:mod:`impactcli.logs.row_cache`) that the chunks are read from. Memory holds a few
blocks whatever the log's length, but for ``--repair-order`` (the stamps of the file,
:func:`~impactcli.logs.repair.increasing_run`) and message stamps out of order in the file
(:mod:`impactcli.logs.messages.message_read`).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..sample_channels import CONTROLLER_CHANNELS, OPTIONAL_CHANNELS, REQUIRED_CHANNELS
from ..types import RobotLog
from .layout import LogChunk, ScanPass, StreamLayout
from .scan import LogScan, RowsKept, pass_chunks, passes, raise_read_errors, scan_layout
from .screen import ColumnScreen

__all__ = ["ColumnScreen", "LogChunk", "LogReader", "LogScan", "MemoryReader", "collect",
           "iter_chunks", "open_log", "scan_log", "scan_memory"]

#: Samples per chunk when a log is collected whole.
COLLECT_ROWS = 1 << 16


# --------------------------------------------------------------------------- results


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

    def times(self) -> Iterator[np.ndarray]:
        """The log's sample times [ns] in blocks, after the scan."""
        for ch in self.chunks(1 << 20):
            yield ch.t_ns

    def close(self) -> None:
        """Delete what the reader keeps (its cache, a URL's local copy)."""

    def __enter__(self) -> LogReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_log(path: str | os.PathLike[str], **read_options: Any) -> LogReader:
    """The reader of a log file, folder or URL (nothing is read before :meth:`~LogReader.scan`).

    Args:
        path: the log, as for :func:`~impactcli.logs.read_log`.
        read_options: :func:`~impactcli.logs.read_log`'s keyword arguments.
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

    def scan(self) -> LogScan:
        if self._scan is None:
            from .urls import is_url

            self._scan = self._scan_url() if is_url(self.path) else self._scan_local(self.path)
        return self._scan

    def _scan_local(self, path: str | os.PathLike[str]) -> LogScan:
        layout = layout_of(path, self.options)
        try:
            scan, ps = scan_layout(layout, self.options, self)
        except BaseException:
            layout.close()
            raise
        self._pass = ps
        return scan

    def _scan_url(self) -> LogScan:
        """The scan of a URL's local copy (:func:`impactcli.logs.urls.fetched`), kept for
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
        assert self._pass is not None
        return pass_chunks(self._pass, rows)

    def times(self) -> Iterator[np.ndarray]:
        """The log's sample times [ns] in blocks (one pass over the scan's rows)."""
        self.scan()
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
            from .describe import time_gaps

            log = self.log
            screens = {s: ColumnScreen.of(getattr(log, s))
                       for s in ("torque", *CONTROLLER_CHANNELS) if getattr(log, s) is not None}
            from .defects import DefectScan
            from .poses import PoseSample, pose_explained

            idx, lengths = time_gaps(log)
            found = DefectScan(len(log.joint_names))  # its jumps (a log in memory is
            found.add(log.t_ns, log.position)         # taken as it is: no turn removed)
            found.finish()
            poses = PoseSample(len(log.joint_names))
            poses.add(log.t_ns, log.position, log.torque)
            ranges = {}
            for s in (*REQUIRED_CHANNELS, *OPTIONAL_CHANNELS):
                a = getattr(log, s)
                if a is not None:
                    r = screens.get(s) or ColumnScreen.of(a)
                    ranges[s] = (r.lo, r.hi)
            self._scan = LogScan(
                log=log.slice(0, 2), n_samples=log.n_samples, t0_ns=log.t0_ns,
                t_last_ns=int(log.t_ns[-1]), clock=log.sample_clock, gaps=idx,
                gap_lengths_s=lengths,
                torque_screen=screens["torque"].unusable(posed=pose_explained(poses)),
                screens=screens, options=self.options, reader=self, ranges=ranges,
                jumps=tuple(found.jumps), n_jumps=found.n_jumps, poses=poses,
                torque_posed=pose_explained(poses))
        return self._scan

    def chunks(self, rows: int) -> Iterator[LogChunk]:
        if rows < 1:
            raise ValueError(f"chunk_rows must be at least 1, got {rows}")
        log = self.log
        for a in range(0, log.n_samples, rows):
            b = min(a + rows, log.n_samples)
            opt = {s: None if getattr(log, s) is None else getattr(log, s)[a:b]
                   for s in OPTIONAL_CHANNELS}
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
    (:func:`impactcli.logs.read_log`)."""
    if isinstance(reader, MemoryReader):
        return reader.log
    scan = reader.scan()
    n, j = scan.n_samples, len(scan.joint_names)
    t = np.empty(n, dtype=np.int64)
    arrays = {s: np.empty((n, j)) for s in (*REQUIRED_CHANNELS, *scan.channels)}
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
        LogFormatError, ChannelMapError: as :func:`~impactcli.logs.read_log` would.
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


# ------------------------------------------------------------------------- layouts
def layout_of(path: str | os.PathLike[str], options: dict[str, Any]) -> StreamLayout:
    """The layout of a local log by its format (CSV, ``.npz``, MCAP or ROS bag).

    Raises:
        LogFormatError, ChannelMapError: the path, its options or its channel map refused.
    """
    from .paths import open_log_options

    opts = {k: v for k, v in options.items() if k not in ("robot", "repair_order")}
    p, where, suffix, _folder, cmap = open_log_options(path, **opts)
    if suffix in (".csv", ".csv.gz"):
        from .csv.csv_read import csv_reader_layout

        return csv_reader_layout(p, where, cmap, options)
    if suffix == ".npz":
        from .npz import npz_layout

        return npz_layout(p, where, cmap, options)
    from .messages.message_plan import message_layout

    return message_layout(p, where, suffix, cmap, options)


def read_columns(path: str | os.PathLike[str], options: dict[str, Any], *,
                 check_rate: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A log's columns as its reader reads and repairs them, without making a log of them
    (``impactcli labels`` reads one channel through a one-column map so): the times [ns]
    (shifted by a map's ``start_at_zero``) and the (n, C) values of the layout's columns.

    Raises:
        LogFormatError, ChannelMapError: as the scan of the file would (but for the
            channels a log needs: a position, a torque).
    """
    import warnings as w

    ctx = layout_of(path, options)
    try:
        rows: list[RowsKept] = []

        def sink() -> RowsKept:
            rows.append(RowsKept())
            return rows[-1]

        with w.catch_warnings():
            rep = passes(ctx, sink)
        kept = rows[-1]
        t = np.concatenate(kept.t) if kept.t else np.zeros(0, np.int64)
        dur = float(t[-1] - t[0]) * 1e-9 if t.size else None
        rate = ctx.rate_error(kept.rate.clock().sample_rate_hz, dur) if check_rate else None
        raise_read_errors(ctx, rep, rate)
        mat = np.concatenate(kept.mat) if kept.mat else np.zeros((0, len(ctx.names)))
        if ctx.start_at_zero and t.size:
            t = t - t[0]
        return t, mat
    finally:
        ctx.close()
