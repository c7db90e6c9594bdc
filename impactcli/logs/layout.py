"""What a format gives the one scan of :mod:`impactcli.logs.scan`: a :class:`StreamLayout`,
and what the scan gives back: :class:`LogChunk` s, through a :class:`ScanPass`.

A format's layout says where the log is and how messages name it, which columns its rows
have (``names``, in the matrix's order, and the column of each ``(signal, joint)``), how a
run of repaired rows becomes the log's arrays (:meth:`StreamLayout.channels` and the
:class:`~impactcli.logs.channels.LogPlan`), and gives the file's rows in blocks
(:meth:`StreamLayout.raw_batches`: :class:`RawRows`, before the repairs of
:mod:`impactcli.logs.repair`). What the format finds wrong while reading (a cell that is
not a number, a time that is not finite) it records as :attr:`StreamLayout.read_error`:
the scan raises it before the repairs' errors, as the whole file would be refused.

Layouts: :class:`~impactcli.logs.csv.csv_read.CsvReaderLayout` (CSV),
:class:`~impactcli.logs.npz.NpzLayout` (``.npz``),
:class:`~impactcli.logs.messages.message_read.MessageLayout` (MCAP and ROS bags).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import LogFormatError
from ..sample_channels import REQUIRED_CHANNELS, Channels
from .channels import JointChannels


@dataclass
class RawRows:
    """One block of rows as read: rows ``row0`` … ``row0 + n − 1`` (the repair's numbering,
    which :meth:`StreamLayout.label` turns into text)."""

    row0: int
    t: np.ndarray  # (n,) int64 [ns]
    mat: np.ndarray  # (n, C) float64 the columns' values, as logged


class StreamLayout:
    """How a format's rows become the log (module docstring).

    Attributes:
        path: the local file or folder (its sha256 is the log's).
        where: the log as messages name it.
        fmt, time_source: ``LogSource.format`` and ``time_source``.
        joints: the J joints of the rows (before joints without data are left out).
        names: the C column keys, in the rows' order (as the repairs name them).
        keys: ``(signal, joint)`` → its column key.
        droppable: the keys of columns that may hold no finite value (passed on as NaN).
        plan: the :class:`~impactcli.logs.channels.LogPlan`, or the LogFormatError planning
            raised (raised by the scan after the repairs' errors, as the whole log would be).
        repair_order: ``--repair-order``.
        time_name: the time as the order error names it.
        start_at_zero: the map's ``start_at_zero`` (times shifted to start at 0).
        read_error: the first error found reading the rows (raised by the scan first).
    """

    path: Path
    where: str
    fmt: str
    time_source: str = "column"
    joints: tuple[str, ...]
    names: list[str]
    keys: dict[tuple[str, int], str]
    droppable: set[str]
    plan: Any
    repair_order: bool = False
    time_name: str = "time"
    start_at_zero: bool = False
    read_error: LogFormatError | None = None

    def label(self, i: int) -> str:
        """Row ``i`` of the repairs' numbering as messages name it."""
        return f"sample {i}"

    def raw_batches(self) -> Iterator[RawRows]:
        """One pass over the file's rows, in blocks."""
        raise NotImplementedError

    def channels(self, t: np.ndarray, mat: np.ndarray) -> JointChannels:
        """Repaired rows ``t`` (n,), ``mat`` (n, C) as the reader's channels."""
        raise NotImplementedError

    def rate_error(self, sample_rate_hz: float, duration_s: float | None = None) -> str | None:
        """The time-unit check on the first steps' rate (None: fine, or not checked);
        ``duration_s``: the log's duration as read [s], when known."""
        return None

    def pass_again(self) -> bool:
        """After the scan's first pass: whether the rows must be read again (a CSV whose
        time or value columns the first pass read otherwise than the whole file must be
        read: the second pass reads them as decided)."""
        return False

    def pre_repairs(self) -> list[str]:
        """Repairs the reader makes before the repair policy's (given first)."""
        return []

    def cut_short(self) -> bool:
        """Whether the file ends before its recording did (read up to the cut)."""
        return False

    def release(self) -> None:
        """The scan keeps a cache of the rows: what the layout holds to read them again
        (a spill) may go."""

    def close(self) -> None:
        """Release what the layout holds (a spill of the scan's)."""


def rate_times(row0: int, n: int, sample_rate_hz: float) -> np.ndarray:
    """The times [ns] of rows ``row0`` … ``row0 + n − 1`` of a log read with ``--rate``:
    row i at round(i × 1e9 / rate) ns (the same for any blocks)."""
    rows = row0 + np.arange(n, dtype=np.float64)
    return np.round(rows * (1e9 / sample_rate_hz)).astype(np.int64)


def rate_note(where: str, sample_rate_hz: float) -> str:
    """The log's provenance when read with ``--rate`` (warned, and recorded in its repairs):
    its times are the rate's, not logged."""
    return (f"{where}: sample i is at i / {sample_rate_hz:g} Hz (--rate {sample_rate_hz:g}), "
            "not at a logged time, so gaps and jitter cannot be seen")


def plan_of(layout: StreamLayout, options: dict[str, Any]) -> Any:
    """The layout's :class:`~impactcli.logs.channels.LogPlan` from its channels without rows
    and the read ``options`` (``robot``, ``torque_source``, ``position_unit``), or the
    LogFormatError planning raises."""
    from .channels import plan_log

    head = layout.channels(np.zeros(0, dtype=np.int64), np.zeros((0, len(layout.names))))
    try:
        return plan_log(head, path=layout.where, robot=options.get("robot"),
                        torque_source=options.get("torque_source"),
                        position_unit=options.get("position_unit"))
    except LogFormatError as err:
        return err


class MappedLayout(StreamLayout):
    """A layout whose columns a channel map names (CSV, ``.npz``): scale and offset by
    :func:`~impactcli.logs.channels.channels_from_columns`."""

    cmap: Any
    ignored: list[str]
    sample_rate_hz: float | None  # --rate: no time column, sample i at i / sample_rate_hz

    def pre_repairs(self) -> list[str]:
        return [] if self.sample_rate_hz is None else [rate_note(self.where, self.sample_rate_hz)]

    def channels(self, t: np.ndarray, mat: np.ndarray) -> JointChannels:
        from .channels import channels_from_columns

        cols = {k: mat[:, i] for i, k in enumerate(self.names)}
        return channels_from_columns(self.cmap, t, cols, self.keys, self.ignored, [])


# --------------------------------------------------------------------------- chunks

@dataclass(frozen=True)
class LogChunk(Channels):
    """Consecutive samples of a log, as :class:`~impactcli.types.RobotLog` holds them: the
    channels of :class:`~impactcli.sample_channels.Channels` (n ≥ 1 samples, as in the log, None
    when the log has none) and these.

    Attributes:
        start: index of the chunk's first sample in the whole log.
        t_ns: (n,) int64 sample times [ns] on the log's clock (absolute, as
            ``RobotLog.t_ns``).
    """

    start: int
    t_ns: np.ndarray

    @property
    def n_samples(self) -> int:
        """Samples in the chunk."""
        return int(self.t_ns.shape[0])

    @property
    def stop(self) -> int:
        """Index after the chunk's last sample in the whole log."""
        return self.start + self.n_samples


@dataclass
class ScanPass:
    """What the passes after the scan need from it: the layout, the columns without any
    finite value (``allbad``, set to NaN), the joints and arrays kept, the clock shift
    (a map's ``start_at_zero``), the rows kept by ``--repair-order``, and the scan's
    cache of its repaired rows (None: the passes read the layout's rows again)."""

    layout: StreamLayout
    allbad: frozenset[int]
    keep: list[int]  # the joints kept (indices into the layout's joints)
    optional: tuple[str, ...]  # the optional arrays the log has
    t_shift: int  # subtracted from every stamp (a map's start_at_zero)
    n_samples: int
    order_keep: np.ndarray | None = None  # --repair-order: raw rows kept (bool), or None
    # the scan's cache of its rows (a stream_cache.RowCache), None: the layout's rows are
    # read again
    cache: Any = field(default=None)
    order_repair: str | None = None  # --repair-order: the repair's message
    wraps: tuple[Any, ...] = ()  # whole turns removed from the positions (logs.defects.Wrap)
    ref_wraps: tuple[Any, ...] = ()  # ... and from the references

    def arrays(self, t: np.ndarray, mat: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Repaired rows as the log's times and (n, J) arrays of the kept joints."""
        from .channels import assemble

        arrays = assemble(self.layout.plan, self.layout.channels(t, mat))
        every = self.keep == list(range(len(self.layout.joints)))
        out = {s: arrays[s] if every else arrays[s][:, self.keep]
               for s in (*REQUIRED_CHANNELS, *self.optional)}
        return (t - self.t_shift if self.t_shift else t), out


def take(pending: list[tuple[np.ndarray, dict[str, np.ndarray]]], rows: int,
         start: int) -> tuple[LogChunk, list[tuple[np.ndarray, dict[str, np.ndarray]]], int]:
    """The first ``rows`` samples of the pending blocks as a chunk, and what is left (with
    its size)."""
    parts_t: list[np.ndarray] = []
    parts: list[dict[str, np.ndarray]] = []
    left = rows
    rest: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []
    for i, (t, arrays) in enumerate(pending):
        if left == 0:
            rest = pending[i:]
            break
        if t.size <= left:
            parts_t.append(t)
            parts.append(arrays)
            left -= t.size
        else:
            parts_t.append(t[:left])
            parts.append({s: a[:left] for s, a in arrays.items()})
            rest = [(t[left:], {s: a[left:] for s, a in arrays.items()}), *pending[i + 1:]]
            left = 0
            break
    t_all = parts_t[0] if len(parts_t) == 1 else np.concatenate(parts_t)
    joined = {s: np.ascontiguousarray(parts[0][s] if len(parts) == 1 else
                                      np.concatenate([p[s] for p in parts]))
              for s in parts[0]}
    size = sum(t.size for t, _ in rest)
    chunk = LogChunk(start=start, t_ns=np.ascontiguousarray(t_all),
                     position=joined.pop("position"), torque=joined.pop("torque"), **joined)
    return chunk, rest, size


def chunked(blocks: Iterator[tuple[np.ndarray, dict[str, np.ndarray]]],
            chunk_rows: int) -> Iterator[LogChunk]:
    """Blocks of the log's samples ``(t, arrays)`` as chunks of ``chunk_rows`` (the last
    one shorter)."""
    pending: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []
    size = 0
    start = 0
    for t, arrays in blocks:
        pending.append((t, arrays))
        size += t.size
        while size >= chunk_rows:
            chunk, pending, size = take(pending, chunk_rows, start)
            start += chunk_rows
            yield chunk
    if size:
        chunk, pending, size = take(pending, size, start)
        yield chunk
