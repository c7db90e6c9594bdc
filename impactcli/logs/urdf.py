"""URDF helpers: parsing a URDF with Pinocchio, its joints, a chain, a reduced model.

Used by the ``urdf`` model structure (:mod:`impactcli.model.structures`), the incidents'
Jacobians (:mod:`impactcli.model.kinematics`) and the shipped robots
(:mod:`impactcli.logs.robot_catalogue`); it imports nothing of theirs, so the robot
catalogue does not depend on the model. Pinocchio is the ``urdf`` extra, imported when
first needed; a URDF is parsed once per text (cached) and meshes are never read. Parser
messages that urdfdom writes to file descriptor 2 are captured; the last one is put in the
error.
"""

from __future__ import annotations

import contextlib
import functools
import os
import tempfile
from collections.abc import Iterator
from typing import Any

from ..errors import ModelError, RobotDescriptionError


def pinocchio() -> Any:
    """The ``pinocchio`` module; ModelError naming the extra to install when it is missing."""
    try:
        import pinocchio
    except ImportError as err:
        raise ModelError(
            "the urdf model needs Pinocchio: pip install 'impactcli[urdf]' (PyPI package 'pin')"
        ) from err
    return pinocchio


@contextlib.contextmanager
def _captured_stderr() -> Iterator[list[str]]:
    """Capture what C++ code (urdfdom) writes to file descriptor 2; yield its lines after."""
    lines: list[str] = []
    try:
        saved = os.dup(2)
    except OSError:  # no real stderr: nothing to capture
        yield lines
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            lines.extend(tmp.read().decode("utf-8", "replace").splitlines())


@functools.lru_cache(maxsize=16)
def full_model(urdf_xml: str, where: str) -> Any:
    """Pinocchio model of the whole URDF (kinematic and inertial tree; meshes never read)."""
    pin = pinocchio()
    with _captured_stderr() as parser_output:
        try:
            full = pin.buildModelFromXML(urdf_xml)
            err = None
        except Exception as e:  # pinocchio raises ValueError/RuntimeError on bad URDF
            err = e
    if err is not None:
        lines = [ln.strip() for ln in parser_output if ln.strip().startswith("Error:")]
        detail = lines[-1].removeprefix("Error:").strip() if lines else ""
        msg = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise RobotDescriptionError(
            f"{where}: URDF does not parse: {msg}" + (f" ({detail})" if detail else "")
        ) from err
    return full


def urdf_joint_names(urdf_xml: str, where: str) -> tuple[str, ...]:
    """The names of the URDF's joints (every non-fixed joint, Pinocchio's order)."""
    return tuple(list(full_model(urdf_xml, where).names)[1:])


def urdf_chain(urdf_xml: str, tip: str, base: str | None, where: str) -> tuple[str, ...]:
    """The 1-dof joints on the chain from link ``base`` (None: the root) to link ``tip``,
    in chain order (base to tip).

    Raises RobotDescriptionError when a link is missing, ``base`` is not on the way to
    ``tip``, or the chain has no joint.
    """
    pin = pinocchio()
    full = full_model(urdf_xml, where)

    def link_joint(link: str) -> int:
        if not full.existFrame(link, pin.FrameType.BODY):
            raise RobotDescriptionError(f"{where}: URDF has no link {link!r}")
        return int(full.frames[full.getFrameId(link, pin.FrameType.BODY)].parentJoint)

    stop = 0 if base is None else link_joint(base)
    chain: list[int] = []
    j = link_joint(tip)
    while j != stop:
        if j == 0:
            raise RobotDescriptionError(f"{where}: link {base!r} is not on the way to {tip!r}")
        chain.append(j)
        j = int(full.parents[j])
    names = tuple(full.names[i] for i in reversed(chain) if full.joints[i].nv == 1)
    if not names:
        raise RobotDescriptionError(f"{where}: no joint between {base or 'the root'} and {tip!r}")
    return names


def urdf_joint_order(joints: tuple[str, ...], structure: dict[str, Any]) -> tuple[str, ...]:
    """The URDF's names of ``joints`` (the log's, in their order), through the model
    structure's ``urdf_joint_map`` when present."""
    jm = structure.get("urdf_joint_map") or {}
    return tuple(str(jm.get(j, j)) for j in joints)


@functools.lru_cache(maxsize=16)
def reduced_model(urdf_xml: str, joints: tuple[str, ...], where: str) -> Any:
    """Pinocchio model from URDF text, reduced to ``joints`` (URDF names; the others are
    locked at neutral: zero, for revolute, continuous and prismatic joints)."""
    pin = pinocchio()
    full = full_model(urdf_xml, where)
    names = list(full.names)[1:]
    missing = [j for j in joints if j not in names]
    if missing:
        raise RobotDescriptionError(
            f"{where}: URDF has no joint(s) {missing} (its joints: {names})"
        )
    lock = [full.getJointId(nm) for nm in names if nm not in joints]
    src = full
    clash = set(names) & {f.name for f in full.frames if f.type != pin.FrameType.JOINT}
    if lock and clash:  # a link named like a joint (SO-100's "gripper"): the reduction
        src = pin.Model(full)  # cannot tell their frames apart; rename the link's, in a copy
        for i in range(len(src.frames)):
            if src.frames[i].type != pin.FrameType.JOINT and src.frames[i].name in clash:
                src.frames[i].name += " (link)"
    model = pin.buildReducedModel(src, lock, pin.neutral(src)) if lock else full
    for j in joints:
        jm = model.joints[model.getJointId(j)]
        if jm.nv != 1:
            raise RobotDescriptionError(f"{where}: URDF joint {j!r} is not a 1-dof joint")
    return model
