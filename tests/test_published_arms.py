"""Arms built from their manufacturer's published table (impactcli/logs/published_arms.py):
the built URDF against the DH chain computed here without Pinocchio, its gravity against the
potential energy of the published masses, the UR10e against a real UR10e controller's own
model torque, ``--robot ur10e`` end to end with only Pinocchio installed, and the detection
floor of links that end on their own joint's axis.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from impactcli.logs import published_arms, write_log
from impactcli.logs import robot_catalogue as robots
from impactcli.logs.robot_files import named_robot_sha256

from .cli_run import cli
from .robot_logs import synthetic_log

pin = pytest.importorskip("pinocchio", reason="the urdf extra (pinocchio) is not installed")
pytestmark = pytest.mark.urdf

ARMS = [a.name for a in published_arms.ARMS]
G = 9.81


def dh(a: published_arms.PublishedArm, q: np.ndarray) -> list[np.ndarray]:
    """The DH frames 1..6 (4×4, base frame) at ``q``: T_i = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)."""
    t = np.eye(4)
    out = []
    for i, qi in enumerate(q):
        c, s = math.cos(qi), math.sin(qi)
        ca, sa = math.cos(a.alpha_rad[i]), math.sin(a.alpha_rad[i])
        step = np.array([[c, -s * ca, s * sa, a.a_m[i] * c],
                         [s, c * ca, -c * sa, a.a_m[i] * s],
                         [0.0, sa, ca, a.d_m[i]],
                         [0.0, 0.0, 0.0, 1.0]])
        t = t @ step
        out.append(t)
    return out


def potential(a: published_arms.PublishedArm, q: np.ndarray) -> float:
    """The links' potential energy [J] at ``q``: each published mass at its published centre
    of mass (DH frame i), gravity along −z of the base."""
    return sum(m * G * (f @ np.r_[c, 1.0])[2]
               for m, c, f in zip(a.mass_kg, a.com_m, dh(a, q), strict=True))


def pin_q(model: object, q: np.ndarray) -> np.ndarray:
    """Pinocchio's configuration for joint angles ``q`` (a continuous joint: cos, sin)."""
    x = []
    for jm, qi in zip(list(model.joints)[1:], q, strict=True):  # type: ignore[attr-defined]
        x += [qi] if jm.nq == 1 else [math.cos(qi), math.sin(qi)]
    return np.array(x)


@pytest.mark.parametrize("name", ARMS)
def test_built_urdf_is_the_published_dh_chain(name: str) -> None:
    a = published_arms.arm(name)
    assert a is not None
    model = pin.buildModelFromXML(robots.urdf_text(name))
    data = model.createData()
    assert tuple(robots.arm_joints(name)) == a.joints
    tool = model.getFrameId("tool0")
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.uniform(-math.pi, math.pi, 6)
        x = pin_q(model, q)
        pin.framesForwardKinematics(model, data, x)
        frames = dh(a, q)
        np.testing.assert_allclose(data.oMf[tool].homogeneous, frames[-1], atol=1e-12)
        for i in range(1, 6):  # joint i+1 sits at the origin of DH frame i
            np.testing.assert_allclose(data.oMi[i + 1].translation, frames[i - 1][:3, 3],
                                       atol=1e-12)
        # gravity: the gradient of the published masses' potential energy
        h = 1e-6
        grad = np.array([(potential(a, q + h * e) - potential(a, q - h * e)) / (2 * h)
                         for e in np.eye(6)])
        tau_g = pin.computeGeneralizedGravity(model, data, x)
        np.testing.assert_allclose(tau_g, grad, atol=1e-6 * (1 + np.abs(grad).max()))
    masses = [model.inertias[i].mass for i in range(1, 7)]
    np.testing.assert_allclose(masses, a.mass_kg, rtol=1e-15)


@pytest.mark.parametrize("name", ARMS)
def test_built_urdf_mass_matrix_is_the_tables_bodies(name: str) -> None:
    """The mass matrix of the built URDF against M(q) = sum_i m_i Jv_i' Jv_i +
    I_i Jw_i' Jw_i computed here from the DH chain: each published mass at its published
    centre of mass (the velocity Jacobian by central differences) with the stand-in
    inertia, a sphere's, the same about every axis (the angular Jacobian: the joint axes
    z_0 … z_(i−1)). It checks every link's centre of mass, link 1's included, which gravity
    does not see (joint 1 is vertical)."""
    a = published_arms.arm(name)
    assert a is not None
    model = pin.buildModelFromXML(robots.urdf_text(name))
    data = model.createData()
    rng = np.random.default_rng(11)
    h = 1e-6
    for _ in range(5):
        q = rng.uniform(-math.pi, math.pi, 6)

        def com(x: np.ndarray, i: int) -> np.ndarray:
            return (dh(a, x)[i] @ np.r_[a.com_m[i], 1.0])[:3]

        frames = dh(a, q)
        axes = [np.array([0.0, 0.0, 1.0])] + [f[:3, 2] for f in frames[:-1]]
        m = np.zeros((6, 6))
        for i in range(6):
            jv = np.column_stack([(com(q + h * e, i) - com(q - h * e, i)) / (2 * h)
                                  for e in np.eye(6)])
            jw = np.column_stack([axes[k] if k <= i else np.zeros(3) for k in range(6)])
            inertia = 0.4 * a.mass_kg[i] * a.housing_radius_m ** 2
            m += a.mass_kg[i] * jv.T @ jv + inertia * jw.T @ jw
        crba = pin.crba(model, data, pin_q(model, q))  # its upper triangle
        np.testing.assert_allclose(np.triu(crba), np.triu(m), atol=1e-7)


def test_the_built_text_is_the_provenance() -> None:
    text = robots.urdf_text("ur10e")
    assert text == published_arms.urdf_xml(published_arms.ARMS[2])
    assert named_robot_sha256("ur10e") == hashlib.sha256(text.encode("utf-8")).hexdigest()
    assert "built from Universal Robots' published" in robots.urdf_label("UR10E")


def test_ur10e_gravity_is_a_real_ur10e_controllers_model_torque(real_logs: Path) -> None:
    """A real UR10e held still (ur_ext_observer/ur-static.csv): its columns 25–30 stay at
    the controller's model torque for the pose [N·m]. The published table, built into a
    URDF, gives the same gravity torque on the loaded joints to 0.5 % (measured: 0.1 %)."""
    x = np.loadtxt(real_logs / "ur_ext_observer" / "ur-static.csv", delimiter=",")
    q = x[:, 1:7].mean(axis=0)
    assert np.ptp(x[:, 1:7], axis=0).max() < 0.01, "the arm is held still"
    controller = x[:, 25:31].mean(axis=0)
    model = pin.buildModelFromXML(robots.urdf_text("ur10e"))
    tau_g = pin.computeGeneralizedGravity(model, model.createData(), pin_q(model, q))
    loaded = np.abs(controller) > 0.5
    assert loaded[1] and loaded[2], controller
    np.testing.assert_allclose(tau_g[loaded], controller[loaded], rtol=5e-3)
    # a smaller arm of the same family is not it: the check tells the arms apart
    ur5e = pin.buildModelFromXML(robots.urdf_text("ur5e"))
    other = pin.computeGeneralizedGravity(ur5e, ur5e.createData(), pin_q(ur5e, q))
    assert abs(other[1] - controller[1]) > 0.3 * abs(controller[1])


def test_ur10e_by_name_needs_only_pinocchio(tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """Without the robots extra's URDFs: ``robots`` lists the built arms and says in one
    line how to get the others; ``--robot ur10e`` identifies and detects; the detection
    floor of the links that end on their own joint's axis is what the joints before them
    see (link 1's, with none before it, a torque), never a force divided by a rounding
    error."""
    monkeypatch.setattr(robots, "data_dir", lambda: None)
    robots.arm_joints.cache_clear()
    try:
        code, out, err = cli(["robots", "--json"])
        assert code == 0, err
        doc = json.loads(out)
        assert [r["name"] for r in doc["robots"]] == ARMS
        assert all(r["urdf"] is None and r["source"] == published_arms.SOURCE
                   for r in doc["robots"])
        assert {n["name"] for n in doc["not_loaded"]} == {
            r.name for r in robots.CATALOGUE if r.built is None}
        code, out, err = cli(["robots"])
        assert code == 0 and "ur10e" in out
        assert err.count("\n") == 1 and "pip install 'impactcli[robots]'" in err, err

        log = tmp_path / "ur10e.csv"
        write_log(synthetic_log("ur10e"), log)
        code, _, err = cli(["identify", str(log), "--robot", "ur10e",
                            "-o", str(tmp_path / "m.json")])
        assert code == 0, err
        code, out, err = cli(["detect", str(log), "--robot", "ur10e",
                              "-o", str(tmp_path / "out")])
        assert code == 0, err
    finally:
        robots.arm_joints.cache_clear()
    tl = json.loads((tmp_path / "out" / "ur10e.timeline.json").read_text())
    assert tl["model"]["model"]["kind"] == "urdf"
    floor = tl["detection_floor"]
    rows = {r["link"]: r for r in floor["per_link"]}
    # UR frames: the shoulder link ends on the base joint's axis, and each wrist link on
    # its own joint's axis; the upper arm and forearm have levers of 0.6 m and 0.57 m
    assert {k for k, r in rows.items() if r.get("no_lever")} == {1, 4, 5, 6}
    for k, r in rows.items():
        forces = [r[d][q] for d in ("static_loading", "adaptive") if d in r
                  for q in ("median_n", "worst_tenth_n") if r[d].get(q) is not None]
        if k == 1:  # no joint before it
            assert forces == [] and r["own_joint"] == "shoulder_pan_joint", r
        else:
            assert forces and max(forces) < 1e4, r
    line = next(ln for ln in out.splitlines() if ln.startswith("detection floor"))
    assert "a torque below" in line and "N·m on shoulder_pan_joint (its link ends" in line
    assert "(links 4, 5, 6 end on their own joints' axes: the force there is what the " \
        "joints before see)" in line, line
    figures = [float(x) for x in re.findall(r"~([0-9.e+-]+) N", line)]
    assert len(figures) >= 6 and max(figures) < 1e4, line
