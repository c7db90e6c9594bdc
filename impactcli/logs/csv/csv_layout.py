"""What a CSV's first lines and its channel map say (:func:`csv_layout`), and the
conversions of its time text (docs/formats.md, "Canonical wide CSV", "Channel maps").

The time column is read as text and converted to int64 ns exactly (no float rounding)
whenever it is written as plain decimals (:func:`decimal_text_to_ns`); ``time_ns`` is read
as int64; ``time`` may also hold ISO-8601 stamps (``2024-05-01T12:00:00.001Z``; UTC unless
the stamp gives an offset), read as epoch ns (:func:`iso_to_ns`). ``--time-unit`` says when
``time`` holds ms, µs or ns; a time that does not fit the int64-ns clock is an error naming
the unit that would fit (:func:`clock_message`).

Common variants of the canonical layout are read as well: a UTF-8 byte-order mark before
the header (Excel), ``;``, tab or space separators — the one with which the header names a
time column (:mod:`impactcli.logs.csv.csv_header`; for a mapped CSV, the map's columns) — and
with those a decimal comma (``0,004``), detected on the first data line; blanks around
separators (``time, q``) are not part of names or cells. A log read with ``--rate`` has no
time column (``tname`` None): its times are the rows' indices at the rate.
A file with binary content (a NUL byte, or mostly control or non-UTF-8 bytes in its first
64 KiB) is "not a text CSV".
"""

from __future__ import annotations

import csv
import gzip
import re
import warnings
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ChannelMapError, ImpactWarning, LogFormatError
from ..channel_map import TIME_UNITS, ChannelMap, ChannelRef, TimeSpec, require_time
from ..repair import GIVE_UNIT, unit_hint
from .csv_header import canonical_map, header_names, mapped_separator, separator

#: Bytes looked at to tell a text CSV from binary content.
SNIFF_BYTES = 1 << 16
#: Largest |time| in ns the int64 clock holds (± about 292 years).
MAX_NS = float(2**63 - 1)
#: Ranges parsed ahead of the reader (and at most this many tables in memory).
IN_FLIGHT = 4
#: Worker threads parsing ranges.
THREADS = 2
_BREAK = re.compile(rb"\r\n|\r|\n")
#: An ISO-8601 date and time at the start of a time cell.
ISO_RE = re.compile(r"^\s*\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}")


def is_gz(path: Path) -> bool:
    return path.name.lower().endswith(".gz")


def _lines(path: Path, skip: int, count: int) -> list[str]:
    """``count`` lines after ``skip`` lines ("" past the end), a UTF-8 BOM removed."""
    opener: Any = gzip.open if is_gz(path) else open
    try:
        with opener(path, "rt", encoding="utf-8-sig", errors="replace", newline="") as f:
            for _ in range(skip):
                f.readline()
            return [str(f.readline()) for _ in range(count)]
    except (OSError, EOFError, ValueError) as err:
        raise LogFormatError(f"{path}: cannot read: {err}") from err


#: ``--rate`` against a time column: its first rows, and the factor beyond which their
#: average step disagrees with 1 / rate (warned).
RATE_CHECK_ROWS = 2000
RATE_CHECK_FACTOR = 1.5


def time_column_of(names: list[str], time_column: str | None,
                   time_unit: str | None) -> tuple[str, str] | None:
    """A canonical CSV's time column read with ``--rate`` (``--time-column``, else one
    named as a time) and its unit (``--time-unit``, else its name's, else s); None: none."""
    from .csv_header import find_time_column, name_unit

    tcol = time_column if time_column in names else find_time_column(names)
    return None if tcol is None else (tcol, time_unit or name_unit(tcol) or "s")


def warn_rate_against_column(path: Path, where: str, column: int, label: str, unit: str,
                             skip: int, delim: str, decimal: str, rate: float) -> None:
    """With ``--rate`` on a CSV that has a time column (``column``, 0-based, after ``skip``
    lines, in ``unit``), the column is not the clock; warn when its average step over the
    first :data:`RATE_CHECK_ROWS` rows (a rounded clock's too) implies a rate off ``rate``
    by more than :data:`RATE_CHECK_FACTOR` (another clock, or a wrong ``--rate``). Stamps
    that are not numbers (ISO 8601) are not checked."""
    vals = []
    for line in _lines(path, skip, RATE_CHECK_ROWS):
        cells = line.rstrip("\r\n").split(delim)
        if not line or len(cells) <= column:  # past the end
            break
        try:
            vals.append(float(cells[column].strip().replace(decimal, ".")))
        except ValueError:
            return
    warn_rate_against_times(np.asarray(vals, dtype=np.float64), unit, rate, where,
                            f"column {label}", "column")


def warn_rate_against_times(t: np.ndarray, unit: str, rate: float, where: str, what: str,
                            kind: str) -> None:
    """Warn when the times ``t`` (in ``unit``; a log's first rows) step, on average (a
    rounded clock's too), at a rate off ``rate`` by more than :data:`RATE_CHECK_FACTOR`:
    the comparison of ``--rate`` with a time column or array it overrides (``what``)."""
    if t.size < 10 or not np.isfinite(t[[0, -1]]).all():
        return
    step_s = float(t[-1] - t[0]) / (t.size - 1) * TIME_UNITS[unit] * 1e-9
    if step_s > 0 and not 1.0 / RATE_CHECK_FACTOR <= 1.0 / step_s / rate <= RATE_CHECK_FACTOR:
        warnings.warn(f"{where}: --rate {rate:g}: the time {what} (not used) steps by "
                      f"{step_s:.3g} s on average over its first {t.size} rows "
                      f"({1.0 / step_s:.3g} Hz, read in {unit}), not the 1/{rate:g} s --rate "
                      f"gives: check the rate (or the {kind}'s unit)", ImpactWarning,
                      stacklevel=4)


def check_text(path: Path, where: str) -> None:
    """LogFormatError ``not a text CSV`` when the first :data:`SNIFF_BYTES` bytes hold a NUL
    byte, or are mostly control bytes or bytes that are not UTF-8 (binary content)."""
    opener: Any = gzip.open if is_gz(path) else open
    try:
        with opener(path, "rb") as f:
            head = bytes(f.read(SNIFF_BYTES))
    except (OSError, EOFError, ValueError) as err:
        raise LogFormatError(f"{where}: cannot read: {err}") from err
    nul = head.find(b"\x00")
    if nul >= 0:
        raise LogFormatError(f"{where}: not a text CSV (binary content: a NUL byte at byte "
                             f"{nul})")
    if not head:
        return
    arr = np.frombuffer(head, dtype=np.uint8)
    control = (arr < 9) | ((arr > 13) & (arr < 32)) | (arr == 127)
    try:
        head.decode("utf-8")
        not_utf8 = 0
    except UnicodeDecodeError as err:
        # a multi-byte character cut at the end of the sniffed bytes is still text
        not_utf8 = 0 if err.start >= len(head) - 3 else int(np.count_nonzero(arr >= 128))
    if np.count_nonzero(control) + not_utf8 > 0.1 * len(head):
        k = int(np.argmax(control | (arr >= 128)))
        raise LogFormatError(f"{where}: not a text CSV (binary content from byte {k})")


def decimal_text_to_ns(values: Any, unit_ns: int) -> np.ndarray | None:
    """Exact conversion of decimal text (``-12.345000001``) in a time unit to int64 ns.

    Args:
        values: a pyarrow string array.
        unit_ns: size of the unit in ns.

    Returns:
        (N,) int64, or ``None`` when some value is not a plain decimal (exponent, null, …).
    """
    import pyarrow as pa
    import pyarrow.compute as pc

    s = pc.utf8_trim_whitespace(values)
    if s.null_count or not pc.all(pc.match_substring_regex(s, r"^[+-]?\d+(\.\d*)?$")).as_py():
        return None
    neg = pc.starts_with(s, "-").to_numpy(zero_copy_only=False)
    s = pc.utf8_ltrim(s, characters="+-")
    s = pc.if_else(pc.match_substring(s, "."), s, pc.binary_join_element_wise(s, ".", ""))
    parts = pc.split_pattern(s, ".", max_splits=1)
    whole_txt = pc.list_element(parts, 0)
    if len(whole_txt) and int(pc.max(pc.utf8_length(whole_txt)).as_py()) > 18:
        return None  # beyond int64: the float path names the row
    whole = pc.cast(whole_txt, pa.int64()).to_numpy()
    frac_txt = pc.list_element(parts, 1)
    frac_txt = pc.utf8_slice_codeunits(pc.utf8_rpad(frac_txt, 9, "0"), 0, 9)
    frac = pc.cast(frac_txt, pa.int64()).to_numpy()  # units of 1e-9 of `unit`
    if whole.size and int(np.max(whole)) >= (2**63 - 1) // unit_ns - 1:
        return None  # beyond the int64-ns clock: the float path names the row
    if unit_ns == 10**9:
        ns = whole * 10**9 + frac
    else:
        ns = whole * unit_ns + np.round(frac * (unit_ns / 1e9)).astype(np.int64)
    out: np.ndarray = np.where(neg, -ns, ns).astype(np.int64)
    return out


def decimal_to_ns(text: Any, unit_ns: int, tf: np.ndarray) -> np.ndarray | None:
    """``decimal_text_to_ns(text, unit_ns)`` of plain decimal text; for seconds with at most
    9 decimals (well within its range) by pyarrow's exact decimal parse, 20× faster.

    Args:
        text: (n,) pyarrow strings matching ``^-?\\d+(\\.\\d+)?$``.  unit_ns: the unit [ns].
        tf: (n,) float64 the same values (to see the range).
    """
    import pyarrow as pa
    import pyarrow.compute as pc

    if unit_ns != 10**9 or not float(np.max(np.abs(tf))) < 9e9:
        return decimal_text_to_ns(text, unit_ns)
    try:
        d = pc.cast(text, pa.decimal128(38, 9))  # unscaled value: ns, exactly
    except pa.ArrowInvalid:  # more than 9 decimals: truncated by decimal_text_to_ns
        return decimal_text_to_ns(text, unit_ns)
    words = np.frombuffer(d.buffers()[1], dtype=np.int64).reshape(-1, 2)
    return words[d.offset: d.offset + len(d), 0].copy()


def ragged_line(path: Path, skip: int, delim: str, expected: int) -> int | None:
    """The 1-based line number of the first data line with another number of fields than
    ``expected`` (only to name it in an error; quoted delimiters are not considered)."""
    opener: Any = gzip.open if is_gz(path) else open
    try:
        with opener(path, "rt", encoding="utf-8", errors="replace", newline="") as f:
            for n, line in enumerate(f, 1):
                if n > skip and line.strip() and line.count(delim) + 1 != expected:
                    return n
    except (OSError, EOFError):
        return None
    return None


def row_labeller(skip: int) -> Any:
    def label(i: int) -> str:
        return f"row {i + 1} (line {i + 1 + skip})"

    return label


@dataclass
class CsvLayout:
    """What a CSV's first lines and its channel map say, before its data are read.

    Attributes:
        path: the file.  where: it as text, for messages.
        cmap: its channel map (the canonical layout's, or the given one).
        fmt: ``csv`` or ``csv-mapped``.
        header: whether the first line (after ``skip``) names the columns.
        skip: lines skipped before the header or the data.
        delim: the field separator.  decimal: the decimal point (``.`` or ``,``).
        names: the column names as the header line gives them (``f0``, ``f1``, ... without
            a header).
        ignored_extra: a canonical CSV's columns that are not channels.
        tname: the time column.  tspec: the time's spec (unit, offset, start at zero).
            Both None for a log read with ``--rate`` (``sample_rate_hz``).
        columns: (signal, joint index) → the column holding it, for every ref of ``cmap``.
    """

    path: Path
    where: str
    cmap: ChannelMap
    fmt: str
    header: bool
    skip: int
    delim: str
    decimal: str
    names: list[str]
    ignored_extra: list[str]
    tname: str | None
    tspec: TimeSpec | None
    columns: dict[tuple[str, int], str]
    sample_rate_hz: float | None = None

    @property
    def used(self) -> set[str]:
        """The columns read: time and every channel's."""
        return {*([self.tname] if self.tname is not None else []), *self.columns.values()}

    def disp(self, col: str) -> str:
        """A column as messages name it (``column 3`` without a header)."""
        return col if self.header else f"column {int(col[1:])}"

    def label(self) -> Any:
        """Row i (0-based data row) → ``row i+1 (line n)``."""
        return row_labeller(self.skip + (1 if self.header else 0))


def csv_layout(path: Path, cmap: ChannelMap | None, *, time_unit: str | None = None,
               time_column: str | None = None, rate: float | None = None) -> CsvLayout:
    """Read a CSV's first lines: separator, decimal point, header, the channel map and
    which column holds what.

    Args:
        path: the file.  cmap: its channel map (None: the canonical layout).
        time_unit, time_column, rate: ``--time-unit``, ``--time-column`` and ``--rate``
            of a canonical CSV (:func:`~impactcli.logs.csv.csv_header.canonical_map`; a map's
            own time has them applied already).

    Raises:
        LogFormatError: not a text CSV, empty, no time or position column (canonical).
        ChannelMapError: a map pointing at a column the file does not have.
    """
    where = str(path)
    check_text(path, where)
    header = True if cmap is None else cmap.header
    skip = 0 if cmap is None else cmap.skip_rows
    line, data_line = _lines(path, skip, 2)
    if not line.strip():
        raise LogFormatError(f"{where}: empty file (no header or data)")
    if cmap is None:
        delim = separator(line, time_column)
    else:
        delim = cmap.delimiter or mapped_separator(cmap, line)
    if not header:
        data_line = line
    # a decimal comma goes with ';', tab or space separators (spreadsheet exports)
    decimal = "," if delim != "," and re.search(r"\d,\d", data_line) else "."
    if header:
        names = header_names(line, delim)
    else:
        names = [f"f{i}" for i in range(len(line.split(delim)))]
    ignored_extra: list[str] = []
    if cmap is None:
        cmap, ignored_extra = canonical_map(names, where, time_unit, time_column=time_column,
                                            rate=rate)
        fmt = "csv"
        found = time_column_of(names, time_column, time_unit) if rate is not None else None
        if rate is not None and found is not None:
            warn_rate_against_column(path, where, names.index(found[0]), repr(found[0]),
                                     found[1], skip + 1, delim, decimal, rate)
    else:
        fmt = "csv-mapped"
    the_map = cmap

    def colname(ref: ChannelRef, what: str) -> str:
        if isinstance(ref.source, int):
            if ref.source >= len(names):
                raise ChannelMapError(
                    f"{where}: channel map {the_map.path or the_map.name}: {what} points at "
                    f"column {ref.source} (0-based), but the file has {len(names)} columns "
                    f"(0–{len(names) - 1}): is this the file the map was written for?"
                )
            return names[ref.source]
        if ref.source not in names:
            raise ChannelMapError(
                f"{where}: channel map {the_map.path or the_map.name}: {what} points at "
                f"column {ref.source!r}, which is not in the file (its columns split at "
                f"{delim!r}: {', '.join(names[:12])}{', …' if len(names) > 12 else ''})"
            )
        return ref.source

    tspec = None if rate is not None else require_time(cmap, where)
    tname = None if tspec is None else colname(tspec.ref, "time")
    src = None if cmap.time is None else cmap.time.ref.source
    present = (isinstance(src, int) and src < len(names)) or (isinstance(src, str)
                                                               and src in names)
    if rate is not None and fmt == "csv-mapped" and cmap.time is not None and present:
        col = colname(cmap.time.ref, "time")  # the map's time: compared, not the clock
        warn_rate_against_column(path, where, names.index(col),
                                 repr(col) if header else f"column {names.index(col)}",
                                 cmap.time.unit, skip + (1 if header else 0), delim, decimal,
                                 rate)
    columns = {(sig, j): colname(ref, f"{cmap.joints[j]}.{sig}") for sig, j, ref in cmap.refs()}
    used = {*columns.values(), *([tname] if tname is not None else [])}
    # a column named twice could be read as either: refused when a channel is one of them
    for col in sorted(used, key=names.index):
        if names.count(col) > 1:
            raise LogFormatError(f"{where}: column {col!r} appears {names.count(col)} times "
                                 "in the header: name each column once")
    return CsvLayout(path=path, where=where, cmap=cmap, fmt=fmt, header=header, skip=skip,
                     delim=delim, decimal=decimal, names=names, ignored_extra=ignored_extra,
                     tname=tname, tspec=tspec, columns=columns, sample_rate_hz=rate)


def csv_read_options(lay: CsvLayout, block_size: int = 1 << 24) -> tuple[Any, Any]:
    """pyarrow ``(ReadOptions, ParseOptions)`` of a CSV's layout."""
    import pyarrow.csv as pacsv

    return (pacsv.ReadOptions(skip_rows=lay.skip, autogenerate_column_names=not lay.header,
                              block_size=block_size),
            pacsv.ParseOptions(delimiter=lay.delim))


def csv_parse_error(lay: CsvLayout, err: BaseException) -> LogFormatError:
    """The LogFormatError of a pyarrow error reading ``lay``'s file (a ragged line named)."""
    msg = str(err).splitlines()[0]
    m = re.search(r"Expected (\d+) columns, got (\d+)", msg)
    if m:
        at = ragged_line(lay.path, lay.skip, lay.delim, int(m.group(1)))
        if at is not None:
            first = "the header has" if lay.header else "the first line has"
            msg = (f"line {at}: {m.group(2)} fields where {first} "
                   f"{m.group(1)}" + msg[m.end():])
    return LogFormatError(f"{lay.where}: cannot parse CSV: {msg}")


def first_valid(arr: Any) -> str:
    """The first non-null value of a pyarrow string array ("" when none)."""
    v = arr.drop_null()
    return str(v[0].as_py()) if len(v) else ""


def cells_as_floats(arr: Any) -> tuple[np.ndarray, tuple[int, Any] | None]:
    """A pyarrow array's cells as float64 by Python's float of each (nulls NaN), and its
    first cell that is not a number ``(index, value)`` (None when all are: the values after
    it are not converted)."""
    vals = arr.to_pylist()
    out = np.empty(len(vals))
    for i, v in enumerate(vals):
        try:
            out[i] = np.nan if v is None else float(v)
        except (TypeError, ValueError):
            return out, (i, v)
    return out, None


def floats(arr: Any, where: str, what: str, label: Any) -> np.ndarray:
    """A pyarrow string array of numbers as float64 (empty cells NaN), or the error naming
    the first cell that is not a number."""
    out, bad = cells_as_floats(arr)
    if bad is not None:
        raise LogFormatError(f"{where}: {what}, {label(bad[0])}: non-numeric value {bad[1]!r}")
    return out


def beyond_clock(values: np.ndarray, unit_ns: int) -> int | None:
    """The first time in the unit of ``unit_ns`` that does not fit the int64-ns clock
    (±292 years), None when all do."""
    with np.errstate(over="ignore", invalid="ignore"):
        over = np.abs(values) * unit_ns >= MAX_NS
    return int(np.argmax(over)) if over.any() else None


def clock_message(value: float, label: str, steps_median: float, unit_ns: int, where: str,
                  what: str, unit: str) -> str:
    """The error for a time beyond the clock's range: most often a time in ns or µs read as
    seconds (the median step of the column's finite values says which unit fits)."""
    step = steps_median
    rate = 1e9 / (step * unit_ns) if step > 0 else float("nan")
    return (f"{where}: {what}, {label}: time {value:g} {unit} is beyond the clock's "
            f"range (±292 years in ns){unit_hint(rate, unit)}: {GIVE_UNIT}")


def median_step(values: np.ndarray) -> float:
    """The median step of the finite values of a time column (0 without steps)."""
    steps = np.diff(values[np.isfinite(values)])
    return float(np.median(steps)) if steps.size else 0.0


def iso_to_ns(arr: Any, where: str, what: str, label: Any) -> np.ndarray:
    """ISO-8601 stamps (pyarrow timestamps, or strings) → (N,) int64 epoch ns; a stamp
    without an offset is UTC."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if arr.null_count:
        i = int(np.argmax(arr.is_null().to_numpy(zero_copy_only=False)))
        raise LogFormatError(f"{where}: {what}, {label(i)}: empty time")
    if pa.types.is_string(arr.type):
        txt = pc.utf8_trim_whitespace(arr)
        has_offset = pc.match_substring_regex(txt, r"(Z|[+-]\d{2}(:?\d{2})?)$")
        txt = pc.if_else(has_offset, txt, pc.binary_join_element_wise(txt, "Z", ""))
        try:
            arr = pc.cast(txt, pa.timestamp("ns", tz="UTC"))
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            given = arr.to_pylist()
            for i, v in enumerate(txt.to_pylist()):
                try:
                    pc.cast(pa.array([v]), pa.timestamp("ns", tz="UTC"))
                except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
                    raise LogFormatError(
                        f"{where}: {what}, {label(i)}: {given[i]!r} is not an ISO-8601 time "
                        "(YYYY-MM-DDThh:mm:ss[.f][Z|±hh:mm]) within 1677–2262"
                    ) from None
            raise LogFormatError(f"{where}: {what}: cannot read its ISO-8601 times") from None
    try:
        ns = pc.cast(arr, pa.timestamp("ns", tz=arr.type.tz)).cast(pa.int64())
    except pa.ArrowInvalid as err:
        raise LogFormatError(f"{where}: {what}: a time outside 1677–2262 ({err})") from None
    return np.asarray(ns.to_numpy(), dtype=np.int64)


def gzip_cut(path: Path, err: OSError) -> bool:
    """Whether pyarrow's error reading ``path`` is a gzip stream that ends early
    ("Truncated compressed stream"): one read up to its cut, not a failure."""
    return is_gz(path) and "runcated" in str(err)


class _Source:
    """The file's bytes (a ``.gz`` decompressed) read ``block`` at a time; a gzip stream
    that ends early is read up to its cut through Python's gzip (``cut``), where pyarrow's
    stream would lose the block it was decompressing."""

    def __init__(self, path: Path) -> None:
        import pyarrow as pa

        self.path, self.read_so_far, self.cut = path, 0, False
        self._src = pa.input_stream(str(path))
        self._rest: Iterator[bytes] | None = None

    def read(self, block: int) -> bytes:
        if self._rest is None:
            try:
                data = self._src.read(block)
            except OSError as err:
                if not gzip_cut(self.path, err):
                    raise
                self._rest = self._after(self.read_so_far, block)
                return self.read(block)
        else:
            data = next(self._rest, b"")
        self.read_so_far += len(data)
        return data

    def _after(self, skip: int, block: int) -> Iterator[bytes]:
        """The decompressed bytes after the first ``skip``, up to the stream's cut."""
        with gzip.open(self.path, "rb") as f:
            try:
                while skip > 0:
                    skip -= len(f.read1(min(skip, block)))
                while True:
                    data = f.read1(block)
                    if not data:
                        return
                    yield data
            except EOFError:
                self.cut = True

    def close(self) -> None:
        self._src.close()


def first_bytes(path: Path, size: int) -> bytes:
    """The file's first ``size`` bytes or more (whole blocks, up to the last line end), a
    gzip stream cut short read up to its cut."""
    src, parts, n = _Source(path), [], 0
    try:
        while n < size and (data := src.read(size)):
            parts.append(data)
            n += len(data)
    finally:
        src.close()
    text = b"".join(parts)
    end = max(text.rfind(b"\n"), text.rfind(b"\r")) + 1
    return text[:end] if end else text


def _drop_cut_line(lay: CsvLayout, text: bytes, stream_cut: bool) -> tuple[bytes, str | None]:
    """The last range's ``text`` without its last line when that line is cut: the file
    (or its gzip stream) ends inside it, with no line end, and it holds fewer fields than
    the header (a gzip stream that ends early: always) — with the note saying so. A gzip
    stream that ends early at a line end keeps its last line and is noted all the same:
    what followed it is lost."""
    if not text or text.endswith((b"\n", b"\r")):
        if not stream_cut:
            return text, None
        return text, (f"{lay.where}: the file is cut short (its gzip stream ends early, at "
                      "a line end: the recording stopped while writing it?); read the "
                      "complete lines before the cut")
    start = max(text.rfind(b"\n"), text.rfind(b"\r")) + 1
    line = text[start:].decode("utf-8", errors="replace")
    fields = len(next(csv.reader([line], delimiter=lay.delim), [""]))
    if stream_cut:
        why = "its gzip stream ends early, inside its last line"
    elif fields < len(lay.names):
        why = (f"its last line ends after {fields} of {len(lay.names)} fields, with no "
               "line end")
    else:
        return text, None
    return text[:start], (f"{lay.where}: the file is cut short ({why}: the recording "
                          "stopped while writing it?); read the complete lines before the "
                          "cut")


def parsed_ranges(lay: CsvLayout, names: list[str] | None, block_size: int,
                  work: Callable[[Callable[[Any], Any], bool], Any],
                  cut_notes: list[str] | None = None) -> Iterator[Any]:
    """``work(parse, first)`` of every range of the CSV ``lay``, in order, computed on
    threads: ``parse(convert_options)`` parses the range into a pyarrow table (the first
    range with the layout's skipped lines and header, the others with the column
    ``names``; None: pyarrow's own names, for a parse that looks at no column). Lines end
    at ``\\n``, ``\\r\\n`` or ``\\r`` as pyarrow reads them (a cut between ``\\r`` and
    ``\\n`` leaves an empty line, which pyarrow skips), and values never hold a line break
    (``newlines_in_values`` is off). A file cut short (:func:`_drop_cut_line`) is read up
    to its cut, and the note saying so is put in ``cut_notes`` (once). Raises what pyarrow raises
    and what ``work`` raises."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    first_opts, parse_opts = csv_read_options(lay, block_size)
    head_lines = lay.skip + (1 if lay.header else 0) + 1  # up to the first data line

    def job(text: bytes, first: bool) -> Any:
        size = max(len(text), 1)

        def parse(convert_options: Any) -> Any:
            if first:
                ropts = pacsv.ReadOptions(skip_rows=first_opts.skip_rows,
                                          autogenerate_column_names=not lay.header,
                                          block_size=size, use_threads=False)
            elif names is None:
                ropts = pacsv.ReadOptions(autogenerate_column_names=True, block_size=size,
                                          use_threads=False)
            else:
                ropts = pacsv.ReadOptions(column_names=names, block_size=size,
                                          use_threads=False)
            return pacsv.read_csv(pa.py_buffer(text), read_options=ropts,
                                  parse_options=parse_opts, convert_options=convert_options)

        return work(parse, first)

    pending: deque[Future[Any]] = deque()
    src = _Source(lay.path)
    with ThreadPoolExecutor(THREADS) as pool:
        try:
            rest = b""
            first = True
            eof = False
            while not eof:
                data = src.read(block_size)
                eof = not data
                buf = rest + data
                if eof:
                    text, rest = buf, b""
                    if not first or _BREAK.search(text):  # not the header alone
                        text, note = _drop_cut_line(lay, text, src.cut)
                        if note is not None and cut_notes is not None and note not in cut_notes:
                            cut_notes.append(note)
                else:
                    cut = max(buf.rfind(b"\n"), buf.rfind(b"\r")) + 1
                    if cut == 0 or (first and len(_BREAK.findall(buf, 0, cut)) < head_lines):
                        rest = buf  # no whole line yet (or not past the header): read on
                        continue
                    text, rest = buf[:cut], buf[cut:]
                if text or first:
                    pending.append(pool.submit(job, text, first))
                    first = False
                while pending and (len(pending) >= IN_FLIGHT or eof):
                    yield pending.popleft().result()
        finally:
            for f in pending:
                f.cancel()
            src.close()


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


def is_parse_error(err: BaseException) -> bool:
    """Whether a pyarrow error is the text's (a ragged line), not a conversion's."""
    return not (isinstance(err, Exception) and "conversion error" in str(err))



def guarded(it: Iterator[Any]) -> Iterator[Any]:
    """The ranges' results; an error reading the file (a cut gzip) is given as one."""
    try:
        yield from it
    except (OSError, EOFError, ValueError) as err:  # pyarrow's errors are ValueErrors
        yield err


