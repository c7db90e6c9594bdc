"""The scan's repaired rows kept on disk for the passes after it (:mod:`impactcli.logs.scan`):
a copy instead of a second parse or merge of the file.

The scan writes the rows it repaired — (n,) int64 times [ns] and (n, C) float64 values of
the used columns, as :class:`~impactcli.logs.repair.Repairer` gives them out — to two binary
files in a temporary directory; :func:`chunks` reads them back in blocks, sets the columns
without any finite value (``allbad``) to NaN and converts the rows as a pass over the file
does (:meth:`~impactcli.logs.layout.ScanPass.arrays`, elementwise): the same arrays
bit for bit (``tests/test_io_stream.py``).

Bounded: memory holds one block of rows (``max(chunk_rows, MIN_READ_ROWS)``), the disk
8·(1 + C) bytes per row. The cache is given up — deleted, and each pass reads the file
again — when no temporary folder can be made, a write fails or the free space falls under
:data:`MIN_FREE_BYTES` (a day-long log must not fill the disk). It is deleted by
:meth:`RowCache.close` (the reader's ``close``), else when it is garbage collected or at
exit (a :func:`weakref.finalize`).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import weakref
from collections.abc import Callable, Iterator
from typing import IO, Any

import numpy as np

from .layout import LogChunk, ScanPass, chunked

#: The cache is given up when its file system has less free space than this [bytes].
MIN_FREE_BYTES = 2 * 1024**3
#: Free space is checked again after this many bytes written.
CHECK_EVERY_BYTES = 64 * 1024**2
#: Rows read back at a time when the chunks are smaller (fewer, larger reads).
MIN_READ_ROWS = 16_384


class RowCache:
    """The repaired rows of a scan on disk (module docstring): :meth:`add` them in order,
    :meth:`finish`, then read them with :meth:`blocks` (any number of times) until
    :meth:`close`. ``usable`` is False once given up or closed."""

    def __init__(self, n_cols: int) -> None:
        self.n_cols = int(n_cols)
        self.rows = 0
        self._unchecked = CHECK_EVERY_BYTES  # check the free space before the first write
        self._dir: str | None = None
        self._files: list[IO[bytes]] | None = None
        self._remove: Callable[[], Any] | None = None
        try:  # no temporary folder to write in: no cache (each pass parses the file)
            self._dir = tempfile.mkdtemp(prefix="impactcli-scan-")
        except OSError:
            return
        # removed when the cache is garbage collected or at exit, if not closed before
        self._remove = weakref.finalize(self, shutil.rmtree, self._dir, ignore_errors=True)
        try:
            self._files = []
            for name in ("t.i8", "values.f8"):
                self._files.append(open(self._path(name), "wb"))  # noqa: SIM115
        except OSError:
            self.close()

    @property
    def usable(self) -> bool:
        return self._dir is not None

    def _path(self, name: str) -> str:
        assert self._dir is not None
        return os.path.join(self._dir, name)

    def add(self, t: np.ndarray, mat: np.ndarray) -> None:
        """Append rows: ``t`` (n,) int64 [ns], ``mat`` (n, C) float64."""
        if self._files is None:
            return
        t = np.ascontiguousarray(t, dtype=np.int64)
        mat = np.ascontiguousarray(mat, dtype=np.float64)
        try:
            if self._unchecked >= CHECK_EVERY_BYTES:
                self._unchecked = 0
                assert self._dir is not None
                if shutil.disk_usage(self._dir).free < MIN_FREE_BYTES:
                    self.close()
                    return
            self._files[0].write(t.data.cast("B"))
            self._files[1].write(mat.reshape(-1).data.cast("B"))
        except OSError:
            self.close()
            return
        self._unchecked += t.nbytes + mat.nbytes
        self.rows += t.shape[0]

    def finish(self) -> None:
        """The last row was added: the files are complete."""
        if self._files is None:
            return
        try:
            for f in self._files:
                f.close()
        except OSError:
            self.close()
        self._files = None

    def blocks(self, rows: int, *, times_only: bool = False
               ) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
        """The rows in blocks of ``rows`` (the last one shorter): ``(t, mat)``, ``mat``
        None when ``times_only``. The arrays are new (the caller may write into them)."""
        assert self.usable and self._files is None, "finish() the cache before reading it"
        c = self.n_cols
        with open(self._path("t.i8"), "rb") as ft, (
                open(os.devnull, "rb") if times_only else open(self._path("values.f8"), "rb")
        ) as fv:
            done = 0
            while done < self.rows:
                k = min(rows, self.rows - done)
                t = np.empty(k, dtype=np.int64)
                _read_into(ft, t)
                mat = None
                if not times_only:
                    mat = np.empty((k, c), dtype=np.float64)
                    _read_into(fv, mat)
                done += k
                yield t, mat

    def close(self) -> None:
        """Delete the files (the cache is no longer usable)."""
        if self._files is not None:
            for f in self._files:
                with contextlib.suppress(OSError):
                    f.close()
            self._files = None
        if self._remove is not None:
            self._remove()
        self._dir = None


def _read_into(f: IO[bytes], a: np.ndarray) -> None:
    view = a.reshape(-1).data.cast("B")
    got = f.readinto(view)  # type: ignore[attr-defined]
    if got != a.nbytes:
        raise OSError(f"scan cache: {got} bytes read of {a.nbytes}")


def chunks(ps: ScanPass, cache: RowCache, chunk_rows: int) -> Iterator[LogChunk]:
    """The log's chunks of ``chunk_rows`` samples from the scan's cached rows (module
    docstring): the ``allbad`` columns set to NaN, the rows converted, the kept joints
    and the log's arrays picked, the clock shifted, as the pass over the file does."""
    cols = sorted(ps.allbad)

    def blocks() -> Iterator[tuple[np.ndarray, dict[str, np.ndarray]]]:
        for t, mat in cache.blocks(max(chunk_rows, MIN_READ_ROWS)):
            assert mat is not None
            if cols:
                mat[:, cols] = np.nan
            yield ps.arrays(t, mat)

    return chunked(blocks(), chunk_rows)
