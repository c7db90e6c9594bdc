"""Arms whose manufacturer publishes their kinematics and link masses, and the URDF the tool
builds from them (pure: no Pinocchio, no NumPy).

Universal Robots publish, for each e-Series arm, the Denavit–Hartenberg parameters of its
six joints and the mass and centre of mass of each link ("Parameters for calculations of
kinematics and dynamics", UR's support article; e-Series software 5.1). The tool carries
those tables (:data:`ARMS`) and turns each into a URDF (:func:`urdf_xml`), so ``--robot
ur10e`` needs no file and no download: only Pinocchio (the ``urdf`` extra) to read it.

The URDF is the DH chain itself. Link *i*'s frame is DH frame *i−1* turned by the joint
angle; joint *i+1* sits at the fixed part of DH transform *i*,
``Trans_z(d_i) · Trans_x(a_i) · Rot_x(alpha_i)`` (origin ``xyz="a 0 d" rpy="alpha 0 0"``),
and link *i*'s centre of mass, which UR gives in DH frame *i*, is mapped through the same
transform. The base frame is the controller's ``base`` frame (z up, gravity −z); the tip
link ``tool0`` is DH frame 6, the tool flange. Joint angles are the controller's: zero is
the DH zero, with no offsets.

What UR do not publish, and what stands in for it:

- **Rotational inertia** (UR: negligible for the UR3e and UR5e). Each link is given the
  inertia of a solid sphere of its mass and of the radius of its joint housing
  (:attr:`PublishedArm.housing_radius_m`), so that the mass matrix is positive definite.
  Identification fits the inertia from the log (it reads only the chain), and the gravity
  scale check reads only masses and centres of mass, so no answer rests on this guess.
- **Joint limits.** Positions ±2π (every e-Series joint turns ±360°; the UR3e's wrist 3
  turns endlessly: a continuous joint). Effort limits are the rated torques of the joint
  sizes each arm is built from (:attr:`PublishedArm.effort_nm`); the tool uses them only
  as a joint's torque capacity when it judges a force (docs/incidents.md). Velocity limits
  are the arm's rated joint speeds.

The tables were checked against physics: on a real UR10e held still (the ``ur-static``
recording that tests/test_published_arms.py reads when it is present), the gravity torque
of the built URDF at the arm's pose matches the controller's own model torque, logged
beside the currents, to 0.1 % on the loaded joints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["ARMS", "SHORT", "SOURCE", "PublishedArm", "arm", "urdf_xml"]

#: Where the numbers come from (the manufacturer's own table), as listings say it.
SOURCE = "Universal Robots' published DH parameters and link masses"
#: The same, short, for a listing's URDF column.
SHORT = "(built: UR's published table)"

#: The UR arms' joint names (those of UR's own ROS description, and of the tool's
#: ``ur3``/``ur5``/``ur10``), base to flange.
UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint")
UR_LINKS = ("base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
            "wrist_2_link", "wrist_3_link")
_HALF_PI = math.pi / 2


@dataclass(frozen=True)
class PublishedArm:
    """One arm of a manufacturer's published table (SI units; joint *i* is index *i−1*).

    Attributes:
        name: the name ``--robot`` takes.
        title: what the arm is, for listings.
        a_m, d_m, alpha_rad: the DH parameters (standard convention:
            ``T_i = Rot_z(theta_i) · Trans_z(d_i) · Trans_x(a_i) · Rot_x(alpha_i)``).
        mass_kg: each link's mass.
        com_m: each link's centre of mass in its DH frame *i*.
        effort_nm: each joint's rated torque (the URDF's effort limit).
        velocity_rad_s: each joint's rated speed.
        housing_radius_m: the radius of the sphere that stands in for each link's
            unpublished rotational inertia.
        continuous: the joints (0-based) that turn endlessly.
    """

    name: str
    title: str
    a_m: tuple[float, ...]
    d_m: tuple[float, ...]
    alpha_rad: tuple[float, ...]
    mass_kg: tuple[float, ...]
    com_m: tuple[tuple[float, float, float], ...]
    effort_nm: tuple[float, ...]
    velocity_rad_s: tuple[float, ...]
    housing_radius_m: float
    continuous: tuple[int, ...] = ()
    joints: tuple[str, ...] = UR_JOINTS
    links: tuple[str, ...] = UR_LINKS
    tip: str = "tool0"


_UR_ALPHA = (_HALF_PI, 0.0, 0.0, _HALF_PI, -_HALF_PI, 0.0)

#: The arms the tool builds from published tables.
ARMS: tuple[PublishedArm, ...] = (
    PublishedArm(
        "ur3e", "Universal Robots UR3e (6 dof; built from UR's published table)",
        a_m=(0.0, -0.24355, -0.2132, 0.0, 0.0, 0.0),
        d_m=(0.15185, 0.0, 0.0, 0.13105, 0.08535, 0.0921),
        alpha_rad=_UR_ALPHA,
        mass_kg=(1.98, 3.4445, 1.437, 0.871, 0.805, 0.261),
        com_m=((0.0, -0.02, 0.0), (0.13, 0.0, 0.1157), (0.05, 0.0, 0.0238), (0.0, 0.0, 0.01),
               (0.0, 0.0, 0.01), (0.0, 0.0, -0.02)),
        effort_nm=(56.0, 56.0, 28.0, 12.0, 12.0, 12.0),
        velocity_rad_s=(math.pi, math.pi, math.pi, 2 * math.pi, 2 * math.pi, 2 * math.pi),
        housing_radius_m=0.045, continuous=(5,)),
    PublishedArm(
        "ur5e", "Universal Robots UR5e (6 dof; built from UR's published table)",
        a_m=(0.0, -0.425, -0.3922, 0.0, 0.0, 0.0),
        d_m=(0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996),
        alpha_rad=_UR_ALPHA,
        mass_kg=(3.761, 8.058, 2.846, 1.37, 1.3, 0.365),
        com_m=((0.0, -0.02561, 0.00193), (0.2125, 0.0, 0.11336), (0.15, 0.0, 0.0265),
               (0.0, -0.0018, 0.01634), (0.0, 0.0018, 0.01634), (0.0, 0.0, -0.001159)),
        effort_nm=(150.0, 150.0, 150.0, 28.0, 28.0, 28.0),
        velocity_rad_s=(math.pi,) * 6,
        housing_radius_m=0.06),
    PublishedArm(
        "ur10e", "Universal Robots UR10e (6 dof; built from UR's published table)",
        a_m=(0.0, -0.6127, -0.57155, 0.0, 0.0, 0.0),
        d_m=(0.1807, 0.0, 0.0, 0.17415, 0.11985, 0.11655),
        alpha_rad=_UR_ALPHA,
        mass_kg=(7.369, 13.051, 3.989, 2.1, 1.98, 0.615),
        com_m=((0.021, 0.0, 0.027), (0.38, 0.0, 0.158), (0.24, 0.0, 0.068),
               (0.0, 0.007, 0.018), (0.0, 0.007, 0.018), (0.0, 0.0, -0.026)),
        effort_nm=(330.0, 330.0, 150.0, 56.0, 56.0, 56.0),
        velocity_rad_s=(2 * math.pi / 3, 2 * math.pi / 3, math.pi, math.pi, math.pi, math.pi),
        housing_radius_m=0.075),
)
_BY_NAME = {a.name: a for a in ARMS}


def arm(name: str) -> PublishedArm | None:
    """The published arm ``name`` (case-insensitive), or None."""
    return _BY_NAME.get(str(name).strip().lower())


def _f(x: float) -> str:
    """A number as the URDF writes it: the shortest text that reads back to the same float."""
    return repr(float(x)) if x != 0 else "0"


def _rot_x(alpha: float, v: tuple[float, float, float]) -> tuple[float, float, float]:
    c, s = math.cos(alpha), math.sin(alpha)
    return (v[0], c * v[1] - s * v[2], s * v[1] + c * v[2])


def urdf_xml(a: PublishedArm) -> str:
    """The URDF text of published arm ``a`` (see the module docstring for the frames).

    The text is a pure function of the table: the same on every machine, so its sha256 is
    the arm's provenance."""
    n = len(a.joints)
    out = ['<?xml version="1.0"?>',
           f'<!-- {a.title}. Built by impactcli from {SOURCE}; rotational inertia: a solid '
           f'sphere of radius {_f(a.housing_radius_m)} m per link (not published). -->',
           f'<robot name="{a.name}">',
           f'  <link name="{a.links[0]}"/>']
    for i in range(n):
        # link i+1 is DH frame i turned by q_{i+1}; its body sits at DH frame i+1, reached
        # through the fixed part of DH transform i+1: Trans_z(d) Trans_x(a) Rot_x(alpha).
        ai, di, al = a.a_m[i], a.d_m[i], a.alpha_rad[i]
        c = _rot_x(al, a.com_m[i])
        com = (ai + c[0], c[1], di + c[2])
        m = a.mass_kg[i]
        inertia = 0.4 * m * a.housing_radius_m ** 2  # a solid sphere: the same about any axis
        if i == 0:
            parent_xyz, parent_rpy = (0.0, 0.0, 0.0), 0.0
        else:
            parent_xyz, parent_rpy = (a.a_m[i - 1], 0.0, a.d_m[i - 1]), a.alpha_rad[i - 1]
        kind = "continuous" if i in a.continuous else "revolute"
        limit = (f'<limit effort="{_f(a.effort_nm[i])}" velocity="{_f(a.velocity_rad_s[i])}"'
                 + ("/>" if kind == "continuous" else
                    f' lower="{_f(-2 * math.pi)}" upper="{_f(2 * math.pi)}"/>'))
        out += [
            f'  <joint name="{a.joints[i]}" type="{kind}">',
            f'    <parent link="{a.links[i]}"/>',
            f'    <child link="{a.links[i + 1]}"/>',
            f'    <origin xyz="{" ".join(_f(v) for v in parent_xyz)}" '
            f'rpy="{_f(parent_rpy)} 0 0"/>',
            '    <axis xyz="0 0 1"/>',
            f'    {limit}',
            '  </joint>',
            f'  <link name="{a.links[i + 1]}">',
            '    <inertial>',
            f'      <origin xyz="{" ".join(_f(v) for v in com)}" rpy="0 0 0"/>',
            f'      <mass value="{_f(m)}"/>',
            f'      <inertia ixx="{_f(inertia)}" ixy="0" ixz="0" iyy="{_f(inertia)}" iyz="0" '
            f'izz="{_f(inertia)}"/>',
            '    </inertial>',
            '  </link>',
        ]
    last = n - 1
    out += [
        f'  <joint name="{a.links[-1]}-{a.tip}_fixed_joint" type="fixed">',
        f'    <parent link="{a.links[-1]}"/>',
        f'    <child link="{a.tip}"/>',
        f'    <origin xyz="{_f(a.a_m[last])} 0 {_f(a.d_m[last])}" '
        f'rpy="{_f(a.alpha_rad[last])} 0 0"/>',
        '  </joint>',
        f'  <link name="{a.tip}"/>',
        '</robot>',
        '',
    ]
    return "\n".join(out)
