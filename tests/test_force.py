"""The force at the isolated link's end and when it is a lower bound
(impactcli/detect/force.py: ``force_estimate``, ``unseen_part``, ``force_mark``; the gate's
note, impactcli/run/gates.py), against known truth: torques made exactly from a force."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactcli.detect.force import RCOND, force_estimate, force_mark, planar_jacobian

LENGTHS = [0.4, 0.35, 0.2]


def _exact(q: np.ndarray, f: np.ndarray, link: int, n: int = 5) -> np.ndarray:
    """(n, 3) residuals of joints 1..3 from the force ``f`` at the end of ``link`` (joints
    beyond the link feel none)."""
    jac = planar_jacobian(LENGTHS)(q, link)
    r = np.zeros(3)
    r[:link] = jac.T @ f
    return np.tile(r, (n, 1))


@settings(max_examples=300, deadline=None)
@given(q=st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3),
       near=st.booleans(),
       f=st.lists(st.floats(-50.0, 50.0), min_size=2, max_size=2),
       link=st.integers(1, 3))
def test_a_stated_force_is_never_more_than_the_force_and_is_it_unless_said(
        q: list[float], near: bool, f: list[float], link: int) -> None:
    """Known truth: the residuals are Jᵀ F exactly, F at the link's end, at any posture
    (near-stretched ones half the time). The stated force is never larger than |F| — the
    truncated or minimum-norm solve is F projected onto what the joints feel — and, unless
    ``at_least`` says a part is unseen, it is |F|."""
    qa = np.asarray(q) * (0.05 if near else 1.0)
    fa = np.asarray(f)
    if np.linalg.norm(planar_jacobian(LENGTHS)(qa, link).T @ fa) < 1e-6:
        return  # a force the joints do not feel at all: no residual, nothing to state
    est = force_estimate(_exact(qa, fa, link), np.tile(qa, (5, 1)), link, [1, 2, 3],
                         planar_jacobian(LENGTHS))
    assert est.force_n is not None, est
    size = float(np.linalg.norm(fa))
    assert est.force_n <= size * (1 + 1e-9) + 1e-9
    if est.at_least:
        assert est.stated.endswith(est.at_least) and "it may be larger" in est.at_least
    else:
        assert est.force_n == pytest.approx(size, rel=1e-6)


def test_which_forces_are_lower_bounds_and_why() -> None:
    """Link 1 of a planar arm (one equation: a force along the link turns no joint) is
    always one; link 2 at a bent posture is an estimate; link 2 near stretched (a singular
    value under RCOND of the largest) is one, and says how many samples; a spatial link
    with two joints (two torques for a 3-D force) is one, minimum norm."""
    jac = planar_jacobian(LENGTHS)
    bent = np.array([0.3, 1.2, 0.0])
    est = force_estimate(_exact(bent, np.array([3.0, 4.0]), 1), np.tile(bent, (5, 1)), 1,
                         [1, 2, 3], jac)
    assert est.at_least == (" — it may be larger: a force's part that turns none of joint 1 "
                            "is not seen")
    est = force_estimate(_exact(bent, np.array([3.0, 4.0]), 2), np.tile(bent, (5, 1)), 2,
                         [1, 2, 3], jac)
    assert est.at_least == "" and est.force_n == pytest.approx(5.0)
    straight = np.array([0.3, 0.02, 0.0])
    sv = np.linalg.svd(jac(straight, 2), compute_uv=False)
    assert sv[1] < RCOND * sv[0]
    along = np.array([np.cos(0.31), np.sin(0.31)])  # nearly along the stretched arm
    normal = np.array([-along[1], along[0]])
    est = force_estimate(_exact(straight, 20.0 * normal + 20.0 * along, 2),
                         np.tile(straight, (5, 1)), 2, [1, 2, 3], jac)
    assert est.at_least.startswith(" — it may be larger: near a singular posture at 5 of the "
                                   "5 samples solved, "), est.at_least
    assert est.force_n is not None and est.force_n < 0.8 * np.hypot(20.0, 20.0)

    def spatial(qq: np.ndarray, link: int) -> np.ndarray:  # two joints about z and y
        return np.array([[0.0, 0.3], [0.5, 0.0], [0.0, -0.2]])[:, :link]

    r = np.tile(spatial(np.zeros(2), 2).T @ np.array([1.0, 2.0, 3.0]), (4, 1))
    est = force_estimate(r, np.zeros((4, 2)), 2, [1, 2], spatial)
    assert "minimum norm" in est.method and est.at_least.endswith(
        "turns none of joints 1, 2 is not seen")
    assert est.force_n is not None and est.force_n <= np.sqrt(14.0)


def test_the_mark_says_which() -> None:
    """``≳`` (at least about) for a force with a part unseen, ``~`` for an estimate; a
    timeline item or an object."""
    class Load:
        force_at_least = True

    assert force_mark({"force_at_least": True}) == "≳"
    assert force_mark({"force_at_least": False}) == "~" == force_mark({})
    assert force_mark(Load()) == "≳"


def test_the_force_gate_could_not_judge_a_force_that_leaves_out_a_part() -> None:
    """--fail-on-force N could not judge a force under N marked ≳ (part of the force turns
    no joint: unbounded) — exit 5, one line per log; before 2026-12-01 it passed it with a
    note, and two trials' 30–35 N pushes read ≳24 N passed limits of 26 and 33 N. One
    above N fails the gate, printed with ≳ (1 wins); an estimate under N is judged."""
    from dataclasses import dataclass

    from impactcli.run.gates import Findings, gate_notes, judge

    @dataclass(frozen=True)
    class Inc:
        t_start: float
        link: int
        force_n: float
        force_at_least: bool
        force_method: str = "force at …"

    low = Findings("a.csv", 40.0, 3.0, (Inc(8.06, 2, 3.33, True), Inc(12.1, 1, 30.1, True),
                                        Inc(20.0, 2, 9.0, False)), (), ())
    failing, unjudged = judge([low], fail_on_detect=False, fail_on_force=100.0)
    assert failing == [] and unjudged == [
        "impactcli: a.csv: --fail-on-force 100 N could not judge the forces of 2 incidents "
        "(≳3.33 to ≳30.1 N), which leave out part of the force: at their postures part of "
        "a force at the link's end turns none of the joints up to it, or too little to be "
        "solved for, so the force may be larger than N (force_method in the timeline); "
        "exit 5"]
    failing, unjudged = judge([low], fail_on_detect=False, fail_on_force=25.0)
    assert failing == ["impactcli: a.csv: the incident at 12.100 s on link 1, ≳30.1 N, "
                       "exceeds --fail-on-force 25 N"]
    assert len(unjudged) == 1 and unjudged[0].startswith(
        "impactcli: a.csv: --fail-on-force 25 N could not judge the force of 1 incident "
        "(≳3.33 N), which leaves out part of the force: at its posture")
    est = Findings("b.csv", 40.0, 3.0, (Inc(20.0, 2, 9.0, False),), (), ())
    assert judge([est], fail_on_detect=False, fail_on_force=100.0) == ([], [])
    assert gate_notes([low], fail_on_detect=False, fail_on_force=100.0) == []


def test_the_at_least_legend_states_the_measured_spread_of_the_docs() -> None:
    """The legend under a list with ≳ gives the estimate's measured spread: the smallest
    and largest estimate/truth of docs/incidents.md's table (incident_quality.py
    --seeds 3), so the two cannot drift apart (a trial read "may be larger" over an
    estimate 1.53× the truth)."""
    import re
    from pathlib import Path

    from impactcli.detect.force import AT_LEAST_TEXT

    doc = (Path(__file__).resolve().parents[1] / "docs" / "incidents.md").read_text("utf-8")
    rows = [ln for ln in doc.splitlines()
            if ln.startswith(("  | heavy geared |", "  | ASSIST-like |"))]
    spans = [(float(a), float(b)) for ln in rows
             for a, b in re.findall(r"\((\d\.\d+)–(\d\.\d+)\)", ln)]
    assert len(spans) == 6, rows
    lo, hi = min(a for a, _ in spans), max(b for _, b in spans)
    assert f"{lo:.2g}–{hi:.2g}× the true force" in AT_LEAST_TEXT, (lo, hi)
    assert f"from {lo:.2f} to {hi:.2f} × the truth" in doc
