"""The temporary file of per-sample columns that the Rerun and report writers keep until
the run's answer is known: one row group per chunk, read back group by group.

A Parquet file written for speed, not size — it is read back once, soon after: no
compression, no statistics and non-nullable columns (no definition levels), so writing and
reading it cost little more than a copy (per-sample floats hardly compress). Written in
:func:`impactcli.files.temp_space` (a full ``TMPDIR`` is one line, not a traceback).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

#: How the spill is written (module docstring).
SPILL_OPTIONS: dict[str, Any] = {"compression": "none", "use_dictionary": False,
                                 "write_statistics": False}


class ColumnSpill:
    """A temporary Parquet file of per-sample columns, one row group per :meth:`append`
    (the first fixes the columns); :meth:`close` removes it."""

    def __init__(self, prefix: str = "impactcli-spill-") -> None:
        from ..files import temp_space

        with temp_space():
            fd, self.path = tempfile.mkstemp(prefix=prefix, suffix=".parquet")
        os.close(fd)
        self._writer: Any = None
        self._schema: Any = None
        self.columns: list[str] = []
        self.rows: list[int] = []  # per row group

    def append(self, cols: dict[str, np.ndarray]) -> None:
        """One row group: column name → (m,) array."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        from ..files import temp_space

        if self._schema is None:
            first = pa.table(cols)
            self._schema = pa.schema([pa.field(f.name, f.type, nullable=False)
                                      for f in first.schema])
            self.columns = list(cols)
        table = pa.table(cols, schema=self._schema)
        with temp_space():
            if self._writer is None:
                self._writer = pq.ParquetWriter(self.path, self._schema, **SPILL_OPTIONS)
            self._writer.write_table(table)
        self.rows.append(table.num_rows)

    def finish(self) -> None:
        """Close the file for writing (its row groups can then be read)."""
        from ..files import temp_space

        if self._writer is not None:
            writer, self._writer = self._writer, None
            with temp_space():
                writer.close()

    def groups(self, columns: Sequence[str] | None = None,
               which: Sequence[int] | None = None) -> Iterator[dict[str, np.ndarray]]:
        """The row groups (all, or those numbered ``which``, in that order): column name →
        (m,) array, of ``columns`` (default all)."""
        import pyarrow.parquet as pq

        self.finish()
        if not self.rows:
            return
        f = pq.ParquetFile(self.path)
        cols = None if columns is None else list(columns)
        for g in range(len(self.rows)) if which is None else which:
            t = f.read_row_group(g, columns=cols)
            yield {name: t.column(name).to_numpy() for name in t.column_names}

    def close(self) -> None:
        """Remove the file."""
        self.finish()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)
