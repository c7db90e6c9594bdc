"""The scan's repaired rows kept on disk for the passes after it (:mod:`impactcli.logs.scan`):
a copy instead of a second parse or merge of the file.

The scan writes the rows it repaired — (n,) int64 times [ns] and (n, C) float64 values of
the used columns, as :class:`~impactcli.logs.repair.Repairer` gives them out — to two binary
files in a temporary directory; :func:`chunks` reads them back in blocks, sets the columns
without any finite value (``allbad``) to NaN and converts the rows as a pass over the file
does (:meth:`~impactcli.logs.layout.ScanPass.arrays`, elementwise): the same arrays
bit for bit (``tests/test_reader_csv.py``).

Bounded: memory holds one block of rows (``max(chunk_rows, MIN_READ_ROWS)``), the disk
8·(1 + C) bytes per row. A cache of the one temporary store (:mod:`impactcli.spill`): given
up — deleted, and each pass reads the file again — when no temporary folder can be made, a
write fails or the free space falls under :data:`impactcli.spill.MIN_FREE_BYTES` (a
day-long log must not fill the disk). It is deleted by :meth:`RowCache.close` (the reader's
``close``), else when it is garbage collected or at exit.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from ..spill import ColumnFiles
from .layout import LogChunk, ScanPass, chunked

#: Rows read back at a time when the chunks are smaller (fewer, larger reads).
MIN_READ_ROWS = 16_384


class RowCache:
    """The repaired rows of a scan on disk (module docstring): :meth:`add` them in order,
    :meth:`finish`, then read them with :meth:`blocks` (any number of times) until
    :meth:`close`. ``usable`` is False once given up or closed. A cache of the one
    temporary store (:class:`impactcli.spill.ColumnFiles`, ``required=False``)."""

    def __init__(self, n_cols: int) -> None:
        self.n_cols = int(n_cols)
        self.store = ColumnFiles("impactcli-scan-", required=False)

    @property
    def usable(self) -> bool:
        return self.store.usable

    @property
    def rows(self) -> int:
        return self.store.rows

    def add(self, t: np.ndarray, mat: np.ndarray) -> None:
        """Append rows: ``t`` (n,) int64 [ns], ``mat`` (n, C) float64."""
        t = np.asarray(t, dtype=np.int64)
        self.store.append({"t": t, "values": np.asarray(mat, dtype=np.float64).reshape(
            t.shape[0], self.n_cols)})

    def finish(self) -> None:
        """The last row was added: the files are complete."""
        self.store.finish()

    def blocks(self, rows: int, *, times_only: bool = False
               ) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
        """The rows in blocks of ``rows`` (the last one shorter): ``(t, mat)``, ``mat``
        None when ``times_only``. The arrays are new (the caller may write into them)."""
        assert self.usable, "the cache was given up"
        keys = ("t",) if times_only else ("t", "values")
        done, n = 0, self.store.rows
        while done < n:
            k = min(rows, n - done)
            got = self.store.read(done, done + k, keys)
            done += k
            yield got["t"], got.get("values")

    def close(self) -> None:
        """Delete the files (the cache is no longer usable)."""
        self.store.close()


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
