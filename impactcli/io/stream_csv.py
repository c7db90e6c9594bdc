"""The CSV side of :mod:`impactcli.io.stream`: which CSV streams, and its rows in blocks.

A local ``.csv`` or ``.csv.gz`` — canonical, or through a CSV channel map, with or without a
UTF-8 byte-order mark (pyarrow drops it, as the whole-file reader does), with a ``.`` or a
``,`` decimal point — whose time column holds plain decimal numbers or ISO-8601 stamps
(``YYYY-MM-DDThh:mm:ss[.f][Z|±hh:mm]``, as its first cell says) and whose value cells are
numbers or empty (:func:`csv_stream_layout`; anything else is read whole). A decimal
comma's time text is read with a point, as the whole-file reader reads it.
The text is parsed by pyarrow range by range with the whole-file reader's options, on
threads ahead of the scan (:mod:`impactcli.io.stream_parse`), and each batch's time is
converted exactly as :func:`~impactcli.io.csv.read_csv_channels` converts the column
(exact decimal text → int64 ns; the float conversion, used by the whole-file reader for a
column below 1e6 s with a decimal point, checked to agree: :meth:`CsvStreamLayout.check_pass`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import LogFormatError
from ._whole import NotStreamable as _NotStreamable
from .stream_layout import MappedLayout, plan_of
from .stream_layout import RawRows as _Raw

#: Bytes of CSV text parsed at a time (one range, one record batch: a 7-joint log's row is
#: ~430 bytes, ~2400 rows a range; :mod:`impactcli.io.stream_parse` parses up to 4 ahead).
BLOCK_SIZE = 1 << 20
#: The time text streamed: plain decimal numbers.
_PLAIN = r"^-?\d+(\.\d+)?$"


@dataclass
class _TimeStats:
    """Whole-column facts the whole-file reader decides the time conversion by."""

    all_int: bool = True
    max_abs: float = 0.0
    disagree: bool = False  # the float conversion differs from the exact one somewhere
    text_fails: bool = False  # the exact decimal conversion of integers fails somewhere
    iso: bool | None = None  # ISO-8601 stamps (the column's first cell decides)



class CsvStreamLayout(MappedLayout):
    """A streamable CSV and how its columns become the log (from its first lines)."""

    def __init__(self, lay: Any, options: dict[str, Any], file_names: list[str]) -> None:
        from .channel_map import TIME_UNITS
        from .repair import DROPPABLE_SIGNALS

        self.lay = lay
        self.path, self.where, self.fmt = lay.path, lay.where, lay.fmt
        self.cmap = lay.cmap
        self.joints = tuple(lay.cmap.joints)
        self.file_names = file_names  # pyarrow's column names
        self.keys = {}
        self.key_cols: dict[str, str] = {}  # column key → column name in the file
        for (sig, j), col in lay.columns.items():
            key = col if lay.header else lay.disp(col)
            self.keys[(sig, j)] = key
            self.key_cols.setdefault(key, col)
        self.names = list(self.key_cols)
        self.droppable = {k for (sig, _), k in self.keys.items() if sig in DROPPABLE_SIGNALS}
        self.ignored = (lay.ignored_extra if lay.fmt == "csv"
                        else [lay.disp(c) for c in file_names if c not in lay.used])
        tspec = lay.tspec
        self.unit_ns = TIME_UNITS[tspec.unit]
        self.offset_ns = round(tspec.offset * self.unit_ns) if tspec.offset else 0
        self.tcol = f"column {lay.disp(lay.tname)!r}" if lay.header else lay.disp(lay.tname)
        self.time_name = lay.disp(lay.tname)
        self.start_at_zero = bool(tspec.start_at_zero)
        self.repair_order = bool(options.get("repair_order", False))
        self.time_unit_given = options.get("time_unit") is not None
        self._label = lay.label()
        self.ts = _TimeStats()
        self.plan = plan_of(self, options.get("robot"), options.get("torque_source"))

    def label(self, i: int) -> str:
        return str(self._label(i))

    def raw_batches(self) -> Iterator[_Raw]:
        self.ts = _TimeStats()
        return _raw_batches(self, self.ts)

    def rate_error(self, rate_hz: float) -> str | None:
        from .repair import rate_message

        return rate_message(rate_hz, self.where, self.tcol,
                            None if self.ts.iso else self.lay.tspec.unit)

    def pass_again(self) -> bool:
        self.check_pass()
        return False

    def check_pass(self) -> None:
        ts = self.ts
        if not ts.all_int and (ts.disagree if _fast_time(self, ts) else ts.text_fails):
            raise _NotStreamable("the whole-file reader converts this time column otherwise")


def csv_stream_layout(p: Path, cmap: Any, options: dict[str, Any]) -> CsvStreamLayout | None:
    """The layout of a local canonical or mapped CSV (module docstring), None when the file
    needs the whole-file reader."""
    from .csv import csv_layout

    try:
        lay = csv_layout(p, cmap, time_unit=options.get("time_unit"))
        names = _probe_names(lay)
    except (LogFormatError, _NotStreamable, UnicodeDecodeError, ValueError):
        return None  # the whole-file reader says what is wrong
    if len(set(names)) != len(names):
        return None
    if not lay.used <= set(names) or lay.tname in lay.columns.values():
        return None
    return CsvStreamLayout(lay, options, names)


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
def _raw_batches(ctx: CsvStreamLayout, ts: _TimeStats) -> Iterator[_Raw]:
    """The file's record batches, time converted exactly and values as float64: the text
    is parsed and each batch converted (:func:`_converted`) on threads ahead of the caller
    (:mod:`impactcli.io.stream_parse`); the time column's facts are gathered here, in order."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from .stream_parse import parsed_batches

    lay = ctx.lay
    cols = list(ctx.key_cols.values())
    types = {lay.tname: pa.string(), **{c: pa.float64() for c in cols}}
    copts = pacsv.ConvertOptions(column_types=types, include_columns=[lay.tname, *cols],
                                 decimal_point=lay.decimal)
    row0 = 0
    try:
        for conv in parsed_batches(lay, ctx.file_names, copts, BLOCK_SIZE,
                                   lambda batch: _converted(batch, ctx, cols)):
            if conv is None:
                continue
            t, facts, mat = conv
            if ts.iso is None:
                ts.iso = facts.iso
            elif facts.iso != ts.iso:
                raise _NotStreamable("ISO-8601 and other time text mixed")
            ts.all_int &= facts.all_int
            ts.max_abs = max(ts.max_abs, facts.max_abs)
            ts.disagree |= facts.disagree
            ts.text_fails |= facts.text_fails
            yield _Raw(row0, t, mat)
            row0 += t.shape[0]
    except (pa.ArrowInvalid, OSError, EOFError, UnicodeDecodeError) as err:
        raise _NotStreamable(str(err)) from err


def _converted(batch: Any, ctx: CsvStreamLayout, cols: list[str]
               ) -> tuple[np.ndarray, _TimeStats, np.ndarray] | None:
    """One record batch → ``(t (n,) int64 ns, its time column's facts, (n, C) float64 the
    used columns)``, None when empty; on a parse worker (it reads only the batch)."""
    n = batch.num_rows
    if n == 0:
        return None
    facts = _TimeStats()
    t = _time_ns(batch.column(ctx.lay.tname), ctx, facts)
    mat = np.empty((n, len(cols)))
    for i, c in enumerate(cols):
        mat[:, i] = numbers(batch.column(c))
    return t, facts, mat


def numbers(arr: Any) -> np.ndarray:
    """A float64 or int64 Arrow array as a NumPy array (a float's nulls NaN), as
    ``Array.to_numpy(zero_copy_only=False)`` gives it — without it: it imports pandas
    (0.5 s of every run's start-up)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    dtype = {pa.float64(): np.float64, pa.int64(): np.int64}[arr.type]
    if arr.null_count:
        if dtype is not np.float64:
            raise ValueError("integers with nulls have no NumPy form")
        arr = pc.fill_null(arr, float("nan"))
    return np.frombuffer(arr.buffers()[1], dtype=dtype, count=len(arr), offset=arr.offset * 8)


def _time_ns(text: Any, ctx: CsvStreamLayout, ts: _TimeStats) -> np.ndarray:
    """A batch's time text → (n,) int64 ns as :func:`read_csv_channels` converts it
    (exact decimal conversion; the float conversion, which the whole-file reader uses for
    a column below 1e6 s with a decimal point, is checked to agree); ``ts`` gets the
    batch's facts (ISO-8601 or not by its first cell)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    from .csv import _ISO_RE

    if ctx.lay.decimal == ",":  # as the whole-file reader reads a decimal comma's time
        text = pc.replace_substring(text, ",", ".")
    if text.null_count:
        raise _NotStreamable("empty time cells")
    ts.iso = bool(_ISO_RE.match(str(text[0].as_py())))
    if ts.iso:
        return _iso_ns(text, ctx)
    if not pc.all(pc.match_substring_regex(text, _PLAIN)).as_py():
        raise _NotStreamable("time text that is not plain decimal")
    tf = numbers(pc.cast(text, pa.float64()))
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
            exact = numbers(pc.cast(text, pa.int64())) * ctx.unit_ns
        except (pa.ArrowInvalid, OverflowError) as err:
            raise _NotStreamable(str(err)) from err
        if as_text is None or not np.array_equal(as_text, exact):
            ts.text_fails = True
    ts.max_abs = float(np.max(np.abs(tf)))
    ts.disagree = not np.array_equal(np.round(tf * ctx.unit_ns).astype(np.int64), exact)
    return exact + ctx.offset_ns if ctx.offset_ns else exact


def _iso_ns(text: Any, ctx: CsvStreamLayout) -> np.ndarray:
    """A batch's ISO-8601 time text → (n,) int64 epoch ns, as the whole-file reader
    converts the column (:func:`~impactcli.io.csv._iso_to_ns`: a stamp without an offset
    is UTC; pyarrow's inferred timestamps of the whole file give the same instants)."""
    from .csv import _iso_to_ns

    if ctx.time_unit_given and ctx.fmt == "csv":
        raise _NotStreamable("--time-unit with ISO-8601 time (the whole reader's error)")
    try:
        t = _iso_to_ns(text, ctx.where, ctx.tcol, ctx.label)
    except LogFormatError as err:  # the whole-file reader names the cell
        raise _NotStreamable(str(err)) from err
    return t + ctx.offset_ns if ctx.offset_ns else t


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


def _fast_time(ctx: CsvStreamLayout, ts: _TimeStats) -> bool:
    """Whether the whole-file reader converts this time column as floats (a decimal point
    somewhere, all below 1e6 s)."""
    return not ts.all_int and ts.max_abs * ctx.unit_ns / 1e9 < 1e6

