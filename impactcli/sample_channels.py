"""The channels of a sample, declared once: the fields of :class:`Channels`, each with
its :class:`ChannelSpec` (unit, role, optional, droppable, angular, replayed).

:class:`~impactcli.types.RobotLog`, the readers' chunks and the replay's arrays are
:class:`Channels` with fields of their own; the name tuples below derive from the one
declaration (tests/test_layout.py checks that no other module declares them again).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class ChannelSpec:
    """One per-joint channel of a sample (docs/formats.md, "Canonical wide CSV").

    Attributes:
        name: the field of :class:`Channels` (so of :class:`RobotLog` and of the chunks
            the readers and the replay pass), and the ``<joint>.<name>`` of a canonical
            CSV column.
        unit: its unit once read (after a channel map's scale and offset).
        role: ``measured`` (the robot's sensors), ``reference`` (the controller's
            commanded motion) or ``controller`` (the controller's own model torques: a
            joint that lacks one holds NaN in its column).
        optional: a log may lack it (only position and torque are required).
        droppable: a joint whose column of it holds no finite value is left out of the
            log (a controller channel's missing column is NaN instead).
        angular: an angle or its derivative (a position unit's scale applies to it).
        replayed: the replay reads it, chunk by chunk.
    """

    name: str
    unit: str
    role: str
    optional: bool
    droppable: bool
    angular: bool
    replayed: bool


def _spec(unit: str, role: str, *, droppable: bool, angular: bool, replayed: bool
          ) -> dict[str, Any]:
    """A :class:`Channels` field's metadata: its :class:`ChannelSpec` less the name and
    ``optional`` (the field has a default, None)."""
    return {"unit": unit, "role": role, "droppable": droppable, "angular": angular,
            "replayed": replayed}


@dataclass(frozen=True, kw_only=True)
class Channels:
    """The per-joint channels of n consecutive samples, declared once: :class:`RobotLog`,
    the readers' chunks and the replay's arrays are these fields and their own; each
    field's :class:`ChannelSpec` is its metadata, and :data:`CHANNELS` lists them.

    Attributes:
        position: (n, J) motor position after reduction [rad] (x1 in the paper).
        velocity: optional (n, J) measured velocity [rad/s].
        torque: (n, J) motor torque after reduction [N·m] (tau, eq. 7).
        current: optional (n, J) measured motor current [A].
        position_ref: optional (n, J) reference position x1_ref [rad].
        velocity_ref: optional (n, J) reference velocity [rad/s].
        acceleration_ref: optional (n, J) reference acceleration [rad/s²].
        torque_model: optional (n, J) the controller's model torque for the measured
            motion, without contact [N·m] (docs/formats.md, "Canonical wide CSV"); an
            all-NaN column: not logged for that joint.
        torque_ext: optional (n, J) the controller's own external-torque estimate [N·m];
            an all-NaN column: not logged for that joint.
    """

    position: np.ndarray = field(metadata=_spec(
        "rad", "measured", droppable=True, angular=True, replayed=True))
    velocity: np.ndarray | None = field(default=None, metadata=_spec(
        "rad/s", "measured", droppable=True, angular=True, replayed=False))
    torque: np.ndarray = field(metadata=_spec(
        "N·m", "measured", droppable=True, angular=False, replayed=True))
    current: np.ndarray | None = field(default=None, metadata=_spec(
        "A", "measured", droppable=True, angular=False, replayed=False))
    position_ref: np.ndarray | None = field(default=None, metadata=_spec(
        "rad", "reference", droppable=True, angular=True, replayed=True))
    velocity_ref: np.ndarray | None = field(default=None, metadata=_spec(
        "rad/s", "reference", droppable=True, angular=True, replayed=True))
    acceleration_ref: np.ndarray | None = field(default=None, metadata=_spec(
        "rad/s²", "reference", droppable=True, angular=True, replayed=True))
    torque_model: np.ndarray | None = field(default=None, metadata=_spec(
        "N·m", "controller", droppable=False, angular=False, replayed=True))
    torque_ext: np.ndarray | None = field(default=None, metadata=_spec(
        "N·m", "controller", droppable=False, angular=False, replayed=True))

    def channels(self) -> dict[str, np.ndarray | None]:
        """Each channel's array (None: not in the log), by name in :data:`CHANNELS`'
        order."""
        return {name: getattr(self, name) for name in CHANNEL_NAMES}


#: The channels of a sample: :class:`Channels`' fields and their specs, in order.
CHANNELS: tuple[ChannelSpec, ...] = tuple(
    ChannelSpec(f.name, optional=f.default is None, **f.metadata)
    for f in dataclasses.fields(Channels))
#: Every channel's name, in declaration order.
CHANNEL_NAMES: tuple[str, ...] = tuple(c.name for c in CHANNELS)
#: The channels every log has (position, torque).
REQUIRED_CHANNELS: tuple[str, ...] = tuple(c.name for c in CHANNELS if not c.optional)
#: The channels a log may lack, in :class:`RobotLog`'s order.
OPTIONAL_CHANNELS: tuple[str, ...] = tuple(c.name for c in CHANNELS if c.optional)
#: The channels whose column may hold no finite value (passed on as NaN): a position or torque
#: (or current, the torque source) column leaves its joint out of the log; an optional
#: signal's column (velocity, current not the torque source, references) leaves that
#: signal out of the log (:func:`impactcli.logs.channels.drop_empty_signals`).
DROPPABLE_CHANNELS: tuple[str, ...] = tuple(c.name for c in CHANNELS if c.droppable)
#: The angular channels (a position unit's scale applies to them).
ANGULAR_CHANNELS: tuple[str, ...] = tuple(c.name for c in CHANNELS if c.angular)
#: The channels the replay reads per chunk.
REPLAYED_CHANNELS: tuple[str, ...] = tuple(c.name for c in CHANNELS if c.replayed)
#: The controller's own channels: a joint that lacks one holds NaN in its column.
CONTROLLER_CHANNELS: tuple[str, ...] = tuple(c.name for c in CHANNELS
                                             if c.role == "controller")
