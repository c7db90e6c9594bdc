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

Streamed (memory bounded, whatever the log's length: the text is parsed on threads in
ranges of about :data:`BLOCK_SIZE` = 1 MiB, at most 4 ahead of the scan
(:mod:`impactcli.io.stream_parse`), one range's arrays are converted at a time, plus the
chunk being put together): a local ``.csv`` or ``.csv.gz`` — canonical, or through a CSV
channel map — with a ``.`` decimal point, whose time column holds plain decimal numbers
(``12.345``, ``1714567890.001``, ``1234``) and whose value cells are numbers or empty. It
is parsed by pyarrow (range by range, with the whole-file reader's options) and converted
batch by batch by the whole-file reader's own steps (exact decimal time → int64 ns, the
map's scale and offset, current → torque), and repaired across batch boundaries as in the
whole file (:mod:`impactcli.io.repair`): exact duplicate rows dropped, runs of at most 5
non-finite values interpolated (rows are held back until a run closes), values beyond 1e12
and rows out of time order refused, the 20 Hz – 100 kHz rate check. The scan keeps,
besides constants per column, the candidate gaps (steps longer than 1.2 provisional
periods, with their windows; a second pass over the file if the period then drifts below).
Only the scan parses the file (all the channels: the repairs and the screen need their
values); it keeps the rows it repaired in a binary temporary file that :func:`iter_chunks`
reads instead (:mod:`impactcli.io.stream_cache`: a copy instead of a parse; the same
arrays bit for bit), until :meth:`LogScan.close`, the scan's garbage collection or the
interpreter's exit deletes it. Without the cache (a full disk) each pass parses the file.

Not streamed (``LogScan.streamed`` False; the scan reads the whole log with
:func:`read_log` and the chunks are slices of it, memory NOT bounded): every other format
(``.npz``, MCAP, bags, rosbag2 folders), URLs, and CSV variants (a UTF-8 byte-order mark,
a decimal comma, ISO-8601 or non-decimal time text, empty or non-numeric time cells, a value
column that is not numeric), ``--repair-order`` on a file with rows out of time order, and
any file the whole-file reader refuses for a reason the stream does not check itself (the
whole-file reader then raises its own error).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
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
from .stream_repair import _NotStreamable, _Repairer
from .stream_screen import ColumnScreen, _screen_of, _ScreenAcc

__all__ = ["BLOCK_SIZE", "ColumnScreen", "LogChunk", "LogScan", "iter_chunks", "scan_log"]

#: Bytes of CSV text parsed at a time (one range, one record batch: a 7-joint log's row is
#: ~430 bytes, ~2400 rows a range; :mod:`impactcli.io.stream_parse` parses up to 4 ahead).
BLOCK_SIZE = 1 << 20
#: The first pass keeps the steps longer than this fraction of 1.5 provisional periods as
#: gap candidates (exact while the final threshold is above; else a second pass).
FLOOR_FRACTION = 0.8
#: The log's optional arrays, in :class:`~impactcli.types.RobotLog`'s order.
OPTIONAL = ("velocity", "current", "position_ref", "velocity_ref", "acceleration_ref",
            "torque_model", "torque_ext")
#: The time text streamed: plain decimal numbers.
_PLAIN = r"^-?\d+(\.\d+)?$"


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

    def close(self) -> None:
        """Delete the scan's cache of the repaired rows (:mod:`impactcli.io.stream_cache`;
        it is deleted anyway when the scan is garbage collected or at exit); later passes
        parse the file again."""
        if self._pass is not None and self._pass.cache is not None:
            self._pass.cache.close()
            self._pass.cache = None

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
    ctx = _context(path, read_options)
    if ctx is not None:
        try:
            return _scan_stream(ctx, read_options)
        except _NotStreamable:
            pass
    return _scan_whole(path, read_options)


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


# --------------------------------------------------------------------- the CSV context
@dataclass
class _Context:
    """A streamable CSV and how its columns become the log (from its first lines)."""

    lay: Any  # CsvLayout
    options: dict[str, Any]
    names: list[str]  # pyarrow's column names
    keys: dict[tuple[str, int], str]  # (signal, joint) → column key (as repair names it)
    key_cols: dict[str, str]  # column key → column name in the file
    droppable: set[str]
    ignored: list[str]
    unit_ns: int
    offset_ns: int
    tcol: str  # the time column, as messages name it
    plan: Any  # LogPlan, or the LogFormatError the plan raised
    repair_order: bool


def _context(path: str | os.PathLike[str], options: dict[str, Any]) -> _Context | None:
    """The streaming context of a local canonical or mapped CSV, None when the file needs
    the whole-file reader (module docstring). Raises what :func:`read_log` raises for the
    path and options."""
    from . import open_log_options
    from .assemble import plan_log
    from .channel_map import TIME_UNITS
    from .csv import channels_from_columns, csv_layout
    from .repair import DROPPABLE_SIGNALS
    from .urls import is_url

    known = {"channel_map", "robot", "topic", "reference_topic", "time_source",
             "torque_source", "time_unit", "repair_order"}
    unknown = set(options) - known
    if unknown:
        raise TypeError(f"unknown read options: {', '.join(sorted(unknown))}")
    if is_url(path):
        return None
    opts = {k: v for k, v in options.items() if k not in ("robot", "repair_order")}
    p, where, suffix, _folder, cmap = open_log_options(path, **opts)
    if suffix not in (".csv", ".csv.gz") or (cmap is not None and cmap.format == "npz"):
        return None
    try:
        lay = csv_layout(p, cmap, time_unit=options.get("time_unit"))
        names = _probe_names(lay)
    except (LogFormatError, _NotStreamable, UnicodeDecodeError, ValueError):
        return None  # the whole-file reader says what is wrong
    if lay.decimal != "." or _has_bom(p) or len(set(names)) != len(names):
        return None
    if not lay.used <= set(names) or lay.tname in lay.columns.values():
        return None
    keys: dict[tuple[str, int], str] = {}
    key_cols: dict[str, str] = {}
    for (sig, j), col in lay.columns.items():
        key = col if lay.header else lay.disp(col)
        keys[(sig, j)] = key
        key_cols.setdefault(key, col)
    droppable = {k for (sig, _), k in keys.items() if sig in DROPPABLE_SIGNALS}
    ignored = (lay.ignored_extra if lay.fmt == "csv"
               else [lay.disp(c) for c in names if c not in lay.used])
    tspec = lay.tspec
    unit_ns = TIME_UNITS[tspec.unit]
    head = channels_from_columns(lay.cmap, np.zeros(0, dtype=np.int64),
                                 {k: np.zeros(0) for k in key_cols}, keys, ignored, [])
    plan: Any
    try:
        plan = plan_log(head, path=where, robot=options.get("robot"),
                        torque_source=options.get("torque_source"))
    except LogFormatError as err:
        plan = err
    tname = lay.tname
    return _Context(
        lay=lay, options=dict(options), names=names, keys=keys, key_cols=key_cols,
        droppable=droppable, ignored=ignored, unit_ns=unit_ns,
        offset_ns=round(tspec.offset * unit_ns) if tspec.offset else 0,
        tcol=f"column {lay.disp(tname)!r}" if lay.header else lay.disp(tname),
        plan=plan, repair_order=bool(options.get("repair_order", False)))


def _has_bom(path: Path) -> bool:
    import gzip

    opener: Any = gzip.open if path.name.lower().endswith(".gz") else open
    with opener(path, "rb") as f:
        return bytes(f.read(3)) == b"\xef\xbb\xbf"


def _probe_names(lay: Any) -> list[str]:
    """pyarrow's column names of the file (those the whole-file reader uses)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from .csv import csv_read_options

    ropts, popts = csv_read_options(lay, 1 << 20)
    try:
        reader = pacsv.open_csv(lay.path, read_options=ropts, parse_options=popts,
                                convert_options=pacsv.ConvertOptions(
                                    column_types={}, include_columns=[]))
        names = list(reader.schema.names)
        reader.close()
    except (pa.ArrowInvalid, OSError, EOFError, UnicodeDecodeError) as err:
        raise _NotStreamable(str(err)) from err
    return names


# ------------------------------------------------------------------------ raw batches
@dataclass
class _Raw:
    """One record batch as read: data rows ``row0`` … ``row0 + n − 1``."""

    row0: int
    t: np.ndarray  # (n,) int64 [ns], exact decimal conversion, offset applied
    mat: np.ndarray  # (n, C) float64 the used columns' values, as logged


@dataclass
class _TimeStats:
    """Whole-column facts the whole-file reader decides the time conversion by."""

    all_int: bool = True
    max_abs: float = 0.0
    disagree: bool = False  # the float conversion differs from the exact one somewhere
    text_fails: bool = False  # the exact decimal conversion of integers fails somewhere


def _raw_batches(ctx: _Context, ts: _TimeStats) -> Iterator[_Raw]:
    """The file's record batches, time converted exactly and values as float64 (the text
    parsed on threads ahead of the caller: :mod:`impactcli.io.stream_parse`)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from .stream_parse import parsed_batches

    lay = ctx.lay
    cols = list(ctx.key_cols.values())
    types = {lay.tname: pa.string(), **{c: pa.float64() for c in cols}}
    copts = pacsv.ConvertOptions(column_types=types, include_columns=[lay.tname, *cols],
                                 decimal_point=".")
    row0 = 0
    try:
        for batch in parsed_batches(lay, ctx.names, copts, BLOCK_SIZE):
            n = batch.num_rows
            if n == 0:
                continue
            t = _time_ns(batch.column(lay.tname), ctx, ts)
            mat = np.empty((n, len(cols)))
            for i, c in enumerate(cols):
                mat[:, i] = batch.column(c).to_numpy(zero_copy_only=False)
            yield _Raw(row0, t, mat)
            row0 += n
    except (pa.ArrowInvalid, OSError, EOFError, UnicodeDecodeError) as err:
        raise _NotStreamable(str(err)) from err


def _time_ns(text: Any, ctx: _Context, ts: _TimeStats) -> np.ndarray:
    """A batch's time text → (n,) int64 ns as :func:`read_csv_channels` converts it
    (exact decimal conversion; the float conversion, which the whole-file reader uses for
    a column below 1e6 s with a decimal point, is checked to agree)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if text.null_count or not pc.all(pc.match_substring_regex(text, _PLAIN)).as_py():
        raise _NotStreamable("time text that is not plain decimal")
    tf = pc.cast(text, pa.float64()).to_numpy()
    as_text = _decimal_ns(text, ctx.unit_ns, tf)
    if pc.any(pc.match_substring(text, ".")).as_py():
        ts.all_int = False
        if as_text is None:
            raise _NotStreamable("time beyond the exact conversion")
        exact = as_text
    else:  # integers: the whole-file reader's integer path, while the column has no '.'
        with np.errstate(over="ignore"):
            if np.any(np.abs(tf) * ctx.unit_ns >= float(2**63 - 1)):
                raise _NotStreamable("time beyond the clock's range")
        try:
            exact = pc.cast(text, pa.int64()).to_numpy() * ctx.unit_ns
        except (pa.ArrowInvalid, OverflowError) as err:
            raise _NotStreamable(str(err)) from err
        if as_text is None or not np.array_equal(as_text, exact):
            ts.text_fails = True
    ts.max_abs = max(ts.max_abs, float(np.max(np.abs(tf))))
    if not ts.disagree:
        ts.disagree = not np.array_equal(np.round(tf * ctx.unit_ns).astype(np.int64), exact)
    return exact + ctx.offset_ns if ctx.offset_ns else exact


def _decimal_ns(text: Any, unit_ns: int, tf: np.ndarray) -> np.ndarray | None:
    """``decimal_text_to_ns(text, unit_ns)`` of plain decimal text; for seconds with at most
    9 decimals (well within its range) by pyarrow's exact decimal parse, 20× faster.

    Args:
        text: (n,) pyarrow strings matching ``^-?\\d+(\\.\\d+)?$``.  unit_ns: the unit [ns].
        tf: (n,) float64 the same values (to see the range).
    """
    import pyarrow as pa
    import pyarrow.compute as pc

    from .csv import decimal_text_to_ns

    if unit_ns != 10**9 or not float(np.max(np.abs(tf))) < 9e9:
        return decimal_text_to_ns(text, unit_ns)
    try:
        d = pc.cast(text, pa.decimal128(38, 9))  # unscaled value: ns, exactly
    except pa.ArrowInvalid:  # more than 9 decimals: truncated by decimal_text_to_ns
        return decimal_text_to_ns(text, unit_ns)
    words = np.frombuffer(d.buffers()[1], dtype=np.int64).reshape(-1, 2)
    return words[d.offset: d.offset + len(d), 0].copy()


def _fast_time(ctx: _Context, ts: _TimeStats) -> bool:
    """Whether the whole-file reader converts this time column as floats (a decimal point
    somewhere, all below 1e6 s)."""
    return not ts.all_int and ts.max_abs * ctx.unit_ns / 1e9 < 1e6


# ---------------------------------------------------------------------- one pass
@dataclass
class _Pass:
    """What the second pass needs from the first."""

    ctx: _Context
    allbad: frozenset[int]
    keep: list[int]  # the joints kept (indices into the layout's joints)
    optional: tuple[str, ...]  # the optional arrays the log has
    t_shift: int  # subtracted from every stamp (a map's start_at_zero)
    n_samples: int
    cache: RowCache | None = None  # the repaired rows on disk (None: parse the file)


def _blocks(ctx: _Context, allbad: frozenset[int] | None, ts: _TimeStats,
            rep: _Repairer) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The repaired rows of one pass over the file, in blocks ``(t, mat)``."""
    for raw in _raw_batches(ctx, ts):
        out = rep.push(raw)
        if out is not None:
            yield out
    out = rep.finish()
    if out is not None:
        yield out


def _arrays(ctx: _Context, t: np.ndarray, mat: np.ndarray) -> dict[str, np.ndarray]:
    """The log's (n, J) arrays of every joint of the layout, from repaired rows."""
    from .assemble import assemble
    from .csv import channels_from_columns

    cols = {k: mat[:, i] for i, k in enumerate(ctx.key_cols)}
    ch = channels_from_columns(ctx.lay.cmap, t, cols, ctx.keys, ctx.ignored, [])
    return assemble(ctx.plan, ch)


def _scan_stream(ctx: _Context, options: dict[str, Any]) -> LogScan:
    """:func:`scan_log` of a streamable CSV."""
    from concurrent.futures import ThreadPoolExecutor

    from .._fs import sha256_file

    hasher = ThreadPoolExecutor(max_workers=1)
    digest = hasher.submit(sha256_file, ctx.lay.path)
    hasher.shutdown(wait=False)
    ts = _TimeStats()
    rep = _Repairer(ctx, None)
    acc = _ScanAcc(ctx)
    cache = RowCache(len(ctx.key_cols))
    try:
        for t, mat in _blocks(ctx, None, ts, rep):
            acc.add(t, mat)
            cache.add(t, mat)
        cache.finish()
        if not ts.all_int and (ts.disagree if _fast_time(ctx, ts) else ts.text_fails):
            raise _NotStreamable("the whole-file reader converts this time column otherwise")
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

    def __init__(self, ctx: _Context) -> None:
        self.ctx = ctx
        self.hist = StepHistogram()
        self.rate = StepHistogram()  # the first MAX_STATS_STEPS steps: the unit check
        self.gaps = GapStream()
        self.n = 0
        self.head_t = np.zeros(0, dtype=np.int64)
        self.head: dict[str, np.ndarray] = {}
        j = len(ctx.lay.cmap.joints)
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
            raise LogFormatError(f"{self.ctx.lay.where}: {s} is not finite at sample {row} "
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
        from .repair import rate_message

        lay = self.ctx.lay
        unit = lay.tspec.unit
        return rate_message(self.rate.clock().rate_hz, lay.where, self.ctx.tcol, unit)

    def finish(self, rep: _Repairer, sha256: str, options: dict[str, Any],
               cache: RowCache) -> LogScan:
        """The scan: drop the joints without data, warn, the header, clock, gaps, screen."""
        from .assemble import (
            drop_empty_signals,
            drop_message,
            empty_joint_reasons,
            warn_dropped,
        )

        ctx, plan, lay = self.ctx, self.ctx.plan, self.ctx.lay
        joints = lay.cmap.joints
        dropped = empty_joint_reasons(joints, self.pos_finite, self.torque_finite,
                                      plan.torque_source)
        if len(dropped) == len(joints):
            raise LogFormatError(drop_message(lay.where, dropped, plan.torque_source))
        repairs = rep.repairs()
        for msg in repairs:
            warnings.warn(msg, ImpactWarning, stacklevel=3)
        warn_dropped(lay.where, dropped)
        out = {j for j, _ in dropped}
        keep = [k for k, j in enumerate(joints) if j not in out]
        kept = tuple(joints[k] for k in keep)
        gone, ignored, msgs = drop_empty_signals(
            lay.where, kept, {s: self.opt_finite[s][keep] for s in plan.optional})
        allbad = frozenset(int(c) for c in np.flatnonzero(rep.empty))
        shift = int(self.head_t[0]) if lay.tspec.start_at_zero else 0
        source = LogSource(path=lay.where, sha256=sha256, format=lay.fmt,
                           torque_source=plan.torque_source, time_source="column",
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


def _nan_where_empty(a: np.ndarray, signal: str, ctx: _Context,
                     allbad: frozenset[int]) -> np.ndarray:
    """``a`` with NaN in the columns of joints whose column holds no finite value (the
    whole-file reader sets such a column to NaN; a ±inf would survive in the first rows)."""
    names = list(ctx.key_cols)
    out = np.array(a, dtype=np.float64)
    for (sig, j), key in ctx.keys.items():
        if names.index(key) in allbad and (sig == signal or (
                signal == "torque" and sig == ctx.plan.torque_source)):
            out[:, j] = np.nan
    return out


def _gap_pass(ctx: _Context, allbad: frozenset[int], clock: SampleClock,
              cache: RowCache | None = None) -> GapStream:
    """Gap candidates at the final threshold: a second pass over the times (the scan's
    cache, else the file)."""
    gs = GapStream()
    if cache is not None and cache.usable:
        times: Iterator[tuple[np.ndarray, Any]] = cache.blocks(1 << 20, times_only=True)
    else:
        times = _blocks(ctx, allbad, _TimeStats(), _Repairer(ctx, allbad))
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
        for t, mat in _blocks(ps.ctx, ps.allbad, _TimeStats(), rep):
            arrays = _arrays(ps.ctx, t, mat)
            arrays = {s: arrays[s][:, ps.keep] for s in ("position", "torque", *ps.optional)}
            pending.append((t - ps.t_shift if ps.t_shift else t, arrays))
            size += t.size
            while size >= chunk_rows:
                chunk, pending, size = take(pending, chunk_rows, start)
                start += chunk_rows
                yield chunk
    except _NotStreamable as err:
        raise LogFormatError(f"{ps.ctx.lay.where}: changed since it was scanned ({err})"
                             ) from None
    last: LogChunk | None = None
    if size:
        last, pending, size = take(pending, size, start)
        start += last.n_samples
    if rep.first_error() is not None or start != ps.n_samples:
        raise LogFormatError(f"{ps.ctx.lay.where}: changed since it was scanned")
    if last is not None:
        yield last

