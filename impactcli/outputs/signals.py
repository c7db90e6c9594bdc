"""Per-sample signals as Parquet (docs/formats.md, "Per-sample signals"), chunk by chunk.

Columns: ``time`` (s since the first sample), then per joint ``<joint>.<signal>`` for every
name in :data:`impactcli.types.SIGNAL_NAMES` and one 0/1 column per detector
(``<joint>.adaptive``, ``<joint>.static_loading``, ``<joint>.static_baseline``); one row group
per replay chunk. File metadata holds ``t0_ns``, the input sha256 and path, the tool version.
:class:`SignalsWriter` writes the file as the replay goes; :func:`signal_groups` reads it back
row group by row group (bounded memory).
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..files import atomic_output
from ..types import DETECTORS, SIGNAL_NAMES

#: How the Parquet file is written: zstd at its fastest level and no dictionary encoding
#: (per-sample floats are nearly all distinct: a dictionary is built and given up).
PARQUET_OPTIONS: dict[str, Any] = {"compression": "zstd", "compression_level": 1,
                                   "use_dictionary": False}


def _meta(t0_ns: int, sha256: str, path: str) -> dict[bytes, bytes]:
    return {
        b"impactcli.version": __version__.encode(),
        b"impactcli.t0_ns": str(t0_ns).encode(),
        b"impactcli.input_sha256": sha256.encode(),
        b"impactcli.input_path": path.encode(),
    }


def chunk_columns(joints: tuple[str, ...], t: np.ndarray, signals: dict[str, np.ndarray],
                  decisions: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The file's columns for ``t`` (n,) [s] and (n, J) signals and decisions."""
    cols: dict[str, np.ndarray] = {"time": np.asarray(t, dtype=np.float64)}
    for j, joint in enumerate(joints):
        for name in SIGNAL_NAMES:
            cols[f"{joint}.{name}"] = np.asarray(signals[name][:, j], dtype=np.float64)
        for det in DETECTORS:
            cols[f"{joint}.{det}"] = decisions[det][:, j].astype(np.uint8)
    return cols


class SignalsWriter:
    """``<stem>.signals.parquet`` written chunk by chunk (one row group each), atomically:
    the file appears only when the ``with`` block succeeds (a failed run leaves nothing).

    Called with a replay's chunk (``joints``, ``time_s``, ``signals``, ``decisions``) or
    :meth:`append`; chunks in time order.
    """

    def __init__(self, path: str | os.PathLike[str], t0_ns: int, sha256: str,
                 input_path: str) -> None:
        self._rows = 0
        self._ctx = atomic_output(path, "wb", verify=self._verify)
        self._f = self._ctx.__enter__()
        self._meta = _meta(t0_ns, sha256, input_path)
        self._writer: Any = None

    def __call__(self, chunk: Any) -> None:
        """One replay chunk (the ``on_chunk`` of a run)."""
        self.append(chunk.joints, chunk.time_s, chunk.signals, chunk.decisions)

    def append(self, joints: tuple[str, ...], t: np.ndarray, signals: dict[str, np.ndarray],
               decisions: dict[str, np.ndarray]) -> None:
        """One chunk: (n,) times [s since the first sample], (n, J) signals of
        :data:`impactcli.types.SIGNAL_NAMES` and (n, J) decisions per detector."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.table(chunk_columns(joints, t, signals, decisions))
        table = table.replace_schema_metadata(self._meta)
        if self._writer is None:
            self._writer = pq.ParquetWriter(self._f, table.schema, **PARQUET_OPTIONS)
        self._writer.write_table(table)
        self._rows += table.num_rows

    def _verify(self, tmp: Path) -> None:
        verify_parquet(tmp, self._rows)

    def __enter__(self) -> SignalsWriter:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        failed: BaseException | None = None
        if self._writer is not None:
            try:
                self._writer.close()  # writes the footer: a full disk may show here
            except BaseException as err:
                failed = err
        if exc is None and failed is not None:  # the file goes; the error is told
            self._ctx.__exit__(type(failed), failed, failed.__traceback__)
            raise failed
        self._ctx.__exit__(exc_type, exc, tb)  # moves into place, or removes and re-raises


def verify_parquet(tmp: Path, rows: int) -> None:
    """A written signals file before it is moved into place: a Parquet file (its magic at
    both ends) whose footer parses and counts the ``rows`` written; ValueError if not."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    with open(tmp, "rb") as f:
        head = f.read(4)
        f.seek(max(tmp.stat().st_size - 4, 0))
        tail = f.read(4)
    if head != b"PAR1" or tail != b"PAR1":
        raise ValueError("not a whole Parquet file (no footer: truncated)")
    try:
        n = pq.ParquetFile(tmp).metadata.num_rows
    except pa.ArrowException as err:
        raise ValueError(f"its Parquet footer does not parse: {err}") from err
    if n != rows:
        raise ValueError(f"{n} rows read back of {rows} written")


def signals_schema(path: str | os.PathLike[str]) -> tuple[list[str], dict[str, str], int]:
    """A signals file's column names, metadata and number of row groups (nothing read but
    its footer)."""
    import pyarrow.parquet as pq

    f = pq.ParquetFile(path)
    meta = {k.decode(): v.decode() for k, v in (f.schema_arrow.metadata or {}).items()}
    return list(f.schema_arrow.names), meta, f.num_row_groups


def signal_groups(path: str | os.PathLike[str], columns: Sequence[str] | None = None
                  ) -> Iterator[dict[str, np.ndarray]]:
    """A Parquet file's ``columns`` (default all), one row group at a time: column name →
    (m,) array."""
    import pyarrow.parquet as pq

    f = pq.ParquetFile(path)
    cols = None if columns is None else list(columns)
    for g in range(f.num_row_groups):
        t = f.read_row_group(g, columns=cols)
        yield {name: t.column(name).to_numpy() for name in t.column_names}


def read_signals(path: str | os.PathLike[str]) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """A signals file read whole (short files, tests): column name → array, metadata."""
    names, meta, _ = signals_schema(path)
    groups = list(signal_groups(path))
    return {n: np.concatenate([g[n] for g in groups]) if groups else np.zeros(0)
            for n in names}, meta
