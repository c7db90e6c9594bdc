"""The result of one detection run: what every output (timeline, signals, report, Rerun) formats.

Built by :func:`impactcli.run.one_log.detect_log`; outputs only read it (no maths in outputs/).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .types import DETECTORS, Event

#: Per-sample signal names (docs/formats.md, "Per-sample signals"), each an (N, J) array.
SIGNAL_NAMES: tuple[str, ...] = (
    "torque",             # measured torque, after any current scaling, before filtering [N·m]
    "residual",           # r = tau_hat - tau (eq. 7) [N·m]
    "filtered_residual",  # r_tilde = G(z) r [N·m]
    "dynamic_threshold",  # v_dyn [N·m]
    "residual_rms",       # r_tilde_rms after F1 (eq. 41) [N·m]
    "threshold",          # |v_stat + v_rms| (eq. 42) [N·m]
    "loading_statistic",  # |LP(r)|, the static-loading detector's statistic [N·m]
)


@dataclass(frozen=True)
class DetectionResult:
    """Everything one replay produced.

    Attributes:
        log: the analysed log: a :class:`~impactcli.types.LogHeader` (the replayed joints
            in order; its ``source`` carries path and sha256).
        model: the rigid model used, as its JSON mapping (``RigidModel.to_dict()``) — for
            joints on a logged generator, the model of what the controller's channel leaves
            out; None when no joint needs one (controller channels taken plain).
        model_sha256: sha256 of that model's canonical JSON (None without a model).
        model_source: ``given`` (--model), ``config`` (embedded in --config),
            ``identified-from-log`` (offline convenience) or ``none``.
        generators: joint → {generator, reason, residual} (:mod:`impactcli.model.generators`).
        incidents: :class:`impactcli.detect.incidents.Incident` per physical contact.
        joints_left_out: ``{name, reason}`` of each logged joint left out of detection
            (:mod:`impactcli.detect.screen`; not in the model or config; left out at
            calibration).
        config: the detector config used, as its mapping, thresholds included.
        calibrated: thresholds came from a calibration on other logs (else the log's own
            statistics — an uncalibrated run).
        thresholds: per joint ``{"v_stat": .., "v0": .., "vL": ..}`` [N·m].
        reference_source: ``reference`` (logged controller reference) or ``measured``
            (fallback: causally filtered measured position).
        threshold_inputs: how u1, u2 were made, in words (which reference signals were
            logged, which were differentiated).
        torque_filtered: the measured torque went through the estimate's causal filter.
        events: all events, every detector, sorted by start time.
        warmup_end_s: the latest warm-up end over joints [s since first sample].
        warmup_per_joint_s: per joint warm-up end [s].
        filter_gain: ``{"frequencies_hz": [...], "gain": {joint: [...]}}`` of G_hat.
        warnings: one-line warnings raised during the run (also shown by the CLI).
        read_options: the options the log was read with (to re-run exactly).
    """

    log: LogHeader
    model: dict[str, Any] | None
    model_sha256: str | None
    model_source: str
    config: dict[str, Any]
    calibrated: bool
    thresholds: dict[str, dict[str, float]]
    reference_source: str
    torque_filtered: bool
    events: tuple[Event, ...]
    warmup_end_s: float
    warmup_per_joint_s: dict[str, float]
    filter_gain: dict[str, Any]
    residual_generator: str = "inverse_dynamics"
    warnings: tuple[str, ...] = ()
    threshold_inputs: str = ""
    read_options: dict[str, Any] = field(default_factory=dict)
    generators: dict[str, dict[str, str]] = field(default_factory=dict)
    joints_left_out: tuple[dict[str, str], ...] = ()
    incidents: tuple[Any, ...] = ()

    @property
    def online_equivalent(self) -> bool:
        """Model (or correction model) and thresholds came from other logs: the robot could
        have run this online."""
        return self.calibrated and self.model_source != "identified-from-log"

    def counted_events(self, detector: str) -> list[Event]:
        """Events of ``detector`` that start after warm-up (the ones summaries count)."""
        return [e for e in self.events if e.detector == detector and not e.in_warmup]

    def counted_incidents(self) -> list[Any]:
        """Incidents that start after warm-up (the ones summaries count)."""
        return [i for i in self.incidents if not i.in_warmup]

    def summary(self) -> dict[str, dict[str, int]]:
        """Per detector: events counted (after warm-up) and events in warm-up."""
        return {
            d: {
                "events": len(self.counted_events(d)),
                "in_warmup": sum(1 for e in self.events if e.detector == d and e.in_warmup),
            }
            for d in DETECTORS
        }
