"""Incidents: one per physical contact — when, where, how hard, what kind
(docs/formats.md, "Detection timeline"; the rules and their measured accuracy:
docs/incidents.md).

- **When** (:func:`group_events`): every product event (adaptive, static_loading) belongs to
  exactly one incident or is a lasting load; events that overlap or follow each other within
  ``events.merge_gap_s`` form one, never across the warm-up's end (events are split there,
  so incidents are too). An incident starts at its first product alarm.
- **Lasting loads** (:class:`LastingLoad`): a product alarm of ``events.LONG_EVENT_S`` (10 s)
  or more is a finding of its own — an unknown payload, a clamp, a model that no longer
  fits — and absorbs no other event: the events during it form incidents as if it were not
  there.
- **Where** (:func:`isolate`, :mod:`impactcli.detect.link_evidence`): a contact on link i
  exerts torque on joints 1..i only (r = J_cᵀ F), so the link is the most distal joint
  whose residual is significant during the incident — its detectors fired, or its residual
  stands out of its own noise there — and the links the evidence cannot tell apart are
  said; links are numbered from the base along the robot's own chain; None when no joint is
  significant.
- **How hard** (:mod:`impactcli.detect.force`): with kinematics, the force at the isolated
  link's end that best explains the residuals of joints 1..i through the Jacobian (a lower
  bound where part of it is not seen; none where no single force there gives them);
  without, None and the peak residual torques.
- **Not a contact** (:func:`mark_defects`): an incident that starts at a data defect of the
  log — a time gap, a jump no motion explains — or within the detectors' settling time
  after it (:func:`settle_s`) is marked with it and counted apart: the residual there shows
  the defect, not a force.
- **What kind** (:func:`contact_type`, ISO/TS 15066): quasi-static when the arm kept
  pressing while it stood nearly still, or pressed for :data:`QS_MIN_PRESS_S` or longer;
  transient otherwise; unknown when the incident runs to the end of the log.

Pure functions of arrays; the replay applies them to each stretch of the log near an alarm.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..types import AlarmSpan, Event
from .events import LONG_EVENT_S
from .link_evidence import decide_link

#: The product's detectors (what incidents are made of).
PRODUCT_DETECTORS: tuple[str, ...] = ("adaptive", "static_loading")
#: Two product events whose gap the static-loading statistic bridges at this fraction of
#: its threshold belong to one incident (:func:`group_events`).
BRIDGE_FRACTION = 0.5
#: Contact type: a joint stands still below this speed [rad/s] ...
STILL_RAD_S = 0.05
#: ... and pressing while still for at least this long makes the contact quasi-static [s];
QS_MIN_STILL_S = 1.0
#: so does pressing (static_loading above its threshold) for this long or longer [s]; less
#: is transient.
QS_MIN_PRESS_S = 2.5


@dataclass(frozen=True)
class Incident:
    """One physical contact as the product sees it (docs/formats.md, "Detection timeline":
    an item of ``incidents``)."""

    t_start: float
    t_end: float
    i_start: int
    i_end: int
    detectors: tuple[str, ...]
    joints: tuple[str, ...]
    link: int | None
    force_n: float | None
    force_method: str
    contact: str
    peak_residual: dict[str, float]
    in_warmup: bool
    t_start_utc: str | None = None
    events: tuple[int, ...] = field(default=())
    number: int | None = None
    link_candidates: tuple[int, ...] = ()
    force_plausible: bool | None = None
    force_ceiling_n: float | None = None
    force_check: str = ""
    outside_envelope: bool | None = None
    data_defect: dict[str, Any] | None = None
    payload_change: int | None = None
    payload_test: str | None = None
    aftermath: dict[str, Any] | None = None
    close_behind: dict[str, Any] | None = None
    load_motion: dict[str, Any] | None = None
    force_at_least: bool = False
    unseen_load_kg: float | None = None
    resumes_load: dict[str, Any] | None = None
    velocity_disagrees: dict[str, Any] | None = None
    held_before: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (timeline ``incidents`` item); ``outside_envelope`` only when
        the config recorded a motion envelope (:mod:`impactcli.detect.envelope`),
        ``data_defect`` only when the incident starts at one (:func:`mark_defects`),
        ``payload_change`` (its 1-based number) only when it is one
        (:func:`mark_payload_changes`), ``payload_test`` only when the payload monitor
        weighed its alarm and found no payload change (why:
        :func:`impactcli.detect.payload_change.mark_tried`) or a payload change with a
        contact beside it (:func:`mark_payload_changes`), ``aftermath`` only when it starts
        while the arm had not settled after an earlier incident
        (:func:`impactcli.detect.aftermath.aftermath_of`, with its ``text``),
        ``close_behind`` only when it starts, no stronger, within the detectors' settling
        time after a counted one and no aftermath tells (:func:`~impactcli.detect.aftermath.
        close_behind`), ``load_motion`` only when it starts while the arm carried a
        calibration log's load on motion no calibration log with that load covered
        (:func:`impactcli.detect.load_motion.mark_load_motion`),
        ``unseen_load_kg`` only when it starts while the arm carried a load no calibration
        log carried (:func:`impactcli.run.loads.unseen_spans`), ``velocity_disagrees`` only
        when it overlaps a stretch where the logged velocity and positions tell two motions
        (:func:`mark_disagreeing`), ``held_before`` only when its alarm ended a load held
        before it (:func:`impactcli.detect.release.mark_held`)."""
        return {
            "t_start": self.t_start, "t_end": self.t_end, "t_start_utc": self.t_start_utc,
            "detectors": list(self.detectors), "joints": list(self.joints), "link": self.link,
            "force_n": self.force_n, "force_method": self.force_method,
            "force_at_least": self.force_at_least, "contact": self.contact,
            "peak_residual": dict(self.peak_residual),
            "in_warmup": self.in_warmup, "i_start": self.i_start, "i_end": self.i_end,
            "events": list(self.events), "number": self.number,
            "link_candidates": list(self.link_candidates) if self.link is not None else None,
            "force_plausible": self.force_plausible, "force_ceiling_n": self.force_ceiling_n,
            "force_check": self.force_check,
            **({} if self.outside_envelope is None
               else {"outside_envelope": self.outside_envelope}),
            **({} if self.data_defect is None else {"data_defect": self.data_defect}),
            **({} if self.payload_change is None else {"payload_change": self.payload_change}),
            **({} if self.payload_test is None else {"payload_test": self.payload_test}),
            **({} if self.aftermath is None else {"aftermath": self.aftermath}),
            **({} if self.close_behind is None else {"close_behind": self.close_behind}),
            **({} if self.load_motion is None else {"load_motion": self.load_motion}),
            **({} if self.unseen_load_kg is None else {"unseen_load_kg": self.unseen_load_kg}),
            **({} if self.resumes_load is None else {"resumes_load": self.resumes_load}),
            **({} if self.velocity_disagrees is None
               else {"velocity_disagrees": self.velocity_disagrees}),
            **({} if self.held_before is None else {"held_before": self.held_before}),
        }


def mark_disagreeing(incidents: Sequence[Incident],
                     stretches: Sequence[tuple[float, float, tuple[str, ...]]]
                     ) -> list[Incident]:
    """The incidents, one that overlaps a stretch where the logged velocity and the
    positions tell two motions (``stretches``: (from [s], to [s], joints), the scan's:
    :mod:`impactcli.logs.velocity_check`) marked with its first such stretch
    (``velocity_disagrees``: ``t_start``, ``t_end``, ``joints``) — still counted: the
    residual there may be the data's (the real KUKA log's last incident runs into it)."""
    if not stretches:
        return list(incidents)
    out = []
    for inc in incidents:
        hit = next(((a, b, j) for a, b, j in stretches
                    if a <= inc.t_end and inc.t_start <= b), None)
        out.append(inc if hit is None else replace(inc, velocity_disagrees={
            "t_start": hit[0], "t_end": hit[1], "joints": list(hit[2])}))
    return out


@dataclass(frozen=True)
class LastingLoad(AlarmSpan):
    """A product alarm (an :class:`~impactcli.types.AlarmSpan`) of
    :data:`~impactcli.detect.events.LONG_EVENT_S` or more: a load
    that persists — an unknown payload, a clamp, or a model that no longer fits the log
    (docs/incidents.md, "The rules"; timeline ``lasting_loads``).

    ``event`` is its index in the log's events; ``ends_with_log``: it lasts to the log's
    last sample (how long it lasts is not known). ``link`` and ``force_n`` as for an
    incident, over its own samples — the median over its span, the load's own level
    (``peak_force_n`` the peak: a contact inside it, or the load's motion, which the gates
    judge).
    """

    peak_ratio: float
    in_warmup: bool
    event: int
    ends_with_log: bool
    link: int | None
    force_n: float | None
    force_method: str
    t_start_utc: str | None = None
    force_plausible: bool | None = None
    force_ceiling_n: float | None = None
    force_check: str = ""
    payload_test: str | None = None
    force_at_least: bool = False
    unseen_load_kg: float | None = None
    on_at_warmup_end: bool = False
    peak_force_n: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (timeline ``lasting_loads`` item); ``payload_test`` and
        ``unseen_load_kg`` as an incident's; ``on_at_warmup_end`` only when true: the alarm
        was on when the warm-up ended (:func:`on_at_warmup_end`), so its ``t_start`` is
        the warm-up's end, not when the load began."""
        return {
            "detector": self.detector, "t_start": self.t_start, "t_end": self.t_end,
            "t_start_utc": self.t_start_utc, "i_start": self.i_start, "i_end": self.i_end,
            "joints": list(self.joints), "peak_ratio": self.peak_ratio,
            "in_warmup": self.in_warmup, "event": self.event,
            "ends_with_log": self.ends_with_log, "link": self.link, "force_n": self.force_n,
            "force_method": self.force_method, "force_at_least": self.force_at_least,
            "force_plausible": self.force_plausible,
            "force_ceiling_n": self.force_ceiling_n, "force_check": self.force_check,
            **({} if self.payload_test is None else {"payload_test": self.payload_test}),
            **({} if self.unseen_load_kg is None else {"unseen_load_kg": self.unseen_load_kg}),
            **({"on_at_warmup_end": True} if self.on_at_warmup_end else {}),
            **({} if self.peak_force_n is None else {"peak_force_n": self.peak_force_n}),
        }


def on_at_warmup_end(loads: Sequence[LastingLoad], events: Sequence[Event]
                     ) -> list[LastingLoad]:
    """The lasting loads, those counted from the warm-up's end because their detector was
    already alarming then marked ``on_at_warmup_end``: the part of the same alarm in the
    warm-up (:func:`impactcli.detect.events.split_at_warmup`), an event of that detector
    in the warm-up, ends on the sample before theirs. When such a load began is not
    known — at the warm-up's end or before it (indices in the log, both)."""
    return [replace(x, on_at_warmup_end=True) if not x.in_warmup and any(
        e.in_warmup and e.detector == x.detector and e.i_end >= x.i_start - 1
        for e in events) else x for x in loads]


def mark_resumed(incidents: Sequence[Incident], loads: Sequence[LastingLoad],
                 settle_s: float) -> list[Incident]:
    """The incidents, each whose alarm begins within ``settle_s`` (the static-loading
    low-pass's settling time) after a lasting load ended, holds that load's detector and
    one of its joints, marked ``resumes_load`` {``t_start``, ``t_end`` (the load's),
    ``gap_s``, ``text``}: the load's detector dipped under its threshold for less than its
    filter settles, so the alarm may be that load again, not a new contact (a load held
    20–40 s read as a 16 s lasting load and a 4 s quasi-static "contact" 0.13 s after it).
    Still counted: the residuals cannot tell."""
    out = []
    for inc in incidents:
        load = next((x for x in loads if x.detector in inc.detectors
                     and set(x.joints) & set(inc.joints)
                     and 0.0 <= inc.t_start - x.t_end <= settle_s), None)
        if load is None or inc.in_warmup:
            out.append(inc)
            continue
        gap = inc.t_start - load.t_end
        out.append(replace(inc, resumes_load={
            "t_start": load.t_start, "t_end": load.t_end, "gap_s": gap,
            "text": (f"resumes the lasting load of {load.t_start:.3f}–{load.t_end:.3f} s after "
                     f"a {gap:.2f} s dip: its {load.detector} alarm on "
                     f"{', '.join(load.joints)} was under its threshold for less than its "
                     "low-pass settles, so this may be that load again, not a new contact")}))
    return out


#: The other product detector, the one left to see a contact while a detector alarms.
OTHER_DETECTOR = {"static_loading": "adaptive", "adaptive": "static_loading"}


def union_length(spans: Iterable[tuple[float, float]], lo: float = -np.inf,
                 hi: float = np.inf) -> float:
    """The length [s] of the union of ``spans`` (``(start, end)``, overlapping or not; an
    empty or reversed one adds nothing) clipped to ``lo`` … ``hi``."""
    total, end = 0.0, lo
    for a, b in sorted((max(float(a), lo), min(float(b), hi)) for a, b in spans):
        if b > max(a, end):
            total, end = total + (b - max(a, end)), b
    return total


def blind_s(loads: Sequence[dict[str, Any]]) -> float:
    """How long the counted lasting loads (timeline dicts) held their detectors alarming
    [s]: the union of their spans (two detectors' may overlap)."""
    return union_length((x["t_start"], x["t_end"]) for x in loads if not x.get("in_warmup"))


def blind_text(loads: Sequence[dict[str, Any]], analysed_s: float | None = None, *,
               listed: bool = False) -> str:
    """What the counted lasting loads (timeline dicts) leave unseen, in words ("" when
    none): while one lasts its detector is already alarming on its joints, so a contact
    there raises no event of that detector on them — only the other product detector can
    see it, and the detection floor (a step or a blow from the detectors' own state) does
    not hold there. ``analysed_s``: the log's time after warm-up [s], for the share;
    ``listed``: the loads are listed just above (their spans not repeated)."""
    counted = [x for x in loads if not x.get("in_warmup")]
    if not counted:
        return ""
    total = blind_s(counted)
    said = ([f"{100 * total / analysed_s:.0f} % of the log after warm-up"] if analysed_s
            else []) + ([] if listed else [
                f"{x['t_start']:.1f}–{x['t_end']:.1f} s, {x['detector']} on "
                f"{', '.join(x['joints'])}" for x in counted])
    others = sorted({OTHER_DETECTOR.get(x["detector"], "the other detector") for x in counted})
    return (f"a lasting load's detector was already alarming on its joints for {total:.1f} s"
            + (f" ({'; '.join(said)})" if said else "")
            + ": a contact there raised no event of that detector on them, only the other "
            f"({' or '.join(others)}) could see it — one it did not see was missed — and the "
            "detection floor does not hold there")


#: The plain |r| > v0 comparison alarms at once where the product's detectors wait for
#: their filters: a baseline alarm this long before an incident's start is that
#: incident's (the heavy sample arm's impact at 26.5 s: baseline at 26.552 s, the
#: incident from 26.61 s) [s] — about the static-loading low-pass's settling.
BASELINE_LEAD_S = 0.5


def baseline_alone(events: Sequence[dict[str, Any]], incidents: Sequence[dict[str, Any]],
                   loads: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The static baseline's events after warm-up (timeline dicts) that no incident (counted
    or not: one at a data defect or a payload change explains its alarm) or lasting load
    after warm-up overlaps, from :data:`BASELINE_LEAD_S` before its start: alarms of the
    plain |r| > v0 comparison the product's detectors did not confirm. Not incidents (the
    product is adaptive and static_loading: docs/incidents.md), but a "no incident" must
    not hide them (a trial's real UR log: a braking whose residual reached 1.8× v0 on
    shoulder_pan, "No incident after warm-up" and no word of it)."""
    spans = [(float(x["t_start"]) - BASELINE_LEAD_S, float(x["t_end"]))
             for x in (*incidents, *loads)
             if not x.get("in_warmup")]  # (one at a data defect or a payload change too)
    return [e for e in events if e["detector"] == "static_baseline" and not e["in_warmup"]
            and not any(a <= e["t_end"] and e["t_start"] <= b for a, b in spans)]


def baseline_alone_text(alone: Sequence[dict[str, Any]]) -> str:
    """:func:`baseline_alone`'s events in words ("" when none): ``the static baseline alone
    alarmed after warm-up at 16.970 s (shoulder_pan, wrist_1; up to 1.8× its threshold
    v0): not an incident — neither product detector confirmed it, but a contact may have
    been there (events in the timeline)``."""
    if not alone:
        return ""
    joints = sorted({j for e in alone for j in e["joints"]})
    top = max(float(e["peak_ratio"]) for e in alone)
    when = (f"at {alone[0]['t_start']:.3f} s" if len(alone) == 1 else
            f"{len(alone)} times (first at {alone[0]['t_start']:.3f} s)")
    return (f"the static baseline alone alarmed after warm-up {when} ({', '.join(joints)}; "
            f"up to {top:.2g}× its threshold v0): not "
            f"{'an incident' if len(alone) == 1 else 'incidents'} — neither product detector "
            "confirmed it, but a contact may have been there (events in the timeline)")


#: A lasting load held its detector alarming over "all" the analysed time when it held
#: this share of it or more (a sample or a merge gap short of it is still all).
ALL_HELD_SHARE = 0.99


def floor_apart(loads: Sequence[dict[str, Any]], analysed_s: float | None
                ) -> tuple[str, bool]:
    """How the detection floor's lines qualify themselves beside the counted lasting loads
    (timeline dicts): ``(words, all_held)`` — ``words`` "" when none, else where the floor
    holds ("outside the 31.0 s a lasting load held its detector alarming") or, when the
    loads held it over all the ``analysed_s`` after warm-up (:data:`ALL_HELD_SHARE`), that
    no moment lies outside them (a trial read a floor "outside the 56.7 s" of a log whose
    56.7 s after warm-up were all a lasting load's); ``all_held`` then True."""
    held = blind_s(loads)
    if held <= 0:
        return "", False
    if analysed_s and held >= ALL_HELD_SHARE * analysed_s:
        counted = [x for x in loads if not x.get("in_warmup")]
        dets = sorted({x["detector"] for x in counted})
        others = sorted({OTHER_DETECTOR.get(d, "the other detector") for d in dets})
        return (f"a lasting load held {' and '.join(dets)} alarming over all the "
                f"{analysed_s:.1f} s after warm-up: no moment lies outside it, so no floor "
                f"holds — a contact could show only through {' or '.join(others)}, or "
                f"through {' or '.join(dets)} on a joint the load left free"), True
    return (f"outside the {held:.1f} s a lasting load held its detector alarming, below: a "
            "contact then needed the other detector"), False


@dataclass(frozen=True)
class DataDefect:
    """A stretch of the log that is not the arm's motion: a time ``gap`` (from its last
    sample before to the first after) or a ``jump`` of the positions no motion explains
    (:mod:`impactcli.logs.defects`; the step into the sample at ``t_end``). ``size``: a gap's
    length [s], a jump's largest step [rad]; ``joints``: a jump's joints."""

    kind: str
    t_start: float
    t_end: float
    size: float
    joints: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (timeline ``data_defects.listed`` item)."""
        return {"kind": self.kind, "t_start": self.t_start, "t_end": self.t_end,
                "size": self.size, "joints": list(self.joints)}


def link_words(link: int | None, candidates: Sequence[int] | None = (),
               unknown: str = "link unknown") -> str:
    """How an answer names an incident's link: ``link 5``, or ``link 5 or 6`` (``link 2, 3
    or 4``) when the residuals cannot tell those links apart (``link_candidates``,
    :mod:`.link_evidence`), ascending; ``unknown`` when no link was isolated."""
    if link is None:
        return unknown
    links = [str(c) for c in sorted({link, *(candidates or ())})]
    return "link " + (links[0] if len(links) == 1 else
                      f"{', '.join(links[:-1])} or {links[-1]}")


def settle_s(loading_cutoff_hz: float, threshold_window_s: float) -> float:
    """How long after a data defect the detectors still show it [s]: five time constants
    of the static-loading low-pass (its memory) plus the adaptive threshold's RMS window
    (eq. 42's N2): 0.56 s with the defaults (2 Hz, 0.16 s)."""
    return 5.0 / (2.0 * np.pi * loading_cutoff_hz) + threshold_window_s


def adaptive_memory_s(forgetting_factor: float, sample_rate_hz: float) -> float:
    """How long the adaptive evaluator remembers a data defect [s]: three time constants
    1 / (1 − λ) of eq. 37–39's forgetting (the RLS estimates a splice disturbed have then
    forgotten 95 % of it): 12 s at λ = 0.999 and 250 Hz; 0 without forgetting (λ = 1)."""
    if forgetting_factor >= 1.0:
        return 0.0
    return 3.0 / ((1.0 - forgetting_factor) * sample_rate_hz)


def mark_defects(incidents: Sequence[Incident], defects: Sequence[DataDefect],
                 settle: float, adaptive_settle: float = 0.0,
                 settled_s: float | None = None) -> list[Incident]:
    """The incidents, each that starts within a defect or ``settle`` seconds after it
    marked with it (its kind and times; the first such defect) — or, raised by the
    adaptive detector alone, ``adaptive_settle`` seconds after it (the evaluator's memory,
    :func:`adaptive_memory_s`: its estimates are still re-converging from the defect),
    unless the defect ended before ``settled_s`` [s]: a warm-up that ended there (not at
    its cap) ended because the evaluator's prediction error had settled, defect and all
    (docs/method.md §5b; a new user's trial: a start transient at 0.012 s took a labelled
    5 N push at 8.08 s out of the count)."""
    if not defects:
        return list(incidents)
    starts = np.array([d.t_start for d in defects])
    ends = np.array([d.t_end for d in defects])
    memory = np.full(len(defects), adaptive_settle)
    if settled_s is not None:
        memory[ends < settled_s] = 0.0
    out = []
    for inc in incidents:
        alone = set(inc.detectors) == {"adaptive"}
        after = np.maximum(settle, memory) if alone else np.full(len(defects), settle)
        hit = np.flatnonzero((starts - 1e-9 <= inc.t_start) & (inc.t_start <= ends + after))
        if hit.size:
            d = defects[int(hit[0])]
            out.append(replace(inc, data_defect={"kind": d.kind, "t_start": d.t_start,
                                                 "t_end": d.t_end}))
        else:
            out.append(inc)
    return out


def mark_payload_changes(incidents: Sequence[Incident], changes: Sequence[Any],
                         settle: float, lead_s: float = 0.1,
                         place: Callable[[Incident, Any], Incident | None] | None = None,
                         ) -> tuple[list[Incident], list[Any]]:
    """The incidents, each that starts from a payload change's onset to ``settle`` seconds
    after its classification, marked with the change's number (1-based): the alarm was the
    load, not a contact (:mod:`impactcli.detect.payload_change`). So is one still going at
    the onset that started at most ``lead_s`` before it (the run passes ``settle``): the
    adaptive detector sees the step at once, and the static-loading low-pass crosses vL up
    to its settling time after it, or was already above it there from a misfit that the
    step ran into — one alarm (a 1 kg release on the simulated soft arm, a new user's
    trial: its incident began 0.28 s before the change's onset, was counted as a 22 N
    quasi-static contact and tripped --fail-on-force). Unlike after a data defect, the
    adaptive evaluator's memory is not added: a blow the adaptive detector alone sees while
    the load is carried must count. Incidents marked already are left alone.

    A change that found a contact in its window (its ``contact``) leaves the incident
    holding that contact's onset (else the nearest of the change's) counted, from that
    onset (``t_start`` moved to it, ``payload_test`` saying why; the nearest alarm from its
    end when it ended before the onset — a contact dated where the monitor's scan began
    may have begun earlier, in it — else from its start): the alarm was the load and a
    contact. ``place`` (incident, change) gives that incident's link, force and contact
    type from the contact apart from the load
    (:func:`impactcli.detect.incident_builder.beside`), or None, when the whole alarm's
    stand, said so. A change whose alarm is no incident (a lasting load) counts none: its
    ``contact`` is marked ``counted: false``, so that no output says it counts — unless a
    counted incident that began before the change spans the contact (it holds it).

    Returns:
        the incidents, and the changes (those with a contact no incident holds marked)."""
    if not changes:
        return list(incidents), list(changes)
    hits: dict[int, int] = {}  # incident → the change (1-based) whose alarm it is
    for n, inc in enumerate(incidents):
        hit = [k for k, c in enumerate(changes, 1)
               if c.t_start - 1e-9 <= inc.t_start <= c.t_classified + settle
               or c.t_start - lead_s - 1e-9 <= inc.t_start <= c.t_start <= inc.t_end]
        if hit and inc.data_defect is None and not inc.in_warmup:
            hits[n] = hit[0]
    beside: dict[int, dict[str, Any]] = {}  # incident → the contact it holds (or is nearest)
    for k, c in enumerate(changes, 1):
        seen = getattr(c, "contact", None)
        mine = [n for n, kk in hits.items() if kk == k]
        if seen is not None and mine:
            t = float(seen["t_s"])
            beside[min(mine, key=lambda n: max(0.0, incidents[n].t_start - t,
                                               t - incidents[n].t_end))] = seen
    counted = {hits[n] for n in beside} | {  # or within an earlier incident that spans it
        k for k, c in enumerate(changes, 1) if getattr(c, "contact", None) is not None
        and any(not i.in_warmup and i.data_defect is None
                and i.t_start <= float(c.contact["t_s"]) <= i.t_end
                for n, i in enumerate(incidents) if n not in hits)}
    return ([_from_contact(inc, hits[n], beside[n], None if place is None
                           else place(inc, changes[hits[n] - 1])) if n in beside
             else replace(inc, payload_change=hits[n]) if n in hits else inc
             for n, inc in enumerate(incidents)],
            [replace(c, contact={**c.contact, "counted": False})
             if getattr(c, "contact", None) is not None and k not in counted else c
             for k, c in enumerate(changes, 1)])


def _from_contact(inc: Incident, k: int, seen: dict[str, Any],
                  placed: Incident | None = None) -> Incident:
    """``inc``, the alarm of payload change ``k`` that holds a contact (``seen``: the
    change's ``contact``), counted from the contact's onset; with the link, force and
    contact type of ``placed`` (``inc`` placed by the contact apart from the load) when
    given, else its own, the whole alarm's."""
    import datetime as dt

    t, i = float(seen["t_s"]), int(seen["i"])
    if t > inc.t_end:  # the nearest of the change's alarms ended before it: from its end
        t, i = inc.t_end, inc.i_end
    elif t < inc.t_start:  # ... began after it: as it is
        t, i = inc.t_start, inc.i_start
    shift = t - inc.t_start
    utc = inc.t_start_utc
    if utc is not None:
        at = dt.datetime.fromisoformat(utc.replace("Z", "+00:00")) + dt.timedelta(
            seconds=shift)
        utc = at.isoformat(timespec="milliseconds").replace("+00:00", "Z")
    whose = ("its link, force and contact type the contact's own, the load's torque "
             "taken out" if placed is not None else
             "its link, force and contact type the whole alarm's, the load's step with it")
    return replace(placed or inc, t_start=t, i_start=i if shift else inc.i_start,
                   t_start_utc=utc,
                   payload_test=(f"a contact beside payload change P{k}, {whose}: "
                                 f"its alarm held the load and, from {seen['t_s']:.3f} s, a "
                                 f"torque on {seen['joint']} the load does not explain "
                                 f"({seen['peak']:.2g}× its loading threshold)"))


def lasting(events: Sequence[Event]) -> list[int]:
    """Indices of the product events lasting :data:`~impactcli.detect.events.LONG_EVENT_S`
    or more (1 ns of rounding tolerated): the lasting loads."""
    return [k for k, e in enumerate(events) if e.detector in PRODUCT_DETECTORS
            and e.t_end - e.t_start >= LONG_EVENT_S - 1e-9]


def group_events(events: Sequence[Event], merge_gap_s: float,
                 pressing: np.ndarray | None = None,
                 exclude: Sequence[int] = ()) -> list[list[int]]:
    """Indices into ``events`` of the product events of each incident, in time order.

    Events of the product's detectors that overlap or follow each other within
    ``merge_gap_s`` (from one's end to the next's start) form one incident; so do two whose
    gap the contact bridges — ``pressing`` (N,) true at every sample between them (the
    static-loading statistic of some joint still at :data:`BRIDGE_FRACTION` of its
    threshold: an alarm that flickers around its threshold while the contact goes on).
    An event in the warm-up and one after it never share an incident (events are split at
    the warm-up's end: what is after it is counted, docs/incidents.md). Every product event
    not in ``exclude`` (the lasting loads) is in exactly one group.
    """
    skip = set(exclude)
    idx = sorted((k for k, e in enumerate(events)
                  if e.detector in PRODUCT_DETECTORS and k not in skip),
                 key=lambda k: (events[k].t_start, events[k].t_end))
    groups: list[list[int]] = []
    end, i_end = -np.inf, -1
    for k in idx:
        e = events[k]
        same_side = bool(groups) and events[groups[-1][0]].in_warmup == e.in_warmup
        bridged = (pressing is not None and same_side and e.i_start > i_end + 1
                   and bool(np.all(pressing[i_end + 1:e.i_start])))
        if same_side and (e.t_start <= end + merge_gap_s + 1e-9 or bridged):
            groups[-1].append(k)
            if e.t_end > end:
                end, i_end = e.t_end, e.i_end
        else:
            groups.append([k])
            end, i_end = e.t_end, e.i_end
    return groups


def isolate(
    loading_ratio: np.ndarray, adaptive_fired: np.ndarray, chain_index: Sequence[int],
) -> int | None:
    """The 1-based link of a contact from its detectors' evidence alone (the residual's is
    :func:`impactcli.detect.link_evidence.decide_link`'s).

    Args:
        loading_ratio: (n, J) |LP(r)| / vL over the incident.
        adaptive_fired: (n, J) the adaptive decision over the incident.
        chain_index: (J,) each detected joint's 1-based position in the robot's chain.
    """
    return decide_link(loading_ratio, adaptive_fired, chain_index).link


def contact_type(
    loading_on: np.ndarray, speed: np.ndarray, dt: float, ends_with_log: bool = False,
) -> str:
    """``transient``, ``quasi_static`` or ``unknown`` (module doc).

    Args:
        loading_on: (n,) static_loading above threshold on some joint, over the incident.
        speed: (n,) largest |q'| of the isolated link's joints [rad/s].
        dt: sample period [s].
        ends_with_log: the incident lasts to the log's end (how long it pressed is unknown).
    """
    pressing = float(np.sum(loading_on)) * dt
    still_pressing = float(np.sum(loading_on & (speed < STILL_RAD_S))) * dt
    if still_pressing >= QS_MIN_STILL_S or pressing >= QS_MIN_PRESS_S:
        return "quasi_static"
    if ends_with_log:
        return "unknown"
    return "transient"


#: A time gap is a data defect from this many sample periods on: two samples missing or
#: more (one dropped sample — a step of two periods, common over a network — disturbs the
#: detectors little and would blank the settling time after it every time; it is still
#: warned of as a gap).
MIN_DEFECT_GAP_PERIODS = 2.5
#: At most this many data defects are listed in the timeline (all are counted).
MAX_LISTED_DEFECTS = 1000


def data_defects(scan: Any, gap_times: np.ndarray) -> list[DataDefect]:
    """The log's time gaps of :data:`MIN_DEFECT_GAP_PERIODS` periods or more (``gap_times``:
    (G, 2) the samples before and after each [s]) and its position jumps (the scan's, one
    per step with the joints that jump), in time order."""
    shortest = MIN_DEFECT_GAP_PERIODS * scan.sample_period_s
    out = [DataDefect("gap", float(a), float(b), float(length))
           for (a, b), length in zip(gap_times, scan.gap_lengths_s, strict=True)
           if np.isfinite(a) and np.isfinite(b) and length >= shortest]
    names = scan.log.joint_names
    by_step: dict[int, list[Any]] = {}
    for x in scan.jumps:
        by_step.setdefault(x.i, []).append(x)
    period = scan.sample_period_s
    for xs in by_step.values():
        t = (xs[0].t_ns - scan.t0_ns) * 1e-9
        out.append(DataDefect("jump", max(t - period, 0.0), t, max(x.size for x in xs),
                              tuple(names[x.joint] for x in xs)))
    return sorted(out, key=lambda d: (d.t_start, d.kind))


def defect_blind_s(defects: Sequence[DataDefect], after_s: Sequence[float] | np.ndarray,
                   t0: float, t1: float) -> float:
    """How long [s] of ``t0`` … ``t1`` (the log after warm-up) lies within a defect or the
    ``after_s`` (one per defect) that follow it — where :func:`mark_defects` takes an alarm
    that starts for the defect's, not counted: a contact starting there is missed."""
    return union_length(((d.t_start, d.t_end + float(a))
                         for d, a in zip(defects, after_s, strict=True)), t0, t1)


def blind_of(defects: Sequence[DataDefect], settle: float, adaptive_settle: float,
             settled_s: float | None, t0: float, t1: float) -> tuple[float, float, float]:
    """``(adaptive_settle, blind, adaptive_blind)`` [s] of :func:`defects_dict`: as
    :func:`mark_defects` marks — ``settle`` after each defect, the adaptive detector's
    memory (at least ``settle``) for its alarms alone, none for a defect that ended before
    ``settled_s`` — over the log after warm-up (``t0`` … ``t1``)."""
    memory = [0.0 if settled_s is not None and d.t_end < settled_s else adaptive_settle
              for d in defects]
    return (adaptive_settle, defect_blind_s(defects, [settle] * len(defects), t0, t1),
            defect_blind_s(defects, np.maximum(settle, memory), t0, t1))


def defects_dict(defects: Sequence[DataDefect], settle: float, n_jumps: int,
                 blind: tuple[float, float, float] | None = None) -> dict[str, Any]:
    """The timeline's ``data_defects``: counts, the settling time, the first listed, and
    (``blind``: the adaptive detector's memory of a defect [s], then
    :func:`defect_blind_s` with ``settle``, and with the memory for the adaptive detector
    alone) how long after warm-up an alarm was taken for a defect's."""
    return {"gaps": sum(1 for d in defects if d.kind == "gap"),
            "jumps": sum(1 for d in defects if d.kind == "jump"),
            "jump_samples": n_jumps, "settle_s": settle,
            **({} if blind is None else {"adaptive_settle_s": blind[0], "blind_s": blind[1],
                                         "adaptive_blind_s": blind[2]}),
            "listed": [d.to_dict() for d in defects[:MAX_LISTED_DEFECTS]]}


def defect_blind_words(dd: dict[str, Any]) -> str | None:
    """What a log's data defects hid (the timeline's ``data_defects`` with the blind times,
    or a batch row's ``defect_blind``), in words: the terminal's and the report's; None
    when they hid nothing (the adaptive detector's blind time, never the shorter, is 0)."""
    if not dd.get("adaptive_blind_s"):
        return None
    n = int(dd["defects"]) if "defects" in dd else int(dd["gaps"]) + int(dd["jumps"])
    after = "after its defect" if n == 1 else f"after one of its {n} defects"
    alone = (f" ({dd['adaptive_blind_s']:.3g} s for a contact only the adaptive detector "
             f"sees: its evaluator remembers a defect {dd['adaptive_settle_s']:.3g} s)"
             if dd["adaptive_blind_s"] > dd["blind_s"] + 1e-9 else "")
    return (f"an alarm starting within {dd['settle_s']:.2g} s {after} is taken for the "
            "defect's and not counted, so a contact starting there is missed: "
            f"{dd['blind_s']:.3g} s of the log after warm-up{alone}; the detection floor "
            "does not hold there")
