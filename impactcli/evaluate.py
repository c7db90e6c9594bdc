"""Alias of :mod:`impactcli.scoring` for the modules not yet moved to it (``study/``, a
benchmark): the names they import, re-exported, and :func:`sweep_thresholds` of an in-memory
result. alias: removed in M (callers import the scoring modules directly).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

# alias: removed in M (the whole module: callers import impactcli.scoring.* directly)
from .scoring.evaluation import (
    ContactOutcome,
    DetectorScore,
    Evaluation,
    KindScore,
    evaluate_events,
    evaluate_result,
)
from .scoring.incidents import (
    CONTACT_OF_KIND,
    CONTACT_TYPES,
    AnswerScore,
    IncidentEvaluation,
    IncidentOutcome,
    evaluate_incidents,
)
from .scoring.match import (
    EPS_S,
    EVALUATED,
    FORCE_KNOWN_FIELD,
    KINDS,
    PRODUCT,
    PRODUCT_PARTS,
    SCHEMA_VERSION,
    SECONDS_PER_HOUR,
    MatchTolerance,
    ScoredEvent,
    force_known,
    product_events,
)
from .scoring.sweep import (
    DEFAULT_SWEEP_SCALES,
    SweepRow,
    ThresholdSweep,
    event_intervals,
    geometric_scales,
    ratios_from_signals,
    sweep_ratios,
)
from .scoring.text import (
    format_evaluation,
    format_incident_evaluation,
)
from .scoring.verdict import (
    Comparison,
    adaptive_helps,
    at_zero_false_alarms,
    compare_at_zero,
    format_sweep,
    sweep_to_dict,
    verdict,
)

__all__ = [
    "CONTACT_OF_KIND",
    "CONTACT_TYPES",
    "DEFAULT_SWEEP_SCALES",
    "EPS_S",
    "EVALUATED",
    "FORCE_KNOWN_FIELD",
    "KINDS",
    "PRODUCT",
    "PRODUCT_PARTS",
    "SCHEMA_VERSION",
    "SECONDS_PER_HOUR",
    "AnswerScore",
    "Comparison",
    "ContactOutcome",
    "DetectorScore",
    "Evaluation",
    "IncidentEvaluation",
    "IncidentOutcome",
    "KindScore",
    "MatchTolerance",
    "ScoredEvent",
    "SweepRow",
    "ThresholdSweep",
    "adaptive_helps",
    "at_zero_false_alarms",
    "compare_at_zero",
    "evaluate_events",
    "evaluate_incidents",
    "evaluate_result",
    "event_intervals",
    "force_known",
    "format_evaluation",
    "format_incident_evaluation",
    "format_sweep",
    "geometric_scales",
    "product_events",
    "ratios_from_signals",
    "sweep_ratios",
    "sweep_thresholds",
    "sweep_to_dict",
    "verdict",
]


# alias: removed in M
def sweep_thresholds(result: Any, labels: Any, scales: Sequence[float], *,
                     tolerance: MatchTolerance | None = None, merge_gap_s: float | None = None,
                     min_duration_s: float | None = None,
                     detectors: Sequence[str] = EVALUATED) -> list[SweepRow]:
    """:func:`sweep_ratios` of a result holding its (N, J) ratios in memory, with the run's
    ``config["events"]`` settings unless given."""
    from .scoring.sweep import event_settings

    gap, min_dur = event_settings(result.config, merge_gap_s, min_duration_s)
    return sweep_ratios(result.ratios, result.log.time_s, labels=labels, scales=scales,
                        warmup_end_s=result.warmup_end_s, merge_gap_s=gap,
                        min_duration_s=min_dur, tolerance=tolerance, detectors=detectors)
