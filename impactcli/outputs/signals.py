"""Per-sample signals as Parquet (formats.md, "Per-sample signals").

Columns: ``time`` (s since the first sample), then per joint ``<joint>.<signal>`` for every
name in :data:`impactcli.result.SIGNAL_NAMES` and one 0/1 column per detector
(``<joint>.adaptive``, ``<joint>.static_loading``, ``<joint>.static_baseline``).
File metadata holds ``t0_ns``, the input sha256 and the tool version.
"""

from __future__ import annotations

import os

import numpy as np

from .. import __version__
from .._fs import atomic_output
from ..result import SIGNAL_NAMES, DetectionResult
from ..types import DETECTORS


def signals_table(result: DetectionResult):  # type: ignore[no-untyped-def]
    """The per-sample signals as a pyarrow Table."""
    import pyarrow as pa

    cols: dict[str, np.ndarray] = {"time": result.log.time_s}
    for j, joint in enumerate(result.log.joint_names):
        for name in SIGNAL_NAMES:
            cols[f"{joint}.{name}"] = np.asarray(result.signals[name][:, j], dtype=np.float64)
        for det in DETECTORS:
            cols[f"{joint}.{det}"] = result.decisions[det][:, j].astype(np.uint8)
    table = pa.table(cols)
    meta = {
        b"impactcli.version": __version__.encode(),
        b"impactcli.t0_ns": str(result.log.t0_ns).encode(),
        b"impactcli.input_sha256": result.log.source.sha256.encode(),
        b"impactcli.input_path": result.log.source.path.encode(),
    }
    return table.replace_schema_metadata(meta)


def write_signals(result: DetectionResult, path: str | os.PathLike[str]) -> None:
    """Write ``<stem>.signals.parquet`` atomically (zstd-compressed)."""
    import pyarrow.parquet as pq

    table = signals_table(result)
    with atomic_output(path, "wb") as f:
        pq.write_table(table, f, compression="zstd")


def read_signals(path: str | os.PathLike[str]) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Read a signals file back: column name → array, and the file metadata."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    meta = {k.decode(): v.decode() for k, v in (table.schema.metadata or {}).items()}
    return {name: table.column(name).to_numpy() for name in table.column_names}, meta
