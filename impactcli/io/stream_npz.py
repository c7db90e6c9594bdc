"""``.npz`` archives streamed (:mod:`impactcli.io.stream`), through a ``format: npz``
channel map, as :func:`impactcli.io.npz.read_npz_channels` reads them whole.

The archive is a zip of ``.npy`` members. Each member the map uses is opened as a stream
(:mod:`zipfile` decompresses a deflated member as it is read), its ``.npy`` header parsed
(:func:`numpy.lib.format.read_magic`, ``read_array_header_*``), and its rows read
:data:`BLOCK_ROWS` at a time: memory holds one block of every array used, whatever the
archive's length. The time is converted as the whole-file reader converts it (integers ×
the unit, floats × the unit rounded to ns, then the offset), values to float64, block by
block; the rate check is that of the whole-file reader on the first steps.

Not streamed (the whole-file reader reads the archive, and raises its own error where it
has one): an archive or member that cannot be read, a key the map names that is not in
the archive, an array of another shape than the map says, or of other lengths than the
time's, not real numbers, in Fortran order, or an object array; a float time that is not
finite.
"""

from __future__ import annotations

import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np

from ._whole import NotStreamable as _NotStreamable
from .stream_layout import MappedLayout, plan_of
from .stream_layout import RawRows as _Raw

#: Rows read from each array at a time.
BLOCK_ROWS = 65_536


def _header(f: IO[bytes]) -> tuple[tuple[int, ...], bool, np.dtype[Any]]:
    """``(shape, fortran_order, dtype)`` of the ``.npy`` stream ``f`` (left at its data)."""
    from numpy.lib import format as npf

    version = npf.read_magic(f)
    if version == (1, 0):
        return npf.read_array_header_1_0(f)  # type: ignore[no-any-return]
    if version == (2, 0):
        return npf.read_array_header_2_0(f)  # type: ignore[no-any-return]
    raise _NotStreamable(f".npy version {version}")


class NpzStreamLayout(MappedLayout):
    """A streamable ``.npz`` archive and its map (module docstring)."""

    def __init__(self, p: Path, where: str, cmap: Any, options: dict[str, Any]) -> None:
        from .channel_map import TIME_UNITS, require_time
        from .repair import DROPPABLE_SIGNALS

        self.path, self.where, self.fmt, self.cmap = p, where, "npz", cmap
        self.joints = tuple(cmap.joints)
        self.repair_order = bool(options.get("repair_order", False))
        tspec = require_time(cmap, where)
        self.tkey = str(tspec.ref.source)
        if tspec.ref.index is not None:
            raise _NotStreamable("a time column of a 2-D array")
        self.time_name = self.tkey
        self.unit, self.unit_ns = tspec.unit, TIME_UNITS[tspec.unit]
        self.offset_ns = round(tspec.offset * self.unit_ns) if tspec.offset else 0
        self.start_at_zero = bool(tspec.start_at_zero)
        # the columns: (signal, joint) → label, label → (array key, column index or None)
        self.keys = {}
        self.cols: dict[str, tuple[str, int | None]] = {}
        for sig, j, ref in cmap.refs():
            self.keys[(sig, j)] = ref.label()
            self.cols.setdefault(ref.label(), (str(ref.source), ref.index))
        self.names = list(self.cols)
        self.droppable = {lab for (sig, _), lab in self.keys.items() if sig in DROPPABLE_SIGNALS}
        try:
            with zipfile.ZipFile(p) as zf:
                members = zf.namelist()
                files = [m[:-4] if m.endswith(".npy") else m for m in members]
                self.members = dict(zip(files, members, strict=True))
                used = {k for k, _ in self.cols.values()} | {self.tkey}
                self.ignored = [k for k in files if k not in used]
                self.n = self._check(zf, used)
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
            raise _NotStreamable(str(err)) from err
        self.plan = plan_of(self, options.get("robot"), options.get("torque_source"))

    def _check(self, zf: zipfile.ZipFile, used: set[str]) -> int:
        """The archive fits the map (else the whole-file reader says why): the arrays'
        length N."""
        lengths = set()
        want: dict[str, set[int | None]] = {k: set() for k in used}  # key → columns (None: 1-D)
        for key, idx in [*self.cols.values(), (self.tkey, None)]:
            want[key].add(idx)
        self.shapes: dict[str, tuple[tuple[int, ...], np.dtype[Any]]] = {}
        for key, idxs in want.items():
            if key not in self.members:
                raise _NotStreamable(f"no array {key!r}")
            with zf.open(self.members[key]) as f:
                shape, fortran, dtype = _header(f)
            cols = [i for i in idxs if i is not None]
            ok_dim = (len(shape) == 1 if idxs == {None} else len(cols) == len(idxs)
                      and len(shape) == 2 and max(cols) < shape[1])
            numeric = np.issubdtype(dtype, np.number) and not np.issubdtype(
                dtype, np.complexfloating)
            if not ok_dim or fortran or dtype.hasobject or not numeric:
                raise _NotStreamable(f"array {key!r}")
            if key == self.tkey and not (np.issubdtype(dtype, np.integer)
                                         or np.issubdtype(dtype, np.floating)):
                raise _NotStreamable("time not integer or float")
            self.shapes[key] = (shape, dtype)
            lengths.add(shape[0])
        if len(lengths) != 1:
            raise _NotStreamable("arrays of different lengths")
        return lengths.pop()

    def rate_error(self, rate_hz: float) -> str | None:
        from .repair import rate_message

        return rate_message(rate_hz, self.where, f"array {self.tkey!r}", self.unit)

    def _time(self, raw: np.ndarray) -> np.ndarray:
        """A block of the time array → int64 ns (as the whole-file reader converts it)."""
        if np.issubdtype(raw.dtype, np.integer):
            t = raw.astype(np.int64) * self.unit_ns
        else:
            if not np.all(np.isfinite(raw)):
                raise _NotStreamable("time that is not finite")
            t = np.round(raw.astype(np.float64) * self.unit_ns).astype(np.int64)
        return t + self.offset_ns if self.offset_ns else t

    def raw_batches(self) -> Iterator[_Raw]:
        keys = list(self.shapes)
        try:
            with zipfile.ZipFile(self.path) as zf:
                files = {k: zf.open(self.members[k]) for k in keys}
                try:
                    for f in files.values():
                        _header(f)
                    for r0 in range(0, self.n, BLOCK_ROWS):
                        k = min(BLOCK_ROWS, self.n - r0)
                        block = {key: _read_rows(files[key], *self.shapes[key], k)
                                 for key in keys}
                        mat = np.empty((k, len(self.names)))
                        for c, (key, idx) in enumerate(self.cols.values()):
                            a = block[key]
                            mat[:, c] = a if idx is None else a[:, idx]
                        yield _Raw(r0, self._time(block[self.tkey]), mat)
                finally:
                    for f in files.values():
                        f.close()
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
            raise _NotStreamable(str(err)) from err


def _read_rows(f: IO[bytes], shape: tuple[int, ...], dtype: np.dtype[Any],
               k: int) -> np.ndarray:
    """The next ``k`` rows of a C-order ``.npy`` stream."""
    per = int(np.prod(shape[1:], dtype=np.int64)) * dtype.itemsize
    data = f.read(k * per)
    if len(data) != k * per:
        raise _NotStreamable("array shorter than its header says")
    return np.frombuffer(data, dtype=dtype).reshape((k, *shape[1:]))


def npz_stream_layout(p: Path, where: str, cmap: Any,
                      options: dict[str, Any]) -> NpzStreamLayout | None:
    """The layout of an ``.npz`` archive (module docstring), None when the whole-file
    reader reads it (no map, or a map for CSV)."""
    if cmap is None or cmap.format == "csv":
        return None
    return NpzStreamLayout(p, where, cmap, options)
