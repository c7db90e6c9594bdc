"""The incidents — the audit's answer, one per physical contact — scored against the labels.

:func:`evaluate_incidents` (called by :func:`impactcli.quality.evaluation.evaluate_events`
for the ``incidents`` part of an :class:`~impactcli.quality.evaluation.Evaluation`): a
counted contact is answered by the earliest counted incident that starts in its window (the
events' matching rule, :class:`~impactcli.quality.match.MatchTolerance`); its ``link`` is
right when it equals the label's, its ``contact`` when it is the type the label's kind calls
for (``impact`` and ``push``: transient; ``clamp``: quasi-static), its ``force_n`` has a
relative error against ``peak_force`` (none for a switch label, ``peak_force_known``
false); per link and per type; and every contact the product detected must be exactly one
incident (its counted alarms all held by one incident). A 1.0 timeline has no incidents:
the evaluation says so (:class:`IncidentEvaluation` with ``available`` false).

Its own rows of text (:meth:`IncidentEvaluation.summary`) are here, with the scores they
print; the per-contact table is :mod:`impactcli.quality.text`'s. Pure logic: no file I/O,
no printing.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..detect.events import LONG_EVENT_S
from ..errors import LogFormatError
from ..types import ContactLabel
from .match import (
    EPS_S,
    PRODUCT_PARTS,
    MatchTolerance,
    ScoredEvent,
    force_known,
    median_or_none,
    rounded,
)

#: The contact type (ISO/TS 15066) a labelled kind calls for (docs/formats.md,
#: "Detection timeline", ``incidents``).
CONTACT_OF_KIND: dict[str, str] = {"impact": "transient", "push": "transient",
                                   "clamp": "quasi_static"}
#: Contact types, in display order.
CONTACT_TYPES: tuple[str, ...] = ("transient", "quasi_static")


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
    payload_change: bool = False
    aftermath: bool = False
    force_at_least: bool = False
    data_defect: bool = False
    candidates: tuple[int, ...] = ()
    resumes: bool = False
    force_trusted: bool = True


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
                    None if not evs else tuple(int(k) for k in evs),
                    get("payload_change") is not None, (get("aftermath") is not None
                     or get("close_behind") is not None),
                    bool(get("force_at_least", False)), get("data_defect") is not None,
                    tuple(int(c) for c in get("link_candidates") or ()),
                    get("resumes_load") is not None, get("force_plausible") is not False)
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
        force_at_least: the incident's force is a lower bound (its ``force_at_least``).
        payload_change: the product's alarms on the contact are held by payload changes'
            alarms only (not counted): the contact was taken for a load.
        force_trusted: the incident's force passed the physics checks (its
            ``force_plausible`` is not false: beyond what the arm can exert, or a log whose
            torque scale is off its description's gravity torque, is not).
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
    force_at_least: bool = False
    link_candidates: tuple[int, ...] = ()
    payload_change: bool = False
    force_trusted: bool = True

    @property
    def among(self) -> bool:
        """The labelled link is among the links the incident could not tell apart, though
        not its link (an answer "link 2 or 3" for link 3 with link 2 first)."""
        return self.link_right is False and self.link_label in self.link_candidates

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (evaluation ``incidents.contacts`` item)."""
        return {
            "label_index": self.label_index, "incident_index": self.incident_index,
            "link_label": self.link_label, "link": self.link,
            "force_label_n": rounded(self.force_label_n), "force_n": rounded(self.force_n),
            "force_rel_error": rounded(self.force_rel_error, 6), "kind": self.kind,
            "contact": self.contact, "link_right": self.link_right,
            "contact_right": self.contact_right, "expected_contact": self.expected_contact,
            "status": self.status, "n_incidents": self.n_incidents,
            "incident_t_start": rounded(self.incident_t_start),
            **({"force_at_least": True} if self.force_at_least else {}),
            **({"link_candidates": list(self.link_candidates)}
               if len(self.link_candidates) > 1 else {}),
            **({"payload_change": True} if self.payload_change else {}),
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
        return median_or_none([abs(x) for x in self.force_rel_errors])

    @property
    def force_bias_median(self) -> float | None:
        """Median of the signed relative force error (negative: under-estimates)."""
        return median_or_none(list(self.force_rel_errors))

    def to_dict(self) -> dict[str, Any]:
        return {
            "n_contacts": self.n_contacts, "matched": self.matched,
            "link_right": self.link_right, "link_accuracy": rounded(self.link_accuracy, 6),
            "contact_right": self.contact_right,
            "contact_accuracy": rounded(self.contact_accuracy, 6),
            "n_forces": len(self.force_rel_errors),
            "force_rel_error_median": rounded(self.force_rel_error_median, 6),
            "force_bias_median": rounded(self.force_bias_median, 6),
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
        n_payload_changes: the alarms of payload changes (not contacts, not counted:
            :func:`impactcli.detect.incidents.mark_payload_changes`).
        n_data_defects: the incidents at a data defect after warm-up (not counted, as
            ``detect`` does not: :func:`impactcli.detect.incidents.mark_defects`).
        unmatched: counted incidents starting in no contact's window (false incidents).
        unmatched_aftermath: of them, those the run marked in an earlier incident's
            aftermath or close behind it (:mod:`impactcli.detect.aftermath`: the arm had not
            settled, or maybe not; still counted, said apart).
        unmatched_resuming: of them, those the run marked as maybe a lasting load resumed
            (:func:`impactcli.detect.incidents.mark_resumed`; still counted, said apart).
        detected: counted contacts the product detected (one of its counted alarms starts
            in the window) — the ones that must each be exactly one incident.
        split: those whose alarms belong to several incidents (label indices).
        not_in_incident: those whose alarms belong to no counted incident (label indices).
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
    n_payload_changes: int = 0
    n_data_defects: int = 0
    unmatched: tuple[int, ...] = ()
    unmatched_aftermath: tuple[int, ...] = ()
    unmatched_resuming: tuple[int, ...] = ()
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
        early = [c for c in self.contacts if c.status == "counted" and not c.payload_change
                 and c.incident_index is None and c.n_incidents >= 1]
        loads = [c for c in self.contacts if c.payload_change and c.incident_index is None]
        rows = [
            ["counted contacts matched by an incident", _frac(o.matched, o.n_contacts) + (
                f"; {len(early)} more held by an incident that began before the contact's "
                f"window (labels {_idx(tuple(c.label_index for c in early))}: an earlier "
                "alarm it merged with began first, so its start, link and force are not "
                "that contact's)" if early else "") + (
                f"; {len(loads)} taken for a payload change (labels "
                f"{_idx(tuple(c.label_index for c in loads))}: only payload changes' alarms, "
                "not counted, hold it — missed as a contact)" if loads else "")],
            ["incidents after warm-up", f"{self.n_incidents}" + (
                f" ({len(self.unmatched)} matching no labelled contact"
                + (f", {len(self.unmatched_aftermath)} of them maybe an earlier incident's "
                   "ringing (in its aftermath or close behind it)"
                   if self.unmatched_aftermath else "")
                + (f", {len(self.unmatched_resuming)} of them just after a lasting load "
                   "ended (maybe that load again)" if self.unmatched_resuming else "")
                + ")" if self.unmatched
                else " (each matches a labelled contact)" if self.n_incidents else "")
             + (f"; besides them, not counted: {'; '.join(besides)}" if (besides := [
                 *([f"{self.n_incidents_in_warmup} in warm-up"]
                   if self.n_incidents_in_warmup else []),
                 *([f"{self.n_payload_changes} the alarm of a payload change"]
                   if self.n_payload_changes else []),
                 *([f"{self.n_data_defects} at a data defect (as detect does not: a "
                    "contact there is missed)"] if self.n_data_defects else [])]) else "")],
            ["link right", _frac(o.link_right, o.matched) + (
                f"; {among} more among the links the incident could not tell apart (link A "
                "or B)" if (among := sum(1 for c in self.contacts if c.status == "counted"
                                         and c.among)) else "")],
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
                txt += f"; in no counted incident: labels {_idx(self.not_in_incident)}"
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
            "n_payload_changes": self.n_payload_changes,
            "n_data_defects": self.n_data_defects,
            "unmatched_incidents": list(self.unmatched),
            "unmatched_in_aftermath": list(self.unmatched_aftermath),
            "unmatched_resuming_load": list(self.unmatched_resuming),
            "link_accuracy": rounded(o.link_accuracy, 6),
            "contact_accuracy": rounded(o.contact_accuracy, 6),
            "force_rel_error_median": rounded(o.force_rel_error_median, 6),
            "force_bias_median": rounded(o.force_bias_median, 6),
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
    incidents: Sequence[Any], evs: Sequence[ScoredEvent], contacts: Sequence[ContactLabel],
    status: Sequence[str], tolerance: MatchTolerance, warmup_end_s: float,
) -> IncidentEvaluation:
    """Score incidents against labelled contacts (docs/formats.md, "Ground-truth labels"):
    ``link`` against the label's link, ``force_n`` against ``peak_force``, ``contact``
    against the kind.

    A contact is answered by the earliest counted incident (after warm-up) that *starts*
    in its window ``[start - pre_s, end + post_s]`` — the events' matching rule; an
    incident already under way at the onset does not answer it. Contacts in warm-up are
    answered by any incident (informational). The "exactly one incident" check follows
    the product's counted alarms that start in a detected contact's window to the
    incidents holding them (the incident's ``events``, else the incident whose span holds
    the alarm's start); a lasting load (an alarm of ``events.LONG_EVENT_S`` or more, in
    no incident: docs/incidents.md) is not one of those alarms.

    Args:
        incidents: :class:`~impactcli.detect.incidents.Incident` s or timeline dicts.
        evs: every event, in the order the incidents' ``events`` index.
        contacts, status: the labels' contacts and their status (evaluate_events).
        tolerance: the matching window. warmup_end_s: [s].
    """
    incs = [_as_inc(x, warmup_end_s, i) for i, x in enumerate(incidents)]
    order = sorted(range(len(incs)), key=lambda k: (incs[k].t_start, incs[k].t_end))
    counted_inc = [k for k in order if not incs[k].in_warmup and not incs[k].payload_change
                   and not incs[k].data_defect]  # detect's counted ones
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
                      and not e.in_warmup and lo - EPS_S <= e.t_start <= hi + EPS_S
                      and e.t_end - e.t_start < LONG_EVENT_S - EPS_S]
            held = set().union(*(holder.get(a, set()) for a in alarms)) if alarms else set()
            n_held = len(held)
            as_load = bool(held) and all(incs[h].payload_change for h in held)
            if alarms:
                detected += 1
                if n_held > 1 and not as_load:  # a load's pick and release: not a split
                    split.append(c_idx)
                elif n_held == 0 or as_load:  # in no counted incident
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
            force_at_least=ans is not None and ans.force_n is not None and ans.force_at_least,
            link_candidates=() if ans is None else ans.candidates,
            payload_change=status[c_idx] == "counted" and as_load,
            force_trusted=ans is None or ans.force_trusted,
        ))
    counted_rows = [r for r in rows if r.status == "counted"]
    per_link = {link: _answer_score([r for r in counted_rows if r.link_label == link])
                for link in sorted({r.link_label for r in counted_rows})}
    per_type = {t: _answer_score([r for r in counted_rows if r.expected_contact == t])
                for t in (*CONTACT_TYPES, "unknown")
                if any(r.expected_contact == t for r in counted_rows)}
    unmatched = tuple(sorted(k for k in counted_inc
                             if not _starts_in_any(incs[k], contacts, tolerance)))
    return IncidentEvaluation(
        available=True, contacts=tuple(rows), overall=_answer_score(counted_rows),
        per_link=per_link, per_type=per_type, n_incidents=len(counted_inc),
        n_incidents_in_warmup=sum(1 for i in incs if i.in_warmup),
        n_payload_changes=sum(1 for i in incs if i.payload_change and not i.in_warmup),
        n_data_defects=sum(1 for i in incs if i.data_defect and not i.in_warmup),
        unmatched=unmatched,
        unmatched_aftermath=tuple(k for k in unmatched if incs[k].aftermath),
        unmatched_resuming=tuple(k for k in unmatched if incs[k].resumes),
        detected=detected, split=tuple(split), not_in_incident=tuple(none_),
        shared=tuple(sorted(k for k, cs in inc_contacts.items() if len(cs) > 1)),
    )


def _starts_in_any(inc: _Inc, contacts: Sequence[ContactLabel], tol: MatchTolerance) -> bool:
    return any(lo - EPS_S <= inc.t_start <= hi + EPS_S
               for lo, hi in (tol.window(c) for c in contacts))
