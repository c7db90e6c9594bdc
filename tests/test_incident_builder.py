"""A contact beside a payload change placed by itself (impactcli.detect.incident_builder.
beside), against a force whose torques are made through the Jacobian: the link and the
force come back; a part whose posture cannot be known gives nothing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from impactcli.detect.force import planar_jacobian
from impactcli.detect.incident_builder import IncidentContext, beside
from impactcli.detect.incidents import Incident
from impactcli.detect.payload_finding import ContactPart

LENGTHS = (0.4, 0.35)


def _ctx(chain_cols: list[int | None]) -> IncidentContext:
    return IncidentContext(("a", "b"), [1, 2], chain_cols, planar_jacobian(LENGTHS),
                           np.array([0.5, 0.3]), 0.004, 0, 10_000, 0.1,
                           link_lengths=LENGTHS, chain=("a", "b"))


def _incident() -> Incident:
    return Incident(10.0, 10.6, 2500, 2650, ("static_loading",), ("a", "b"), 1, 55.0,
                    "whole alarm", "quasi_static", {"a": 9.0, "b": 4.0}, False)


def _part(force: float, began_before: bool = False) -> ContactPart:
    """A 0.3 s half-sine push of ``force`` N at the end of link 2, normal to it, while the
    arm moves slowly; the torques r = Jᵀ F, their loading ratio as the monitor gives it."""
    n = 75
    t = np.arange(n) * 0.004
    q = np.column_stack([0.3 + 0.1 * t, 0.8 - 0.05 * t])
    jac = planar_jacobian(LENGTHS)
    shape = np.sin(np.pi * t / t[-1])
    r = np.zeros((n, 2))
    for k in range(n):
        j = jac(q[k], 2)
        assert j is not None
        phi = q[k].sum()
        f = force * shape[k] * np.array([-np.sin(phi), np.cos(phi)])  # normal to link 2
        r[k] = j.T @ f
    ratio = np.abs(r) / np.array([0.5, 0.3])
    qd = np.tile([0.1, -0.05], (n, 1))
    return ContactPart(("a", "b"), r, ratio, q, qd, 0.004, began_before)


def test_the_contact_apart_from_the_load_gives_its_own_link_and_force() -> None:
    got = beside(_ctx([0, 1]), _incident(), _part(30.0))
    assert got is not None
    assert got.link == 2 and got.contact == "transient"
    assert got.force_n == pytest.approx(30.0, rel=1e-6)
    assert got.force_method.endswith("(the torque the load leaves)")
    assert got.t_start == 10.0 and got.number is None  # only the figures change
    assert got.peak_residual["b"] == pytest.approx(float(np.max(np.abs(_part(30.0).r[:, 1]))))


def test_a_part_that_holds_only_the_contacts_end_gives_no_force() -> None:
    got = beside(_ctx([0, 1]), _incident(), _part(30.0, began_before=True))
    assert got is not None and got.link == 2 and got.force_n is None
    assert "at least 30 N at the end of link 2" in got.force_method
    assert got.force_plausible is None


def test_a_chain_joint_logged_but_not_replayed_leaves_the_whole_alarms_figures() -> None:
    ctx = _ctx([0, 1])
    ctx3 = IncidentContext(ctx.joints, ctx.index, [0, 1, 2], ctx.jac, ctx.vl, ctx.dt,
                           ctx.t0_ns, ctx.n_samples, ctx.merge_gap_s,
                           link_lengths=(*LENGTHS, 0.1), chain=("a", "b", "c"))
    assert beside(ctx3, _incident(), _part(30.0)) is None
    other = ContactPart(("a", "x"), *[getattr(_part(30.0), k) for k in
                                      ("r", "ratio", "q", "qd", "dt")])
    assert beside(ctx, _incident(), other) is None


def test_a_model_torque_beyond_what_the_joint_exerted_states_no_force() -> None:
    """Known truth: τ̂ = r + τ is the model's torque. A 20 N·m residual on joint a whose
    logged torque never passed 5 N·m (a still arm's model predicting 25 N·m) is the
    model's extrapolation: no force, and why. The same residual where the joint exerted
    12 N·m (τ̂ within 3× of it), or below vL beyond it, is left to the force estimate."""
    from dataclasses import replace

    from impactcli.detect.force import BEYOND_LOGGED
    from impactcli.detect.incident_builder import MODEL_BEYOND, beyond_logged

    ctx = replace(_ctx([0, 1]), torque_peak=np.array([5.0, 3.0]))
    r = np.column_stack([np.linspace(0.0, 20.0, 50), np.zeros(50)])
    tau = np.full((50, 2), 5.0)  # τ̂ on a: 5 … 25 N·m, beyond 3 × 5
    est = beyond_logged(ctx, r, tau, [0, 1])
    assert est is not None and est.force_n is None
    assert est.method.startswith(f"{BEYOND_LOGGED} a reached 25 N·m, more than "
                                 f"{MODEL_BEYOND:g}× the most it exerted anywhere in the "
                                 "log (5 N·m)"), est.method
    moving = 5.0 + 0.6 * r  # the logged torque follows the residual, as a contact's does
    assert beyond_logged(replace(ctx, torque_peak=np.array([13.0, 3.0])), r, moving, [0, 1]) \
        is None  # τ̂ up to 37 ≤ 3 × 13, and it swings 32 ≤ 3 × the logged 12
    assert beyond_logged(ctx, r, tau, [1]) is None  # joint b's model stays within
    small = replace(ctx, torque_peak=np.array([0.1, 3.0]), vl=np.array([30.0, 0.3]))
    assert beyond_logged(small, r, tau, [0, 1]) is None  # beyond 3×, but by less than vL
    assert beyond_logged(replace(ctx, torque_peak=None), r, tau, [0, 1]) is None


def test_a_model_torque_that_swings_where_the_logged_one_stays_states_no_force() -> None:
    """Known truth: within the peak the joint exerted in the log, a model's torque that
    moves 20 N·m in the incident while the logged torque moves 2 N·m made the residual
    itself (a contact's torque reaches the motor): no force, and why. The same residual
    where the logged torque moved 8 N·m (the model's swing 3× of it or less), or with a
    swing beyond 3× but by less than vL, is left to the force estimate."""
    from dataclasses import replace

    from impactcli.detect.force import BEYOND_LOGGED
    from impactcli.detect.incident_builder import MODEL_BEYOND, beyond_logged

    ctx = replace(_ctx([0, 1]), torque_peak=np.array([40.0, 3.0]))
    r = np.column_stack([np.linspace(0.0, -20.0, 50), np.zeros(50)])
    still = np.column_stack([np.linspace(5.0, 7.0, 50), np.full(50, 1.0)])
    est = beyond_logged(ctx, r, still, [0, 1])  # τ̂ on a: 5 … −13, within 3 × 40
    assert est is not None and est.force_n is None
    assert est.method.startswith(f"{BEYOND_LOGGED} a moved 18 N·m within the incident, more "
                                 f"than {MODEL_BEYOND:g}× the logged torque did (2 N·m)"), \
        est.method
    # a joint that did not alarm is said to be one: its residual still enters the force
    # (a trial took a wrist's model error for the whole incident's on a real UR braking)
    named = beyond_logged(ctx, r, still, [0, 1], fired=("b",))
    assert named is not None and named.method.startswith(
        f"{BEYOND_LOGGED} a (which did not alarm; its residual enters the force at the "
        "link's end) moved 18 N·m"), named.method
    assert beyond_logged(ctx, r, still, [0, 1], fired=("a",)).method == est.method
    follows = np.column_stack([np.linspace(5.0, 13.0, 50), np.full(50, 1.0)])
    assert beyond_logged(ctx, r, follows, [0, 1]) is None  # τ̂ swings 12 ≤ 3 × 8
    wide = replace(ctx, vl=np.array([20.0, 0.3]))
    assert beyond_logged(wide, r, still, [0, 1]) is None  # 18 − 2 N·m < vL
    assert beyond_logged(replace(ctx, torque_peak=None), r, still, [0, 1]) is None


@pytest.mark.parametrize(("arm", "why"), [("ur10e", "reached"),
                                          ("ur5e", "moved")])
def test_a_still_arms_model_gives_no_force_where_it_predicts_what_the_joint_never_did(
        real_logs: Path, tmp_path: Path, arm: str, why: str) -> None:
    """The real UR arm held still and pushed by hand (ur-static.csv), modelled from the log
    itself: the log barely moves it, so the model is poorly determined (the run warns so).
    At 30.97 s, as a UR10e, it predicted 106 N·m on shoulder_pan, whose logged torque
    never passed ~33 N·m; the incident read ~250 N (a new user's trial). As a UR5e (a
    later trial's guess) its torque there stayed within that, but swung 131 N·m in 54 ms
    while the logged torque moved ~1.3 N·m; the incident read "~278 N", plausible. Both now
    state no force there, and say why; the incidents whose model stays within what the
    joints did keep theirs."""
    import json

    from click.testing import CliRunner

    from impactcli.cli import main
    from impactcli.detect.force import BEYOND_LOGGED

    robot = tmp_path / f"{arm}.robot.json"
    robot.write_text(json.dumps({"kinematics": {"type": "urdf", "robot": arm},
                                 "joint_map": {j: f"{j}_joint" for j in (
                                     "shoulder_pan", "shoulder_lift", "elbow", "wrist_1",
                                     "wrist_2", "wrist_3")}}), encoding="utf-8")
    r = CliRunner().invoke(main, ["detect", str(real_logs / "ur_ext_observer" / "ur-static.csv"),
                                  "--channel-map", "ur_ext_observer", "--robot", str(robot),
                                  "-o", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    tl = json.loads((tmp_path / "out" / "ur-static.timeline.json").read_text("utf-8"))
    counted = [i for i in tl["incidents"] if i["number"] is not None]
    beyond = [i for i in counted if i["force_method"].startswith(BEYOND_LOGGED)]
    assert beyond and all(i["force_n"] is None for i in beyond), counted
    assert any(abs(i["t_start"] - 30.97) < 0.1 for i in beyond), beyond
    assert f"the model's torque on shoulder_pan {why}" in r.stdout
    assert any(i["force_n"] is not None for i in counted)  # the others keep their force


def test_the_force_check_names_the_joint_that_holds_the_most_force_at_the_links_end() -> None:
    """Known truth on the planar arm (0.4 m, 0.35 m): at link 2's end, joint a (10 N·m over
    0.75 m) holds 13.3 N and joint b (5 N·m over 0.35 m) 14.3 N — b, the weaker joint,
    holds the more force there; the check says so (a trial read "its strongest joint" of
    a 56 N·m wrist beside 330 N·m shoulders)."""
    from dataclasses import replace

    from impactcli.detect.force import FORCE_CEILING_FACTOR, ForceEstimate
    from impactcli.detect.incident_builder import check_force

    ctx = replace(_ctx([0, 1]), capacity=np.array([10.0, 5.0]), capacity_source="rated")
    chk = check_force(ctx, ForceEstimate(12.0, "m", {1: 0.75, 2: 0.35}), 2)
    assert chk.plausible is True
    assert chk.ceiling_n == pytest.approx(FORCE_CEILING_FACTOR * 5.0 / 0.35)
    assert "of the joints up to the link, b holds the most force at its end, ~14 N: " \
        "5 N·m (rated) over a 0.35 m lever arm" in chk.why, chk.why


def test_only_a_poorly_determined_models_torque_is_held_against_the_logged_one() -> None:
    """A model whose identification warned (condition number above its level, parameters
    not excited, joints standing still) — and only such a one — is checked by
    beyond_logged: a well-determined model's torque passes the logged peak where a hard
    impact truly decelerates the arm (a review's point), and that force must stand."""
    from impactcli.detect.incident_builder import poorly_determined

    fit = {"condition_number": 120.0, "options": {"condition_warn": 1000.0},
           "unexcited_parameters": [], "still_joints": []}
    assert not poorly_determined({"fit": fit}) and not poorly_determined(None)
    assert poorly_determined({"fit": {**fit, "condition_number": 3.2e4}})
    assert poorly_determined({"fit": {**fit, "unexcited_parameters": ["j1.Izz"]}})
    assert poorly_determined({"fit": {**fit, "still_joints": ["shoulder_pan"]}})
