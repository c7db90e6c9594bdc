"""Reading a log chunk by chunk: :func:`scan_log` (a first pass), then :func:`iter_chunks`.

A day-long log is replayed in bounded memory: the first pass finds everything that needs
the whole log before the replay (:class:`LogScan`: the header and provenance, the number of
samples, the sample clock, the gaps, the torque screen), the second yields
:class:`LogChunk` s of at most ``chunk_rows`` samples.

Exact: for any ``chunk_rows``, the chunks' arrays concatenated are :func:`~impactcli.io.read_log`'s
arrays bit for bit (NaN where it has NaN), the scan's ``log.source`` is its
:class:`~impactcli.types.LogSource` (the whole file's sha256, the same repairs), its warnings
are the same and given once (by the scan), its clock, gaps and screen those of the whole
:class:`~impactcli.types.RobotLog` (:mod:`impactcli.sampling`'s step histogram and chunked
gap rule, :func:`impactcli.detect.screen.unusable_columns` from per-column minimum, maximum
and up to ``FEW_VALUES`` distinct values). Its errors are :func:`read_log`'s one-line
LogFormatErrors, raised by the scan (a bad file fails before any output is written).

Streamed (memory bounded, whatever the log's length), one implementation for every
format: a format's layout (:mod:`impactcli.io.stream_layout`) gives the file's rows in
blocks, before repairs; they are repaired across block boundaries as in the whole file
(:mod:`impactcli.io.stream_repair`, the policy of :mod:`impactcli.io.repair`: exact
duplicate rows dropped, runs of at most 5 non-finite values interpolated — rows are held
back until a run closes —, values beyond 1e12 and rows out of time order refused; the
20 Hz – 100 kHz rate check of CSV and ``.npz`` time columns), converted block by block by
the whole-file reader's own steps (the map's scale and offset, current → torque). The
formats:

- a local ``.csv`` or ``.csv.gz`` — canonical, or through a CSV channel map; a UTF-8
  byte-order mark or a decimal comma too — whose time column holds plain decimal numbers
  (``12.345``, ``1714567890.001``, ``1234``) or ISO-8601 stamps and whose value cells are
  numbers or empty: parsed by
  pyarrow in ranges of about :data:`BLOCK_SIZE` = 1 MiB, on threads at most 4 ahead of the
  scan (:mod:`impactcli.io.stream_csv`, :mod:`impactcli.io.stream_parse`);
- MCAP (ROS 2 JointState with its ``_ref``/``_model``/``_ext`` companions, impactcli's JSON
  joint samples, any message type through a ``format: messages`` channel map) and ROS bags
  (rosbag2 ``.db3`` files and folders, ROS 1 ``.bag``): one MCAP chunk (or 8192 bag
  messages) at a time, in two passes — the first decodes and counts (the state topic, its
  signals, the time source, each topic's stamps), the second merges the companion and map
  topics by causal sample-and-hold (:mod:`impactcli.io.stream_msgs`,
  :mod:`impactcli.io.stream_msgs_plan`, :mod:`impactcli.io.stream_blocks`); a truncated
  MCAP as the whole reader reads it;
- ``.npz`` through a ``format: npz`` map: each ``.npy`` member read 65536 rows at a time,
  deflated members too (:mod:`impactcli.io.stream_npz`);
- any of these named by URL (``file://``, or fsspec: ``s3://``, ``memory://``...): the
  local copy :func:`read_log` reads (a remote object downloaded to a temporary folder) is
  streamed and kept for the scan's lifetime, deleted by :meth:`LogScan.close`, the scan's
  garbage collection or the interpreter's exit; ``source.path`` is the URL and errors name
  it, as :func:`read_log`'s do (its repairs name the local copy, as :func:`read_log`'s do).

The scan keeps, besides constants per column, the candidate gaps (steps longer than 1.2
provisional periods, with their windows; a second pass if the period then drifts below).
Only the scan reads the file (all the channels: the repairs and the screen need their
values); it keeps the rows it repaired in a binary temporary file that :func:`iter_chunks`
reads instead (:mod:`impactcli.io.stream_cache`: a copy instead of a parse; the same
arrays bit for bit), until :meth:`LogScan.close`, the scan's garbage collection or the
interpreter's exit deletes it. Without the cache (a full disk) each pass reads the file.

Not streamed (``LogScan.streamed`` False; the scan reads the whole log with
:func:`read_log` and the chunks are slices of it, memory NOT bounded): CSV variants
(other time text — exponents, dates without a time —, empty or non-numeric time cells, a
value column that is not numeric); message logs whose state
stamps (or a held topic's) are out of order in the file (the whole reader sorts them),
whose companion topics change their joint names between messages, with ROS 1 JointState
inside MCAP, an MCAP compression the scanner does not know, or a held topic more than
200 000 messages ahead or behind the state in the file;
``--repair-order`` on a file with rows out of time order; and any file the whole-file
reader refuses for a reason the stream does not check itself (the whole-file reader then
raises its own error: a bad file, a topic it cannot choose, an array of the wrong shape...).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ImpactWarning, LogFormatError
from ..sampling import (
    GAP_FACTOR,
    MAX_STATS_STEPS,
    GapStream,
    SampleClock,
    StepHistogram,
)
from ..types import CONTROLLER_CHANNELS, LogSource, RobotLog
from .stream_cache import RowCache, take
from .stream_csv import BLOCK_SIZE, _decimal_ns  # noqa: F401  (the CSV stream's, named here too)
from .stream_layout import StreamLayout
from .stream_repair import _NotStreamable, _Repairer
from .stream_screen import ColumnScreen, _screen_of, _ScreenAcc

__all__ = ["BLOCK_SIZE", "ColumnScreen", "LogChunk", "LogScan", "iter_chunks", "scan_log"]

#: The first pass keeps the steps longer than this fraction of 1.5 provisional periods as
#: gap candidates (exact while the final threshold is above; else a second pass).
FLOOR_FRACTION = 0.8
#: The log's optional arrays, in :class:`~impactcli.types.RobotLog`'s order.
OPTIONAL = ("velocity", "current", "position_ref", "velocity_ref", "acceleration_ref",
            "torque_model", "torque_ext")


# --------------------------------------------------------------------------- results
@dataclass(frozen=True)
class LogChunk:
    """Consecutive samples of a log, as :class:`~impactcli.types.RobotLog` holds them.

    Attributes:
        start: index of the chunk's first sample in the whole log.
        t_ns: (n,) int64 sample times [ns] on the log's clock (absolute, as
            ``RobotLog.t_ns``), n ≥ 1.
        position, torque: (n, J) float64 [rad], [N·m].
        velocity, current, position_ref, velocity_ref, acceleration_ref, torque_model,
            torque_ext: (n, J) float64 as in the log, None when the log has none.
    """

    start: int
    t_ns: np.ndarray
    position: np.ndarray
    torque: np.ndarray
    velocity: np.ndarray | None = None
    current: np.ndarray | None = None
    position_ref: np.ndarray | None = None
    velocity_ref: np.ndarray | None = None
    acceleration_ref: np.ndarray | None = None
    torque_model: np.ndarray | None = None
    torque_ext: np.ndarray | None = None

    @property
    def n_samples(self) -> int:
        """Samples in the chunk."""
        return int(self.t_ns.shape[0])

    @property
    def stop(self) -> int:
        """Index after the chunk's last sample in the whole log."""
        return self.start + self.n_samples


@dataclass(frozen=True)
class LogScan:
    """The first pass over a log (:func:`scan_log`): what needs the whole log.

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
        streamed: whether :func:`iter_chunks` reads the file chunk by chunk (memory bounded)
            or slices the whole log read by the scan.
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
    streamed: bool
    options: dict[str, Any] = field(default_factory=dict, repr=False)
    _whole: RobotLog | None = field(default=None, repr=False, compare=False)
    _pass: _Pass | None = field(default=None, repr=False, compare=False)
    _copy: Any = field(default=None, repr=False, compare=False)  # a URL's local copy

    def close(self) -> None:
        """Delete the scan's cache of the repaired rows (:mod:`impactcli.io.stream_cache`;
        it is deleted anyway when the scan is garbage collected or at exit); later passes
        parse the file again."""
        if self._pass is not None and self._pass.cache is not None:
            self._pass.cache.close()
            self._pass.cache = None
        if self._copy is not None:
            self._copy.close()

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
        """The largest peak-to-peak of the log's torque columns [N·m] (the pipeline's
        reference for the screen)."""
        s = self.screens["torque"]
        return float(np.max(s.ptp)) if s.ptp.size else 0.0


# ------------------------------------------------------------------------ entry points
def scan_log(path: str | os.PathLike[str], **read_options: Any) -> LogScan:
    """The first pass over a log (:class:`LogScan`), warning about its repairs once.

    Args:
        path: the log, as for :func:`~impactcli.io.read_log`.
        read_options: :func:`read_log`'s keyword arguments (``channel_map``, ``robot``,
            ``topic``, ``reference_topic``, ``time_source``, ``torque_source``,
            ``time_unit``, ``repair_order``).
    Raises:
        LogFormatError, ChannelMapError: as :func:`read_log` would, for the same file.
    """
    _check_options(read_options)
    from .urls import is_url

    if is_url(path):
        return _scan_url(str(path), read_options)
    return _scan_local(path, read_options)


def _check_options(options: dict[str, Any]) -> None:
    known = {"channel_map", "robot", "topic", "reference_topic", "time_source",
             "torque_source", "time_unit", "repair_order"}
    unknown = set(options) - known
    if unknown:
        raise TypeError(f"unknown read options: {', '.join(sorted(unknown))}")


def _scan_local(path: str | os.PathLike[str], options: dict[str, Any]) -> LogScan:
    """:func:`scan_log` of a local file or folder: streamed when its format's layout says
    so, else read whole."""
    try:
        ctx = _layout(path, options)
        if ctx is not None:
            return _scan_stream(ctx, options)
    except _NotStreamable:
        pass
    return _scan_whole(path, options)


def _layout(path: str | os.PathLike[str], options: dict[str, Any]) -> StreamLayout | None:
    """The streaming layout of a local log (module docstring), None when it is read whole.
    Raises what :func:`read_log` raises for the path and options, or ``_NotStreamable``."""
    from . import open_log_options

    opts = {k: v for k, v in options.items() if k not in ("robot", "repair_order")}
    p, where, suffix, _folder, cmap = open_log_options(path, **opts)
    if suffix in (".csv", ".csv.gz"):
        if cmap is not None and cmap.format == "npz":
            return None
        from .stream_csv import csv_stream_layout

        return csv_stream_layout(p, cmap, options)
    if suffix == ".npz":
        from .stream_npz import npz_stream_layout

        return npz_stream_layout(p, where, cmap, options)
    from .stream_msgs import message_layout

    return message_layout(p, where, suffix, cmap, options)


def _scan_url(url: str, options: dict[str, Any]) -> LogScan:
    """:func:`scan_log` of a URL: the local copy (:func:`impactcli.io.urls.fetched`) is
    scanned and kept for the scan's lifetime (deleted by :meth:`LogScan.close`, the scan's
    garbage collection or the interpreter's exit); its ``source.path`` is the URL and its
    errors name it, as :func:`read_log` on the URL does."""
    import contextlib
    import dataclasses
    import sys
    import weakref

    from .urls import fetched, refuse_remote_folder

    refuse_remote_folder(url)
    stack = contextlib.ExitStack()
    lp = stack.enter_context(fetched(url, "log file"))
    try:
        scan = _scan_local(lp, options)
    except BaseException:
        stack.__exit__(*sys.exc_info())  # raises the error renamed after the URL
        raise
    if scan._whole is not None:
        stack.close()
    log = scan.log
    scan = dataclasses.replace(scan, log=dataclasses.replace(
        log, source=dataclasses.replace(log.source, path=url)), _copy=stack)
    weakref.finalize(scan, stack.close)
    return scan


def iter_chunks(path: str | os.PathLike[str], scan: LogScan, chunk_rows: int,
                **read_options: Any) -> Iterator[LogChunk]:
    """The log's samples in chunks of ``chunk_rows`` (the last one shorter).

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
    if scan._whole is not None:
        yield from _slices(scan._whole, chunk_rows)
        return
    assert scan._pass is not None
    yield from _stream_chunks(scan, chunk_rows)


def _slices(log: RobotLog, chunk_rows: int) -> Iterator[LogChunk]:
    """Chunks of a log in memory."""
    for a in range(0, log.n_samples, chunk_rows):
        b = min(a + chunk_rows, log.n_samples)
        opt = {s: None if getattr(log, s) is None else getattr(log, s)[a:b] for s in OPTIONAL}
        yield LogChunk(start=a, t_ns=log.t_ns[a:b], position=log.position[a:b],
                       torque=log.torque[a:b], **opt)


def _scan_whole(path: str | os.PathLike[str], read_options: dict[str, Any]) -> LogScan:
    """The scan of a log read whole (:func:`read_log`)."""
    from . import read_log
    from .inspect import time_gaps

    log = read_log(path, **read_options)
    screens = {s: _screen_of(getattr(log, s)) for s in ("torque", *CONTROLLER_CHANNELS)
               if getattr(log, s) is not None}
    idx, lengths = time_gaps(log)
    return LogScan(log=log.slice(0, 2), n_samples=log.n_samples, t0_ns=log.t0_ns,
                   t_last_ns=int(log.t_ns[-1]), clock=log.sample_clock, gaps=idx,
                   gap_lengths_s=lengths, torque_screen=screens["torque"].unusable(),
                   screens=screens, streamed=False, options=dict(read_options), _whole=log)


# ---------------------------------------------------------------------- one pass
@dataclass
class _Pass:
    """What the second pass needs from the first."""

    ctx: StreamLayout
    allbad: frozenset[int]
    keep: list[int]  # the joints kept (indices into the layout's joints)
    optional: tuple[str, ...]  # the optional arrays the log has
    t_shift: int  # subtracted from every stamp (a map's start_at_zero)
    n_samples: int
    cache: RowCache | None = None  # the repaired rows on disk (None: parse the file)


def _blocks(ctx: StreamLayout, rep: _Repairer) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The repaired rows of one pass over the file, in blocks ``(t, mat)``."""
    for raw in ctx.raw_batches():
        out = rep.push(raw)
        if out is not None:
            yield out
    out = rep.finish()
    if out is not None:
        yield out


def _arrays(ctx: StreamLayout, t: np.ndarray, mat: np.ndarray) -> dict[str, np.ndarray]:
    """The log's (n, J) arrays of every joint of the layout, from repaired rows."""
    from .assemble import assemble

    return assemble(ctx.plan, ctx.channels(t, mat))


def _scan_stream(ctx: StreamLayout, options: dict[str, Any]) -> LogScan:
    """:func:`scan_log` of a streamable log (its layout: :mod:`impactcli.io.stream_layout`)."""
    from concurrent.futures import ThreadPoolExecutor

    from . import log_sha256

    hasher = ThreadPoolExecutor(max_workers=1)
    digest = hasher.submit(log_sha256, ctx.path)
    hasher.shutdown(wait=False)
    rep = _Repairer(ctx, None)
    acc = _ScanAcc(ctx)
    cache = RowCache(len(ctx.names))
    try:
        for t, mat in _blocks(ctx, rep):
            acc.add(t, mat)
            cache.add(t, mat)
        cache.finish()
        ctx.check_pass()
        if rep.prev_t is None or rep.n_kept < 2:
            raise _NotStreamable("fewer than 2 rows")  # the whole-file reader's message
        err = rep.first_error() or acc.rate_error()
        if err is not None:
            raise LogFormatError(err)
        if isinstance(ctx.plan, LogFormatError):
            raise ctx.plan
        return acc.finish(rep, digest.result(), options, cache)
    except BaseException:
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
        self.screens = {s: _ScreenAcc(j) for s in ("torque", *CONTROLLER_CHANNELS)}
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
        """RobotLog's error for a non-finite value left in a kept joint's column (in a
        value scaled out of range; ``_as_matrix``); the signals ``gone`` are not in the log."""
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
        if self.rate.n_stamps < MAX_STATS_STEPS + 1:
            self.rate.add(t[: MAX_STATS_STEPS + 1 - self.rate.n_stamps])
        self.hist.add(t)
        period = self.hist.period_ns()
        self.floor = FLOOR_FRACTION * GAP_FACTOR * period if period > 0 else float("-inf")
        self.gaps.add(t, self.floor)
        self.n += t.size
        if isinstance(self.ctx.plan, LogFormatError):
            return
        arrays = _arrays(self.ctx, t, mat)
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
        """The time-unit check on the first steps (:func:`check_time_rate`)."""
        return self.ctx.rate_error(self.rate.clock().rate_hz)

    def finish(self, rep: _Repairer, sha256: str, options: dict[str, Any],
               cache: RowCache) -> LogScan:
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
        shift = int(self.head_t[0]) if ctx.start_at_zero else 0
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
        self.gaps.add(np.zeros(0, dtype=np.int64), self.floor, last=True)
        if not self.gaps.exact_for(clock):  # the rate moved: a second pass at the threshold
            self.gaps = _gap_pass(ctx, allbad, clock, cache)
        idx, lengths = self.gaps.gaps(clock)
        screens = {s: self.screens[s].result().select(keep) for s in self.screens
                   if getattr(log, s) is not None}
        optional = tuple(s for s in OPTIONAL if getattr(log, s) is not None)
        return LogScan(log=log, n_samples=self.n, t0_ns=int(self.head_t[0]) - shift,
                       t_last_ns=int(self.hist.last or 0) - shift, clock=clock, gaps=idx,
                       gap_lengths_s=lengths, torque_screen=screens["torque"].unusable(),
                       screens=screens, streamed=True, options=dict(options),
                       _pass=_Pass(ctx, allbad, keep, optional, shift, self.n,
                                   cache if cache.usable else None))


def _nan_where_empty(a: np.ndarray, signal: str, ctx: StreamLayout,
                     allbad: frozenset[int]) -> np.ndarray:
    """``a`` with NaN in the columns of joints whose column holds no finite value (the
    whole-file reader sets such a column to NaN; a ±inf would survive in the first rows)."""
    names = ctx.names
    out = np.array(a, dtype=np.float64)
    for (sig, j), key in ctx.keys.items():
        if names.index(key) in allbad and (sig == signal or (
                signal == "torque" and sig == ctx.plan.torque_source)):
            out[:, j] = np.nan
    return out


def _gap_pass(ctx: StreamLayout, allbad: frozenset[int], clock: SampleClock,
              cache: RowCache | None = None) -> GapStream:
    """Gap candidates at the final threshold: a second pass over the times (the scan's
    cache, else the file)."""
    gs = GapStream()
    if cache is not None and cache.usable:
        times: Iterator[tuple[np.ndarray, Any]] = cache.blocks(1 << 20, times_only=True)
    else:
        times = _blocks(ctx, _Repairer(ctx, allbad))
    for t, _ in times:
        gs.add(t, clock.gap_threshold_s * 1e9)
    gs.add(np.zeros(0, dtype=np.int64), clock.gap_threshold_s * 1e9, last=True)
    return gs


def _stream_chunks(scan: LogScan, chunk_rows: int) -> Iterator[LogChunk]:
    """A pass after the scan: chunks of ``chunk_rows`` repaired samples, from the scan's
    cache of the repaired rows (:mod:`impactcli.io.stream_cache`), else from the file."""
    from . import stream_cache

    ps = scan._pass
    assert ps is not None
    if ps.cache is not None and ps.cache.usable:
        yield from stream_cache.chunks(ps, ps.cache, chunk_rows)
        return
    rep = _Repairer(ps.ctx, ps.allbad)
    pending: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []
    size = 0
    start = 0
    try:
        for t, mat in _blocks(ps.ctx, rep):
            arrays = _arrays(ps.ctx, t, mat)
            arrays = {s: arrays[s][:, ps.keep] for s in ("position", "torque", *ps.optional)}
            pending.append((t - ps.t_shift if ps.t_shift else t, arrays))
            size += t.size
            while size >= chunk_rows:
                chunk, pending, size = take(pending, chunk_rows, start)
                start += chunk_rows
                yield chunk
    except _NotStreamable as err:
        raise LogFormatError(f"{ps.ctx.where}: changed since it was scanned ({err})"
                             ) from None
    last: LogChunk | None = None
    if size:
        last, pending, size = take(pending, size, start)
        start += last.n_samples
    if rep.first_error() is not None or start != ps.n_samples:
        raise LogFormatError(f"{ps.ctx.where}: changed since it was scanned")
    if last is not None:
        yield last

