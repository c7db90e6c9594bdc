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
Positions that are no motion — noise, whose speed over windows :data:`SMOOTH_FACTOR` times
longer is far lower (:meth:`MotionSketch.smooth`) — say nothing of a unit: such a joint is
not judged.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..columns import column_range

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
#: The smoothness check's windows are this many speed windows long ...
SMOOTH_FACTOR = 10
#: ... and a joint whose speed over them is below this share of its speed over the short
#: windows is noise, not motion (white noise: about 0.1, a random walk 0.3; an arm's
#: motion, whose periods are seconds: about 1).
SMOOTH_RATIO = 0.5
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
        # the smoothness check: windows SMOOTH_FACTOR × longer
        self.long = SMOOTH_FACTOR * self.lag
        self.counts_long = np.zeros_like(self.counts)
        self.tail = np.empty((0, n_joints))  # the last `long` samples fed
        self.seen = 0  # samples fed

    def update(self, position: np.ndarray) -> None:
        """Feed the next (n, J) positions [as read]; NaN (a joint not logged) is skipped,
        and so is a window touching an infinite value. The windows start every ``lag``
        samples of the whole log (the speed windows tile it), whatever the chunks."""
        q = np.asarray(position, dtype=np.float64)
        if q.shape[0] == 0:
            return
        with np.errstate(invalid="ignore", over="ignore"):
            lo, hi = column_range(q, skip_nan=True)  # NaN: not logged
            self.lo, self.hi = np.fmin(self.lo, lo), np.fmax(self.hi, hi)
            both = np.concatenate([self.tail, q])
            base = self.seen - self.tail.shape[0]  # the sample both[0] is
            for counts, length in ((self.counts, self.lag), (self.counts_long, self.long)):
                # windows ending in q: starting from its first row − length on
                first = max(self.tail.shape[0] - length, 0)
                # the starts from `first` on whose sample (base + start) is a multiple of lag
                starts = np.arange(first + (-(base + first)) % self.lag,
                                   max(both.shape[0] - length, first), self.lag)
                if starts.size:
                    self._count(counts, np.abs(both[starts + length] - both[starts])
                                / (self.span_s * length / self.lag))
            self.tail = both[-self.long:]
        self.seen += q.shape[0]

    @staticmethod
    def _count(counts: np.ndarray, speed: np.ndarray) -> None:
        """Add (m, J) window speeds to the (J, bins) histogram ``counts`` (finite ones)."""
        fin = np.isfinite(speed)
        nb = _EDGES.size + 1
        flat = _bins(np.where(fin, speed, 0.0)) + nb * np.arange(speed.shape[1])
        counts += np.bincount(flat[fin], minlength=counts.size).reshape(counts.shape)

    def travel(self) -> np.ndarray:
        """(J,) max − min of each joint's positions [as read]; 0 for a joint never logged."""
        t = self.hi - self.lo
        return np.where(np.isfinite(t), t, 0.0)

    def speed(self, quantile: float = SPEED_QUANTILE) -> np.ndarray:
        """(J,) the ``quantile`` of each joint's window speed [as read per s] (upper bin
        edge: never below the true quantile); 0 without samples."""
        return _quantiles(self.counts, quantile)

    def smooth(self, quantile: float = SPEED_QUANTILE) -> np.ndarray:
        """(J,) bool: whether each joint's positions are a motion, not noise — its speed
        over windows :data:`SMOOTH_FACTOR` × longer is at least :data:`SMOOTH_RATIO` of its
        speed over the short ones (true without samples or speed)."""
        short, long = self.speed(quantile), _quantiles(self.counts_long, quantile)
        return np.asarray((short == 0) | (long >= SMOOTH_RATIO * short), dtype=bool)


def _quantiles(counts: np.ndarray, quantile: float) -> np.ndarray:
    """(J,) the ``quantile`` of each row of a (J, bins) speed histogram: the upper edge of
    its bin (never below the true quantile); 0 for an empty row."""
    out = np.zeros(counts.shape[0])
    for j, c in enumerate(counts):
        total = int(c.sum())
        if total:
            k = int(np.searchsorted(np.cumsum(c), quantile * total))
            out[j] = _EDGES[min(k, _EDGES.size - 1)]
    return out


def _bins(s: np.ndarray) -> np.ndarray:
    """``np.searchsorted(_EDGES, s)`` (the number of edges below each speed ``s`` ≥ 0),
    from the edges' log spacing (an estimate, then set right against the edges): several
    times faster, the same bins."""
    size = _EDGES.size
    with np.errstate(divide="ignore", invalid="ignore"):
        est = np.ceil((np.log10(s) + 6.0) * 50.0)
    k = np.clip(np.nan_to_num(est, nan=0.0, neginf=0.0, posinf=size), 0, size).astype(np.intp)
    k += (k < size) & (_EDGES.take(np.minimum(k, size - 1)) < s)  # an edge below s: up
    k -= (k > 0) & (_EDGES.take(np.maximum(k - 1, 0)) >= s)  # the one before isn't: down
    return k


@dataclass(frozen=True)
class UnitVerdict:
    """What the check found: ``ok``, ``warn`` or ``refuse``, the message (empty when ok)
    and the joints it names."""

    kind: str
    message: str = ""
    joints: tuple[str, ...] = ()


def _impossible(travel: float, speed: float, lim: JointLimits | None) -> bool:
    """A joint's motion that no arm's radians could be (a URDF's ``continuous`` joint may
    travel without bound: only its speed counts)."""
    if lim is not None and lim.kind == "continuous":
        return speed > MAX_JOINT_SPEED_RAD_S
    return travel > MAX_JOINT_TRAVEL_RAD or speed > MAX_JOINT_SPEED_RAD_S


def _beyond_description(travel: float, speed: float, lim: JointLimits | None) -> bool:
    """A joint's motion beyond what its URDF allows (3× its velocity limit, or twice its
    range): this arm's radians cannot be so, but a description may be wrong — warned, never
    refused."""
    if lim is None:
        return False
    if lim.velocity and speed > 3.0 * lim.velocity:
        return True
    return (lim.kind != "continuous" and lim.lower is not None and lim.upper is not None
            and lim.upper > lim.lower and travel > 2.0 * (lim.upper - lim.lower) + 0.1)


def _suspicious(travel: float, speed: float, lim: JointLimits | None) -> bool:
    if lim is not None and lim.kind == "continuous":
        return False
    return travel > SUSPICIOUS_TRAVEL_RAD


def position_unit_verdict(
    where: str, joints: Sequence[str], travel: np.ndarray, speed: np.ndarray,
    limits: dict[str, JointLimits] | None = None, smooth: np.ndarray | None = None,
) -> UnitVerdict:
    """Whether a log's positions can be radians.

    Args:
        where: the log, for the message.  joints: the J joint names (the URDF's names when
            ``limits`` is given, through the robot's joint map).
        travel: (J,) max − min of each joint's positions [as read].
        speed: (J,) each joint's high-percentile speed [as read per s] (:class:`MotionSketch`).
        limits: a URDF's :class:`JointLimits` by joint name, or None.
        smooth: (J,) whether each joint's positions are a motion
            (:meth:`MotionSketch.smooth`); the others are not judged. None: all are.
    Returns:
        ``refuse`` when most joints (more than half of those that move) are impossible as
        radians for any arm and plausible as degrees; ``warn`` when some joint is
        impossible, beyond its URDF's limits (a description may be wrong: never refused)
        or suspicious; else ``ok``.
    """
    lims = limits or {}
    moving = [j for j, t in enumerate(travel)
              if t > 0 and (smooth is None or bool(smooth[j]))]

    def impossible(j: int, scale: float = 1.0, described: bool = False) -> bool:
        test = _beyond_description if described else _impossible
        return test(travel[j] * scale, speed[j] * scale, lims.get(joints[j]))

    bad = [j for j in moving if impossible(j)]
    as_deg = [j for j in bad if not impossible(j, DEG) and not impossible(j, DEG, True)]
    names = tuple(joints[j] for j in bad)
    beyond = [j for j in moving if j not in bad and impossible(j, described=True)]

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
    if beyond:
        far = tuple(joints[j] for j in beyond)
        return UnitVerdict("warn", (
            f"{where}: joint(s) {', '.join(far)} {span(beyond)} read as radians, beyond the "
            "URDF's velocity limit or range: check the position unit (--position-unit "
            "deg|rad), the gear ratio and the robot description"), far)
    odd = [j for j in moving if _suspicious(travel[j], speed[j], lims.get(joints[j]))]
    if odd:
        odd_names = tuple(joints[j] for j in odd)
        return UnitVerdict("warn", (
            f"{where}: joint(s) {', '.join(odd_names)} {span(odd)}, more than a full turn: "
            "check the position unit (--position-unit deg|rad), or that the joint is "
            "continuous"), odd_names)
    return UnitVerdict("ok")


#: A position beyond a URDF joint's limits by more than this share of its range (and at
#: least :data:`LIMIT_MARGIN_RAD`) is "far outside" them: warned by name.
LIMIT_MARGIN_SHARE = 0.1
LIMIT_MARGIN_RAD = 0.1


def robot_joint_limits(robot: object, joints: Sequence[str]) -> dict[str, JointLimits]:
    """The URDF :class:`JointLimits` of the log's ``joints`` (by the log's names, through
    the robot's ``joint_map``) when ``robot`` (a
    :class:`~impactcli.types.RobotDescription`) has URDF kinematics; ``{}`` without one or
    when its URDF cannot be read (the model's reader reports that)."""
    kin = getattr(robot, "kinematics", None)
    if not isinstance(kin, dict) or kin.get("type") != "urdf":
        return {}
    xml = kin.get("urdf_xml")
    try:
        if xml is None and kin.get("robot") is not None:
            from .robot_catalogue import urdf_text

            xml = urdf_text(str(kin["robot"]))
        elif xml is None and kin.get("path") is not None:
            from pathlib import Path

            xml = Path(str(kin["path"])).read_text(encoding="utf-8")
    except Exception:  # a missing extra or file: the model's reader says so
        return {}
    if not isinstance(xml, str):
        return {}
    limits = urdf_joint_limits(xml)
    jmap = getattr(robot, "joint_map", None) or {}
    return {j: limits[jmap.get(j, j)] for j in joints if jmap.get(j, j) in limits}


def limit_warnings(where: str, joints: Sequence[str], lo: np.ndarray, hi: np.ndarray,
                   limits: dict[str, JointLimits]) -> list[str]:
    """One warning per joint whose positions [rad] lie far outside its URDF limits
    (beyond them by more than :data:`LIMIT_MARGIN_SHARE` of the range and
    :data:`LIMIT_MARGIN_RAD`): a unit, offset or sign the description does not share.

    Args:
        lo, hi: (J,) each joint's smallest and largest position [rad] (NaN: not logged).
    """
    out = []
    for k, j in enumerate(joints):
        lim = limits.get(j)
        if lim is None or lim.lower is None or lim.upper is None or lim.upper <= lim.lower \
                or not np.isfinite(lo[k]):
            continue
        margin = max(LIMIT_MARGIN_SHARE * (lim.upper - lim.lower), LIMIT_MARGIN_RAD)
        if lo[k] < lim.lower - margin or hi[k] > lim.upper + margin:
            out.append(f"{where}: joint {j}'s positions {lo[k]:.4g}…{hi[k]:.4g} rad lie far "
                       f"outside its URDF limits {lim.lower:.4g}…{lim.upper:.4g} rad: check "
                       "the position unit (--position-unit deg|rad), the joint's offset and "
                       "sign, and the joint map")
    return out


#: A joint whose travel, read as degrees, is below this share of the calibration logs'
#: position range, and read as radians within :data:`AS_RADIANS_SHARE` of it, travels as the
#: calibration's did in radians and barely at all in degrees.
AS_DEGREES_SHARE = 0.05
AS_RADIANS_SHARE = (0.2, 3.0)


def degrees_against_calibration(where: str, joints: Sequence[str], travel: np.ndarray,
                                calibrated: dict[str, Sequence[float]]) -> str | None:
    """The warning of positions given as degrees (``--position-unit deg``) whose motion the
    calibration's envelope says are radians: every joint that travels (``travel`` (J,) max −
    min [rad], as converted from degrees) travels less than :data:`AS_DEGREES_SHARE` of the
    calibration logs' position range (``calibrated``: joint → [min, max] rad) and, its
    numbers as logged read as radians (× 180/π), at most the top of
    :data:`AS_RADIANS_SHARE` of it; at least one joint's reach its bottom. None when the
    calibration has no such range, a joint travels as degrees could, or none as radians
    would travel as the calibration's did."""
    rows = []
    for j, tr in zip(joints, travel, strict=True):
        rng = calibrated.get(j)
        if rng is None or not np.isfinite(tr) or tr <= 0:
            continue
        width = float(rng[1]) - float(rng[0])
        if width <= 0:
            continue
        raw = tr / DEG
        lo, hi = AS_RADIANS_SHARE
        if tr >= AS_DEGREES_SHARE * width or raw > hi * width:
            return None  # one joint travels as degrees could, or as radians could not
        if raw >= lo * width:  # (one that barely moves either way tells nothing)
            rows.append((j, tr, raw, width))
    if not rows:
        return None
    span = ", ".join(f"{j} {raw:.3g} rad against {w:.3g}" for j, _, raw, w in rows)
    most = max(tr / w for _, tr, _, w in rows)
    return (f"{where}: --position-unit deg reads its positions as degrees, so its joints "
            f"travel at most {100 * most:.2g} % of the calibration logs' range; read as radians "
            f"they travel as those did ({span}): check the position unit — a radians log "
            "read as degrees gives the model, the forces and the envelope a nearly still "
            "arm")
