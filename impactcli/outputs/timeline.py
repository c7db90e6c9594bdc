"""The detection timeline JSON (docs/formats.md, "Detection timeline";
schemas/timeline.schema.json).

Formatting only: every number comes from a :class:`~impactcli.types.DetectionResult`.
Times are seconds since the log's first sample; ``input.t0_ns`` anchors them on the
log's own clock. Output is deterministic (sorted keys, fixed float formatting by
``json``), so the same inputs give byte-identical files.
"""

from __future__ import annotations

import json
import math
import os
from typing import Any

from .. import TOOL_NAME, __version__
from ..files import atomic_write_text
from ..types import DetectionResult

SCHEMA_VERSION = "2.12"
#: Timeline versions ``report`` and ``evaluate`` read (2.x adds optional fields only; 2.1:
#: ``lasting_loads``, ``counts``, each incident's ``number`` and force check).
READABLE_VERSIONS: tuple[str, ...] = ("1.0", "2.0", "2.1", "2.2", "2.3", "2.4", "2.5", "2.6",
                                      "2.7", "2.8", "2.9", "2.10", "2.11", "2.12")


def _clean(x: Any) -> Any:
    """Make a value JSON-safe: numpy scalars → Python, non-finite floats → None, tuples → lists."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    if hasattr(x, "item") and not isinstance(x, str | bytes):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _absolute(path: str) -> str:
    """The log's absolute path, or its URL as given (so a timeline finds its log from any
    folder)."""
    import os

    if "://" in path or path.startswith("<"):
        return path
    return os.path.abspath(path)


def timeline_dict(result: DetectionResult) -> dict[str, Any]:
    """The timeline as a JSON-ready mapping (validated by schemas/timeline.schema.json)."""
    log = result.log
    src = log.source
    doc: dict[str, Any] = {
        "schema_version": SCHEMA_VERSION,
        "tool": {"name": TOOL_NAME, "version": __version__},
        "input": {
            "path": src.path,
            "abs_path": _absolute(src.path),
            "sha256": src.sha256,
            "format": src.format,
            "joints": list(log.joint_names),
            "n_samples": log.n_samples,
            "duration_s": log.duration_s,
            "sample_rate_hz": log.sample_rate_hz,
            "t0_ns": log.t0_ns,
            "torque_source": src.torque_source,
            "time_source": src.time_source,
            "read_options": result.read_options.as_dict(),
            "repairs": list(src.repairs),
            **({"truncated": True} if src.truncated else {}),
            "joints_left_out": list(result.joints_left_out),
            **({} if result.torque_scale is None else {"torque_scale": result.torque_scale}),
            **({} if result.payload is None else {"payload": result.payload}),
        },
        "config": result.config,
        "calibrated": result.calibrated,
        "model": (None if result.model is None else
                  {"source": result.model_source, "sha256": result.model_sha256,
                   "model": result.model}),
        "replay": {
            "online_equivalent": result.online_equivalent,
            "reference_source": result.reference_source,
            "torque_filtered": result.torque_filtered,
            "residual_generator": result.residual_generator,
            "generator": result.generators,
            "threshold_inputs": result.threshold_inputs,
        },
        "warmup_end_s": result.warmup_end_s,
        "warmup_per_joint_s": result.warmup_per_joint_s,
        "thresholds": result.thresholds,
        "filter_gain": result.filter_gain,
        "events": [e.to_dict() for e in result.events],
        "incidents": [i.to_dict() for i in result.incidents],
        "lasting_loads": [x.to_dict() for x in result.lasting_loads],
        **({} if result.motion_envelope is None
           else {"motion_envelope": result.motion_envelope}),
        **({} if result.detection_floor is None
           else {"detection_floor": result.detection_floor}),
        **({} if result.data_defects is None else {"data_defects": result.data_defects}),
        **({} if result.payload_changes is None
           else {"payload_changes": list(result.payload_changes)}),
        "counts": result.counts(),
        "summary": result.summary(),
        "warnings": list(result.warnings),
    }
    cleaned: dict[str, Any] = _clean(doc)
    return cleaned


def timeline_json(result: DetectionResult) -> str:
    """The timeline as deterministic JSON text."""
    return dumps_timeline(timeline_dict(result))


def dumps_timeline(doc: dict[str, Any]) -> str:
    """A timeline mapping as the deterministic JSON text the tool writes (sorted keys, one
    space of indent, no NaN): what :func:`read_timeline` reads back unchanged."""
    return json.dumps(doc, indent=1, sort_keys=True, allow_nan=False) + "\n"


def read_timeline(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A timeline file validated against schemas/timeline.schema.json (``report`` and
    ``evaluate`` read 1.0 and 2.x); LogFormatError naming the file and the problem."""
    from ..errors import LogFormatError
    from ..files import load_mapping
    from ..schema import validate

    doc = load_mapping(path, LogFormatError, "timeline")
    validate(doc, "timeline", LogFormatError, str(path))
    return doc


def write_timeline(result: DetectionResult, path: str | os.PathLike[str]) -> None:
    """Write ``<stem>.timeline.json`` atomically."""
    atomic_write_text(path, timeline_json(result))
