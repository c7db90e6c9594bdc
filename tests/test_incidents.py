"""Incidents (impactcli.detect.incidents): grouping, isolation, force through the Jacobian,
contact type; end to end on the sample logs against their labels; the CLI's gates."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.config import load_config
from impactcli.detect.force import (
    estimate_force,
    force_estimate,
    lstsq_many,
    own_levers,
    planar_jacobian,
    smallest_caught_force,
)
from impactcli.detect.incidents import contact_type, group_events, isolate
from impactcli.logs import read_log
from impactcli.logs.robot_files import read_labels
from impactcli.outputs.timeline import timeline_dict
from impactcli.run.collect import detect_in_memory
from impactcli.schema import validate
from impactcli.types import Event

REPO = Path(__file__).resolve().parents[1]
CSV = REPO / "sample_logs" / "csv"
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"


def ev(det: str, a: float, b: float) -> Event:
    return Event(det, a, b, int(a * 250), int(b * 250), ("j1",), 2.0, {"j1": 1.0}, False)


def test_group_events_merges_overlaps_and_near_gaps_only() -> None:
    events = [ev("adaptive", 1.0, 1.1), ev("static_loading", 1.05, 1.5),
              ev("static_baseline", 1.0, 9.0), ev("adaptive", 1.55, 1.6),
              ev("static_loading", 3.0, 3.2)]
    groups = group_events(events, merge_gap_s=0.1)
    assert groups == [[0, 1, 3], [4]]  # 1.55 starts 0.05 s after 1.5; baseline not in any
    product = sorted(k for g in groups for k in g)
    assert product == [0, 1, 3, 4]  # every product event in exactly one incident


def test_isolation_takes_the_most_distal_joint_that_fired() -> None:
    ratio = np.array([[0.2, 0.1, 0.05], [3.0, 1.2, 0.3]])
    fired = np.zeros((2, 3), dtype=bool)
    assert isolate(ratio, fired, [1, 2, 4]) == 2  # joint 3 of the chain left out: link 2
    fired[0, 2] = True
    assert isolate(ratio, fired, [1, 2, 4]) == 4  # numbers stay the robot's own
    assert isolate(np.full((2, 3), 0.3), np.zeros((2, 3), bool), [1, 2, 3]) is None


def test_planar_jacobian_matches_finite_differences_and_force_is_recovered() -> None:
    lengths = [0.4, 0.35, 0.2]
    jac = planar_jacobian(lengths)

    def tip(q: np.ndarray, i: int) -> np.ndarray:
        phi = np.cumsum(q[:i])
        return np.array([sum(lengths[k] * np.cos(phi[k]) for k in range(i)),
                         sum(lengths[k] * np.sin(phi[k]) for k in range(i))])

    q = np.array([0.3, -0.7, 1.1])
    for i in (1, 2, 3):
        num = np.column_stack([(tip(q + h, i) - tip(q - h, i)) / 2e-6
                               for h in np.eye(3)[:i] * 1e-6])
        np.testing.assert_allclose(jac(q, i), num, atol=1e-8)
    force = np.array([3.0, -12.0])  # 12.4 N at the end of link 3
    r = np.tile(jac(q, 3).T @ force, (5, 1))
    f, method = estimate_force(r, np.tile(q, (5, 1)), 3, [1, 2, 3], jac)
    assert f == pytest.approx(float(np.hypot(3.0, 12.0)), rel=1e-9)
    assert "end of link 3" in method and "least squares" in method
    # link 1: one equation, the normal force at its end
    r1 = np.tile([2.0, 0.0, 0.0], (3, 1))
    f1, m1 = estimate_force(r1, np.tile(q, (3, 1)), 1, [1, 2, 3], jac)
    assert f1 == pytest.approx(2.0 / 0.4) and "one equation" in m1


def test_a_force_is_stated_only_where_one_force_at_the_links_end_gives_the_torques() -> None:
    """Known truth, a planar arm of 0.4, 0.35 and 0.2 m: a 30 N push normal to link 3 at
    70 % of its length gives τ = J_cᵀ F (J_c the contact point's Jacobian: link 3's with
    its last length 0.14 m); the force at the link's end that best explains it is stated,
    within the lever ratio of 30 N. A torque on joint 3 alone — the model's own error
    there, none on joints 1–2 — is no force at the link's end: the force that fits the
    three best gives torques where there are none and misses most of joint 3's; no force
    is stated, and the method says how little it explains. Link 2 (two torques, two force
    parts: always one force) keeps its estimate."""
    from impactcli.detect.force import FIT_SHARE, NO_SINGLE_FORCE, force_estimate

    jac = planar_jacobian([0.4, 0.35, 0.2])
    at70 = planar_jacobian([0.4, 0.35, 0.14])
    q = np.tile([0.3, -0.7, 1.1], (5, 1))
    phi = float(np.sum(q[0]))
    push = 30.0 * np.array([-np.sin(phi), np.cos(phi)])  # normal to link 3
    r = np.tile(at70(q[0], 3).T @ push, (5, 1))
    est = force_estimate(r, q, 3, [1, 2, 3], jac)
    assert est.force_n is not None and 0.7 * 30.0 <= est.force_n <= 1.05 * 30.0, est
    f_end = np.linalg.lstsq(jac(q[0], 3).T, r[0], rcond=None)[0]
    share = 1 - np.sum((jac(q[0], 3).T @ f_end - r[0]) ** 2) / np.sum(r[0] ** 2)
    assert share >= 0.99 > FIT_SHARE  # the offset (0.06 m × 30 N) is a small share of it
    alone = np.tile([0.0, 0.0, 1.1], (5, 1))
    f_end = np.linalg.lstsq(jac(q[0], 3).T, alone[0], rcond=None)[0]
    share = 1 - np.sum((jac(q[0], 3).T @ f_end - alone[0]) ** 2) / 1.1**2
    assert share < FIT_SHARE
    est = force_estimate(alone, q, 3, [1, 2, 3], jac)
    assert est.force_n is None and est.method.startswith(NO_SINGLE_FORCE), est
    assert f"accounts for {100 * share:.0f} % of their torque" in est.method, est.method
    two = force_estimate(alone[:, :2] + [0.0, 1.1], q, 2, [1, 2, 3], jac)
    assert two.force_n is not None and two.force_n > 0
    # any force exactly at the link's end, at any posture — near-stretched ones too, where
    # the truncated solve drops a direction (a review found 9 in 1000 refused) — is stated
    rng = np.random.default_rng(4)
    for k in range(500):
        qk = (rng.uniform(-np.pi, np.pi, 3) if k % 2 else rng.normal(0.0, 0.15, 3))
        rk = np.tile(jac(qk, 3).T @ rng.normal(0.0, 20.0, 2), (5, 1))
        assert force_estimate(rk, np.tile(qk, (5, 1)), 3, [1, 2, 3], jac).force_n is not None


def test_an_incident_without_a_single_force_says_so_on_its_row() -> None:
    """The terminal's row of such an incident: ``force ?`` and why, up to its colon."""
    from impactcli.cli.detect import _incident_line
    from impactcli.detect.force import NO_SINGLE_FORCE

    why = f"{NO_SINGLE_FORCE} 3 gives the residuals: the force … accounts for 23 % of it"
    line = _incident_line(2, {"t_start": 11.938, "link": 3, "link_candidates": [3],
                              "force_n": None, "contact": "transient",
                              "detectors": ["static_loading"], "force_plausible": None,
                              "no_force": why})
    assert "force ?" in line and line.endswith(
        "no single force at the end of link 3 gives the residuals (force_method in the "
        "timeline)"), line


def test_contact_type_rule() -> None:
    dt = 0.004
    still = np.zeros(300)
    assert contact_type(np.ones(300, bool), still, dt) == "quasi_static"  # 1.2 s still
    moving = np.full(700, 0.5)
    assert contact_type(np.ones(100, bool), moving[:100], dt) == "transient"  # 0.4 s
    assert contact_type(np.ones(700, bool), moving, dt) == "quasi_static"  # 2.8 s pressing
    assert contact_type(np.ones(100, bool), moving[:100], dt, ends_with_log=True) == "unknown"


@pytest.mark.parametrize("name", ["assist_impacts", "assist_pushes", "assist_clamps"])
def test_sample_contacts_each_one_incident_with_link_force_and_type(name: str) -> None:
    res, _ = detect_in_memory(read_log(CSV / f"{name}.csv.gz"), config=load_config(CONFIG))
    labels = read_labels(CSV / f"{name}.labels.json")
    product = [k for k, e in enumerate(res.events)
               if e.detector in ("adaptive", "static_loading")]
    owned = sorted(k for i in res.incidents for k in i.events)
    assert owned == product  # every product event in exactly one incident
    counted = res.counted_incidents()
    assert len(counted) == len(labels.events)
    kind = {"impact": "transient", "push": "transient", "clamp": "quasi_static"}
    for inc, lab in zip(counted, labels.events, strict=True):
        assert lab.start - 0.02 <= inc.t_start <= lab.end + 0.25
        assert inc.link == lab.link, (inc.t_start, inc.link, lab.link)
        assert inc.contact == kind[lab.kind], (inc.t_start, inc.contact, lab.kind)
        assert inc.force_n is not None and "end" in inc.force_method
        assert 0.4 * lab.peak_force <= inc.force_n <= 1.3 * lab.peak_force, (
            inc.t_start, inc.force_n, lab.peak_force)
    doc = timeline_dict(res)
    validate(doc, "timeline", AssertionError, name)
    assert len(doc["incidents"]) == len(res.incidents)


def test_cli_counts_incidents_and_gates_on_force(tmp_path: Path) -> None:
    log = str(CSV / "assist_pushes.csv.gz")
    r = CliRunner().invoke(main, ["detect", log, "--config", str(CONFIG), "-o",
                                  str(tmp_path / "a")])
    assert r.exit_code == 0, r.output
    row = next(line for line in r.output.splitlines() if line.startswith("assist_pushes"))
    assert row.split()[4:7] == ["9", "0", "|"]  # 9 incidents, no lasting load, then events
    assert "incidents of assist_pushes.csv.gz" in r.output
    # the time is the first alarm's, not the contact's start (a new user read it as that)
    assert ("#  alarm at    link" in r.output
            and "detectors  (a contact begins before its alarm, unless the incident "
            "merged an earlier alarm)" in r.output)
    r = CliRunner().invoke(main, ["detect", log, "--config", str(CONFIG), "-o",
                                  str(tmp_path / "b"), "--fail-on-force", "100"])
    assert r.exit_code == 5, r.output
    # nothing but the slow stretches the log has beyond the calibration's, and that the
    # forces under the limit leave out a part (the arm pushed near stretched; link 1's one
    # equation): not judged
    tl = json.loads((tmp_path / "b" / "assist_pushes.timeline.json").read_text())
    counted = [i for i in tl["incidents"] if i["number"] is not None]
    assert all(i["force_at_least"] for i in counted)
    fs = sorted(i["force_n"] for i in counted)
    assert [ln for ln in r.stderr.splitlines() if "motion envelope" not in ln] == [
        f"impactcli: assist_pushes.csv.gz: --fail-on-force 100 N could not judge the "
        f"forces of {len(counted)} incidents (≳{fs[0]:.3g} to ≳{fs[-1]:.3g} N), which leave "
        "out part of the force: at their postures part of a force at the link's end turns "
        "none of the joints up to it, or too little to be solved for, so the force may be "
        "larger than N (force_method in the timeline); exit 5"]
    assert f"≳{counted[0]['force_n']:.3g} N" in r.output
    assert "(≳: the joints up to the link do not feel part of that force" in r.output
    for n, out in (("25", "c"), ("10", "c10")):
        r = CliRunner().invoke(main, ["detect", log, "--config", str(CONFIG), "-o",
                                      str(tmp_path / out), "--fail-on-force", n])
        assert r.exit_code == 1, r.output
        # exit 1 says why: the log's first incident above N, its time, link and force
        tl = json.loads((tmp_path / out / "assist_pushes.timeline.json").read_text())
        over = [i for i in tl["incidents"] if not i["in_warmup"] and i["force_n"] > float(n)]
        assert len(over) == (1 if n == "25" else 6)
        more = f" ({len(over)} incidents above it)" if len(over) > 1 else ""
        gate = [ln + "\n" for ln in r.stderr.splitlines() if "motion envelope" not in ln]
        assert "".join(gate) == (
            f"impactcli: assist_pushes.csv.gz: the incident at {over[0]['t_start']:.3f} s on "
            f"link {over[0]['link']}, ≳{over[0]['force_n']:.3g} N, exceeds --fail-on-force "
            f"{n} N{more}\n" + "".join(gate[1:]))
        assert len(gate) == 2  # and the lower bounds under N
    r = CliRunner().invoke(main, ["detect", log, "--config", str(CONFIG), "-o",
                                  str(tmp_path / "d"), "--fail-on-detect"])
    assert r.exit_code == 1, r.output
    doc = json.loads((tmp_path / "d" / "assist_pushes.timeline.json").read_text())
    assert doc["schema_version"] == "2.12" and len(doc["incidents"]) >= 9


def test_fail_on_force_without_kinematics_could_not_judge(tmp_path: Path) -> None:
    """A push found with no kinematics has no force estimate: --fail-on-force cannot judge
    it and exits 5 (could not judge), naming the incident, never 0."""
    import dataclasses

    from impactcli.logs import write_log

    from .conftest import make_log

    # 30 s (the uncalibrated rule's block quantile needs more than the push's own blocks)
    log = make_log(n=7500, joints=("j1", "j2", "j3"), seed=0)
    tau = np.array(log.torque) * np.array([10.0, 5.0, 0.05])
    tau[5500:5600, 0] += 20.0  # a push on the first joint, no kinematics known
    write_log(dataclasses.replace(log, torque=tau), tmp_path / "x.csv")
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "x.csv"), "-o", str(tmp_path),
                                  "--fail-on-force", "1"])
    assert "--fail-on-force 1 N could not judge 1 incident (the first at 22." in r.output
    assert "no force estimate" in r.output
    assert r.exit_code == 5, r.output


def test_urdf_link_end_jacobian_matches_finite_differences() -> None:
    """A shipped robot's URDF: the Jacobian of each link's end point (next joint's origin;
    the tool for the last link) against finite differences, and a force at the end of link
    4 recovered from J^T F."""
    pytest.importorskip("pinocchio")
    from impactcli.errors import ImpactError
    from impactcli.logs.robot_catalogue import arm_joints, urdf_text
    from impactcli.model.kinematics import urdf_link_end_jacobian

    try:
        joints, xml = arm_joints("panda"), urdf_text("panda")
    except ImpactError as err:
        pytest.skip(f"the robots extra is not installed: {err}")
    structure = {"urdf_xml": xml, "urdf_path": "panda", "urdf_robot": "panda"}
    jac = urdf_link_end_jacobian(structure, joints)
    q = np.array([0.1, -0.5, 0.3, -2.0, 0.2, 1.5, 0.4])
    import pinocchio as pin

    from impactcli.logs.urdf import reduced_model

    model = reduced_model(xml, joints, "panda")
    data = model.createData()

    def point(x: np.ndarray, i: int) -> np.ndarray:
        pin.forwardKinematics(model, data, x)
        pin.updateFramePlacements(model, data)
        if i < 7:
            return np.array(data.oMi[model.getJointId(joints[i])].translation)
        return np.array(data.oMf[model.getFrameId("panda_hand")].translation)

    for i in (1, 4, 7):
        num = np.column_stack([(point(q + h, i) - point(q - h, i)) / 2e-6
                               for h in np.eye(7)[:i] * 1e-6])
        np.testing.assert_allclose(jac(q, i), num, atol=1e-7)
    force = np.array([0.0, 20.0, -15.0])
    j4 = jac(q, 4)
    r = np.tile(j4.T @ force, (3, 1))
    f, method = estimate_force(r, np.tile(q, (3, 1)), 4, [1, 2, 3, 4], jac)
    # 4 equations, 3 unknowns: recovered unless a direction is near-singular (then less)
    assert f == pytest.approx(25.0, rel=0.05) or f < 25.0
    assert "end of link 4" in method
    # one kinematics pass serves every link at a posture: whatever was asked before, a
    # link's Jacobian is that of a fresh function, to the bit
    q2 = q[::-1].copy()
    for i, x in ((3, q2), (7, q), (2, q2), (2, q), (5, q)):
        fresh = urdf_link_end_jacobian(structure, joints)(x, i)
        assert jac(x, i).tobytes() == fresh.tobytes(), i


def test_top_level_help_names_both_gates_of_exit_1() -> None:
    r = CliRunner().invoke(main, ["--help"])
    assert r.exit_code == 0
    text = " ".join(r.stdout.split())
    assert ("Exit codes: 0 success; 1 events found with --fail-on-detect, or a contact force "
            "above N with detect --fail-on-force N; 2 usage error ") in text


@pytest.mark.parametrize("link", [1, 2, 3])
def test_the_batched_jacobian_gives_the_same_force_to_the_bit(link: int) -> None:
    """A planar arm's Jacobians at all the strong samples at once give the force estimate,
    its method and its lever arms of one Jacobian per sample, to the last bit (a timeline
    does not depend on how they were computed)."""
    rng = np.random.default_rng(link)
    arm = planar_jacobian([0.45, 0.35, 0.2])
    q = rng.uniform(-3.0, 3.0, (400, 3))
    force = rng.normal(0.0, 20.0, (400, 2)) * np.hanning(400)[:, None]
    r = np.zeros((400, 3))  # the torques of a force at the link's end, and noise
    for k in range(400):
        r[k, :link] = arm(q[k], link).T @ force[k]
    r += rng.normal(0.0, 0.05, r.shape)
    batched = force_estimate(r, q, link, [1, 2, 3], arm)
    def one_at_a_time(x: np.ndarray, i: int) -> np.ndarray | None:  # no .many
        return arm(x, i)

    one_by_one = force_estimate(r, q, link, [1, 2, 3], one_at_a_time)
    assert batched == one_by_one and batched.force_n is not None and batched.force_n > 0


def test_least_squares_of_many_systems_is_lstsq_of_each_to_the_bit() -> None:
    """The force estimate solves all its samples' systems at once: each solution has the
    bits of np.linalg.lstsq on that system alone, well posed, nearly rank-deficient (the
    cut of RCOND acting) or tiny."""
    rng = np.random.default_rng(7)
    for trial in range(60):
        n, m, d = int(rng.integers(1, 40)), int(rng.integers(1, 5)), int(rng.integers(2, 4))
        a = rng.standard_normal((n, m, d))
        if trial % 3 == 0:  # two nearly parallel columns
            a[:, :, -1] = a[:, :, 0] * (1 + 1e-9 * rng.standard_normal((n, m)))
        if trial % 5 == 0:
            a[: n // 2] *= 1e-6
        b = rng.standard_normal((n, m)) * 10 ** rng.uniform(-3, 3)
        got = lstsq_many(a, b, 0.1)
        want = np.array([np.linalg.lstsq(a[k], b[k], rcond=0.1)[0] for k in range(n)])
        assert got.tobytes() == want.tobytes(), (n, m, d)


def test_the_floors_lever_arms_are_the_caught_force_ones() -> None:
    """own_levers (the detection floor's link forces) gives, at every posture, the lever
    arm smallest_caught_force divides by, to the bit; NaN for a link without a Jacobian."""
    rng = np.random.default_rng(3)
    arm = planar_jacobian([0.45, 0.35, 0.2])
    q = rng.uniform(-3.0, 3.0, (50, 3))
    got = own_levers(q, 3, arm)
    want = [[row["lever_m"] for row in smallest_caught_force([1.0] * 3, x, arm)] for x in q]
    assert got.tobytes() == np.array(want).tobytes()

    def two_links(x: np.ndarray, i: int) -> np.ndarray | None:  # no .many, no link 3
        return arm(x, i) if i < 3 else None

    part = own_levers(q, 3, two_links)
    assert part[:, :2].tobytes() == got[:, :2].tobytes() and np.isnan(part[:, 2]).all()


def test_a_change_with_a_contact_beside_it_counts_the_alarm_holding_it() -> None:
    """mark_payload_changes: of a change's alarms, the one holding its contact's onset is
    counted from that onset (t_start, i_start, t_start_utc moved, payload_test saying why),
    the others stay the change's; with no alarm holding the onset the nearest counts, as it
    is; a change whose alarm is no incident has its contact marked uncounted."""
    from impactcli.detect.incidents import Incident, mark_payload_changes
    from impactcli.detect.payload_finding import PayloadChange

    def alarm(t0: float, t1: float) -> Incident:
        return Incident(t0, t1, round(t0 * 500), round(t1 * 500), ("static_loading",),
                        ("elbow",), 2, 10.0, "residual", "transient", {"elbow": 1.0}, False,
                        t_start_utc="2026-11-30T00:00:10.000Z" if t0 == 10.0 else None)

    def change(t0: float, t_c: float, contact: dict | None) -> PayloadChange:
        return PayloadChange(t0, t_c, 1.0, 0.01, {"m": 1.0}, 0.99, 1.0, contact=contact)

    seen = {"i": 5250, "t_s": 10.5, "joint": "elbow", "peak": 5.0}
    incs = [alarm(10.0, 11.0), alarm(12.0, 12.2), alarm(30.0, 30.5)]
    out, _ = mark_payload_changes(incs, [change(10.0, 13.0, seen), change(30.0, 33.0, None)],
                                  0.56)
    assert out[0].payload_change is None and out[0].t_start == 10.5
    assert out[0].i_start == 5250 and out[0].t_start_utc == "2026-11-30T00:00:10.500Z"
    assert (out[0].payload_test or "").startswith(
        "a contact beside payload change P1, its link, force")
    assert out[1].payload_change == 1 and out[2].payload_change == 2
    # no alarm holds the onset: the nearest of the change's counts, from its end when it
    # ended before the onset, from its start when it began after it
    late = dict(seen, i=5700, t_s=11.4)
    out, held = mark_payload_changes(incs[:2], [change(10.0, 13.0, late)], 0.56)
    assert out[0].payload_change is None and (out[0].t_start, out[0].i_start) == (11.0, 5500)
    assert out[0].t_start_utc == "2026-11-30T00:00:11.000Z" and out[1].payload_change == 1
    early = dict(seen, i=5900, t_s=11.8)
    out, _ = mark_payload_changes(incs[:2], [change(10.0, 13.0, early)], 0.56)
    assert out[0].payload_change == 1 and out[1].payload_change is None
    assert (out[1].t_start, out[1].i_start) == (12.0, 6000)
    # a change no incident holds (its alarm a lasting load): its contact is not counted
    _, changes = mark_payload_changes(incs, [change(20.0, 23.0, dict(seen, t_s=21.0))], 0.56)
    assert changes[0].contact["counted"] is False
    assert "counted" not in held[0].contact
    # ... unless a counted incident that began long before the change spans its contact
    # (a trial's 17.7 s incident held it, and P1 said "no incident holds it")
    inside = dict(seen, i=10700, t_s=21.4)
    long_one = [alarm(5.6, 23.3)]
    out, changes = mark_payload_changes(long_one, [change(20.0, 23.0, inside)], 0.56)
    assert "counted" not in changes[0].contact and out[0].payload_change is None
    in_warmup = [dataclasses.replace(long_one[0], in_warmup=True)]
    _, changes = mark_payload_changes(in_warmup, [change(20.0, 23.0, inside)], 0.56)
    assert changes[0].contact["counted"] is False


def test_an_alarm_already_on_at_a_change_s_onset_is_the_change_s() -> None:
    """mark_payload_changes: an incident running across a change's onset that began up to
    ``lead_s`` before it is the change's alarm (the run passes settle_s, 0.56 s: the
    static-loading low-pass lags the step, or was already above vL from a misfit the step
    ran into — a new user's 1 kg release, whose alarm began 0.28 s before the change's
    onset, was counted as a 22 N contact and tripped --fail-on-force); one that began
    earlier stays counted, and so does one that ended before the onset."""
    from impactcli.detect.incidents import Incident, mark_payload_changes
    from impactcli.detect.payload_finding import PayloadChange

    def alarm(t0: float, t1: float) -> Incident:
        return Incident(t0, t1, round(t0 * 500), round(t1 * 500), ("static_loading",),
                        ("elbow",), 2, 22.0, "residual", "quasi_static", {"elbow": 1.0}, False)

    change = PayloadChange(40.012, 43.012, -1.0, 0.01, {"m": -1.0}, 0.99, 0.0)
    incs = [alarm(39.736, 43.244), alarm(39.0, 43.0), alarm(39.7, 39.9)]
    out, _ = mark_payload_changes(incs[:1], [change], 0.56, 0.56)
    assert out[0].payload_change == 1
    out, _ = mark_payload_changes(incs[:1], [change], 0.56, 0.1)  # the merge gap, as before
    assert out[0].payload_change is None
    out, _ = mark_payload_changes(incs[1:], [change], 0.56, 0.56)
    assert [i.payload_change for i in out] == [None, None]


def test_a_lasting_load_on_when_the_warm_up_ended_is_marked() -> None:
    """Known truth: an alarm that straddles the warm-up's end is split there (its part in
    the warm-up ends on the sample before the counted part): the counted lasting load
    began then or before, not at its t_start. One whose detector's warm-up event ended
    earlier, or another detector's, began where it says."""
    from impactcli.detect.incidents import LastingLoad, on_at_warmup_end

    def ev(det: str, i0: int, i1: int, warm: bool) -> Event:
        return Event(det, i0 / 100, i1 / 100, i0, i1, ("j1",), 2.0, {"j1": 1.0}, warm)

    def load(i0: int, det: str = "static_loading") -> LastingLoad:
        return LastingLoad(det, i0 / 100, 40.0, i0, 4000, ("j1",), 9.0, False, 1, False, 2,
                           20.0, "")

    split = [ev("static_loading", 120, 299, True), ev("static_loading", 300, 4000, False)]
    assert [x.on_at_warmup_end for x in on_at_warmup_end([load(300)], split)] == [True]
    assert load(300).to_dict().get("on_at_warmup_end") is None
    assert on_at_warmup_end([load(300)], split)[0].to_dict()["on_at_warmup_end"] is True
    apart = [ev("static_loading", 120, 250, True)]  # it stopped, then a new alarm
    assert not on_at_warmup_end([load(300)], apart)[0].on_at_warmup_end
    other = [ev("adaptive", 120, 299, True)]  # another detector's alarm
    assert not on_at_warmup_end([load(300)], other)[0].on_at_warmup_end


def test_what_a_lasting_load_leaves_unseen_is_said_over_its_union() -> None:
    """Known truth: two lasting loads of different detectors, 8.7–40.2 s and 30–45 s, blind
    their detectors for the union, 36.3 s (71 % of 51.3 s after warm-up); each leaves
    the other detector to see a contact. A load in the warm-up is not counted."""
    from impactcli.detect.incidents import blind_text

    loads = [{"t_start": 8.7, "t_end": 40.2, "detector": "static_loading",
              "joints": ["shoulder", "elbow"]},
             {"t_start": 30.0, "t_end": 45.0, "detector": "adaptive", "joints": ["elbow"]},
             {"t_start": 0.0, "t_end": 12.0, "detector": "adaptive", "joints": ["elbow"],
              "in_warmup": True}]
    assert blind_text(loads, 51.3) == (
        "a lasting load's detector was already alarming on its joints for 36.3 s (71 % of "
        "the log after warm-up; 8.7–40.2 s, static_loading on shoulder, elbow; 30.0–45.0 s, "
        "adaptive on elbow): a contact there raised no event of that detector on them, only "
        "the other (adaptive or static_loading) could see it — one it did not see was missed "
        "— and the detection floor does not hold there")
    assert blind_text(loads[:1], listed=True).startswith(
        "a lasting load's detector was already alarming on its joints for 31.5 s: a contact "
        "there raised no event of that detector on them, only the other (adaptive) could")
    assert blind_text(loads[2:]) == "" and blind_text([]) == ""


def test_an_alarm_just_after_a_lasting_load_ended_may_be_that_load_again() -> None:
    """Known truth: a load held 20–40 s read as a lasting load to 36.044 s and, after a
    0.132 s dip of its static-loading alarm, a 4 s quasi-static "contact" on the same
    joints (a trial's). Within the low-pass's settling time (0.56 s) such an alarm is
    marked as maybe that load again — still counted; one later, on other joints only, or
    of the other detector only, is not."""
    from impactcli.cli.detect import _incident_line
    from impactcli.detect.incidents import Incident, LastingLoad, mark_resumed
    from impactcli.run.batch import _incident_row

    def alarm(t0: float, dets: tuple[str, ...] = ("static_loading", "adaptive"),
              joints: tuple[str, ...] = ("elbow", "shoulder")) -> Incident:
        return Incident(t0, t0 + 4.0, round(t0 * 250), round((t0 + 4) * 250), dets, joints,
                        2, 18.7, "residual", "quasi_static", {"elbow": 1.0}, False, number=3)

    load = LastingLoad("static_loading", 20.064, 36.044, 5016, 9011, ("elbow", "shoulder"),
                       28.0, False, 4, False, 2, 26.2, "")
    got = mark_resumed([alarm(36.176), alarm(36.7), alarm(36.176, joints=("wrist",)),
                        alarm(36.176, dets=("adaptive",))], [load], 0.56)
    mark = got[0].resumes_load
    assert mark is not None and mark["gap_s"] == pytest.approx(0.132)
    assert (mark["t_start"], mark["t_end"]) == (20.064, 36.044)
    assert mark["text"] == (
        "resumes the lasting load of 20.064–36.044 s after a 0.13 s dip: its static_loading "
        "alarm on elbow, shoulder was under its threshold for less than its low-pass "
        "settles, so this may be that load again, not a new contact")
    assert [i.resumes_load is None for i in got[1:]] == [True, True, True]
    assert got[0].to_dict()["resumes_load"] == mark and "resumes_load" not in got[1].to_dict()
    line = _incident_line(3, _incident_row(got[0]))  # type: ignore[arg-type]
    assert line.endswith("resumes the lasting load of 20.064–36.044 s after a 0.13 s dip "
                         "(resumes_load in the timeline)"), line


def test_the_floor_holds_outside_a_lasting_load_or_nowhere_when_it_lasts_throughout() -> None:
    """Known truth: loads holding 27 s of 40 s analysed leave the floor to the other 13 s;
    loads holding 39.7 of 40 s (a sample and a merge gap short) leave no moment outside:
    no floor is stated, and what could still see a contact is said."""
    from impactcli.detect.incidents import ALL_HELD_SHARE, floor_apart

    def load(a: float, b: float, det: str = "static_loading") -> dict:
        return {"t_start": a, "t_end": b, "detector": det, "in_warmup": False}

    assert floor_apart([], 40.0) == ("", False)
    words, every = floor_apart([load(3.0, 30.0)], 40.0)
    assert not every and words.startswith("outside the 27.0 s a lasting load held")
    words, every = floor_apart([load(3.0, 20.0), load(18.0, 42.7)], 40.0)
    assert ALL_HELD_SHARE * 40.0 <= 39.7 and every
    assert words.startswith("a lasting load held static_loading alarming over all the "
                            "40.0 s after warm-up: no moment lies outside it")
    assert "only through adaptive, or through static_loading on a joint" in words
    words, every = floor_apart([load(3.0, 43.0, "adaptive"), load(3.0, 43.0)], 40.0)
    assert every and "held adaptive and static_loading alarming" in words
    assert "only through adaptive or static_loading, or through" in words


def test_a_baseline_alarm_no_incident_explains_is_said_and_one_that_leads_an_incident_not(
) -> None:
    """Known truth: baseline events at 5 s (alone), 9.8 s (0.2 s before the incident at
    10 s: the incident's own, the plain comparison alarms first), 20 s (inside a lasting
    load), 30 s (at an uncounted data-defect incident) and 1 s (warm-up). Only the 5 s one
    is alone; its words give the time, joints and the largest ratio."""
    from impactcli.detect.incidents import BASELINE_LEAD_S, baseline_alone, baseline_alone_text

    def ev(t: float, warm: bool = False, det: str = "static_baseline") -> dict:
        return {"detector": det, "t_start": t, "t_end": t + 0.05, "in_warmup": warm,
                "joints": ["j2"], "peak_ratio": 1.8}

    events = [ev(1.0, True), ev(5.0), ev(9.8), ev(20.0), ev(30.0), ev(40.0, det="adaptive")]
    incidents = [{"t_start": 10.0, "t_end": 10.3, "in_warmup": False, "number": 1},
                 {"t_start": 30.0, "t_end": 30.1, "in_warmup": False, "number": None}]
    loads = [{"t_start": 15.0, "t_end": 25.0, "in_warmup": False}]
    assert BASELINE_LEAD_S > 0.2
    alone = baseline_alone(events, incidents, loads)
    assert [e["t_start"] for e in alone] == [5.0]
    assert baseline_alone_text(alone) == (
        "the static baseline alone alarmed after warm-up at 5.000 s (j2; up to 1.8× its "
        "threshold v0): not an incident — neither product detector confirmed it, but a "
        "contact may have been there (events in the timeline)")
    assert baseline_alone_text([]) == ""
    two = baseline_alone([ev(5.0), ev(50.0)], [], [])
    assert baseline_alone_text(two).startswith(
        "the static baseline alone alarmed after warm-up 2 times (first at 5.000 s")
