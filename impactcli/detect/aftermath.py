"""A contact's aftermath: alarms while the arm had not settled after an incident.

A contact does not end when its force does. A 30 N push on a compliant simulated arm sets it
ringing for seconds under a calm reference: its tracking error swings to 0.19 rad against
0.10 in the calibration logs, its measured shoulder acceleration to −13.5 rad/s² against
−3.89 … 3.65. Each
velocity reversal of the ringing turns the model's friction (its smooth sign, docs/method.md
§2) faster than the calibration's motion ever did, and the static-loading detector fired on
four of them, 1.0–2.1 s after the push began, as 3–5 N "contacts" at a 0.39 s rhythm
(docs/incidents.md, "A contact's aftermath"). The reference's motion, which the motion
envelope reads (:mod:`impactcli.detect.envelope`), stayed inside the calibrated ranges, so
nothing told them from new contacts.

The measured motion tells. Where the logs have a reference, ``calibrate`` records the ranges
of the measured velocity and acceleration too, and ``detect`` keeps the stretches where the
measured motion left them while the joint's reference motion stayed inside its own
(:class:`MeasuredStretch`; a motion commanded beyond the calibration's is the envelope's
finding, not an arm that did not settle). Those stretches are not "outside the
calibrated motion" in the envelope's sense — a contact itself throws the measured motion out
of its ranges, by construction — but they date the disturbance a contact leaves:

- stretches closer than the detectors' settling time (``settle_s``: the static-loading
  low-pass's five time constants plus the adaptive threshold's RMS window, 0.56 s with the
  defaults; :func:`impactcli.detect.incidents.settle_s`) form one *unsettled span*: the
  detectors still show one when the next begins;
- a span is an incident's when it begins while that incident is on (from
  :data:`LEAD_S` before its start to its end): the contact threw the arm out — but not an
  incident that begins at the log's first sample (``i_start`` 0, in the warm-up): that is
  the filters starting, not a contact (on a simulated heavy arm whose triangle corners
  threw the measured acceleration out every 0.54 s, 14 false incidents were called "the
  aftermath of the incident at 0.000 s");
- an incident that starts after that incident ended, while the span lasts or within
  ``settle_s`` after it, is in the first one's *aftermath*;
- so is one that starts within ``settle_s`` after the end of an incident already in that
  aftermath, when it is no stronger than the first one (its force no larger where both are
  known, else its peak residual no larger on any joint it alarmed on): the detectors still
  showed the ringing that raised the one before (``follows``: its number).
  A trial's 30 N push rang as five alarms 0.38 s apart; the measured motion was back in
  its ranges before the last, which read as a new 12 N contact.

Where the measured motion never left its ranges — a calibration whose measured motion was
wide (point-to-point moves beside a pick-and-place), or one without measured ranges — a
ringing arm still raises alarms in a chain: a 30 N push on a compliant arm carrying 1 kg
rang as five static-loading alarms of 3.6 → 1.8 N, 0.11–0.28 s apart, after the push's own
(a trial's robot seed 53; on its robot seed 91 the same chain was marked by the measured
motion). So an incident that starts within ``settle_s`` after the end of a counted one,
no stronger than the first of the chain, is *close behind* it (:func:`close_behind`): the
same caveat on the timing's evidence alone, said as such.

The mark is a caveat, not a verdict: the incident stays counted and gated — a second blow
while the arm rings is a contact too — but its row says that the arm had not settled, with
the measured quantity that had left its range, so a 3 N "contact" half a second after a
30 N one reads as what it most likely is. Pure functions; :mod:`impactcli.run.one_log`
applies them once every incident is known (a note on the answer, not part of the online
replay).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["LEAD_S", "MeasuredStretch", "PeakRuns", "aftermath_of", "aftermath_text",
           "close_behind", "mark_aftermath", "ringing_text", "runs"]

#: A span is an incident's when it begins from this long before the incident's start (the
#: residual's filters lag the motion, as :data:`impactcli.detect.envelope.LEAD_S`) [s].
LEAD_S = 0.2


def runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and last index of each run of True in (n,) ``mask``."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        z = np.zeros(0, dtype=np.int64)
        return z, z
    brk = np.flatnonzero(np.diff(idx) > 1)
    return (np.concatenate([idx[:1], idx[brk + 1]]), np.concatenate([idx[brk], idx[-1:]]))


@dataclass(frozen=True)
class MeasuredStretch:
    """A stretch [s] where the measured motion left the calibration's measured ranges, and
    its farthest sample: ``joint``'s ``quantity`` (``measured_velocity`` or
    ``measured_acceleration``) reached ``value`` against the calibrated [``lo``, ``hi``]
    (rad/s, rad/s²)."""

    t_start: float
    t_end: float
    joint: str
    quantity: str
    value: float
    lo: float
    hi: float

    @property
    def score(self) -> float:
        """How far out ``value`` lay, as a share of the range's width (0 inside)."""
        width = self.hi - self.lo if self.hi > self.lo else 1.0
        return max(self.value - self.hi, self.lo - self.value, 0.0) / width

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready mapping (a timeline's ``motion_envelope.measured_stretches`` item)."""
        return {"t_start": self.t_start, "t_end": self.t_end, "joint": self.joint,
                "quantity": self.quantity, "value": self.value,
                "calibrated": [self.lo, self.hi]}

    @classmethod
    def from_dict(cls, d: Any) -> MeasuredStretch:
        """The stretch of :meth:`to_dict`'s mapping."""
        lo, hi = (float(x) for x in d["calibrated"])
        return cls(float(d["t_start"]), float(d["t_end"]), str(d["joint"]),
                   str(d["quantity"]), float(d["value"]), lo, hi)

    def text(self) -> str:
        """``measured shoulder acceleration -13.5 rad/s² (calibration logs: -3.89 … 3.65)``."""
        what, unit = (("velocity", "rad/s") if self.quantity.endswith("velocity")
                      else ("acceleration", "rad/s²"))
        return (f"measured {self.joint} {what} {self.value:.3g} {unit} (calibration logs: "
                f"{self.lo:.3g} … {self.hi:.3g})")


class PeakRuns:
    """Runs of outside samples as [t_first, t_last] with their farthest sample's (score,
    column, quantity, value), joined across chunk boundaries and over ``merge_s`` [s]."""

    def __init__(self, merge_s: float) -> None:
        self.merge_s = float(merge_s)
        self.runs: list[list[Any]] = []   # [t0, t1, score, col, quantity, value]
        self.end = -1                      # the last run's end index (exclusive)

    def add(self, k0: int, t: np.ndarray, score: np.ndarray, col: np.ndarray,
            quantity: np.ndarray, value: np.ndarray) -> None:
        """Samples ``k0`` … of the log, (n,) each: a sample is outside where ``score`` > 0;
        its farthest quantity (an index) on column ``col`` reached ``value``."""
        for a, b in zip(*runs(score > 0), strict=True):
            k = int(a) + int(np.argmax(score[a:b + 1]))
            run = [float(t[a]), float(t[b]), float(score[k]), int(col[k]),
                   int(quantity[k]), float(value[k])]
            last = self.runs[-1] if self.runs else None
            if last is not None and (self.end == k0 + int(a)
                                     or run[0] - last[1] <= self.merge_s + 1e-9):
                last[1] = run[1]
                if run[2] > last[2]:
                    last[2:] = run[2:]
            else:
                self.runs.append(run)
            self.end = k0 + int(b) + 1


def _spans(stretches: Sequence[MeasuredStretch], settle_s: float
           ) -> list[list[MeasuredStretch]]:
    """The stretches, in time order, grouped into unsettled spans (gaps ≤ ``settle_s``)."""
    out: list[list[MeasuredStretch]] = []
    for s in sorted(stretches, key=lambda x: x.t_start):
        if out and s.t_start - out[-1][-1].t_end <= settle_s + 1e-9:
            out[-1].append(s)
        else:
            out.append([s])
    return out


def aftermath_of(incidents: Sequence[Any], stretches: Sequence[MeasuredStretch],
                 settle_s: float) -> list[dict[str, Any] | None]:
    """Per incident (anything with ``t_start``, ``t_end`` [s] and ``number``; ``i_start``
    when known), the incident whose aftermath it starts in (module docstring), or None.

    Each mark is a mapping: ``incident`` (the first incident's number, None when it has none:
    in warm-up, at a data defect, a payload change), ``t_start`` of that incident [s],
    ``until_s`` (the span's last sample outside), and the farthest measured stretch of the
    span up to the incident's end (``measured``, :meth:`MeasuredStretch.to_dict`)."""
    spans = _spans(stretches, settle_s)
    order = sorted(range(len(incidents)), key=lambda k: (float(incidents[k].t_start),
                                                         float(incidents[k].t_end)))
    out: list[dict[str, Any] | None] = [None] * len(incidents)
    for span in spans:
        s0, s1 = span[0].t_start, span[-1].t_end
        cause = next((k for k in order if float(incidents[k].t_start) - LEAD_S <= s0
                      <= float(incidents[k].t_end)
                      and getattr(incidents[k], "i_start", None) != 0), None)
        if cause is None:
            continue
        p = incidents[cause]
        marked: list[int] = []
        for k in order:
            t0 = float(incidents[k].t_start)
            if k == cause or t0 <= float(p.t_end):
                continue
            if t0 <= s1 + settle_s:
                seen = [s for s in span if s.t_start <= float(incidents[k].t_end)]
                out[k] = {"incident": p.number, "t_start": float(p.t_start), "until_s": s1,
                          "measured": max(seen, key=lambda s: s.score).to_dict()}
                marked.append(k)
                continue
            before = [j for j in marked if float(incidents[j].t_start) < t0]
            last = max(before, key=lambda j: float(incidents[j].t_end), default=None)
            if (last is None or t0 - float(incidents[last].t_end) > settle_s + 1e-9
                    or not _no_larger(incidents[k], p)):  # (a ring still on: gap < 0)
                break  # the chain ends: a later alarm is a contact again
            prev = out[last]
            assert prev is not None
            out[k] = {**prev, "follows": incidents[last].number}
            marked.append(k)
    return out


def _no_larger(inc: Any, cause: Any) -> bool:
    """Whether ``inc`` is no stronger than ``cause``: its force no larger where both forces
    are known (:func:`_by_force`), else its peak residual no larger on any joint it alarmed
    on (a joint ``cause`` did not alarm on counts as larger)."""
    if _by_force(inc, cause):
        return float(inc.force_n) <= float(cause.force_n)
    mine = getattr(inc, "peak_residual", None) or {}
    theirs = getattr(cause, "peak_residual", None) or {}
    return bool(mine) and all(abs(float(v)) <= abs(float(theirs.get(j, 0.0)))
                              for j, v in mine.items())


def _by_force(inc: Any, cause: Any) -> bool:
    """Whether both incidents' forces are known (else their residuals are compared)."""
    return (getattr(inc, "force_n", None) is not None
            and getattr(cause, "force_n", None) is not None)


def aftermath_text(mark: dict[str, Any]) -> str:
    """The incident row's caveat for a mark of :func:`aftermath_of`."""
    who = (f"incident {mark['incident']}" if mark.get("incident") is not None
           else "the incident")
    far = MeasuredStretch.from_dict(mark["measured"])
    after = ("an earlier alarm" if mark.get("follows") is None
             else f"incident {mark['follows']}")
    then = ("" if "follows" not in mark else
            f"; it follows {after}, itself in that aftermath, within the detectors' settling "
            "time")
    return (f"in the aftermath of {who} at {float(mark['t_start']):.3f} s: the arm had not "
            f"settled ({far.text()}, out until {float(mark['until_s']):.3f} s){then}, so this "
            "alarm may be its ringing, not a new contact")


def mark_aftermath(incidents: Sequence[Any], stretches: Sequence[MeasuredStretch],
                   settle_s: float) -> list[Any]:
    """The incidents (frozen dataclasses with an ``aftermath`` field), each in an earlier
    one's aftermath marked with :func:`aftermath_of`'s mapping and its ``text``."""
    from dataclasses import replace

    marks = aftermath_of(incidents, stretches, settle_s)
    return [i if m is None else replace(i, aftermath={**m, "text": aftermath_text(m)})
            for i, m in zip(incidents, marks, strict=True)]


def close_behind(incidents: Sequence[Any], settle_s: float, measured_checked: bool
                 ) -> list[Any]:
    """The incidents, each counted one (``number`` set) without an ``aftermath`` mark that
    starts within ``settle_s`` after the end of the counted one before it, its force no larger
    than the first of that chain's (where a force is unknown: its peak residuals no larger),
    marked ``close_behind`` (module docstring): ``incident``
    (the chain's first: its number, ``t_start`` [s], ``force_n``), ``after`` (the one it
    follows: its number, ``gap_s`` from that one's end) and ``text``. An aftermath-marked
    incident, one not counted or a stronger one starts a chain anew (or none).
    ``measured_checked``: whether the measured motion was held against the calibration's
    ranges (the text says that it stayed inside them)."""
    from dataclasses import replace

    order = sorted(range(len(incidents)), key=lambda k: (float(incidents[k].t_start),
                                                         float(incidents[k].t_end)))
    out = list(incidents)
    head = prev = None
    for k in order:
        inc = incidents[k]
        if inc.number is None or getattr(inc, "aftermath", None) is not None:
            head = prev = None
            continue
        gap: float | None = None if prev is None else float(inc.t_start) - float(prev.t_end)
        if (head is None or prev is None or gap is None or not 0 < gap <= settle_s + 1e-9
                or not _no_larger(inc, head)):
            head = prev = inc
            continue
        mark = {"incident": head.number, "t_start": float(head.t_start),
                "force_n": getattr(head, "force_n", None), "after": prev.number,
                "gap_s": gap, "settle_s": float(settle_s)}
        out[k] = replace(inc, close_behind={**mark, "text": _close_text(
            mark, measured_checked, by_force=_by_force(inc, head))})
        prev = inc
    return out


def _close_text(mark: dict[str, Any], measured_checked: bool, *, by_force: bool = True) -> str:
    """The incident row's caveat for a :func:`close_behind` mark (``by_force``: both forces
    known, else its peak residuals were compared)."""
    f = mark.get("force_n")
    first = (f"incident {mark['incident']} ("
             + ("" if f is None else f"{float(f):.3g} N ") + f"at {mark['t_start']:.3f} s)")
    via = ("that alarm" if mark["after"] == mark["incident"]
           else f"incident {mark['after']}, itself close behind it,")
    why = ("the measured motion stayed within the calibration's ranges, so only the timing "
           "tells" if measured_checked else "the measured motion was not held against the "
           "calibration's ranges, so only the timing tells")
    return (f"close behind {first}: it began {mark['gap_s']:.3f} s after {via} ended, "
            f"within the detectors' settling time ({mark['settle_s']:.2f} s), and is no "
            + ("stronger" if by_force else "stronger (its peak residual no larger on any "
               "joint: the forces are not both known)")
            + f", so this alarm may be that contact's ringing, not a new contact ({why})")


def ringing_text(inc: Any) -> str | None:
    """An incident's (an Incident or its timeline mapping) maybe-ringing caveat: its
    ``aftermath`` or ``close_behind`` text, or None."""
    get = inc.get if isinstance(inc, dict) else (lambda key: getattr(inc, key, None))
    for key in ("aftermath", "close_behind"):
        mark = get(key)
        if mark:
            return str(mark["text"]) if isinstance(mark, dict) else str(mark)
    return None
