"""Robot descriptions (docs/formats.md, "Robot description") and ground-truth labels files.

``--robot`` takes a file (JSON or YAML), a URL, or the name of a robot the tool ships
(:mod:`impactcli.logs.robot_catalogue`; a path that exists wins). A shipped robot given
by name is its URDF's arm joints (gear ratio 1, no torque constant) with kinematics
``{"type": "urdf", "robot": NAME}``; a file can name one too, with its own joints (gear
ratios, torque constants) and a ``joint_map`` {log joint: URDF joint} for names that differ.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..errors import LabelsError, RobotDescriptionError
from ..files import load_mapping
from ..types import GRAVITY_M_S2, ContactLabel, JointSpec, Labels, RobotDescription
from . import robot_catalogue as robots


def _num(value: Any, where: str, field: str, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RobotDescriptionError(f"{where}: {field} must be a number, got {value!r}")
    v = float(value)
    if positive and not v > 0:
        raise RobotDescriptionError(f"{where}: {field} must be positive, got {value!r}")
    return v


def _joint_map(d: dict[str, Any], where: str) -> dict[str, str] | None:
    raw = d.get("joint_map")
    if raw is None:
        return None
    if not isinstance(raw, dict) or not all(
            isinstance(k, str) and isinstance(v, str) and k and v for k, v in raw.items()):
        raise RobotDescriptionError(
            f"{where}: joint_map must map log joint names to URDF joint names (strings)")
    dup = sorted({v for v in raw.values() if list(raw.values()).count(v) > 1})
    if dup:
        raise RobotDescriptionError(f"{where}: joint_map maps several log joints to {dup}")
    return dict(raw)


def _urdf_kinematics(kin: dict[str, Any], where: str) -> dict[str, Any]:
    has_path, has_robot = kin.get("path") is not None, kin.get("robot") is not None
    if has_path == has_robot:
        raise RobotDescriptionError(
            f"{where}: urdf kinematics needs a 'path' or a 'robot' (a shipped robot's name: "
            f"{', '.join(r.name for r in robots.CATALOGUE)}), not both")
    if has_path:
        if not isinstance(kin["path"], str) or not kin["path"]:
            raise RobotDescriptionError(f"{where}: urdf kinematics needs a 'path'")
        return dict(kin)
    shipped = robots.entry(kin["robot"]) if isinstance(kin["robot"], str) else None
    if shipped is None:
        raise RobotDescriptionError(
            f"{where}: kinematics.robot {kin['robot']!r} is not a shipped robot (shipped: "
            f"{', '.join(robots.available_names())})")
    return dict(kin, robot=shipped.name)


def robot_from_dict(d: dict[str, Any], where: str = "robot description") -> RobotDescription:
    """Build and validate a :class:`RobotDescription` from its mapping form.

    With kinematics naming a shipped robot, ``joints`` may be left out: they are then the
    robot's arm joints (named as the log names them, through ``joint_map``).
    """
    joint_map = _joint_map(d, where)
    joints_raw = d.get("joints")
    kin0 = d.get("kinematics")
    if (joints_raw is None and isinstance(kin0, dict) and kin0.get("type") == "urdf"
            and kin0.get("robot") is not None and kin0.get("path") is None):
        shipped = _urdf_kinematics(kin0, where)["robot"]
        back = {u: j for j, u in (joint_map or {}).items()}
        joints_raw = [{"name": back.get(u, u)} for u in robots.arm_joints(shipped)]
    if not isinstance(joints_raw, list) or not joints_raw:
        by_path = (isinstance(kin0, dict) and kin0.get("type") == "urdf"
                   and bool(kin0.get("path")) and kin0.get("robot") is None)
        raise RobotDescriptionError(
            f"{where}: 'joints' must be a non-empty list" + (
                " — a URDF given by 'path' does not say which of its joints are the arm's: "
                "list the log's joints, base first, each {\"name\": ...} with its "
                "gear_ratio (and torque_constant for currents) (docs/robots.md)"
                if by_path and joints_raw is None else ""))
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
            g = kin.get("gravity", [0.0, -GRAVITY_M_S2])
            if not isinstance(g, list) or len(g) != 2:
                raise RobotDescriptionError(f"{where}: kinematics.gravity must be [gx, gy]")
            kin = {"type": "planar", "link_lengths": [float(v) for v in ll],
                   "gravity": [float(v) for v in g]}
        else:
            kin = _urdf_kinematics(kin, where)
    if joint_map is not None:
        if not kin or kin["type"] != "urdf":
            raise RobotDescriptionError(f"{where}: joint_map needs urdf kinematics")
        names = [j.name for j in joints]
        unknown = [k for k in joint_map if k not in names]
        if unknown:
            raise RobotDescriptionError(
                f"{where}: joint_map names log joint(s) {unknown} that are not in 'joints' "
                f"({names})")
    nominal = d.get("nominal")
    if nominal is not None and not isinstance(nominal, dict):
        raise RobotDescriptionError(f"{where}: 'nominal' must be a mapping")
    return RobotDescription(
        joints=tuple(joints), kinematics=kin, nominal=nominal,
        name=str(d.get("name", "")), path=where, joint_map=joint_map,
    )


def shipped_robot(name: str) -> RobotDescription:
    """The robot description of a shipped robot given by name: its arm joints (gear ratio
    1, no torque constant) and kinematics ``{"type": "urdf", "robot": NAME}``.

    Raises RobotDescriptionError (not shipped), RobotsExtraMissing (extra not installed).
    """
    shipped = robots.entry(name)
    if shipped is None:
        robots.urdf_path(name)  # raises, naming the shipped robots
        raise AssertionError("unreachable")  # pragma: no cover
    joints = tuple(JointSpec(j) for j in robots.arm_joints(shipped.name))
    return RobotDescription(joints=joints, kinematics={"type": "urdf", "robot": shipped.name},
                            name=shipped.name, path=shipped.name)


def named_robot_sha256(spec: str | os.PathLike[str]) -> str | None:
    """For ``--robot`` given as a shipped robot's name (no such path exists): the sha256 of
    its URDF (the provenance a file's sha256 gives); None when ``spec`` is not one."""
    if Path(spec).exists() or robots.entry(str(spec)) is None:
        return None
    return robots.urdf_sha256(str(spec))


def read_robot(path: str | os.PathLike[str]) -> RobotDescription:
    """Read a robot description from JSON or YAML, or a shipped robot by name.

    A path that exists wins; else a shipped robot's name (:func:`shipped_robot`); else a
    RobotDescriptionError saying the file is not found, listing the shipped robots.
    A relative URDF ``path`` is resolved against the description's folder.
    """
    if not Path(path).exists():
        if robots.entry(str(path)) is not None:
            return shipped_robot(str(path))
        hint = "" if robots.data_dir() is not None else f"; they need {robots.INSTALL_HINT}"
        raise RobotDescriptionError(
            f"{path}: robot description file not found (nor a shipped robot's name; shipped "
            f"robots: {', '.join(robots.available_names())}{hint})")
    d = load_mapping(path, RobotDescriptionError, "robot description")
    robot = robot_from_dict(d, str(path))
    if robot.kinematics and robot.kinematics["type"] == "urdf" and "path" in robot.kinematics:
        urdf = Path(robot.kinematics["path"])
        if not urdf.is_absolute():
            urdf = Path(path).parent / urdf
        kin = dict(robot.kinematics, path=str(urdf))
        robot = dataclasses.replace(robot, kinematics=kin)
    return robot


def write_robot(robot: RobotDescription, path: str | os.PathLike[str]) -> None:
    """Write a robot description as JSON (atomically); a URDF path is written relative to
    the file's folder, as :func:`read_robot` reads it."""
    from ..files import atomic_write_text

    d = robot.to_dict()
    kin = d.get("kinematics")
    if isinstance(kin, dict) and isinstance(kin.get("path"), str) and "://" not in kin["path"]:
        folder = os.path.dirname(os.path.abspath(path))
        d["kinematics"] = dict(kin, path=os.path.relpath(os.path.abspath(kin["path"]), folder))
    atomic_write_text(path, json.dumps(d, indent=2) + "\n")


def labels_from_dict(d: dict[str, Any], where: str = "labels") -> Labels:
    """Build and validate :class:`Labels` from the labels mapping (docs/formats.md)."""
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
    extra = {k: v for k, v in d.items() if k not in ("events", "sample_rate")}
    return Labels(events=tuple(out), sample_rate=rate, path=where, extra=extra)


def read_labels(path: str | os.PathLike[str]) -> Labels:
    """Read a ground-truth labels file (JSON or YAML), validated against
    schemas/labels.schema.json; LabelsError naming the file and the field."""
    from ..schema import validate

    d = load_mapping(path, LabelsError, "labels")
    validate(d, "labels", LabelsError, str(path))
    return labels_from_dict(d, str(path))


def write_labels(labels: Labels, path: str | os.PathLike[str]) -> None:
    """Write labels as JSON (atomically)."""
    from ..files import atomic_write_text

    atomic_write_text(path, json.dumps(labels.to_dict(), indent=2) + "\n")


def joint_map_hint(log_joints: Sequence[str], urdf_joints: Sequence[str],
                   shipped: str | None) -> str:
    """How to name a log's joints onto a URDF's (``shipped``: the robot's name, None for a
    URDF file): a robot file's ``joint_map`` (docs/robots.md), spelled out when each logged
    joint is the start or the end of exactly one URDF joint's name (``shoulder_pan`` →
    ``shoulder_pan_joint``)."""
    pairs = {}
    for j in log_joints:
        hits = [u for u in urdf_joints if u != j and (u.startswith(j) or u.endswith(j))]
        if len(hits) == 1:
            pairs[j] = hits[0]
    how = "map the log's joint names onto the URDF's with a robot file's joint_map"
    if pairs and len(set(pairs.values())) == len(pairs) == len(log_joints):
        robot = f'"robot": "{shipped}"' if shipped else '"path": "PATH"'
        return (f'{how}, e.g. {{"kinematics": {{"type": "urdf", {robot}}}, "joint_map": '
                + json.dumps(pairs) + "} (docs/robots.md)")
    return f"{how} (docs/robots.md)"


def check_label_links(labels: Labels, joints: Sequence[str], floor: dict[str, Any] | None,
                      where: str) -> None:
    """A labelled contact on a link the log's arm does not have — beyond its ``joints``
    and the links its detection floor (``floor``, the timeline's) lists, counted from 1 at
    the base — is a LabelsError naming the file, the contact and both counts: the labels
    are of another arm, or the link is miscounted (a trial's link 7 on a 2-link arm was
    scored "7 / 2 WRONG"). No joint and no floor: not checked."""
    rows = (floor or {}).get("per_link") or ()
    n_links = max([len(set(joints)), *(int(r["link"]) for r in rows)])
    for k, c in enumerate(labels.events):
        if n_links and not 1 <= int(c.link) <= n_links:
            raise LabelsError(
                f"{labels.path}: event {k} (from 0) is on link {c.link}, but {where}'s arm "
                f"has {n_links} link(s) ({', '.join(map(str, joints))}): are these the "
                "labels of this log, its links counted from 1 at the base?")
