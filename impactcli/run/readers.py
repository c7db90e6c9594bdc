"""A log as the replay reads it: a scan (what needs the whole log), then chunks, then close.

alias: removed in M — the readers of :mod:`impactcli.io` give this interface
(``open_log(path, **options)`` and ``MemoryReader(log)``); until then :class:`FileReader`
wraps :func:`impactcli.io.stream.scan_log` / :func:`~impactcli.io.stream.iter_chunks` and
:class:`MemoryReader` makes the scan of a log already in memory, whose chunks are slices of
it (one chunk when ``rows`` ≥ its samples). Both give the same scan for the same log.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any, Protocol

from ..io.stream import OPTIONAL, LogChunk, LogScan
from ..types import CONTROLLER_CHANNELS, RobotLog


class LogReader(Protocol):
    """What the replay reads a log through (:func:`impactcli.run.one_log.detect_log`)."""

    def scan(self) -> LogScan:
        """The first pass over the log, made once (:class:`~impactcli.io.stream.LogScan`)."""
        ...

    def chunks(self, rows: int) -> Iterator[LogChunk]:
        """The log's repaired samples in chunks of ``rows`` (the last one shorter);
        repeatable."""
        ...

    def close(self) -> None:
        """Free what the scan keeps (its cache of the rows, a URL's local copy)."""
        ...


class FileReader:
    """A log file (any format and URL :func:`impactcli.io.read_log` takes) read in chunks.

    ``scan``: the log's scan if already made (then the caller closes it, not :meth:`close`).
    """

    def __init__(self, path: str | os.PathLike[str], scan: LogScan | None = None,
                 **read_options: Any) -> None:
        self.path, self.options = str(path), read_options
        self._scan, self._owned = scan, scan is None

    def scan(self) -> LogScan:
        if self._scan is None:
            from ..io.stream import scan_log

            self._scan = scan_log(self.path, **self.options)
        return self._scan

    def chunks(self, rows: int) -> Iterator[LogChunk]:
        from ..io.stream import iter_chunks

        return iter_chunks(self.path, self.scan(), rows, **self.options)

    def close(self) -> None:
        if self._scan is not None and self._owned:
            self._scan.close()

    def __enter__(self) -> FileReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class MemoryReader:
    """A log in memory as a reader: its scan from its arrays, its chunks slices of it.

    ``options``: the read options the log was read with (recorded in the scan).
    """

    def __init__(self, log: RobotLog, options: dict[str, Any] | None = None) -> None:
        self.log, self.options = log, dict(options or {})
        self._scan: LogScan | None = None

    def scan(self) -> LogScan:
        if self._scan is None:
            self._scan = _scan_memory(self.log, self.options)
        return self._scan

    def chunks(self, rows: int) -> Iterator[LogChunk]:
        if rows < 1:
            raise ValueError(f"chunk_rows must be at least 1, got {rows}")
        log = self.log
        for a in range(0, log.n_samples, rows):
            b = min(a + rows, log.n_samples)
            opt = {s: None if (v := getattr(log, s)) is None else v[a:b] for s in OPTIONAL}
            yield LogChunk(start=a, t_ns=log.t_ns[a:b], position=log.position[a:b],
                           torque=log.torque[a:b], **opt)

    def close(self) -> None:
        pass

    def __enter__(self) -> MemoryReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _scan_memory(log: RobotLog, options: dict[str, Any]) -> LogScan:
    """The scan of a log in memory: what :func:`impactcli.io.stream.scan_log` gives for the
    file it was read from (the scan :mod:`impactcli.io.stream` makes of a log it reads
    whole). alias: removed in M (the io readers' ``MemoryReader``)."""
    from ..io.inspect import time_gaps
    from ..io.stream_screen import _screen_of  # alias: removed in M

    screens = {s: _screen_of(getattr(log, s)) for s in ("torque", *CONTROLLER_CHANNELS)
               if getattr(log, s) is not None}
    idx, lengths = time_gaps(log)
    return LogScan(log=log.slice(0, 2), n_samples=log.n_samples, t0_ns=log.t0_ns,
                   t_last_ns=int(log.t_ns[-1]), clock=log.sample_clock, gaps=idx,
                   gap_lengths_s=lengths, torque_screen=screens["torque"].unusable(),
                   screens=screens, streamed=False, options=dict(options))
