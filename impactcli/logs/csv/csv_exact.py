"""The exact passes of the CSV reader (:mod:`impactcli.logs.csv.csv_read`), for a file whose first
pass met cells it does not read as the whole file is read.

pyarrow gives each column of a CSV one type, inferred over the whole file: the first of
:data:`KINDS` every cell converts as (integers, reals, ISO-8601 stamps, ... text). A
column's cells become numbers by that type: integers and reals as numbers, text by
Python's float of each cell (a cell that is not one is an error naming it), the time by a
route its type gives (:func:`infer`: integers × the unit, reals as floats below 1e6 s and
as exact decimal text above, ISO-8601 stamps, ...). The first exact pass infers each
range's types and the whole column's from them (:func:`whole_type`); the second
(:func:`exact_rows`) converts each range with them, and the first error in the whole
file's order is the read error.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import LogFormatError
from ..layout import RawRows, rate_times
from .csv_layout import (
    ISO_RE,
    beyond_clock,
    cells_as_floats,
    clock_message,
    csv_parse_error,
    decimal_text_to_ns,
    floats,
    iso_to_ns,
    median_step,
    numbers,
)

#: pyarrow's type inference, in the order it tries types (each accepts the values of
#: every earlier one but where :func:`_fits` says otherwise).
KINDS = ("null", "int64", "bool", "double", "date32[day]", "time32[s]", "timestamp[s]",
         "timestamp[ns]", "timestamp[s, tz=UTC]", "timestamp[ns, tz=UTC]", "string",
         "binary")


def _kind(t: Any) -> int:
    """The position of an inferred pyarrow type in :data:`KINDS`."""
    name = str(t)
    return KINDS.index(name) if name in KINDS else KINDS.index("string")


#: Inferred types whose values another type also accepts (besides null → any type and any
#: type but binary → text or binary): (inferred, whole).
_ACCEPTS = {("int64", "double"), ("date32[day]", "timestamp[s]"),
            ("date32[day]", "timestamp[ns]"), ("timestamp[s]", "timestamp[ns]"),
            ("timestamp[s, tz=UTC]", "timestamp[ns, tz=UTC]")}


def _fits(k: int, whole: int, zero_one: bool) -> bool:
    """Whether values inferred as ``KINDS[k]`` convert as ``KINDS[whole]`` (≥ k)."""
    a, b = KINDS[k], KINDS[whole]
    return (k == whole or a == "null" or b == "binary" or (b == "string" and a != "binary")
            or (a, b) in _ACCEPTS or ((a, b) == ("int64", "bool") and zero_one))


def whole_type(kinds: list[tuple[int, bool]]) -> int:
    """The type pyarrow infers for a whole column from its ranges' inferred types
    ``(kind, only 0 and 1)``: the first in :data:`KINDS` every range converts as."""
    if not kinds:
        return 0
    whole = max(k for k, _ in kinds)
    while not all(_fits(k, whole, z) for k, z in kinds):
        whole += 1
    return whole


@dataclass
class _Column:
    """A column's inferred types over the ranges (the first exact pass)."""

    kinds: list[tuple[int, bool]] = field(default_factory=list)
    nulls: int = 0
    max_abs: float = 0.0


@dataclass
class Exact:
    """How the second exact pass converts each range: the columns' whole types and the
    time's route (``int``, ``float``, ``text``: exact decimal text, ``floats``: Python
    floats of the cells, ``iso``: ISO-8601 stamps), and the errors decided already."""

    types: dict[str, Any]  # column → pyarrow type to parse it as
    route: str
    time_type: Any
    error: LogFormatError | None = None


def infer(ctx: Any) -> Exact:
    """The first exact pass: each column's type as pyarrow infers it over the whole
    file, and the time's route (module docstring)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.csv as pacsv

    lay = ctx.lay
    tname = None if lay.tname is None else ctx.arrow[lay.tname]  # None: --rate
    include = ctx.include_columns()
    infer_opts = pacsv.ConvertOptions(include_columns=include, decimal_point=lay.decimal)
    text_opts = (None if tname is None else
                 pacsv.ConvertOptions(column_types={tname: pa.string()}, include_columns=[tname]))

    def work(parse: Callable[[Any], Any], first: bool) -> Any:
        try:
            table = parse(infer_opts)
            text = (pa.array([], pa.string()) if tname is None
                    else parse(text_opts).column(tname).combine_chunks())
        except Exception as err:
            return err
        out: dict[str, tuple[int, bool, int, float]] = {}
        for c in include:
            a = table.column(c).combine_chunks()
            k = _kind(a.type)
            zero_one, big = False, 0.0
            if str(a.type) in ("int64", "double"):
                v = numbers(pc.fill_null(a, 0) if a.type == pa.int64() else a)
                v = v.astype(np.float64) if a.type == pa.int64() else v
                fin = v[np.isfinite(v) | np.isinf(v)]
                zero_one = bool(np.all((v == 0) | (v == 1) | np.isnan(v)))
                big = float(np.max(np.abs(fin))) if fin.size else 0.0
            out[c] = (k, zero_one, a.null_count, big)
        if lay.decimal == ",":
            text = _comma(text)
        exact_ok = len(text) == 0 or decimal_text_to_ns(text, ctx.unit_ns) is not None
        head = str(text[0].as_py()) if first and len(text) else None
        return table.num_rows, out, exact_ok, head

    cols: dict[str, _Column] = {c: _Column() for c in include}
    rows, exact_ok, head = 0, True, ""
    for got in ctx.ranges(work):
        if isinstance(got, BaseException):
            return Exact({}, "", None, csv_parse_error(lay, got))
        n, out, ok, first_text = got
        rows += n
        exact_ok &= ok
        if first_text is not None:
            head = first_text
        for c, (k, z, nulls, big) in out.items():
            if n:
                cols[c].kinds.append((k, z))
            cols[c].nulls += nulls
            cols[c].max_abs = max(cols[c].max_abs, big)
    if rows < 2:
        return Exact({}, "", None, LogFormatError(
            f"{ctx.where}: holds {rows} data row(s); at least 2 are needed"))
    types = {c: _arrow_type(KINDS[whole_type(col.kinds)]) for c, col in cols.items()}
    if tname is None:
        return Exact(types, "rate", None)
    return _route(ctx, types, cols[tname], exact_ok, head)

def _route(ctx: Any, types: dict[str, Any], tcol: _Column, exact_ok: bool,
           head: str) -> Exact:
    """The time's route, from its whole type (module docstring)."""
    import pyarrow as pa

    tname = ctx.arrow[ctx.lay.tname]
    kind = str(types[tname])
    where, what = ctx.where, ctx.tcol
    iso = kind.startswith("timestamp") or (kind == "string" and bool(ISO_RE.match(head)))
    if iso and ctx.time_unit_given and ctx.fmt == "csv":
        return Exact(types, "", None, LogFormatError(
            f"{where}: --time-unit {ctx.lay.tspec.unit} does not apply: {what} holds "
            "ISO-8601 stamps"))
    ctx.iso = iso
    errors = {"date32[day]": f"{where}: {what} holds {kind} values: give ISO-8601 stamps "
                             "with date and time, or numbers",
              "null": f"{where}: {what}, {ctx.label(0)}: time is not a finite number"}
    errors["time32[s]"] = errors["date32[day]"]
    if kind in errors:
        return Exact(types, "", None, LogFormatError(errors[kind]))
    small = not (tcol.nulls or tcol.max_abs * ctx.unit_ns / 1e9 >= 1e6)
    if iso or kind == "int64" or (kind == "double" and small):
        return Exact(types, "iso" if iso else "int" if kind == "int64" else "float",
                      types[tname])
    if kind in ("double", "string"):  # read as text: exact decimals, else floats
        return Exact(types, "text" if exact_ok else "floats", pa.string())
    return Exact(types, "cells", types[tname])  # bool, binary: floats of the cells

def exact_rows(ctx: Any) -> Iterator[RawRows]:
    """The second exact pass: each range converted with the whole file's types; the
    first error in the whole file's order is the read error (rows stop there)."""
    import pyarrow.csv as pacsv

    plan = ctx.exact
    assert plan is not None
    if plan.error is not None:
        ctx.read_error = plan.error
        return
    lay = ctx.lay
    tname = None if lay.tname is None else ctx.arrow[lay.tname]  # None: --rate
    vcols = [ctx.arrow[c] for c in ctx.key_cols.values()]
    types = dict(plan.types)
    both = tname in vcols and str(plan.time_type) != str(plan.types[tname])
    if tname is not None:
        types[tname] = plan.time_type
    copts = pacsv.ConvertOptions(column_types=types, include_columns=ctx.include_columns(),
                                 decimal_point=lay.decimal)
    vopts = (pacsv.ConvertOptions(column_types={tname: plan.types[tname]},
                                  include_columns=[tname], decimal_point=lay.decimal)
             if both else None)

    def work(parse: Callable[[Any], Any], first: bool) -> Any:
        try:
            table = parse(copts)
            values = parse(vopts) if both else table
        except Exception as err:
            return err
        terr: dict[str, tuple[int, Any]] = {}
        t: np.ndarray | None = None
        if tname is not None:
            t, terr = _time(ctx, table.column(tname).combine_chunks(), plan.route)
        mat = np.empty((table.num_rows, len(vcols)))
        verr: dict[int, tuple[int, Any]] = {}
        for i, c in enumerate(vcols):
            mat[:, i], bad = _values((values if c == tname else table).column(c)
                                     .combine_chunks())
            if bad is not None:
                verr[i] = bad
        return t, terr, mat, verr

    row0 = 0
    time_err: dict[str, tuple[int, Any]] = {}  # kind → (row, what) of the first one
    value_err: dict[int, tuple[int, Any]] = {}
    stopped = False
    for got in ctx.ranges(work):
        if isinstance(got, BaseException):
            ctx.read_error = csv_parse_error(lay, got)
            return
        t, terr, mat, verr = got
        if t is None:
            t = rate_times(row0, mat.shape[0], ctx.sample_rate_hz)
        for kind, (i, what) in terr.items():
            time_err.setdefault(kind, (row0 + i, what))
        for c, (i, v) in verr.items():
            value_err.setdefault(c, (row0 + i, v))
        stopped |= bool(terr or verr)
        if not stopped:
            yield RawRows(row0, t, mat)
        row0 += mat.shape[0]
    ctx.read_error = _first_error(ctx, time_err, value_err, vcols)

def _time(ctx: Any, arr: Any, route: str) -> tuple[np.ndarray, dict[str, tuple[int, Any]]]:
    """A range's time as the whole column is converted (its route), and its errors by
    kind (``empty``, ``iso``: the message, ``text``/``cell``: a cell that is not a
    number, ``finite``, ``clock``: the value), with their rows in the range."""
    import pyarrow as pa

    errs: dict[str, tuple[int, Any]] = {}
    t = np.zeros(len(arr), dtype=np.int64)
    if route in ("iso", "int") and arr.null_count:
        errs["empty"] = (int(np.argmax(arr.is_null().to_numpy(zero_copy_only=False))), None)
    elif route == "iso":
        if arr.type == pa.string() and ctx.lay.decimal == ",":
            arr = _comma(arr)
        try:
            t = iso_to_ns(arr, ctx.where, ctx.tcol, lambda i: f"@ROW{i}@")
        except LogFormatError as err:
            m = re.search(r"@ROW(\d+)@", str(err))
            errs["iso"] = (int(m.group(1)) if m else 0, str(err))
    elif route == "int":
        raw = numbers(arr).astype(np.int64)
        t = _clocked(ctx, raw.astype(np.float64), errs, raw * ctx.unit_ns)
    elif route == "text":
        exact = decimal_text_to_ns(_comma(arr) if ctx.lay.decimal == "," else arr,
                                   ctx.unit_ns)
        assert exact is not None
        t = exact
    else:
        tf = _floats(ctx, arr, route, errs)
        if tf is not None:
            t = _clocked(ctx, tf, errs, None)
    return (t + ctx.offset_ns if ctx.offset_ns and not errs else t), errs

def _floats(ctx: Any, arr: Any, route: str, errs: dict[str, tuple[int, Any]]
            ) -> np.ndarray | None:
    """The float times of a range (``float``, ``floats``: Python's float of the text,
    ``cells``: of the cells), checked finite; None after an error."""
    import pyarrow as pa

    if route == "float":
        tf = numbers(arr.cast(pa.float64()))
    elif route == "cells":
        tf, bad = _values(arr)
        if bad is not None:
            errs["cell"] = bad
            return None
    else:
        if ctx.lay.decimal == ",":
            arr = _comma(arr)
        try:
            tf = floats(arr, ctx.where, ctx.tcol, str)
        except LogFormatError:
            errs["text"] = _first_non_number(arr)
            return None
    fin = np.isfinite(tf)
    if not fin.all():
        errs["finite"] = (int(np.argmax(~fin)), None)
        return None
    return tf

def _clocked(ctx: Any, tf: np.ndarray, errs: dict[str, tuple[int, Any]],
             exact: np.ndarray | None) -> np.ndarray:
    """Times in the unit as int64 ns (``exact``, else rounded), or the clock error."""
    bad = beyond_clock(tf, ctx.unit_ns)
    if bad is not None:
        errs["clock"] = (bad, float(tf[bad]))
        return np.zeros(tf.shape[0], dtype=np.int64)
    return exact if exact is not None else np.round(tf * ctx.unit_ns).astype(np.int64)

def _first_error(ctx: Any, time_err: dict[str, tuple[int, Any]],
                 value_err: dict[int, tuple[int, Any]], vcols: list[str]
                 ) -> LogFormatError | None:
    """The whole file's first error: the time's (a cell that is not a number before a
    time that is not finite or beyond the clock), then the first value column's."""
    where, what = ctx.where, ctx.tcol
    for kind in ("empty", "iso", "text", "cell", "finite", "clock"):
        if kind not in time_err:
            continue
        i, v = time_err[kind]
        at = ctx.label(i)
        if kind == "iso":
            return LogFormatError(re.sub(r"@ROW\d+@", at, str(v)))
        if kind == "clock":
            return LogFormatError(clock_message(v, at, _median(ctx), ctx.unit_ns, where,
                                                what, ctx.lay.tspec.unit))
        return LogFormatError({
            "empty": f"{where}: {what}, {at}: empty time",
            "text": f"{where}: {what}, {at}: non-numeric value {v!r}",
            # a cell of another type is named as a value column's cell is
            "cell": f"{where}: column {ctx.time_name!r}, {at}: non-numeric value {v!r}",
            "finite": f"{where}: {what}, {at}: time is not a finite number"}[kind])
    for c in range(len(vcols)):
        if c in value_err:
            i, v = value_err[c]
            return LogFormatError(f"{where}: column {ctx.names[c]!r}, {ctx.label(i)}: "
                                  f"non-numeric value {v!r}")
    return None

def _median(ctx: Any) -> float:
    """The median step of the time column's finite values (a clock error's hint): a
    pass over the file's time, converted as the route does."""
    import pyarrow.csv as pacsv

    plan = ctx.exact
    assert plan is not None
    tname = ctx.arrow[ctx.lay.tname]
    copts = pacsv.ConvertOptions(column_types={tname: plan.time_type},
                                 include_columns=[tname], decimal_point=ctx.lay.decimal)

    def work(parse: Callable[[Any], Any], first: bool) -> np.ndarray | None:
        arr = parse(copts).column(tname).combine_chunks()
        if plan.route == "int":
            return numbers(arr).astype(np.float64)
        return _floats(ctx, arr, plan.route, {})

    parts = [p for p in ctx.ranges(work)
             if p is not None]
    values = np.concatenate(parts) if parts else np.zeros(0)
    return median_step(values)


def _comma(arr: Any) -> Any:
    import pyarrow.compute as pc

    return pc.replace_substring(arr, ",", ".")


def _arrow_type(name: str) -> Any:
    """The pyarrow type of a name of :data:`KINDS`."""
    import pyarrow as pa

    return {"null": pa.null(), "int64": pa.int64(), "bool": pa.bool_(),
            "double": pa.float64(), "date32[day]": pa.date32(), "time32[s]": pa.time32("s"),
            "timestamp[s]": pa.timestamp("s"), "timestamp[ns]": pa.timestamp("ns"),
            "timestamp[s, tz=UTC]": pa.timestamp("s", tz="UTC"),
            "timestamp[ns, tz=UTC]": pa.timestamp("ns", tz="UTC"),
            "string": pa.string(), "binary": pa.binary()}[name]


def _first_non_number(arr: Any) -> tuple[int, Any]:
    """The first cell of a column that is not a number (Python's float), and it."""
    for i, v in enumerate(arr.to_pylist()):
        try:
            float(v) if v is not None else None
        except (TypeError, ValueError):
            return i, v
    return 0, None


def _values(arr: Any) -> tuple[np.ndarray, tuple[int, Any] | None]:
    """A value column of a range as float64 as the whole column is converted (integers
    and reals as numbers, nulls NaN, anything else by Python's float of each cell), and
    its first cell that is not a number."""
    import pyarrow as pa

    if pa.types.is_integer(arr.type) or pa.types.is_floating(arr.type):
        return numbers(arr.cast(pa.float64())), None
    if pa.types.is_null(arr.type):
        return np.full(len(arr), np.nan), None
    return cells_as_floats(arr)


