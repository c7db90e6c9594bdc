"""The gates and payload changes not told from a contact (impactcli/run/gates.py,
impactcli/detect/payload_words.py): a change whose inertia did not show is, to the torque,
a steady press of |m| g along gravity, so no gate may pass it as judged."""

from __future__ import annotations

import pytest

from impactcli.detect.payload_words import press_force_n, press_text
from impactcli.run.gates import Findings, judge


def change(mass_kg: float, inertia: str | None, t: float = 9.806, **extra: object) -> dict:
    return {"t_start": t, "mass_kg": mass_kg, "mass_se_kg": 0.1, "explained": 0.97,
            "drift": 0.2, **({} if inertia is None else {"inertia": inertia}), **extra}


def findings(*changes: dict) -> Findings:
    return Findings("/data/clamp.csv", 18.0, 3.0, (), (), (), payload_changes=changes)


def test_the_press_a_mass_step_equals_is_m_g_and_its_sign_says_down_or_its_end() -> None:
    """A 20 N clamp pressing down on the flange has the torque of +2.04 kg (9.81 m/s²)."""
    assert press_force_n(change(20.0 / 9.81, "unseen")) == pytest.approx(20.0)
    down = press_text(change(1.96, "unseen"))
    assert down is not None and "a steady press of ~19 N down along gravity (a clamp)" in down
    end = press_text(change(-1.84, "unseen"))
    assert end is not None and "the end of a steady press of ~18 N down" in end \
        and "or one up" in end
    assert press_text(change(1.96, "shows")) is None
    assert press_text(change(1.96, None)) is None  # a timeline from before the test
    untrusted = press_text(change(-2.7, "shows", mass_check="released 2.7 kg, ..."))
    assert untrusted is not None and "cannot be trusted" in untrusted


def test_fail_on_detect_could_not_judge_a_change_its_inertia_did_not_tell() -> None:
    """The trial's 20 N clamp, weighed +1.96 kg then −1.84 kg with no inertia seen: exit 5
    (not 0, as before), one line naming the first and how many; a change whose inertia
    showed is judged (no line), as before."""
    f = findings(change(1.96, "unseen"), change(-1.84, "unseen", t=13.06))
    failing, unjudged = judge([f], fail_on_detect=True, fail_on_force=None)
    assert failing == [] and len(unjudged) == 1
    assert unjudged[0].startswith("impactcli: clamp.csv: --fail-on-detect could not judge "
                                  "2 payload changes: P1 at 9.806 s, +1.96 kg: its inertia "
                                  "did not show, so a steady press of ~19 N down")
    assert unjudged[0].endswith("(and 1 other); exit 5")
    shown = findings(change(0.99, "shows"), change(-0.99, "shows", t=40.0))
    assert judge([shown], fail_on_detect=True, fail_on_force=None) == ([], [])


@pytest.mark.parametrize(("limit", "judged"), [(25.0, True), (19.0, False), (15.0, False)])
def test_fail_on_force_could_not_judge_only_a_press_that_would_pass_it(
        limit: float, judged: bool) -> None:
    """+1.96 kg is a 19.2 N press: under 25 N the gate judges it whichever it was; at 19 N
    or 15 N a press would pass the limit, so it could not judge it. A mass_check release
    is never judged (its mass is not to be trusted)."""
    f = findings(change(1.96, "unseen"))
    _, unjudged = judge([f], fail_on_detect=False, fail_on_force=limit)
    assert (unjudged == []) == judged, unjudged
    if not judged:
        assert f"--fail-on-force {limit:g} N could not judge 1 payload change: P1" in \
            unjudged[0]
    odd = findings(change(-0.5, "shows", mass_check="released 0.5 kg, ..."))
    _, unjudged = judge([odd], fail_on_detect=False, fail_on_force=100.0)
    assert len(unjudged) == 1 and "cannot be trusted" in unjudged[0]


def test_an_incident_where_the_data_disagree_is_not_judged_by_either_gate() -> None:
    """An incident overlapping a stretch where the logged velocity and the positions tell
    two motions: both gates could not judge it (exit 5), where --fail-on-detect failed the
    real KUKA log on it (exit 1); another incident in the same log is judged as ever."""
    from types import SimpleNamespace

    def inc(t: float, data: bool) -> SimpleNamespace:
        return SimpleNamespace(t_start=t, force_n=50.0, force_at_least=False,
                               force_plausible=True, force_check="", force_method="",
                               velocity_disagrees={"t_start": 25.014, "t_end": 25.1,
                                                   "joints": ["j1"]} if data else None)

    only = Findings("/data/kuka.csv", 25.1, 3.0, (), (), (), disagreeing=(inc(24.8, True),))
    for kw in ({"fail_on_detect": True, "fail_on_force": None},
               {"fail_on_detect": False, "fail_on_force": 10.0}):
        failing, unjudged = judge([only], **kw)
        assert failing == [] and len(unjudged) == 1, (kw, failing, unjudged)
        assert ("could not judge 1 incident where the log's velocity and positions tell two "
                "motions (the first at 24.800 s, the stretch from 25.014 s)") in unjudged[0]
    both = Findings("/data/kuka.csv", 25.1, 3.0, (inc(10.0, False),), (), (),
                    disagreeing=(inc(24.8, True),))
    failing, unjudged = judge([both], fail_on_detect=True, fail_on_force=None)
    assert len(failing) == 1 and "1 incident after warm-up" in failing[0]
    assert len(unjudged) == 1
