"""A log as the replay reads it: the readers of :mod:`impactcli.io.stream` (a scan, then
chunks, then close). alias: removed in M — callers use ``open_log`` and ``MemoryReader``.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..io.stream import LogChunk, LogReader, LogScan, MemoryReader, open_log

__all__ = ["FileReader", "LogReader", "MemoryReader"]


class FileReader(LogReader):
    """A log file read in chunks; ``scan``: a scan already made (its reader is used, and
    the caller closes it, not :meth:`close`)."""

    def __init__(self, path: str | os.PathLike[str], scan: LogScan | None = None,
                 **read_options: Any) -> None:
        made = scan.reader if scan is not None else None
        self._reader = made if isinstance(made, LogReader) else open_log(path, **read_options)
        self._owned = scan is None
        self.options = self._reader.options

    def scan(self) -> LogScan:
        return self._reader.scan()

    def chunks(self, rows: int) -> Iterator[LogChunk]:
        return self._reader.chunks(rows)

    def times(self) -> Iterator[np.ndarray]:
        return self._reader.times()

    def close(self) -> None:
        if self._owned:
            self._reader.close()
