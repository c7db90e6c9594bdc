"""What a CSV's header line says: its names, its separator and its time column
(docs/formats.md, "Canonical wide CSV", "Channel maps").

Names and cells are read with the blanks around separators stripped (``time, q, tau``, as
``printf`` loggers write), and a name's quotes removed (:func:`header_names`). The
separator is the one with which the header names what the reader looks for: a canonical
CSV's time column (else a ``<joint>.position`` column), a channel map's columns
(:func:`mapped_separator`; a map's ``csv.delimiter`` forces one). A time column is
recognised by its name, case-insensitively (:func:`find_time_column`): ``time``,
``__time`` (PlotJuggler), ``timestamp``, ``stamp`` or ``t``, each also with a unit suffix
``_s``, ``_ms``, ``_us`` or ``_ns`` — the unit of its numbers (:func:`name_unit`; without a
suffix seconds, or ``--time-unit``). ``--time-column NAME`` names any other column; a log
without any time column is read with ``--rate HZ`` (sample i at i / HZ s).
"""

from __future__ import annotations

import warnings

from ...errors import ImpactWarning, LogFormatError
from ...sample_channels import CHANNEL_NAMES
from ..channel_map import TIME_UNITS, ChannelMap, ChannelRef, TimeSpec

#: Separators a CSV's header is split at, tried in this order.
SEPARATORS: tuple[str, ...] = (",", ";", "\t", " ")
#: Separators tried on a headerless file's first data line, in this order (a decimal comma
#: makes ``,`` split a ``;`` or tab separated line too: those first).
HEADERLESS_SEPARATORS: tuple[str, ...] = ("\t", ";", ",", " ")
#: Names of a time column without their unit suffix, by preference (lower case).
TIME_NAMES: tuple[str, ...] = ("time", "__time", "timestamp", "stamp", "t")
#: Unit suffixes of a time column's name (``time_ms``), by preference.
UNIT_SUFFIXES: dict[str, str] = {"_ns": "ns", "_us": "us", "_ms": "ms", "_s": "s"}
#: Recognised time columns (lower case), by preference: ``time_ns`` … ``time``, ``__time``…
TIME_COLUMNS: tuple[str, ...] = tuple(
    base + suffix for base in TIME_NAMES for suffix in (*UNIT_SUFFIXES, ""))
#: A joint's column read as its torque when it has no ``.torque``: ROS JointState's name.
EFFORT = "effort"
#: How messages list the recognised time columns.
TIME_COLUMNS_TEXT = ("time, timestamp, stamp, t or PlotJuggler's __time, any case, with an "
                     "optional unit suffix _s, _ms, _us or _ns")


def header_names(line: str, delim: str) -> list[str]:
    """The column names of a header ``line`` split at ``delim``: blanks around each name
    and its double quotes removed (``"time", q1`` → ``time``, ``q1``)."""
    return [c.strip().strip('"').strip() for c in line.rstrip("\r\n").split(delim)]


def name_unit(name: str) -> str | None:
    """The unit a time column's name says: its suffix's (``time_ms`` → ``ms``), ``s`` for
    PlotJuggler's ``__time`` (epoch seconds); None when the name says none."""
    low = name.lower()
    if low == "__time":
        return "s"
    for suffix, unit in UNIT_SUFFIXES.items():
        if low.endswith(suffix) and len(low) > len(suffix):
            return unit
    return None


def find_time_column(names: list[str]) -> str | None:
    """The header's time column: the first of :data:`TIME_COLUMNS` it has, in any case
    (of two names differing only in case, the first in the header); None without one."""
    low = [n.lower() for n in names]
    for want in TIME_COLUMNS:
        if want in low:
            return names[low.index(want)]
    return None


def pick_column(names: list[str], name: str, where: str, what: str) -> str:
    """The header's column ``name`` (exactly, else the one column equal to it in any case),
    or the LogFormatError listing the columns."""
    if name in names:
        return name
    same = [n for n in names if n.lower() == name.lower()]
    if len(same) == 1:
        return same[0]
    shown = ", ".join(names[:30]) + (f", … ({len(names)} columns)" if len(names) > 30 else "")
    raise LogFormatError(f"{where}: {what} {name!r} is not a column of the file (its "
                         f"columns: {shown})")


def _is_position(name: str) -> bool:
    joint, dot, sig = name.partition(".")
    return bool(dot and joint and sig == "position")


def separator(line: str, time_column: str | None = None) -> str:
    """A canonical CSV's separator: the first of :data:`SEPARATORS` with which the header
    ``line`` names a time column (``time_column``, any case, when given), else a
    ``<joint>.position`` column (a log read with ``--rate``); ``,`` when none does."""
    def splits(test: object) -> str | None:
        for sep in SEPARATORS:
            if any(test(c) for c in header_names(line, sep)):  # type: ignore[operator]
                return sep
        return None

    if time_column is not None:
        want = time_column.lower()
        found = splits(lambda c: c.lower() == want)
    else:
        found = splits(lambda c: c.lower() in TIME_COLUMNS)
    return found or splits(_is_position) or ","


def mapped_separator(cmap: ChannelMap, line: str) -> str:
    """The separator of a CSV read through ``cmap`` when the map does not force one: with
    a header, the first of :data:`SEPARATORS` with which the header ``line`` names most of
    the columns the map names (the time's first); without one (or a map naming columns by
    index only), the first of :data:`HEADERLESS_SEPARATORS` that splits ``line`` (the
    first data line) into enough fields for the map's largest index. ``,`` when none
    does."""
    refs = [r for _, _, r in cmap.refs()]
    if cmap.time is not None:
        refs.insert(0, cmap.time.ref)
    named = [str(r.source) for r in refs if isinstance(r.source, str)]
    if cmap.header and named:
        best, score = ",", (0, 0)
        for sep in SEPARATORS:
            names = set(header_names(line, sep))
            got = (int(named[0] in names), sum(n in names for n in named))
            if got > score:
                best, score = sep, got
        return best
    need = 1 + max((int(r.source) for r in refs if isinstance(r.source, int)), default=0)
    for sep in HEADERLESS_SEPARATORS:
        if len(line.rstrip("\r\n").split(sep)) >= max(need, 2):
            return sep
    return ","


def canonical_map(header: list[str], path: str, time_unit: str | None = None, *,
                  time_column: str | None = None, rate: float | None = None
                  ) -> tuple[ChannelMap, list[str]]:
    """The channel map implied by a canonical CSV header, and the ignored columns.

    Args:
        header: the column names.  path: the file, for messages.
        time_unit: ``--time-unit``: the time column's unit (``s``, ``ms``, ``us``, ``ns``);
            None: the unit its name says (``time_ms``), else s. Given, it wins over the
            name (warned).
        time_column: ``--time-column``: the time column's name (else recognised by name,
            :func:`find_time_column`).
        rate: ``--rate`` [Hz]: sample i is at i / rate (the map's ``time`` is None); a time
            column is then not read as the clock (warned).

    A joint's ``.effort`` column (ROS JointState's name) is its torque when it has no
    ``.torque`` (with both, ``.torque`` wins, warned).

    Raises:
        LogFormatError: no time column (without ``rate``), no joint with a position, a
            ``time_column`` not in the header.
    """
    if time_unit is not None and time_unit not in TIME_UNITS:
        raise LogFormatError(f"{path}: unknown time unit {time_unit!r} (s, ms, us or ns)")
    if time_column is not None:
        tcol: str | None = pick_column(header, time_column, path, "--time-column")
        named_col = find_time_column(header)
        if named_col is not None and named_col != tcol:
            warnings.warn(f"{path}: --time-column {tcol!r} given: the column {named_col!r}, "
                          "a time column by its name, is not read as the log's clock",
                          ImpactWarning, stacklevel=2)
    else:
        tcol = find_time_column(header)
    time: TimeSpec | None = None
    if rate is not None:
        if tcol is not None:  # the user's rate wins: the column is not the clock
            warnings.warn(
                f"{path}: --rate {rate:g} given: sample i is placed at i / {rate:g} s and "
                f"the time column {tcol!r} is not read as the log's clock", ImpactWarning,
                stacklevel=2)
    elif tcol is None:
        raise LogFormatError(
            f"{path}: no time column (recognised: {TIME_COLUMNS_TEXT}): name yours with "
            "--time-column NAME, give --rate HZ for a log without one, or pass a channel "
            "map (--channel-map) for other layouts")
    else:
        named = name_unit(tcol)
        if time_unit is not None and named is not None and time_unit != named:
            warnings.warn(f"{path}: --time-unit {time_unit} given: column {tcol!r} is read "
                          f"in {time_unit}, not in {named} as its name says", ImpactWarning,
                          stacklevel=2)
        time = TimeSpec(ChannelRef(tcol), unit=time_unit or named or "s")
    joints: dict[str, dict[str, ChannelRef]] = {}
    ignored: list[str] = []
    efforts: dict[str, str] = {}  # joint → its ROS-style `.effort` column
    for col in header:
        if col == tcol:
            continue
        joint, dot, sig = col.partition(".")
        if dot and joint and sig in CHANNEL_NAMES:
            joints.setdefault(joint, {})[sig] = ChannelRef(source=col)
        elif dot and joint and sig == EFFORT:
            efforts[joint] = col
        else:
            ignored.append(col)
    for joint, col in efforts.items():  # ROS's JointState effort: the joint's torque
        sigs = joints.setdefault(joint, {})
        if "torque" in sigs:
            ignored.append(col)
            warnings.warn(f"{path}: joint {joint!r} has both {sigs['torque'].source!r} and "
                          f"{col!r}: {sigs['torque'].source!r} is read as its torque, "
                          f"{col!r} ignored", ImpactWarning, stacklevel=2)
        else:
            sigs["torque"] = ChannelRef(source=col)
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
        for s in CHANNEL_NAMES
        if any(s in joints[j] for j in names)
    }
    cmap = ChannelMap(name="canonical", time=time, joints=names, signals=signals, path="",
                      header=True)
    return cmap, ignored
