"""From a replay's events and signals to incidents (:mod:`impactcli.detect.incidents`).

What an incident needs is fixed once per log (:class:`IncidentContext`: the robot's chain,
the link numbers of the detected joints, the link Jacobian, the static-loading thresholds,
the joints' torque capacity) and then read from the samples of the incident's own stretch:
the residual, the static-loading statistic, the decisions, the positions of the whole chain
and the joints' causal velocity. :func:`build_findings` takes those arrays for any stretch
of the log that holds whole incidents — one "island" of a replay (the samples near an alarm
or a pressing contact, :mod:`impactcli.run.one_log`) — with its offset in the log, and
gives its incidents and lasting loads.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import ImpactError, ImpactWarning
from ..types import Event, RobotDescription
from .force import (
    BEYOND_LOGGED,
    FORCE_CEILING_FACTOR,
    MIN_LEVER_M,
    ForceEstimate,
    JacobianFn,
    force_estimate,
    planar_jacobian,
)
from .incidents import BRIDGE_FRACTION, Incident, LastingLoad, contact_type, group_events, lasting
from .link_evidence import LinkDecision, decide_link

#: A lasting load's force is solved at this many of its samples at most (evenly spread).
LASTING_FORCE_SAMPLES = 500


def robot_chain(full_joints: tuple[str, ...], robot: RobotDescription | None,
                model: dict[str, Any] | None, detected: tuple[str, ...] = (),
                ) -> tuple[tuple[str, ...], dict[str, Any] | None]:
    """The robot's joint chain (base first) and its kinematics mapping: the robot
    description's (given, or the one the model was identified with), else the log's own
    joint order (``full_joints``) without kinematics. Link numbers are positions in this
    chain."""
    desc = robot.to_dict() if robot is not None else (model or {}).get("robot")
    kin = desc.get("kinematics") if isinstance(desc, dict) else None
    if isinstance(desc, dict) and desc.get("joints"):
        names = tuple(str(j["name"]) for j in desc["joints"])  # the log's names
        if set(detected) <= set(names):
            return names, kin
    if isinstance(kin, dict) and kin.get("type") == "urdf" and model is not None:
        return tuple(model["joint_names"]), kin  # a named robot: the model's chain
    return full_joints, None


def _urdf_jacobian(model: dict[str, Any], chain: tuple[str, ...]) -> Any:
    """The link-end Jacobian of a URDF model, taking positions in ``chain`` order."""
    from ..model.kinematics import urdf_link_end_jacobian

    mj = tuple(model["joint_names"])
    inner = urdf_link_end_jacobian(model["structure"], mj)
    pos = [chain.index(j) for j in mj]
    # the chain's link i ends at model joint i+1: the link index in the model's joints
    link_of = {c: sum(1 for p in pos if p < c) for c in range(1, len(chain) + 1)}

    def jac(q: np.ndarray, i: int) -> np.ndarray | None:
        k = link_of.get(i, 0)
        j = inner(q[pos], k) if k >= 1 else None
        if j is None:
            return None
        out = np.zeros((j.shape[0], i))
        for n in range(k):
            out[:, pos[n]] = j[:, n]
        return out

    return jac


def utc(t_ns: int) -> str | None:
    """ISO 8601 UTC of an epoch time [ns], or None when the clock is not an epoch (a log
    whose time starts near 0: before 1990)."""
    import datetime as _dt

    if t_ns < 631_152_000 * 10**9:
        return None
    return _dt.datetime.fromtimestamp(t_ns / 1e9, tz=_dt.UTC).isoformat(
        timespec="milliseconds").replace("+00:00", "Z")


@dataclass(frozen=True)
class IncidentContext:
    """What every incident of one log shares.

    Attributes:
        joints: the detected joints (the replay's order).
        index: (J,) each detected joint's 1-based link number in the robot's chain.
        chain_cols: per chain joint, its column in the log's full position matrix (None:
            not logged, held at zero).
        jac: the link-end Jacobian (:data:`impactcli.detect.force.JacobianFn`) or None.
        vl: (J,) the static-loading thresholds [N·m].
        dt: the sample period [s]. t0_ns: the log's first sample [ns].
        n_samples: the log's length. merge_gap_s: events.merge_gap_s [s].
        capacity: (J,) each detected joint's torque capacity [N·m] (NaN: unknown) and
            ``capacity_source``, what it is (:func:`torque_capacity`).
        link_lengths: a planar arm's link lengths [m] (a joint's reach to a link's end is
            their sum, whatever the posture); None otherwise.
        chain: the chain's joint names, base first (link i ends at chain joint i).
        torque_peak: (J,) the largest |torque| logged on each detected joint [N·m] (None:
            unknown): what the model's torque is checked against (:func:`beyond_logged`).
    """

    joints: tuple[str, ...]
    index: list[int]
    chain_cols: list[int | None]
    jac: JacobianFn | None
    vl: np.ndarray
    dt: float
    t0_ns: int
    n_samples: int
    merge_gap_s: float
    capacity: np.ndarray | None = None
    capacity_source: str = ""
    link_lengths: tuple[float, ...] | None = None
    chain: tuple[str, ...] = ()
    torque_peak: np.ndarray | None = None

    def reach(self, chain_pos: int, link: int, est: ForceEstimate) -> float:
        """Chain joint ``chain_pos``'s longest lever arm to the end of ``link`` [m]: the sum
        of the link lengths between (planar), else the longest seen over the estimate's
        samples (|J_k|)."""
        if self.link_lengths is not None and link <= len(self.link_lengths):
            return float(sum(self.link_lengths[chain_pos - 1:link]))
        return est.levers.get(chain_pos, 0.0)

    def pressing(self, loading: np.ndarray) -> np.ndarray:
        """(n,) some joint's static-loading statistic at BRIDGE_FRACTION of its threshold
        (the contact still pressing: :func:`impactcli.detect.incidents.group_events`)."""
        return np.asarray(np.any(
            loading >= BRIDGE_FRACTION * np.maximum(self.vl, 1e-12)[None, :], axis=1))


def urdf_efforts(model: dict[str, Any] | None, joints: tuple[str, ...]) -> np.ndarray:
    """(J,) each joint's effort limit [N·m] from a URDF model's ``<limit effort>`` (NaN
    where the model is not a URDF or gives none)."""
    structure = (model or {}).get("structure") if (model or {}).get("kind") == "urdf" else None
    xml = (structure or {}).get("urdf_xml") if isinstance(structure, dict) else None
    if not xml:
        return np.full(len(joints), np.nan)
    return effort_limits(str(xml), (structure or {}).get("urdf_joint_map") or {}, joints)


def effort_limits(xml: str, joint_map: dict[str, str], joints: tuple[str, ...]) -> np.ndarray:
    """(J,) each joint's ``<limit effort>`` [N·m] in URDF text ``xml``, the log's joint names
    renamed through ``joint_map`` (NaN where the URDF gives none, or cannot be read)."""
    out = np.full(len(joints), np.nan)
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(xml)
    except ET.ParseError:
        return out
    limits = {}
    for jt in root.iter("joint"):
        lim = jt.find("limit")
        try:
            eff = float(lim.get("effort", "nan")) if lim is not None else np.nan
        except ValueError:
            eff = np.nan
        limits[str(jt.get("name"))] = eff
    for k, j in enumerate(joints):
        v = limits.get(str(joint_map.get(j, j)), np.nan)
        out[k] = v if np.isfinite(v) and v > 0 else np.nan
    return out


#: A joint's motor holds at least its largest gravity torque with margin: its capacity,
#: when a description's masses say that torque, is this many times it.
HOLD_FACTOR = 2.0


def torque_capacity(efforts: np.ndarray, torque_peak: np.ndarray | None,
                    gravity_hold: np.ndarray | None = None) -> tuple[np.ndarray, str]:
    """Each joint's torque capacity [N·m] for the force plausibility check
    (docs/incidents.md, "The rules"): the URDF's effort limit where it gives one; else
    :data:`HOLD_FACTOR` × the largest gravity torque the description's masses say the joint
    holds over the log's poses (``gravity_hold``, where it is at least 1 % of the largest
    joint's: a joint gravity does not load says nothing); else the largest |torque| logged on
    it (the log's own scale, unverified: said so); NaN where none is known. Returns
    (capacity, what it is in words)."""
    cap = np.asarray(efforts, dtype=np.float64).copy()
    hold = (np.full(cap.shape, np.nan) if gravity_hold is None
            else np.asarray(gravity_hold, dtype=np.float64))
    top = float(np.nanmax(hold)) if np.isfinite(hold).any() else 0.0
    use_hold = ~np.isfinite(cap) & np.isfinite(hold) & (hold > 0.01 * top) & (top > 0)
    cap[use_hold] = HOLD_FACTOR * hold[use_hold]
    peak = (np.full(cap.shape, np.nan) if torque_peak is None
            else np.asarray(torque_peak, dtype=np.float64))
    use_peak = ~np.isfinite(cap) & np.isfinite(peak) & (peak > 1e-9)
    cap[use_peak] = peak[use_peak]
    kinds = []
    if np.isfinite(efforts).any():
        kinds.append("the URDF's effort limit")
    if use_hold.any():
        kinds.append(f"{HOLD_FACTOR:g}× the largest gravity torque the description's masses "
                     "put on the joint")
    if use_peak.any():
        kinds.append("the largest torque logged on the joint: the log's own scale, "
                     "not verified against physics")
    return cap, " or ".join(kinds)


def incident_context(
    joints: tuple[str, ...], full_joints: tuple[str, ...], robot: RobotDescription | None,
    model: dict[str, Any] | None, vl: np.ndarray, dt: float, t0_ns: int, n_samples: int,
    merge_gap_s: float, where: str = "", torque_peak: np.ndarray | None = None,
    gravity_hold: np.ndarray | None = None,
) -> IncidentContext:
    """The :class:`IncidentContext` of a log: ``joints`` detected, ``full_joints`` as
    logged (positions of joints left out of detection still place the links);
    ``torque_peak``: (J,) the largest |torque| logged per detected joint [N·m];
    ``gravity_hold``: (J,) the largest gravity torque the description's masses put on each
    over the log's poses [N·m] (:func:`torque_capacity`)."""
    chain, kin = robot_chain(full_joints, robot, model, joints)
    if not set(joints) <= set(chain):
        chain, kin = full_joints, None
    index = [chain.index(j) + 1 for j in joints]
    cols = [full_joints.index(j) if j in full_joints else None for j in chain]
    jac = None
    lengths = None
    if isinstance(kin, dict) and kin.get("type") == "planar":
        jac = planar_jacobian(kin["link_lengths"])
        lengths = tuple(float(x) for x in kin["link_lengths"])
    elif (isinstance(kin, dict) and kin.get("type") == "urdf" and model is not None
          and model.get("kind") == "urdf"):
        try:
            jac = _urdf_jacobian(model, chain)
        except (ImpactError, RuntimeError, ValueError) as err:  # no Jacobian: no force
            warnings.warn(f"{where}: no link Jacobian from the URDF ({err}): "
                          "incidents without a force estimate", ImpactWarning, stacklevel=3)
    cap, source = torque_capacity(urdf_efforts(model, tuple(joints)), torque_peak,
                                  gravity_hold)
    return IncidentContext(tuple(joints), index, cols, jac, np.asarray(vl, dtype=np.float64),
                           float(dt), int(t0_ns), int(n_samples), float(merge_gap_s),
                           cap, source, lengths, tuple(chain),
                           None if torque_peak is None
                           else np.asarray(torque_peak, dtype=np.float64))


#: A model whose torque on a joint, during an incident, passes this many times the largest
#: torque logged on that joint anywhere in the log predicts what the joint never did: its
#: residual there is the model's extrapolation, not a contact's torque.
MODEL_BEYOND = 3.0


def poorly_determined(model: dict[str, Any] | None) -> bool:
    """Whether a model's identification said the log determines it poorly: a condition
    number above its warning level, parameters the log did not excite, or joints that
    stood still (its ``fit``; the run warned of each). Only such a model's torque is held
    against what the joints exerted (:func:`beyond_logged`): a well-determined model's
    torque passes the logged peak only where the arm truly accelerated — a hard impact
    decelerating it, whose force must stand."""
    fit = (model or {}).get("fit") or {}
    cond = fit.get("condition_number")
    warn = ((fit.get("options") or {}).get("condition_warn")) or 1000.0
    return bool((isinstance(cond, (int, float)) and cond > float(warn))
                or fit.get("unexcited_parameters") or fit.get("still_joints"))


def beyond_logged(ctx: IncidentContext, r: np.ndarray, tau: np.ndarray | None,
                  cols: list[int], fired: Sequence[str] = ()) -> ForceEstimate | None:
    """The incident's force as not stated (None) with why, when the model's torque
    τ̂ = r + τ on one of ``cols`` (the detected joints up to the link) did what no motion of
    the log asked of the joint — a model the log does not determine (a still arm, a joint it
    barely moves) predicting torques of its own, whose residual is no contact's
    (docs/incidents.md, "The rules"):

    - it passed :data:`MODEL_BEYOND` × the largest |τ| logged on the joint, or
    - within the incident it moved (max − min) :data:`MODEL_BEYOND` × as far as the logged
      torque did: a contact's torque reaches the joint's motor, and a residual made of the
      model's own swing is its response to the motion (a real UR arm held still, modelled
      with a guessed UR5e's kinematics, swung 131 N·m on a joint whose logged torque moved
      1.3 N·m).

    Each by more than its vL. None when the model stays within what the joints did. A
    joint not among ``fired`` (those that alarmed) is said to be one: its residual still
    enters the force at the link's end (a real UR log's braking read "force ?" for a wrist
    the log holds still, and a new user took the whole incident for the model's)."""
    if tau is None or ctx.torque_peak is None or not cols:
        return None
    hat = r[:, cols] + tau[:, cols]
    if not np.all(np.isfinite(hat)) or hat.size == 0:
        return None
    vl = ctx.vl[cols]
    peak_hat = np.abs(hat).max(axis=0)
    logged = ctx.torque_peak[cols]
    over = (peak_hat > MODEL_BEYOND * logged) & (peak_hat - logged > vl)
    if np.any(over):
        k = int(np.argmax(np.where(over, peak_hat / np.maximum(logged, 1e-12), -np.inf)))
        return ForceEstimate(None, (
            f"{BEYOND_LOGGED} {_named(ctx.joints[cols[k]], fired)} reached "
            f"{peak_hat[k]:.3g} N·m, more "
            f"than {MODEL_BEYOND:g}× the most it exerted anywhere in the log "
            f"({logged[k]:.3g} N·m): the residual there is the model's extrapolation, not a "
            "contact's torque (a model the log does not determine: see the run's warnings); "
            "no force stated"))
    swing_hat = np.ptp(hat, axis=0)
    swing = np.ptp(tau[:, cols], axis=0)
    over = (swing_hat > MODEL_BEYOND * swing) & (swing_hat - swing > vl)
    if not np.any(over):
        return None
    k = int(np.argmax(np.where(over, swing_hat / np.maximum(swing, 1e-12), -np.inf)))
    return ForceEstimate(None, (
        f"{BEYOND_LOGGED} {_named(ctx.joints[cols[k]], fired)} moved "
        f"{swing_hat[k]:.3g} N·m within the "
        f"incident, more than {MODEL_BEYOND:g}× the logged torque did ({swing[k]:.3g} N·m): "
        "a contact's torque reaches the joint's motor, so the residual there is the model's "
        "response to the motion, not a contact's torque (a model the log does not "
        "determine: see the run's warnings); no force stated"))


def _named(joint: str, fired: Sequence[str]) -> str:
    """A joint as :func:`beyond_logged` names it: ``wrist_3 (which did not alarm; its
    residual enters the force at the link's end)`` when it is not among ``fired``."""
    return (joint if not fired or joint in fired else f"{joint} (which did not alarm; its "
            "residual enters the force at the link's end)")


def blind_beyond(where: LinkDecision, jac: JacobianFn, q: np.ndarray,
                 n_links: int) -> LinkDecision:
    """``where`` with its candidates extended by the links beyond its link whose end no
    joint beyond it has a lever to (each under :data:`MIN_LEVER_M` at posture ``q``): a
    contact at such a link's end turns only the joints the contact on ``where.link`` turns,
    so the residuals cannot tell the two apart (a UR's flange lies on its wrist 3 axis: a
    push there is seen as on link 5)."""
    if where.link is None:
        return where
    extra = []
    for m in range(where.link + 1, n_links + 1):
        j = jac(q, m)
        if j is None or np.any(np.linalg.norm(j[:, where.link:m], axis=0) >= MIN_LEVER_M):
            break
        extra.append(m)
    if not extra:
        return where
    return LinkDecision(where.link, tuple(sorted({*where.candidates, *extra})))


@dataclass(frozen=True)
class ForceCheck:
    """Whether an estimated force is one the arm could exert (docs/incidents.md, "The
    rules"): ``plausible`` (None: not checked — no force, or no capacity known),
    ``ceiling_n`` :data:`~impactcli.detect.force.FORCE_CEILING_FACTOR` × the largest
    force one of the joints up to the link holds at its end with its longest lever [N], and
    ``why`` in words."""

    plausible: bool | None
    ceiling_n: float | None
    why: str


def check_force(ctx: IncidentContext, est: ForceEstimate, link: int | None) -> ForceCheck:
    """The :class:`ForceCheck` of a force estimate at ``link``: implausible above
    FORCE_CEILING_FACTOR × the largest capacity / reach (:meth:`IncidentContext.reach`)
    among the joints up to the link."""
    if est.force_n is None or link is None or not est.levers or ctx.capacity is None:
        return ForceCheck(None, None, "no force estimate to check")
    best, at, arm = 0.0, -1, 0.0
    for c in est.levers:
        k = ctx.index.index(c)
        cap, lever = float(ctx.capacity[k]), ctx.reach(c, link, est)
        if np.isfinite(cap) and cap > 0 and lever >= MIN_LEVER_M and cap / lever > best:
            best, at, arm = cap / lever, k, lever
    if at < 0:
        return ForceCheck(None, None, "no torque capacity known for the joints up to the link")
    ceiling = FORCE_CEILING_FACTOR * best
    name = ctx.joints[at]
    hold = (f"of the joints up to the link, {name} holds the most force at its end, "
            f"~{best:,.0f} N: "
            f"{float(ctx.capacity[at]):.3g} N·m ({ctx.capacity_source}) over a "
            f"{arm:.3g} m lever arm")
    if est.force_n > ceiling:
        return ForceCheck(False, ceiling, (
            f"beyond what the arm can exert — {hold}; positions in degrees? a wrong gear "
            "ratio or torque constant?"))
    return ForceCheck(True, ceiling, f"within {FORCE_CEILING_FACTOR:g}× what the arm can "
                                     f"exert ({hold})")


def build_findings(
    ctx: IncidentContext, events: list[Event], t: np.ndarray, r: np.ndarray,
    loading: np.ndarray, adaptive_d: np.ndarray, loading_d: np.ndarray,
    q_full: np.ndarray, qd: np.ndarray, offset: int = 0, event_offset: int = 0,
    level: np.ndarray | None = None, noise: np.ndarray | None = None,
    tau: np.ndarray | None = None,
) -> tuple[list[Incident], list[LastingLoad]]:
    """The incidents and lasting loads of a stretch of the log holding whole incidents.

    Args:
        ctx: the log's :class:`IncidentContext`.
        events: the stretch's events, time-ordered as in the timeline, their sample
            indices relative to the stretch.
        t: (n,) times [s since the log's first sample]; r: (n, J) residual [N·m];
        loading: (n, J) |LP(r)| [N·m]; adaptive_d, loading_d: (n, J) decisions;
        q_full: (n, J_full) positions of every logged joint [rad]; qd: (n, J) the detected
            joints' causal velocity [rad/s].
        offset: the stretch's first sample in the log; event_offset: its first event's
            index in the log's event list.
        level, noise: (n, J) each joint's residual level and noise before each sample
            (:class:`impactcli.detect.link_evidence.ResidualNoise`; None: the link from the
            detectors' evidence alone).
        tau: (n, J) the torque the residual compares the model's with [N·m]
            (:func:`beyond_logged`; None: not checked).
    Returns:
        Incidents (numbered later, by :func:`number_incidents`) and lasting loads, with
        indices in the log (``i_start``, ``i_end``, ``events``/``event``).
    """
    long_ = lasting(events)
    pressing = ctx.pressing(loading)
    for k in long_:  # a lasting load bridges nothing: as if it were not there
        pressing[events[k].i_start:events[k].i_end + 1] = False
    groups = group_events(events, ctx.merge_gap_s, pressing, exclude=long_)
    if not groups and not long_:
        return [], []
    n = t.shape[0]
    q_chain = np.zeros((n, len(ctx.chain_cols)))
    for c, col in enumerate(ctx.chain_cols):
        if col is not None:
            q_chain[:, c] = q_full[:, col]
    ratio = loading / np.maximum(ctx.vl, 1e-12)[None, :]
    index = ctx.index

    def where_and_force(win: slice, max_samples: int | None = None, typical: bool = False,
                        ) -> tuple[LinkDecision, ForceEstimate]:
        a0 = win.start
        fired = tuple(j for k, j in enumerate(ctx.joints)  # the joints that alarmed in it
                      if adaptive_d[win, k].any() or loading_d[win, k].any())
        where = decide_link(ratio[win], adaptive_d[win], index, r[win],
                            None if level is None else level[a0],
                            None if noise is None else noise[a0], ctx.vl)
        link = where.link
        est = ForceEstimate(None, "no kinematics: the peak residual torques are the answer")
        if link is not None and ctx.jac is not None:
            est = force_estimate(r[win], q_chain[win], link, index, ctx.jac, max_samples,
                                 typical)
            where = blind_beyond(where, ctx.jac, q_chain[(win.start + win.stop) // 2],
                                 len(ctx.chain_cols))
            up_to = [k for k, c in enumerate(index) if c <= link]
            est = beyond_logged(ctx, r[win], None if tau is None else tau[win], up_to,
                                fired) or est
        elif link is None:
            est = ForceEstimate(None, "the residuals cannot say which link: no force estimate")
        return where, est

    out = []
    for g in groups:
        evs = [events[k] for k in g]
        a, b = min(e.i_start for e in evs), max(e.i_end for e in evs)
        win = slice(a, b + 1)
        where, est = where_and_force(win)
        link = where.link
        chk = check_force(ctx, est, link)
        joints = tuple(dict.fromkeys(j for e in sorted(evs, key=lambda e: e.t_start)
                                     for j in e.joints))
        cols = [k for k, c in enumerate(index) if link is None or c <= link]
        speed = np.max(np.abs(qd[win][:, cols]), axis=1)
        kind = contact_type(np.asarray(loading_d[win].any(axis=1)), speed, ctx.dt,
                            ends_with_log=offset + b >= ctx.n_samples - 1)
        peak = {}
        for j in joints:
            seg = r[win, ctx.joints.index(j)]
            peak[j] = float(seg[np.argmax(np.abs(seg))])
        first = min(evs, key=lambda e: e.t_start)
        out.append(Incident(
            t_start=float(t[a]), t_end=float(t[b]), i_start=int(a + offset),
            i_end=int(b + offset),
            detectors=tuple(dict.fromkeys(e.detector for e in sorted(evs,
                                                                     key=lambda e: e.t_start))),
            joints=joints, link=link, force_n=est.force_n, force_method=est.stated,
            force_at_least=bool(est.at_least), contact=kind, peak_residual=peak,
            in_warmup=bool(first.in_warmup),
            t_start_utc=utc(ctx.t0_ns + round(t[a] * 1e9)),
            events=tuple(k + event_offset for k in g), force_plausible=chk.plausible,
            force_ceiling_n=chk.ceiling_n, force_check=chk.why,
            link_candidates=where.candidates))
    loads = []
    for k in long_:
        e = events[k]
        where, est = where_and_force(slice(e.i_start, e.i_end + 1), LASTING_FORCE_SAMPLES,
                                     typical=True)  # the load's level, not a push's peak
        link = where.link
        chk = check_force(ctx, est, link)
        loads.append(LastingLoad(
            detector=e.detector, t_start=e.t_start, t_end=e.t_end,
            i_start=e.i_start + offset, i_end=e.i_end + offset, joints=e.joints,
            peak_ratio=e.peak_ratio, in_warmup=e.in_warmup, event=k + event_offset,
            ends_with_log=offset + e.i_end >= ctx.n_samples - 1, link=link,
            force_n=est.force_n, force_method=est.stated, force_at_least=bool(est.at_least),
            t_start_utc=utc(ctx.t0_ns + round(e.t_start * 1e9)),
            force_plausible=chk.plausible, force_ceiling_n=chk.ceiling_n,
            force_check=chk.why, peak_force_n=est.peak_n if est.force_n is not None else None))
    return out, loads


def beside(ctx: IncidentContext, inc: Incident, part: Any) -> Incident | None:
    """``inc``, a contact beside a payload change, placed and sized by the contact itself:
    its link, force and contact type from ``part`` (a
    :class:`~impactcli.detect.payload_finding.ContactPart`: the residual with the load's
    torque taken out, over the contact's excursion) by the rules of :func:`build_findings`
    (the link from the detectors' evidence, the residual's noise not known there). None
    when the part cannot place it: a joint of the chain logged but not in the replay (its
    posture unknown there), or joints that are not the context's."""
    names = tuple(part.joints)
    if set(names) != set(ctx.joints) or part.r.shape[0] == 0:
        return None
    order = [names.index(j) for j in ctx.joints]  # the part's columns in the context's order
    r, ratio = part.r[:, order], part.ratio[:, order]
    q_chain = np.zeros((r.shape[0], len(ctx.chain_cols)))
    for c, name in enumerate(ctx.chain):
        if name in names:
            q_chain[:, c] = part.q[:, names.index(name)]
        elif ctx.chain_cols[c] is not None:
            return None
    where = decide_link(ratio, np.zeros(ratio.shape, dtype=bool), ctx.index, r, None, None,
                        ctx.vl)
    link = where.link
    est = ForceEstimate(None, "no kinematics: the peak residual torques are the answer")
    if link is not None and ctx.jac is not None:
        est = force_estimate(r, q_chain, link, ctx.index, ctx.jac)
        where = blind_beyond(where, ctx.jac, q_chain[r.shape[0] // 2], len(ctx.chain_cols))
    elif link is None:
        est = ForceEstimate(None, "the residuals cannot say which link: no force estimate")
    if part.began_before and est.force_n is not None:  # its end only: no peak to give
        est = ForceEstimate(None, (
            "no force estimate: the contact began before the torque the load leaves could "
            "be read apart from the load's step (within the change's settling time); after "
            f"that, at least {est.force_n:.3g} N at the end of link {link}"), est.levers)
    chk = check_force(ctx, est, link)
    cols = [k for k, c in enumerate(ctx.index) if link is None or c <= link]
    speed = np.max(np.abs(part.qd[:, order][:, cols]), axis=1)
    kind = contact_type(np.asarray((ratio > 1.0).any(axis=1)), speed, part.dt)
    peak = {j: float(r[np.argmax(np.abs(r[:, k])), k]) for k, j in enumerate(ctx.joints)
            if j in inc.joints}
    return replace(inc, link=link, link_candidates=where.candidates, force_n=est.force_n,
                   force_method=est.method + ("" if est.force_n is None
                                              else " (the torque the load leaves)")
                   + est.at_least, force_at_least=bool(est.at_least),
                   force_plausible=chk.plausible, force_ceiling_n=chk.ceiling_n,
                   force_check=chk.why, contact=kind, peak_residual=peak)


def number_incidents(incidents: list[Incident]) -> list[Incident]:
    """The log's incidents with their ``number``: 1, 2, … in time order for those counted
    (after warm-up, not at a data defect nor a payload change), None for the others — the
    number the terminal and the report show."""
    import dataclasses

    out, n = [], 0
    for inc in incidents:
        if inc.in_warmup or inc.data_defect is not None or inc.payload_change is not None:
            out.append(dataclasses.replace(inc, number=None))
        else:
            n += 1
            out.append(dataclasses.replace(inc, number=n))
    return out
