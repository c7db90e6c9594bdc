"""The robots the tool ships: URDFs of the ``robots`` extra (PyPI ``example-robot-data``),
and arms built from their manufacturer's published table (:mod:`.published_arms`).

``impactcli robots`` lists them; ``--robot NAME`` and a robot description's kinematics
``{"type": "urdf", "robot": NAME}`` name them (docs/formats.md, "Robot description").
A built arm needs only Pinocchio (the ``urdf`` extra); the others need the ``robots``
extra's URDFs too.

Each entry names one URDF of the package and the links its arm chain runs between; the
arm's joints are the movable joints on that chain, in chain order, with the URDF's own
names (read from the URDF by Pinocchio, never typed here). Only the kinematic and inertial
tree is used: meshes are never loaded, so a URDF whose meshes are missing still works.

The package (6.0.0) holds only data — no Python module: its files sit under
``cmeel.prefix/share/example-robot-data/robots`` of the environment, found through the
installed distribution's metadata. A model identified on a named robot embeds the URDF
text (the model stays self-contained) and records the robot's name, not a path of this
machine, so a description naming the robot resolves again on another machine.
"""

from __future__ import annotations

import functools
import importlib.metadata
from dataclasses import dataclass
from pathlib import Path

from ..errors import EXIT_USAGE, ImpactError, RobotDescriptionError
from . import published_arms

__all__ = [
    "CATALOGUE", "DIST", "INSTALL_HINT", "PINNED", "RobotsExtraMissing", "ShippedRobot",
    "arm_joints", "available", "available_names", "data_dir", "data_version", "entry",
    "urdf_label", "urdf_path", "urdf_sha256", "urdf_text",
]

#: The PyPI distribution that holds the URDFs.
DIST = "example-robot-data"
#: How to install what named robots need (the URDFs and Pinocchio).
INSTALL_HINT = "pip install 'impactcli[robots]'"
#: The release the catalogue was checked against (pinned by the extra).
PINNED = "6.0.0"
#: Where the distribution puts its robots, relative to its install location.
_ROBOTS_DIR = "cmeel.prefix/share/example-robot-data/robots"


@dataclass(frozen=True)
class ShippedRobot:
    """One robot of the catalogue.

    Attributes:
        name: the name ``--robot`` takes (lower case).
        urdf: the URDF, relative to the package's robots folder; for a built arm, where
            its numbers come from.
        tip: the link the arm chain ends at (a hand or flange, fixed to the last arm joint).
        base: the link the arm chain starts from; None: the URDF's root.
        title: what the robot is, for listings.
    """

    name: str
    urdf: str
    tip: str
    base: str | None = None
    title: str = ""
    #: The published table the URDF is built from; None: a URDF of the package.
    built: published_arms.PublishedArm | None = None


#: Robots whose URDF the package's current release (6.0.0) holds and Pinocchio loads, then
#: the arms built from their manufacturer's table (:data:`.published_arms.ARMS`).
#: Grippers and other branches (fingers, head, wheels, a torso lift) are not arm joints:
#: when they are not logged they are held at zero.
CATALOGUE: tuple[ShippedRobot, ...] = (
    ShippedRobot("panda", "panda_description/urdf/panda.urdf", "panda_hand",
                 title="Franka Emika Panda (7 dof)"),
    ShippedRobot("ur3", "ur_description/urdf/ur3_robot.urdf", "tool0",
                 title="Universal Robots UR3 (6 dof)"),
    ShippedRobot("ur5", "ur_description/urdf/ur5_robot.urdf", "tool0",
                 title="Universal Robots UR5 (6 dof)"),
    ShippedRobot("ur10", "ur_description/urdf/ur10_robot.urdf", "tool0",
                 title="Universal Robots UR10 (6 dof)"),
    ShippedRobot("tiago", "tiago_description/robots/tiago_no_hand.urdf", "arm_tool_link",
                 base="torso_lift_link", title="PAL TIAGo arm (7 dof; torso, head, wheels "
                 "held)"),
    ShippedRobot("so100", "so_arm_description/urdf/so100.urdf", "gripper",
                 title="SO-100 arm (5 dof; jaw not an arm joint)"),
    ShippedRobot("so101", "so_arm_description/urdf/so101.urdf", "gripper_link",
                 title="SO-101 arm (5 dof; jaw not an arm joint)"),
    ShippedRobot("xarm7", "xarm_description/urdf/xarm7.urdf", "link_eef",
                 title="UFACTORY xArm7 (7 dof)"),
    ShippedRobot("kinova", "kinova_description/robots/kinova.urdf", "j2s6s200_end_effector",
                 title="Kinova Jaco2 j2s6s200 (6 dof, three continuous joints)"),
    ShippedRobot("z1", "z1_description/urdf/z1.urdf", "gripperStator",
                 title="Unitree Z1 (6 dof; gripper not an arm joint)"),
    *(ShippedRobot(a.name, published_arms.SHORT, a.tip, title=a.title, built=a)
      for a in published_arms.ARMS),
)
_BY_NAME = {r.name: r for r in CATALOGUE}


class RobotsExtraMissing(RobotDescriptionError):
    """A shipped robot was asked for but the ``robots`` extra is not installed (exit 2:
    an environment problem, like a missing Dask extra)."""

    exit_code = EXIT_USAGE


def entry(name: str) -> ShippedRobot | None:
    """The catalogue entry of ``name`` (case-insensitive), or None."""
    return _BY_NAME.get(str(name).strip().lower())


def data_dir() -> Path | None:
    """The package's robots folder, or None when ``example-robot-data`` is not installed."""
    try:
        dist = importlib.metadata.distribution(DIST)
    except importlib.metadata.PackageNotFoundError:
        return None
    d = Path(str(dist.locate_file(_ROBOTS_DIR)))
    return d if d.is_dir() else None


def data_version() -> str | None:
    """The installed ``example-robot-data`` version, or None."""
    try:
        return importlib.metadata.version(DIST)
    except importlib.metadata.PackageNotFoundError:
        return None


def _missing(what: str) -> RobotsExtraMissing:
    return RobotsExtraMissing(f"{what} need the robots extra: {INSTALL_HINT}")


def urdf_path(name: str) -> Path:
    """The URDF file of shipped robot ``name``.

    Raises:
        RobotDescriptionError: not a shipped robot, or the installed release lacks its URDF.
        RobotsExtraMissing: the extra is not installed.
    """
    e = entry(name)
    if e is None:
        raise RobotDescriptionError(f"{name}: not a shipped robot (shipped: "
                                    f"{', '.join(r.name for r in CATALOGUE)})")
    if e.built is not None:
        raise RobotDescriptionError(f"{e.name}: built from {published_arms.SOURCE}, not a "
                                    "file (urdf_text gives its URDF)")
    d = data_dir()
    if d is None:
        raise _missing(f"{e.name}: the shipped robots")
    p = d / e.urdf
    if not p.is_file():
        raise RobotDescriptionError(
            f"{e.name}: {DIST} {data_version()} has no {e.urdf} (impactcli expects "
            f"{PINNED}: {INSTALL_HINT})")
    return p


def urdf_label(name: str) -> str:
    """How messages and models name the URDF of a shipped robot (no path of this machine)."""
    e = entry(name)
    assert e is not None
    if e.built is not None:
        return f"robot {e.name!r} (built from {published_arms.SOURCE})"
    return f"robot {e.name!r} ({e.urdf} of {DIST} {data_version() or '?'})"


def urdf_text(name: str) -> str:
    """The URDF text of shipped robot ``name``: a built arm's, built here; else the
    package's file (errors as :func:`urdf_path`)."""
    e = entry(name)
    if e is not None and e.built is not None:
        return published_arms.urdf_xml(e.built)
    p = urdf_path(name)
    try:
        return p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise RobotDescriptionError(f"{urdf_label(name)}: cannot read URDF: {err}") from err


def urdf_sha256(name: str) -> str:
    """The sha256 of shipped robot ``name``'s URDF: the file's bytes, or a built arm's text
    (UTF-8) — the provenance a robot file's sha256 gives (errors as :func:`urdf_path`)."""
    import hashlib

    e = entry(name)
    if e is not None and e.built is not None:
        return hashlib.sha256(urdf_text(e.name).encode("utf-8")).hexdigest()
    return hashlib.sha256(urdf_path(name).read_bytes()).hexdigest()


@functools.lru_cache(maxsize=32)
def arm_joints(name: str) -> tuple[str, ...]:
    """The arm joints of shipped robot ``name``: movable joints from its base link to its
    tip link, in chain order, as the URDF names them (Pinocchio parses the URDF)."""
    from .urdf import urdf_chain

    e = entry(name)
    if e is None:
        urdf_path(name)  # raises, naming the shipped robots
        raise AssertionError("unreachable")  # pragma: no cover
    xml = urdf_text(e.name)
    _require_pinocchio(e.built is not None)
    return urdf_chain(xml, e.tip, e.base, urdf_label(e.name))


def _require_pinocchio(built: bool = False) -> None:
    """RobotsExtraMissing unless Pinocchio imports; a built arm needs only the ``urdf``
    extra, so its message names that one."""
    try:
        import pinocchio  # noqa: F401
    except ImportError:
        if built:
            raise RobotsExtraMissing("the arms built from a published table need Pinocchio: "
                                     "pip install 'impactcli[urdf]'") from None
        raise _missing("the shipped robots (Pinocchio, PyPI 'pin')") from None


def available() -> tuple[list[tuple[ShippedRobot, tuple[str, ...]]], list[tuple[str, str]]]:
    """The shipped robots whose URDF is installed and loads, each with its arm joints,
    and those that do not (name, why). Without the ``robots`` extra's URDFs, only the built
    arms load; the others are listed as not loaded, with how to install them.

    Raises:
        RobotsExtraMissing: Pinocchio is not installed.
    """
    _require_pinocchio()
    have_data = data_dir() is not None
    ok: list[tuple[ShippedRobot, tuple[str, ...]]] = []
    bad: list[tuple[str, str]] = []
    for e in CATALOGUE:
        if e.built is None and not have_data:
            bad.append((e.name, f"its URDF needs the robots extra: {INSTALL_HINT}"))
            continue
        try:
            ok.append((e, arm_joints(e.name)))
        except ImpactError as err:
            bad.append((e.name, str(err)))
    return ok, bad


def available_names() -> list[str]:
    """Names of the shipped robots that load here; every catalogue name when the extra is
    missing (for messages)."""
    try:
        return [e.name for e, _ in available()[0]]
    except RobotsExtraMissing:
        return [e.name for e in CATALOGUE]
