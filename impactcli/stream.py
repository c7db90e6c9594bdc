"""alias: removed in M — the names other modules and tests still import from here.

The replay of a log is :func:`impactcli.run.one_log.detect_log`; :func:`analyze_stream`
is it on a log file, with today's signature.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .config import DetectorConfig
from .model.rigid import RigidModel
from .result import DetectionResult
from .run.one_log import CHUNK_ROWS, RunSetup, detect_log
from .run.readers import FileReader
from .types import LogHeader, RobotDescription, SignalsChunk

StreamChunk = SignalsChunk  # alias: removed in M

__all__ = ["CHUNK_ROWS", "LogHeader", "StreamChunk", "analyze_stream"]


def analyze_stream(  # alias: removed in M
    log_path: str, *, config: DetectorConfig | None, model: RigidModel | None = None,
    robot: RobotDescription | None = None, read_options: dict[str, Any] | None = None,
    model_from_log: bool = False, generator: str | None = None, config_where: str = "config",
    allow_slow: bool = False, chunk_rows: int = CHUNK_ROWS, scan: Any = None,
    on_chunk: Callable[[SignalsChunk], None] | None = None,
    progress: Callable[[float, float], None] | None = None,
) -> DetectionResult:
    """:func:`impactcli.run.one_log.detect_log` of the log at ``log_path`` (``scan``: its
    scan if already made, then closed by the caller)."""
    opts = dict(read_options or {})
    read_kw = dict(opts, robot=robot) if robot is not None else dict(opts)
    setup = RunSetup(config=config, model=model, robot=robot, generator=generator,
                     model_from_log=model_from_log, allow_slow=allow_slow,
                     config_where=config_where, read_options=opts, chunk_rows=chunk_rows)
    with FileReader(log_path, scan=scan, **read_kw) as reader:
        return detect_log(reader, setup, on_chunk=on_chunk, progress=progress)
