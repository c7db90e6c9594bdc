"""Flexible-joint arm simulator (the paper's eq. 1–2) used for sample logs and tests.

Public API: :func:`simulate`, :class:`Scenario`, :class:`SimResult`, :func:`scenario`
(named scenarios), the arm presets :func:`assist_like` / :func:`heavy_geared`, the
references of :mod:`impactcli.sim.reference` and the contacts of
:mod:`impactcli.sim.contacts`. A scenario's ``controller_channels`` adds the controller's own
``torque_model`` / ``torque_ext`` channels to the log (:mod:`impactcli.sim.controller`).
"""

from .arm import ArmParams, assist_like, heavy_geared, preset
from .contacts import LABEL_THRESHOLD_N, Clamp, Push, Surface
from .core import Scenario, SimResult, energy, simulate
from .reference import FMTriangle, MultiSine, PointToPoint, Triangle, Waypoints
from .scenarios import SCENARIOS, scenario

__all__ = [
    "LABEL_THRESHOLD_N", "SCENARIOS", "ArmParams", "Clamp", "FMTriangle", "MultiSine",
    "PointToPoint", "Push", "Scenario", "SimResult", "Surface", "Triangle", "Waypoints",
    "assist_like", "energy", "heavy_geared", "preset", "scenario", "simulate",
]
