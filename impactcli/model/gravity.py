"""The log's torque scale against physics: the gravity torque a robot description's masses
and lengths predict, compared with the torque the log implies (its torque columns, or
current × torque constant × gear ratio), over the log's slow poses.

The description's gravity torque g(q) (:func:`nominal_gravity`): a planar description's
``nominal`` link masses and centres of mass (fractions of the link lengths, 0.5 when not
given) under its ``gravity``; a URDF's inertials (Pinocchio, the ``urdf`` extra). Nominal
masses may be wrong, but not by a factor of 10: a unit error is.

The comparison (:func:`scale_check`) per joint, over the sampled poses where every joint
moves slowly (below :data:`SLOW_RAD_S`: gravity dominates the torque there) and where the
joint's predicted gravity torque is large — at least :data:`LOADED_SHARE` of the largest
any joint carries over the log, so far above the torque's noise, its friction and its
offset — is the median of τ_log / g(q): the joint's scale k, robust to the contacts and
the accelerations some of those poses carry. A joint with fewer than :data:`MIN_POSES`
such poses is not judged. The verdict over the judged joints (their median k, when they
agree within a factor of :data:`AGREE_FACTOR`):

- **refuse** (exit 3) when k sits within a factor of :data:`CERTAIN_FACTOR` of a clean unit
  factor — 1000 or 1/1000 (A vs mA, N·m vs N·mm), a joint's gear ratio or its inverse
  (motor- vs joint-side), a gear ratio counting only above :data:`CERTAIN_FACTOR` ×
  :data:`WARN_FACTOR` = 6 (nearer 1, a payload or rough masses could make it);
- **warn** when k is off 1 by more than :data:`WARN_FACTOR` otherwise;
- **ok** else. Without masses, or with no joint to judge, the scale is **unverified**, and
  the run says so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..types import GRAVITY_M_S2, RobotDescription

#: A pose is slow when every joint moves slower than this [rad/s].
SLOW_RAD_S = 0.3
#: At least this many slow poses are needed to judge the scale.
MIN_POSES = 50
#: A pose judges a joint when the joint's predicted gravity torque there is at least this
#: share of the largest any joint carries over the log's slow poses.
LOADED_SHARE = 0.3
#: The judged joints' scales must agree within this factor for a verdict.
AGREE_FACTOR = 2.0
#: The log's torque and the description's gravity torque agree when within this factor;
#: beyond it, within WARN_FACTOR, they are of one order only (said so).
CLOSE_FACTOR = 1.25
#: A scale within this factor of a clean unit factor is certain: refused.
CERTAIN_FACTOR = 2.0
#: A scale off 1 by more than this factor (and no clean unit factor) is warned of.
WARN_FACTOR = 3.0


def nominal_gravity(robot: RobotDescription | None, joints: Sequence[str],
                    q: np.ndarray) -> np.ndarray | None:
    """(n, J) the description's gravity torque [N·m] at the (n, J) positions [rad] of
    ``joints`` (the log's), NaN for a joint the description does not model; None when the
    description gives no masses (or the chain's joints are not all logged)."""
    if robot is None or not robot.kinematics:
        return None
    kin = robot.kinematics
    if kin.get("type") == "planar":
        return _planar_gravity(robot, joints, q)
    if kin.get("type") == "urdf":
        return _urdf_gravity(robot, joints, q)
    return None


def _planar_gravity(robot: RobotDescription, joints: Sequence[str],
                    q: np.ndarray) -> np.ndarray | None:
    nominal = robot.nominal or {}
    kin = robot.kinematics or {}
    chain = [j.name for j in robot.joints]
    masses = nominal.get("link_masses")
    lengths = np.asarray(kin.get("link_lengths") or [], dtype=np.float64)
    if masses is None or len(masses) != len(chain) or len(lengths) != len(chain):
        return None
    if not set(chain) <= set(joints):
        return None
    m = np.asarray(masses, dtype=np.float64)
    frac = np.asarray(nominal.get("com_fractions") or [0.5] * len(chain), dtype=np.float64)
    grav = np.asarray(kin.get("gravity") or [0.0, -GRAVITY_M_S2], dtype=np.float64)
    qc = q[:, [list(joints).index(j) for j in chain]]
    phi = np.cumsum(qc, axis=1)  # (n, L) absolute link angles
    u = np.stack((np.cos(phi), np.sin(phi)), axis=-1)  # (n, L, 2)
    ends = np.cumsum(lengths[None, :, None] * u, axis=1)
    starts = np.concatenate((np.zeros_like(ends[:, :1]), ends[:, :-1]), axis=1)
    com = starts + (frac * lengths)[None, :, None] * u
    # the torque that holds the arm, τ_j = ∂U/∂q_j with U = −Σ m_i g·p_ci:
    # τ_j = −Σ_{i≥j} m_i g·(ẑ × (p_ci − p_j))
    out = np.full(q.shape, np.nan)
    for jj, name in enumerate(chain):
        r = com[:, jj:, :] - starts[:, jj:jj + 1, :]  # (n, L−j, 2)
        dp = np.stack((-r[..., 1], r[..., 0]), axis=-1)  # ẑ × r
        out[:, list(joints).index(name)] = -np.einsum("nlk,l,k->n", dp, m[jj:], grav)
    return out


def _urdf_gravity(robot: RobotDescription, joints: Sequence[str],
                  q: np.ndarray) -> np.ndarray | None:
    from ..errors import ImpactError
    from ..logs.urdf import pinocchio, reduced_model
    from .identification import urdf_source

    try:
        pin = pinocchio()
        xml, label, _ = urdf_source(robot.kinematics or {})
        jm = robot.joint_map or {}
        logged = [j for j in joints if j in {s.name for s in robot.joints}]
        model = reduced_model(xml, tuple(str(jm.get(j, j)) for j in logged), label)
    except (ImpactError, ImportError, RuntimeError, ValueError):
        return None
    if sum(float(i.mass) for i in model.inertias) <= 0.0:
        return None
    data = model.createData()
    ids = [model.getJointId(str(jm.get(j, j))) for j in logged]
    iv = [model.joints[i].idx_v for i in ids]
    cols = [list(joints).index(j) for j in logged]
    qv = np.tile(pin.neutral(model), (q.shape[0], 1))
    for c, i in zip(cols, ids, strict=True):
        a = model.joints[i].idx_q
        if model.joints[i].nq == 1:
            qv[:, a] = q[:, c]
        else:  # a continuous joint: (cos, sin)
            qv[:, a], qv[:, a + 1] = np.cos(q[:, c]), np.sin(q[:, c])
    out = np.full(q.shape, np.nan)
    for k in range(q.shape[0]):
        out[k, cols] = pin.computeGeneralizedGravity(model, data, qv[k])[iv]
    return out


@dataclass(frozen=True)
class ScaleVerdict:
    """The torque scale's verdict (module docstring): ``kind`` ``refuse``, ``warn``, ``ok``
    or ``unverified``; ``scale`` the judged joints' median k (None when not judged),
    ``per_joint`` each judged joint's k, ``message`` the sentence the run says."""

    kind: str
    scale: float | None = None
    per_joint: dict[str, float] = field(default_factory=dict)
    message: str = ""

    @property
    def order_only(self) -> bool:
        """``ok`` but of one order only: some joint's k beyond :data:`CLOSE_FACTOR` of 1,
        within :data:`WARN_FACTOR` (forces are as good as that ratio: the run says so)."""
        return self.kind == "ok" and any(not 1.0 / CLOSE_FACTOR <= k <= CLOSE_FACTOR
                                         for k in self.per_joint.values())

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (timeline ``input.torque_scale``)."""
        return {"verdict": self.kind, "scale": self.scale, "per_joint": dict(self.per_joint),
                "message": self.message}


def clean_factors(gear_ratios: Sequence[float]) -> list[tuple[float, str]]:
    """The unit factors a scale error is made of, with their likely cause."""
    out = [(1000.0, "the torque or current is 1000× too large: mA logged as A, or N·mm "
                    "as N·m"),
           (1e-3, "the torque or current is 1000× too small: A logged as mA, or kN·m")]
    # a factor is told from a payload or rough masses only well beyond the warned band
    for n in sorted({float(r) for r in gear_ratios
                     if r and abs(float(r)) > CERTAIN_FACTOR * WARN_FACTOR}):
        out.append((n, f"the torque is {n:g}× too large: the gear ratio applied twice, or a "
                       "motor-side value multiplied by it"))
        out.append((1.0 / n, f"the torque is motor-side (÷ the gear ratio {n:g}): give "
                             "the joint-side torque, or the current with the gear ratio"))
    return out


def scale_check(where: str, joints: Sequence[str], g: np.ndarray, tau: np.ndarray,
                speed: np.ndarray, gear_ratios: Sequence[float]) -> ScaleVerdict:
    """The torque scale's verdict over sampled poses (module docstring): ``g``, ``tau``
    (n, J) [N·m], ``speed`` (n, J) |q̇| [rad/s]."""
    slow = np.all(np.isfinite(speed) & (speed < SLOW_RAD_S), axis=1)
    if int(slow.sum()) < MIN_POSES:
        return ScaleVerdict("unverified", message=(
            f"{where}: the torque scale is not verified: fewer than {MIN_POSES} slow poses "
            "to compare the log's torque with the description's gravity torque"))
    gs, ts = g[slow], tau[slow]
    top = float(np.nanmax(np.abs(gs))) if np.isfinite(gs).any() else 0.0
    per: dict[str, float] = {}
    for j, name in enumerate(joints):
        with np.errstate(invalid="ignore"):
            loaded = (np.abs(gs[:, j]) >= LOADED_SHARE * top) & np.isfinite(ts[:, j])
        if top > 0 and int(loaded.sum()) >= MIN_POSES:
            per[name] = float(np.median(ts[loaded, j] / gs[loaded, j]))
    if not per:
        return ScaleVerdict("unverified", message=(
            f"{where}: the torque scale is not verified: no joint carries enough gravity "
            f"torque over {MIN_POSES} of the log's slow poses to compare"))
    ks = np.array(list(per.values()))
    med = float(np.median(ks))
    text = ", ".join(f"{n} {k:.3g}" for n, k in per.items())
    what = (f"the log's torque over the description's gravity torque, on the slow poses: "
            f"{text}")
    fix = ("; if the description's masses are wrong, correct them; else fix the unit "
           "(a channel map's scale, the torque constant or gear ratio)")
    agree = med > 0 and bool(np.all(ks > 0)) and float(ks.max() / ks.min()) <= AGREE_FACTOR
    if agree:
        for factor, cause in clean_factors(gear_ratios):
            if 1.0 / CERTAIN_FACTOR <= med / factor <= CERTAIN_FACTOR:
                return ScaleVerdict("refuse", med, per, (
                    f"{where}: the torque is off by ~{med:.3g}× ({what}): {cause}{fix}"))
    if med <= 0:
        return ScaleVerdict("warn", med, per, (
            f"{where}: the torque's sign is opposite to the description's gravity torque "
            f"({what}): check the joints' direction and the torque's sign{fix}"))
    if not 1.0 / WARN_FACTOR <= med <= WARN_FACTOR:
        return ScaleVerdict("warn", med, per, (
            f"{where}: the torque may be off by ~{med:.3g}× ({what}): forces and "
            f"thresholds in N·m may be wrong{fix}"))
    close = bool(np.all((ks >= 1.0 / CLOSE_FACTOR) & (ks <= CLOSE_FACTOR)))
    return ScaleVerdict("ok", med, per, (
        f"{where}: the torque scale agrees with the description's gravity torque "
        f"(~{med:.2g}×; {text})" if close else
        f"{where}: the torque scale is of the order of the description's gravity torque "
        f"(~{med:.2g}×; {text}): within the {WARN_FACTOR:g}× this check tells a unit error "
        "from, not an agreement — another arm's description, a payload or rough masses "
        "differ by that much, and forces in N are as good as that ratio"))
