"""Residual generators: both estimate a known external torque on exactly rigid data, causally."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.errors import ModelError
from impactcli.model import ResidualOptions, compute_residual, identify_signals
from impactcli.types import JointSpec, LogSource, RobotDescription, RobotLog

from .reference.two_link_arm import TwoLinkArm, multisine

JOINTS = ("shoulder", "elbow")
ARM = TwoLinkArm()
DT = 0.004
ROBOT = RobotDescription(
    joints=tuple(JointSpec(j) for j in JOINTS),
    kinematics={"type": "planar", "link_lengths": [ARM.l1, ARM.l2], "gravity": [0.0, -ARM.g]},
)


@pytest.fixture(scope="module")
def model():  # type: ignore[no-untyped-def]
    t = np.arange(3000) * DT
    q, qd, qdd = multisine(t, 2, seed=11)
    return identify_signals(q, qd, qdd, ARM.torque(q, qd, qdd), joint_names=JOINTS,
                            kind="planar", robot=ROBOT)


def push_log(n: int = 3000, seed: int = 12) -> tuple[RobotLog, np.ndarray]:
    """A slow, rigid motion with a 1.5 s external push; the motor torque is what the arm
    needs minus what the push provides (M q'' + n = tau + tau_ext)."""
    t = np.arange(n) * DT
    q, qd, qdd = multisine(t, 2, seed=seed, f_max=0.6, amp=0.4)
    ext = np.zeros((n, 2))
    s, e = 1000, 1375  # 4.0 s to 5.5 s
    if n >= e:
        ext[s:e] = np.sin(np.linspace(0, np.pi, e - s))[:, None] ** 2 * np.array([2.0, 1.0])
    tau = ARM.torque(q, qd, qdd) - ext
    log = RobotLog(t_ns=np.round(t * 1e9).astype(np.int64), joint_names=JOINTS,
                   position=q, torque=tau, source=LogSource("push.csv", "", "memory"))
    return log, ext


@pytest.mark.parametrize("generator", ["inverse_dynamics", "momentum_observer"])
def test_residual_estimates_a_slow_push(model, generator: str) -> None:  # type: ignore[no-untyped-def]
    log, ext = push_log()
    res = compute_residual(model, log, ResidualOptions(generator=generator))
    assert res.r.shape == (3000, 2)
    k = int(np.argmax(ext[:, 0]))
    settled = slice(250, None)  # after the filters' first second
    free = np.ones(3000, bool)
    free[950:1500] = False
    free[:250] = False
    for j in range(2):
        peak = np.max(np.abs(res.r[950:1500, j]))
        # within a few % of the applied torque at its peak; elsewhere only the Coulomb
        # reversals show (≈ 0.02 N·m with fc = 0.25–0.4 N·m, see ResidualOptions)
        assert abs(peak - ext[k, j]) < 0.02 * ext[k, j], (generator, j, peak, ext[k, j])
        assert np.max(np.abs(res.r[free, j])) < 0.035, (generator, j)
    np.testing.assert_allclose(res.r[settled], (res.tau_hat - res.tau_used)[settled], atol=1e-12)


def test_coulomb_through_filter_lowers_the_reversal_spikes(model) -> None:  # type: ignore[no-untyped-def]
    log, _ = push_log()
    quiet = slice(1600, None)
    on = compute_residual(model, log, ResidualOptions(coulomb_through_filter=True)).r[quiet]
    off = compute_residual(model, log, ResidualOptions(coulomb_through_filter=False)).r[quiet]
    assert np.all(np.abs(on).max(axis=0) < 0.7 * np.abs(off).max(axis=0))


def test_residual_is_causal(model) -> None:  # type: ignore[no-untyped-def]
    log, _ = push_log()
    cut = log.slice(0, 1200)
    for gen in ("inverse_dynamics", "momentum_observer"):
        full = compute_residual(model, log, ResidualOptions(generator=gen))
        part = compute_residual(model, cut, ResidualOptions(generator=gen))
        np.testing.assert_allclose(part.r, full.r[:1200], atol=1e-12)


def test_filtering_the_torque_lowers_the_residual_floor(model) -> None:  # type: ignore[no-untyped-def]
    log, _ = push_log()
    rng = np.random.default_rng(3)
    noisy = RobotLog(t_ns=log.t_ns, joint_names=JOINTS, position=log.position,
                     torque=log.torque + rng.normal(0, 0.2, log.torque.shape))
    quiet = slice(1600, None)
    on = compute_residual(model, noisy, ResidualOptions(filter_torque=True)).r[quiet]
    off = compute_residual(model, noisy, ResidualOptions(filter_torque=False)).r[quiet]
    assert np.all(np.std(on, axis=0) < 0.5 * np.std(off, axis=0))


def test_missing_joint_and_bad_options_are_model_errors(model) -> None:  # type: ignore[no-untyped-def]
    log, _ = push_log(400)
    other = RobotLog(t_ns=log.t_ns, joint_names=("shoulder", "wrist"), position=log.position,
                     torque=log.torque)
    with pytest.raises(ModelError, match="'elbow'"):
        compute_residual(model, other)
    with pytest.raises(ModelError, match="generator"):
        ResidualOptions(generator="kalman")
    with pytest.raises(ModelError, match="too high"):
        compute_residual(model, log, ResidualOptions(generator="momentum_observer",
                                                     observer_gain=400.0))
