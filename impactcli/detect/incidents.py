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
- **How hard**: with kinematics, the force at the isolated link's end that best explains
  the residuals of joints 1..i through the Jacobian, in least squares (small singular
  values dropped); without, None and the peak residual torques. On a planar arm, where the
  joints give more torques than the force has parts and it accounts for less than
  :data:`FIT_SHARE` of them, no single force at the link's end gives the torques (the
  model's own error, or a contact elsewhere): no force is stated, and ``force_method``
  says why.
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

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..types import AlarmSpan, Event
from .events import LONG_EVENT_S
from .link_evidence import decide_link

try:  # numpy's stacked least-squares kernel, behind np.linalg.lstsq (lstsq_many)
    from numpy.linalg import _umath_linalg
    _LSTSQ: Any = _umath_linalg.lstsq
except (ImportError, AttributeError):  # pragma: no cover - another numpy
    _LSTSQ = None

#: The product's detectors (what incidents are made of).
PRODUCT_DETECTORS: tuple[str, ...] = ("adaptive", "static_loading")
#: Two product events whose gap the static-loading statistic bridges at this fraction of
#: its threshold belong to one incident (:func:`group_events`).
BRIDGE_FRACTION = 0.5
#: The force is estimated at the samples where the residuals of joints 1..i reach at least
#: this fraction of their peak (a near-singular posture while the residual is small must
#: not make a large force out of noise).
STRONG_FRACTION = 0.5
#: Singular values of the Jacobian below this fraction of the largest are dropped (the
#: force along those directions cannot be seen in the joint torques: the minimum-norm
#: solution leaves it out, an under-estimate rather than a blow-up near singularities).
RCOND = 0.1
#: On a planar arm, where joints 1..i give more torques than a force at link i's end has
#: parts, the force is stated only when it accounts for at least this share of their
#: torque energy over the samples solved: a contact on the link away from its end leaves a
#: torque the end's force cannot give, but a small share of it (tests/test_incidents.py).
#: Not on spatial arms: a tool beyond the flange, or a wrist housing off its axis, leaves
#: more than a fifth unexplained in some directions (a review: 15–40 of 300–400 random
#: such contacts of a UR10e). Measured (2026-11-30, full-rank): the pushes of the heavy
#: geared sample log and of a new user's trial (robot seed 57) 100 %; that trial's three
#: false alarms on link 3, the model's own error, 45, 96 and 99 %: one is caught.
FIT_SHARE = 0.8
#: How ``force_method`` begins when no single force at the link's end gives the torques.
NO_SINGLE_FORCE = "no single force at the end of link"
#: ... and when the model's torque passed what the joint exerted in the log
#: (:func:`impactcli.detect.incident_builder.beyond_logged`).
BEYOND_LOGGED = "the model's torque on"
#: The ``force_method`` beginnings of a force the physics checks leave unstated.
FORCE_NOT_STATED = (NO_SINGLE_FORCE, BEYOND_LOGGED)
#: A joint's lever arm to a link's end shorter than this [m] is none: that point lies on the
#: joint's axis (a UR's wrist links end on their own joints' axes), so no force there turns
#: the joint and a force divided by it would be a rounding error's (1e17 N).
MIN_LEVER_M = 1e-3
#: An estimated force is implausible — beyond what the arm can exert — above this many times
#: the largest force one of the joints 1..i holds at the link's end with its longest lever:
#: its torque capacity (the URDF's effort limit, else the largest torque logged on it) over
#: its reach to that point (docs/incidents.md, "The rules"): such a force is no contact but a
#: log read wrongly (positions in degrees, a wrong gear ratio or torque constant). Genuine
#: contacts of the sample and simulated sets reach at most 1.35 of that force.
FORCE_CEILING_FACTOR = 3.0
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
        (:func:`impactcli.detect.aftermath.aftermath_of`, with its ``text``)."""
        return {
            "t_start": self.t_start, "t_end": self.t_end, "t_start_utc": self.t_start_utc,
            "detectors": list(self.detectors), "joints": list(self.joints), "link": self.link,
            "force_n": self.force_n, "force_method": self.force_method,
            "contact": self.contact, "peak_residual": dict(self.peak_residual),
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
        }


@dataclass(frozen=True)
class LastingLoad(AlarmSpan):
    """A product alarm (an :class:`~impactcli.types.AlarmSpan`) of
    :data:`~impactcli.detect.events.LONG_EVENT_S` or more: a load
    that persists — an unknown payload, a clamp, or a model that no longer fits the log
    (docs/incidents.md, "The rules"; timeline ``lasting_loads``).

    ``event`` is its index in the log's events; ``ends_with_log``: it lasts to the log's
    last sample (how long it lasts is not known). ``link`` and ``force_n`` as for an
    incident, over its own samples (the peak).
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

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (timeline ``lasting_loads`` item); ``payload_test`` as an
        incident's."""
        return {
            "detector": self.detector, "t_start": self.t_start, "t_end": self.t_end,
            "t_start_utc": self.t_start_utc, "i_start": self.i_start, "i_end": self.i_end,
            "joints": list(self.joints), "peak_ratio": self.peak_ratio,
            "in_warmup": self.in_warmup, "event": self.event,
            "ends_with_log": self.ends_with_log, "link": self.link, "force_n": self.force_n,
            "force_method": self.force_method, "force_plausible": self.force_plausible,
            "force_ceiling_n": self.force_ceiling_n, "force_check": self.force_check,
            **({} if self.payload_test is None else {"payload_test": self.payload_test}),
        }


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
                 settle: float, adaptive_settle: float = 0.0) -> list[Incident]:
    """The incidents, each that starts within a defect or ``settle`` seconds after it
    marked with it (its kind and times; the first such defect) — or, raised by the
    adaptive detector alone, ``adaptive_settle`` seconds after it (the evaluator's memory,
    :func:`adaptive_memory_s`: its estimates are still re-converging from the defect)."""
    if not defects:
        return list(incidents)
    starts = np.array([d.t_start for d in defects])
    ends = np.array([d.t_end for d in defects])
    out = []
    for inc in incidents:
        after = max(settle, adaptive_settle) if set(inc.detectors) == {"adaptive"} else settle
        hit = np.flatnonzero((starts - 1e-9 <= inc.t_start) & (inc.t_start <= ends + after))
        if hit.size:
            d = defects[int(hit[0])]
            out.append(replace(inc, data_defect={"kind": d.kind, "t_start": d.t_start,
                                                 "t_end": d.t_end}))
        else:
            out.append(inc)
    return out


def mark_payload_changes(incidents: Sequence[Incident], changes: Sequence[Any],
                         settle: float, merge_gap_s: float = 0.1,
                         place: Callable[[Incident, Any], Incident | None] | None = None,
                         ) -> tuple[list[Incident], list[Any]]:
    """The incidents, each that starts from a payload change's onset to ``settle`` seconds
    after its classification, marked with the change's number (1-based): the alarm was the
    load, not a contact (:mod:`impactcli.detect.payload_change`). So is one still going at
    the onset that started at most ``merge_gap_s`` (the events' merge gap) before it: the
    adaptive detector sees the step a few milliseconds before the static-loading onset,
    and those are one alarm. Unlike after a data defect, the adaptive evaluator's memory is
    not added: a blow the adaptive detector alone sees while the load is carried must
    count. Incidents marked already are left alone.

    A change that found a contact in its window (its ``contact``) leaves the incident
    holding that contact's onset (else the nearest of the change's) counted, from that
    onset (``t_start`` moved to it, ``payload_test`` saying why; the nearest alarm from its
    end when it ended before the onset — a contact dated where the monitor's scan began
    may have begun earlier, in it — else from its start): the alarm was the load and a
    contact. ``place`` (incident, change) gives that incident's link, force and contact
    type from the contact apart from the load
    (:func:`impactcli.detect.incident_builder.beside`), or None, when the whole alarm's
    stand, said so. A change whose alarm is no incident (a lasting load) counts none: its
    ``contact`` is marked ``counted: false``, so that no output says it counts.

    Returns:
        the incidents, and the changes (those with a contact no incident holds marked)."""
    if not changes:
        return list(incidents), list(changes)
    hits: dict[int, int] = {}  # incident → the change (1-based) whose alarm it is
    for n, inc in enumerate(incidents):
        hit = [k for k, c in enumerate(changes, 1)
               if c.t_start - 1e-9 <= inc.t_start <= c.t_classified + settle
               or c.t_start - merge_gap_s - 1e-9 <= inc.t_start <= c.t_start <= inc.t_end]
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
    counted = {hits[n] for n in beside}
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


#: A function giving, for a posture q (chain order, (J_chain,)) and a 1-based link i, the
#: (d, i) Jacobian of the point at that link's end (d = 2 planar, 3 spatial), or None.
JacobianFn = Callable[[np.ndarray, int], np.ndarray | None]


class PlanarJacobian:
    """(2, i) Jacobian of the end of link i of a planar serial arm: the first angle from the
    horizontal, each next one relative to the previous link (docs/formats.md,
    "Robot description"). A :data:`JacobianFn`; :meth:`many` gives it at many postures at
    once, with the same operations per posture (the same bits as one call each)."""

    def __init__(self, link_lengths: Sequence[float]) -> None:
        self.ll = np.asarray(link_lengths, dtype=np.float64)

    def __call__(self, q: np.ndarray, i: int) -> np.ndarray | None:
        got = self.many(np.asarray(q)[None, :], i)
        return None if got is None else got[0]

    def many(self, q: np.ndarray, i: int) -> np.ndarray | None:
        """(n, 2, i) Jacobians at the (n, J) postures ``q``; None for no such link."""
        if i < 1 or i > len(self.ll):
            return None
        phi = np.cumsum(q[:, :i], axis=1)
        pts = np.zeros((q.shape[0], i + 1, 2))
        for k in range(i):
            pts[:, k + 1] = pts[:, k] + self.ll[k] * np.stack(
                (np.cos(phi[:, k]), np.sin(phi[:, k])), axis=1)
        d = pts[:, i][:, None, :] - pts[:, :i]  # from each joint to the point
        return np.stack((-d[:, :, 1], d[:, :, 0]), axis=1)  # z × d: (n, 2, i)


def planar_jacobian(link_lengths: Sequence[float]) -> PlanarJacobian:
    """The :class:`PlanarJacobian` of an arm with these link lengths [m]."""
    return PlanarJacobian(link_lengths)


@dataclass(frozen=True)
class ForceEstimate:
    """A contact-force estimate (:func:`force_estimate`): the peak magnitude [N] (None when
    it cannot be made), how, and each joint's longest lever arm to the link's end over the
    samples solved (chain position → max |J_k| [m], joints 1..i that are detected)."""

    force_n: float | None
    method: str
    levers: dict[int, float] = field(default_factory=dict)


def lstsq_many(a: np.ndarray, b: np.ndarray, rcond: float) -> np.ndarray:
    """(n, d) least-squares solutions of the n systems a[k] x = b[k] ((n, m, d), (n, m)),
    minimum norm, singular values below ``rcond`` × the largest cut: the same bits as one
    ``np.linalg.lstsq(a[k], b[k], rcond=rcond)`` each. It runs numpy's stacked kernel, the
    one np.linalg.lstsq calls for a single matrix, over all n at once (one LAPACK gelsd
    per system, without numpy's per-call overhead); without that kernel, a loop."""
    n, m, d = a.shape
    if _LSTSQ is None or n == 0 or m == 0:
        out = np.zeros((n, d))
        for k in range(n):
            out[k] = np.linalg.lstsq(a[k], b[k], rcond=rcond)[0] if m else 0.0
        return out

    def failed(*_: object) -> None:
        raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")

    with np.errstate(call=failed, invalid="call", over="ignore", divide="ignore",
                     under="ignore"):
        x, *_ = _LSTSQ(np.asarray(a, dtype=np.float64),
                       np.asarray(b, dtype=np.float64)[..., None], rcond,
                       signature="ddd->ddid")
    return np.array(x[..., 0], dtype=np.float64)


def force_estimate(
    r: np.ndarray, q: np.ndarray, link: int, chain_index: Sequence[int],
    jacobian: JacobianFn, max_samples: int | None = None,
) -> ForceEstimate:
    """Peak contact-force magnitude at the end of ``link`` over an incident (module doc).

    Args:
        r: (n, J) residual over the incident (detected joints) [N·m].
        q: (n, J_chain) positions in chain order (joints not logged held at 0) [rad].
        link: the isolated link (1-based, chain order).
        chain_index: (J,) chain position of each detected joint.
        jacobian: :data:`JacobianFn`.
        max_samples: solve at most this many of the strong samples, evenly spread (a
            lasting load's hours of samples); None: every one.
    """
    cols = {c: k for k, c in enumerate(chain_index)}
    use = [c for c in range(1, link + 1) if c in cols]  # joints 1..i that are detected
    if not use:
        return ForceEstimate(None, "no residual of the joints up to the isolated link")
    best = 0.0
    method = ""
    levers: dict[int, float] = {}
    sel = [cols[c] for c in use]
    size = np.linalg.norm(r[:, sel], axis=1)
    strong = (np.flatnonzero(size >= STRONG_FRACTION * size.max()) if size.max() > 0
              else np.zeros(0, dtype=np.int64))
    if max_samples is not None and strong.size > max_samples:
        strong = strong[np.linspace(0, strong.size - 1, max_samples).round().astype(np.int64)]
    in_jac = [c - 1 for c in use]
    one_equation = len(use) == 1 and link == 1
    rows = 0  # the Jacobian's: 2 planar, 3 spatial
    if strong.size:
        many = getattr(jacobian, "many", None)  # every strong sample's at once, when it can
        jacs = many(q[strong], link) if many is not None else None
        if jacs is None:
            each = [jacobian(q[n], link) for n in strong]
            if any(j is None for j in each):
                return ForceEstimate(None, "no Jacobian for this link")
            jacs = np.stack([j for j in each if j is not None])
        rows = jacs.shape[1]
        a = jacs[:, :, in_jac].transpose(0, 2, 1)  # (n, m, d): r_m = a F at each sample
        b = r[strong][:, sel]
        sols = None if one_equation else lstsq_many(a, b, RCOND)
        if one_equation and not np.any(np.linalg.norm(jacs[:, :, 0], axis=1) >= MIN_LEVER_M):
            return ForceEstimate(None, "link 1 ends on joint 1's axis: no force at its end "
                                       "turns joint 1 (its residual is the answer, in N·m)")
        for k in range(strong.size):
            if sols is None:
                lever = float(np.linalg.norm(jacs[k][:, 0]))
                f = abs(float(b[k, 0])) / lever if lever >= MIN_LEVER_M else 0.0
            else:
                f = float(np.linalg.norm(sols[k]))
            arms = np.linalg.norm(a[k], axis=1)
            levers = {c: max(levers.get(c, 0.0), float(x))
                      for c, x in zip(use, arms, strict=True)}
            best = max(best, f)
    if strong.size and one_equation:
        method = "force normal to link 1 at its end, from joint 1's residual (one equation)"
    elif strong.size:
        method = (f"force at the end of link {link} explaining the residuals of joints "
                  f"{', '.join(str(c) for c in use)} (least squares through the Jacobian"
                  + (", minimum norm" if len(use) < rows else "") + ")")
        if rows == 2 and len(use) > rows and sols is not None:  # a planar arm with more
            # torques than the force has parts: does one force at the link's end give them?
            # Judged on the full-rank solve (the truncated one leaves out what lies along
            # the small singular values: an end force there reads as unexplained)
            fit = np.einsum("nmd,nd->nm", a, lstsq_many(a, b, 1e-10))
            total = float(np.sum(b * b))
            share = 1.0 - float(np.sum((b - fit) ** 2)) / total if total > 0 else 1.0
            if share < FIT_SHARE:
                return ForceEstimate(None, (
                    f"{NO_SINGLE_FORCE} {link} gives the residuals: the force there that "
                    f"best explains joints {', '.join(str(c) for c in use)} accounts for "
                    f"{100 * max(share, 0.0):.0f} % of their torque — the model's own "
                    "error, or a contact elsewhere"), levers)
    return ForceEstimate(best, method, levers)


def estimate_force(
    r: np.ndarray, q: np.ndarray, link: int, chain_index: Sequence[int],
    jacobian: JacobianFn,
) -> tuple[float | None, str]:
    """(force [N] or None, force_method): :func:`force_estimate`'s magnitude and method."""
    est = force_estimate(r, q, link, chain_index, jacobian)
    return est.force_n, est.method


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


def own_lever(jac: np.ndarray, i: int) -> float:
    """|J_i|: joint i's lever arm to the end of link i [m], from that link's (rows, i)
    Jacobian ``jac`` (the distance from joint i to the link's end in a planar arm)."""
    return float(np.linalg.norm(jac[:, i - 1]))


def own_levers(postures: np.ndarray, n_links: int, jacobian: JacobianFn) -> np.ndarray:
    """(P, n_links) :func:`own_lever` of every link at each of the (P, J_chain) postures,
    NaN where the link has no Jacobian or no lever (below :data:`MIN_LEVER_M`): what
    :func:`smallest_caught_force`'s ``own_force_n`` divides by, the same bits. Each
    link's Jacobians come at once when ``jacobian`` has a ``many``."""
    out = np.full((len(postures), n_links), np.nan)
    for i in range(1, n_links + 1):
        for p, jac in enumerate(link_jacobians(postures, i, jacobian)):
            if jac is None:
                continue
            lever = own_lever(jac, i)
            if lever >= MIN_LEVER_M:
                out[p, i - 1] = lever
    return out


def link_jacobians(postures: np.ndarray, i: int, jacobian: JacobianFn,
                   ) -> Sequence[np.ndarray | None]:
    """Link i's end-point Jacobian at each of the (P, J_chain) postures (None where the
    link has none), all at once when ``jacobian`` has a ``many``."""
    many = getattr(jacobian, "many", None)
    jacs = many(postures, i) if many is not None and len(postures) else None
    return [jacobian(p, i) for p in postures] if jacs is None else list(jacs)


def smallest_caught_force(
    vl: Sequence[float | None], q: np.ndarray, jacobian: JacobianFn,
) -> list[dict[str, Any]]:
    """Per link i (1-based, chain order), the smallest *static* force at the end of link i
    that the static-loading thresholds catch at posture ``q`` (what an audit could not see).

    The force is taken along n_i = J_i / |J_i| (J_i: joint i's column of the Jacobian of
    the end of link i) — normal to the link in a planar arm, the direction that turns
    joint i most in general. It gives joint k <= i the torque tau_k = (J_k · n_i) F, and
    the low-passed residual of a static load settles at tau_k, so joint k's static-loading
    detector fires once |tau_k| >= vL_k. Joint i's own lever arm |J_i| is the distance from
    joint i to the end of link i (the link length in a planar arm, whatever the posture):
    ``own_force_n`` = vL_i / |J_i| is the force that reaches joint i's threshold — the one
    the incident would be isolated to link i by. ``any_force_n`` is the smallest over
    k <= i (a proximal joint may fire first: an alarm, isolated to an inner link). A
    contact nearer joint i than the link's end needs more force, by the lever-arm ratio.

    Args:
        vl: (J_chain,) each chain joint's static-loading threshold vL [N·m]; None for a
            joint not detected (left out of detection, or not logged).
        q: (J_chain,) the posture [rad], chain order.
        jacobian: :data:`JacobianFn`.
    Returns:
        One mapping per link: ``link``, ``lever_m`` (|J_i|, None without a Jacobian),
        ``own_force_n`` (None when joint i is not detected), ``any_force_n`` and
        ``any_joint`` (the 1-based chain position giving it; None when no joint 1..i is).
    """
    out: list[dict[str, Any]] = []
    for i in range(1, len(vl) + 1):
        row: dict[str, Any] = {"link": i, "lever_m": None, "own_force_n": None,
                               "any_force_n": None, "any_joint": None}
        jac = jacobian(np.asarray(q, dtype=np.float64), i)
        if jac is None:
            out.append(row)
            continue
        lever = own_lever(jac, i)
        row["lever_m"] = lever
        if lever < MIN_LEVER_M:
            out.append(row)
            continue
        n = jac[:, i - 1] / lever
        own = vl[i - 1]
        if own is not None:
            row["own_force_n"] = float(own) / lever
        for k in range(1, i + 1):
            v = vl[k - 1]
            arm = abs(float(jac[:, k - 1] @ n))
            if v is None or arm <= 1e-12 * lever:
                continue
            f = float(v) / arm
            if row["any_force_n"] is None or f < row["any_force_n"]:
                row["any_force_n"], row["any_joint"] = f, k
        out.append(row)
    return out
