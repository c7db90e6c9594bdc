"""Tests of the flexible-joint simulator (impactcli.sim) against known physics."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from impactcli.logs.robot_files import robot_from_dict
from impactcli.sim import (
    LABEL_THRESHOLD_N,
    SCENARIOS,
    Clamp,
    MultiSine,
    Push,
    Scenario,
    Surface,
    Triangle,
    Waypoints,
    assist_like,
    energy,
    heavy_geared,
    scenario,
    simulate,
)
from impactcli.sim import kernel as kern
from impactcli.sim.arm import true_parameters, without_losses
from impactcli.sim.reference import FMTriangle, PointToPoint


def _state(res) -> np.ndarray:
    t = res.truth
    return np.c_[t["x1"], t["x2"], t["x1_dot"], t["x2_dot"]]


@pytest.mark.parametrize("arm", [assist_like(), heavy_geared()], ids=lambda a: a.name)
def test_energy_conserved_without_friction_and_control(arm):
    """Free motion of eq. 1–2 (no friction, damping, control, contact) keeps its energy:
    to ~1e-8 of the kinetic energy with fine steps, and the error falls as RK4's h⁴."""
    n = arm.n_joints
    start = tuple([0.4] + [0.3] * (n - 1))
    ref = Triangle(start, (0.0,) * n, (1.0,) * n)
    sc = Scenario("energy", without_losses(arm), 2.0, ref, control=False, friction=False,
                  friction_drift=0.0, initial_link_velocity=tuple([1.0] + [-2.0] * (n - 1)))
    drift = {}
    for sub in (None, 8, 16):
        res = simulate(replace(sc, substeps=sub), seed=4)
        e = energy(res.params, _state(res), arm.gravity)
        drift[sub] = np.max(np.abs(e - e[0]))
    assert np.ptp(res.truth["x2"][:, 0]) > 0.3  # it really moved
    p = res.params
    m = np.empty((n, n))
    ke = 0.0
    for q, v in zip(res.truth["x2"][::25], res.truth["x2_dot"][::25], strict=True):
        kern.mass_matrix(q, p["lengths"], p["mass"], p["com"], p["inertia"], m)
        ke = max(ke, 0.5 * v @ m @ v)
    assert ke > 0.1
    assert drift[16] < 1e-7 * ke
    assert drift[8] / drift[16] > 10  # 4th-order convergence: 16x per halving of h
    assert drift[None] < 1e-3 * ke  # default substeps (chosen for stability)


def test_mass_matrix_matches_newton_euler():
    """M(q) columns equal RNEA(q, 0, e_j) without gravity; M is symmetric positive definite."""
    p = true_parameters(heavy_geared(), np.random.default_rng(1), 0.2, payload_kg=1.0)
    rng = np.random.default_rng(2)
    for _ in range(5):
        q = rng.uniform(-2, 2, 3)
        m = np.empty((3, 3))
        kern.mass_matrix(q, p["lengths"], p["mass"], p["com"], p["inertia"], m)
        cols = np.empty((3, 3))
        out = np.empty(3)
        for j in range(3):
            kern.rnea(q, np.zeros(3), np.eye(3)[j], p["lengths"], p["mass"], p["com"],
                      p["inertia"], 0.0, 0.0, out)
            cols[:, j] = out
        np.testing.assert_allclose(m, cols, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(m, m.T, atol=1e-14)
        assert np.linalg.eigvalsh(m)[0] > 0


def _point(q: np.ndarray, lengths: np.ndarray, link: int, frac: float) -> np.ndarray:
    phi = np.cumsum(q)
    p = np.zeros(2)
    for i in range(link):
        p += lengths[i] * np.array([math.cos(phi[i]), math.sin(phi[i])])
    return p + frac * lengths[link] * np.array([math.cos(phi[link]), math.sin(phi[link])])


def test_external_torque_is_jacobian_transpose_of_force():
    """tau_ext = J(q)^T F, with J from central finite differences of the forward kinematics."""
    lengths = np.array([0.5, 0.4, 0.2])
    rng = np.random.default_rng(3)
    for link in range(3):
        q = rng.uniform(-1.5, 1.5, 3)
        frac, ang, peak = 0.7, 0.9, 12.0
        forces = np.array([[link, frac, ang, peak, 0.0, 1.0, 0, 0, kern.PULSE]])
        t = 0.5  # half-sine peak
        w = np.zeros((kern.N_SCRATCH, 4))
        kern.kin_w(q, 0, 3, lengths, w)
        tau = np.empty(3)
        src = np.empty(1)
        kern.external(t, 3, np.zeros(3), 0, lengths, w, np.zeros((0, 7)), forces, tau, src,
                      np.zeros(0))
        f = peak * np.array([math.cos(ang), math.sin(ang)])
        jac = np.empty((2, 3))
        h = 1e-6
        for j in range(3):
            dq = np.zeros(3)
            dq[j] = h
            jac[:, j] = (_point(q + dq, lengths, link, frac)
                         - _point(q - dq, lengths, link, frac)) / (2 * h)
        np.testing.assert_allclose(tau, jac.T @ f, atol=1e-7)
        assert src[0] == pytest.approx(peak)


def test_deterministic_for_a_seed():
    sc = scenario("pushes", "assist_like", 9.0)
    a, b = simulate(sc, seed=7), simulate(sc, seed=7)
    c = simulate(sc, seed=8)
    for name in ("position", "torque", "current", "velocity", "position_ref"):
        np.testing.assert_array_equal(getattr(a.log, name), getattr(b.log, name))
    np.testing.assert_array_equal(a.log.t_ns, b.log.t_ns)
    assert a.labels.to_dict() == b.labels.to_dict()
    assert not np.array_equal(a.log.torque, c.log.torque)


def test_robot_seed_fixes_the_robot_not_the_run():
    """Same robot_seed: the same true parameters whatever the run seed (noise and drift
    still differ); another robot_seed or none: another robot."""
    sc = replace(scenario("free_p2p", "assist_like", 3.0), robot_seed=100)
    a, b = simulate(sc, seed=1), simulate(sc, seed=2)
    for k in a.params:
        np.testing.assert_array_equal(a.params[k], b.params[k])
    assert not np.array_equal(a.log.torque, b.log.torque)
    other = simulate(replace(sc, robot_seed=101), seed=1)
    unit = simulate(replace(sc, robot_seed=None), seed=1)
    assert not np.array_equal(a.params["mass"], other.params["mass"])
    assert not np.array_equal(a.params["mass"], unit.params["mass"])


def test_sample_logs_of_an_arm_share_one_robot():
    from impactcli.sim.sample_logs import MANIFEST, ROBOT_SEEDS

    for arm, seed in ROBOT_SEEDS.items():
        scs = [m.make() for m in MANIFEST if m.arm == arm]
        assert len(scs) >= 3 and all(sc.robot_seed == seed for sc in scs)


def test_labels_match_true_contact_force():
    pushes = (Push(link=2, t0_s=1.0, peak_n=10.0, duration_s=0.2),
              Push(link=1, t0_s=2.0, peak_n=25.0, duration_s=0.3, point=0.5,
                   direction_deg=90.0))
    clamps = (Clamp(link=2, t0_s=3.0, peak_n=20.0, rise_s=1.0, hold_s=0.5, release_s=0.1),)
    arm = assist_like()
    sc = Scenario("lab", arm, 6.0, MultiSine((0.0, 0.3), (0.2, 0.2)), pushes=pushes,
                  clamps=clamps)
    res = simulate(sc, seed=1)
    f = res.truth["contact_force"]
    t = res.truth["time_s"]
    ts = arm.sample_period_s
    assert [(e.kind, e.link) for e in res.labels.events] == [("push", 2), ("push", 1),
                                                            ("clamp", 2)]
    for e, spec in zip(res.labels.events, (*pushes, *clamps), strict=True):
        k = e.extra["source"]
        a, b = round(e.start / ts), round(e.end / ts)
        assert t[a] == pytest.approx(e.start) and t[b] == pytest.approx(e.end)
        assert f[a, k] > LABEL_THRESHOLD_N >= f[a - 1, k]
        assert f[b, k] > LABEL_THRESHOLD_N >= f[b + 1, k]
        assert e.peak_force == pytest.approx(f[a:b + 1, k].max())
        assert e.peak_force == pytest.approx(spec.peak_n, rel=0.02)
        assert e.start == pytest.approx(spec.t0_s, abs=0.05)
    # the external torque is non-zero exactly when some force acts
    active = res.truth["contact_force_total"] > 0
    assert np.all(np.abs(res.truth["tau_ext"][~active]) == 0)
    assert np.all(np.abs(res.truth["tau_ext"][active]).sum(axis=1) > 0)


def test_position_on_encoder_grid_and_torque_from_quantised_current():
    arm = assist_like()
    res = simulate(scenario("free_triangle", arm, 4.0), seed=2)
    counts = res.log.position / arm.encoder_resolution
    assert np.max(np.abs(counts - np.round(counts))) < 1e-3
    assert len(np.unique(res.log.position[:, 0])) > 50  # moved over many counts
    steps = res.log.current / np.asarray(arm.current_lsb_a)
    assert np.max(np.abs(steps - np.round(steps))) < 1e-3
    np.testing.assert_allclose(res.log.torque, res.log.current * arm.torque_scale, atol=1e-6)
    # the logged torque is noisy: it differs from the applied torque by ~ the noise level
    resid = res.log.torque - res.truth["tau"]
    noise = np.asarray(arm.current_noise_a) * arm.torque_scale
    np.testing.assert_allclose(resid.std(axis=0), noise, rtol=0.2)
    # and the true motor position differs from the logged one by < half a count
    assert np.all(np.abs(res.truth["x1"] - res.log.position) <= 0.5 * arm.encoder_resolution
                  + 1e-6)


@pytest.mark.parametrize("arm", ["assist_like", "heavy_geared"])
def test_pd_tracks_reference(arm):
    res = simulate(scenario("free_multisine", arm, 8.0), seed=3)
    err = res.log.position_ref - res.log.position
    amp = np.ptp(res.log.position_ref, axis=0)
    assert np.all(amp > 0.1)
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) < 0.05 * amp)


def test_contact_force_is_stiffness_times_penetration():
    """Elastomer force = k δ + c δ' while penetrating, 0 otherwise; tau_ext = J^T F."""
    arm = assist_like()
    reach = sum(arm.link_lengths)
    th_s = -0.05
    ref = Waypoints((0.0, 0.5, 1.5, 2.5, 3.5), ((0.05, 0.0), (0.05, 0.0), (-0.25, 0.0),
                                                (-0.25, 0.0), (0.05, 0.0)))
    surf = Surface(reach * math.sin(th_s), 5.93, x_min_m=reach - 0.2, x_max_m=reach + 0.2)
    res = simulate(Scenario("surf", arm, 4.0, ref, surfaces=(surf,)), seed=5)
    tr = res.truth
    k = 5.93e3
    c = 0.002 * k
    pen = tr["penetration"][:, 0]
    inside = pen > 0
    assert inside.sum() > 100
    f = tr["contact_force"][:, 0]
    assert np.all(f[~inside] == 0)
    # tip vertical velocity from the link velocities (J row)
    x2, x2d = tr["x2"], tr["x2_dot"]
    vy = np.empty(len(pen))
    for i, (q, qd) in enumerate(zip(x2, x2d, strict=True)):
        cs, sn, ox, oy = np.empty(2), np.empty(2), np.empty(3), np.empty(3)
        kern.kinematics(q, np.asarray(arm.link_lengths), cs, sn, ox, oy)
        vy[i] = np.dot(ox[2] - ox[:2], qd)
    expect = np.maximum(k * pen - c * vy, 0.0)
    np.testing.assert_allclose(f[inside], expect[inside], rtol=1e-9, atol=1e-9)
    # quasi-static part: while the tip rests, F ≈ k δ
    rest = inside & (np.abs(vy) < 1e-3)
    assert rest.sum() > 50
    np.testing.assert_allclose(f[rest], k * pen[rest], rtol=0.02)
    assert f.max() > 5
    # the label says impact on the last link, with a peak equal to the sampled maximum
    (e,) = res.labels.events
    assert (e.kind, e.link, e.peak_force) == ("impact", 2, pytest.approx(f.max()))


def test_references_are_consistent():
    """Velocity references integrate to the position references; triangles are velocity steps."""
    ts = 0.004
    t = np.arange(5000) * ts
    rng = np.random.default_rng(0)
    refs = [Triangle((0.0,), (0.3,), (2.0,)), FMTriangle((0.0,), (0.3,), (2.0,)),
            PointToPoint((0.0,), (-0.5,), (0.5,), (1.0,), (4.0,)),
            MultiSine((0.1,), (0.4,))]
    for ref in refs:
        pos, vel, acc = ref.generate(t, ts, rng)
        integ = pos[0] + np.concatenate(([0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]) * ts)))
        assert np.max(np.abs(integ - pos[:, 0])) < 0.02, type(ref).__name__
    _, vel, acc = refs[0].generate(t, ts, rng)
    assert set(np.round(np.abs(vel[:, 0]), 9)) == {0.6}
    spikes = np.flatnonzero(acc[:, 0])
    assert len(spikes) == 20  # one impulse per corner: 2 per period, 10 periods in 20 s
    np.testing.assert_allclose(np.abs(acc[spikes, 0]), 1.2 / ts)
    _, vel, acc = refs[3].generate(t, ts, np.random.default_rng(0))
    np.testing.assert_allclose(np.gradient(vel[:, 0], ts)[5:-5], acc[5:-5, 0], atol=0.01)


def test_scenario_library_and_nominal_description():
    for arm in ("assist_like", "heavy_geared"):
        for name in SCENARIOS:
            sc = scenario(name, arm)
            assert sc.duration_s >= 30
            assert sc.arm.name == arm
    sc = scenario("payload", "assist_like", 5.0, uncertainty=0.0)
    assert sc.payload_kg > 0 and sc.uncertainty == 0.0 and sc.duration_s == 5.0
    with pytest.raises(ValueError, match="unknown scenario"):
        scenario("nope")
    res = simulate(replace(sc, duration_s=0.5), seed=0)
    robot = robot_from_dict(res.robot.to_dict())
    assert robot.kinematics["type"] == "planar"
    assert robot.kinematics["link_lengths"] == [0.4, 0.4]
    assert robot.nominal["link_masses"] == [1.6, 1.0]
    assert res.log.source.format == "memory"
    assert res.log.sample_period_s == pytest.approx(0.004)
    # the true robot is not the nominal one: uncertainty 0 but a payload on the last link
    assert res.params["mass"][-1] == pytest.approx(1.0 + sc.payload_kg)


def test_payload_loads_the_shoulder():
    base = scenario("free_multisine", "assist_like", 6.0, uncertainty=0.0, noise=False)
    a = simulate(base, seed=1)
    b = simulate(replace(base, payload_kg=0.5), seed=1)
    # the extra gravity torque at the shoulder ≈ payload × g × horizontal reach
    extra = (b.log.torque[:, 0] - a.log.torque[:, 0])[750:].mean()
    reach = np.abs(a.truth["tip"][750:, 0]).mean()
    assert extra == pytest.approx(0.5 * 9.81 * reach, rel=0.15)


def test_friction_drift_is_slow_and_bounded():
    res = simulate(scenario("free_triangle", "assist_like", 2.0), seed=1)
    fs = res.truth["friction_scale"]
    np.testing.assert_allclose(fs[0], 1.0)
    assert np.all((fs > 0.7) & (fs < 1.1))
    assert np.max(np.abs(np.diff(fs, axis=0))) < 1e-4


def test_a_payload_picked_mid_run_changes_the_arm_from_then_on() -> None:
    """``Scenario.payload_changes``: the run is the payload-free run bit for bit up to the
    pick; after it the servos hold the load (the shoulder's torque rises by about its
    gravity torque, m g times the horizontal reach of the tip)."""
    from dataclasses import replace

    from impactcli.sim import scenario, simulate

    base = scenario("free_multisine", duration_s=8.0, robot_seed=3)
    picked = replace(base, payload_changes=((4.0, 1.5),))
    a, b = simulate(base, seed=1), simulate(picked, seed=1)
    k = round(4.0 / base.arm.sample_period_s)
    np.testing.assert_array_equal(a.log.torque[:k], b.log.torque[:k])
    np.testing.assert_array_equal(a.log.position[:k], b.log.position[:k])
    late = slice(k + 250, None)  # a second after the pick, the servos hold the load
    extra = b.log.torque[late, 0] - a.log.torque[late, 0]
    reach = b.truth["tip"][late, 0]  # horizontal distance of the tip from the base [m]
    expected = 1.5 * 9.81 * reach
    assert abs(np.median(extra / expected) - 1.0) < 0.15
