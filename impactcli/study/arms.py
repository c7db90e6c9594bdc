"""The sensitivity study's simulated world: the one robot of a study (:func:`the_robot`,
the preset's parameters drawn off it), the task's amplitudes (:func:`amplitudes`), the
joint-1 triangle references, and the scenarios of a case (the elastomer slid in) and of a
collision-free run (:func:`free_scenario`).

How they are used: docs/validation.md. The simulator is imported
lazily (:mod:`impactcli.sim`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from .spec import ARM_GEOMETRY, StudySpec, seed_of

_SCENARIO_OF = {"triangle": "free_triangle", "trapezoid": "free_p2p",
                "multisine": "free_multisine"}


def the_robot(arm_name: str, seed: int, uncertainty: float = 0.2) -> Any:
    """The one simulated robot of a study: the preset with every physical parameter scaled
    by 1 + U(−u, u) (COM fractions by 1 + U(−u/2, u/2)), drawn from ``seed``.

    Returns an :class:`impactcli.sim.ArmParams` (same name, kinematics, drives and
    controller as the preset). Simulate it with ``uncertainty=0``.
    """
    from ..sim import preset

    arm = preset(arm_name)
    rng = np.random.default_rng(seed_of("robot", arm_name, seed))

    def sc(v: tuple[float, ...], u: float = uncertainty) -> tuple[float, ...]:
        return tuple(float(x * (1.0 + rng.uniform(-u, u))) for x in v)

    return replace(
        arm, link_masses=sc(arm.link_masses), com_fractions=sc(arm.com_fractions, uncertainty / 2),
        link_inertias=sc(arm.link_inertias), motor_inertias=sc(arm.motor_inertias),
        stiffness=sc(arm.stiffness), transmission_damping=sc(arm.transmission_damping),
        motor_viscous=sc(arm.motor_viscous), motor_coulomb=sc(arm.motor_coulomb),
        link_viscous=sc(arm.link_viscous), link_coulomb=sc(arm.link_coulomb),
    )


def servo_compliance(arm: Any) -> float:
    """Tip compliance of the PD servos, arm extended: Σ_j r_j² / kp_j [m/N]."""
    ll = arm.link_lengths
    return float(sum(sum(ll[j:]) ** 2 / arm.kp[j] for j in range(len(ll))))


def amplitudes(arm_name: str, forces_n: Sequence[float]) -> tuple[float, ...]:
    """Joint-1 triangle amplitudes [rad]: gap + F · c / reach per nominal force F [N]."""
    from ..sim import preset

    arm = preset(arm_name)
    gap, _ = ARM_GEOMETRY[arm_name]
    c = servo_compliance(arm)
    reach = sum(arm.link_lengths)
    return tuple(round(gap + f * c / reach, 6) for f in forces_n)


def task_reference(arm: Any, amps: Sequence[float], period_s: float) -> Any:
    """Waypoints: joint-1 triangles 0 → +A → −A → 0 (period T, one amplitude per cycle),
    the other joints at 0. Velocity steps and acceleration impulses, like the paper's."""
    from ..sim import Waypoints

    n = arm.n_joints
    rest = (0.0,) * (n - 1)
    times, pos = [0.0], [(0.0, *rest)]
    t = 0.0
    for a in amps:
        for frac, th in ((0.25, a), (0.5, -a), (0.25, 0.0)):
            t += frac * period_s
            times.append(round(t, 9))
            pos.append((th, *rest))
    return Waypoints(tuple(times), tuple(pos))


def case_scenario(arm: Any, stiffness: float, amplitude: float, spec: StudySpec,
                  payload_kg: float = 0.0) -> Any:
    """One Table II case: lead-in triangles, then the elastomer slid in at a cycle's top and
    ``spec.impacts_per_case`` impacts of amplitude ``amplitude`` [rad] on ``stiffness``."""
    from ..sim import Scenario, Surface

    gap, period = ARM_GEOMETRY[arm.name]
    n_lead = max(1, math.ceil(spec.lead_in_s / period))
    n_cyc = n_lead + spec.impacts_per_case
    reach = sum(arm.link_lengths)
    t_on = n_lead * period + 0.25 * period  # the tip is at +A, far above the surface
    surface = Surface(reach * math.sin(-gap), stiffness, x_min_m=reach - 0.2,
                      x_max_m=reach + 0.2, t_on_s=t_on)
    return Scenario(
        "sensitivity_case", arm, n_cyc * period + 0.5, task_reference(arm, [amplitude] * n_cyc,
                                                                      period),
        surfaces=(surface,), payload_kg=payload_kg, uncertainty=0.0,
        description=f"joint-1 triangles A={amplitude:.4f} rad, T={period:g} s onto "
                    f"{stiffness} N/mm")


def free_scenario(arm: Any, family: str, duration_s: float, payload_kg: float,
                  amps: Sequence[float]) -> Any:
    """A collision-free run of ``family`` (:data:`SOAK_FAMILIES`) on ``arm``."""
    from ..sim import Scenario, scenario

    if family == "task":
        _, period = ARM_GEOMETRY[arm.name]
        n_cyc = math.ceil(duration_s / period) + 1
        ref = task_reference(arm, [amps[k % len(amps)] for k in range(n_cyc)], period)
        return Scenario("task", arm, duration_s, ref, payload_kg=payload_kg, uncertainty=0.0,
                        description="joint-1 task triangles over every case amplitude, "
                                    "no elastomer")
    return scenario(_SCENARIO_OF[family], arm=arm, duration_s=duration_s,
                    payload_kg=payload_kg, uncertainty=0.0)
