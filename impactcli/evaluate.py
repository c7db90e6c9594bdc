"""Detection quality against ground-truth labels, and the equal-false-alarm threshold sweep:
the public entry (``from impactcli.evaluate import ...``).

The code lives in :mod:`impactcli.scoring`, one concern a module, data flowing one way
(each imports only the ones before it):

- :mod:`impactcli.scoring.match`: the matching window (an event matches a labelled contact
  when it starts within ``[start - pre_s, end + post_s]``, :class:`MatchTolerance`), the
  events evaluation reads, the product's alarms (adaptive OR static_loading, merged);
- :mod:`impactcli.scoring.incidents`: the incidents (link, force, contact type) scored
  against the labels (:func:`evaluate_incidents`);
- :mod:`impactcli.scoring.evaluation`: a log's events scored per contact and per detector
  (:func:`evaluate_events`, :func:`evaluate_result`; the counting rules are its docstring);
- :mod:`impactcli.scoring.sweep`: every threshold rescaled and the events scored again
  (:func:`sweep_thresholds`, :func:`sweep_ratios`);
- :mod:`impactcli.scoring.verdict`: the zero-false-alarm points, adaptive against
  static_loading there, the verdict; the sweep as JSON and text;
- :mod:`impactcli.scoring.text`: the plain-text table of an evaluation.

This module only re-exports their names, so that callers and tests keep one import path.
Pure logic: no file I/O, no printing. The CLI (``impactcli evaluate``) reads the files.
"""

from __future__ import annotations

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
    _as_ev,  # noqa: F401  private, re-exported for tests
    _Ev,  # noqa: F401  private, re-exported for outputs/sweep_stream.py
    force_known,
    product_events,
)
from .scoring.sweep import (
    DEFAULT_SWEEP_SCALES,
    SweepRow,
    _event_settings,  # noqa: F401  private, re-exported for outputs/sweep_stream.py
    event_intervals,
    geometric_scales,
    ratios_from_signals,
    sweep_ratios,
    sweep_thresholds,
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
    "SweepRow",
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
