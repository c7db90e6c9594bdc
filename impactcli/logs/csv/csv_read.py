"""The CSV reader (canonical wide CSV, or any CSV through a channel map): its rows in blocks
for the one scan (:mod:`impactcli.logs.scan`; docs/formats.md, "Canonical wide CSV").

The file's text is cut at line ends into ranges of about :data:`BLOCK_SIZE` bytes, each
parsed by pyarrow on a worker thread (:func:`parsed_ranges`, at most :data:`IN_FLIGHT`
ahead of the scan), with the options a parse of the whole file would take: every range's
rows are the whole file's rows, cut elsewhere.

How a column's text becomes numbers depends on what the whole column holds (pyarrow infers
one type per column: integers, reals, ISO-8601 stamps, text...). The first pass assumes
what nearly every log holds — time as plain decimals (``12.345``, ``1714567890.001``,
``1234``) or ISO-8601 stamps, values as numbers or empty — and converts each range as the
whole column would be (exact decimal text → int64 ns; the float conversion that a column
of decimals below 1e6 s takes is checked to agree). A file that holds anything else is
read again (:meth:`CsvReaderLayout.pass_again`): a first pass of the ranges infers each
column's type as pyarrow does over the whole file, the second converts each range with
those types (:mod:`impactcli.logs.csv.csv_exact`). Errors (a cell that is not a number, an empty
time...) are found range by range and the first one in the whole file's order is raised
by the scan.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import LogFormatError
from ...sample_channels import DROPPABLE_CHANNELS
from ..layout import MappedLayout, RawRows, plan_of, rate_times
from .csv_exact import Exact, exact_rows, infer
from .csv_layout import (
    ISO_RE,
    CsvLayout,
    beyond_clock,
    csv_layout,
    csv_parse_error,
    csv_read_options,
    decimal_to_ns,
    first_bytes,
    guarded,
    gzip_cut,
    is_parse_error,
    iso_to_ns,
    numbers,
    parsed_ranges,
)

#: Bytes of CSV text parsed at a time (one range: a 7-joint log's row is ~430 bytes).
BLOCK_SIZE = 1 << 20
#: The time text of the first pass: plain decimal numbers.
_PLAIN = r"^-?\d+(\.\d+)?$"


# ------------------------------------------------------------------- the first pass
@dataclass
class _Facts:
    """What a range's time text says (the first pass): ISO-8601 stamps, or plain decimals
    — all integers or not, their largest magnitude, and whether the times given agree
    with the float conversion and with the exact text conversion of the whole column."""

    iso: bool
    all_int: bool
    max_abs: float
    float_ok: bool
    text_ok: bool


class _Exotic(Exception):
    """A range the first pass does not read as the whole file would be read."""


def _fast_range(table: Any, ctx: CsvReaderLayout
                ) -> tuple[np.ndarray | None, _Facts, np.ndarray]:
    """A range of the first pass: ``(t (n,) int64 ns, its time facts, (n, C) values)``;
    ``t`` None for a log read with ``--rate`` (the rows' times are their indices')."""
    n = table.num_rows
    facts = _Facts(iso=False, all_int=True, max_abs=0.0, float_ok=True, text_ok=True)
    t = (None if ctx.lay.tname is None else
         _fast_time(table.column(ctx.arrow[ctx.lay.tname]).combine_chunks(), ctx, facts))
    mat = np.empty((n, len(ctx.names)))
    for i, c in enumerate(ctx.key_cols.values()):
        mat[:, i] = numbers(table.column(ctx.arrow[c]).combine_chunks())
    return t, facts, mat


def _fast_time(text: Any, ctx: CsvReaderLayout, facts: _Facts) -> np.ndarray:
    """A range's time text → (n,) int64 ns as the whole column converts it when it is
    plain decimals or ISO-8601 stamps (else :class:`_Exotic`)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if ctx.lay.decimal == ",":  # a decimal comma's time is read with a point
        text = pc.replace_substring(text, ",", ".")
    if text.null_count or len(text) == 0:
        raise _Exotic
    facts.iso = bool(ISO_RE.match(str(text[0].as_py())))
    if facts.iso:
        if ctx.time_unit_given and ctx.fmt == "csv":
            raise _Exotic
        try:
            t = iso_to_ns(text, ctx.where, ctx.tcol, ctx.label)
        except LogFormatError:
            raise _Exotic from None
        return t + ctx.offset_ns if ctx.offset_ns else t
    if not pc.all(pc.match_substring_regex(text, _PLAIN)).as_py():
        raise _Exotic
    tf = numbers(pc.cast(text, pa.float64()))
    as_text = decimal_to_ns(text, ctx.unit_ns, tf)
    if pc.any(pc.match_substring(text, ".")).as_py():
        facts.all_int = False
        if as_text is None:
            raise _Exotic
        exact = as_text
    else:  # integers: the whole column's integer conversion, while no range has a '.'
        if beyond_clock(tf, ctx.unit_ns) is not None:
            raise _Exotic
        try:
            exact = numbers(pc.cast(text, pa.int64())) * ctx.unit_ns
        except (pa.ArrowInvalid, OverflowError):
            raise _Exotic from None
    # a '.' anywhere makes the column reals, converted as floats or as exact text
    facts.text_ok = as_text is not None and np.array_equal(as_text, exact)
    facts.float_ok = np.array_equal(np.round(tf * ctx.unit_ns).astype(np.int64), exact)
    facts.max_abs = float(np.max(np.abs(tf)))
    return exact + ctx.offset_ns if ctx.offset_ns else exact


class CsvReaderLayout(MappedLayout):
    """A CSV and how its columns become the log (module docstring)."""

    def __init__(self, lay: CsvLayout, options: dict[str, Any], file_names: list[str] | None,
                 header_error: str | None) -> None:
        from ..channel_map import TIME_UNITS

        self.lay = lay
        self.path, self.where, self.fmt = lay.path, lay.where, lay.fmt
        self.cmap = lay.cmap
        self.joints = tuple(lay.cmap.joints)
        self.file_names = file_names  # pyarrow's column names
        # the header's names → pyarrow's (by position: a name read with spaces around it)
        self.arrow = (dict(zip(lay.names, file_names, strict=True))
                      if file_names is not None and len(file_names) == len(lay.names)
                      else {c: c for c in lay.names})
        self.header_error = header_error
        self.keys = {}
        self.key_cols: dict[str, str] = {}  # column key → column name in the file
        for (sig, j), col in lay.columns.items():
            key = col if lay.header else lay.disp(col)
            self.keys[(sig, j)] = key
            self.key_cols.setdefault(key, col)
        self.names = list(self.key_cols)
        self.droppable = {k for (sig, _), k in self.keys.items() if sig in DROPPABLE_CHANNELS}
        self.ignored = (lay.ignored_extra if lay.fmt == "csv"
                        else [lay.disp(c) for c in lay.names if c not in lay.used])
        tspec = lay.tspec
        self.sample_rate_hz = lay.sample_rate_hz
        if tspec is None or lay.tname is None:  # --rate: no time column
            self.unit_ns, self.offset_ns = 1, 0
            self.tcol = self.time_name = "--rate"
            self.start_at_zero = False
        else:
            self.unit_ns = TIME_UNITS[tspec.unit]
            self.offset_ns = round(tspec.offset * self.unit_ns) if tspec.offset else 0
            self.tcol = (f"column {lay.disp(lay.tname)!r}" if lay.header
                         else lay.disp(lay.tname))
            self.time_name = lay.disp(lay.tname)
            self.start_at_zero = bool(tspec.start_at_zero)
        self.repair_order = bool(options.get("repair_order", False))
        self.time_unit_given = options.get("time_unit") is not None
        self._label = lay.label()
        self.exact: Exact | None = None  # the exact passes' plan, once the first fails
        self._again = False
        self.iso = False
        self.truncated: list[str] = []  # the note of a file cut short, read up to the cut
        self.plan = plan_of(self, options)

    def label(self, i: int) -> str:
        return str(self._label(i))

    def rate_error(self, sample_rate_hz: float, duration_s: float | None = None) -> str | None:
        from ..repair import rate_message

        if self.sample_rate_hz is not None:
            return rate_message(self.sample_rate_hz, self.where, "--rate", None, duration_s)
        assert self.lay.tspec is not None
        return rate_message(sample_rate_hz, self.where, self.tcol,
                            None if self.iso else self.lay.tspec.unit, duration_s)

    def ranges(self, work: Callable[[Callable[[Any], Any], bool], Any]) -> Iterator[Any]:
        """``work`` of every range of the file (:func:`parsed_ranges`), an error reading
        the file given as a result."""
        return guarded(parsed_ranges(self.lay, self.file_names, BLOCK_SIZE, work,
                                     self.truncated))

    def cut_short(self) -> bool:
        return bool(self.truncated)

    def pre_repairs(self) -> list[str]:
        return [*self.truncated, *super().pre_repairs()]

    def pass_again(self) -> bool:
        again, self._again = self._again, False
        return again

    def raw_batches(self) -> Iterator[RawRows]:
        self.read_error = None
        self.truncated.clear()
        if self.header_error is not None or self.file_names is None:
            yield from self._parse_only()
        elif self.exact is None:
            yield from self._fast_pass()
        else:
            yield from exact_rows(self)

    # -- the passes
    def include_columns(self) -> list[str]:
        tname = [] if self.lay.tname is None else [self.lay.tname]
        return list(dict.fromkeys(self.arrow[c] for c in (*tname, *self.key_cols.values())))

    def _parse_only(self) -> Iterator[RawRows]:
        """A file whose header pyarrow cannot name: its first parse error, else the
        header's (no rows)."""
        import pyarrow.csv as pacsv

        copts = pacsv.ConvertOptions(include_columns=[])
        names = [f"f{i}" for i in range(len(self.lay.names))]  # pyarrow cannot name them
        try:
            for _ in parsed_ranges(self.lay, names, BLOCK_SIZE,
                                   lambda parse, first: parse(copts).num_rows):
                pass
        except (OSError, EOFError, ValueError) as err:  # pyarrow's errors are ValueErrors
            self.read_error = csv_parse_error(self.lay, err)
            return
        self.read_error = LogFormatError(self.header_error or f"{self.where}: cannot "
                                         "parse CSV: its header is not UTF-8 text")
        yield from ()

    def _fast_pass(self) -> Iterator[RawRows]:
        """The first pass (module docstring); a range it does not read as the whole
        file is read ends it, and the file is read again (:meth:`pass_again`)."""
        import pyarrow as pa
        import pyarrow.csv as pacsv

        lay = self.lay
        cols = [self.arrow[c] for c in self.key_cols.values()]
        tnames = [] if lay.tname is None else [self.arrow[lay.tname]]
        if set(tnames) & set(cols) or len(set(cols)) != len(cols):
            yield from self._go_exact()
            return
        types = {**{c: pa.string() for c in tnames}, **{c: pa.float64() for c in cols}}
        copts = pacsv.ConvertOptions(column_types=types, include_columns=[*tnames, *cols],
                                     decimal_point=lay.decimal)

        def work(parse: Callable[[Any], Any], first: bool) -> Any:
            try:
                table = parse(copts)
            except Exception as err:
                if is_parse_error(err):
                    return err
                return _Exotic()
            if table.num_rows == 0:
                return None
            try:
                return _fast_range(table, self)
            except _Exotic as err:
                return err

        row0 = 0
        isos: set[bool] = set()
        all_int, max_abs, float_ok, text_ok = True, 0.0, True, True
        for got in self.ranges(work):
            if got is None:
                continue
            if isinstance(got, _Exotic):
                yield from self._go_exact()
                return
            if isinstance(got, BaseException):
                self.read_error = csv_parse_error(lay, got)
                return
            t, facts, mat = got
            if t is None:
                t = rate_times(row0, mat.shape[0], self.sample_rate_hz or 1.0)
            isos.add(facts.iso)
            if len(isos) > 1:
                yield from self._go_exact()
                return
            all_int &= facts.all_int
            max_abs = max(max_abs, facts.max_abs)
            float_ok &= facts.float_ok
            text_ok &= facts.text_ok
            yield RawRows(row0, t, mat)
            row0 += t.shape[0]
        self.iso = isos == {True}
        # a column of reals below 1e6 s is converted as floats, the others as exact text
        if not self.iso and not all_int and not (
                float_ok if max_abs * self.unit_ns / 1e9 < 1e6 else text_ok):
            yield from self._go_exact()
            return
        if row0 < 2:
            self.read_error = LogFormatError(f"{self.where}: holds {row0} data row(s); at "
                                             "least 2 are needed")

    def _go_exact(self) -> Iterator[RawRows]:
        """Leave the first pass: the file is read again by the exact passes."""
        self.exact = infer(self)
        self._again = True
        yield from ()

# ------------------------------------------------------------------------- the layout
def _header_reader(lay: CsvLayout, ropts: Any, popts: Any) -> Any:
    """pyarrow's streaming reader of the CSV's first block, which names its columns; a
    gzip stream cut inside that block is read up to the cut (:func:`first_bytes`)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    copts = pacsv.ConvertOptions(column_types={}, include_columns=[])
    try:
        return pacsv.open_csv(lay.path, read_options=ropts, parse_options=popts,
                              convert_options=copts)
    except OSError as err:
        if not gzip_cut(lay.path, err):
            raise
    return pacsv.open_csv(pa.BufferReader(first_bytes(lay.path, BLOCK_SIZE)),
                          read_options=ropts, parse_options=popts, convert_options=copts)


def csv_reader_layout(p: Path, where: str, cmap: Any, options: dict[str, Any]
                      ) -> CsvReaderLayout:
    """The reader of a local canonical or mapped CSV (module docstring).

    Raises:
        LogFormatError: not a text CSV, a layout its first lines refuse, a map for npz.
        ChannelMapError: a map pointing at a column the file does not have.
    """
    import pyarrow as pa

    if cmap is not None and cmap.format == "npz":
        raise LogFormatError(f"{where}: channel map {cmap.path} is for .npz archives")
    rate = options.get("rate")
    lay = csv_layout(p, cmap, time_unit=None if cmap is not None else options.get("time_unit"),
                     time_column=None if cmap is not None else options.get("time_column"),
                     rate=None if rate is None else float(rate))
    ropts, popts = csv_read_options(lay, BLOCK_SIZE)
    names: list[str] | None = None
    header_error = None
    try:
        reader = _header_reader(lay, ropts, popts)
        try:
            names = list(reader.schema.names)
        except UnicodeDecodeError:
            header_error = (f"{where}: cannot parse CSV: its header (line {lay.skip + 1}) "
                            "is not UTF-8 text")
        reader.close()
    except UnicodeDecodeError:
        header_error = (f"{where}: cannot parse CSV: its header (line {lay.skip + 1}) is "
                        "not UTF-8 text")
    except (pa.ArrowInvalid, OSError, EOFError) as err:
        if "Empty CSV file" not in str(err):
            raise csv_parse_error(lay, err) from err
        names = []
    if names is not None and len(names) != len(lay.names):
        raise LogFormatError(f"{where}: cannot parse CSV: its header has {len(names)} "
                             f"columns as CSV, {len(lay.names)} split at "
                             f"{lay.delim!r}")
    return CsvReaderLayout(lay, options, names, header_error)
