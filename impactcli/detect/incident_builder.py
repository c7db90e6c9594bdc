"""From a replay's events and signals to incidents (:mod:`impactcli.detect.incidents`).

What an incident needs is fixed once per log (:class:`IncidentContext`: the robot's chain,
the link numbers of the detected joints, the link Jacobian, the static-loading thresholds)
and then read from the samples of the incident's own stretch: the residual, the
static-loading statistic, the decisions, the positions of the whole chain and the joints'
causal velocity. :func:`build_incidents` takes those arrays for any stretch of the log
that holds whole incidents — one "island" of a replay (the samples near an alarm or a
pressing contact, :mod:`impactcli.run.one_log`) — with its offset in the log.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ImpactError, ImpactWarning
from ..types import Event, RobotDescription
from .incidents import (
    BRIDGE_FRACTION,
    Incident,
    JacobianFn,
    contact_type,
    estimate_force,
    group_events,
    isolate,
    planar_jacobian,
)


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
        jac: the link-end Jacobian (:data:`impactcli.detect.incidents.JacobianFn`) or None.
        vl: (J,) the static-loading thresholds [N·m].
        dt: the sample period [s]. t0_ns: the log's first sample [ns].
        n_samples: the log's length. merge_gap_s: events.merge_gap_s [s].
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

    def pressing(self, loading: np.ndarray) -> np.ndarray:
        """(n,) some joint's static-loading statistic at BRIDGE_FRACTION of its threshold
        (the contact still pressing: :func:`impactcli.detect.incidents.group_events`)."""
        return np.asarray(np.any(
            loading >= BRIDGE_FRACTION * np.maximum(self.vl, 1e-12)[None, :], axis=1))


def incident_context(
    joints: tuple[str, ...], full_joints: tuple[str, ...], robot: RobotDescription | None,
    model: dict[str, Any] | None, vl: np.ndarray, dt: float, t0_ns: int, n_samples: int,
    merge_gap_s: float, where: str = "",
) -> IncidentContext:
    """The :class:`IncidentContext` of a log: ``joints`` detected, ``full_joints`` as
    logged (positions of joints left out of detection still place the links)."""
    chain, kin = robot_chain(full_joints, robot, model, joints)
    if not set(joints) <= set(chain):
        chain, kin = full_joints, None
    index = [chain.index(j) + 1 for j in joints]
    cols = [full_joints.index(j) if j in full_joints else None for j in chain]
    jac = None
    if isinstance(kin, dict) and kin.get("type") == "planar":
        jac = planar_jacobian(kin["link_lengths"])
    elif (isinstance(kin, dict) and kin.get("type") == "urdf" and model is not None
          and model.get("kind") == "urdf"):
        try:
            jac = _urdf_jacobian(model, chain)
        except (ImpactError, RuntimeError, ValueError) as err:  # no Jacobian: no force
            warnings.warn(f"{where}: no link Jacobian from the URDF ({err}): "
                          "incidents without a force estimate", ImpactWarning, stacklevel=3)
    return IncidentContext(tuple(joints), index, cols, jac, np.asarray(vl, dtype=np.float64),
                           float(dt), int(t0_ns), int(n_samples), float(merge_gap_s))


def build_incidents(
    ctx: IncidentContext, events: list[Event], t: np.ndarray, r: np.ndarray,
    loading: np.ndarray, adaptive_d: np.ndarray, loading_d: np.ndarray,
    q_full: np.ndarray, qd: np.ndarray, offset: int = 0, event_offset: int = 0,
) -> list[Incident]:
    """The incidents of a stretch of the log holding whole incidents.

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
    Returns:
        Incidents with indices in the log (``i_start``, ``i_end``, ``events``).
    """
    groups = group_events(events, ctx.merge_gap_s, ctx.pressing(loading))
    if not groups:
        return []
    n = t.shape[0]
    q_chain = np.zeros((n, len(ctx.chain_cols)))
    for c, col in enumerate(ctx.chain_cols):
        if col is not None:
            q_chain[:, c] = q_full[:, col]
    ratio = loading / np.maximum(ctx.vl, 1e-12)[None, :]
    index = ctx.index
    out = []
    for g in groups:
        evs = [events[k] for k in g]
        a, b = min(e.i_start for e in evs), max(e.i_end for e in evs)
        win = slice(a, b + 1)
        link = isolate(ratio[win], adaptive_d[win], index)
        joints = tuple(dict.fromkeys(j for e in sorted(evs, key=lambda e: e.t_start)
                                     for j in e.joints))
        force, method = (None, "no kinematics: the peak residual torques are the answer")
        if link is not None and ctx.jac is not None:
            force, method = estimate_force(r[win], q_chain[win], link, index, ctx.jac)
        elif link is None:
            method = "the residuals cannot say which link: no force estimate"
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
            joints=joints, link=link, force_n=force, force_method=method, contact=kind,
            peak_residual=peak, in_warmup=bool(first.in_warmup),
            t_start_utc=utc(ctx.t0_ns + round(t[a] * 1e9)),
            events=tuple(k + event_offset for k in g)))
    return out
