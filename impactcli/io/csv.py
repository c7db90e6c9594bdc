"""Canonical wide CSV and channel-mapped CSV (formats.md, "Canonical wide CSV", "Channel maps").

Reading uses ``pyarrow.csv`` (multi-threaded, ``.gz`` decompressed on the fly). The time
column is read as text and converted to int64 ns exactly (no float rounding) whenever it is
written as plain decimals; ``time_ns`` is read as int64.

Writing produces the canonical layout: ``time`` in seconds with 9 decimals (exact in ns),
then per joint ``<joint>.position``, ``<joint>.torque`` and the optional signals, values in
shortest round-trip (repr) precision — reading the file back gives the same RobotLog.
"""

from __future__ import annotations

import gzip
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ChannelMapError, LogFormatError
from ..types import RobotLog
from .assemble import JointChannels
from .channel_map import SIGNALS, TIME_UNITS, ChannelMap, ChannelRef, TimeSpec, require_time
from .repair import repair_samples

#: Recognised time columns of a canonical CSV, by preference.
TIME_COLUMNS: tuple[str, ...] = ("time_ns", "time", "__time")


def _is_gz(path: Path) -> bool:
    return path.name.lower().endswith(".gz")


def _first_line(path: Path, skip: int = 0) -> str:
    opener: Any = gzip.open if _is_gz(path) else open
    try:
        with opener(path, "rt", encoding="utf-8", errors="replace", newline="") as f:
            for _ in range(skip):
                f.readline()
            return str(f.readline())
    except (OSError, EOFError) as err:
        raise LogFormatError(f"{path}: cannot read: {err}") from err


def canonical_map(header: list[str], path: str) -> tuple[ChannelMap, list[str]]:
    """The channel map implied by a canonical CSV header, and the ignored columns.

    Raises:
        LogFormatError: no time column, or no joint with a position.
    """
    tcol = next((c for c in TIME_COLUMNS if c in header), None)
    if tcol is None:
        raise LogFormatError(
            f"{path}: no time column (one of {', '.join(TIME_COLUMNS)}); for other layouts "
            "pass a channel map (--channel-map)"
        )
    unit = "ns" if tcol == "time_ns" else "s"
    joints: dict[str, dict[str, ChannelRef]] = {}
    ignored: list[str] = []
    for col in header:
        if col == tcol:
            continue
        joint, dot, sig = col.partition(".")
        if dot and joint and sig in SIGNALS:
            joints.setdefault(joint, {})[sig] = ChannelRef(source=col)
        else:
            ignored.append(col)
    # a "joint" without a position is not a joint: its columns are ignored
    for j in [j for j, sigs in joints.items() if "position" not in sigs]:
        ignored += [f"{j}.{s}" for s in joints.pop(j)]
    if not joints:
        raise LogFormatError(
            f"{path}: no '<joint>.position' column; for other layouts pass a channel map "
            "(--channel-map)"
        )
    names = tuple(joints)
    signals = {
        s: tuple(joints[j].get(s) for j in names)
        for s in SIGNALS
        if any(s in joints[j] for j in names)
    }
    cmap = ChannelMap(
        name="canonical", time=TimeSpec(ChannelRef(tcol), unit=unit), joints=names,
        signals=signals, path="", header=True,
    )
    return cmap, ignored


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
    whole = pc.cast(pc.list_element(parts, 0), pa.int64()).to_numpy()
    frac_txt = pc.list_element(parts, 1)
    frac_txt = pc.utf8_slice_codeunits(pc.utf8_rpad(frac_txt, 9, "0"), 0, 9)
    frac = pc.cast(frac_txt, pa.int64()).to_numpy()  # units of 1e-9 of `unit`
    if unit_ns == 10**9:
        ns = whole * 10**9 + frac
    else:
        ns = whole * unit_ns + np.round(frac * (unit_ns / 1e9)).astype(np.int64)
    out: np.ndarray = np.where(neg, -ns, ns).astype(np.int64)
    return out


def _ragged_line(path: Path, skip: int, delim: str, expected: int) -> int | None:
    """The 1-based line number of the first data line with another number of fields than
    ``expected`` (only to name it in an error; quoted delimiters are not considered)."""
    opener: Any = gzip.open if _is_gz(path) else open
    try:
        with opener(path, "rt", encoding="utf-8", errors="replace", newline="") as f:
            for n, line in enumerate(f, 1):
                if n > skip and line.strip() and line.count(delim) + 1 != expected:
                    return n
    except (OSError, EOFError):
        return None
    return None


def _row_labeller(skip: int) -> Any:
    def label(i: int) -> str:
        return f"row {i + 1} (line {i + 1 + skip})"

    return label


def read_csv_channels(path: Path, cmap: ChannelMap | None) -> tuple[JointChannels, str]:
    """Read a CSV (canonical, or through ``cmap``) into :class:`JointChannels`.

    Returns:
        ``(channels, format)`` with format ``csv`` or ``csv-mapped``.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    where = str(path)
    header = True if cmap is None else cmap.header
    skip = 0 if cmap is None else cmap.skip_rows
    delim = "," if cmap is None else cmap.delimiter
    line = _first_line(path, skip)
    if not line.strip():
        raise LogFormatError(f"{where}: empty file (no header or data)")
    if header:
        names = [c.strip().strip('"') for c in line.rstrip("\r\n").split(delim)]
    else:
        names = [f"f{i}" for i in range(len(line.split(delim)))]
    ignored_extra: list[str] = []
    if cmap is None:
        cmap, ignored_extra = canonical_map(names, where)
        fmt = "csv"
    else:
        fmt = "csv-mapped"

    def colname(ref: ChannelRef, what: str) -> str:
        if isinstance(ref.source, int):
            if ref.source >= len(names):
                raise ChannelMapError(
                    f"{where}: channel map {cmap.path or cmap.name}: {what} points at column "
                    f"{ref.source} (0-based), but the file has {len(names)} columns "
                    f"(0–{len(names) - 1}): is this the file the map was written for?"
                )
            return names[ref.source]
        if ref.source not in names:
            raise ChannelMapError(
                f"{where}: channel map {cmap.path or cmap.name}: {what} points at column "
                f"{ref.source!r}, which is not in the file"
            )
        return ref.source

    tspec = require_time(cmap, where)
    tname = colname(tspec.ref, "time")
    used = {tname}
    refs = cmap.refs()
    for sig, j, ref in refs:
        used.add(colname(ref, f"{cmap.joints[j]}.{sig}"))
    def read(types: dict[str, Any], include: list[str] | None = None) -> Any:
        try:
            return pacsv.read_csv(
                path,
                read_options=pacsv.ReadOptions(
                    skip_rows=skip, autogenerate_column_names=not header, block_size=1 << 24,
                ),
                parse_options=pacsv.ParseOptions(delimiter=delim),
                convert_options=pacsv.ConvertOptions(column_types=types,
                                                     include_columns=include),
            )
        except (pa.ArrowInvalid, OSError) as err:
            msg = str(err).splitlines()[0]
            m = re.search(r"Expected (\d+) columns, got (\d+)", msg)
            if m:
                at = _ragged_line(path, skip, delim, int(m.group(1)))
                if at is not None:
                    msg = (f"line {at}: {m.group(2)} fields where the header has "
                           f"{m.group(1)}" + msg[m.end():])
            raise LogFormatError(f"{where}: cannot parse CSV: {msg}") from err

    # Time is parsed as float64 when that is exact to the nanosecond: decimal text with at
    # most 9 decimals below 1e6 s rounds back to its integer ns (half an ulp plus the
    # product's rounding stay below 0.2 ns). Larger (epoch) times are re-read as text and
    # converted exactly by decimal_text_to_ns.
    table = read({})
    if header:
        names = list(table.column_names)
    n = table.num_rows
    if n < 2:
        raise LogFormatError(f"{where}: holds {n} data row(s); at least 2 are needed")
    label = _row_labeller(skip + (1 if header else 0))

    def disp(col: str) -> str:
        return col if header else f"column {int(col[1:])}"

    def numeric(col: str) -> np.ndarray:
        arr = table.column(col)
        if pa.types.is_integer(arr.type) or pa.types.is_floating(arr.type):
            return np.asarray(arr.cast(pa.float64()).to_numpy(), dtype=np.float64).copy()
        if pa.types.is_null(arr.type):
            return np.full(n, np.nan)
        vals = arr.to_pylist()
        for i, v in enumerate(vals):
            try:
                float(v) if v is not None else None
            except (TypeError, ValueError):
                raise LogFormatError(
                    f"{where}: column {disp(col)!r}, {label(i)}: non-numeric value {v!r}"
                ) from None
        return np.array([np.nan if v is None else float(v) for v in vals], dtype=np.float64)

    # time
    tarr = table.column(tname).combine_chunks()
    unit_ns = TIME_UNITS[tspec.unit]
    if pa.types.is_integer(tarr.type):
        if tarr.null_count:
            i = int(np.argmax(tarr.is_null().to_numpy(zero_copy_only=False)))
            raise LogFormatError(f"{where}: column {disp(tname)!r}, {label(i)}: empty time")
        t_ns = tarr.to_numpy().astype(np.int64) * unit_ns
    else:
        if pa.types.is_floating(tarr.type) and (
            tarr.null_count or float(np.nanmax(np.abs(tarr.to_numpy(zero_copy_only=False))))
            * unit_ns / 1e9 >= 1e6
        ):
            tarr = read({tname: pa.string()}, [tname]).column(tname).combine_chunks()
        exact = decimal_text_to_ns(tarr, unit_ns) if pa.types.is_string(tarr.type) else None
        if exact is not None:
            t_ns = exact
        else:
            tf = numeric(tname)
            if not np.all(np.isfinite(tf)):
                i = int(np.argmax(~np.isfinite(tf)))
                raise LogFormatError(
                    f"{where}: column {disp(tname)!r}, {label(i)}: time is not a finite number"
                )
            t_ns = np.round(tf * unit_ns).astype(np.int64)
    if tspec.offset:
        t_ns = t_ns + round(tspec.offset * unit_ns)
    # signals
    cols: dict[str, np.ndarray] = {}
    keys: dict[tuple[str, int], str] = {}
    for sig, j, ref in refs:
        col = colname(ref, f"{cmap.joints[j]}.{sig}")
        key = col if header else disp(col)
        keys[(sig, j)] = key
        if key not in cols:
            cols[key] = numeric(col)
    t_ns, cols, repairs = repair_samples(
        t_ns, cols, where=where, time_name=disp(tname), row_label=label
    )
    if tspec.start_at_zero:
        t_ns = t_ns - t_ns[0]
    ignored = ignored_extra if fmt == "csv" else [disp(c) for c in names if c not in used]
    return channels_from_columns(cmap, t_ns, cols, keys, ignored, repairs), fmt


def channels_from_columns(
    cmap: ChannelMap,
    t_ns: np.ndarray,
    cols: dict[str, np.ndarray],
    keys: dict[tuple[str, int], str],
    ignored: list[str],
    repairs: list[str],
) -> JointChannels:
    """Apply scale/offset and stack per-joint columns into (N, J) signals."""
    n, jn = t_ns.shape[0], len(cmap.joints)
    signals: dict[str, np.ndarray] = {}
    missing: dict[str, list[str]] = {}
    current_scale = np.full(jn, np.nan)
    for sig, per in cmap.signals.items():
        m = np.full((n, jn), np.nan)
        for j, ref in enumerate(per):
            if ref is None:
                missing.setdefault(sig, []).append(cmap.joints[j])
                continue
            v = cols[keys[(sig, j)]]
            if sig == "current":
                if ref.scale is not None:
                    current_scale[j] = ref.scale
                m[:, j] = v  # the current as logged; its scale converts it to torque
                continue
            if ref.scale is not None:
                v = v * ref.scale
            if ref.offset:
                v = v + ref.offset
            m[:, j] = v
        signals[sig] = m
    return JointChannels(
        t_ns=t_ns, joints=cmap.joints, signals=signals, missing=missing,
        current_scale=current_scale, ignored=ignored, repairs=repairs,
    )


def _ns_to_decimal(t_ns: np.ndarray) -> Any:
    """int64 ns → pyarrow strings of seconds with 9 decimals (exact), e.g. ``-0.500000000``."""
    import pyarrow as pa
    import pyarrow.compute as pc

    t = np.asarray(t_ns, dtype=np.int64)
    sec, frac = np.divmod(np.abs(t), 10**9)
    txt = pc.binary_join_element_wise(
        pc.cast(pa.array(sec), pa.string()),
        pc.utf8_lpad(pc.cast(pa.array(frac), pa.string()), 9, "0"),
        ".",
    )
    if np.any(t < 0):
        txt = pc.if_else(pa.array(t < 0), pc.binary_join_element_wise("-", txt, ""), txt)
    return txt


def canonical_columns(log: RobotLog) -> list[tuple[str, np.ndarray]]:
    """The canonical CSV's value columns: (name, (N,) values) in file order."""
    out: list[tuple[str, np.ndarray]] = []
    for j, name in enumerate(log.joint_names):
        for sig in SIGNALS:
            arr = getattr(log, sig)
            if arr is not None and log.has_channel(sig)[j]:
                out.append((f"{name}.{sig}", arr[:, j]))
    return out


def write_csv(log: RobotLog, path: str | os.PathLike[str]) -> None:
    """Write ``log`` as canonical wide CSV (``.csv``, or gzip for ``.csv.gz``), atomically.

    ``time`` holds seconds on the log's own clock with 9 decimals (exact ns); values are
    written in shortest round-trip precision, so :func:`read_log` returns the same arrays.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from .._fs import atomic_output

    cols = canonical_columns(log)
    table = pa.table(
        {"time": _ns_to_decimal(np.asarray(log.t_ns))}
        | {name: pa.array(np.ascontiguousarray(v)) for name, v in cols}
    )
    head = ",".join(["time"] + [c for c, _ in cols]) + "\n"
    opts = pacsv.WriteOptions(include_header=False, quoting_style="none")
    p = Path(path)
    with atomic_output(p, "wb") as f:
        if _is_gz(p):
            with gzip.GzipFile(fileobj=f, mode="wb", compresslevel=1, mtime=0) as gz:
                gz.write(head.encode())
                pacsv.write_csv(table, gz, opts)
        else:
            f.write(head.encode())
            pacsv.write_csv(table, f, opts)
