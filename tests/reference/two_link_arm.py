"""A 2-link planar arm in a vertical plane, closed form (Spong, Hutchinson & Vidyasagar).

Written independently of :mod:`impactcli.model.structures` — it is the reference the
planar and URDF regressors are checked against, and a source of exactly rigid test data.
Angles as in the robot description: q1 from the horizontal, q2 relative to link 1;
gravity g along −y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TwoLinkArm:
    """Physical parameters [m, kg, kg·m², N·m·s/rad, N·m].

    ``l*`` link lengths, ``lc*`` centre-of-mass distances along the links, ``i*`` inertias
    about the centres of mass (axis normal to the plane), ``ia*`` reflected motor inertias,
    ``fv*``/``fc*`` viscous/Coulomb friction (Coulomb through tanh(q'/vs)), ``off*`` offsets.
    """

    l1: float = 0.5
    l2: float = 0.4
    m1: float = 2.0
    m2: float = 1.5
    lc1: float = 0.25
    lc2: float = 0.2
    i1: float = 0.05
    i2: float = 0.03
    ia1: float = 0.02
    ia2: float = 0.015
    fv1: float = 0.3
    fv2: float = 0.2
    fc1: float = 0.4
    fc2: float = 0.25
    off1: float = 0.1
    off2: float = -0.05
    g: float = 9.81
    vs: float = 0.01

    def torque(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """(N, 2) joint torque M q'' + C q' + g + friction + offset [N·m]."""
        q1, q2 = q[:, 0], q[:, 1]
        d1, d2 = qd[:, 0], qd[:, 1]
        a1, a2 = qdd[:, 0], qdd[:, 1]
        c2, s2 = np.cos(q2), np.sin(q2)
        m11 = (self.m1 * self.lc1**2
               + self.m2 * (self.l1**2 + self.lc2**2 + 2 * self.l1 * self.lc2 * c2)
               + self.i1 + self.i2 + self.ia1)
        m12 = self.m2 * (self.lc2**2 + self.l1 * self.lc2 * c2) + self.i2
        m22 = self.m2 * self.lc2**2 + self.i2 + self.ia2
        h = -self.m2 * self.l1 * self.lc2 * s2
        g1 = ((self.m1 * self.lc1 + self.m2 * self.l1) * self.g * np.cos(q1)
              + self.m2 * self.lc2 * self.g * np.cos(q1 + q2))
        g2 = self.m2 * self.lc2 * self.g * np.cos(q1 + q2)
        t1 = m11 * a1 + m12 * a2 + h * (2 * d1 * d2 + d2**2) + g1
        t2 = m12 * a1 + m22 * a2 - h * d1**2 + g2
        t1 = t1 + self.fv1 * d1 + self.fc1 * np.tanh(d1 / self.vs) + self.off1
        t2 = t2 + self.fv2 * d2 + self.fc2 * np.tanh(d2 / self.vs) + self.off2
        return np.stack([t1, t2], axis=1)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """(N, 2, 2) inertia matrix M(q) including the motor inertias [kg·m²]."""
        z = np.zeros_like(q)
        base = self.torque(q, z, z)
        out = np.empty((q.shape[0], 2, 2))
        for i in range(2):
            e = np.zeros_like(q)
            e[:, i] = 1.0
            out[:, :, i] = self.torque(q, z, e) - base
        return out

    def base_parameters(self) -> dict[str, float]:
        """The planar structure's base parameters (names without joint prefix, per link)."""
        return {
            "1.ZZR": self.i1 + self.m1 * self.lc1**2 + self.m2 * self.l1**2 + self.ia1,
            "1.MXR": self.m1 * self.lc1 + self.m2 * self.l1,
            "1.MYR": 0.0,
            "1.fv": self.fv1, "1.fc": self.fc1, "1.offset": self.off1,
            "2.ZZR": self.i2 + self.m2 * self.lc2**2,
            "2.MXR": self.m2 * self.lc2,
            "2.MYR": 0.0,
            "2.Ia": self.ia2,
            "2.fv": self.fv2, "2.fc": self.fc2, "2.offset": self.off2,
        }

    def urdf(self, names: tuple[str, str] = ("j1", "j2")) -> str:
        """The same arm as URDF text (joint axes −y, links along x, gravity −z ≡ −y here).

        Motor inertias and friction are not in the URDF: the urdf model has its own ``Ia``
        and friction columns for them.
        """
        def link(name: str, m: float, lc: float, izz: float) -> str:
            return (
                f'<link name="{name}"><inertial><origin xyz="{lc} 0 0"/><mass value="{m}"/>'
                f'<inertia ixx="0.01" ixy="0" ixz="0" iyy="{izz}" iyz="0" izz="0.02"/>'
                "</inertial></link>"
            )

        lim = '<limit lower="-10" upper="10" effort="100" velocity="10"/>'
        return (
            '<?xml version="1.0"?><robot name="two_link"><link name="base"/>'
            + link("link1", self.m1, self.lc1, self.i1) + link("link2", self.m2, self.lc2, self.i2)
            + f'<joint name="{names[0]}" type="revolute"><parent link="base"/>'
            f'<child link="link1"/><axis xyz="0 -1 0"/>{lim}</joint>'
            f'<joint name="{names[1]}" type="revolute"><parent link="link1"/><child link="link2"/>'
            f'<origin xyz="{self.l1} 0 0"/><axis xyz="0 -1 0"/>{lim}</joint></robot>'
        )


def multisine(
    t: np.ndarray, n_joints: int = 2, seed: int = 0, f_max: float = 1.5, amp: float = 0.6,
    n_freq: int = 4,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smooth exciting trajectory with exact derivatives: (q, qd, qdd), each (N, n_joints).

    A sum of ``n_freq`` sines per joint up to ``f_max`` Hz, random phases, total amplitude
    about ``amp`` rad around a random offset.
    """
    rng = np.random.default_rng(seed)
    q = np.zeros((t.size, n_joints))
    qd = np.zeros_like(q)
    qdd = np.zeros_like(q)
    for j in range(n_joints):
        q[:, j] += rng.uniform(-0.5, 0.5)
        for f in rng.uniform(0.15, f_max, n_freq):
            w = 2 * np.pi * f
            a = amp / n_freq * rng.uniform(0.6, 1.4)
            ph = rng.uniform(0, 2 * np.pi)
            q[:, j] += a * np.sin(w * t + ph)
            qd[:, j] += a * w * np.cos(w * t + ph)
            qdd[:, j] -= a * w * w * np.sin(w * t + ph)
    return q, qd, qdd
