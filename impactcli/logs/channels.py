"""From per-joint channels to a validated :class:`~impactcli.types.RobotLog`.

Shared by every reader: picks the torque source (docs/formats.md: ``.torque`` when present, else
``.current`` × gear ratio × torque constant, ``--torque-source`` overrides), converts current
to torque, and fills :class:`~impactcli.types.LogSource`.

A joint whose position, or whose torque (the chosen source: torque or current), holds no
finite value at all — an empty or all-NaN column, a sensor not logged — is left out of the
log with a warning and recorded in ``LogSource.joints_dropped`` (the pipeline records it
with the joints it leaves out of detection); a log without any joint left is an error.
An optional signal (velocity, current beside a torque, references) whose column holds no
finite value for one of the joints kept is left out of the log for every joint (a
:class:`~impactcli.types.RobotLog` holds a signal for all its joints or none; the other
joints' columns of it are listed as ignored), with a warning recorded in the repairs
(:func:`empty_signals`).
"""

from __future__ import annotations

import contextlib
import contextvars
import math
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ImpactWarning, LogFormatError
from ..sample_channels import ANGULAR_CHANNELS, CONTROLLER_CHANNELS, OPTIONAL_CHANNELS
from ..types import RobotDescription

TORQUE_SOURCES = ("torque", "current")
TIME_SOURCES = ("log", "publish", "header")


@dataclass
class JointChannels:
    """What a reader found, before torque conversion.

    Attributes:
        t_ns: (N,) int64 sample times [ns].
        joints: J joint names.
        signals: signal name → (N, J) float64 array; columns of joints that lack the
            signal hold NaN and are listed in ``missing``.
        missing: signal name → joint names without that signal.
        current_scale: (J,) N·m per logged current unit from the channel map, NaN where
            the map gives no scale (then the robot description's factor is used).
        ignored: channels present in the file but not used.
        repairs: repairs already made by the reader.
    """

    t_ns: np.ndarray
    joints: tuple[str, ...]
    signals: dict[str, np.ndarray]
    missing: dict[str, list[str]] = field(default_factory=dict)
    current_scale: np.ndarray | None = None
    ignored: list[str] = field(default_factory=list)
    repairs: list[str] = field(default_factory=list)


def check_torque_source(value: str | None, where: str) -> None:
    """Raise LogFormatError when ``value`` is not ``None``, ``torque`` or ``current``."""
    if value is not None and value not in TORQUE_SOURCES:
        raise LogFormatError(f"{where}: unknown torque source {value!r} (torque or current)")


def _has(ch: JointChannels, sig: str, joint: str) -> bool:
    return sig in ch.signals and joint not in ch.missing.get(sig, [])


#: While set (:func:`describing`), a current that cannot be converted to torque (no gear
#: ratio and torque constant) is kept as it is, in A, and said in ``LogSource.notes``
#: instead of an error: ``inspect`` describes a log it cannot yet convert.
_DESCRIBING: contextvars.ContextVar[bool] = contextvars.ContextVar("describing", default=False)


@contextlib.contextmanager
def describing() -> Iterator[None]:
    """Read logs for description only (:data:`_DESCRIBING`)."""
    token = _DESCRIBING.set(True)
    try:
        yield
    finally:
        _DESCRIBING.reset(token)


def describing_only() -> bool:
    """Whether logs are read for description only (inside :func:`describing`): what would
    refuse a log (positions that cannot be radians) is said instead."""
    return _DESCRIBING.get()


@dataclass(frozen=True)
class LogPlan:
    """How a reader's channels become a log's arrays (:func:`plan_log`): decided from which
    channels there are, not from their values, so it applies to any run of samples.

    Attributes:
        torque_source: ``torque`` or ``current``.
        scale: (J,) N·m per current unit (a current source), else None.
        optional: the optional signals the log keeps (velocity, current, references).
        controller: the controller channels there are (``torque_model``, ``torque_ext``).
        ignored: channels present in the file but not used.
        notes: what could not be made of the channels (:func:`describing` only).
        angle_scale: rad per logged unit of the angular signals (:data:`ANGULAR_CHANNELS`:
            ``--position-unit deg`` → π/180), None when they are radians.
    """

    torque_source: str
    scale: np.ndarray | None
    optional: tuple[str, ...]
    controller: tuple[str, ...]
    ignored: tuple[str, ...]
    notes: tuple[str, ...]
    angle_scale: float | None = None


def plan_log(ch: JointChannels, *, path: str, robot: RobotDescription | None,
             torque_source: str | None, position_unit: str | None = None) -> LogPlan:
    """Choose the torque source and its conversion, and the channels kept (module
    docstring); only which channels ``ch`` has is looked at, not their values.
    ``position_unit`` ``deg`` converts the angular signals to radians (after a channel
    map's scale and offset: one conversion path, :func:`assemble`).

    Raises:
        LogFormatError: a joint without position, without any torque signal, or with only
            current and no way to convert it (naming the joint).
    """
    check_torque_source(torque_source, path)
    for j in ch.joints:
        if not _has(ch, "position", j):
            raise LogFormatError(f"{path}: joint {j!r} has no position channel")
    if torque_source is None:
        if all(_has(ch, "torque", j) for j in ch.joints):
            src = "torque"
        else:
            for j in ch.joints:
                if not _has(ch, "torque", j) and not _has(ch, "current", j):
                    raise LogFormatError(
                        f"{path}: joint {j!r} has neither a torque nor a current channel"
                    )
            if not all(_has(ch, "current", j) for j in ch.joints):
                j = next(j for j in ch.joints if not _has(ch, "current", j))
                raise LogFormatError(
                    f"{path}: joint {j!r} has no current channel while others have no torque "
                    "channel; give every joint a torque or every joint a current"
                )
            src = "current"
    else:
        src = torque_source
        for j in ch.joints:
            if not _has(ch, src, j):
                raise LogFormatError(
                    f"{path}: torque source {src!r} requested but joint {j!r} has no {src} channel"
                )
    notes: list[str] = []
    scale: np.ndarray | None = None
    if src == "current":
        scale = _current_scale(ch, path, robot, notes)
    optional = [s for s in OPTIONAL_CHANNELS if s not in CONTROLLER_CHANNELS
                and s in ch.signals and not ch.missing.get(s)]
    controller = tuple(s for s in CONTROLLER_CHANNELS if s in ch.signals)
    # a signal present for some joints only is not usable: list it as ignored
    ignored = list(ch.ignored)
    for s, miss in ch.missing.items():
        if s in CONTROLLER_CHANNELS:
            continue
        if s in ch.signals and miss and s in optional:
            optional.remove(s)
        if s in ch.signals and miss and s not in ("torque", "current", "position"):
            have = [j for j in ch.joints if j not in miss]
            ignored += [f"{j}.{s}" for j in have]
    return LogPlan(torque_source=src, scale=scale, optional=tuple(optional),
                   controller=controller, ignored=tuple(ignored), notes=tuple(notes),
                   angle_scale=math.pi / 180.0 if position_unit == "deg" else None)


def _current_scale(ch: JointChannels, path: str, robot: RobotDescription | None,
                   notes: list[str]) -> np.ndarray:
    """(J,) N·m per current unit: the channel map's scale, else the robot description's
    gear ratio × torque constant (module docstring)."""
    scale = (
        np.full(len(ch.joints), np.nan) if ch.current_scale is None
        else np.asarray(ch.current_scale, dtype=np.float64).copy()
    )
    need = np.isnan(scale)
    if need.any() and robot is None and _DESCRIBING.get():
        names = [ch.joints[int(k)] for k in np.flatnonzero(need)]
        notes.append(f"current of {', '.join(names)} not converted to torque: needs a "
                     "robot description (--robot) with gear_ratio and torque_constant, "
                     "or a scale in the channel map (torque shown in A)")
        scale[need] = 1.0
        need[:] = False
    if need.any():
        if robot is None:
            j = ch.joints[int(np.argmax(need))]
            raise LogFormatError(
                f"{path}: joint {j!r} has only current; converting it to torque needs a "
                "robot description (--robot) with gear_ratio and torque_constant, or a "
                "scale in the channel map"
            )
        by_name = dict(zip(robot.joint_names, robot.torque_scale(), strict=True))
        for k in np.flatnonzero(need):
            j = ch.joints[int(k)]
            if j not in by_name:
                raise LogFormatError(
                    f"{path}: joint {j!r} has only current and is not in the robot "
                    f"description {robot.path or robot.name!r}"
                )
            scale[k] = by_name[j]
    return scale


def assemble(plan: LogPlan, ch: JointChannels) -> dict[str, np.ndarray]:
    """The log's (n, J) arrays of every joint of ``ch`` under ``plan``: ``position``,
    ``torque`` and the optional and controller channels kept (a joint without a
    controller channel holds NaN in it); the angular signals in radians
    (``plan.angle_scale``). Elementwise, so samples may come in any runs."""
    torque = ch.signals["torque"] if plan.scale is None else ch.signals["current"] * plan.scale
    out: dict[str, np.ndarray] = {"position": ch.signals["position"], "torque": torque}
    for s in plan.optional:
        out[s] = ch.signals[s]
    if plan.angle_scale is not None:
        for s in ANGULAR_CHANNELS:
            if s in out:
                out[s] = out[s] * plan.angle_scale
    # the controller's channels are per joint: a joint without one holds NaN (docs/formats.md)
    for s in plan.controller:
        m = np.array(ch.signals[s], dtype=np.float64)
        for j in ch.missing.get(s, []):
            m[:, ch.joints.index(j)] = np.nan
        out[s] = m
    return out


def drop_message(path: str, dropped: list[tuple[str, str]], src: str) -> str:
    """The error when every joint is left out (the scan's finish)."""
    return (f"{path}: no joint has a finite position and {src}: "
            + "; ".join(f"{j}: {why}" for j, why in dropped))


def warn_dropped(path: str, dropped: list[tuple[str, str]]) -> None:
    """Warn about each joint left out of the log (ImpactWarning)."""
    for j, why in dropped:
        warnings.warn(f"{path}: joint {j!r} left out of detection: {why}",
                      ImpactWarning, stacklevel=4)


def empty_signals(joints: tuple[str, ...], finite: dict[str, np.ndarray]
                  ) -> list[tuple[str, list[str]]]:
    """``(signal, joints)`` of the optional signals some kept joint's column of which holds
    no finite value: those signals are left out of the log (module docstring).

    Args:
        joints: the J joints kept.  finite: optional signal → (J,) bool, whether each
            joint's column holds a finite value.
    """
    return [(s, [j for j, ok in zip(joints, f, strict=True) if not ok])
            for s, f in finite.items() if not np.all(f)]


def empty_signal_message(path: str, signal: str, empty: list[str],
                         joints: tuple[str, ...]) -> str:
    """The warning (and repair) for an optional signal left out of the log because the
    columns of the joints ``empty`` hold no finite value."""
    cols = ", ".join(repr(f"{j}.{signal}") for j in empty)
    msg = (f"{path}: column{'s' if len(empty) > 1 else ''} {cols} "
           f"hold{'' if len(empty) > 1 else 's'} no finite value: {signal} is read as not "
           "logged")
    if len(empty) < len(joints):
        msg += ", for every joint (a log has a signal for all its joints or none)"
    return msg


def drop_empty_signals(path: str, joints: tuple[str, ...], finite: dict[str, np.ndarray]
                       ) -> tuple[list[str], list[str], list[str]]:
    """The optional signals to leave out of the log (:func:`empty_signals`), warned.

    Returns:
        (the signals left out, the other joints' channels of them — now ignored —, the
        warnings, also repairs).
    """
    out, ignored, msgs = [], [], []
    for sig, empty in empty_signals(joints, finite):
        out.append(sig)
        ignored += [f"{j}.{sig}" for j in joints if j not in empty]
        msg = empty_signal_message(path, sig, empty, joints)
        msgs.append(msg)
        warnings.warn(msg, ImpactWarning, stacklevel=4)
    return out, ignored, msgs


def empty_joint_reasons(joints: tuple[str, ...], position_finite: np.ndarray,
                        torque_finite: np.ndarray, src: str) -> list[tuple[str, str]]:
    """``(joint, reason)`` of the joints left out of the log.

    Args:
        joints: J names.  position_finite, torque_finite: (J,) bool, whether the column
            holds a finite value.  src: the torque source (``torque`` or ``current``).
    """
    out = []
    for k, j in enumerate(joints):
        for what, ok in (("position", position_finite), (src, torque_finite)):
            if not ok[k]:
                out.append((j, f"its {what} column holds no finite value (not logged?)"))
                break
    return out


def channels_from_columns(
    cmap: Any,
    t_ns: np.ndarray,
    cols: dict[str, np.ndarray],
    keys: dict[tuple[str, int], str],
    ignored: list[str],
    repairs: list[str],
) -> JointChannels:
    """Apply scale/offset and stack per-joint columns into (N, J) signals."""
    n, jn = t_ns.shape[0], len(cmap.joints)
    signals: dict[str, np.ndarray] = {}
    missing: dict[str, list[str]] = {}
    current_scale = np.full(jn, np.nan)
    for sig, per in cmap.signals.items():
        m = np.full((n, jn), np.nan)
        for j, ref in enumerate(per):
            if ref is None:
                missing.setdefault(sig, []).append(cmap.joints[j])
                continue
            v = cols[keys[(sig, j)]]
            if sig == "current":
                if ref.scale is not None:
                    current_scale[j] = ref.scale
                m[:, j] = v  # the current as logged; its scale converts it to torque
                continue
            if ref.scale is not None:
                v = v * ref.scale
            if ref.offset:
                v = v + ref.offset
            m[:, j] = v
        signals[sig] = m
    return JointChannels(
        t_ns=t_ns, joints=cmap.joints, signals=signals, missing=missing,
        current_scale=current_scale, ignored=ignored, repairs=repairs,
    )
