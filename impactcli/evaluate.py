"""Detection quality against ground-truth labels, and the equal-false-alarm threshold sweep.

Pure logic: no file I/O, no printing. The CLI (``impactcli evaluate``) reads the files.

Matching rule (documented in :class:`MatchTolerance`): an event *matches* a labelled contact
when the event **starts** within ``[contact.start - pre_s, contact.end + post_s]`` (bounds
included, with 1 ns of tolerance for float rounding of sample times).

- ``pre_s`` (default 0.02 s) absorbs clock and filter alignment between the label's source
  (a load cell, a simulator) and the robot's log: an alarm a few samples before the labelled
  onset is the same contact.
- ``post_s`` (default 0.25 s) accepts an alarm raised just after the contact ended: the
  adaptive detector is high-pass by design (method.md §7) and may fire only on the release
  of a slow push or clamp.

A contact is *detected* by a detector if any counted event of that detector matches it; its
*delay* is the earliest matching event's start minus the labelled onset (it can be slightly
negative, down to ``-pre_s``). One event may match several contacts (overlapping windows):
all of them are detected and the event is no false alarm. An event that starts at one contact
and is still on when a second contact begins matches only the first (the detector raised no
new alarm for the second): the second counts as missed and is flagged
``alarm_on_at_onset`` in its outcome.

A *false alarm* is a counted event (starting after warm-up) that matches no contact. Events
in warm-up (``in_warmup``, or starting before ``warmup_end_s``) are listed, never counted:
they neither detect a contact nor count as false alarms. A contact whose onset lies before
``warmup_end_s`` is reported separately (``in_warmup``) and is *not* counted as a miss — the
detector is not yet armed there. A contact whose onset lies after the log's end is reported
as ``outside_log`` and not counted either. The false-alarm rate is per hour of
*collision-free time*: the part of ``[warmup_end_s, duration_s]`` outside every contact's
tolerance window ``[start - pre_s, end + post_s]``.

The *product* detector is the OR of ``adaptive`` and ``static_loading`` (method.md §5):
their events are merged where they overlap (or lie within ``product_merge_gap_s``), so a
moment where both fire is one product alarm, not two. A contact counts as detected by the
product when one of its parts detects it, with the earliest part's delay (so the product is
never worse than a part, even when a merged alarm started earlier at an unrelated part's
alarm); a product alarm is false when one of the part alarms starting in it matched no
contact.

*Incidents* — the audit's answer, one per physical contact — are scored by
:func:`evaluate_incidents`: a counted contact is answered by the earliest counted incident
that starts in its window (the same rule); its ``link`` is right when it equals the
label's, its ``contact`` when it is the type the label's kind calls for (``impact`` and
``push``: transient; ``clamp``: quasi-static), its ``force_n`` has a relative error
against ``peak_force`` (none for a switch label, ``peak_force_known`` false); per link and
per type; and every contact the product detected must be exactly one incident (its
counted alarms all held by one incident). A 1.0 timeline has no incidents: the evaluation
says so.

The sweep (:func:`sweep_thresholds`) rescales every threshold by a factor ``s`` — decision
``ratio > s`` with ``ratio = statistic / threshold`` (eq. 42 for the adaptive detector) —
re-extracts events and evaluates them, so that detectors can be compared at equal false-alarm
rates. :func:`at_zero_false_alarms` takes, per detector, the smallest swept scale from which
on the log stays free of false alarms; :func:`compare_at_zero` pairs adaptive and
static_loading there contact by contact, and :func:`verdict` says in one sentence whether the
adaptive detector helps (it detects a smaller contact than static_loading's smallest, or
fires earlier on the contacts both detect — medians over different contacts are not
compared). The scales are chosen on the very log they are scored on: an in-sample,
best-case comparison of the detectors at matched rates, not a calibration (that is
``impactcli calibrate`` on collision-free logs).
"""

from __future__ import annotations

import math
import statistics
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .detect.events import split_at_warmup
from .errors import ConfigError, ImpactWarning, LogFormatError
from .types import DETECTORS, ContactLabel, Event, Labels

if TYPE_CHECKING:
    from .result import DetectionResult

SCHEMA_VERSION = "1.0"
#: The product's alarm: adaptive OR static_loading (method.md §5).
PRODUCT = "product"
PRODUCT_PARTS: tuple[str, ...] = ("adaptive", "static_loading")
#: Every row of an evaluation, in display order.
EVALUATED: tuple[str, ...] = (*DETECTORS, PRODUCT)
KINDS: tuple[str, ...] = ("impact", "push", "clamp")
SECONDS_PER_HOUR = 3600.0
#: Tolerance of time comparisons [s]: sample times are float sums of periods (as detect.events).
EPS_S = 1e-9


@dataclass(frozen=True)
class MatchTolerance:
    """When an event matches a contact: it starts within ``[start - pre_s, end + post_s]``.

    Attributes:
        pre_s: how long before the labelled onset an alarm still belongs to the contact [s]
            (clock / filter alignment; default 0.02 s = 5 samples at 4 ms).
        post_s: how long after the labelled end an alarm still belongs to it [s] (a
            high-pass detector may fire on the release; default 0.25 s).
    """

    pre_s: float = 0.02
    post_s: float = 0.25

    def __post_init__(self) -> None:
        for name in ("pre_s", "post_s"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ConfigError(
                    f"match tolerance: {name} must be a finite number >= 0, got {v!r}")

    def window(self, c: ContactLabel) -> tuple[float, float]:
        """The interval of event starts that match contact ``c`` [s]."""
        return (c.start - self.pre_s, c.end + self.post_s)


@dataclass(frozen=True)
class _Ev:
    """The part of an event evaluation needs (from an :class:`Event` or a timeline dict)."""

    detector: str
    t_start: float
    t_end: float
    in_warmup: bool
    joints: tuple[str, ...] = ()
    peak_ratio: float = float("nan")


def _as_ev(e: Event | Mapping[str, Any] | _Ev, warmup_end_s: float, i: int) -> _Ev:
    if isinstance(e, _Ev):
        return e
    if isinstance(e, Event):
        det, t0, t1, warm = e.detector, e.t_start, e.t_end, e.in_warmup
        joints, peak = tuple(e.joints), e.peak_ratio
    else:
        try:
            det = str(e["detector"])
            t0, t1 = float(e["t_start"]), float(e["t_end"])
            warm = bool(e.get("in_warmup", False))
            joints = tuple(str(j) for j in e.get("joints", ()))
            peak = float(e.get("peak_ratio", float("nan")))
        except (KeyError, TypeError, ValueError) as err:
            raise LogFormatError(f"events[{i}]: missing or bad field: {err}") from None
    if det not in DETECTORS:
        raise LogFormatError(f"events[{i}]: unknown detector {det!r}")
    return _Ev(det, t0, t1, warm or t0 < warmup_end_s, joints, peak)


def product_events(
    events: Iterable[_Ev], warmup_end_s: float, merge_gap_s: float = 0.0
) -> list[_Ev]:
    """OR of the adaptive and static-loading events: overlapping ones merged into one alarm.

    Two events merge when the next starts at most ``merge_gap_s`` after the current one ends
    (default 0: only overlapping or touching events). A merged event is in warm-up when it
    starts before ``warmup_end_s`` or its first part was flagged so; an alarm after the
    warm-up is never merged into one from the warm-up (it stays counted, as in
    :func:`impactcli.detect.events.split_at_warmup`).
    """
    parts = sorted((e for e in events if e.detector in PRODUCT_PARTS),
                   key=lambda e: (e.t_start, e.t_end))
    out: list[_Ev] = []
    for e in parts:
        warm = e.in_warmup or e.t_start < warmup_end_s
        # a counted alarm never merges into one from the warm-up (it would hide in it)
        if out and e.t_start <= out[-1].t_end + merge_gap_s \
                and not (out[-1].in_warmup and not warm):
            cur = out[-1]
            joints = cur.joints + tuple(j for j in e.joints if j not in cur.joints)
            peak = e.peak_ratio if math.isnan(cur.peak_ratio) else max(cur.peak_ratio, e.peak_ratio)
            out[-1] = _Ev(PRODUCT, cur.t_start, max(cur.t_end, e.t_end), cur.in_warmup,
                          joints, peak)
        else:
            out.append(_Ev(PRODUCT, e.t_start, e.t_end, warm, e.joints, e.peak_ratio))
    return out


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

    @property
    def missed(self) -> int:
        """Counted contacts not detected."""
        return self.n_contacts - self.detected

    @property
    def recall(self) -> float | None:
        """Detected / counted contacts (None without counted contacts)."""
        return self.detected / self.n_contacts if self.n_contacts else None


def _r(x: float | None, nd: int = 9) -> float | None:
    """Round for output (drops float noise like 0.027000000000000003); non-finite → None."""
    if x is None or not math.isfinite(x):
        return None
    return round(float(x), nd)


# ---------------------------------------------------------------------------------------
# Incidents: the answer (where, how hard, what kind) against the labels


#: The contact type (ISO/TS 15066) a labelled kind calls for (formats.md, ``incidents``).
CONTACT_OF_KIND: dict[str, str] = {"impact": "transient", "push": "transient",
                                   "clamp": "quasi_static"}
#: Contact types, in display order.
CONTACT_TYPES: tuple[str, ...] = ("transient", "quasi_static")
#: A label event with this extra field false has no force (labels made from a switch
#: channel, ``impactcli labels``): its ``peak_force`` is not scored.
FORCE_KNOWN_FIELD = "peak_force_known"


def force_known(c: ContactLabel) -> bool:
    """Whether a label's ``peak_force`` is a force (not a switch label's placeholder)."""
    return c.extra.get(FORCE_KNOWN_FIELD, True) is not False


@dataclass(frozen=True)
class _Inc:
    """The part of an incident evaluation needs (an :class:`Incident` or a timeline dict)."""

    t_start: float
    t_end: float
    link: int | None
    force_n: float | None
    contact: str
    in_warmup: bool
    events: tuple[int, ...] | None


def _as_inc(x: Any, warmup_end_s: float, i: int) -> _Inc:
    if isinstance(x, _Inc):
        return x
    def get(key: str, default: Any = None) -> Any:
        return x.get(key, default) if isinstance(x, Mapping) else getattr(x, key, default)

    try:
        t0, t1 = float(get("t_start")), float(get("t_end"))
        link = get("link")
        force = get("force_n")
        evs = get("events")
        return _Inc(t0, t1, None if link is None else int(link),
                    None if force is None else float(force), str(get("contact", "unknown")),
                    bool(get("in_warmup", False)) or t0 < warmup_end_s,
                    None if not evs else tuple(int(k) for k in evs))
    except (KeyError, TypeError, ValueError) as err:
        raise LogFormatError(f"incidents[{i}]: missing or bad field: {err}") from None


@dataclass(frozen=True)
class IncidentOutcome:
    """The incident that answers one labelled contact, and how right it is.

    Attributes:
        label_index: position in the labels' ``events`` (0-based).
        status: the contact's status (``counted``, ``in_warmup``, ``outside_log``).
        incident_index: the matching incident's position in the incidents (0-based; the
            earliest counted incident starting in the contact's window), or None.
        n_incidents: how many incidents the product's alarms on this contact belong to
            (1 when the contact is one incident; 0 when the product did not detect it).
        link_label, link: the labelled link and the incident's (None: it cannot say).
        force_label_n, force_n: the labelled peak force (None: a switch label) and the
            incident's estimate (None: no kinematics) [N].
        force_rel_error: (force_n − force_label_n) / force_label_n, signed (negative: an
            under-estimate), None when either is unknown or the label's force is 0.
        kind: the label's kind; expected_contact: the contact type it calls for.
        contact: the incident's contact type.
        link_right, contact_right: None without a matching incident.
        incident_t_start: the matching incident's start [s], or None.
    """

    label_index: int
    status: str
    incident_index: int | None
    n_incidents: int
    link_label: int
    link: int | None
    force_label_n: float | None
    force_n: float | None
    force_rel_error: float | None
    kind: str
    expected_contact: str
    contact: str | None
    link_right: bool | None
    contact_right: bool | None
    incident_t_start: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (evaluation ``incidents.contacts`` item)."""
        return {
            "label_index": self.label_index, "incident_index": self.incident_index,
            "link_label": self.link_label, "link": self.link,
            "force_label_n": _r(self.force_label_n), "force_n": _r(self.force_n),
            "force_rel_error": _r(self.force_rel_error, 6), "kind": self.kind,
            "contact": self.contact, "link_right": self.link_right,
            "contact_right": self.contact_right, "expected_contact": self.expected_contact,
            "status": self.status, "n_incidents": self.n_incidents,
            "incident_t_start": _r(self.incident_t_start),
        }


@dataclass(frozen=True)
class AnswerScore:
    """How right the incidents are over a group of counted contacts (all, a link, a type).

    Accuracies are over the contacts an incident matched (a missed contact has no answer);
    an incident that cannot say (link None, contact ``unknown``) is wrong.
    """

    n_contacts: int
    matched: int
    link_right: int
    contact_right: int
    force_rel_errors: tuple[float, ...] = ()

    @property
    def link_accuracy(self) -> float | None:
        """Right links / matched contacts."""
        return self.link_right / self.matched if self.matched else None

    @property
    def contact_accuracy(self) -> float | None:
        """Right contact types / matched contacts."""
        return self.contact_right / self.matched if self.matched else None

    @property
    def force_rel_error_median(self) -> float | None:
        """Median of |force_n − peak_force| / peak_force over contacts with both."""
        return _median([abs(x) for x in self.force_rel_errors])

    @property
    def force_bias_median(self) -> float | None:
        """Median of the signed relative force error (negative: under-estimates)."""
        return _median(list(self.force_rel_errors))

    def to_dict(self) -> dict[str, Any]:
        return {
            "n_contacts": self.n_contacts, "matched": self.matched,
            "link_right": self.link_right, "link_accuracy": _r(self.link_accuracy, 6),
            "contact_right": self.contact_right,
            "contact_accuracy": _r(self.contact_accuracy, 6),
            "n_forces": len(self.force_rel_errors),
            "force_rel_error_median": _r(self.force_rel_error_median, 6),
            "force_bias_median": _r(self.force_bias_median, 6),
        }


def _answer_score(rows: Sequence[IncidentOutcome]) -> AnswerScore:
    matched = [r for r in rows if r.incident_index is not None]
    return AnswerScore(
        n_contacts=len(rows), matched=len(matched),
        link_right=sum(1 for r in matched if r.link_right),
        contact_right=sum(1 for r in matched if r.contact_right),
        force_rel_errors=tuple(r.force_rel_error for r in matched
                               if r.force_rel_error is not None),
    )


@dataclass(frozen=True)
class IncidentEvaluation:
    """The incidents (the audit's answer) scored against the labels.

    Attributes:
        available: the input had incidents (a 1.0 timeline has none: ``note`` says so).
        note: why not, or "".
        contacts: per labelled contact, the incident that answers it.
        overall: over counted contacts; per_link: by labelled link; per_type: by the
            contact type the label's kind calls for.
        n_incidents, n_incidents_in_warmup: counted incidents and those in warm-up.
        unmatched: counted incidents starting in no contact's window (false incidents).
        detected: counted contacts the product detected (one of its counted alarms starts
            in the window) — the ones that must each be exactly one incident.
        split: those whose alarms belong to several incidents (label indices).
        not_in_incident: those whose alarms belong to no incident (label indices).
        shared: incidents holding the alarms of several counted contacts (indices).
    """

    available: bool
    note: str = ""
    contacts: tuple[IncidentOutcome, ...] = ()
    overall: AnswerScore = AnswerScore(0, 0, 0, 0)
    per_link: dict[int, AnswerScore] = field(default_factory=dict)
    per_type: dict[str, AnswerScore] = field(default_factory=dict)
    n_incidents: int = 0
    n_incidents_in_warmup: int = 0
    unmatched: tuple[int, ...] = ()
    detected: int = 0
    split: tuple[int, ...] = ()
    not_in_incident: tuple[int, ...] = ()
    shared: tuple[int, ...] = ()

    @property
    def one_incident_each(self) -> bool | None:
        """Every detected counted contact belongs to exactly one incident (None: no
        incidents, or nothing detected)."""
        if not self.available or self.detected == 0:
            return None
        return not self.split and not self.not_in_incident

    def summary(self) -> list[list[str]]:
        """``[label, value]`` rows a report prints as they are."""
        if not self.available:
            return [["incidents", self.note or "not evaluated"]]
        o = self.overall
        rows = [
            ["counted contacts matched by an incident", _frac(o.matched, o.n_contacts)],
            ["incidents after warm-up", f"{self.n_incidents}" + (
                f" ({len(self.unmatched)} matching no labelled contact)" if self.unmatched
                else " (each matches a labelled contact)" if self.n_incidents else "")
             + (f"; {self.n_incidents_in_warmup} in warm-up (not counted)"
                if self.n_incidents_in_warmup else "")],
            ["link right", _frac(o.link_right, o.matched)],
            ["contact type right", _frac(o.contact_right, o.matched)],
            ["force error (median |F − F_label| / F_label)", _pct(o.force_rel_error_median)
             + (f" over {len(o.force_rel_errors)} contact(s)" if o.force_rel_errors
                else " (no contact with both forces)")],
            ["force bias (median (F − F_label) / F_label)", _pct(o.force_bias_median, True)],
        ]
        one = self.one_incident_each
        if one is None:
            txt = "no contact detected" if self.available else "-"
        else:
            n_ok = self.detected - len(self.split) - len(self.not_in_incident)
            txt = ("yes" if one else "no") + f" ({n_ok}/{self.detected})"
            if self.split:
                txt += f"; split over several incidents: labels {_idx(self.split)}"
            if self.not_in_incident:
                txt += f"; in no incident: labels {_idx(self.not_in_incident)}"
        if self.shared:
            txt += f"; incidents {_idx(self.shared)} each hold several contacts"
        rows.append(["every detected contact is exactly one incident", txt])
        for link, s in sorted(self.per_link.items()):
            rows.append([f"link {link}", _group_text(s)])
        for ctype, s in self.per_type.items():
            kinds = ", ".join(k for k, v in CONTACT_OF_KIND.items() if v == ctype)
            rows.append([f"{ctype} ({kinds})", _group_text(s)])
        return rows

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (evaluation ``incidents``); deterministic."""
        o = self.overall
        return {
            "available": self.available,
            "note": self.note,
            "summary": self.summary(),
            "contacts": [c.to_dict() for c in self.contacts],
            "per_link": {str(k): s.to_dict() for k, s in sorted(self.per_link.items())},
            "per_type": {k: s.to_dict() for k, s in self.per_type.items()},
            "n_contacts": o.n_contacts,
            "matched": o.matched,
            "n_incidents": self.n_incidents,
            "n_incidents_in_warmup": self.n_incidents_in_warmup,
            "unmatched_incidents": list(self.unmatched),
            "link_accuracy": _r(o.link_accuracy, 6),
            "contact_accuracy": _r(o.contact_accuracy, 6),
            "force_rel_error_median": _r(o.force_rel_error_median, 6),
            "force_bias_median": _r(o.force_bias_median, 6),
            "one_incident_per_contact": {
                "holds": self.one_incident_each, "detected": self.detected,
                "split": list(self.split), "not_in_incident": list(self.not_in_incident),
                "shared_incidents": list(self.shared),
            },
        }


def _frac(a: int, b: int) -> str:
    return f"{a}/{b}" + (f" ({100 * a / b:.0f}%)" if b else "")


def _pct(x: float | None, signed: bool = False) -> str:
    if x is None:
        return "-"
    return f"{100 * x:+.0f}%" if signed else f"{100 * x:.0f}%"


def _idx(xs: Sequence[int]) -> str:
    return ", ".join(f"#{k}" for k in xs)


def _group_text(s: AnswerScore) -> str:
    return (f"matched {s.matched}/{s.n_contacts}, link right {_frac(s.link_right, s.matched)}"
            f", type right {_frac(s.contact_right, s.matched)}, force error "
            f"{_pct(s.force_rel_error_median)}")


def evaluate_incidents(
    incidents: Sequence[Any], evs: Sequence[_Ev], contacts: Sequence[ContactLabel],
    status: Sequence[str], tolerance: MatchTolerance, warmup_end_s: float,
) -> IncidentEvaluation:
    """Score incidents against labelled contacts (formats.md: ``link`` against the label's
    link, ``force_n`` against ``peak_force``, ``contact`` against the kind).

    A contact is answered by the earliest counted incident (after warm-up) that *starts*
    in its window ``[start - pre_s, end + post_s]`` — the events' matching rule; an
    incident already under way at the onset does not answer it. Contacts in warm-up are
    answered by any incident (informational). The "exactly one incident" check follows
    the product's counted alarms that start in a detected contact's window to the
    incidents holding them (the incident's ``events``, else the incident whose span holds
    the alarm's start).

    Args:
        incidents: :class:`~impactcli.detect.incidents.Incident` s or timeline dicts.
        evs: every event, in the order the incidents' ``events`` index.
        contacts, status: the labels' contacts and their status (evaluate_events).
        tolerance: the matching window. warmup_end_s: [s].
    """
    incs = [_as_inc(x, warmup_end_s, i) for i, x in enumerate(incidents)]
    order = sorted(range(len(incs)), key=lambda k: (incs[k].t_start, incs[k].t_end))
    counted_inc = [k for k in order if not incs[k].in_warmup]
    # product alarm k → the incidents holding it
    holder: dict[int, set[int]] = {}
    with_events = bool(incs) and all(i.events is not None for i in incs)
    for k, inc in enumerate(incs):
        if with_events:
            for a in inc.events or ():
                holder.setdefault(a, set()).add(k)
    if not with_events:
        for a, ev in enumerate(evs):
            if ev.detector in PRODUCT_PARTS:
                for k, inc in enumerate(incs):
                    if inc.t_start - EPS_S <= ev.t_start <= inc.t_end + EPS_S:
                        holder.setdefault(a, set()).add(k)
    rows: list[IncidentOutcome] = []
    detected = 0
    split: list[int] = []
    none_: list[int] = []
    inc_contacts: dict[int, set[int]] = {}
    for c_idx, c in enumerate(contacts):
        lo, hi = tolerance.window(c)
        cands = counted_inc if status[c_idx] == "counted" else order
        hit = next((k for k in cands
                    if lo - EPS_S <= incs[k].t_start <= hi + EPS_S), None)
        n_held = 0
        if status[c_idx] == "counted":
            alarms = [e_idx for e_idx, e in enumerate(evs) if e.detector in PRODUCT_PARTS
                      and not e.in_warmup and lo - EPS_S <= e.t_start <= hi + EPS_S]
            held = set().union(*(holder.get(a, set()) for a in alarms)) if alarms else set()
            n_held = len(held)
            if alarms:
                detected += 1
                if n_held > 1:
                    split.append(c_idx)
                elif n_held == 0:
                    none_.append(c_idx)
            for h in held:
                inc_contacts.setdefault(h, set()).add(c_idx)
        expected = CONTACT_OF_KIND.get(c.kind, "unknown")
        f_label = float(c.peak_force) if force_known(c) else None
        ans = incs[hit] if hit is not None else None
        err = None
        if ans is not None and ans.force_n is not None and f_label:
            err = (ans.force_n - f_label) / f_label
        rows.append(IncidentOutcome(
            label_index=c_idx, status=status[c_idx], incident_index=hit, n_incidents=n_held,
            link_label=int(c.link), link=None if ans is None else ans.link,
            force_label_n=f_label, force_n=None if ans is None else ans.force_n,
            force_rel_error=err, kind=c.kind, expected_contact=expected,
            contact=None if ans is None else ans.contact,
            link_right=None if ans is None else ans.link == c.link,
            contact_right=None if ans is None else ans.contact == expected,
            incident_t_start=None if ans is None else ans.t_start,
        ))
    counted_rows = [r for r in rows if r.status == "counted"]
    per_link = {link: _answer_score([r for r in counted_rows if r.link_label == link])
                for link in sorted({r.link_label for r in counted_rows})}
    per_type = {t: _answer_score([r for r in counted_rows if r.expected_contact == t])
                for t in (*CONTACT_TYPES, "unknown")
                if any(r.expected_contact == t for r in counted_rows)}
    return IncidentEvaluation(
        available=True, contacts=tuple(rows), overall=_answer_score(counted_rows),
        per_link=per_link, per_type=per_type, n_incidents=len(counted_inc),
        n_incidents_in_warmup=len(incs) - len(counted_inc),
        unmatched=tuple(sorted(k for k in counted_inc
                               if not _starts_in_any(incs[k], contacts, tolerance))),
        detected=detected, split=tuple(split), not_in_incident=tuple(none_),
        shared=tuple(sorted(k for k, cs in inc_contacts.items() if len(cs) > 1)),
    )


def _starts_in_any(inc: _Inc, contacts: Sequence[ContactLabel], tol: MatchTolerance) -> bool:
    return any(lo - EPS_S <= inc.t_start <= hi + EPS_S
               for lo, hi in (tol.window(c) for c in contacts))


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
    """

    tolerance: MatchTolerance
    duration_s: float
    warmup_end_s: float
    collision_free_s: float
    contacts: tuple[ContactOutcome, ...]
    scores: dict[str, DetectorScore]
    labels_path: str = ""
    product_merge_gap_s: float = 0.0
    incidents: IncidentEvaluation = IncidentEvaluation(False, "no incidents given")

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
                "recall": _r(s.recall, 6),
                "false_alarms": s.false_alarms,
                "false_alarms_per_hour": _r(s.false_alarms_per_hour, 6),
                "delay_median_s": _r(s.delay_median_s),
                "delay_max_s": _r(s.delay_max_s),
                "min_detected_force": _r(s.min_detected_force),
                "max_missed_force": _r(s.max_missed_force),
                "by_kind": {
                    k.kind: {
                        "n_contacts": k.n_contacts, "detected": k.detected,
                        "delay_median_s": _r(k.delay_median_s),
                        "min_detected_force": _r(k.min_detected_force),
                        "max_missed_force": _r(k.max_missed_force),
                    }
                    for k in s.by_kind
                },
                "false_alarm_times": [[_r(a), _r(b)] for a, b in s.false_alarm_times],
                "warmup_events": [[_r(a), _r(b)] for a, b in s.warmup_events],
            }

        return {
            "schema_version": SCHEMA_VERSION,
            "labels": self.labels_path,
            "tolerance": {"pre_s": self.tolerance.pre_s, "post_s": self.tolerance.post_s,
                          "rule": "an event matches a contact if it starts within "
                                  "[start - pre_s, end + post_s]"},
            "product": {"detectors": list(PRODUCT_PARTS), "merge_gap_s": self.product_merge_gap_s},
            "duration_s": _r(self.duration_s),
            "warmup_end_s": _r(self.warmup_end_s),
            "collision_free_s": _r(self.collision_free_s),
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
                    "delay_s": {d: _r(v) for d, v in c.delay_s.items()},
                    "alarm_on_at_onset": dict(c.alarm_on_at_onset),
                }
                for c in self.contacts
            ],
            "incidents": self.incidents.to_dict(),
        }


def _union_length(intervals: Iterable[tuple[float, float]], lo: float, hi: float) -> float:
    """Length of the union of ``intervals`` clipped to ``[lo, hi]`` [s]."""
    clipped = sorted((max(a, lo), min(b, hi)) for a, b in intervals)
    total, cur_a, cur_b = 0.0, None, None
    for a, b in clipped:
        if b <= a:
            continue
        if cur_b is None or a > cur_b:
            if cur_b is not None and cur_a is not None:
                total += cur_b - cur_a
            cur_a, cur_b = a, b
        else:
            cur_b = max(cur_b, b)
    if cur_b is not None and cur_a is not None:
        total += cur_b - cur_a
    return total


def _match(
    evs: Sequence[_Ev], win_lo: np.ndarray, win_hi: np.ndarray
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


def _median(xs: Sequence[float]) -> float | None:
    return float(statistics.median(xs)) if xs else None


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
    return (len(hits), _median(delays), min(det_f) if det_f else None,
            max(miss_f) if miss_f else None, delays)


def evaluate_events(
    events: Sequence[Event | Mapping[str, Any] | _Ev],
    labels: Labels,
    *,
    duration_s: float,
    warmup_end_s: float,
    tolerance: MatchTolerance | None = None,
    product_merge_gap_s: float = 0.0,
    detectors: Sequence[str] = EVALUATED,
    incidents: Sequence[Any] | None = None,
    incidents_note: str = "",
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
    evs = [_as_ev(e, warmup_end_s, i) for i, e in enumerate(events)]
    by_det: dict[str, list[_Ev]] = {d: [e for e in evs if e.detector == d] for d in DETECTORS}
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
    if outside:
        where = labels.path or "labels"
        warnings.warn(
            f"{where}: {len(outside)} contact(s) start after the log's end ({duration_s:g} s), "
            f"first at {contacts[outside[0]].start:g} s: not counted (labels of another log?)",
            ImpactWarning, stacklevel=2,
        )
    before = [i for i, c in enumerate(contacts) if c.start < 0]
    if before:  # label times are seconds since the log's first sample (formats.md)
        warnings.warn(
            f"{labels.path or 'labels'}: {len(before)} contact(s) start before the log's "
            f"first sample, first at {contacts[before[0]].start:g} s: in its warm-up, not "
            "counted (labels of another log?)", ImpactWarning, stacklevel=2,
        )
    windows = [tol.window(c) for c in contacts]
    win_lo = np.array([w[0] for w in windows], dtype=np.float64)
    win_hi = np.array([w[1] for w in windows], dtype=np.float64)
    collision_free = max(0.0, duration_s - warmup_end_s) - _union_length(
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
    part_starts = [(e.t_start, bool(m)) for d in PRODUCT_PARTS
                   for e, m in zip(by_det[d], matches[d][2], strict=True)]

    def _earliest(xs: Sequence[float | None]) -> float | None:
        vals = [x for x in xs if x is not None]
        return min(vals) if vals else None

    p_first = [_earliest([matches[d][0][k] for d in PRODUCT_PARTS]) for k in range(len(contacts))]
    p_any = [_earliest([matches[d][1][k] for d in PRODUCT_PARTS]) for k in range(len(contacts))]
    def _product_ok(e: _Ev, m: bool) -> bool:
        inside = [ok for a, ok in part_starts if e.t_start - EPS_S <= a <= e.t_end + EPS_S]
        return all(inside) if inside else bool(m)

    p_matched = np.array([_product_ok(e, bool(m))
                          for e, m in zip(by_det[PRODUCT], matches[PRODUCT][2], strict=True)],
                         dtype=bool)
    matches[PRODUCT] = (p_first, p_any, p_matched)
    for d in detectors:
        d_evs = by_det[d]
        counted = [e for e in d_evs if not e.in_warmup]
        warm = [e for e in d_evs if e.in_warmup]
        first_match, first_any, matched = matches[d]
        false_alarms = [e for e, m in zip(d_evs, matched, strict=True) if not m and not e.in_warmup]
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
    return Evaluation(
        tolerance=tol, duration_s=float(duration_s), warmup_end_s=float(warmup_end_s),
        collision_free_s=collision_free, contacts=outcomes, scores=scores,
        labels_path=labels.path, product_merge_gap_s=product_merge_gap_s,
        incidents=inc_eval,
    )


def evaluate_result(
    result: DetectionResult, labels: Labels, *, tolerance: MatchTolerance | None = None
) -> Evaluation:
    """:func:`evaluate_events` on a run: its events, incidents, duration, warm-up, and its
    event merge gap (``config["events"]["merge_gap_s"]``, else 0) for the product's alarms."""
    ev_cfg = result.config.get("events") if isinstance(result.config, Mapping) else None
    gap = float(ev_cfg.get("merge_gap_s", 0.0)) if isinstance(ev_cfg, Mapping) else 0.0
    return evaluate_events(result.events, labels, duration_s=result.log.duration_s,
                           warmup_end_s=result.warmup_end_s, tolerance=tolerance,
                           product_merge_gap_s=gap, incidents=list(result.incidents))


# ---------------------------------------------------------------------------------------
# Text table


def _fmt_ms(x: float | None) -> str:
    return "-" if x is None else f"{x * 1e3:.0f} ms"


def _fmt_n(x: float | None) -> str:
    return "-" if x is None else f"{x:.3g} N"


def _fmt_rate(x: float | None) -> str:
    return "-" if x is None else f"{x:.3g}"


def format_evaluation(ev: Evaluation) -> str:
    """A plain-text table of an :class:`Evaluation` (one row per detector, then per kind)."""
    n_counted = len(ev.contacts_with_status("counted"))
    n_warm = len(ev.contacts_with_status("in_warmup"))
    n_out = len(ev.contacts_with_status("outside_log"))
    lines = [
        f"Contacts: {n_counted} counted"
        + (f", {n_warm} in warm-up (reported, not counted)" if n_warm else "")
        + (f", {n_out} after the log's end (not counted)" if n_out else ""),
        f"Log {ev.duration_s:.3f} s, warm-up until {ev.warmup_end_s:.3f} s, "
        f"collision-free time {ev.collision_free_s:.3f} s",
        f"Match: an event starting within [contact start - {ev.tolerance.pre_s:g} s, "
        f"contact end + {ev.tolerance.post_s:g} s]; product = adaptive OR static_loading",
        "",
    ]
    head = ("detector", "detected", "false alarms", "FA/h", "delay med", "delay max",
            "min detected F", "max missed F", "warm-up ev.")
    rows = [head]
    for d, s in ev.scores.items():
        rows.append((
            d, f"{s.detected}/{s.n_contacts}", str(s.false_alarms),
            _fmt_rate(s.false_alarms_per_hour),
            _fmt_ms(s.delay_median_s), _fmt_ms(s.delay_max_s), _fmt_n(s.min_detected_force),
            _fmt_n(s.max_missed_force), str(s.n_events_in_warmup),
        ))
    lines += _table(rows)
    kind_rows: list[tuple[str, ...]] = [("detector", "kind", "detected", "delay med",
                                         "min detected F", "max missed F")]
    for d, s in ev.scores.items():
        for k in s.by_kind:
            kind_rows.append((d, k.kind, f"{k.detected}/{k.n_contacts}", _fmt_ms(k.delay_median_s),
                              _fmt_n(k.min_detected_force), _fmt_n(k.max_missed_force)))
    if len(kind_rows) > 1:
        lines += ["", "By contact kind:", *_table(kind_rows)]
    warm = ev.contacts_with_status("in_warmup")
    if warm:
        lines += ["", "Contacts in warm-up (not counted as misses):"]
        for c in warm:
            by = [d for d, v in c.detected.items() if v]
            lines.append(f"  #{c.index} {c.label.kind} at {c.label.start:.3f} s, "
                         f"{c.label.peak_force:.3g} N: alarm by {', '.join(by) if by else 'none'}")
    lines += ["", *format_incident_evaluation(ev.incidents)]
    return "\n".join(lines) + "\n"


def format_incident_evaluation(ie: IncidentEvaluation) -> list[str]:
    """Text lines: the incidents' scores (:meth:`IncidentEvaluation.summary`) and, per
    labelled contact, the incident that answers it."""
    if not ie.available:
        return [f"Incidents: {ie.note}"]
    rows = ie.summary()
    width = max(len(a) for a, _ in rows)
    lines = ["Incidents (the answer: link, force, contact type) against the labels:"]
    lines += [f"  {a.ljust(width)}  {b}" for a, b in rows]
    if not ie.contacts:
        return lines
    table: list[tuple[str, ...]] = [("label", "kind", "incident at", "link: label / found",
                                     "force: label / found", "error", "type: expected / found")]
    for c in ie.contacts:
        def mark(ok: bool | None) -> str:
            return "" if ok is None else (" ok" if ok else " WRONG")
        f_lab = "switch" if c.force_label_n is None else f"{c.force_label_n:.3g} N"
        f_inc = "-" if c.force_n is None else f"{c.force_n:.3g} N"
        table.append((
            f"#{c.label_index}" + ("" if c.status == "counted" else f" ({c.status})"),
            c.kind,
            "none" if c.incident_t_start is None else f"{c.incident_t_start:.3f} s",
            f"{c.link_label} / {'-' if c.link is None else c.link}{mark(c.link_right)}",
            f"{f_lab} / {f_inc}",
            "-" if c.force_rel_error is None else f"{100 * c.force_rel_error:+.0f}%",
            f"{c.expected_contact} / {c.contact or '-'}{mark(c.contact_right)}",
        ))
    lines += ["", "Per labelled contact (label # from 0, as in the labels' events):",
              *_table(table)]
    return lines


def _table(rows: Sequence[Sequence[str]]) -> list[str]:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    out = []
    for n, r in enumerate(rows):
        out.append("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in
                             enumerate(zip(r, widths, strict=True))).rstrip())
        if n == 0:
            out.append("  ".join("-" * w for w in widths))
    return out


# ---------------------------------------------------------------------------------------
# Threshold sweep (equal-false-alarm comparison)


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
    scales_sorted = sorted({float(s) for s in scales})
    if not scales_sorted or any(not (math.isfinite(s) and s > 0) for s in scales_sorted):
        raise ConfigError(f"sweep: scales must be positive finite numbers, got {list(scales)!r}")
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
            ev = evaluate_events(
                evs, labels, duration_s=duration_s, warmup_end_s=warmup_end_s, tolerance=tol,
                product_merge_gap_s=merge_gap_s, detectors=list(rows_of),
            )
            for d, sc in ev.scores.items():
                per_contact = tuple(
                    c.delay_s[d] if c.status == "counted" and c.detected[d] else None
                    for c in ev.contacts)
                rows_of[d].append(SweepRow(
                    d, s, sc.n_events, sc.n_contacts, sc.detected, sc.false_alarms,
                    sc.false_alarms_per_hour, sc.delay_median_s, sc.min_detected_force,
                    per_contact))
    if any(c.start > duration_s for c in labels.events):
        evaluate_events([], labels, duration_s=duration_s, warmup_end_s=warmup_end_s,
                        tolerance=tol, detectors=())
    return [r for rows in rows_of.values() for r in rows]


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


def at_zero_false_alarms(rows: Sequence[SweepRow]) -> dict[str, SweepRow | None]:
    """Per detector, the sweep row at the smallest scale from which on it stays silent.

    That is the smallest swept scale s such that this scale and every larger swept scale
    give zero false alarms (a lone silent scale below a noisy one is not trusted: event
    merging can make the count non-monotonic). None when even the largest scale
    false-alarms. Its ``min_detected_force`` is the minimal detected force at zero false
    alarms.
    """
    out: dict[str, SweepRow | None] = {}
    for d in dict.fromkeys(r.detector for r in rows):
        best: SweepRow | None = None
        for r in sorted((r for r in rows if r.detector == d), key=lambda r: -r.scale):
            if r.false_alarms:
                break
            best = r
        out[d] = best
    return out


def _at_edge(zero: Mapping[str, SweepRow | None], smallest_scale: float | None) -> list[str]:
    """Compared detectors already silent at the smallest swept scale (their zero-false-alarm
    point lies below the sweep)."""
    if smallest_scale is None:
        return []
    return [d for d in PRODUCT_PARTS
            if (r := zero.get(d)) is not None and r.scale <= smallest_scale + EPS_S]


@dataclass(frozen=True)
class Comparison:
    """Adaptive vs static_loading, each at its own zero-false-alarm threshold scale.

    Attributes:
        adaptive, static_loading: their sweep rows at that point.
        adaptive_only, loading_only, both: counted contacts detected by only one / by both.
        paired_delay_gain_s: median over contacts detected by both of (static_loading delay
            − adaptive delay) [s]: positive when adaptive fires earlier; None if none shared.
    """

    adaptive: SweepRow
    static_loading: SweepRow
    adaptive_only: int
    loading_only: int
    both: int
    paired_delay_gain_s: float | None

    @property
    def smaller_force(self) -> bool:
        """Adaptive detects a smaller contact than static_loading's smallest detected one."""
        a, s = self.adaptive.min_detected_force, self.static_loading.min_detected_force
        return a is not None and (s is None or a < s)

    @property
    def earlier(self) -> bool:
        """On the contacts both detect, adaptive fires earlier (median of paired delays)."""
        return self.paired_delay_gain_s is not None and self.paired_delay_gain_s > EPS_S


def compare_at_zero(zero: Mapping[str, SweepRow | None]) -> Comparison | None:
    """The :class:`Comparison` of adaptive and static_loading at zero false alarms, or None
    when either never reached zero false alarms in the sweep."""
    a, s = zero.get("adaptive"), zero.get("static_loading")
    if a is None or s is None:
        return None
    da, ds = a.contact_delays_s, s.contact_delays_s
    if len(da) != len(ds):
        raise ValueError("sweep rows of different label sets cannot be compared")
    pairs = [(x, y) for x, y in zip(da, ds, strict=True) if x is not None and y is not None]
    return Comparison(
        adaptive=a, static_loading=s,
        adaptive_only=sum(1 for x, y in zip(da, ds, strict=True) if x is not None and y is None),
        loading_only=sum(1 for x, y in zip(da, ds, strict=True) if x is None and y is not None),
        both=len(pairs),
        paired_delay_gain_s=_median([y - x for x, y in pairs]),
    )


def adaptive_helps(zero: Mapping[str, SweepRow | None], *,
                   smallest_scale: float | None = None) -> bool | None:
    """Whether adaptive beats static_loading at matched (zero) false alarms, or None if unknown.

    Each detector is taken at its own zero-false-alarm scale (:func:`at_zero_false_alarms`).
    Helps when adaptive detects a smaller contact than any static_loading detects (smaller
    minimal detected force — that contact is one static_loading misses), or when, on the
    contacts both detect, it fires earlier (median of the paired delay differences: median
    delays over different sets of contacts are not compared). Unknown (None): either
    detector never reaches zero false alarms in the sweep, or is already silent at
    ``smallest_scale`` (the smallest swept scale: its true zero-false-alarm point lies
    lower, so the two are not compared at matched rates), or there is no counted contact.
    """
    cmp = compare_at_zero(zero)
    if cmp is None or cmp.adaptive.n_contacts == 0 or _at_edge(zero, smallest_scale):
        return None
    return cmp.smaller_force or cmp.earlier


def _row_text(r: SweepRow) -> str:
    txt = f"{r.detected}/{r.n_contacts} contacts at threshold scale {r.scale:g}"
    if r.detected:
        txt += (f", down to {r.min_detected_force:.3g} N with a median delay of "
                f"{_fmt_ms(r.delay_median_s)}")
    return txt


def _pair_text(cmp: Comparison) -> str:
    parts = [f"{cmp.adaptive_only} contact(s) only adaptive detects, {cmp.loading_only} only "
             f"static_loading detects, {cmp.both} both"]
    if cmp.paired_delay_gain_s is not None:
        g = cmp.paired_delay_gain_s
        parts.append(f"on those adaptive fires {_fmt_ms(abs(g))} "
                     f"{'earlier' if g >= 0 else 'later'} (median)")
    return ", ".join(parts)


def verdict(zero: Mapping[str, SweepRow | None], *, smallest_scale: float | None = None) -> str:
    """One plain sentence: does the adaptive detector help on this robot and log?

    Compares adaptive with static_loading at their zero-false-alarm points
    (:func:`at_zero_false_alarms`); criteria in :func:`adaptive_helps`.
    """
    a, s = zero.get("adaptive"), zero.get("static_loading")
    missing = [d for d, r in (("adaptive", a), ("static_loading", s)) if r is None]
    if missing:
        return (f"Undetermined: {' and '.join(missing)} never reached zero false alarms "
                "within the swept threshold scales; sweep larger scales.")
    cmp = compare_at_zero(zero)
    assert a is not None and s is not None and cmp is not None
    if a.n_contacts == 0:
        return "Undetermined: the labels hold no contact after warm-up to compare detectors on."
    both = (f"adaptive detected {_row_text(a)}; static_loading detected {_row_text(s)}; "
            f"{_pair_text(cmp)}.")
    edge = _at_edge(zero, smallest_scale)
    if edge:
        return (f"Undetermined: {' and '.join(edge)} had no false alarm even at the smallest "
                f"swept scale ({smallest_scale:g}), so the detectors are not compared at "
                f"matched rates; sweep smaller scales ({both[:-1]}).")
    if cmp.smaller_force or cmp.earlier:
        why = " and ".join(w for w, ok in (("detects smaller contacts", cmp.smaller_force),
                                          ("fires earlier on shared contacts", cmp.earlier))
                           if ok)
        return f"The adaptive detector helps here at zero false alarms ({why}): {both}"
    return ("The adaptive detector does not help here at zero false alarms (no smaller "
            f"contact detected, not earlier on shared contacts): {both}")


def sweep_to_dict(rows: Sequence[SweepRow]) -> dict[str, Any]:
    """The sweep, its zero-false-alarm points and the verdict, JSON-ready (deterministic)."""
    zero = at_zero_false_alarms(rows)
    lo = min((r.scale for r in rows), default=None)
    return {
        "rows": [r.to_dict() for r in rows],
        "at_zero_false_alarms": {
            d: (r.to_dict(per_contact=True) if r is not None else None)
            for d, r in zero.items()},
        "adaptive_helps": adaptive_helps(zero, smallest_scale=lo),
        "verdict": verdict(zero, smallest_scale=lo),
    }


def format_sweep(rows: Sequence[SweepRow]) -> str:
    """A plain-text table of the sweep's zero-false-alarm points and the verdict."""
    zero = at_zero_false_alarms(rows)
    scales = sorted({r.scale for r in rows})
    lo = scales[0] if scales else None
    table: list[tuple[str, ...]] = [("detector", "scale @ 0 FA", "detected", "min detected F",
                                     "delay med")]
    for d, r in zero.items():
        if r is None:
            table.append((d, f"never (> {scales[-1]:g})", "-", "-", "-"))
        else:
            at_lo = lo is not None and r.scale <= lo + EPS_S
            table.append((d, f"<= {r.scale:g}" if at_lo else f"{r.scale:g}",
                          f"{r.detected}/{r.n_contacts}",
                          _fmt_n(r.min_detected_force), _fmt_ms(r.delay_median_s)))
    rng = f"{scales[0]:g}–{scales[-1]:g}, {len(scales)} scales" if scales else "no scales"
    return "\n".join([f"Threshold sweep ({rng}), at zero false alarms:", *_table(table), "",
                      verdict(zero, smallest_scale=lo)]) + "\n"
