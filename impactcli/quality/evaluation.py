"""A log's detection events scored against its labels: per labelled contact what each
detector did, per detector its score (:func:`evaluate_events`, :class:`Evaluation`); the
window and the product's alarms are :mod:`impactcli.quality.match`'s, the incidents part
:mod:`impactcli.quality.incident_scores`'s; the sweep calls :func:`evaluate_events` per scale.

A contact is *detected* by a detector when a counted event of it matches; its *delay* is
the earliest match's start minus the onset (down to ``-pre_s``). One event may match several
contacts (all detected, no false alarm); an event still on when a second contact begins
matches only the first (the second is missed, flagged ``alarm_on_at_onset``). A *false
alarm* is a counted event (starting after warm-up) that matches no contact. Events in
warm-up are listed, never counted; a contact with its onset in warm-up (``in_warmup``) or
after the log's end (``outside_log``) is reported, not counted as a miss. False alarms are
per hour of *collision-free time*: ``[warmup_end_s, duration_s]`` outside every contact's
window. The *product* (adaptive OR static_loading, alarms merged) detects a contact when a
part does, with the earliest part's delay (never worse than a part); a product alarm is
false when one of the part alarms starting in it matched no contact.

Pure logic: no file I/O, no printing.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..detect.incidents import union_length
from ..errors import ConfigError, ImpactWarning, LabelsError, LogFormatError
from ..types import DETECTORS, ContactLabel, Event, Labels
from .incident_scores import IncidentEvaluation, evaluate_incidents
from .match import (
    EPS_S,
    EVALUATED,
    KINDS,
    PRODUCT,
    PRODUCT_PARTS,
    SCHEMA_VERSION,
    SECONDS_PER_HOUR,
    MatchTolerance,
    ScoredEvent,
    force_known,
    median_or_none,
    product_events,
    rounded,
    scored_event,
)

if TYPE_CHECKING:
    from ..types import DetectionResult


@dataclass(frozen=True)
class ContactOutcome:
    """What each detector did about one labelled contact.

    Attributes:
        index: position in the labels file's ``events`` (0-based).
        label: the contact itself.
        status: ``counted``; ``in_warmup`` (onset before warm-up end: reported, not counted);
            ``outside_log`` (onset after the log's last sample: not counted).
        detected: detector → whether a counted event matched it (for ``in_warmup`` contacts:
            whether any event, warm-up ones included, matched — informational).
        delay_s: detector → earliest matching event start − contact start [s], or None.
        alarm_on_at_onset: detector → not detected, but an earlier counted event of that
            detector was still on at the contact's onset (its alarm was already raised).
    """

    index: int
    label: ContactLabel
    status: str
    detected: dict[str, bool]
    delay_s: dict[str, float | None]
    alarm_on_at_onset: dict[str, bool]


@dataclass(frozen=True)
class KindScore:
    """One detector's score on the counted contacts of one kind (impact, push, clamp)."""

    kind: str
    n_contacts: int
    detected: int
    delay_median_s: float | None
    min_detected_force: float | None
    max_missed_force: float | None


@dataclass(frozen=True)
class DetectorScore:
    """One detector's score over a log.

    Attributes:
        detector: ``adaptive``, ``static_loading``, ``static_baseline`` or ``product``.
        n_events: counted events (starting after warm-up).
        n_events_in_warmup: events in warm-up (listed in ``warmup_events``, never counted).
        n_contacts: counted contacts (onset after warm-up, inside the log).
        detected: counted contacts matched by at least one counted event.
        false_alarms: counted events matching no contact.
        false_alarms_per_hour: ``false_alarms`` per hour of collision-free time (None when
            there is no collision-free time).
        delay_median_s, delay_max_s: over detected contacts [s] (None when none detected).
        min_detected_force: smallest ``peak_force`` among detected contacts [N].
        max_missed_force: largest ``peak_force`` among missed contacts [N].
        by_kind: the same per contact kind present among counted contacts.
        false_alarm_times: (t_start, t_end) of each false alarm [s].
        warmup_events: (t_start, t_end) of each event in warm-up [s].
        payload_change_events: (t_start, t_end) of each counted event inside a payload
            change's alarm that matches no contact [s]: a load picked or released, not a
            false alarm (the run's incidents say which: ``payload_change``).
    """

    detector: str
    n_events: int
    n_events_in_warmup: int
    n_contacts: int
    detected: int
    false_alarms: int
    false_alarms_per_hour: float | None
    delay_median_s: float | None
    delay_max_s: float | None
    min_detected_force: float | None
    max_missed_force: float | None
    by_kind: tuple[KindScore, ...] = ()
    false_alarm_times: tuple[tuple[float, float], ...] = ()
    warmup_events: tuple[tuple[float, float], ...] = ()
    payload_change_events: tuple[tuple[float, float], ...] = ()

    @property
    def missed(self) -> int:
        """Counted contacts not detected."""
        return self.n_contacts - self.detected

    @property
    def recall(self) -> float | None:
        """Detected / counted contacts (None without counted contacts)."""
        return self.detected / self.n_contacts if self.n_contacts else None


@dataclass(frozen=True)
class Evaluation:
    """Detection quality of one log's events against its labels (see the module docstring).

    Attributes:
        tolerance: the matching rule used.
        duration_s: log duration [s]; warmup_end_s: warm-up end [s].
        collision_free_s: time after warm-up outside every contact's window [s].
        contacts: per labelled contact, what each detector did.
        scores: detector → its score, detectors in :data:`EVALUATED` order.
        labels_path: where the labels came from (for the record).
        product_merge_gap_s: gap below which adaptive and static-loading events merge [s].
        incidents: the incidents (the answer: link, force, contact type) scored against
            the labels (:func:`evaluate_incidents`); ``available`` False without them.
        payload_changes: the payload changes found scored against the labelled ones
            (:func:`impactcli.quality.payload_scores.score_payload_changes`); None when the
            labels list none and the run looked for none.
    """

    tolerance: MatchTolerance
    duration_s: float
    warmup_end_s: float
    collision_free_s: float
    contacts: tuple[ContactOutcome, ...]
    scores: dict[str, DetectorScore]
    labels_path: str = ""
    product_merge_gap_s: float = 0.0
    # a frozen dataclass (an immutable default), defined in incidents.py
    incidents: IncidentEvaluation = IncidentEvaluation(False, "no incidents given")  # noqa: RUF009
    payload_changes: dict[str, Any] | None = None

    def contacts_with_status(self, status: str) -> list[ContactOutcome]:
        """Contacts of one status (``counted``, ``in_warmup``, ``outside_log``)."""
        return [c for c in self.contacts if c.status == status]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (schemas/evaluation.schema.json); deterministic."""
        def score(s: DetectorScore) -> dict[str, Any]:
            return {
                "n_events": s.n_events,
                "n_events_in_warmup": s.n_events_in_warmup,
                "n_contacts": s.n_contacts,
                "detected": s.detected,
                "missed": s.missed,
                "recall": rounded(s.recall, 6),
                "false_alarms": s.false_alarms,
                "false_alarms_per_hour": rounded(s.false_alarms_per_hour, 6),
                "delay_median_s": rounded(s.delay_median_s),
                "delay_max_s": rounded(s.delay_max_s),
                "min_detected_force": rounded(s.min_detected_force),
                "max_missed_force": rounded(s.max_missed_force),
                "by_kind": {
                    k.kind: {
                        "n_contacts": k.n_contacts, "detected": k.detected,
                        "delay_median_s": rounded(k.delay_median_s),
                        "min_detected_force": rounded(k.min_detected_force),
                        "max_missed_force": rounded(k.max_missed_force),
                    }
                    for k in s.by_kind
                },
                "false_alarm_times": [[rounded(a), rounded(b)] for a, b in s.false_alarm_times],
                "warmup_events": [[rounded(a), rounded(b)] for a, b in s.warmup_events],
                **({"payload_change_events": [[rounded(a), rounded(b)] for a, b in
                                              s.payload_change_events]}
                   if s.payload_change_events else {}),
            }

        return {
            "schema_version": SCHEMA_VERSION,
            "labels": self.labels_path,
            "tolerance": {"pre_s": self.tolerance.pre_s, "post_s": self.tolerance.post_s,
                          "rule": "an event matches a contact if it starts within "
                                  "[start - pre_s, end + post_s]"},
            "product": {"detectors": list(PRODUCT_PARTS), "merge_gap_s": self.product_merge_gap_s},
            "duration_s": rounded(self.duration_s),
            "warmup_end_s": rounded(self.warmup_end_s),
            "collision_free_s": rounded(self.collision_free_s),
            "n_contacts": {
                st: len(self.contacts_with_status(st))
                for st in ("counted", "in_warmup", "outside_log")
            },
            "detectors": {d: score(s) for d, s in self.scores.items()},
            "contacts": [
                {
                    "index": c.index, "start": c.label.start, "end": c.label.end,
                    "peak_force": c.label.peak_force, "kind": c.label.kind, "link": c.label.link,
                    "status": c.status,
                    "detected": dict(c.detected),
                    "delay_s": {d: rounded(v) for d, v in c.delay_s.items()},
                    "alarm_on_at_onset": dict(c.alarm_on_at_onset),
                }
                for c in self.contacts
            ],
            "incidents": self.incidents.to_dict(),
            **({} if self.payload_changes is None
               else {"payload_changes": _rounded_tree(self.payload_changes)}),
        }


def _rounded_tree(x: Any) -> Any:
    """``x`` with every float :func:`rounded` (the evaluation's JSON is deterministic)."""
    if isinstance(x, dict):
        return {k: _rounded_tree(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_rounded_tree(v) for v in x]
    return rounded(x) if isinstance(x, float) else x


def with_payload_changes(ev: Evaluation, labels: Labels,
                         found: Sequence[dict[str, Any]] | None) -> Evaluation:
    """``ev`` with its payload changes scored (:mod:`impactcli.quality.payload_scores`)
    when the labels list some (``payload_changes``) or the run found some; ``found`` None:
    the run did not look for loads (its timeline has no ``payload_changes``), said as
    ``watched: false``, not as misses."""
    from .payload_scores import labelled_steps, score_payload_changes

    labelled = labels.extra.get("payload_changes")
    if not labelled and not found:
        return ev
    if found is None:  # the run did not look for loads (no monitor): nothing was missed
        return replace(ev, payload_changes={"watched": False,
                                            "labelled": len(labelled_steps(labelled or ()))})
    return replace(ev, payload_changes={"watched": True, **score_payload_changes(
        list(found), list(labelled or ()))})


def _match(
    evs: Sequence[ScoredEvent], win_lo: np.ndarray, win_hi: np.ndarray
) -> tuple[list[float | None], list[float | None], np.ndarray]:
    """Match events (sorted by start) to contact windows.

    Returns, per contact, the earliest counted matching start and the earliest matching start
    of any event (warm-up included), and per event whether it matched any contact.
    """
    n_c = win_lo.shape[0]
    if not evs or n_c == 0:
        return [None] * n_c, [None] * n_c, np.zeros(len(evs), dtype=bool)
    t0 = np.array([e.t_start for e in evs], dtype=np.float64)
    warm = np.array([e.in_warmup for e in evs], dtype=bool)
    m = (t0[:, None] >= win_lo[None, :] - EPS_S) & (t0[:, None] <= win_hi[None, :] + EPS_S)

    def first(mask: np.ndarray) -> list[float | None]:
        any_: list[bool] = np.asarray(mask.any(axis=0)).tolist()
        idx: list[int] = np.asarray(np.argmax(mask, axis=0)).tolist()  # events sorted by start
        return [float(t0[i]) if a else None for i, a in zip(idx, any_, strict=True)]

    return first(m & ~warm[:, None]), first(m), np.asarray(m.any(axis=1))


def _score_of(
    idx: Sequence[int], det_k: Sequence[bool], del_k: Sequence[float | None],
    contacts: Sequence[ContactLabel],
) -> tuple[int, float | None, float | None, float | None, list[float]]:
    """(detected, median delay, min detected force, max missed force, delays) over ``idx``."""
    hits = [k for k in idx if det_k[k]]
    delays = [v for k in hits if (v := del_k[k]) is not None]
    # a switch label's peak_force is no force (force_known): left out of the forces
    det_f = [contacts[k].peak_force for k in hits if force_known(contacts[k])]
    miss_f = [contacts[k].peak_force for k in idx if not det_k[k] and force_known(contacts[k])]
    return (len(hits), median_or_none(delays), min(det_f) if det_f else None,
            max(miss_f) if miss_f else None, delays)


def evaluate_events(
    events: Sequence[Event | Mapping[str, Any] | ScoredEvent],
    labels: Labels,
    *,
    duration_s: float,
    warmup_end_s: float,
    tolerance: MatchTolerance | None = None,
    product_merge_gap_s: float = 0.0,
    detectors: Sequence[str] = EVALUATED,
    incidents: Sequence[Any] | None = None,
    incidents_note: str = "",
    truncated: bool = False,
) -> Evaluation:
    """Score detection events against labelled contacts (rules in the module docstring).

    Args:
        events: detection events of any detectors — :class:`Event` or timeline ``events``
            dicts (``t_start``, ``t_end``, ``detector``, ``in_warmup``) [s since first sample].
        labels: the ground truth (times on the same base).
        duration_s: the log's duration [s] (first to last sample).
        warmup_end_s: end of the detector's warm-up [s]; earlier events and contacts are
            reported, never counted.
        tolerance: the matching window (default :class:`MatchTolerance()`).
        product_merge_gap_s: adaptive and static-loading events closer than this merge into
            one product alarm [s].
        detectors: which rows to score (default every detector and ``product``).
        incidents: the run's incidents (:class:`~impactcli.detect.incidents.Incident` s or
            timeline ``incidents`` dicts; their ``events`` index ``events``), scored by
            :func:`evaluate_incidents`; None: not available (``incidents_note`` says why).
        truncated: the file is cut (its recording went on after ``duration_s``): contacts
            after its end are the cut's, not another log's, and the warning says so.

    Returns:
        The :class:`Evaluation`. Contacts with onset after ``duration_s`` are warned about.
    """
    tol = tolerance if tolerance is not None else MatchTolerance()
    if not (math.isfinite(duration_s) and duration_s >= 0):
        raise LogFormatError(
            f"evaluation: duration_s must be a finite number >= 0, got {duration_s!r}")
    for d in detectors:
        if d not in EVALUATED:
            raise ConfigError(f"evaluation: unknown detector {d!r} (expected one of {EVALUATED})")
    evs, steps = from_contacts(
        [scored_event(e, warmup_end_s, i) for i, e in enumerate(events)], incidents or ())
    held, spans = payload_alarms(incidents or (), evs)
    held |= steps
    parts = [e for e in evs if e.detector in PRODUCT_PARTS]

    def picked_up(e: ScoredEvent) -> bool:  # the alarm of a payload change (not a contact)
        if id(e) in held:
            return True
        if e.detector == PRODUCT and held:  # a merged alarm: every part a change's
            inside = [p for p in parts if p.t_start <= e.t_end + EPS_S
                      and p.t_end >= e.t_start - EPS_S]
            if inside and all(id(p) in held for p in inside):
                return True
        return _in_any(e, spans)
    by_det: dict[str, list[ScoredEvent]] = {d: [e for e in evs if e.detector == d]
                                            for d in DETECTORS}
    by_det[PRODUCT] = product_events(evs, warmup_end_s, product_merge_gap_s)
    for d_evs in by_det.values():
        d_evs.sort(key=lambda e: (e.t_start, e.t_end))

    contacts = list(labels.events)
    status = []
    outside = []
    for i, c in enumerate(contacts):
        if c.start > duration_s:
            status.append("outside_log")
            outside.append(i)
        elif c.start < warmup_end_s:
            status.append("in_warmup")
        else:
            status.append("counted")
    if outside and len(outside) == len(contacts) and not truncated:
        raise LabelsError(
            f"{labels.path or 'labels'}: every one of its {len(contacts)} contact(s) starts "
            f"after the log's end ({duration_s:g} s), first at "
            f"{min(c.start for c in contacts):g} s: the labels of another log, or times not "
            "in seconds since the log's first sample "
            "(milliseconds?) — nothing to score")
    if outside:
        where = labels.path or "labels"
        warnings.warn(
            f"{where}: {len(outside)} contact(s) start after the log's end ({duration_s:g} s), "
            f"first at {contacts[outside[0]].start:g} s: not counted "
            + ("(the file is truncated: its recording went on after its end, and the file "
               "does not hold those contacts)" if truncated else "(labels of another log?)"),
            ImpactWarning, stacklevel=2,
        )
    before = [i for i, c in enumerate(contacts) if c.start < 0]
    if before:  # label times: seconds since the log's first sample
        warnings.warn(
            f"{labels.path or 'labels'}: {len(before)} contact(s) start before the log's "
            f"first sample, first at {contacts[before[0]].start:g} s: in its warm-up, not "
            "counted (labels of another log?)", ImpactWarning, stacklevel=2,
        )
    windows = [tol.window(c) for c in contacts]
    win_lo = np.array([w[0] for w in windows], dtype=np.float64)
    win_hi = np.array([w[1] for w in windows], dtype=np.float64)
    collision_free = max(0.0, duration_s - warmup_end_s) - union_length(
        windows, warmup_end_s, duration_s)
    collision_free = max(0.0, collision_free)

    detected: dict[str, list[bool]] = {}
    delay: dict[str, list[float | None]] = {}
    on_at_onset: dict[str, list[bool]] = {}
    scores: dict[str, DetectorScore] = {}
    matches = {d: _match(by_det[d], win_lo, win_hi) for d in (*DETECTORS, PRODUCT)}
    # The product detects a contact when one of its parts does, at the first part's alarm
    # (a merged product alarm may start before the contact, at an unrelated part's alarm);
    # a product alarm is false when one of the part alarms starting in it matched no contact
    # (or, with no part start inside, when it matched none itself).
    starts = np.array([e.t_start for d in PRODUCT_PARTS for e in by_det[d]], dtype=np.float64)
    unmatched = np.concatenate([~np.asarray(matches[d][2], dtype=bool) for d in PRODUCT_PARTS])
    order = np.argsort(starts, kind="stable")
    starts = starts[order]
    bad_before = np.concatenate(([0], np.cumsum(unmatched[order])))  # unmatched in starts[:k]

    def _earliest(xs: Sequence[float | None]) -> float | None:
        vals = [x for x in xs if x is not None]
        return min(vals) if vals else None

    p_first = [_earliest([matches[d][0][k] for d in PRODUCT_PARTS]) for k in range(len(contacts))]
    p_any = [_earliest([matches[d][1][k] for d in PRODUCT_PARTS]) for k in range(len(contacts))]
    p_evs = by_det[PRODUCT]
    lo = np.searchsorted(starts, [e.t_start - EPS_S for e in p_evs], side="left")
    hi = np.searchsorted(starts, [e.t_end + EPS_S for e in p_evs], side="right")
    # the part starts inside a product alarm all matched; none inside: its own match
    p_matched = np.where(hi > lo, bad_before[hi] == bad_before[lo],
                         np.asarray(matches[PRODUCT][2], dtype=bool)).astype(bool)
    matches[PRODUCT] = (p_first, p_any, p_matched)
    for d in detectors:
        d_evs = by_det[d]
        counted = [e for e in d_evs if not e.in_warmup]
        warm = [e for e in d_evs if e.in_warmup]
        first_match, first_any, matched = matches[d]
        no_match = [e for e, m in zip(d_evs, matched, strict=True) if not m and not e.in_warmup]
        excused = [picked_up(e) for e in no_match]
        false_alarms = [e for e, x in zip(no_match, excused, strict=True) if not x]
        picked = [e for e, x in zip(no_match, excused, strict=True) if x]
        c_start = np.array([e.t_start for e in counted])
        c_end = np.array([e.t_end for e in counted])
        det_k, del_k, on_k = [], [], []
        for k, c in enumerate(contacts):
            if status[k] == "in_warmup":
                t = first_any[k]
            elif status[k] == "counted":
                t = first_match[k]
            else:
                t = None
            det_k.append(t is not None)
            del_k.append(None if t is None else t - c.start)
            on_k.append(bool(t is None and status[k] == "counted" and np.any(
                (c_start < win_lo[k]) & (c_end >= c.start))))
        detected[d], delay[d], on_at_onset[d] = det_k, del_k, on_k
        idx_all = [k for k in range(len(contacts)) if status[k] == "counted"]
        n_det, med, min_f, max_miss, delays = _score_of(idx_all, det_k, del_k, contacts)
        by_kind = []
        for kind in KINDS:
            idx = [k for k in idx_all if contacts[k].kind == kind]
            if idx:
                kd, kmed, kmin, kmax, _ = _score_of(idx, det_k, del_k, contacts)
                by_kind.append(KindScore(kind, len(idx), kd, kmed, kmin, kmax))
        fa = len(false_alarms)
        hours = collision_free / SECONDS_PER_HOUR
        scores[d] = DetectorScore(
            detector=d, n_events=len(counted), n_events_in_warmup=len(warm),
            n_contacts=len(idx_all), detected=n_det, false_alarms=fa,
            false_alarms_per_hour=fa / hours if hours > 0 else None,
            delay_median_s=med, delay_max_s=max(delays) if delays else None,
            min_detected_force=min_f, max_missed_force=max_miss, by_kind=tuple(by_kind),
            false_alarm_times=tuple((e.t_start, e.t_end) for e in false_alarms),
            warmup_events=tuple((e.t_start, e.t_end) for e in warm),
            payload_change_events=tuple((e.t_start, e.t_end) for e in picked),
        )

    outcomes = tuple(
        ContactOutcome(
            index=k, label=c, status=status[k],
            detected={d: detected[d][k] for d in detectors},
            delay_s={d: delay[d][k] for d in detectors},
            alarm_on_at_onset={d: on_at_onset[d][k] for d in detectors},
        )
        for k, c in enumerate(contacts)
    )
    if incidents is None:
        inc_eval = IncidentEvaluation(False, incidents_note or "no incidents given")
    else:
        inc_eval = evaluate_incidents(incidents, evs, contacts, status, tol, warmup_end_s)
        note = force_unit_note(inc_eval)
        if note is not None:
            warnings.warn(f"{labels.path or 'labels'}: {note}", ImpactWarning, stacklevel=2)
    return Evaluation(
        tolerance=tol, duration_s=float(duration_s), warmup_end_s=float(warmup_end_s),
        collision_free_s=collision_free, contacts=outcomes, scores=scores,
        labels_path=labels.path, product_merge_gap_s=product_merge_gap_s,
        incidents=inc_eval,
    )


#: The incidents' force estimates over the truth on the simulated arms (docs/incidents.md):
#: each contact's 0.34–1.72 ×, the median of a contact set's 0.79–1.44 × (a trial's robot
#: 53 pushes: 0.74). A median over matched contacts beyond these bounds (1.7× wider) is
#: not the estimate's error.
FORCE_RATIO_PLAUSIBLE = (0.4, 2.5)
#: Units a label's force may have been written in, as the factor N / that unit.
FORCE_UNITS: tuple[tuple[str, float], ...] = (("kN", 1000.0), ("kgf", 9.80665),
                                              ("lbf", 4.4482216), ("mN", 0.001))


def force_unit_note(inc_eval: IncidentEvaluation, least: int = 3) -> str | None:
    """What the labels' forces say against physics, or None: over at least ``least``
    matched contacts with both forces (the incident's trusted: one the physics checks found
    implausible, or of a log whose torque scale is off, says nothing of the labels), the
    median of the incidents' force over the labelled peak force, when it lies beyond
    :data:`FORCE_RATIO_PLAUSIBLE` — the labels' forces in another unit (the nearest of
    :data:`FORCE_UNITS` within 2× named) or another log's labels; the force errors then
    compare across units."""
    ratios = [c.force_n / c.force_label_n for c in inc_eval.contacts
              if c.force_n is not None and c.force_trusted and c.force_label_n
              and c.force_label_n > 0]
    if len(ratios) < least:
        return None
    med = float(np.median(ratios))
    lo, hi = FORCE_RATIO_PLAUSIBLE
    if lo <= med <= hi:
        return None
    unit, factor = min(FORCE_UNITS, key=lambda u: abs(math.log(med / u[1])))
    guess = (f"peak_force written in {unit} rather than N (×{factor:g})?"
             if abs(math.log(med / factor)) < math.log(2.0) else "labels of another log?")
    return (f"the incidents' forces are a median {med:.3g}× the labels' peak_force over "
            f"{len(ratios)} matched contacts, where on simulated arms a contact set's median "
            f"lay within 0.79–1.44× the truth: {guess} The force errors below compare "
            "across that factor")


def evaluate_result(
    result: DetectionResult, labels: Labels, *, tolerance: MatchTolerance | None = None
) -> Evaluation:
    """:func:`evaluate_events` on a run: its events, incidents, duration, warm-up, and its
    event merge gap (``config["events"]["merge_gap_s"]``, else 0) for the product's alarms."""
    ev_cfg = result.config.get("events") if isinstance(result.config, Mapping) else None
    gap = float(ev_cfg.get("merge_gap_s", 0.0)) if isinstance(ev_cfg, Mapping) else 0.0
    return evaluate_events(result.events, labels, duration_s=result.log.duration_s,
                           warmup_end_s=result.warmup_end_s, tolerance=tolerance,
                           product_merge_gap_s=gap, incidents=list(result.incidents),
                           truncated=bool(result.log.source.truncated))


def payload_alarms(incidents: Sequence[Any], evs: Sequence[ScoredEvent],
                   ) -> tuple[set[int], list[tuple[float, float]]]:
    """The alarms of payload changes (incidents after warm-up marked ``payload_change``;
    :class:`~impactcli.detect.incidents.Incident` s or timeline dicts): a load picked or
    released, which detect neither counts nor gates. Returns the ``id`` s of the events
    ``evs`` they hold (their ``events``) and, for incidents that do not list their events
    (older timelines), their (t_start, t_end) [s]."""
    held: set[int] = set()
    spans = []
    for x in incidents:
        d = x if isinstance(x, Mapping) else vars(x)
        if d.get("payload_change") is None or d.get("in_warmup", False):
            continue
        ks = [int(k) for k in d.get("events") or () if 0 <= int(k) < len(evs)]
        if ks:
            held |= {id(evs[k]) for k in ks}
        else:
            spans.append((float(d["t_start"]), float(d["t_end"])))
    return held, spans


def from_contacts(evs: list[ScoredEvent], incidents: Sequence[Any]
                  ) -> tuple[list[ScoredEvent], set[int]]:
    """The events ``evs`` of a counted incident that starts after them: one counted from a
    contact beside a payload change, the alarm's part before it the load's step
    (:func:`impactcli.detect.incidents.mark_payload_changes`). Each such event still on at
    the incident's start is scored from there, as the incident is; the ``id`` s of those
    that ended before it (the step's alone) are returned as the change's alarms."""
    out, steps = list(evs), set()
    for x in incidents:
        d = x if isinstance(x, Mapping) else vars(x)
        if d.get("payload_change") is not None or d.get("in_warmup", False):
            continue
        t0 = float(d["t_start"])
        for k in (int(k) for k in d.get("events") or ()):
            if not (0 <= k < len(out) and out[k].t_start < t0 - EPS_S):
                continue
            if out[k].t_end >= t0 - EPS_S:
                out[k] = replace(out[k], t_start=t0)
            else:
                steps.add(id(out[k]))
    return out, steps


def _in_any(e: Any, spans: Sequence[tuple[float, float]]) -> bool:
    """Whether the event ``e`` overlaps one of ``spans``."""
    return any(e.t_start <= b + EPS_S and e.t_end >= a - EPS_S for a, b in spans)
