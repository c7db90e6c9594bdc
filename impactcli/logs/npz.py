"""NumPy ``.npz`` archives through a ``format: npz`` channel map (docs/formats.md, "Channel
maps"): its reader for the one scan (:mod:`impactcli.logs.scan`), block by block.

Arrays are addressed by key; a 2-D array (N, k) by key plus column ``index``. Every array
used must have the time array's length N. Integer time is multiplied by its unit, float
time in ``unit`` is rounded to ns, then the map's offset is added.

The archive is a zip of ``.npy`` members. Each member the map uses is opened as a stream
(:mod:`zipfile` decompresses a deflated member as it is read), its ``.npy`` header parsed,
and its rows read :data:`BLOCK_ROWS` at a time: memory holds one block of every array used,
whatever the archive's length. A member in Fortran order or of a ``.npy`` version other
than 1.0 or 2.0 is read whole (that one array). The archive is checked as a whole array
of each member would be: the first problem in the map's order (the time, then each
channel) is the error — an array missing, of another shape, length or type, or one that
cannot be read (its message is NumPy's own for that member).
"""

from __future__ import annotations

import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np

from ..errors import ChannelMapError, LogFormatError
from ..sample_channels import DROPPABLE_CHANNELS
from .layout import MappedLayout, RawRows, plan_of, rate_times

#: Rows read from each array at a time.
BLOCK_ROWS = 65_536
#: The errors of reading a member (NumPy's and zipfile's).
READ_ERRORS = (ValueError, zipfile.BadZipFile, zlib.error, EOFError, OSError)



def warn_rate_against_array(path: Any, where: str, tspec: Any, rate: float) -> None:
    """With ``--rate`` on an archive whose map names a time array: warn when its first
    rows' average step implies a rate off ``rate`` (as a CSV's time column,
    :func:`impactcli.logs.csv.csv_layout.warn_rate_against_column`)."""
    from .csv.csv_layout import RATE_CHECK_ROWS, warn_rate_against_times

    try:
        with np.load(path, allow_pickle=False) as archive:
            if str(tspec.ref.source) not in archive.files:
                return
            a = np.asarray(archive[str(tspec.ref.source)])  # (a time array: 8 bytes a row)
    except READ_ERRORS:
        return
    if a.ndim == 2 and tspec.ref.index is not None:
        a = a[:, tspec.ref.index]
    if a.ndim != 1 or a.dtype.kind not in "iuf":
        return
    warn_rate_against_times(a[:RATE_CHECK_ROWS].astype(np.float64), tspec.unit, rate, where,
                            f"array {tspec.ref.label()!r}", "array")

class _Whole(Exception):
    """A member read whole (a ``.npy`` version or order the blocks do not read)."""


def _header(f: IO[bytes]) -> tuple[tuple[int, ...], bool, np.dtype[Any]]:
    """``(shape, fortran_order, dtype)`` of the ``.npy`` stream ``f`` (left at its data)."""
    from numpy.lib import format as npf

    version = npf.read_magic(f)
    if version == (1, 0):
        return npf.read_array_header_1_0(f)  # type: ignore[no-any-return]
    if version == (2, 0):
        return npf.read_array_header_2_0(f)  # type: ignore[no-any-return]
    raise _Whole


class NpzLayout(MappedLayout):
    """An ``.npz`` archive and its map (module docstring)."""

    def __init__(self, p: Path, where: str, cmap: Any, options: dict[str, Any]) -> None:
        from .channel_map import TIME_UNITS, require_time

        self.path, self.where, self.fmt, self.cmap = p, where, "npz", cmap
        self.joints = tuple(cmap.joints)
        self.repair_order = bool(options.get("repair_order", False))
        try:
            with np.load(p, allow_pickle=False) as archive:  # NumPy's errors for the file
                keys = list(archive.files)
        except READ_ERRORS as err:
            raise LogFormatError(f"{where}: not a readable .npz archive: {err}") from err
        rate = options.get("rate")
        self.sample_rate_hz = None if rate is None else float(rate)
        if self.sample_rate_hz is None:
            tspec = require_time(cmap, where)
            self.tref: Any = tspec.ref
            self.tkey: str | None = str(tspec.ref.source)
            self.time_name = str(self.tkey)
            self.unit, self.unit_ns = tspec.unit, TIME_UNITS[tspec.unit]
            self.offset_ns = round(tspec.offset * self.unit_ns) if tspec.offset else 0
            self.start_at_zero = bool(tspec.start_at_zero)
        else:  # --rate: no time array read as the clock; the map's, if any, compared
            self.tref, self.tkey, self.time_name = None, None, "--rate"
            self.unit, self.unit_ns, self.offset_ns = "s", 10**9, 0
            if cmap.time is not None:
                warn_rate_against_array(p, where, cmap.time, self.sample_rate_hz)
        # the columns: (signal, joint) → label, label → (array key, column index or None)
        self.keys = {}
        self.cols: dict[str, tuple[str, int | None]] = {}
        for sig, j, ref in cmap.refs():
            self.keys[(sig, j)] = ref.label()
            self.cols.setdefault(ref.label(), (str(ref.source), ref.index))
        self.names = list(self.cols)
        self.droppable = {lab for (sig, _), lab in self.keys.items() if sig in DROPPABLE_CHANNELS}
        used = {str(r.source) for _, _, r in cmap.refs()} | (
            {self.tkey} if self.tkey is not None else set())
        self.ignored = [k for k in keys if k not in used]
        self.archive_keys = keys
        self.shapes: dict[str, tuple[tuple[int, ...], np.dtype[Any]]] = {}
        self.whole: dict[str, np.ndarray] = {}  # members read whole
        self.n = self._check(cmap)
        self.time_error: LogFormatError | None = None
        self.plan = plan_of(self, options)

    # -- the archive as a whole array of each member would be read
    def _member(self, key: str) -> str:
        return key + ".npy" if key + ".npy" in self._members else key

    def _read_error(self, key: str) -> LogFormatError | None:
        """The error of reading member ``key`` whole (None: it reads); checked by a pass
        over its bytes, the message NumPy's own."""
        try:
            with zipfile.ZipFile(self.path) as zf, zf.open(self._member(key)) as f:
                shape, _fortran, dtype = _header(f)
                size = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
                got = 0
                while True:
                    data = f.read(1 << 22)
                    if not data:
                        break
                    got += len(data)
                if got >= size:
                    return None
        except _Whole:
            pass
        except READ_ERRORS:
            pass
        try:
            with np.load(self.path, allow_pickle=False) as archive:
                np.asarray(archive[key])
        except READ_ERRORS as err:  # object arrays need pickle (refused); a corrupt member
            return LogFormatError(f"{self.where}: array {key!r} cannot be read: {err}")
        return None

    def _array_header(self, key: str, read: list[str]) -> tuple[tuple[int, ...], Any]:
        """The shape and dtype of member ``key``; a member the blocks cannot read is read
        whole (:data:`whole`). ``read``: the members read so far (in the map's order)."""
        if key in self.shapes:
            return self.shapes[key]
        try:
            with zipfile.ZipFile(self.path) as zf, zf.open(self._member(key)) as f:
                shape, fortran, dtype = _header(f)
            if fortran:
                raise _Whole
        except (_Whole, *READ_ERRORS):
            err = self._first_error([*read, key])
            if err is not None:
                raise err from None
            with np.load(self.path, allow_pickle=False) as archive:
                a = np.asarray(archive[key])
            self.whole[key] = a
            shape, dtype = a.shape, a.dtype
        self.shapes[key] = (shape, dtype)
        read.append(key)
        return shape, dtype

    def _first_error(self, keys: list[str]) -> LogFormatError | None:
        """The read error of the first member of ``keys`` that cannot be read."""
        for k in dict.fromkeys(keys):
            err = self._read_error(k)
            if err is not None:
                return err
        return None

    def _check(self, cmap: Any) -> int:
        """The archive against the map, in the order a whole read checks it: the time,
        then each channel (module docstring). Returns the arrays' length N."""
        with zipfile.ZipFile(self.path) as zf:
            self._members = zf.namelist()
        where, mapname = self.where, cmap.path or cmap.name
        read: list[str] = []

        def get(ref: Any, what: str) -> tuple[tuple[int, ...], Any]:
            key = str(ref.source)
            if key not in self.archive_keys:
                err = self._first_error(read)
                raise err or ChannelMapError(
                    f"{where}: channel map {mapname}: {what} points at array {key!r}, which "
                    f"is not in the archive (keys: {', '.join(self.archive_keys)})")
            shape, dtype = self._array_header(key, read)
            bad: ChannelMapError | None = None
            if ref.index is None:
                if len(shape) != 1:
                    bad = ChannelMapError(
                        f"{where}: channel map {mapname}: {what}: array {key!r} has shape "
                        f"{shape}; give a column 'index'")
                return_shape = shape
            else:
                if len(shape) != 2 or ref.index >= shape[1]:
                    bad = ChannelMapError(
                        f"{where}: channel map {mapname}: {what}: column {ref.index} does not "
                        f"exist in array {key!r} of shape {shape}")
                return_shape = shape[:1]
            if bad is not None:
                raise self._first_error(read) or bad
            return return_shape, dtype

        if self.tref is not None:
            tshape, tdtype = get(self.tref, "time")
        else:  # --rate: the length of the first array the map names
            sig0, j0, ref0 = cmap.refs()[0]
            tshape, tdtype = get(ref0, f"{cmap.joints[j0]}.{sig0}")
        n = tshape[0]
        for sig, j, ref in cmap.refs():
            what = f"{cmap.joints[j]}.{sig}"
            shape, dtype = get(ref, what)
            err: LogFormatError | None = None
            if shape[0] != n:
                first = (repr(self.tkey) if self.tkey is not None
                         else repr(cmap.refs()[0][2].label()))
                err = LogFormatError(
                    f"{where}: mismatched channel lengths: {first} has {n} samples but "
                    f"{ref.label()!r} ({what}) has {shape[0]}")
            elif not np.issubdtype(dtype, np.number) or np.issubdtype(dtype,
                                                                       np.complexfloating):
                err = LogFormatError(f"{where}: array {ref.label()!r} is not real numbers "
                                     f"({dtype})")
            if err is not None:
                raise self._first_error(read) or err
        if self.tkey is not None and not (np.issubdtype(tdtype, np.integer)
                                          or np.issubdtype(tdtype, np.floating)):
            raise self._first_error(read) or LogFormatError(
                f"{where}: time array {self.tkey!r} is not numeric ({tdtype})")
        self.read_order = read
        return int(n)

    def rate_error(self, sample_rate_hz: float, duration_s: float | None = None) -> str | None:
        from .repair import rate_message

        if self.sample_rate_hz is not None:
            return rate_message(self.sample_rate_hz, self.where, "--rate", None, duration_s)
        return rate_message(sample_rate_hz, self.where, f"array {self.tkey!r}", self.unit,
                            duration_s)

    def _time(self, raw: np.ndarray, row0: int) -> np.ndarray:
        """A block of the time array → int64 ns (integers × the unit, floats rounded)."""
        if np.issubdtype(raw.dtype, np.integer):
            t = raw.astype(np.int64) * self.unit_ns
        else:
            fin = np.isfinite(raw)
            if not fin.all():
                if self.time_error is None:
                    i = row0 + int(np.argmax(~fin))
                    self.time_error = LogFormatError(
                        f"{self.where}: array {self.tkey!r}, sample {i}: time is not finite")
                return np.zeros(raw.shape[0], dtype=np.int64)
            t = np.round(raw.astype(np.float64) * self.unit_ns).astype(np.int64)
        return t + self.offset_ns if self.offset_ns else t

    def raw_batches(self) -> Iterator[RawRows]:
        self.read_error = None
        self.time_error = None
        keys = list(self.shapes)
        failed: set[str] = set()
        tidx = None if self.tref is None else self.tref.index
        try:
            with zipfile.ZipFile(self.path) as zf:
                files = {k: zf.open(self._member(k)) for k in keys if k not in self.whole}
                try:
                    for f in files.values():
                        _header(f)
                    for r0 in range(0, self.n, BLOCK_ROWS):
                        k = min(BLOCK_ROWS, self.n - r0)
                        block = {}
                        for key in keys:
                            if key in self.whole:
                                block[key] = self.whole[key][r0:r0 + k]
                                continue
                            try:
                                block[key] = _read_rows(files[key], *self.shapes[key], k)
                            except READ_ERRORS:
                                failed.add(key)
                        if failed:
                            continue
                        mat = np.empty((k, len(self.names)))
                        for c, (key, idx) in enumerate(self.cols.values()):
                            a = block[key]
                            mat[:, c] = a if idx is None else a[:, idx]
                        if self.tkey is None:  # --rate
                            t = rate_times(r0, k, self.sample_rate_hz or 1.0)
                        else:
                            tb = block[self.tkey]
                            t = self._time(tb if tidx is None else tb[:, tidx], r0)
                        if self.time_error is None:
                            yield RawRows(r0, t, mat)
                    for key, f in files.items():  # the rest of the member: its CRC
                        try:
                            while f.read(1 << 22):
                                pass
                        except READ_ERRORS:
                            failed.add(key)
                finally:
                    for f in files.values():
                        f.close()
        except READ_ERRORS:
            failed.update(keys)
        if failed:
            err = self._first_error([k for k in self.read_order if k in failed])
            if err is not None:
                self.read_error = err
                return
        self.read_error = self.time_error


def _read_rows(f: IO[bytes], shape: tuple[int, ...], dtype: np.dtype[Any],
               k: int) -> np.ndarray:
    """The next ``k`` rows of a C-order ``.npy`` stream."""
    per = int(np.prod(shape[1:], dtype=np.int64)) * dtype.itemsize
    data = f.read(k * per)
    if len(data) != k * per:
        raise EOFError("array shorter than its header says")
    return np.frombuffer(data, dtype=dtype).reshape((k, *shape[1:]))


def npz_layout(p: Path, where: str, cmap: Any, options: dict[str, Any]) -> NpzLayout:
    """The reader of an ``.npz`` archive through its map (module docstring).

    Raises:
        LogFormatError: no map, a map for CSV, an archive that does not fit the map.
        ChannelMapError: a map naming an array the archive does not have, or of another
            shape.
    """
    if cmap is None:
        raise LogFormatError(f"{where}: an .npz log needs a channel map (--channel-map)")
    if cmap.format == "csv":
        raise LogFormatError(f"{where}: channel map {cmap.path} is for CSV files")
    return NpzLayout(p, where, cmap, options)
