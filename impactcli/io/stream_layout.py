"""What :mod:`impactcli.io.stream` needs of a streamed format: a :class:`StreamLayout`.

One scan, one repair and one cache for every format (:mod:`impactcli.io.stream`): a
format's layout says where the log is and how messages name it, which columns its rows
have (``names``, in the matrix's order, and the column of each ``(signal, joint)``), how a
run of repaired rows becomes the log's arrays (:meth:`StreamLayout.channels` and the
:class:`~impactcli.io.assemble.LogPlan`), and gives the file's rows as they are read, in
blocks (:meth:`StreamLayout.raw_batches`: times [ns] and values, before the repairs of
:mod:`impactcli.io.repair`, which :class:`~impactcli.io.stream_repair._Repairer` makes).

Layouts: :class:`~impactcli.io.stream_csv.CsvStreamLayout` (CSV),
:class:`~impactcli.io.stream_npz.NpzStreamLayout` (``.npz``),
:class:`~impactcli.io.stream_msgs.MessageLayout` (MCAP and ROS bags).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import LogFormatError
from .assemble import JointChannels


@dataclass
class _Raw:
    """One block of rows as read: rows ``row0`` … ``row0 + n − 1`` (the repair's numbering,
    which :meth:`StreamLayout.label` turns into text)."""

    row0: int
    t: np.ndarray  # (n,) int64 [ns]
    mat: np.ndarray  # (n, C) float64 the columns' values, as logged


class StreamLayout:
    """How a streamed format's rows become the log (module docstring).

    Attributes:
        path: the local file or folder (its sha256 is the log's).
        where: the log as messages name it.
        fmt, time_source: ``LogSource.format`` and ``time_source``.
        joints: the J joints of the rows (before joints without data are left out).
        names: the C column keys, in the rows' order (as the repairs name them).
        keys: ``(signal, joint)`` → its column key.
        droppable: the keys of columns that may hold no finite value (repair's keep_empty).
        plan: the :class:`~impactcli.io.assemble.LogPlan`, or the LogFormatError planning
            raised (raised by the scan after the repairs' errors, as the whole reader does).
        repair_order: ``--repair-order`` (rows out of order: not streamed).
        time_name: the time as the order error names it.
        start_at_zero: the map's ``start_at_zero`` (times shifted to start at 0).
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

    def label(self, i: int) -> str:
        """Row ``i`` of the repairs' numbering as messages name it."""
        return f"sample {i}"

    def raw_batches(self) -> Iterator[_Raw]:
        """One pass over the file's rows, in blocks."""
        raise NotImplementedError

    def channels(self, t: np.ndarray, mat: np.ndarray) -> JointChannels:
        """Repaired rows ``t`` (n,), ``mat`` (n, C) as the reader's channels."""
        raise NotImplementedError

    def rate_error(self, rate_hz: float) -> str | None:
        """The time-unit check on the first steps' rate (None: fine, or not checked)."""
        return None

    def check_pass(self) -> None:
        """After the scan's pass: raise ``_NotStreamable`` when the whole-file reader would
        have read the rows otherwise (CSV time conversion)."""

    def pre_repairs(self) -> list[str]:
        """Repairs the reader makes before the repair policy's (given first)."""
        return []


def plan_of(layout: StreamLayout, robot: Any, torque_source: str | None) -> Any:
    """The layout's :class:`~impactcli.io.assemble.LogPlan` from its channels without rows,
    or the LogFormatError planning raises."""
    from .assemble import plan_log

    head = layout.channels(np.zeros(0, dtype=np.int64), np.zeros((0, len(layout.names))))
    try:
        return plan_log(head, path=layout.where, robot=robot, torque_source=torque_source)
    except LogFormatError as err:
        return err


class MappedLayout(StreamLayout):
    """A layout whose columns a channel map names (CSV, ``.npz``): scale and offset by
    :func:`~impactcli.io.csv.channels_from_columns`."""

    cmap: Any
    ignored: list[str]

    def channels(self, t: np.ndarray, mat: np.ndarray) -> JointChannels:
        from .csv import channels_from_columns

        cols = {k: mat[:, i] for i, k in enumerate(self.names)}
        return channels_from_columns(self.cmap, t, cols, self.keys, self.ignored, [])
