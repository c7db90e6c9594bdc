"""Position units that cannot be right: degrees (or radians of another scale) read as radians.

Positions are read as radians after the reduction (docs/formats.md, "Canonical wide CSV").
A log written in degrees is 57.3 times too large: the model then explains nothing and every
residual looks like a contact of thousands of newtons. Physics tells such a log apart
cheaply: no robot arm's joint turns many times over one log, or faster than
:data:`MAX_JOINT_SPEED_RAD_S`. The check is certain before it refuses — most joints
impossible as radians, and the same numbers plausible as degrees — and only warns where a
joint is merely suspicious. A URDF sharpens it: its ``continuous`` joints may turn without
bound, its revolute joints' limits bound their travel, its velocity limits their speed.

Speeds are a high percentile (:data:`SPEED_QUANTILE`) of the speed over
:data:`SPEED_WINDOW_S` windows, so a wrapped angle or a glitch of a few samples does not count.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: No robot arm's joint reaches this speed [rad/s] (fast wrists: 2π–10 rad/s).
MAX_JOINT_SPEED_RAD_S = 20.0
#: No revolute joint of an arm travels more than this over one log [rad] (two turns).
MAX_JOINT_TRAVEL_RAD = 4 * math.pi
#: A travel above this is suspicious for a joint that is not continuous [rad] (one turn).
SUSPICIOUS_TRAVEL_RAD = 2 * math.pi
#: Degrees to radians.
DEG = math.pi / 180.0
#: Speeds are differences over windows of this length [s] ...
SPEED_WINDOW_S = 0.02
#: ... and the joint's speed is this quantile of them (a few glitches do not count).
SPEED_QUANTILE = 0.99
#: Bins of the speed histogram: log-spaced edges [rad/s], 50 per decade.
_EDGES = np.logspace(-6, 8, 14 * 50 + 1)


@dataclass(frozen=True)
class JointLimits:
    """What a URDF says of one joint: its type, position limits [rad] (None when absent or
    continuous) and velocity limit [rad/s] (None when absent)."""

    kind: str
    lower: float | None = None
    upper: float | None = None
    velocity: float | None = None


def urdf_joint_limits(urdf_xml: str) -> dict[str, JointLimits]:
    """Joint name → :class:`JointLimits` of every revolute or continuous joint of a URDF
    (XML text); other joints are left out. A URDF that does not parse gives ``{}`` (the
    model's reader reports it)."""
    try:
        root = ET.fromstring(urdf_xml)
    except ET.ParseError:
        return {}
    out: dict[str, JointLimits] = {}
    for joint in root.iter("joint"):
        kind, name = joint.get("type", ""), joint.get("name", "")
        if kind not in ("revolute", "continuous") or not name:
            continue
        limit = joint.find("limit")

        def num(attr: str, lim: ET.Element | None = limit) -> float | None:
            try:
                return None if lim is None or lim.get(attr) is None else float(lim.get(attr, ""))
            except ValueError:
                return None

        bounded = kind == "revolute"
        out[name] = JointLimits(kind, num("lower") if bounded else None,
                                num("upper") if bounded else None, num("velocity"))
    return out


class MotionSketch:
    """Per joint, the travel (max − min) and the distribution of speed of positions fed
    chunk by chunk, in bounded memory (a histogram of window speeds).

    Args:
        n_joints: J.  sample_period_s: the log's sample period [s].
    """

    def __init__(self, n_joints: int, sample_period_s: float) -> None:
        self.lo = np.full(n_joints, np.inf)
        self.hi = np.full(n_joints, -np.inf)
        self.lag = max(1, round(SPEED_WINDOW_S / sample_period_s))
        self.span_s = self.lag * sample_period_s
        self.counts = np.zeros((n_joints, _EDGES.size + 1), dtype=np.int64)
        self.tail = np.empty((0, n_joints))

    def update(self, position: np.ndarray) -> None:
        """Feed the next (n, J) positions [as read]; NaN (a joint not logged) is skipped."""
        q = np.asarray(position, dtype=np.float64)
        if q.shape[0] == 0:
            return
        with np.errstate(invalid="ignore"):
            self.lo = np.fmin(self.lo, np.nanmin(q, axis=0, initial=np.inf))
            self.hi = np.fmax(self.hi, np.nanmax(q, axis=0, initial=-np.inf))
        both = np.concatenate([self.tail, q])
        if both.shape[0] > self.lag:
            speed = np.abs(both[self.lag:] - both[:-self.lag]) / self.span_s
            for j in range(q.shape[1]):
                s = speed[:, j]
                s = s[np.isfinite(s)]
                self.counts[j] += np.bincount(np.searchsorted(_EDGES, s),
                                              minlength=_EDGES.size + 1)
        self.tail = both[-self.lag:]

    def travel(self) -> np.ndarray:
        """(J,) max − min of each joint's positions [as read]; 0 for a joint never logged."""
        t = self.hi - self.lo
        return np.where(np.isfinite(t), t, 0.0)

    def speed(self, quantile: float = SPEED_QUANTILE) -> np.ndarray:
        """(J,) the ``quantile`` of each joint's window speed [as read per s] (upper bin
        edge: never below the true quantile); 0 without samples."""
        out = np.zeros(self.counts.shape[0])
        for j, c in enumerate(self.counts):
            total = int(c.sum())
            if total:
                k = int(np.searchsorted(np.cumsum(c), quantile * total))
                out[j] = _EDGES[min(k, _EDGES.size - 1)]
        return out


@dataclass(frozen=True)
class UnitVerdict:
    """What the check found: ``ok``, ``warn`` or ``refuse``, the message (empty when ok)
    and the joints it names."""

    kind: str
    message: str = ""
    joints: tuple[str, ...] = ()


def _impossible(travel: float, speed: float, lim: JointLimits | None) -> bool:
    """A joint's motion that no arm's radians could be."""
    if lim is not None and lim.velocity and speed > 3.0 * lim.velocity:
        return True
    if lim is not None and lim.kind == "continuous":
        return speed > MAX_JOINT_SPEED_RAD_S
    if lim is not None and lim.lower is not None and lim.upper is not None \
            and lim.upper > lim.lower and travel > 2.0 * (lim.upper - lim.lower) + 0.1:
        return True
    return travel > MAX_JOINT_TRAVEL_RAD or speed > MAX_JOINT_SPEED_RAD_S


def _suspicious(travel: float, speed: float, lim: JointLimits | None) -> bool:
    if lim is not None and lim.kind == "continuous":
        return False
    return travel > SUSPICIOUS_TRAVEL_RAD


def position_unit_verdict(
    where: str, joints: Sequence[str], travel: np.ndarray, speed: np.ndarray,
    limits: dict[str, JointLimits] | None = None,
) -> UnitVerdict:
    """Whether a log's positions can be radians.

    Args:
        where: the log, for the message.  joints: the J joint names (the URDF's names when
            ``limits`` is given, through the robot's joint map).
        travel: (J,) max − min of each joint's positions [as read].
        speed: (J,) each joint's high-percentile speed [as read per s] (:class:`MotionSketch`).
        limits: a URDF's :class:`JointLimits` by joint name, or None.
    Returns:
        ``refuse`` when most joints (more than half of those that move) are impossible as
        radians and plausible as degrees; ``warn`` when some joint is impossible or
        suspicious; else ``ok``.
    """
    lims = limits or {}
    moving = [j for j, t in enumerate(travel) if t > 0]
    bad = [j for j in moving if _impossible(travel[j], speed[j], lims.get(joints[j]))]
    as_deg = [j for j in bad
              if not _impossible(travel[j] * DEG, speed[j] * DEG, lims.get(joints[j]))]
    names = tuple(joints[j] for j in bad)

    def span(idx: list[int], scale: float = 1.0) -> str:
        tr = [travel[j] * scale for j in idx]
        sp = [speed[j] * scale for j in idx]
        return (f"travel {min(tr):.3g}–{max(tr):.3g} rad at up to {max(sp):.3g} rad/s"
                if len(idx) > 1 else f"travels {tr[0]:.3g} rad at up to {sp[0]:.3g} rad/s")

    if moving and len(as_deg) * 2 > len(moving):
        joined = ", ".join(joints[j] for j in as_deg)
        return UnitVerdict("refuse", (
            f"{where}: positions look like degrees: joint(s) {joined} {span(as_deg)} read as "
            f"radians — no arm moves so; read as degrees they {span(as_deg, DEG)}. Give "
            "--position-unit deg (or --position-unit rad if they are radians)"), names)
    if bad:
        return UnitVerdict("warn", (
            f"{where}: joint(s) {', '.join(names)} {span(bad)} read as radians, more than an "
            "arm's joint moves: check the position unit (--position-unit deg|rad) and the "
            "gear ratio"), names)
    odd = [j for j in moving if _suspicious(travel[j], speed[j], lims.get(joints[j]))]
    if odd:
        odd_names = tuple(joints[j] for j in odd)
        return UnitVerdict("warn", (
            f"{where}: joint(s) {', '.join(odd_names)} {span(odd)}, more than a full turn: "
            "check the position unit (--position-unit deg|rad), or that the joint is "
            "continuous"), odd_names)
    return UnitVerdict("ok")
