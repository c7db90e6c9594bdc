"""Incidents: one per physical contact — when, where, how hard, what kind (formats.md,
"Detection timeline", ``incidents``).

**When.** The product's detectors (adaptive, static_loading) fire per joint and per burst;
one contact gives several events (the adaptive detector at the onset and the release,
static_loading while it presses). Every product event belongs to exactly one incident:
events that overlap, or follow each other within ``events.merge_gap_s``, form one
(:func:`group_events`). An incident starts at its first product alarm.

**Where — isolation.** A contact on link i exerts torque on joints 1..i only (the
Jacobian of a point on link i has zero columns beyond i, paper eq. 8 context: r = J_c^T F);
this holds for the joint-space residual of any generator. So the incident's link is the
most distal joint whose residual is *significant* during the incident
(:func:`isolate`): a joint is significant when its static-loading statistic |LP(r)| reaches
:data:`SIGNIFICANT_FRACTION` of its own threshold vL, or its adaptive decision fired —
i.e. that joint's own detectors fired, measured against its own noise through its
calibrated threshold. Links are
numbered from the base along the robot's own chain (a joint left out of detection keeps
its number and can never be significant); ``None`` when no joint is significant.

**How hard — identification.** With kinematics, the contact force from the residual
through the Jacobian of the isolated link: r_{1..i} = J_{1..i}(q)^T F. The contact point
along the link is unknown; the tool assumes the link's *end* (the next joint, or the tool
for the last link) and takes the force F there — a 2-D force in the plane (planar arms), a
3-D force (URDF) — that best explains the residuals of joints 1..i in least squares (the
minimum-norm one when joints are fewer than the force's components). On link 1 that is one
equation: the force normal to the link at its end, |F| = |r_1| / L_1. ``force_n`` is the
largest |F| over the samples where those residuals are at least half their peak (the
Jacobian's singular values below a tenth of its largest are dropped: near a singular
posture the unobservable part of the force is left out, not blown up); ``force_method``
says which of these was used. A contact
nearer the joint than the link's end is *under*-estimated by the lever-arm ratio. Without
kinematics ``force_n`` is None and the peak residual torques are the answer.

**What kind — contact type** (ISO/TS 15066: *transient*, a collision the body can recoil
from, vs *quasi-static*, clamping or pinching against a constraint; the paper's Fig. 10
distinction between impacts and slow loading) — :func:`contact_type`: quasi-static when the
arm kept pressing while it stood (nearly) still: the isolated link's joints moved less than
:data:`STILL_RAD_S` for at least :data:`QS_MIN_STILL_S` while the static-loading statistic
stayed above its threshold; transient when the pressing lasted less than
:data:`TRANSIENT_MAX_S`; ``unknown`` in between.

Pure functions of arrays; :func:`impactcli.pipeline.analyze` applies them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..types import Event

#: The product's detectors (what incidents are made of).
PRODUCT_DETECTORS: tuple[str, ...] = ("adaptive", "static_loading")
#: A joint is significant in an incident when |LP(r)| reaches this fraction of its vL —
#: 1: when its own static-loading detector fired. (On the ASSIST-like sample logs, pushes on
#: link 1 lift the elbow's statistic to 0.18–0.85 × its vL by dynamic coupling; contacts
#: on link 2 to ≥ 3.7 ×.)
SIGNIFICANT_FRACTION = 1.0
#: The force is estimated at the samples where the residuals of joints 1..i reach at least
#: this fraction of their peak (a near-singular posture while the residual is small must
#: not make a large force out of noise).
STRONG_FRACTION = 0.5
#: Singular values of the Jacobian below this fraction of the largest are dropped (the
#: force along those directions cannot be seen in the joint torques: the minimum-norm
#: solution leaves it out, an under-estimate rather than a blow-up near singularities).
RCOND = 0.1
#: Contact type: a joint stands still below this speed [rad/s] ...
STILL_RAD_S = 0.05
#: ... and pressing while still for at least this long makes the contact quasi-static [s];
QS_MIN_STILL_S = 0.5
#: pressing (static_loading above its threshold) for less than this is transient [s].
TRANSIENT_MAX_S = 2.5


@dataclass(frozen=True)
class Incident:
    """One physical contact as the product sees it (formats.md ``incidents`` item)."""

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

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (timeline ``incidents`` item)."""
        return {
            "t_start": self.t_start, "t_end": self.t_end, "t_start_utc": self.t_start_utc,
            "detectors": list(self.detectors), "joints": list(self.joints), "link": self.link,
            "force_n": self.force_n, "force_method": self.force_method,
            "contact": self.contact, "peak_residual": dict(self.peak_residual),
            "in_warmup": self.in_warmup, "i_start": self.i_start, "i_end": self.i_end,
            "events": list(self.events),
        }


def group_events(events: Sequence[Event], merge_gap_s: float) -> list[list[int]]:
    """Indices into ``events`` of the product events of each incident, in time order.

    Events of the product's detectors that overlap or follow each other within
    ``merge_gap_s`` (from one's end to the next's start) form one incident; every product
    event is in exactly one group.
    """
    idx = sorted((k for k, e in enumerate(events) if e.detector in PRODUCT_DETECTORS),
                 key=lambda k: (events[k].t_start, events[k].t_end))
    groups: list[list[int]] = []
    end = -np.inf
    for k in idx:
        e = events[k]
        if groups and e.t_start <= end + merge_gap_s + 1e-9:
            groups[-1].append(k)
            end = max(end, e.t_end)
        else:
            groups.append([k])
            end = e.t_end
    return groups


def isolate(
    loading_ratio: np.ndarray, adaptive_fired: np.ndarray, chain_index: Sequence[int],
) -> int | None:
    """The 1-based link of a contact: the most distal significant joint (module doc).

    Args:
        loading_ratio: (n, J) |LP(r)| / vL over the incident.
        adaptive_fired: (n, J) the adaptive decision over the incident.
        chain_index: (J,) each detected joint's 1-based position in the robot's chain.
    """
    sig = (np.max(loading_ratio, axis=0) >= SIGNIFICANT_FRACTION) | np.any(adaptive_fired,
                                                                           axis=0)
    if not sig.any():
        return None
    return int(max(chain_index[int(j)] for j in np.flatnonzero(sig)))


#: A function giving, for a posture q (chain order, (J_chain,)) and a 1-based link i, the
#: (d, i) Jacobian of the point at that link's end (d = 2 planar, 3 spatial), or None.
JacobianFn = Callable[[np.ndarray, int], np.ndarray | None]


def planar_jacobian(link_lengths: Sequence[float]) -> JacobianFn:
    """(2, i) Jacobian of the end of link i of a planar serial arm (formats.md: the first
    angle from the horizontal, each next one relative to the previous link)."""
    ll = np.asarray(link_lengths, dtype=np.float64)

    def jac(q: np.ndarray, i: int) -> np.ndarray | None:
        if i < 1 or i > len(ll):
            return None
        phi = np.cumsum(q[:i])
        pts = np.zeros((i + 1, 2))
        for k in range(i):
            pts[k + 1] = pts[k] + ll[k] * np.array([np.cos(phi[k]), np.sin(phi[k])])
        tip = pts[i]
        d = tip[None, :] - pts[:i]  # from each joint to the point
        return np.stack([-d[:, 1], d[:, 0]])  # z × d: (2, i)

    return jac


def estimate_force(
    r: np.ndarray, q: np.ndarray, link: int, chain_index: Sequence[int],
    jacobian: JacobianFn,
) -> tuple[float | None, str]:
    """Peak contact-force magnitude at the end of ``link`` over an incident (module doc).

    Args:
        r: (n, J) residual over the incident (detected joints) [N·m].
        q: (n, J_chain) positions in chain order (joints not logged held at 0) [rad].
        link: the isolated link (1-based, chain order).
        chain_index: (J,) chain position of each detected joint.
        jacobian: :data:`JacobianFn`.
    Returns:
        (force [N] or None, force_method).
    """
    cols = {c: k for k, c in enumerate(chain_index)}
    use = [c for c in range(1, link + 1) if c in cols]  # joints 1..i that are detected
    if not use:
        return None, "no residual of the joints up to the isolated link"
    best = 0.0
    method = ""
    sel = [cols[c] for c in use]
    size = np.linalg.norm(r[:, sel], axis=1)
    strong = (np.flatnonzero(size >= STRONG_FRACTION * size.max()) if size.max() > 0
              else np.zeros(0, dtype=np.int64))
    for n in strong:
        jac = jacobian(q[n], link)
        if jac is None:
            return None, "no Jacobian for this link"
        a = jac[:, [c - 1 for c in use]].T  # (m, d): r_m = a F
        b = r[n, [cols[c] for c in use]]
        if len(use) == 1 and link == 1:
            lever = float(np.linalg.norm(jac[:, 0]))
            f = abs(float(b[0])) / lever if lever > 0 else 0.0
            method = ("force normal to link 1 at its end, from joint 1's residual (one "
                      "equation)")
        else:
            sol, *_ = np.linalg.lstsq(a, b, rcond=RCOND)
            f = float(np.linalg.norm(sol))
            method = (f"force at the end of link {link} explaining the residuals of joints "
                      f"{', '.join(str(c) for c in use)} (least squares through the Jacobian"
                      + (", minimum norm" if len(use) < a.shape[1] else "") + ")")
        best = max(best, f)
    return best, method


def contact_type(
    loading_on: np.ndarray, speed: np.ndarray, dt: float,
) -> str:
    """``transient``, ``quasi_static`` or ``unknown`` (module doc).

    Args:
        loading_on: (n,) static_loading above threshold on some joint, over the incident.
        speed: (n,) largest |q'| of the isolated link's joints [rad/s].
        dt: sample period [s].
    """
    pressing = float(np.sum(loading_on)) * dt
    still_pressing = float(np.sum(loading_on & (speed < STILL_RAD_S))) * dt
    if still_pressing >= QS_MIN_STILL_S:
        return "quasi_static"
    if pressing < TRANSIENT_MAX_S:
        return "transient"
    return "unknown"
