"""How hard: the force at the isolated link's end (docs/incidents.md, "The rules").

A contact on link i exerts the torques r = J_cᵀ F on joints 1..i (the Jacobian of the contact
point, eq. 3's external torque). The force is estimated at the end of the link — the next
joint, or the tool for the last link — as the one that best explains the residuals of
joints 1..i through that point's Jacobian, in least squares (:func:`force_estimate`):

- Singular values of the Jacobian under :data:`RCOND` of the largest are dropped: near a
  singular posture the part of the force the joints barely feel is left out rather than
  blown up from noise. There, and wherever the joints give fewer torques than the force
  has parts (one equation on link 1, minimum norm on a spatial arm's first links), part of
  a force is not seen: the stated force leaves that part out (``force_at_least``,
  :func:`unseen_part`), printed "≳" (:func:`force_mark`) — at least about this: the
  projection is never longer than the true force, but the estimate it is made of errs as
  any (the filters, the model's own error: a new user's heavy-arm impacts read 14 of 15
  above their labelled force, median +34 %), so it is no strict lower bound.
- On a planar arm, where the joints give more torques than the force has parts and it
  accounts for less than :data:`FIT_SHARE` of them, no single force at the link's end gives
  the torques (the model's own error, or a contact elsewhere): no force is stated, and
  ``force_method`` says why.
- What the static-loading thresholds could see at all — the smallest static force at each
  link's end that reaches them — is :func:`smallest_caught_force`.

Pure functions of arrays.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

try:  # numpy's stacked least-squares kernel, behind np.linalg.lstsq (lstsq_many)
    from numpy.linalg import _umath_linalg
    _LSTSQ: Any = _umath_linalg.lstsq
except (ImportError, AttributeError):  # pragma: no cover - another numpy
    _LSTSQ = None

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
#: ... and when the model's torque passed what the joint exerted in the log, or swung where
#: the logged torque stayed (:func:`impactcli.detect.incident_builder.beyond_logged`).
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
#: How ``force_check`` begins when no force of the log can be trusted because its torque
#: scale is off the robot description's gravity torque (:mod:`impactcli.model.gravity`):
#: the force is not beyond what the arm exerts, it is in units the tool cannot check.
OFF_SCALE = "the log's torque is off the description's gravity torque"


def scale_untrusted(finding: Any) -> bool:
    """Whether a finding's force (an incident's or lasting load's, or its timeline mapping)
    is one no one can trust because the log's torque scale is off (:data:`OFF_SCALE`)."""
    check = (finding.get("force_check") if isinstance(finding, dict)
             else getattr(finding, "force_check", ""))
    return str(check or "").startswith(OFF_SCALE)


#: The mark of a force that leaves out a part the joints do not feel: at least about this
#: (module docstring). Said under every table that shows one (:data:`AT_LEAST_TEXT`).
AT_LEAST = "≳"
#: What :data:`AT_LEAST` means, in the words every output gives it.
AT_LEAST_TEXT = ("≳: the joints up to the link do not feel part of that force (on link 1, "
                 "near a singular posture, a spatial arm's first links), so the force may be "
                 "larger; like every force here it is an estimate at the link's end that errs "
                 "both ways, not a bound (on simulated arms' contacts 0.34–1.7× the true "
                 "force: docs/incidents.md)")


def force_mark(x: Any) -> str:
    """:data:`AT_LEAST` before a force that leaves out a part the joints do not feel
    (``force_at_least`` of a timeline item or of an incident or lasting load,
    :func:`unseen_part`), ``~`` before an estimate."""
    at_least = (x.get("force_at_least") if isinstance(x, Mapping)
                else getattr(x, "force_at_least", False))
    return AT_LEAST if at_least else "~"


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
    it cannot be made), how, each joint's longest lever arm to the link's end over the
    samples solved (chain position → max |J_k| [m], joints 1..i that are detected), and
    why it is a lower bound (``at_least``, "" when it is not: at some sample solved, part of
    a force at the link's end turns none of those joints, or too little to be solved for —
    :func:`unseen_part`)."""

    force_n: float | None
    method: str
    levers: dict[int, float] = field(default_factory=dict)
    at_least: str = ""
    peak_n: float | None = None  # with ``typical``: the peak beside the median

    @property
    def stated(self) -> str:
        """``force_method`` as the timeline states it: how, and why it is a lower bound."""
        return self.method + self.at_least


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


def unseen_part(a: np.ndarray) -> np.ndarray:
    """(n,) bool: at which of the n samples part of a force at the link's end is not seen
    in the joints' torques r = a F ((n, m, d) ``a``, the Jacobian's transpose over joints
    1..i): fewer independent torques than the force has parts — one joint for a planar
    force, two for a spatial one (the force's part along the null space turns none of
    them) — or a singular value below :data:`RCOND` × the largest (near a singular posture:
    the solve drops that part rather than blow noise up). There the stated force is the
    force projected onto what the joints feel, never longer than it: a lower bound (where
    the residual is the contact's torque and the contact is at or inside the link's end)."""
    n, m, d = a.shape
    if n == 0:
        return np.zeros(0, dtype=bool)
    if m < d:
        return np.ones(n, dtype=bool)
    sv = np.linalg.svd(a, compute_uv=False)  # (n, d), descending
    return np.asarray(np.any(sv < RCOND * sv[:, :1], axis=1))


def force_estimate(
    r: np.ndarray, q: np.ndarray, link: int, chain_index: Sequence[int],
    jacobian: JacobianFn, max_samples: int | None = None, typical: bool = False,
) -> ForceEstimate:
    """Peak contact-force magnitude at the end of ``link`` over an incident (module doc);
    with ``typical``, the median over every sample (a lasting load's own level: a trial's
    1 kg load held 20 s read "≳29 N", the peak of a 30 N push inside its span).

    Args:
        r: (n, J) residual over the incident (detected joints) [N·m].
        q: (n, J_chain) positions in chain order (joints not logged held at 0) [rad].
        link: the isolated link (1-based, chain order).
        chain_index: (J,) chain position of each detected joint.
        jacobian: :data:`JacobianFn`.
        max_samples: solve at most this many of the strong samples, evenly spread (a
            lasting load's hours of samples); None: every one.
        typical: the median force over all the samples (spread as above), not the peak
            over the strong ones.
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
    strong = (np.flatnonzero(size >= (0.0 if typical else STRONG_FRACTION) * size.max())
              if size.max() > 0 else np.zeros(0, dtype=np.int64))
    each_f: list[float] = []
    if max_samples is not None and strong.size > max_samples:
        strong = strong[np.linspace(0, strong.size - 1, max_samples).round().astype(np.int64)]
    in_jac = [c - 1 for c in use]
    one_equation = len(use) == 1 and link == 1
    rows = 0  # the Jacobian's: 2 planar, 3 spatial
    unseen = np.zeros(0, dtype=bool)  # per sample solved: part of the force not seen
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
            each_f.append(f)
        unseen = unseen_part(a)
        if typical:
            best = float(np.median(each_f))
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
    if strong.size and typical:
        method += (f", its median over the span (the load's own level; at its peak "
                   f"{max(each_f):.3g} N: a contact during it, or the load's motion)")
    at_least = ""
    if unseen.any():
        joints = (f"joint {use[0]}" if len(use) == 1
                  else f"joints {', '.join(str(c) for c in use)}")
        at_least = (f" — it may be larger: a force's part that turns none of {joints} is not "
                    "seen" if len(use) < rows else
                    f" — it may be larger: near a singular posture at {int(unseen.sum())} of "
                    f"the {unseen.size} samples solved, the part of the force {joints} "
                    "barely feel is left out")
    return ForceEstimate(best, method, levers, at_least,
                         max(each_f) if typical and each_f else None)


def estimate_force(
    r: np.ndarray, q: np.ndarray, link: int, chain_index: Sequence[int],
    jacobian: JacobianFn,
) -> tuple[float | None, str]:
    """(force [N] or None, force_method): :func:`force_estimate`'s magnitude and method."""
    est = force_estimate(r, q, link, chain_index, jacobian)
    return est.force_n, est.stated


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
