"""The simulated controller's own channels (impactcli.sim.controller): ``torque_model`` (the
nominal rigid model on the measured motion) and ``torque_ext`` (a momentum observer on it).

Sign convention checked throughout: torque_ext ≈ +truth['tau_ext'] (the external torque
acting on the joints, Jᵀ F).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from impactcli.sim import (
    Clamp,
    MultiSine,
    Push,
    Scenario,
    assist_like,
    heavy_geared,
    scenario,
    simulate,
)
from impactcli.sim import kernel as kern
from impactcli.sim.arm import ArmParams, nominal_parameters
from impactcli.sim.controller import simulate_channels

LOG_COLUMNS = ("position", "torque", "velocity", "current", "position_ref", "velocity_ref",
               "acceleration_ref")


def _rigid(arm: ArmParams, counts: int | None = None) -> ArmParams:
    """The arm with 100× stiffer, 10× more damped transmissions (modes far above Nyquist),
    the controller's Coulomb smoothing equal to the true one, optionally finer encoders."""
    out = replace(arm, stiffness=tuple(100 * s for s in arm.stiffness),
                  transmission_damping=tuple(10 * d for d in arm.transmission_damping),
                  controller_coulomb_eps=arm.coulomb_velocity_eps)
    return replace(out, encoder_counts=(counts,) * arm.n_joints) if counts else out


def _ideal_observer(ext: np.ndarray, arm: ArmParams) -> np.ndarray:
    """What the discrete observer + output low-pass make of ``ext`` with a perfect model."""
    ts = arm.sample_period_s
    g = 1 - math.exp(-2 * math.pi * arm.torque_ext_cutoff_hz * ts)
    r = np.zeros_like(ext)
    y = np.zeros_like(ext)
    for k in range(1, ext.shape[0]):
        r[k] = r[k - 1] + arm.observer_gain * ts * (ext[k - 1] - r[k - 1])
        y[k] = y[k - 1] + g * (r[k] - y[k - 1])
    return y


def test_observer_and_model_are_exact_on_exact_rigid_data():
    """The equations themselves: on a rigid motion with the torque of the nominal model
    (no noise, no lag, no flexibility), torque_ext stays at the forward-Euler error
    (~Ts/2 · d/dt of the momentum rate: < 0.6 % of the torque range) and torque_model
    equals the torque up to the acceleration filter's lag (< 2.5 %)."""
    arm = assist_like()
    nom = nominal_parameters(arm)
    ts = arm.sample_period_s
    t = np.arange(5000) * ts
    amp = np.array([[0.3, 0.2], [0.4, 0.1]])
    om = np.array([[2.0, 5.0], [3.1, 1.7]])
    ph = np.array([[0.0, 0.0], [1.0, 0.0]])
    arg = om[None] * t[:, None, None] + ph[None]
    q = (amp * np.sin(arg)).sum(axis=2)
    qd = (amp * om * np.cos(arg)).sum(axis=2)
    qdd = (-amp * om**2 * np.sin(arg)).sum(axis=2)
    fv, fc = nom["fv_m"] + nom["fv_a"], nom["fc_m"] + nom["fc_a"]
    tau = np.empty_like(q)
    out = np.empty(2)
    for k in range(t.size):
        kern.rnea(q[k], qd[k], qdd[k], nom["lengths"], nom["mass"], nom["com"],
                  nom["inertia"], *arm.gravity, out)
        tau[k] = out + nom["i_mot"] * qdd[k] + fv * qd[k] + fc * np.tanh(qd[k] / 0.02)
    tm, te = simulate_channels(q, qd, tau, ts, nom, arm.gravity, gain=50.0,
                               accel_cutoff_hz=20.0, coulomb_eps=0.02)
    rng = np.ptp(tau, axis=0)
    assert np.all(np.abs(te[50:]).max(axis=0) < 0.006 * rng)
    assert np.all(np.sqrt(np.mean((tm - tau)[50:] ** 2, axis=0)) < 0.025 * rng)
    # an external torque added to the motion (tau = model − tau_ext) is what r estimates,
    # with the sign of tau_ext and the observer's first-order dynamics
    ext = np.zeros_like(tau)
    ext[2000:3500] = [1.5, -0.7]
    _, te2 = simulate_channels(q, qd, tau - ext, ts, nom, arm.gravity, gain=50.0,
                               accel_cutoff_hz=20.0, coulomb_eps=0.02)
    np.testing.assert_allclose(te2[2200:3500], ext[2200:3500], atol=0.006 * rng.max())
    # a step of tau_ext at sample k0: r(k0 + m) = (1 − (1 − K Ts)^m) tau_ext (forward Euler)
    m = np.arange(1, 30)
    step = 1.0 - (1.0 - 50.0 * ts) ** m
    np.testing.assert_allclose(te2[2000 + m], np.outer(step, ext[2000]),
                               atol=0.006 * rng.max())


@pytest.mark.parametrize("counts", [None, 2**20], ids=["encoder-4096", "encoder-2^20"])
def test_exact_nominal_model_free_motion(counts):
    """(a) Nominal = true (uncertainty 0, no drift), no current noise, stiff transmissions,
    no contact: torque_ext stays near zero and torque_model tracks the motor torque.

    What is left is the measurement: with the 4096-count encoder, the velocity estimate's
    quantisation noise (one count in 4 ms = 0.019 rad/s) enters the observer with the gain
    K·M_r ≈ 50 × 0.45 N·m·s/rad (≈ 0.04 N·m rms after the 20 Hz output filter) and the
    acceleration estimate of torque_model is noisier still (≈ 0.25 N·m rms); with a
    2^20-count encoder both fall to the filters' lag and discretisation (< 0.02 and
    < 0.06 N·m rms) — the equations are right. Torque ranges: 2.5–3.6 / 0.8–1.4 N·m."""
    arm = _rigid(assist_like(), counts)
    sc = scenario("free_multisine", arm, 10.0, uncertainty=0.0, friction_drift=0.0,
                  noise=False, controller_channels=True)
    res = simulate(sc, seed=2)
    log = res.log
    assert log.torque_model is not None and log.torque_ext is not None
    s = slice(round(1.0 / arm.sample_period_s), None)
    te = log.torque_ext[s]
    dm = (log.torque_model - log.torque)[s]
    rng = np.ptp(log.torque[s], axis=0)
    assert np.all(rng > 0.8)
    ext_rms, ext_max = (0.06, 0.15) if counts is None else (0.02, 0.05)
    model_rms, model_max = (0.3, 1.0) if counts is None else (0.06, 0.25)
    assert np.all(np.sqrt(np.mean(te**2, axis=0)) < ext_rms)
    assert np.all(np.abs(te).max(axis=0) < ext_max)
    assert np.all(np.sqrt(np.mean(dm**2, axis=0)) < model_rms)
    assert np.all(np.abs(dm).max(axis=0) < model_max)
    # the truth exposes the same errors (no contact: tau_ext = 0)
    np.testing.assert_array_equal(res.truth["torque_ext_error"], log.torque_ext)
    np.testing.assert_allclose(res.truth["torque_model_error"],
                               log.torque_model - res.truth["tau"])


def _contact_run(seed: int) -> tuple[Scenario, object]:
    arm = assist_like()
    ref = MultiSine((0.0, 0.3), (0.15, 0.15), f_min=0.03, f_max=0.15, n_sines=3)
    clamp = Clamp(link=2, t0_s=3.0, peak_n=20.0, rise_s=1.0, hold_s=1.5, release_s=0.1,
                  point=0.8, direction_deg=-90.0)
    pushes = (Push(link=1, t0_s=7.0, peak_n=20.0, duration_s=0.3, point=0.7,
                   direction_deg=90.0),
              Push(link=2, t0_s=9.0, peak_n=10.0, duration_s=0.15, point=0.8,
                   direction_deg=-90.0))
    sc = Scenario("contacts", arm, 11.0, ref, pushes=pushes, clamps=(clamp,),
                  controller_channels=True)  # default ±20 % robot, noise, drift
    return sc, simulate(sc, seed=seed)


@pytest.mark.parametrize("seed", [1, 4])
def test_torque_ext_follows_known_contacts(seed):
    """(b) On the default robot (±20 %, flexible, noisy), the observer estimates known
    contact torques with the simulator's sign.

    * Clamp held (20 N on link 2, from 5 time constants after the ramp's end): the
      observer is in steady state, so its error is the model error it has in free motion
      at that motion (bounded by the free-motion maximum just before the contact) plus a
      little that the load itself changes (2 % of tau_ext: deflection, friction load).
    * Half-sine pushes (0.3 s on link 1, 0.15 s on link 2): the peak is what the ideal
      observer (perfect model: r' = K (tau_ext − r), then the 20 Hz output filter) makes
      of the truth, within 10 % of the true peak (the flexible links' 6–26 Hz modes
      and the velocity estimate's lag distort fast pulses) plus the free-motion floor; it
      comes 12–60 ms after the true peak (1/K = 20 ms, 8 ms of filter, a pulse's
      smoothing)."""
    sc, res = _contact_run(seed)
    arm = sc.arm
    ts = arm.sample_period_s
    t = res.truth["time_s"]
    ext = res.truth["tau_ext"]
    te = res.log.torque_ext
    assert te is not None
    free = (t > 1.0) & (t < 2.95)
    assert np.all(ext[free] == 0)
    floor = np.abs(te[free]).max(axis=0)
    hold = (t > 4.0 + 5 / arm.observer_gain) & (t < 5.5)
    big = np.abs(ext[hold]).max(axis=0)
    assert np.all(big > 5.0)  # ≈ 14 N·m shoulder, 6 N·m elbow
    err = np.abs(te - ext)[hold].max(axis=0)
    assert np.all(err <= floor + 0.02 * big), (err, floor)
    assert np.all(np.sign(te[hold]) == np.sign(ext[hold]))
    np.testing.assert_array_equal(res.truth["torque_ext_error"], te - ext)
    ideal = _ideal_observer(ext, arm)
    for push in sc.pushes:
        sel = np.flatnonzero((t >= push.t0_s) & (t < push.t0_s + push.duration_s + 0.2))
        for j in range(arm.n_joints):
            truth_peak = np.abs(ext[sel, j]).max()
            if truth_peak < 1.0:
                continue  # a push on link 1 puts no torque on joint 2
            est_peak = np.abs(te[sel, j]).max()
            assert abs(est_peak - np.abs(ideal[sel, j]).max()) <= (
                0.1 * truth_peak + floor[j]), (push, j, est_peak, truth_peak)
            lag = (sel[np.argmax(np.abs(te[sel, j]))] - sel[np.argmax(np.abs(ext[sel, j]))])
            assert 0.012 <= lag * ts <= 0.06, (push, j, lag * ts)
            k = sel[np.argmax(np.abs(ext[sel, j]))]
            assert np.sign(te[k, j]) == np.sign(ext[k, j])


@pytest.mark.parametrize("name", ["free_p2p", "free_multisine"])
def test_model_error_in_free_motion_is_visible_but_small(name):
    """(c) With the default ±20 % robot (the sample logs' robot), torque_ext in free motion
    is not zero — the nominal model is wrong and rigid — but well below the motor torque's
    range: rms < 15 % and peak < 25 % of the range (measured 3–10 % and 8–17 % on seeds
    11–13; the slow multi-sine has the smallest range, 3.7 N·m on the shoulder, and the
    largest share: a constant gravity-parameter error of ≈ 0.3 N·m); torque_model −
    torque < 20 % rms. The exact model (uncertainty 0) on the same motion does better."""
    sc = scenario(name, "assist_like", 20.0, robot_seed=100, controller_channels=True)
    res = simulate(sc, seed=11)
    log = res.log
    assert log.torque_ext is not None and log.torque_model is not None
    s = slice(round(1.0 / sc.arm.sample_period_s), None)
    te = log.torque_ext[s]
    rng = np.ptp(log.torque[s], axis=0)
    rms = np.sqrt(np.mean(te**2, axis=0))
    assert np.all(rms > 0.05)  # model error, well above the 0.01 N·m LSB
    assert np.all(rms < 0.15 * rng)
    assert np.all(np.abs(te).max(axis=0) < 0.25 * rng)
    dm = (log.torque_model - log.torque)[s]
    assert np.all(np.sqrt(np.mean(dm**2, axis=0)) < 0.2 * rng)
    # the exact model of the same motion does better: the error is the model's
    exact = simulate(replace(sc, uncertainty=0.0, friction_drift=0.0), seed=11)
    assert exact.log.torque_ext is not None
    rms0 = np.sqrt(np.mean(exact.log.torque_ext[s] ** 2, axis=0))
    assert np.all(rms0 < rms)


@pytest.mark.parametrize("arm", ["assist_like", "heavy_geared"])
def test_flag_changes_nothing_else(arm):
    """(d) Off: no channels. On: the same log otherwise, bit for bit, same labels and
    truth — the channels come from the logged data after the integration, no draw."""
    sc = scenario("pushes", arm, 10.0)
    off = simulate(sc, seed=5)
    on = simulate(replace(sc, controller_channels=True), seed=5)
    assert off.log.torque_model is None and off.log.torque_ext is None
    assert on.log.torque_model is not None and on.log.torque_ext is not None
    assert on.log.torque_model.shape == on.log.position.shape
    assert np.all(on.log.has_channel("torque_ext"))
    np.testing.assert_array_equal(off.log.t_ns, on.log.t_ns)
    for c in LOG_COLUMNS:
        np.testing.assert_array_equal(getattr(off.log, c), getattr(on.log, c), err_msg=c)
    assert off.labels.to_dict() == on.labels.to_dict()
    assert set(on.truth) - set(off.truth) == {"torque_model_error", "torque_ext_error"}
    for k, v in off.truth.items():
        np.testing.assert_array_equal(v, on.truth[k], err_msg=k)
    for k, v in off.params.items():
        np.testing.assert_array_equal(v, on.params[k], err_msg=k)
    # contacts show in the estimate: the largest |torque_ext| is during a push
    active = on.truth["contact_force_total"] > 0
    assert np.abs(on.log.torque_ext).max() == pytest.approx(
        np.abs(on.log.torque_ext[np.convolve(active, np.ones(50), "same") > 0]).max())


@pytest.mark.parametrize(("lsb", "decimals"), [(0.01, 7), (0.05, None)])
def test_channels_on_the_lsb_grid(lsb, decimals):
    """(e) Both channels are logged on the controller's torque LSB, and rounded to
    log_decimals like every other column."""
    arm = replace(assist_like(), controller_torque_lsb=lsb)
    sc = scenario("free_p2p", arm, 5.0, controller_channels=True, log_decimals=decimals)
    log = simulate(sc, seed=3).log
    for a in (log.torque_ext, log.torque_model):
        assert a is not None
        steps = a / lsb
        np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
        assert len(np.unique(a[:, 0])) > 20
        if decimals is not None:
            np.testing.assert_array_equal(a, np.round(a, decimals))


def test_sample_logs_carry_channels_on_assist_only():
    """The ASSIST-like sample logs log the controller's channels; the heavy arm's do not."""
    from impactcli.sim.sample_logs import MANIFEST

    for m in MANIFEST:
        assert m.make().controller_channels is (m.arm == "assist_like"), m.name


def test_heavy_arm_channels():
    """The 3-joint geared arm: the observer runs on 3 joints and sees a push on link 3 on
    every joint; free motion stays far below the push (strong friction modelled)."""
    arm = heavy_geared()
    ref = MultiSine((0.0, 0.0, 0.0), (0.1, 0.1, 0.1), f_min=0.03, f_max=0.15, n_sines=3)
    push = Push(link=3, t0_s=3.0, peak_n=60.0, duration_s=0.4, point=0.8)
    sc = Scenario("heavy", arm, 4.0, ref, pushes=(push,), controller_channels=True)
    res = simulate(sc, seed=1)
    te = res.log.torque_ext
    assert te is not None and te.shape == (res.log.n_samples, 3)
    t = res.truth["time_s"]
    ext = res.truth["tau_ext"]
    free = (t > 1.0) & (t < 2.95)
    during = (t > 3.0) & (t < 3.6)
    peak = np.abs(ext[during]).max(axis=0)
    assert np.all(peak > 5.0)
    assert np.all(np.abs(te[free]).max(axis=0) < 0.5 * peak)
    k = np.argmax(np.abs(ext[:, 0]))
    assert np.all(np.sign(te[k]) == np.sign(ext[k]))
