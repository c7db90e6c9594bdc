"""The threshold sweep: every threshold rescaled, events re-extracted and scored again.

:func:`sweep_thresholds` rescales every threshold by a factor ``s`` — decision
``ratio > s`` with ``ratio = statistic / threshold`` (eq. 42 for the adaptive detector) —
re-extracts events (:func:`event_intervals`, the intervals of
:func:`impactcli.detect.events.extract_events`) and evaluates them
(:func:`impactcli.scoring.evaluation.evaluate_events`), so that detectors can be compared at
equal false-alarm rates: one :class:`SweepRow` per (detector, scale). :func:`sweep_ratios`
is the same on bare arrays (the ratios of a run, or :func:`ratios_from_signals` rebuilt
from a signals Parquet); the streamed sweep (:mod:`impactcli.outputs.sweep_stream`) reuses
its pieces. What the rows say is :mod:`impactcli.scoring.verdict`'s.

Pure logic: no file I/O, no printing.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..detect.events import split_at_warmup
from ..errors import ConfigError, ImpactWarning, LogFormatError
from ..types import DETECTORS, Labels
from .evaluation import evaluate_events
from .match import EPS_S, EVALUATED, PRODUCT, PRODUCT_PARTS, MatchTolerance, _Ev, _r

if TYPE_CHECKING:
    from ..result import DetectionResult


def geometric_scales(start: float, stop: float, factor: float) -> tuple[float, ...]:
    """Threshold scales ``start × factor^k`` up to ``stop`` (inclusive), 4 significant digits.

    Thresholds compare in ratios, so a geometric grid spaces them evenly.
    """
    if not (stop >= start > 0 and factor > 1):
        raise ValueError(f"geometric scales need 0 < start <= stop and factor > 1, got "
                         f"{start!r}, {stop!r}, {factor!r}")
    n = math.floor(math.log(stop / start) / math.log(factor) + 1e-9)
    if n > 10_000:
        raise ValueError(f"geometric scales: {n + 1} scales are too many")
    return tuple(sorted({float(f"{start * factor**k:.4g}") for k in range(n + 1)}))


#: The default sweep: 0.2 … 5 in 5 % steps (66 scales).
DEFAULT_SWEEP_SCALES: tuple[float, ...] = geometric_scales(0.2, 5.0, 1.05)


@dataclass(frozen=True)
class SweepRow:
    """One (detector, threshold scale) point of a sweep.

    Attributes:
        detector: a detector of :data:`EVALUATED`.
        scale: threshold multiplier s (decision: statistic / threshold > s) [-].
        n_events: counted events; n_contacts, detected: counted contacts and those detected.
        false_alarms, false_alarms_per_hour: as in :class:`DetectorScore`.
        delay_median_s [s], min_detected_force [N]: None when nothing is detected.
        contact_delays_s: per labelled contact (labels order), its detection delay [s], or
            None when missed or not counted (warm-up, outside the log) — for paired
            comparisons between detectors.
    """

    detector: str
    scale: float
    n_events: int
    n_contacts: int
    detected: int
    false_alarms: int
    false_alarms_per_hour: float | None
    delay_median_s: float | None
    min_detected_force: float | None
    contact_delays_s: tuple[float | None, ...] = ()

    def to_dict(self, *, per_contact: bool = False) -> dict[str, Any]:
        """JSON-ready mapping (``per_contact``: with ``contact_delays_s``)."""
        d: dict[str, Any] = {
            "detector": self.detector, "scale": _r(self.scale), "n_events": self.n_events,
            "n_contacts": self.n_contacts, "detected": self.detected,
            "false_alarms": self.false_alarms,
            "false_alarms_per_hour": _r(self.false_alarms_per_hour, 6),
            "delay_median_s": _r(self.delay_median_s),
            "min_detected_force": _r(self.min_detected_force),
        }
        if per_contact:
            d["contact_delays_s"] = [_r(v) for v in self.contact_delays_s]
        return d


def event_intervals(
    decision: np.ndarray, time_s: np.ndarray, merge_gap_s: float, min_duration_s: float,
    warmup_end_s: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(i_start, i_end) sample indices of the events of an (N, J) decision, vectorised.

    The same intervals as :func:`impactcli.detect.events.extract_events` (decisions ORed over
    joints; bursts whose gap ≤ ``merge_gap_s`` merged; events shorter than
    ``min_duration_s`` dropped; 1 ns tolerance on both) without the per-event joints and
    peaks, which a sweep does not need — several times faster on noisy low scales (tests
    check the equality).
    """
    dec = np.asarray(decision, dtype=bool)
    anyd = np.asarray(dec.any(axis=1)) if dec.ndim == 2 else dec
    t = np.asarray(time_s, dtype=np.float64)
    x = np.diff(anyd.astype(np.int8), prepend=np.int8(0), append=np.int8(0))
    starts = np.flatnonzero(x == 1)
    ends = np.flatnonzero(x == -1) - 1
    if starts.size == 0:
        return starts, ends
    new = np.concatenate(([True], t[starts[1:]] - t[ends[:-1]] > merge_gap_s + EPS_S))
    first = np.flatnonzero(new)
    g_start = starts[first]
    g_end = ends[np.concatenate((first[1:] - 1, [ends.size - 1]))]
    if warmup_end_s is not None:
        g_start, g_end = split_at_warmup(g_start, g_end, anyd, t, warmup_end_s)
    keep = t[g_end] - t[g_start] >= min_duration_s - EPS_S
    return g_start[keep], g_end[keep]


def _event_settings(config: Any, merge_gap_s: float | None,
                    min_duration_s: float | None) -> tuple[float, float]:
    """(merge_gap_s, min_duration_s): the keyword values, else the run's ``config["events"]``."""
    cfg = config.get("events") if isinstance(config, Mapping) else None
    cfg = cfg if isinstance(cfg, Mapping) else {}
    out = []
    for name, given in (("merge_gap_s", merge_gap_s), ("min_duration_s", min_duration_s)):
        v = given if given is not None else cfg.get(name)
        if v is None:
            raise ConfigError(f"sweep: the run's config has no events.{name}; pass {name}=")
        out.append(float(v))
    return out[0], out[1]


def sweep_ratios(
    ratios: Mapping[str, np.ndarray],
    time_s: np.ndarray,
    *,
    labels: Labels,
    scales: Sequence[float],
    warmup_end_s: float,
    merge_gap_s: float,
    min_duration_s: float,
    tolerance: MatchTolerance | None = None,
    detectors: Sequence[str] = EVALUATED,
) -> list[SweepRow]:
    """The sweep on bare arrays (see :func:`sweep_thresholds`).

    Args:
        ratios: detector → (N, J) statistic / threshold [-] (decision at scale s: ratio > s).
        time_s: (N,) seconds since the first sample.
        labels: ground truth. scales: threshold multipliers (> 0).
        warmup_end_s [s]; merge_gap_s, min_duration_s: event extraction settings [s].
    """
    tol = tolerance if tolerance is not None else MatchTolerance()
    scales_sorted = sorted_scales(scales)
    for d in detectors:
        if d not in EVALUATED:
            raise ConfigError(f"sweep: unknown detector {d!r} (expected one of {EVALUATED})")
    need = {d for d in detectors if d != PRODUCT}
    if PRODUCT in detectors:
        need |= set(PRODUCT_PARTS)
    for d in sorted(need):
        if d not in ratios:
            raise ConfigError(f"sweep: the run holds no ratios for detector {d!r}")
    time_s = np.asarray(time_s, dtype=np.float64)
    duration_s = float(time_s[-1] - time_s[0]) if time_s.size else 0.0
    rows_of: dict[str, list[SweepRow]] = {d: [] for d in EVALUATED if d in detectors}
    with warnings.catch_warnings():
        # contacts after the log's end are warned about once, below, not once per scale
        warnings.simplefilter("ignore", ImpactWarning)
        for s in scales_sorted:
            evs: list[_Ev] = []
            for d in DETECTORS:
                if d in need:
                    i0, i1 = event_intervals(np.asarray(ratios[d]) > s, time_s, merge_gap_s,
                                             min_duration_s, warmup_end_s)
                    evs += [_Ev(d, a, b, a < warmup_end_s) for a, b in
                            zip(time_s[i0].tolist(), time_s[i1].tolist(), strict=True)]
            add_rows(rows_of, s, evs, labels, duration_s=duration_s,
                     warmup_end_s=warmup_end_s, tolerance=tol, merge_gap_s=merge_gap_s)
    warn_late_labels(labels, duration_s, warmup_end_s, tol)
    return [r for rows in rows_of.values() for r in rows]


def sorted_scales(scales: Sequence[float]) -> list[float]:
    """The sweep's distinct scales, ascending (ConfigError unless positive and finite)."""
    out = sorted({float(s) for s in scales})
    if not out or any(not (math.isfinite(s) and s > 0) for s in out):
        raise ConfigError(f"sweep: scales must be positive finite numbers, got {list(scales)!r}")
    return out


def add_rows(rows_of: dict[str, list[SweepRow]], scale: float, evs: list[_Ev],
             labels: Labels, *, duration_s: float, warmup_end_s: float,
             tolerance: MatchTolerance, merge_gap_s: float) -> None:
    """Score one scale's events against the labels; one :class:`SweepRow` per detector of
    ``rows_of`` (the whole-log sweep and the streamed one, outputs/sweep_stream.py)."""
    ev = evaluate_events(
        evs, labels, duration_s=duration_s, warmup_end_s=warmup_end_s, tolerance=tolerance,
        product_merge_gap_s=merge_gap_s, detectors=list(rows_of),
    )
    for d, sc in ev.scores.items():
        per_contact = tuple(
            c.delay_s[d] if c.status == "counted" and c.detected[d] else None
            for c in ev.contacts)
        rows_of[d].append(SweepRow(
            d, scale, sc.n_events, sc.n_contacts, sc.detected, sc.false_alarms,
            sc.false_alarms_per_hour, sc.delay_median_s, sc.min_detected_force,
            per_contact))


def warn_late_labels(labels: Labels, duration_s: float, warmup_end_s: float,
                     tolerance: MatchTolerance) -> None:
    """Contacts labelled after the log's end: warned about once (scoring the scales kept
    quiet), by scoring nothing."""
    if any(c.start > duration_s for c in labels.events):
        evaluate_events([], labels, duration_s=duration_s, warmup_end_s=warmup_end_s,
                        tolerance=tolerance, detectors=())


def sweep_thresholds(
    result: DetectionResult,
    labels: Labels,
    scales: Sequence[float],
    *,
    tolerance: MatchTolerance | None = None,
    merge_gap_s: float | None = None,
    min_duration_s: float | None = None,
    detectors: Sequence[str] = EVALUATED,
) -> list[SweepRow]:
    """Rescale every detector's thresholds by each ``s`` in ``scales`` and evaluate.

    For each detector, decisions are ``result.ratios[detector] > s`` ((N, J); ratio =
    statistic / threshold — r_rms / |v_stat + v_rms| for the adaptive detector, eq. 42 —
    so s = 1 reproduces the run), events are re-extracted
    (the intervals of :func:`impactcli.detect.events.extract_events`, via
    :func:`event_intervals`) with the run's ``config["events"]``
    settings (``merge_gap_s``, ``min_duration_s``; the keyword arguments override or supply
    them) and scored with :func:`evaluate_events`. The product at scale s is the OR of
    adaptive and static_loading both at scale s (their events merged within merge_gap_s).

    Returns:
        One :class:`SweepRow` per (detector, scale), detectors in :data:`EVALUATED` order,
        scales ascending.
    """
    gap, min_dur = _event_settings(result.config, merge_gap_s, min_duration_s)
    log = result.log
    return sweep_ratios(
        result.ratios, log.time_s, labels=labels, scales=scales,
        warmup_end_s=result.warmup_end_s, merge_gap_s=gap, min_duration_s=min_dur,
        tolerance=tolerance, detectors=detectors,
    )


def ratios_from_signals(
    columns: Mapping[str, np.ndarray], joint_names: Sequence[str],
    thresholds: Mapping[str, Mapping[str, float]],
) -> dict[str, np.ndarray]:
    """Rebuild the detectors' (N, J) ratios from a signals Parquet's columns (formats.md).

    adaptive = ``residual_rms / threshold`` (eq. 42, threshold = |v_stat + v_rms|);
    static_loading = ``loading_statistic / vL``; static_baseline = ``|residual| / v0``.

    Args:
        columns: column name → (N,) array (``<joint>.<signal>``).
        joint_names: the J joints in order. thresholds: per joint ``{v0, vL}`` [N·m].

    Returns:
        detector → (N, J) ratio.

    Raises:
        LogFormatError naming the first missing column or threshold.
    """
    def col(j: str, name: str) -> np.ndarray:
        key = f"{j}.{name}"
        if key not in columns:
            raise LogFormatError(f"signals: column {key!r} missing")
        return np.asarray(columns[key], dtype=np.float64)

    def thr(j: str, name: str) -> float:
        try:
            return float(thresholds[j][name])
        except (KeyError, TypeError, ValueError):
            raise LogFormatError(f"timeline: thresholds.{j}.{name} missing") from None

    def safe_div(a: np.ndarray, b: np.ndarray | float) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.asarray(np.where(np.asarray(b) > 0, a / b, np.inf))

    return {
        "adaptive": np.column_stack([
            safe_div(np.abs(col(j, "residual_rms")), np.abs(col(j, "threshold")))
            for j in joint_names]),
        "static_loading": np.column_stack([
            safe_div(np.abs(col(j, "loading_statistic")), thr(j, "vL")) for j in joint_names]),
        "static_baseline": np.column_stack([
            safe_div(np.abs(col(j, "residual")), thr(j, "v0")) for j in joint_names]),
    }
