"""Identification of the rough rigid model by robust least squares (docs/method.md §2, eq. 7).

Stack tau(k) = Y(q(k), q'(k), q''(k)) theta over samples and joints and solve for theta:
zero-phase derivatives and the same filter on torques and regressor columns (offline);
unexcited parameters fixed at 0 by pivoted QR; Huber then Tukey bisquare reweighting, so
a contact in the log does not bend the model (:mod:`impactcli.model.fit`; ``coupled`` adds a
ridge on its cross terms chosen by blocked cross-validation); fit statistics on the fitted
part and a held-back last part; fit-sanity warnings (:mod:`impactcli.model.sanity`). Each
step, and why: docs/method.md §2, "Identification". The rows are built in windows fixed by
the sample count (:mod:`impactcli.model.rows`), so :class:`IdentifyStream` fed a log in
chunks of any size gives the rows, and the model, of the log fed whole. Settings:
:class:`~impactcli.model.identify_options.IdentifyOptions`.
"""

from __future__ import annotations

import hashlib
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImpactWarning, ModelError, RobotDescriptionError
from ..logs.robot_files import joint_map_hint
from ..logs.urdf import urdf_joint_names
from ..types import GRAVITY_M_S2, RobotDescription, RobotLog
from . import payload, structures
from .derivatives import clip_cutoff
from .fit import column_errors, fit_ridge, joint_stats, robust_lstsq
from .identify_options import IdentifyOptions
from .rigid import RigidModel
from .rows import Rows, RowsBuilder, RowsPlan
from .sanity import fit_sanity


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
        from ..logs import robot_catalogue as robots

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


def _urdf_joints(log_joints: tuple[str, ...], robot: RobotDescription, where: str,
                 ) -> tuple[list[str], list[str], str, str | None]:
    """The robot's joints its URDF models, those of them logged, how messages name the
    URDF and the shipped robot it is; RobotDescriptionError when none is logged."""
    assert robot.kinematics is not None
    xml, label, shipped = urdf_source(robot.kinematics)
    in_urdf = set(urdf_joint_names(xml, label))
    jm = robot.joint_map or {}
    modelled = [j for j in robot.joint_names if jm.get(j, j) in in_urdf]
    used = [j for j in modelled if j in log_joints]
    if not used:
        raise RobotDescriptionError(
            f"{where}: no logged joint is a joint of the URDF of {label} (log: "
            f"{list(log_joints)}; robot description: {[jm.get(j, j) for j in modelled]}): "
            + joint_map_hint(log_joints, [jm.get(j, j) for j in modelled], shipped))
    return modelled, used, label, shipped


def check_shares_joints(log_joints: tuple[str, ...], robot: RobotDescription | None,
                        where: str) -> None:
    """RobotDescriptionError (exit 3) when the robot shares no joint with the log — the
    check identification makes (:func:`match_urdf_joints`), for every run that is given a
    robot, with a config or without (docs/formats.md, "Robot description": a partial match
    keeps its warnings)."""
    if robot is None:
        return
    if robot.kinematics and robot.kinematics.get("type") == "urdf":
        _urdf_joints(log_joints, robot, where)
        return
    if not set(robot.joint_names) & set(log_joints):
        raise RobotDescriptionError(
            f"{where}: robot description {robot.path or robot.name or ''!s} shares no joint "
            f"with the log (log: {list(log_joints)}; robot description: "
            f"{list(robot.joint_names)})")


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
    modelled, used, label, shipped = _urdf_joints(log_joints, robot, where)
    jm = robot.joint_map or {}
    expected = [jm.get(j, j) for j in modelled]
    if shipped is not None:
        from ..logs import robot_catalogue as robots

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

#: What works on a log without motion: a model or thresholds made on other
#: logs of the same robot.
STILL_HINT = ("a config or a model from other logs of the same robot, with motion, works: "
              "--config CONFIG (from `impactcli calibrate` on logs with motion) or --model "
              "MODEL (from `impactcli identify` on a log with motion)")


def check_motion(
    q: np.ndarray | None, joints: tuple[str, ...], min_motion_rad: float, where: str,
    allow_still: bool = False, ranges: np.ndarray | None = None,
) -> list[str]:
    """ModelError if the log has no motion, or (unless ``allow_still``) a joint stays constant.

    ``q`` (N, J) positions, or their (J,) ``ranges`` (a log read in chunks).
    Returns the names of the joints that stay constant (only with ``allow_still``).
    """
    rng = np.ptp(np.asarray(q), axis=0) if ranges is None else np.asarray(ranges)
    still = [j for j, r in zip(joints, rng, strict=True) if r < min_motion_rad]
    if len(still) == len(joints):
        raise ModelError(
            f"{where}: the log has no motion (every joint moves less than "
            f"{min_motion_rad:g} rad): a model cannot be identified from it; {STILL_HINT}"
        )
    if still:
        listed = ", ".join(f"{j} {rng[joints.index(j)]:.2g} rad" for j in still)
        if allow_still:
            warnings.warn(
                f"{where}: joint(s) stay constant ({listed}): only their constant torque "
                "is modelled", ImpactWarning, stacklevel=3,
            )
            return still
        raise ModelError(
            f"{where}: joint(s) stay constant ({listed}, below {min_motion_rad:g} rad): their "
            "dynamics cannot be identified; record a log in which every joint moves "
            "(or allow still joints)"
        )
    return []


#: Identification's compute per second of a 1 kHz log [s], per kind, as a * J**b (J joints):
#: measured with impactcli.model.identify on 7- and 12-joint logs of 200 and 800 s (2-vCPU
#: x86_64, 2026-11-29): decoupled 5.4 s, coupled 4.3 s, urdf (panda) 19.6 s for 800 s at 7
#: joints; the urdf regressor grows with J squared, the others about linearly (rows capped).
IDENTIFY_COST = {"decoupled": (1.0e-3, 1.0), "coupled": (1.0e-3, 1.0),
                 "planar": (5.0e-4, 2.0), "urdf": (5.0e-4, 2.0)}


def identification_cost(kind: str, n_joints: int, sample_rate_hz: float) -> float:
    """Estimated compute of identifying a ``kind`` model [s per second of log]
    (:data:`IDENTIFY_COST`, linear in the sample rate: the filtering pass reads every
    sample)."""
    a, b = IDENTIFY_COST.get(kind, IDENTIFY_COST["urdf"])
    return a * float(n_joints) ** b * sample_rate_hz / 1000.0


def check_coupled_size(n_joints: int, options: IdentifyOptions, where: str) -> None:
    """Refuse (ScaleLimitError, exit 2) a coupled model whose regressor cannot be held within
    ``options.coupled_max_mb`` even at the rows it needs: J × J(5J+1) numbers a row, so its
    memory grows with the cube of the joint count (20 joints: 0.3 GB at 1,000 rows)."""
    from ..errors import ScaleLimitError
    from .rows import COUPLED_MIN_ROWS

    mb = COUPLED_MIN_ROWS * 8.0 * n_joints * n_joints * (5 * n_joints + 1) / 2**20
    if mb > options.coupled_max_mb:
        raise ScaleLimitError(
            f"{where}: a coupled model of {n_joints} joints needs a regressor of about "
            f"{mb / 1024:.3g} GiB at the {COUPLED_MIN_ROWS} rows it needs (J × J(5J+1) numbers "
            f"a row), above coupled_max_mb = {options.coupled_max_mb:g} MB: use --kind "
            "decoupled (a model per joint)")


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
    if kind == "coupled":
        check_coupled_size(len(joints), options, where)
        base["velocity_products"] = options.coupled_velocity_products
        return base
    kin = robot.kinematics if robot is not None else None
    if not kin or kin.get("type") != kind:
        raise RobotDescriptionError(
            f"{where}: a {kind} model needs a robot description with {kind} kinematics "
            f"(--robot), got {kin.get('type') if kin else 'none'}"
        )
    if kind == "planar":
        base["link_lengths"] = [float(v) for v in kin["link_lengths"]]
        base["gravity"] = [float(v) for v in kin.get("gravity", [0.0, -GRAVITY_M_S2])]
        return base
    if kind == "urdf":
        xml, label, shipped = urdf_source(kin)
        return structures.urdf_structure(xml, joints, base, label,
                                         joint_map=robot.joint_map if robot else None,
                                         robot=shipped)
    raise ModelError(f"unknown model kind {kind!r} (choose from {', '.join(structures.KINDS)})")


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
        joint_names: J names.  kind: ``decoupled``, ``coupled``, ``planar`` or ``urdf``.
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
    hold_still = None
    if holdout is not None:
        hq, hqd, hqdd, htau = (np.asarray(x, dtype=np.float64) for x in holdout)
        y_hold = (structures.regressor(kind, joints, structure, hq, hqd, hqdd), htau)
        hold_still = _still_fraction(hq, hqd, options)
    return _fit(y_reg, tau, y_hold, kind=kind, joints=joints, structure=structure,
                robot=robot, options=options, where=where, filter_info={},
                input_sha256=input_sha256, still=still, hold_still_fraction=hold_still,
                poses=_poses(q), acc_rms=np.sqrt(np.mean(qdd**2, axis=0)), cv_gap=1)


def _still_fraction(q: np.ndarray, qd: np.ndarray, options: IdentifyOptions) -> np.ndarray:
    """(J,) fraction of the samples in which each joint stands still: slower than
    ``still_speed_rad_s`` (1 for a joint whose range stays below ``min_motion_rad``)."""
    frac = np.mean(np.abs(qd) < options.still_speed_rad_s, axis=0)
    return np.asarray(np.where(np.ptp(q, axis=0) < options.min_motion_rad, 1.0, frac))


def _poses(q: np.ndarray, k: int = 8) -> np.ndarray:
    """(<= k, J) evenly spaced rows of ``q``: the poses the sanity of M(q) is checked at."""
    if q.shape[0] == 0:
        return q
    return q[np.unique(np.linspace(0, q.shape[0] - 1, k).round().astype(int))]


def frozen_params(kind: str, joints: tuple[str, ...], names: list[str],
                  still: list[str]) -> set[str]:
    """Parameters fixed at 0 because of still joints: their motion parameters (coupled: all
    of their row but the offset, and their own terms in the other rows)."""
    frozen = {f"{j}.{p}" for j in still for p in MOTION_PARAMS}
    if kind == "coupled":
        for nm in names:
            row, term = nm.split(".", 1)
            if row in still and term != "offset":
                frozen.add(nm)
            if ":" in term and term.split(":", 1)[1] in still:
                frozen.add(nm)
    return frozen


def _fit(
    y_reg: np.ndarray, tau: np.ndarray, y_hold: tuple[np.ndarray, np.ndarray] | None, *,
    kind: str, joints: tuple[str, ...], structure: dict[str, Any],
    robot: RobotDescription | None, options: IdentifyOptions, where: str,
    filter_info: dict[str, Any], input_sha256: str, still: list[str] | None = None,
    hold_still_fraction: np.ndarray | None = None, poses: np.ndarray | None = None,
    acc_rms: np.ndarray | None = None, cv_gap: int = 1,
    lambdas: Sequence[float] | None = None, extra_names: Sequence[str] = (),
    prior: np.ndarray | None = None,
) -> RigidModel:
    """Excitation check, robust fit, statistics and sanity on a stacked regressor (N, J, P).

    The motion parameters (:data:`MOTION_PARAMS`) of the joints in ``still`` are fixed at 0.
    ``hold_still_fraction``: (J,) fraction of the held-back part in which each joint stands
    still (:func:`_still_fraction`);
    ``poses``: a few positions of the log and ``acc_rms`` (J,) its RMS accelerations
    (the urdf sanity check of M(q));
    ``cv_gap``: rows left out on each side of a cross-validation stretch (coupled);
    ``lambdas``: (J,) coupled ridge penalties chosen elsewhere (None: chosen here);
    ``extra_names``: the last columns of the regressor beyond the model's own (the logs'
    payloads, :mod:`impactcli.model.payload`): fitted with it, their values and standard
    errors in ``fit["extra"]``, left out of the model's parameters and of its sanity;
    ``prior``: (N, J) weights of the rows (:func:`impactcli.model.fit.robust_lstsq`).
    """
    names = structures.param_names(kind, joints, structure) + list(extra_names)
    p_own = len(names) - len(extra_names)
    still = list(still or [])
    frozen = frozen_params(kind, joints, names, still)
    n, nj, p = y_reg.shape
    a = y_reg.reshape(n * nj, p)
    pen = (structures.coupled_penalised(joints, structure) if kind == "coupled"
           else np.zeros(p, dtype=bool))
    # excitation: normalised pivoted QR (rows scaled per joint by the torque RMS) of the
    # unpenalised columns (the ridge takes care of the penalised ones)
    trms = np.sqrt(np.mean(tau**2, axis=0))
    rs = np.tile(1.0 / np.maximum(trms, 1e-12 * max(float(trms.max()), 1e-300)), n)
    not_frozen = np.array([nm not in frozen for nm in names], dtype=bool)
    norms = np.sqrt(np.einsum("i,ij,ij->j", rs**2, a, a))
    top = float(norms.max()) if norms.size else 0.0
    live = (norms > 1e-12 * top) & not_frozen
    checked = np.flatnonzero(live & ~pen)
    # column by column into Fortran order, which LAPACK factorises in place: no copy of
    # the (rows × parameters) matrix beside the regressor (memory of a long log's fit)
    an = np.empty((a.shape[0], checked.size), order="F")
    for c, col in enumerate(checked):
        an[:, c] = a[:, col] * rs / norms[col]
    keep = live & pen
    r = np.zeros((0, 0))
    nk = 0
    piv = np.zeros(0, dtype=np.int64)
    if checked.size:
        from scipy.linalg import qr  # identification only (0.3 s to import)

        # "raw": R is cut from the factorised matrix (mode "r" copies all of it into triu)
        _, r, piv = qr(an, mode="raw", pivoting=True, overwrite_a=True)
        d = np.abs(np.diag(r))
        nk = int(np.sum(d > options.drop_tolerance * d[0]))
        keep[checked[piv[:nk]]] = True
    del an
    dropped = [names[i] for i in range(p) if not keep[i] and names[i] not in frozen]
    if dropped:
        warnings.warn(
            f"{where}: the log does not excite {len(dropped)} parameter(s) of the {kind} model "
            f"({', '.join(dropped)}); they are fixed at 0", ImpactWarning, stacklevel=3,
        )
    # the kept columns, in pivot order, are Q R[:nk, :nk] (R upper triangular): the same
    # singular values and right singular vectors from the small triangle
    _, sv, vt = np.linalg.svd(r[:nk, :nk])
    cond = (float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")) if sv.size else 1.0
    if cond > options.condition_warn:
        weak_idx = np.argsort(np.abs(vt[-1]))[::-1][:3]
        weak = [names[i] for i in checked[piv[:nk]][weak_idx]]
        warnings.warn(
            f"{where}: the log excites the {kind} model poorly (condition number {cond:.3g} "
            f"> {options.condition_warn:g}); least determined: {', '.join(weak)}",
            ImpactWarning, stacklevel=3,
        )
    theta = np.zeros(p)
    ridge_info: dict[str, Any] | None = None
    if kind == "coupled":
        th_k, w, info, ridge_info, keep = fit_ridge(
            y_reg, tau, keep, pen, joints, names, options, cv_gap, fixed=lambdas)
    else:
        th_k, w, info = robust_lstsq(y_reg[:, :, keep], tau, options, prior=prior)
    theta[keep] = th_k
    if "robust_scale_nm" in info:  # per joint: a table keyed by joint name
        info = info | {"robust_scale_nm": dict(zip(joints, info["robust_scale_nm"],
                                                   strict=True))}
    res = (a @ theta).reshape(n, nj) - tau
    fit: dict[str, Any] = {
        "method": f"robust least squares ({options.robust})"
                  + (", ridge on the cross terms" if kind == "coupled" else ""),
        "n_samples_fit": int(n),
        "n_samples_holdout": 0,
        "condition_number": cond,
        "unexcited_parameters": dropped,
        "still_joints": still,
        "robust": {
            **info,
            "downweighted_fraction": {
                nm: float(np.mean(w[:, j] < 0.5)) for j, nm in enumerate(joints)
            },
        },
        "joints": {"fit": joint_stats(res, tau, joints, still), "holdout": None},
        "options": asdict(options),
    }
    if ridge_info is not None:
        fit["ridge"] = ridge_info
    hold_still: list[str] = []
    if y_hold is not None:
        yh, htau = y_hold
        if hold_still_fraction is not None:
            hold_still = [j for j, fr in zip(joints, hold_still_fraction, strict=True)
                          if j in still or fr > 0.5]
        fit["n_samples_holdout"] = int(yh.shape[0])
        fit["joints"]["holdout"] = joint_stats(
            np.asarray(yh @ theta) - htau, htau, joints, hold_still)
    if extra_names:
        fit["extra"] = column_errors(a, res, nj, theta, keep, p_own, extra_names)
        tau = tau - np.einsum("njp,p->nj", y_reg[:, :, p_own:], theta[p_own:])
        y_reg, theta, names = y_reg[:, :, :p_own], theta[:p_own], names[:p_own]
    fit["sanity"] = fit_sanity(
        kind, joints, names, theta, y_reg, tau, fit, still, hold_still,
        hold_still_fraction, poses, acc_rms, structure, options, where
    ) if options.check_sanity else []
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


@dataclass
class IdentifyStream:
    """Identification fed a log's samples in order, whole or chunk by chunk: state in,
    state out (:class:`impactcli.model.rows.RowsBuilder` — the same rows, bit for bit,
    however the log arrives). :func:`identify` is it fed one whole log.

    Use :meth:`start`, then :meth:`feed` every sample in order, then :meth:`finish`.
    """

    builder: RowsBuilder
    cols: list[int]
    robot: RobotDescription | None
    options: IdentifyOptions
    where: str
    input_sha256: str

    @classmethod
    def start(cls, joint_names: Sequence[str], n: int, sample_rate_hz: float, duration_s: float, *,
              robot: RobotDescription | None = None, kind: str | None = None,
              options: IdentifyOptions = IdentifyOptions(), where: str = "log",
              input_sha256: str = "") -> IdentifyStream:
        """Plan the identification of a log of ``n`` samples at ``sample_rate_hz`` [Hz] whose
        columns are ``joint_names`` (raises what :func:`identify` raises before any sample)."""
        kind = kind or default_kind(robot)
        if kind not in structures.KINDS:
            raise ModelError(
                f"unknown model kind {kind!r} (choose from {', '.join(structures.KINDS)})")
        cols = match_joints(tuple(joint_names), robot, where, kind)
        joints = tuple(joint_names[c] for c in cols)
        cutoff = clip_cutoff(options.cutoff_hz, sample_rate_hz, "identification cut-off")
        if n < 4 * int(np.ceil(sample_rate_hz / cutoff)) + 20:
            raise ModelError(
                f"{where}: log too short to identify a model ({n} samples, {duration_s:.3g} s)"
            )
        structure = _structure_for(kind, robot, joints, options, where)
        plan = RowsPlan.make(n, sample_rate_hz, cutoff, options, kind, len(joints),
                             len(structures.param_names(kind, joints, structure)))
        builder = RowsBuilder(plan, kind, joints, structure, options.filter_order,
                              options.filter_regressor)
        return cls(builder, list(cols), robot, options, where, input_sha256)

    def feed(self, t: np.ndarray, q: np.ndarray, tau: np.ndarray) -> None:
        """The next samples: (m,) times [s], (m, J) positions [rad] and torques [N·m] in
        the order of the joint names :meth:`start` was given."""
        self.builder.feed(t, np.asarray(q)[:, self.cols], np.asarray(tau)[:, self.cols])

    def rows(self) -> Rows:
        """The filtered rows, once every sample came (checks the motion first)."""
        b, o, p = self.builder, self.options, self.builder.plan
        still = check_motion(None, b.joints, o.min_motion_rad, self.where,
                             o.allow_still_joints, ranges=b.ranges())
        info = {
            "method": "butterworth zero-phase (filtfilt) on positions and torques; central "
                      "differences"
                      + ("; regressor columns filtered alike" if o.filter_regressor else ""),
            "cutoff_hz": p.cutoff, "order": o.filter_order,
            "sample_rate_hz": p.sample_rate_hz, "edge_trim_samples": p.edge * p.k1,
            "decimation": {"filtered_signals": p.k1, "fit_rows": p.k2},
        }
        return b.finish(still, info, o, _still_fraction, _poses)

    def finish(self) -> RigidModel:
        """The identified model."""
        return fit_rows([self.rows()], [self.where], robot=self.robot, options=self.options,
                        input_sha256=self.input_sha256)


def prepare_rows(
    log: RobotLog, robot: RobotDescription | None, kind: str | None, options: IdentifyOptions,
) -> Rows:
    """The filtered regressor rows of one log in memory (what :func:`identify` fits)."""
    s = _start(log, robot, kind, options)
    return s.rows()


def fit_rows(
    rows: Sequence[Rows], paths: Sequence[str], *, robot: RobotDescription | None,
    options: IdentifyOptions, input_sha256: str, lambdas: Sequence[float] | None = None,
    payloads: bool = False,
) -> RigidModel:
    """The model fitted on the rows of one or more logs (``paths``: their names), stacked:
    each log's fitted rows into one robust fit, each log's held-back tail into the
    validation set. One log: exactly :meth:`IdentifyStream.finish`. ``lambdas``: the coupled
    ridge penalties per joint chosen elsewhere (:mod:`impactcli.model.selection`).
    ``payloads`` (two or more logs of a kind with kinematics): a payload per log fitted
    jointly with the arm (:mod:`impactcli.model.payload`), recorded in
    ``fit["payloads"]``; the model's parameters carry the lightest log's load."""
    if len(rows) == 1:
        r = rows[0]
        return _fit(r.y_fit, r.tau_fit, r.y_hold, kind=r.kind, joints=r.joints,
                    structure=r.structure, robot=robot, options=options,
                    where=paths[0], filter_info=r.filter_info,
                    input_sha256=input_sha256, still=r.still,
                    hold_still_fraction=r.hold_still_fraction, poses=r.poses,
                    acc_rms=r.acc_rms, cv_gap=r.cv_gap, lambdas=lambdas)
    first = rows[0]
    for path, r in zip(paths[1:], rows[1:], strict=True):
        if r.joints != first.joints or r.kind != first.kind:
            raise ModelError(f"{path}: joints {list(r.joints)} differ from "
                             f"{paths[0]}'s {list(first.joints)}")
    pay = payload.basis(first.kind, first.joints, first.structure) if payloads else None
    extra: list[str] = []
    prior = None
    if pay is None:
        y_fit = np.concatenate([r.y_fit for r in rows])
        y_holds = [r.y_hold[0] for r in rows if r.y_hold is not None]
    else:
        extra = [f"payload{k}.{nm}" for k in range(1, len(rows)) for nm in pay[1]]
        ys = payload.augment([r.y_fit for r in rows], pay[0])
        prior = payload.log_weights(ys, [r.tau_fit for r in rows], options)
        y_fit = np.concatenate(ys)
        y_holds = [y for r, y in zip(rows, payload.augment(
            [r.y_hold[0] if r.y_hold is not None else r.y_fit[:0] for r in rows], pay[0]),
            strict=True) if r.y_hold is not None]
    tau_fit = np.concatenate([r.tau_fit for r in rows])
    holds = [r.y_hold for r in rows if r.y_hold is not None]
    y_hold = ((np.concatenate(y_holds), np.concatenate([h[1] for h in holds]))
              if holds else None)
    info = dict(first.filter_info, logs=list(paths))
    fracs = [(r.hold_still_fraction, r.y_hold[0].shape[0]) for r in rows
             if r.hold_still_fraction is not None and r.y_hold is not None]
    poses = [r.poses for r in rows if r.poses is not None]
    accs = [r.acc_rms for r in rows if r.acc_rms is not None]
    model = _fit(y_fit, tau_fit, y_hold, kind=first.kind, joints=first.joints,
                structure=first.structure, robot=robot, options=options,
                where=", ".join(paths), filter_info=info,
                input_sha256=input_sha256, still=first.still,
                hold_still_fraction=(np.average([f for f, _ in fracs], axis=0,
                                                weights=[max(k, 1) for _, k in fracs])
                                     if fracs else None),
                poses=np.concatenate(poses) if poses else None,
                acc_rms=np.max(accs, axis=0) if accs else None,
                cv_gap=max(r.cv_gap for r in rows), lambdas=lambdas, extra_names=extra,
                prior=prior)
    if pay is None:
        return model
    return payload.with_log_payloads(model, pay[0], pay[1], paths)


def many_sha256(logs: Sequence[RobotLog]) -> str:
    """The ``input_sha256`` of a model identified on several logs: the sha256 of their
    sha256s joined by newlines, in order (one log: its own)."""
    if len(logs) == 1:
        return logs[0].source.sha256
    return hashlib.sha256("\n".join(lg.source.sha256 for lg in logs).encode()).hexdigest()


def _start(log: RobotLog, robot: RobotDescription | None, kind: str | None,
           options: IdentifyOptions) -> IdentifyStream:
    """:class:`IdentifyStream` fed the whole log."""
    s = IdentifyStream.start(log.joint_names, log.n_samples, log.sample_rate_hz,
                             log.duration_s, robot=robot, kind=kind, options=options,
                             where=log.source.path, input_sha256=log.source.sha256)
    s.feed(log.time_s, log.position, log.torque)
    return s


def identify(
    log: RobotLog, *, robot: RobotDescription | None = None, kind: str | None = None,
    options: IdentifyOptions = IdentifyOptions(),
) -> RigidModel:
    """Identify a rough rigid model from a log (docs/method.md §2; eq. 7).

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
        kind: ``decoupled``, ``coupled``, ``planar``, ``urdf``, or None for
            :func:`default_kind`.
        options: :class:`IdentifyOptions`.
    Returns:
        The model, with per-joint fit statistics on the fitted part and the held-back part.
    Raises:
        ModelError (no motion, constant joint, too short), RobotDescriptionError (joints
        do not match, kinematics missing, URDF does not parse).
    """
    return _start(log, robot, kind, options).finish()


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
    rows = [prepare_rows(lg, robot, kind, options) for lg in logs]
    return fit_rows(rows, [lg.source.path for lg in logs], robot=robot, options=options,
                    input_sha256=many_sha256(logs))
