"""Identification of the rough rigid model by robust least squares (method.md §2, eq. 7).

Stack tau(k) = Y(q(k), q'(k), q''(k)) theta over samples and joints and solve for theta:

1. Derivatives: zero-phase Butterworth on the positions, central differences, and the
   same zero-phase filter on the torques (identification is offline, method.md §1).
   The first and last 1/cut-off seconds are dropped (filter edges).
2. Excitation: the stacked base regressor is column-normalised and factorised by pivoted
   QR; a parameter whose pivot is below ``drop_tolerance`` of the largest is not excited by
   the log — it is fixed at 0 with an ImpactWarning naming it. The condition number of the
   remaining (normalised) regressor is reported and warned about above
   ``condition_warn``.
3. Robust fit: rows are normalised per joint by a robust residual scale (1.4826 × MAD);
   iteratively reweighted least squares with Huber weights (k = 1.345) to convergence,
   then, by default, Tukey bisquare weights (c = 4.685, scale frozen) so that the few
   samples of a contact a user's log may contain get zero weight instead of bending the
   model.
4. Fit statistics per joint: RMS error [N·m], relative to the joint's torque RMS and to
   its torque range, on the fitted part and — when the log is long enough — on a held-back
   last part (``holdout_fraction``, at least ``min_holdout_s``) that the fit never saw.
"""

from __future__ import annotations

import hashlib
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import qr

from ..errors import ImpactWarning, ModelError, RobotDescriptionError
from ..types import RobotDescription, RobotLog
from . import structures
from .derivatives import clip_cutoff, zero_phase_derivatives, zero_phase_lowpass
from .rigid import RigidModel


@dataclass(frozen=True)
class IdentifyOptions:
    """Settings of :func:`identify`.

    Attributes:
        cutoff_hz: zero-phase Butterworth cut-off for positions and torques [Hz]
            (clipped below 0.4 × sample rate). 10 Hz suits 100 Hz – 1 kHz logs of arm motion.
        filter_order: Butterworth order (one way; filtfilt doubles it).
        coulomb_slope_rad_s: v_s of the smooth sign tanh(q'/v_s) [rad/s].
            0.01 rad/s: on the simulator (true v_eps 2 mrad/s, encoder quantisation)
            it fitted and replayed better than 0.02 and 0.05, no worse than 0.005.
        offset: include a constant torque per joint.
        motor_inertia: include the reflected motor inertia Ia per joint (planar, urdf).
        filter_regressor: pass the regressor columns through the torque's zero-phase filter.
        robust: ``bisquare`` (Huber then Tukey bisquare), ``huber`` or ``none`` (plain LS).
        huber_k, bisquare_c: tuning constants, in robust standard deviations.
        max_iter: iteration cap of each reweighting stage.
        holdout_fraction: last fraction of the log held back for validation (0: none).
        min_holdout_s: hold back only when that part lasts at least this long [s].
        min_motion_rad: a joint whose position range is below this is "constant" [rad].
        allow_still_joints: a constant joint is an error by default; with this, it is
            warned about and its unexcited parameters are fixed at 0 (it keeps an offset).
        max_fit_samples: at most this many samples (fit + held back) enter the least
            squares; a longer log is fitted on every k-th filtered sample (memory and
            time stay bounded; the rows of a 10 Hz band-limited signal are correlated).
        drop_tolerance: relative QR pivot below which a parameter is "not excited".
        condition_warn: warn when the normalised regressor's condition number exceeds it.
    """

    cutoff_hz: float = 10.0
    filter_order: int = 4
    coulomb_slope_rad_s: float = 0.01
    offset: bool = True
    motor_inertia: bool = True
    filter_regressor: bool = True
    robust: str = "bisquare"
    huber_k: float = 1.345
    bisquare_c: float = 4.685
    max_iter: int = 50
    holdout_fraction: float = 0.2
    min_holdout_s: float = 2.0
    min_motion_rad: float = 1e-3
    allow_still_joints: bool = False
    max_fit_samples: int = 100_000
    drop_tolerance: float = 1e-4
    condition_warn: float = 1e3

    def __post_init__(self) -> None:
        if self.robust not in ("bisquare", "huber", "none"):
            raise ModelError(f"robust must be bisquare, huber or none, got {self.robust!r}")
        if not 0.0 <= self.holdout_fraction < 0.9:
            raise ModelError(f"holdout_fraction must be in [0, 0.9), got {self.holdout_fraction}")
        if not self.coulomb_slope_rad_s > 0:
            raise ModelError("coulomb_slope_rad_s must be positive")


# ------------------------------------------------------------------ helpers
def default_kind(robot: RobotDescription | None) -> str:
    """planar / urdf when the robot description has that kinematics, else decoupled."""
    if robot is not None and robot.kinematics:
        return str(robot.kinematics["type"])
    return "decoupled"


def match_joints(
    log_joints: tuple[str, ...], robot: RobotDescription | None, where: str,
    kind: str | None = None,
) -> list[int]:
    """Column indices of the log's joints in the robot's chain order.

    For a ``urdf`` model of a robot with URDF kinematics see :func:`match_urdf_joints`
    (joints may be missing on either side). Otherwise raises RobotDescriptionError naming
    the joints that are missing on either side.
    """
    if robot is None:
        return list(range(len(log_joints)))
    if kind == "urdf" and robot.kinematics and robot.kinematics.get("type") == "urdf":
        return match_urdf_joints(log_joints, robot, where)
    rj = robot.joint_names
    missing = [j for j in rj if j not in log_joints]
    extra = [j for j in log_joints if j not in rj]
    if missing or extra:
        parts = []
        if missing:
            parts.append(f"joints {missing} of the robot description are not in the log")
        if extra:
            parts.append(f"log joints {extra} are not in the robot description")
        raise RobotDescriptionError(
            f"{where}: robot description {robot.path or robot.name or ''!s} does not match "
            f"the log: {'; '.join(parts)}"
        )
    return [log_joints.index(j) for j in rj]


def urdf_source(kin: dict[str, Any]) -> tuple[str, str, str | None]:
    """The URDF text of ``urdf`` kinematics, how messages name it, and the shipped robot it
    is (None for a file): ``urdf_xml`` when given, else the shipped robot ``robot``'s URDF,
    else the file at ``path`` (the one file read in model/)."""
    name = kin.get("robot")
    if name is not None:
        from .. import robots

        xml = kin.get("urdf_xml") or robots.urdf_text(str(name))
        shipped = robots.entry(str(name))
        assert shipped is not None  # urdf_text raised otherwise
        return str(xml), robots.urdf_label(shipped.name), shipped.name
    xml = kin.get("urdf_xml")
    upath = str(kin.get("path", "URDF"))
    if xml is None:
        try:
            xml = Path(upath).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise RobotDescriptionError(f"{upath}: cannot read URDF: {err}") from err
    return str(xml), upath, None


def match_urdf_joints(
    log_joints: tuple[str, ...], robot: RobotDescription, where: str
) -> list[int]:
    """Column indices of the log's joints that a URDF model can use, in the robot's order.

    A joint of the robot description (through its ``joint_map``) that the URDF has is
    modelled when logged. The robot's joints the log lacks — those of the description and,
    for a shipped robot, its arm joints — are held at zero (one ImpactWarning naming
    them). A logged joint that is not a modelled joint is left out (an ImpactWarning each,
    worded as the pipeline's, which records it in the timeline). Nothing is renumbered.
    Raises RobotDescriptionError when no logged joint is a joint of the URDF.
    """
    assert robot.kinematics is not None
    xml, label, shipped = urdf_source(robot.kinematics)
    in_urdf = set(structures.urdf_joint_names(xml, label))
    jm = robot.joint_map or {}
    modelled = [j for j in robot.joint_names if jm.get(j, j) in in_urdf]
    used = [j for j in modelled if j in log_joints]
    if not used:
        raise RobotDescriptionError(
            f"{where}: no logged joint is a joint of the URDF of {label} (log: "
            f"{list(log_joints)}; robot description: {[jm.get(j, j) for j in modelled]})")
    expected = [jm.get(j, j) for j in modelled]
    if shipped is not None:
        from .. import robots

        expected += [a for a in robots.arm_joints(shipped) if a not in expected]
    used_urdf = {jm.get(j, j) for j in used}
    log_name = {jm.get(j, j): j for j in robot.joint_names if jm.get(j, j) != j}
    held = [u for u in expected if u not in used_urdf]
    if held:
        named = ", ".join(f"{u} (log name {log_name[u]})" if u in log_name else u for u in held)
        warnings.warn(f"{where}: URDF joint(s) {named} of {label} not in the log: held at zero",
                      ImpactWarning, stacklevel=3)
    stray = [j for j in robot.joint_names if j not in modelled and j not in log_joints]
    if stray:
        warnings.warn(f"{where}: joint(s) {', '.join(stray)} of the robot description are "
                      f"neither in the URDF of {label} nor in the log: ignored",
                      ImpactWarning, stacklevel=3)
    for j in log_joints:
        if j not in used:
            warnings.warn(f"{where}: joint {j!r} left out of detection: not in the model",
                          ImpactWarning, stacklevel=3)
    return [log_joints.index(j) for j in used]


MOTION_PARAMS: tuple[str, ...] = ("inertia", "gcos", "gsin", "Ia", "fv", "fc")


def check_motion(
    q: np.ndarray, joints: tuple[str, ...], min_motion_rad: float, where: str,
    allow_still: bool = False,
) -> list[str]:
    """ModelError if the log has no motion, or (unless ``allow_still``) a joint stays constant.

    Returns the names of the joints that stay constant (only with ``allow_still``).
    """
    rng = np.ptp(q, axis=0)
    still = [j for j, r in zip(joints, rng, strict=True) if r < min_motion_rad]
    if len(still) == len(joints):
        raise ModelError(
            f"{where}: the log has no motion (every joint moves less than "
            f"{min_motion_rad:g} rad): a model cannot be identified from it"
        )
    if still:
        ranges = ", ".join(f"{j} {rng[joints.index(j)]:.2g} rad" for j in still)
        if allow_still:
            warnings.warn(
                f"{where}: joint(s) stay constant ({ranges}): only their constant torque "
                "is modelled", ImpactWarning, stacklevel=3,
            )
            return still
        raise ModelError(
            f"{where}: joint(s) stay constant ({ranges}, below {min_motion_rad:g} rad): their "
            "dynamics cannot be identified; record a log in which every joint moves "
            "(or allow still joints)"
        )
    return []


def _structure_for(
    kind: str, robot: RobotDescription | None, joints: tuple[str, ...],
    options: IdentifyOptions, where: str,
) -> dict[str, Any]:
    base: dict[str, Any] = {
        "coulomb_slope_rad_s": options.coulomb_slope_rad_s,
        "offset": options.offset,
        "motor_inertia": options.motor_inertia,
    }
    if kind == "decoupled":
        return base
    kin = robot.kinematics if robot is not None else None
    if not kin or kin.get("type") != kind:
        raise RobotDescriptionError(
            f"{where}: a {kind} model needs a robot description with {kind} kinematics "
            f"(--robot), got {kin.get('type') if kin else 'none'}"
        )
    if kind == "planar":
        base["link_lengths"] = [float(v) for v in kin["link_lengths"]]
        base["gravity"] = [float(v) for v in kin.get("gravity", [0.0, -9.81])]
        return base
    if kind == "urdf":
        xml, label, shipped = urdf_source(kin)
        return structures.urdf_structure(xml, joints, base, label,
                                         joint_map=robot.joint_map if robot else None,
                                         robot=shipped)
    raise ModelError(f"unknown model kind {kind!r} (choose from {', '.join(structures.KINDS)})")


def _robust_scale(res: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """(J,) 1.4826 × median absolute deviation per joint, floored."""
    med = np.median(res, axis=0)
    s = 1.4826 * np.median(np.abs(res - med), axis=0)
    return np.asarray(np.maximum(s, floor))


def robust_lstsq(
    y_reg: np.ndarray, tau: np.ndarray, options: IdentifyOptions
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Robust least squares tau ≈ Y theta over all samples and joints.

    Args:
        y_reg: (N, J, P) regressor; tau: (N, J) torques [N·m].
    Returns:
        theta (P,), weights (N, J) in [0, 1], info (iterations, stage).
    """
    n, nj, p = y_reg.shape
    trms = np.sqrt(np.mean(tau**2, axis=0))
    floor = 1e-9 * np.maximum(trms, 1e-12)
    # per joint, only the columns that are non-zero in its rows (the decoupled model is
    # block diagonal; a chain's last joints see few columns): far less work per iteration
    blocks = []
    for j in range(nj):
        cols = np.flatnonzero(np.any(y_reg[:, j, :] != 0.0, axis=0))
        blocks.append((cols, np.ascontiguousarray(y_reg[:, j, cols])))

    def predict(th: np.ndarray) -> np.ndarray:
        return np.stack([aj @ th[cols] for cols, aj in blocks], axis=1)

    def wls(w: np.ndarray) -> np.ndarray:
        """Weighted normal equations (w: (N, J) row weights), diagonally scaled: accurate at
        the condition numbers the excitation check lets through (≤ 1/drop_tolerance)."""
        g = np.zeros((p, p))
        h = np.zeros(p)
        for j, (cols, aj) in enumerate(blocks):
            awj = aj * w[:, j, None]
            g[np.ix_(cols, cols)] += awj.T @ aj
            h[cols] += awj.T @ tau[:, j]
        d = np.sqrt(np.diag(g))
        d[d == 0] = 1.0
        gs = g / d[:, None] / d[None, :]
        try:
            sol = np.linalg.solve(gs, h / d)
        except np.linalg.LinAlgError:
            sol, *_ = np.linalg.lstsq(gs, h / d, rcond=None)
        return np.asarray(sol) / d

    scale0 = np.maximum(trms, floor)
    theta = wls(np.broadcast_to(1.0 / scale0**2, (n, nj)))
    w = np.ones((n, nj))
    iters = {"huber": 0, "bisquare": 0}
    if options.robust == "none":
        return theta, w, {"iterations": iters}
    sigma = scale0
    for stage in ("huber", "bisquare"):
        if stage == "bisquare" and options.robust != "bisquare":
            break
        for _ in range(options.max_iter):
            res = tau - predict(theta)
            if stage == "huber":
                sigma = _robust_scale(res, floor)
            u = np.abs(res) / sigma
            if stage == "huber":
                w = np.minimum(1.0, options.huber_k / np.maximum(u, 1e-300))
            else:
                c = options.bisquare_c
                w = np.where(u < c, (1.0 - (u / c) ** 2) ** 2, 0.0)
            new = wls(w / sigma**2)
            iters[stage] += 1
            done = bool(np.linalg.norm(new - theta) <= 1e-7 * np.linalg.norm(theta))
            theta = new
            if done:
                break
    return theta, w, {"iterations": iters, "robust_scale_nm": sigma.tolist()}


def _joint_stats(res: np.ndarray, tau: np.ndarray, joints: tuple[str, ...]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for j, name in enumerate(joints):
        rms = float(np.sqrt(np.mean(res[:, j] ** 2)))
        trms = float(np.sqrt(np.mean(tau[:, j] ** 2)))
        rng = float(np.ptp(tau[:, j]))
        out[name] = {
            "rms_nm": rms,
            "torque_rms_nm": trms,
            "torque_range_nm": rng,
            "rms_rel_torque_rms": rms / trms if trms > 0 else None,
            "rms_rel_range": rms / rng if rng > 0 else None,
        }
    return out


# ------------------------------------------------------------------ public
def identify_signals(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, tau: np.ndarray, *,
    joint_names: tuple[str, ...], kind: str, robot: RobotDescription | None = None,
    options: IdentifyOptions = IdentifyOptions(), holdout: tuple[np.ndarray, ...] | None = None,
    where: str = "log", input_sha256: str = "",
) -> RigidModel:
    """Identify a model from positions, derivatives and torques already in hand (no filtering).

    Args:
        q, qd, qdd: (N, J) [rad, rad/s, rad/s²] in ``joint_names`` (= robot chain) order.
        tau: (N, J) torques [N·m].
        joint_names: J names.  kind: ``decoupled``, ``planar`` or ``urdf``.
        robot: the robot description (needed for planar and urdf).
        holdout: optional (q, qd, qdd, tau) of a held-back part, for validation only.
        where: name of the input for messages.
    Returns:
        The identified :class:`RigidModel`.
    """
    joints = tuple(joint_names)
    q, qd, qdd, tau = (np.asarray(x, dtype=np.float64) for x in (q, qd, qdd, tau))
    if kind not in structures.KINDS:
        raise ModelError(f"unknown model kind {kind!r} (choose from {', '.join(structures.KINDS)})")
    still = check_motion(q, joints, options.min_motion_rad, where, options.allow_still_joints)
    structure = _structure_for(kind, robot, joints, options, where)
    y_reg = structures.regressor(kind, joints, structure, q, qd, qdd)
    y_hold = None
    if holdout is not None:
        hq, hqd, hqdd, htau = holdout
        y_hold = (structures.regressor(kind, joints, structure, hq, hqd, hqdd), htau)
    return _fit(y_reg, tau, y_hold, kind=kind, joints=joints, structure=structure,
                robot=robot, options=options, where=where, filter_info={},
                input_sha256=input_sha256, still=still)


def _fit(
    y_reg: np.ndarray, tau: np.ndarray, y_hold: tuple[np.ndarray, np.ndarray] | None, *,
    kind: str, joints: tuple[str, ...], structure: dict[str, Any],
    robot: RobotDescription | None, options: IdentifyOptions, where: str,
    filter_info: dict[str, Any], input_sha256: str, still: list[str] | None = None,
) -> RigidModel:
    """Excitation check, robust fit and statistics on a stacked regressor (N, J, P).

    The motion parameters (:data:`MOTION_PARAMS`) of the joints in ``still`` are fixed at 0.
    """
    names = structures.param_names(kind, joints, structure)
    frozen = {f"{j}.{p}" for j in (still or []) for p in MOTION_PARAMS}
    n, nj, p = y_reg.shape
    a = y_reg.reshape(n * nj, p)
    # excitation: normalised pivoted QR (rows scaled per joint by the torque RMS)
    trms = np.sqrt(np.mean(tau**2, axis=0))
    rs = np.tile(1.0 / np.maximum(trms, 1e-12 * max(float(trms.max()), 1e-300)), n)
    an = a * rs[:, None]
    norms = np.linalg.norm(an, axis=0)
    top = float(norms.max()) if norms.size else 0.0
    live = (norms > 1e-12 * top) & np.array([nm not in frozen for nm in names], dtype=bool)
    keep = np.zeros(p, dtype=bool)
    if np.any(live):
        idx = np.flatnonzero(live)
        _, r, piv = qr(an[:, idx] / norms[idx], mode="economic", pivoting=True)
        d = np.abs(np.diag(r))
        ok = d > options.drop_tolerance * d[0]
        keep[idx[piv[: int(np.sum(ok))]]] = True
    dropped = [names[i] for i in range(p) if not keep[i] and names[i] not in frozen]
    if dropped:
        warnings.warn(
            f"{where}: the log does not excite {len(dropped)} parameter(s) of the {kind} model "
            f"({', '.join(dropped)}); they are fixed at 0", ImpactWarning, stacklevel=3,
        )
    ak = an[:, keep] / norms[keep]
    _, sv, vt = np.linalg.svd(ak, full_matrices=False)
    cond = float(sv[0] / sv[-1]) if sv.size and sv[-1] > 0 else float("inf")
    if cond > options.condition_warn:
        weak_idx = np.argsort(np.abs(vt[-1]))[::-1][:3]
        weak = [names[i] for i in np.flatnonzero(keep)[weak_idx]]
        warnings.warn(
            f"{where}: the log excites the {kind} model poorly (condition number {cond:.3g} "
            f"> {options.condition_warn:g}); least determined: {', '.join(weak)}",
            ImpactWarning, stacklevel=3,
        )
    theta = np.zeros(p)
    th_k, w, info = robust_lstsq(y_reg[:, :, keep], tau, options)
    theta[keep] = th_k
    res = (a @ theta).reshape(n, nj) - tau
    fit: dict[str, Any] = {
        "method": f"robust least squares ({options.robust})",
        "n_samples_fit": int(n),
        "n_samples_holdout": 0,
        "condition_number": cond,
        "unexcited_parameters": dropped,
        "still_joints": list(still or []),
        "robust": {
            **info,
            "downweighted_fraction": {
                nm: float(np.mean(w[:, j] < 0.5)) for j, nm in enumerate(joints)
            },
        },
        "joints": {"fit": _joint_stats(res, tau, joints), "holdout": None},
        "options": asdict(options),
    }
    if y_hold is not None:
        yh, htau = y_hold
        fit["n_samples_holdout"] = int(yh.shape[0])
        fit["joints"]["holdout"] = _joint_stats(yh @ theta - htau, htau, joints)
    return RigidModel(
        kind=kind, joint_names=joints, param_names=tuple(names), theta=theta,
        structure=structure, filter=filter_info, fit=fit,
        robot=_robot_dict(robot), input_sha256=input_sha256,
    )


def _robot_dict(robot: RobotDescription | None) -> dict[str, Any] | None:
    if robot is None:
        return None
    d = robot.to_dict()
    if d.get("kinematics") and "urdf_xml" in d["kinematics"]:
        d["kinematics"] = {k: v for k, v in d["kinematics"].items() if k != "urdf_xml"}
    return d


def _filtered_rows(
    kind: str, joints: tuple[str, ...], structure: dict[str, Any],
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, selections: tuple[np.ndarray, ...],
    fs: float, cutoff: float, options: IdentifyOptions | None, margin: int,
    chunk: int = 20000,
) -> list[np.ndarray]:
    """Regressor rows at the sample indices of each selection, computed chunk by chunk.

    With ``options`` the regressor columns pass through the zero-phase filter (each chunk
    is filtered with ``4 × margin`` extra samples on each side, then cut), so memory stays
    bounded on hour-long logs. Returns one (len(sel), J, P) array per selection.
    """
    n = q.shape[0]
    pad = 4 * margin if options is not None else 0
    outs: list[list[np.ndarray]] = [[] for _ in selections]
    for s in range(0, n, chunk):
        e = min(n, s + chunk)
        wanted = [sel[(sel >= s) & (sel < e)] for sel in selections]
        if not any(w.size for w in wanted):
            continue
        a, b = max(0, s - pad), min(n, e + pad)
        y = structures.regressor(kind, joints, structure, q[a:b], qd[a:b], qdd[a:b])
        if options is not None:
            shape = y.shape
            y = zero_phase_lowpass(y.reshape(shape[0], -1), fs, cutoff,
                                   options.filter_order).reshape(shape)
        for k, w in enumerate(wanted):
            outs[k].append(y[w - a])
    p = len(structures.param_names(kind, joints, structure))
    return [np.concatenate(o, axis=0) if o else np.zeros((0, len(joints), p)) for o in outs]


@dataclass(frozen=True)
class _Rows:
    """Filtered regressor rows of one log, ready to stack and fit."""

    kind: str
    joints: tuple[str, ...]
    structure: dict[str, Any]
    still: Any
    y_fit: np.ndarray
    tau_fit: np.ndarray
    y_hold: tuple[np.ndarray, np.ndarray] | None
    filter_info: dict[str, Any]


def _prepare_rows(
    log: RobotLog, robot: RobotDescription | None, kind: str | None, options: IdentifyOptions,
) -> _Rows:
    where = log.source.path
    kind = kind or default_kind(robot)
    if kind not in structures.KINDS:
        raise ModelError(f"unknown model kind {kind!r} (choose from {', '.join(structures.KINDS)})")
    cols = match_joints(log.joint_names, robot, where, kind)
    joints = tuple(log.joint_names[c] for c in cols)
    q_raw = log.position[:, cols]
    tau_raw = log.torque[:, cols]
    still = check_motion(q_raw, joints, options.min_motion_rad, where,
                         options.allow_still_joints)
    t = log.time_s
    fs = log.sample_rate_hz
    cutoff = clip_cutoff(options.cutoff_hz, fs, "identification cut-off")
    n = log.n_samples
    if n < 4 * int(np.ceil(fs / cutoff)) + 20:
        raise ModelError(
            f"{where}: log too short to identify a model ({n} samples, {log.duration_s:.3g} s)"
        )
    structure = _structure_for(kind, robot, joints, options, where)
    qf, qd, qdd = zero_phase_derivatives(t, q_raw, cutoff, options.filter_order)
    tau_f = zero_phase_lowpass(tau_raw, fs, cutoff, options.filter_order)
    # everything is band-limited to the cut-off now: keep >= 10 samples per cut-off period
    k1 = max(1, int(fs // (10.0 * cutoff)))
    if k1 > 1:
        qf, qd, qdd, tau_f, t = qf[::k1], qd[::k1], qdd[::k1], tau_f[::k1], t[::k1]
    fs_d = fs / k1
    nd = qf.shape[0]
    edge = int(np.ceil(fs_d / cutoff))
    n_hold = round(options.holdout_fraction * nd)
    use_holdout = (n_hold > 0 and n_hold / fs_d >= options.min_holdout_s
                   and nd - n_hold > 4 * edge + 20)
    split = nd - n_hold if use_holdout else nd
    fit_idx = np.arange(edge, split - edge)
    hold_idx = np.arange(split + edge, nd - edge) if use_holdout else np.arange(0)
    # a long log: fit on every k2-th filtered sample (the rows are strongly correlated)
    k2 = max(1, int(np.ceil((fit_idx.size + hold_idx.size) / options.max_fit_samples)))
    fit_idx, hold_idx = fit_idx[::k2], hold_idx[::k2]
    y_fit, y_hold_arr = _filtered_rows(
        kind, joints, structure, qf, qd, qdd, (fit_idx, hold_idx),
        fs_d, cutoff, options if options.filter_regressor else None, edge,
    )
    y_hold = (y_hold_arr, tau_f[hold_idx]) if use_holdout else None
    return _Rows(kind, joints, structure, still, y_fit, tau_f[fit_idx], y_hold,
                 {
        "method": "butterworth zero-phase (filtfilt) on positions and torques; central "
                  "differences"
                  + ("; regressor columns filtered alike" if options.filter_regressor else ""),
        "cutoff_hz": cutoff, "order": options.filter_order,
        "sample_rate_hz": fs, "edge_trim_samples": edge * k1,
        "decimation": {"filtered_signals": k1, "fit_rows": k2},
        "holdout": {"fraction": options.holdout_fraction if use_holdout else 0.0,
                    "start_s": float(t[split]) if use_holdout else None},
    })


def identify(
    log: RobotLog, *, robot: RobotDescription | None = None, kind: str | None = None,
    options: IdentifyOptions = IdentifyOptions(),
) -> RigidModel:
    """Identify a rough rigid model from a log (method.md §2; eq. 7).

    Positions are smoothed and differentiated without phase lag; the torque and — with
    ``options.filter_regressor`` (default) — every regressor column pass through the same
    zero-phase filter ("parallel filtering"), so that F tau = F(Y) theta holds even for the
    sharp Coulomb term, which a filtered torque alone would smear at velocity reversals.

    Args:
        log: the recording (positions [rad], torques [N·m]).
        robot: robot description (planar/urdf kinematics; joint order). Its joints must be
            exactly the log's joints (any order) — except for a ``urdf`` model, where robot
            joints the log lacks are held at zero and logged joints the URDF lacks are left
            out, each warned about (:func:`match_urdf_joints`).
        kind: ``decoupled``, ``planar``, ``urdf``, or None for :func:`default_kind`.
        options: :class:`IdentifyOptions`.
    Returns:
        The model, with per-joint fit statistics on the fitted part and the held-back part.
    Raises:
        ModelError (no motion, constant joint, too short), RobotDescriptionError (joints
        do not match, kinematics missing, URDF does not parse).
    """
    r = _prepare_rows(log, robot, kind, options)
    return _fit(r.y_fit, r.tau_fit, r.y_hold, kind=r.kind, joints=r.joints,
                structure=r.structure, robot=robot, options=options, where=log.source.path,
                filter_info=r.filter_info, input_sha256=log.source.sha256, still=r.still)


def identify_many(
    logs: Sequence[RobotLog], *, robot: RobotDescription | None = None, kind: str | None = None,
    options: IdentifyOptions = IdentifyOptions(),
) -> RigidModel:
    """Identify one model from several logs of the same robot (e.g. for calibration).

    Each log is filtered and differentiated on its own (no filter runs across the seam
    between two logs); their regressor rows are stacked into one robust fit, and each
    log's held-back tail is stacked into the validation set. ``input_sha256`` of the model
    is the sha256 of the logs' sha256s joined by newlines, in order.
    """
    if not logs:
        raise ModelError("identify_many needs at least one log")
    if len(logs) == 1:
        return identify(logs[0], robot=robot, kind=kind, options=options)
    rows = [_prepare_rows(lg, robot, kind, options) for lg in logs]
    first = rows[0]
    for lg, r in zip(logs[1:], rows[1:], strict=True):
        if r.joints != first.joints or r.kind != first.kind:
            raise ModelError(f"{lg.source.path}: joints {list(r.joints)} differ from "
                             f"{logs[0].source.path}'s {list(first.joints)}")
    y_fit = np.concatenate([r.y_fit for r in rows])
    tau_fit = np.concatenate([r.tau_fit for r in rows])
    holds = [r.y_hold for r in rows if r.y_hold is not None]
    y_hold = ((np.concatenate([h[0] for h in holds]), np.concatenate([h[1] for h in holds]))
              if holds else None)
    digest = hashlib.sha256("\n".join(lg.source.sha256 for lg in logs).encode()).hexdigest()
    info = dict(first.filter_info, logs=[lg.source.path for lg in logs])
    still = first.still
    return _fit(y_fit, tau_fit, y_hold, kind=first.kind, joints=first.joints,
                structure=first.structure, robot=robot, options=options,
                where=", ".join(lg.source.path for lg in logs), filter_info=info,
                input_sha256=digest, still=still)
