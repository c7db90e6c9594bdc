"""The threshold sweep: every threshold rescaled, events re-extracted and scored again.

At scale ``s`` a detector decides ``ratio > s``, ``ratio = statistic / threshold`` (eq. 42
for the adaptive detector), so ``s = 1`` is the run; its events are re-extracted (the
intervals of :func:`impactcli.detect.events.extract_events`) and scored
(:func:`impactcli.quality.evaluation.evaluate_events`), which compares detectors at equal
false-alarm rates: one :class:`SweepRow` per (detector, scale). What the rows say is
:mod:`impactcli.quality.verdict`'s.

One sweep, fed by chunks in time order (:class:`ThresholdSweep`): a report's spill row group
by row group, a signals Parquet row group by row group (``evaluate TIMELINE --sweep``), or a
run's arrays as one chunk (:func:`sweep_ratios`, :func:`event_intervals`). Per (detector,
scale) an :class:`EventIntervals` carries across chunks the run of firing samples and the
merged event still open, so memory is one chunk and the events found.
Ratios are rebuilt from signal columns (a signals Parquet holds none) by the run's own
formula, :func:`impactcli.detect.thresholds.detector_ratios`. Pure logic: no file I/O, no printing.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..detect.thresholds import detector_ratios
from ..errors import ConfigError, ImpactWarning, LogFormatError
from ..types import DETECTORS, Labels
from .evaluation import evaluate_events
from .match import EPS_S, EVALUATED, PRODUCT, PRODUCT_PARTS, MatchTolerance, ScoredEvent, rounded


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
        collision_free_s: the time after warm-up outside every contact's window [s], over
            which ``false_alarms`` were counted (not in :meth:`to_dict`: the sweep's own).
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
    collision_free_s: float | None = None

    def to_dict(self, *, per_contact: bool = False) -> dict[str, Any]:
        """JSON-ready mapping (``per_contact``: with ``contact_delays_s``)."""
        d: dict[str, Any] = {
            "detector": self.detector, "scale": rounded(self.scale), "n_events": self.n_events,
            "n_contacts": self.n_contacts, "detected": self.detected,
            "false_alarms": self.false_alarms,
            "false_alarms_per_hour": rounded(self.false_alarms_per_hour, 6),
            "delay_median_s": rounded(self.delay_median_s),
            "min_detected_force": rounded(self.min_detected_force),
        }
        if per_contact:
            d["contact_delays_s"] = [rounded(v) for v in self.contact_delays_s]
        return d


class EventIntervals:
    """The events of one decision, from its samples in consecutive chunks.

    The intervals of :func:`impactcli.detect.events.extract_events` (decisions ORed over
    joints): runs of firing samples merged across gaps of at most ``merge_gap_s``, the one
    merged event across the warm-up's end split there, events shorter than
    ``min_duration_s`` dropped (1 ns tolerance on both). The split is done on the runs: a run
    across the warm-up's first sample k_w is cut before it, and a run at or after k_w never
    merges with one before it — the two parts
    :func:`impactcli.detect.events.split_at_warmup` gives (the part before ends at the last
    firing sample before k_w, the part after starts at the first at or after it).

    Args:
        merge_gap_s, min_duration_s: event extraction settings [s].
        warmup_end_s: the warm-up's end [s]; None: no split.
    """

    def __init__(self, merge_gap_s: float, min_duration_s: float,
                 warmup_end_s: float | None = None) -> None:
        self.gap, self.min_dur = merge_gap_s + EPS_S, min_duration_s - EPS_S
        self.split = warmup_end_s is not None
        self.wu = (warmup_end_s if warmup_end_s is not None else math.inf) - EPS_S
        self.k_w: int | None = None          # first sample at or after the warm-up's end
        self.t_kw = (math.nan, math.nan)     # t[k_w - 1], t[k_w]
        self.k0, self.t_last = 0, math.nan   # samples seen; the last one's time
        self.run: tuple[int, float, int, float] | None = None   # open at the last chunk's end
        self.open: tuple[int, float, int, float] | None = None  # the merged event still open
        self.out: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []

    def update(self, t: np.ndarray, fire: np.ndarray) -> None:
        """Absorb the next chunk: (m,) times [s] and (m,) bool decisions."""
        m = int(t.shape[0])
        if m == 0:
            return
        k0, self.k0 = self.k0, self.k0 + m
        if self.split and self.k_w is None:
            j = int(np.searchsorted(t, self.wu))
            if j < m:
                self.k_w = k0 + j
                self.t_kw = (float(t[j - 1]) if j > 0 else self.t_last, float(t[j]))
        self.t_last = float(t[-1])
        x = np.diff(np.asarray(fire, dtype=np.int8), prepend=np.int8(0), append=np.int8(0))
        s = np.flatnonzero(x == 1)
        e = np.flatnonzero(x == -1) - 1
        i0, t0, i1, t1 = s + k0, t[s], e + k0, t[e]
        if self.run is not None:
            r, self.run = self.run, None
            if s.size and s[0] == 0:  # the run goes on
                i0[0], t0[0] = r[0], r[1]
            else:
                i0, t0 = np.concatenate(([r[0]], i0)), np.concatenate(([r[1]], t0))
                i1, t1 = np.concatenate(([r[2]], i1)), np.concatenate(([r[3]], t1))
        if e.size and e[-1] == m - 1:  # open at the chunk's end
            self.run = (int(i0[-1]), float(t0[-1]), int(i1[-1]), float(t1[-1]))
            i0, t0, i1, t1 = i0[:-1], t0[:-1], i1[:-1], t1[:-1]
        self._runs(i0, t0, i1, t1)

    def _runs(self, i0: np.ndarray, t0: np.ndarray, i1: np.ndarray, t1: np.ndarray) -> None:
        """Merge complete runs (first and last index and time, in order) into events."""
        if i0.size == 0:
            return
        kw = self.k_w if self.k_w is not None else np.iinfo(np.int64).max
        cut = np.flatnonzero((i0 < kw) & (i1 >= kw))
        if cut.size:  # across the warm-up's end: two runs
            p = int(cut[0])
            i0, t0 = np.insert(i0, p + 1, kw), np.insert(t0, p + 1, self.t_kw[1])
            i1, t1 = np.insert(i1, p, kw - 1), np.insert(t1, p, self.t_kw[0])
        if self.open is not None:
            o = self.open
            i0, t0 = np.concatenate(([o[0]], i0)), np.concatenate(([o[1]], t0))
            i1, t1 = np.concatenate(([o[2]], i1)), np.concatenate(([o[3]], t1))
        apart = ~(t0[1:] - t1[:-1] <= self.gap) | ((i0[1:] >= kw) & (i1[:-1] < kw))
        first = np.concatenate(([0], np.flatnonzero(apart) + 1))
        last = np.concatenate((first[1:] - 1, [i0.size - 1]))
        self.open = (int(i0[first[-1]]), float(t0[first[-1]]), int(i1[last[-1]]),
                     float(t1[last[-1]]))
        self._close(i0[first[:-1]], t0[first[:-1]], i1[last[:-1]], t1[last[:-1]])

    def _close(self, i0: np.ndarray, t0: np.ndarray, i1: np.ndarray, t1: np.ndarray) -> None:
        keep = t1 - t0 >= self.min_dur
        if keep.any():
            self.out.append((i0[keep], t0[keep], i1[keep], t1[keep]))

    def finish(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The events, in time order: (E,) first and last sample index, (E,) their times [s]."""
        if self.run is not None:
            r, self.run = self.run, None
            self._runs(np.array([r[0]]), np.array([r[1]]), np.array([r[2]]), np.array([r[3]]))
        if self.open is not None:
            o, self.open = self.open, None
            self._close(np.array([o[0]]), np.array([o[1]]), np.array([o[2]]), np.array([o[3]]))
        if not self.out:
            z = np.zeros(0, dtype=np.int64)
            return z, np.zeros(0), z, np.zeros(0)
        i0, t0, i1, t1 = (np.concatenate(p) for p in zip(*self.out, strict=True))
        self.out = [(i0, t0, i1, t1)]
        return i0, t0, i1, t1


def event_intervals(
    decision: np.ndarray, time_s: np.ndarray, merge_gap_s: float, min_duration_s: float,
    warmup_end_s: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(i_start, i_end) sample indices of the events of an (N, J) or (N,) decision: the
    intervals of :func:`impactcli.detect.events.extract_events` (:class:`EventIntervals`
    fed one chunk), without the per-event joints and peaks a sweep does not need."""
    dec = np.asarray(decision, dtype=bool)
    iv = EventIntervals(merge_gap_s, min_duration_s, warmup_end_s)
    fire = np.asarray(dec.any(axis=1)) if dec.ndim == 2 else dec
    iv.update(np.asarray(time_s, dtype=np.float64), fire)
    i0, _, i1, _ = iv.finish()
    return i0, i1


def event_settings(config: Any, merge_gap_s: float | None,
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


def sorted_scales(scales: Sequence[float]) -> list[float]:
    """The sweep's distinct scales, ascending (ConfigError unless positive and finite)."""
    out = sorted({float(s) for s in scales})
    if not out or any(not (math.isfinite(s) and s > 0) for s in out):
        raise ConfigError(f"sweep: scales must be positive finite numbers, got {list(scales)!r}")
    return out


class ThresholdSweep:
    """The sweep of one run, fed its ratios chunk by chunk in time order.

    Args:
        scales: threshold multipliers (> 0).
        warmup_end_s [s]; merge_gap_s, min_duration_s: event extraction settings [s].
        detectors: the rows wanted, of :data:`EVALUATED` (the product needs its parts'
            ratios).
    """

    def __init__(self, scales: Sequence[float], *, warmup_end_s: float, merge_gap_s: float,
                 min_duration_s: float, detectors: Sequence[str] = EVALUATED) -> None:
        self.scales = sorted_scales(scales)
        for d in detectors:
            if d not in EVALUATED:
                raise ConfigError(f"sweep: unknown detector {d!r} (expected one of {EVALUATED})")
        need = {d for d in detectors if d != PRODUCT}
        if PRODUCT in detectors:
            need |= set(PRODUCT_PARTS)
        self.need = [d for d in DETECTORS if d in need]
        self.rows_of = [d for d in EVALUATED if d in detectors]
        self.warmup_end_s, self.merge_gap_s = float(warmup_end_s), float(merge_gap_s)
        self.iv = {(d, s): EventIntervals(merge_gap_s, min_duration_s, warmup_end_s)
                   for d in self.need for s in self.scales}
        self.t_first = self.t_last = math.nan

    def update(self, time_s: np.ndarray, ratios: Mapping[str, np.ndarray]) -> None:
        """The next chunk: (m,) times [s since the first sample] and detector → (m, J)
        statistic / threshold [-] (decision at scale s: ratio > s on some joint)."""
        for d in sorted(self.need):
            if d not in ratios:
                raise ConfigError(f"sweep: the run holds no ratios for detector {d!r}")
        t = np.asarray(time_s, dtype=np.float64)
        if t.size == 0:
            return
        if math.isnan(self.t_first):
            self.t_first = float(t[0])
        self.t_last = float(t[-1])
        for d in self.need:
            r = np.asarray(ratios[d], dtype=np.float64)
            # some joint above s <=> the largest non-NaN ratio above s
            top = np.fmax.reduce(r, axis=1) if r.ndim == 2 else r
            for s in self.scales:
                self.iv[(d, s)].update(t, top > s)

    def rows(self, labels: Labels, tolerance: MatchTolerance | None = None,
             changes: Sequence[Mapping[str, Any]] = ()) -> list[SweepRow]:
        """One :class:`SweepRow` per (detector, scale): detectors in :data:`EVALUATED`
        order, scales ascending. Call once, after the last chunk. ``changes``: the run's
        payload changes (timeline ``payload_changes`` items): an event at any scale from a
        change's onset to its classification is its alarm, not a false alarm (as
        ``evaluate`` has it)."""
        loads = [{"t_start": float(c["t_start"]), "t_end": float(c["t_classified"]),
                  "payload_change": k} for k, c in enumerate(changes, 1)]
        tol = tolerance if tolerance is not None else MatchTolerance()
        wu = self.warmup_end_s
        duration_s = 0.0 if math.isnan(self.t_first) else self.t_last - self.t_first
        found = {k: iv.finish() for k, iv in self.iv.items()}
        rows_of: dict[str, list[SweepRow]] = {d: [] for d in self.rows_of}
        with warnings.catch_warnings():
            # contacts after the log's end are warned about once, below, not once per scale
            warnings.simplefilter("ignore", ImpactWarning)
            for s in self.scales:
                evs = [ScoredEvent(d, a, b, a < wu) for d in self.need
                       for a, b in zip(found[(d, s)][1].tolist(), found[(d, s)][3].tolist(),
                                       strict=True)]
                add_rows(rows_of, s, evs, labels, duration_s=duration_s, warmup_end_s=wu,
                         tolerance=tol, merge_gap_s=self.merge_gap_s, loads=loads)
        warn_late_labels(labels, duration_s, wu, tol)
        return [r for rows in rows_of.values() for r in rows]


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
    changes: Sequence[Mapping[str, Any]] = (),
) -> list[SweepRow]:
    """The sweep of a run's arrays, one chunk of :class:`ThresholdSweep`; ``changes`` its
    payload changes (:meth:`ThresholdSweep.rows`).

    Args:
        ratios: detector → (N, J) statistic / threshold [-] (decision at scale s: ratio > s).
        time_s: (N,) seconds since the first sample.
        labels: ground truth. scales: threshold multipliers (> 0).
        warmup_end_s [s]; merge_gap_s, min_duration_s: event extraction settings [s].
        tolerance: the matching window. detectors: the rows wanted.
    """
    sweep = ThresholdSweep(scales, warmup_end_s=warmup_end_s, merge_gap_s=merge_gap_s,
                           min_duration_s=min_duration_s, detectors=detectors)
    sweep.update(time_s, ratios)
    return sweep.rows(labels, tolerance, changes)


def add_rows(rows_of: dict[str, list[SweepRow]], scale: float, evs: list[ScoredEvent],
             labels: Labels, *, duration_s: float, warmup_end_s: float,
             tolerance: MatchTolerance, merge_gap_s: float,
             loads: Sequence[Mapping[str, Any]] = ()) -> None:
    """Score one scale's events against the labels; one :class:`SweepRow` per detector of
    ``rows_of``; ``loads``: the payload changes' alarms as spans (incident-like mappings,
    :meth:`ThresholdSweep.rows`)."""
    ev = evaluate_events(
        evs, labels, duration_s=duration_s, warmup_end_s=warmup_end_s, tolerance=tolerance,
        product_merge_gap_s=merge_gap_s, detectors=list(rows_of),
        incidents=list(loads) or None,
    )
    for d, sc in ev.scores.items():
        per_contact = tuple(
            c.delay_s[d] if c.status == "counted" and c.detected[d] else None
            for c in ev.contacts)
        rows_of[d].append(SweepRow(
            d, scale, sc.n_events, sc.n_contacts, sc.detected, sc.false_alarms,
            sc.false_alarms_per_hour, sc.delay_median_s, sc.min_detected_force,
            per_contact, ev.collision_free_s))


def warn_late_labels(labels: Labels, duration_s: float, warmup_end_s: float,
                     tolerance: MatchTolerance) -> None:
    """Contacts labelled after the log's end: warned about once (scoring the scales kept
    quiet), by scoring nothing."""
    if any(c.start > duration_s for c in labels.events):
        evaluate_events([], labels, duration_s=duration_s, warmup_end_s=warmup_end_s,
                        tolerance=tolerance, detectors=())


def ratios_from_signals(
    columns: Mapping[str, np.ndarray], joint_names: Sequence[str],
    thresholds: Mapping[str, Mapping[str, float]],
) -> dict[str, np.ndarray]:
    """The detectors' (n, J) ratios (:func:`~impactcli.detect.thresholds.detector_ratios`)
    from a signals Parquet's columns
    (``<joint>.<signal>``, docs/formats.md, "Per-sample signals") and a timeline's
    per-joint thresholds ``{v0, vL}`` [N·m].

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

    per = [detector_ratios(col(j, "residual_rms"), col(j, "threshold"),
                         col(j, "loading_statistic"), np.abs(col(j, "residual")),
                         thr(j, "vL"), thr(j, "v0")) for j in joint_names]
    return {d: np.column_stack([p[d] for p in per]) for d in DETECTORS}
