"""Robot descriptions (formats.md, "Robot description") and ground-truth labels files."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..errors import LabelsError, RobotDescriptionError
from ..types import ContactLabel, JointSpec, Labels, RobotDescription
from .structured import load_mapping


def _num(value: Any, where: str, field: str, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RobotDescriptionError(f"{where}: {field} must be a number, got {value!r}")
    v = float(value)
    if positive and not v > 0:
        raise RobotDescriptionError(f"{where}: {field} must be positive, got {value!r}")
    return v


def robot_from_dict(d: dict[str, Any], where: str = "robot description") -> RobotDescription:
    """Build and validate a :class:`RobotDescription` from its mapping form."""
    joints_raw = d.get("joints")
    if not isinstance(joints_raw, list) or not joints_raw:
        raise RobotDescriptionError(f"{where}: 'joints' must be a non-empty list")
    joints = []
    for i, jd in enumerate(joints_raw):
        if not isinstance(jd, dict) or not isinstance(jd.get("name"), str):
            raise RobotDescriptionError(f"{where}: joints[{i}] needs a string 'name'")
        gr = _num(jd.get("gear_ratio", 1.0), where, f"joints[{i}].gear_ratio")
        kt_raw = jd.get("torque_constant")
        kt = None if kt_raw is None else _num(kt_raw, where, f"joints[{i}].torque_constant")
        joints.append(JointSpec(name=jd["name"], gear_ratio=gr, torque_constant=kt))
    kin = d.get("kinematics")
    if kin is not None:
        if not isinstance(kin, dict) or kin.get("type") not in ("planar", "urdf"):
            raise RobotDescriptionError(
                f"{where}: kinematics must be null or have type 'planar' or 'urdf'"
            )
        if kin["type"] == "planar":
            ll = kin.get("link_lengths")
            if not isinstance(ll, list) or len(ll) != len(joints):
                raise RobotDescriptionError(
                    f"{where}: planar kinematics needs one link length per joint "
                    f"({len(joints)}), got {ll!r}"
                )
            for k, v in enumerate(ll):
                _num(v, where, f"kinematics.link_lengths[{k}]")
            g = kin.get("gravity", [0.0, -9.81])
            if not isinstance(g, list) or len(g) != 2:
                raise RobotDescriptionError(f"{where}: kinematics.gravity must be [gx, gy]")
            kin = {"type": "planar", "link_lengths": [float(v) for v in ll],
                   "gravity": [float(v) for v in g]}
        else:
            if not isinstance(kin.get("path"), str):
                raise RobotDescriptionError(f"{where}: urdf kinematics needs a 'path'")
            kin = dict(kin)
    nominal = d.get("nominal")
    if nominal is not None and not isinstance(nominal, dict):
        raise RobotDescriptionError(f"{where}: 'nominal' must be a mapping")
    return RobotDescription(
        joints=tuple(joints), kinematics=kin, nominal=nominal,
        name=str(d.get("name", "")), path=where,
    )


def read_robot(path: str | os.PathLike[str]) -> RobotDescription:
    """Read a robot description from JSON or YAML.

    A relative URDF ``path`` is resolved against the description's folder.
    """
    d = load_mapping(path, RobotDescriptionError, "robot description")
    robot = robot_from_dict(d, str(path))
    if robot.kinematics and robot.kinematics["type"] == "urdf":
        urdf = Path(robot.kinematics["path"])
        if not urdf.is_absolute():
            urdf = Path(path).parent / urdf
        kin = dict(robot.kinematics, path=str(urdf))
        robot = RobotDescription(robot.joints, kin, robot.nominal, robot.name, robot.path)
    return robot


def write_robot(robot: RobotDescription, path: str | os.PathLike[str]) -> None:
    """Write a robot description as JSON (atomically)."""
    from .._fs import atomic_write_text

    atomic_write_text(path, json.dumps(robot.to_dict(), indent=2) + "\n")


def labels_from_dict(d: dict[str, Any], where: str = "labels") -> Labels:
    """Build and validate :class:`Labels` from the labels mapping (formats.md)."""
    evs = d.get("events")
    if not isinstance(evs, list):
        raise LabelsError(f"{where}: 'events' must be a list")
    out = []
    for i, e in enumerate(evs):
        if not isinstance(e, dict):
            raise LabelsError(f"{where}: events[{i}] must be a mapping")
        try:
            start, end = float(e["start"]), float(e["end"])
            peak = float(e["peak_force"])
            kind, link = str(e["kind"]), int(e["link"])
        except (KeyError, TypeError, ValueError) as err:
            raise LabelsError(
                f"{where}: events[{i}] is missing or has a bad field: {err}") from None
        known = ("start", "end", "peak_force", "kind", "link")
        extra = {k: v for k, v in e.items() if k not in known}
        out.append(ContactLabel(start, end, peak, kind, link, extra))
    try:
        rate = float(d["sample_rate"])
    except (KeyError, TypeError, ValueError):
        raise LabelsError(f"{where}: 'sample_rate' (Hz) is missing or not a number") from None
    return Labels(events=tuple(out), sample_rate=rate, path=where)


def read_labels(path: str | os.PathLike[str]) -> Labels:
    """Read a ground-truth labels JSON file."""
    return labels_from_dict(load_mapping(path, LabelsError, "labels"), str(path))


def write_labels(labels: Labels, path: str | os.PathLike[str]) -> None:
    """Write labels as JSON (atomically)."""
    from .._fs import atomic_write_text

    atomic_write_text(path, json.dumps(labels.to_dict(), indent=2) + "\n")
