"""The one temporary store: columns of per-sample values kept on disk while a log is read or
replayed, so that memory holds only their layout, whatever the log's length.

Every stage that spills uses it — the scan's repaired rows (:mod:`impactcli.logs.row_cache`),
the message reader's decoded topics (:mod:`impactcli.logs.messages.message_merge`, its folder and
policy), the warm-up's trailing RMS (:mod:`impactcli.detect.warmup`), the replay's islands
and passes (:mod:`impactcli.run.one_log`), the Rerun and report writers' columns
(:mod:`impactcli.outputs.rerun`, :mod:`impactcli.outputs.report.samples`).

One disk-full policy, two kinds of store:

- a **cache** (``required=False``: the scan's rows, the decoded messages) is a copy of
  what the file holds. It gives itself up — its files deleted, the reader reading the file
  again or keeping the rest in memory — when no temporary folder can be made, a write fails,
  or its file system has less than :data:`MIN_FREE_BYTES` free (checked every
  :data:`CHECK_EVERY_BYTES` written): a day-long log must not fill the disk for a copy.
- a **spill** (``required=True``: everything else) is the only copy of what the replay
  computed. A folder that cannot be made or a write that fails stops the run with
  :class:`~impactcli.errors.TempSpaceError` (exit 2: one line naming ``TMPDIR``, no
  traceback; :func:`impactcli.files.temp_space`).

Files are deleted by ``close``, else when the store is garbage collected or at exit.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import weakref
from collections.abc import Iterator, Sequence
from typing import IO, Any

import numpy as np

from .files import discard, temp_prefix, temp_space_error, whole

#: A cache gives itself up when its file system has less free space than this [bytes].
MIN_FREE_BYTES = 2 * 1024**3
#: Free space is checked again after this many bytes written.
CHECK_EVERY_BYTES = 64 * 1024**2


class SpillFolder:
    """A temporary folder of spill files (module docstring). ``path`` is None when a cache's
    folder cannot be made; a spill's raises :class:`~impactcli.errors.TempSpaceError`."""

    def __init__(self, prefix: str = "impactcli-spill-", *, required: bool = True) -> None:
        self.path: str | None = None
        self.required = required
        self.full = False
        self._unchecked = CHECK_EVERY_BYTES  # check the free space before the first write
        with whole():  # a stop signal cannot fall between the folder and its removal
            try:
                self.path = tempfile.mkdtemp(prefix=temp_prefix(prefix))
            except OSError as err:
                if required:
                    raise temp_space_error(err) from err
                return
            self._remove = weakref.finalize(self, shutil.rmtree, self.path, ignore_errors=True)

    def file(self, name: str) -> str:
        """The path of the file ``name`` in the folder."""
        assert self.path is not None
        return os.path.join(self.path, name)

    def room(self, nbytes: int) -> bool:
        """Whether a cache may write ``nbytes`` more (module docstring: the free space is
        checked now and then; once short, never again). A spill always may."""
        if self.required:
            return True
        if self.path is None or self.full:
            return False
        self._unchecked += nbytes
        if self._unchecked >= CHECK_EVERY_BYTES:
            self._unchecked = 0
            try:
                self.full = shutil.disk_usage(self.path).free < MIN_FREE_BYTES
            except OSError:
                self.full = True
        return not self.full

    def close(self) -> None:
        """Delete the folder and its files."""
        if self.path is not None:
            try:
                discard(self.path, folder=True)  # all of it, even when a stop signal lands
            finally:
                self._remove.detach()
                self.path = None


class ColumnFiles:
    """Named columns appended by rows, a file per name, read back by rows or by the groups
    of rows they were appended in (module docstring).

    Args:
        prefix: the temporary folder's name prefix.
        required: a spill (errors stop the run) or a cache (gives itself up: ``usable``
            False, nothing more stored).
    """

    def __init__(self, prefix: str = "impactcli-spill-", *, required: bool = True) -> None:
        self.folder = SpillFolder(prefix, required=required)
        self.files: dict[str, IO[bytes]] = {}
        self.layout: dict[str, tuple[np.dtype[Any], tuple[int, ...]]] = {}
        self.rows = 0
        self.group_rows: list[int] = []  # rows of each append
        self.usable = self.folder.path is not None

    def append(self, arrays: dict[str, np.ndarray]) -> None:
        """Append rows: name → (m, ...) array (the same m; each name's dtype and row shape
        fixed by its first append)."""
        if not self.usable:
            return
        vals = {k: np.ascontiguousarray(v) for k, v in arrays.items()}
        if not self.folder.room(sum(v.nbytes for v in vals.values())):
            self.close()  # a cache short of room gives itself up
            return
        m = 0
        try:
            for key, v in vals.items():
                f = self.files.get(key)
                if f is None:
                    f = self.files[key] = open(self.folder.file(key), "wb")  # noqa: SIM115
                    self.layout[key] = (v.dtype, v.shape[1:])
                self._write(f, v)
                m = int(v.shape[0])
        except OSError as err:
            self._failed(err)
            return
        self.rows += m
        self.group_rows.append(m)

    @staticmethod
    def _write(f: IO[bytes], v: np.ndarray) -> None:
        """The one place every spill and cache writes its bytes (a test injects a full disk
        here)."""
        f.write(v.data.cast("B"))

    def flush(self) -> None:
        """What the write buffers hold to disk, the files kept open."""
        self._each_file(lambda f: f.flush())

    def finish(self) -> None:
        """Close the files for writing; their rows stay readable."""
        self._each_file(lambda f: f.close())

    def _each_file(self, act: Any) -> None:
        try:
            for f in self.files.values():
                act(f)
        except OSError as err:
            self._failed(err)

    def _failed(self, err: OSError) -> None:
        """A write failed: a spill stops the run (exit 2, naming ``TMPDIR``), a cache gives
        itself up."""
        if self.folder.required:
            raise temp_space_error(err) from err
        self.close()

    def read(self, row_from: int, row_to: int, keys: Sequence[str] | None = None,
             ) -> dict[str, np.ndarray]:
        """Rows [row_from, row_to) of every column (``keys``: of these; new arrays),
        written to disk (:meth:`flush` or :meth:`finish`)."""
        out = {}
        for key in (tuple(self.layout) if keys is None else keys):
            dtype, shape = self.layout[key]
            width = int(np.prod(shape)) if shape else 1
            want = (row_to - row_from) * width
            with open(self.folder.file(key), "rb") as f:
                f.seek(row_from * dtype.itemsize * width)
                a = np.fromfile(f, dtype=dtype, count=want)
            if a.size != want:
                raise OSError(f"spill {key}: {a.size} values read of {want}")
            out[key] = a.reshape((-1, *shape))
        return out

    def groups(self, keys: Sequence[str] | None = None,
               which: Sequence[int] | None = None) -> Iterator[dict[str, np.ndarray]]:
        """The groups of rows as appended (all, or those numbered ``which``, in that order):
        column name → array, of ``keys`` (default all); the files closed for writing."""
        self.finish()
        starts = np.concatenate([[0], np.cumsum(self.group_rows, dtype=np.int64)])
        for g in range(len(self.group_rows)) if which is None else which:
            yield self.read(int(starts[g]), int(starts[g + 1]), keys)

    def chunks(self, keys: Sequence[str] | None = None
               ) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        """(first row, arrays) of each group of rows as appended, in order (``keys``: only
        these columns); the files stay open for writing."""
        self.flush()
        k0 = 0
        for m in self.group_rows:
            yield k0, self.read(k0, k0 + m, keys)
            k0 += m

    def median(self, key: str) -> float:
        """``np.median`` of the (NaN-free) float64 column ``key``, exactly, in bounded memory
        (:func:`spilled_median`)."""
        self.flush()
        with open(self.folder.file(key), "rb") as f:
            return spilled_median(f, self.rows)

    def close(self) -> None:
        """Delete the files (the store is no longer usable)."""
        for f in self.files.values():
            with contextlib.suppress(OSError):
                f.close()
        self.files = {}
        self.folder.close()
        self.usable = False


#: Rows of a spilled float64 column read at a time by :func:`spilled_median`.
SPILL_BLOCK_ROWS = 1 << 16
#: :func:`spilled_median` selects among at most this many values in memory (32 MB: the
#: later half of 2.3 hours at 1 kHz in one selection).
SELECT_IN_MEMORY = 1 << 22


def spilled_median(f: Any, m: int) -> float:
    """``np.median`` of the m float64 values written to the file ``f``, exactly, in bounded
    memory: the values are narrowed to the ranks wanted by counting them into value bins
    (one pass over the file per narrowing) until at most :data:`SELECT_IN_MEMORY` remain,
    which are then read and selected. NaN-free input."""
    ranks = sorted({(m - 1) // 2, m // 2})
    vals = [_select_rank(f, m, r) for r in ranks]
    return float(vals[0]) if len(vals) == 1 else float(np.mean(np.array(vals)))


def _blocks(f: Any, m: int) -> Any:
    f.seek(0)
    for a in range(0, m, SPILL_BLOCK_ROWS):
        yield np.fromfile(f, dtype=np.float64, count=min(SPILL_BLOCK_ROWS, m - a))


def _select_rank(f: Any, m: int, rank: int) -> float:
    """The value of rank ``rank`` (0-based, ascending) of the file's values (see above)."""
    lo, hi = -np.inf, np.inf          # the value lies in [lo, hi]
    below = 0                         # values < lo
    while True:
        count = 0
        vmin, vmax = np.inf, -np.inf
        for block in _blocks(f, m):
            c = block[(block >= lo) & (block <= hi)]
            count += c.size
            if c.size:
                vmin, vmax = min(vmin, float(c.min())), max(vmax, float(c.max()))
        if vmin == vmax:
            return vmin
        if count <= SELECT_IN_MEMORY:
            inside = np.concatenate([c[(c >= lo) & (c <= hi)] for c in _blocks(f, m)])
            return float(np.partition(inside, rank - below)[rank - below])
        edges = np.linspace(vmin, vmax, 4097)
        counts = np.zeros(4096, dtype=np.int64)
        # bin i holds edges[i] <= v < edges[i + 1] (the last one v == vmax too): NumPy's
        # uniform-bin histogram (its indices checked against these same edges), or a search
        # of the edges where the range is too narrow or too wide for it
        fast = bool(np.isfinite(vmax - vmin)) and np.unique(edges).size == edges.size
        for block in _blocks(f, m):
            c = block[(block >= lo) & (block <= hi)]
            if fast:
                counts += np.histogram(c, bins=4096, range=(vmin, vmax))[0]
            else:
                k = np.clip(np.searchsorted(edges, c, side="right") - 1, 0, 4095)
                counts += np.bincount(k, minlength=4096)
        cum = below + np.cumsum(counts)
        b = int(np.searchsorted(cum, rank, side="right"))
        below = int(cum[b - 1]) if b > 0 else below
        lo = float(edges[b]) if b > 0 else vmin
        hi = float(np.nextafter(edges[b + 1], -np.inf)) if b < 4095 else vmax
