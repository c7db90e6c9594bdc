"""alias: removed in M — the names other modules and tests still import from here.

There is one replay, :func:`impactcli.run.one_log.detect_log`. :func:`analyze` is it on a
log in memory (:func:`impactcli.run.collect.detect_in_memory`) with the per-sample arrays
put back in the result; :func:`replay` is its threshold-free pass with the residual and
statistics collected. Both for callers that have not moved yet.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from .config import DetectorConfig
from .detect.thresholds import compare_to_thresholds, detector_ratios
from .detect.warmup import Warmup
from .model.rigid import RigidModel
from .result import DetectionResult
from .run.plan import calibrated_thresholds
from .types import RobotDescription, RobotLog

__all__ = ["Replay", "analyze", "calibrated_thresholds", "compare_to_thresholds",
           "detector_ratios", "replay"]


def analyze(  # alias: removed in M
    log: RobotLog, *, model: RigidModel | None = None, config: DetectorConfig | None = None,
    robot: RobotDescription | None = None, read_options: dict[str, Any] | None = None,
    model_from_log: bool = False, generator: str | None = None, config_where: str = "config",
    allow_slow: bool = False,
) -> DetectionResult:
    """:func:`impactcli.run.collect.detect_in_memory`, its result holding the per-sample
    arrays and the log (its replayed joints, in the replay's order)."""
    from .run.collect import detect_in_memory

    res, sig = detect_in_memory(log, model=model, config=config, robot=robot,
                                read_options=dict(read_options or {}),
                                model_from_log=model_from_log, generator=generator,
                                config_where=config_where, allow_slow=allow_slow)
    return dataclasses.replace(res, log=log.select(res.log.joint_names), signals=sig.signals,
                               decisions=sig.decisions, ratios=sig.ratios)


@dataclass(frozen=True)
class Replay:  # alias: removed in M
    """The threshold-free pass of a replay: the log (its replayed joints, in order), the
    model, the (N, J) residual, the warm-up and the statistics
    (:class:`impactcli.run.collect.ReplayStats`)."""

    log: RobotLog
    model: RigidModel | None
    r: np.ndarray
    warmup: Warmup
    stats: dict[str, np.ndarray]


def replay(  # alias: removed in M
    log: RobotLog, model: RigidModel | None, cfg: DetectorConfig,
    robot: RobotDescription | None = None, model_from_log: bool = False,
    allow_slow: bool = False,
) -> Replay:
    """:func:`impactcli.run.collect.stats_in_memory`, as the old record."""
    from .run.collect import stats_in_memory

    st, rp, plan = stats_in_memory(log, config=cfg, model=model, robot=robot,
                                   model_from_log=model_from_log, allow_slow=allow_slow)
    return Replay(log.select(plan.joints), plan.model, st.r, rp.warmup, st.stats)
