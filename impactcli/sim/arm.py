"""Arm parameters of the simulator: the nominal robot, its two presets, and the "true" robot.

All joint-space quantities are *after the reduction* (link side of the gearbox), as in the
paper's eq. 1–2: motor inertia ``I_mot`` is the rotor inertia × gear ratio², motor
friction ``tau_fm`` is the gearbox-output equivalent, ``tau = gear_ratio ×
torque_constant × current``. The true robot differs from the nominal one the way a real
robot differs from its description (:func:`true_parameters`).

Presets (numbers in :func:`assist_like` and :func:`heavy_geared`):

* ``assist_like`` — the paper's ASSIST class: 2 joints, 0.4/0.4 m links of 1.6/1.0 kg,
  cable reduction 20:1, reflected motor inertia 0.02/0.012 kg·m², joint stiffness
  800/300 N·m/rad (arm extended, nominal: locked-motor link modes 6.2/25.7 Hz, modes
  with free motors 30.5/37.6 Hz), low friction (Coulomb 0.12/0.08 N·m motor side),
  4096-count encoders, current noise 0.04/0.03 A rms on a 5 mA grid, Ts = 4 ms.
* ``heavy_geared`` — a heavier geared arm: 3 joints, 0.5/0.4/0.2 m links of 8/5/2 kg,
  100:1 gears, reflected motor inertia 2.0/1.2/0.4 kg·m², stiffness 20000/12000/4000
  N·m/rad (arm extended, nominal: locked-motor modes 9/43/106 Hz, free-motor modes
  18/46/107 Hz), strong Coulomb friction 8/5/2 N·m (motor side), 2048-count encoders,
  current noise 0.02 A rms (0.2 N·m after 100:1 × 0.1 N·m/A), Ts = 2 ms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..types import GRAVITY_M_S2, JointSpec, RobotDescription

#: Velocity scale of the smoothed Coulomb friction tanh(v / v_eps) [rad/s]: the smooth sign
#: reaches 0.76 at 5 mrad/s (0.3 deg/s); its slope at 0 is Fc / v_eps.
COULOMB_VELOCITY_EPS = 5e-3


@dataclass(frozen=True)
class ArmParams:
    """A planar flexible-joint arm (nominal values) with its drives and controller.

    Tuples hold one value per joint / link, chain order. Units: lengths [m], masses [kg],
    inertias [kg·m²] (link: about its COM; motor: after reduction), stiffness [N·m/rad],
    damping and viscous friction [N·m·s/rad], Coulomb friction [N·m], torque constant
    [N·m/A] (motor side), current noise and resolution [A], gains kp [N·m/rad] and
    kd [N·m·s/rad], sample period [s].

    The controller's own channels (:mod:`impactcli.sim.controller`, logged when a scenario
    sets ``controller_channels``) use: ``observer_gain`` K of the momentum observer [1/s]
    (time constant 1/K: 20 ms at the default 50), ``torque_ext_cutoff_hz`` its output
    low-pass [Hz] (0: none), ``accel_cutoff_hz`` the low-pass of the controller's
    acceleration estimate for ``torque_model`` [Hz], ``controller_coulomb_eps`` the Coulomb
    smoothing velocity of the controller's friction model [rad/s] (default 0.02 ≈ one
    velocity quantum of the ASSIST encoder at 4 ms: one count does not flip the friction
    sign) and ``controller_torque_lsb`` the resolution both channels are logged with [N·m].
    """

    name: str
    joint_names: tuple[str, ...]
    link_lengths: tuple[float, ...]
    link_masses: tuple[float, ...]
    com_fractions: tuple[float, ...]
    link_inertias: tuple[float, ...]
    motor_inertias: tuple[float, ...]
    stiffness: tuple[float, ...]
    transmission_damping: tuple[float, ...]
    motor_viscous: tuple[float, ...]
    motor_coulomb: tuple[float, ...]
    link_viscous: tuple[float, ...]
    link_coulomb: tuple[float, ...]
    gear_ratio: tuple[float, ...]
    torque_constant: tuple[float, ...]
    encoder_counts: tuple[int, ...]
    current_noise_a: tuple[float, ...]
    current_lsb_a: tuple[float, ...]
    kp: tuple[float, ...]
    kd: tuple[float, ...]
    velocity_cutoff_hz: float
    sample_period_s: float
    home: tuple[float, ...]
    joint_ranges: tuple[tuple[float, float], ...]
    gravity: tuple[float, float] = (0.0, -GRAVITY_M_S2)
    coulomb_velocity_eps: float = COULOMB_VELOCITY_EPS
    observer_gain: float = 50.0
    torque_ext_cutoff_hz: float = 20.0
    accel_cutoff_hz: float = 20.0
    controller_coulomb_eps: float = 0.02
    controller_torque_lsb: float = 0.01
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def n_joints(self) -> int:
        """Number of joints n."""
        return len(self.joint_names)

    @property
    def encoder_resolution(self) -> np.ndarray:
        """(n,) position resolution after reduction: 2π / (counts per motor rev × gear) [rad]."""
        return np.array([2 * math.pi / (c * g) for c, g in
                         zip(self.encoder_counts, self.gear_ratio, strict=True)])

    @property
    def torque_scale(self) -> np.ndarray:
        """(n,) gear_ratio × torque_constant [N·m/A]."""
        return np.array(self.gear_ratio) * np.array(self.torque_constant)

    def robot_description(self) -> RobotDescription:
        """The NOMINAL robot description (docs/formats.md, "Robot description"): planar
        kinematics, nominal masses."""
        joints = tuple(JointSpec(nm, float(g), float(k)) for nm, g, k in
                       zip(self.joint_names, self.gear_ratio, self.torque_constant, strict=True))
        nominal = {
            "link_masses": list(self.link_masses),
            "com_fractions": list(self.com_fractions),
            "link_inertias": list(self.link_inertias),
            "motor_inertias": list(self.motor_inertias),
            "stiffness": list(self.stiffness),
            "motor_viscous": list(self.motor_viscous),
            "motor_coulomb": list(self.motor_coulomb),
            "encoder_counts": list(self.encoder_counts),
            "sample_period_s": self.sample_period_s,
            "note": "nominal values; the simulated robot differs (uncertainty, payload, drift)",
        }
        kin = {"type": "planar", "link_lengths": list(self.link_lengths),
               "gravity": list(self.gravity)}
        return RobotDescription(joints=joints, kinematics=kin, nominal=nominal,
                                name=f"impactcli-sim {self.name}")


def _rod(m: float, length: float) -> float:
    return m * length * length / 12.0


def assist_like() -> ArmParams:
    """The paper's ASSIST class: light, cable-driven, backdrivable, low friction, soft."""
    lengths = (0.4, 0.4)
    masses = (1.6, 1.0)
    return ArmParams(
        name="assist_like", joint_names=("shoulder", "elbow"),
        link_lengths=lengths, link_masses=masses, com_fractions=(0.5, 0.45),
        link_inertias=tuple(_rod(m, ln) for m, ln in zip(masses, lengths, strict=True)),
        motor_inertias=(0.02, 0.012), stiffness=(800.0, 300.0),
        transmission_damping=(0.3, 0.1),
        motor_viscous=(0.02, 0.012), motor_coulomb=(0.12, 0.08),
        link_viscous=(0.01, 0.006), link_coulomb=(0.03, 0.02),
        gear_ratio=(20.0, 20.0), torque_constant=(0.05, 0.05), encoder_counts=(4096, 4096),
        current_noise_a=(0.04, 0.03), current_lsb_a=(0.005, 0.005),
        kp=(120.0, 60.0), kd=(2.0, 1.0), velocity_cutoff_hz=40.0,
        sample_period_s=0.004, home=(0.0, 0.0),
        joint_ranges=((-0.8, 0.8), (-1.4, 1.4)),
    )


def heavy_geared() -> ArmParams:
    """A heavier geared 3-joint arm: 100:1 gears, strong Coulomb friction, stiffer joints."""
    lengths = (0.5, 0.4, 0.2)
    masses = (8.0, 5.0, 2.0)
    return ArmParams(
        name="heavy_geared", joint_names=("j1", "j2", "j3"),
        link_lengths=lengths, link_masses=masses, com_fractions=(0.5, 0.5, 0.5),
        link_inertias=tuple(_rod(m, ln) for m, ln in zip(masses, lengths, strict=True)),
        motor_inertias=(2.0, 1.2, 0.4), stiffness=(20000.0, 12000.0, 4000.0),
        transmission_damping=(10.0, 6.0, 2.0),
        motor_viscous=(3.0, 2.0, 0.8), motor_coulomb=(8.0, 5.0, 2.0),
        link_viscous=(0.3, 0.2, 0.05), link_coulomb=(0.2, 0.1, 0.02),
        gear_ratio=(100.0, 100.0, 100.0), torque_constant=(0.1, 0.1, 0.08),
        encoder_counts=(2048, 2048, 2048),
        current_noise_a=(0.02, 0.02, 0.02), current_lsb_a=(0.005, 0.005, 0.005),
        kp=(3000.0, 2000.0, 600.0), kd=(150.0, 100.0, 30.0), velocity_cutoff_hz=80.0,
        sample_period_s=0.002, home=(0.0, 0.0, 0.0),
        joint_ranges=((-0.6, 0.6), (-1.0, 1.0), (-1.2, 1.2)),
    )


PRESETS = {"assist_like": assist_like, "heavy_geared": heavy_geared}


def preset(name: str) -> ArmParams:
    """The preset arm called ``name`` (``assist_like`` or ``heavy_geared``)."""
    try:
        return PRESETS[name]()
    except KeyError:
        raise ValueError(f"unknown arm {name!r}; choose one of {sorted(PRESETS)}") from None


def with_payload(masses: np.ndarray, com: np.ndarray, inertia: np.ndarray,
                 lengths: np.ndarray, payload_kg: float) -> tuple[np.ndarray, ...]:
    """Merge a point mass at the end effector into the last link (mass, COM, inertia)."""
    m, c, ic = masses.copy(), com.copy(), inertia.copy()
    if payload_kg > 0:
        mn, cn, ln = m[-1], c[-1], lengths[-1]
        mt = mn + payload_kg
        ct = (mn * cn + payload_kg * ln) / mt
        ic[-1] = ic[-1] + mn * (cn - ct) ** 2 + payload_kg * (ln - ct) ** 2
        m[-1], c[-1] = mt, ct
    return m, c, ic


def true_parameters(arm: ArmParams, rng: np.random.Generator, uncertainty: float,
                    payload_kg: float = 0.0) -> dict[str, np.ndarray]:
    """The simulated robot's true parameters: nominal × (1 + U(−u, u)) per parameter.

    Masses, link and motor inertias, stiffness, damping and friction coefficients are each
    scaled by an independent factor in [1 − u, 1 + u]; COM fractions by [1 − u/2, 1 + u/2].
    A payload [kg] is a point mass at the end effector, merged into the last link.
    Returns arrays (n,) keyed like the kernel's arguments; com is a distance [m].
    """
    n = arm.n_joints

    def scale(v: tuple[float, ...], u: float) -> np.ndarray:
        return np.asarray(v, dtype=np.float64) * (1.0 + rng.uniform(-u, u, n))

    lengths = np.asarray(arm.link_lengths, dtype=np.float64)
    p = {
        "mass": scale(arm.link_masses, uncertainty),
        "com": scale(arm.com_fractions, uncertainty / 2) * lengths,
        "inertia": scale(arm.link_inertias, uncertainty),
        "i_mot": scale(arm.motor_inertias, uncertainty),
        "stiff": scale(arm.stiffness, uncertainty),
        "damp": scale(arm.transmission_damping, uncertainty),
        "fv_m": scale(arm.motor_viscous, uncertainty),
        "fc_m": scale(arm.motor_coulomb, uncertainty),
        "fv_a": scale(arm.link_viscous, uncertainty),
        "fc_a": scale(arm.link_coulomb, uncertainty),
    }
    p["mass"], p["com"], p["inertia"] = with_payload(
        p["mass"], p["com"], p["inertia"], lengths, payload_kg)
    p["lengths"] = lengths
    return p


def nominal_parameters(arm: ArmParams) -> dict[str, np.ndarray]:
    """The nominal parameters in the layout of :func:`true_parameters` (no uncertainty)."""
    rng = np.random.default_rng(0)
    return true_parameters(arm, rng, 0.0)


def without_losses(arm: ArmParams) -> ArmParams:
    """The same arm with zero friction and transmission damping (for energy checks)."""
    z = tuple(0.0 for _ in arm.joint_names)
    return replace(arm, transmission_damping=z, motor_viscous=z, motor_coulomb=z,
                   link_viscous=z, link_coulomb=z)
