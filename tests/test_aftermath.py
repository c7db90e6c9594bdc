"""A contact's aftermath (impactcli.detect.aftermath) on incidents and measured stretches
whose times are chosen, so the rule's every edge is known: which span an incident threw, the
settling time that joins stretches and ends a span, the incident that starts the span never
in its own aftermath, one that starts while its cause is still on never either."""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from impactcli.detect.aftermath import (
    LEAD_S,
    MeasuredStretch,
    PeakRuns,
    aftermath_of,
    aftermath_text,
    close_behind,
    mark_aftermath,
    ringing_text,
)

SETTLE = 0.56


@dataclass(frozen=True)
class Inc:
    t_start: float
    t_end: float
    number: int | None
    aftermath: dict | None = None
    close_behind: dict | None = None


def out(t0: float, t1: float, value: float = 9.0) -> MeasuredStretch:
    return MeasuredStretch(t0, t1, "elbow", "measured_acceleration", value, -5.0, 5.0)


def test_alarms_while_the_arm_rings_after_a_push_are_its_aftermath() -> None:
    push = Inc(35.05, 35.86, 5)
    ring = [Inc(35.99, 36.24, 6), Inc(36.38, 36.57, 7), Inc(37.15, 37.18, 8)]
    later = Inc(40.0, 40.3, 9)   # after the span and its settling time: a contact again
    # the push throws the arm out (from 35.07); excursions 0.1–0.5 s apart until 37.0 s
    stretches = [out(35.07, 36.61, 13.5), out(36.74, 36.96), out(39.0, 39.05)]
    marks = aftermath_of([push, *ring, later], stretches, SETTLE)
    assert marks[0] is None and marks[4] is None
    for m in marks[1:4]:
        assert m is not None and m["incident"] == 5 and m["t_start"] == 35.05
        assert m["until_s"] == 36.96  # 39.0 lies 2 s further: another span
        assert m["measured"]["value"] == 13.5  # the span's farthest stretch so far
    text = aftermath_text(marks[1])
    assert text.startswith("in the aftermath of incident 5 at 35.050 s: the arm had not "
                           "settled (measured elbow acceleration 13.5 rad/s²")
    assert "may be its ringing, not a new contact" in text
    # the settling time bounds it: an incident 0.5 s after the span's end is in it, 0.6 s not
    near, far = Inc(36.96 + 0.5, 37.6, 10), Inc(36.96 + 0.6, 37.7, 11)
    (m_near,) = aftermath_of([push, near], stretches[:2], SETTLE)[1:]
    (m_far,) = aftermath_of([push, far], stretches[:2], SETTLE)[1:]
    assert m_near is not None and m_far is None and "follows" not in m_near


@dataclass(frozen=True)
class Forced(Inc):
    force_n: float | None = None
    peak_residual: dict | None = None


def test_ringing_that_outlasts_the_measured_span_follows_the_last_marked_alarm() -> None:
    """A trial's 30 N push (robot 67): the adaptive detector rang at 0.38 s intervals, and
    the measured motion was back in its ranges before the last ring, 0.60 s after it — read
    as a new 12 N contact. An alarm within the settling time after the end of one already
    in the aftermath, no stronger than its cause, follows it; a stronger one, or one after
    a longer quiet, is a contact again (and ends the chain)."""
    push = Forced(35.43, 35.66, 6, force_n=27.3)
    rings = [Forced(35.81, 36.02, 7, force_n=21.5), Forced(36.21, 36.35, 8, force_n=18.7),
             Forced(36.58, 36.65, 9, force_n=11.9), Forced(37.0, 37.1, 10, force_n=8.0)]
    stretches = [out(35.42, 35.98, -2.27)]
    marks = aftermath_of([push, *rings], stretches, SETTLE)
    assert marks[0] is None
    assert [m is not None and m.get("follows") for m in marks[1:]] == [None, None, 8, 9]
    assert all(m["incident"] == 6 and m["until_s"] == 35.98 for m in marks[1:])
    text = aftermath_text(marks[3])
    assert ("out until 35.980 s); it follows incident 8, itself in that aftermath, within the "
            "detectors' settling time, so this alarm may be its ringing") in text
    # a stronger alarm is a contact, and nothing after it follows
    strong = [*rings[:2], Forced(36.58, 36.65, 9, force_n=40.0), rings[3]]
    assert [m is None for m in aftermath_of([push, *strong], stretches, SETTLE)[1:]] == [
        False, False, True, True]
    # a quiet longer than the settling time ends the chain
    late = [*rings[:2], Forced(36.35 + SETTLE + 0.05, 37.0, 9, force_n=5.0)]
    assert aftermath_of([push, *late], stretches, SETTLE)[3] is None
    # unknown forces: the peak residuals tell, no larger on any joint than the cause's
    blind = [dataclasses.replace(x, force_n=None, peak_residual={"elbow": 3.0}) for x in rings]
    loud = dataclasses.replace(push, peak_residual={"elbow": 3.0})
    assert all(m is not None for m in aftermath_of([loud, *blind], stretches, SETTLE)[1:])
    louder = [*blind[:3], dataclasses.replace(blind[3], peak_residual={"elbow": 3.1})]
    assert aftermath_of([loud, *louder], stretches, SETTLE)[4] is None
    # an alarm that starts while the ring before it is still on follows it too
    overlap = [*rings[:2], Forced(36.50, 36.70, 9, force_n=11.9),
               Forced(36.60, 36.80, 10, force_n=8.0)]  # 36.60: past the span's 36.54
    marks = aftermath_of([push, *overlap], stretches, SETTLE)
    assert "follows" not in marks[3] and marks[4]["follows"] == 9
    # a ring not counted (no number) is followed all the same, and the row says so
    uncounted = [*rings[:1], dataclasses.replace(rings[1], number=None), rings[2]]
    m = aftermath_of([push, *uncounted], stretches, SETTLE)[3]
    assert m is not None and m["follows"] is None
    assert "; it follows an earlier alarm, itself in that aftermath" in aftermath_text(m)


def test_a_chain_of_weaker_alarms_close_behind_a_push_is_marked_on_timing_alone() -> None:
    """A trial's robot 53 carrying 1 kg: a 30 N push (21.2 N read) rang as five
    static-loading alarms of 3.6 → 1.8 N, 0.11–0.28 s apart, while the measured motion
    never left its (wide) ranges. Each is close behind the push (the chain's first), the
    first one by the push itself, the later ones through the one before; the push and an
    alarm after a longer quiet are not; a stronger alarm starts a chain of its own."""
    push = Forced(35.048, 36.032, 3, force_n=21.19)
    rings = [Forced(36.144, 36.416, 4, force_n=3.59), Forced(36.544, 36.768, 5, force_n=3.02),
             Forced(36.948, 37.108, 6, force_n=2.21), Forced(37.328, 37.472, 7, force_n=2.04),
             Forced(37.752, 37.816, 8, force_n=1.76)]
    later = Forced(50.096, 50.428, 9, force_n=13.8)
    got = close_behind([push, *rings, later], SETTLE, measured_checked=True)
    assert got[0] is push and got[-1] is later
    marks = [g.close_behind for g in got[1:-1]]
    assert [m["incident"] for m in marks] == [3] * 5
    assert [m["after"] for m in marks] == [3, 4, 5, 6, 7]
    assert [round(m["gap_s"], 3) for m in marks] == [0.112, 0.128, 0.18, 0.22, 0.28]
    assert marks[0]["text"] == (
        "close behind incident 3 (21.2 N at 35.048 s): it began 0.112 s after that alarm "
        "ended, within the detectors' settling time (0.56 s), and is no stronger, so this "
        "alarm may be that contact's ringing, not a new contact (the measured motion stayed "
        "within the calibration's ranges, so only the timing tells)")
    assert "after incident 4, itself close behind it, ended" in marks[1]["text"]
    assert ringing_text(got[2]) == marks[1]["text"] and ringing_text(push) is None
    unchecked = close_behind([push, rings[0]], SETTLE, measured_checked=False)[1]
    assert "the measured motion was not held against the calibration's ranges" in (
        unchecked.close_behind["text"])
    # the settling time bounds each link: 0.55 s after the end is close, 0.57 s is not
    for gap, marked in ((0.55, True), (0.57, False)):
        x = Forced(36.032 + gap, 36.9, 4, force_n=2.0)
        assert (close_behind([push, x], SETTLE, True)[1].close_behind is not None) is marked
    # a stronger alarm is a contact and heads its own chain; weaker ones follow it
    strong = Forced(36.3, 36.5, 4, force_n=30.0)
    after_strong = Forced(36.6, 36.7, 5, force_n=25.0)
    got = close_behind([push, strong, after_strong], SETTLE, True)
    assert got[1].close_behind is None and got[2].close_behind["incident"] == 4
    # an alarm that starts before the last one ended (overlap), one not counted, and one
    # already in a measured aftermath are not marked, and the last two break the chain
    overlap = Forced(36.0, 36.3, 4, force_n=2.0)
    assert close_behind([push, overlap], SETTLE, True)[1].close_behind is None
    uncounted = Forced(36.144, 36.416, None, force_n=3.59)
    got = close_behind([push, uncounted, rings[1]], SETTLE, True)
    assert got[1].close_behind is None and got[2].close_behind is None
    in_after = dataclasses.replace(rings[0], aftermath={"text": "x"})
    got = close_behind([push, in_after, rings[1]], SETTLE, True)
    assert got[1].close_behind is None and got[2].close_behind is None
    assert ringing_text(in_after) == "x"
    # unknown forces: the peak residuals tell (no larger on any joint); the input's order
    # is kept
    res = {"elbow": 4.0, "shoulder": 1.0}
    head = dataclasses.replace(push, peak_residual=res)
    blind = [dataclasses.replace(x, force_n=None, peak_residual={"elbow": 4.0 - k})
             for k, x in enumerate(rings)]
    got = close_behind([*reversed(blind), head], SETTLE, True)
    assert got[-1].close_behind is None and all(g.close_behind for g in got[:-1])
    assert got[-2].close_behind["text"].startswith(
        "close behind incident 3 (21.2 N at 35.048 s): it began 0.112 s after that alarm "
        "ended, within the detectors' settling time (0.56 s), and is no stronger (its peak "
        "residual no larger on any joint: the forces are not both known), so this alarm")
    # one larger on a joint, or alarming on a joint the chain's first did not, is not
    up = dataclasses.replace(blind[1], peak_residual={"elbow": 1.0, "shoulder": 1.5})
    new = dataclasses.replace(blind[1], peak_residual={"wrist": 0.1})
    for odd in (up, new):
        got = close_behind([head, blind[0], odd], SETTLE, True)
        assert got[1].close_behind and got[2].close_behind is None


@given(gaps=st.lists(st.floats(0.01, 1.2), min_size=1, max_size=8),
       forces=st.lists(st.floats(0.5, 40.0), min_size=9, max_size=9))
def test_close_behind_marks_exactly_the_chains(gaps: list[float], forces: list[float]) -> None:
    """Against the rule written out: an incident is marked iff it starts within the settling
    time after the one before and is no stronger than the first of the chain it continues;
    a mark names that first incident."""
    incs, t = [], 10.0
    for k, gap in enumerate([0.0, *gaps]):
        t += gap
        incs.append(Forced(t, t + 0.2, k + 1, force_n=forces[k]))
        t += 0.2
    got = close_behind(incs, SETTLE, True)
    head = incs[0]
    assert got[0].close_behind is None
    for k in range(1, len(incs)):
        ok = incs[k].t_start - incs[k - 1].t_end <= SETTLE + 1e-9 and (
            incs[k].force_n <= head.force_n)
        mark = got[k].close_behind
        assert (mark is not None) is ok
        if ok:
            assert mark["incident"] == head.number and mark["after"] == k
        else:
            head = incs[k]


def test_a_span_no_incident_threw_marks_nothing() -> None:
    """Motion that left the measured ranges before any incident (a fast reference, an unseen
    bump) is not an incident's aftermath: the first incident in it is not its cause."""
    a, b = Inc(10.5, 10.8, 1), Inc(11.2, 11.4, 2)
    assert aftermath_of([a, b], [out(10.0, 11.3)], SETTLE) == [None, None]
    # from LEAD_S before an incident's start it is the incident's (the residual lags)
    early = [out(10.5 - LEAD_S + 0.01, 11.3)]
    assert aftermath_of([a, b], early, SETTLE)[1] is not None
    late = [out(10.5 - LEAD_S - 0.01, 11.3)]
    assert aftermath_of([a, b], late, SETTLE)[1] is None


def test_the_filters_starting_throw_no_aftermath() -> None:
    """A new user's heavy-arm log: the measured acceleration left its range at each corner
    of the lead-in triangles, every 0.54 s (closer than the settling time: one span from
    the first), and the span began within the warm-up's incident at the log's first sample
    — the filters starting. Its 14 alarms were each called "in the aftermath of the incident
    at 0.000 s". That incident is no contact: the span has no cause."""

    @dataclass(frozen=True)
    class At(Inc):
        i_start: int = 1

    corners = [out(0.092 + 0.54 * k, 0.142 + 0.54 * k) for k in range(20)]
    start = At(0.0, 0.15, None, i_start=0)
    alarms = [At(0.5 + 0.54 * k, 0.55 + 0.54 * k, k + 1, i_start=100 + k) for k in range(19)]
    assert aftermath_of([start, *alarms], corners, SETTLE) == [None] * 20
    # the same alarm 0.004 s in (its second sample) is a cause as before
    second = At(0.004, 0.15, None, i_start=1)
    marks = aftermath_of([second, *alarms], corners, SETTLE)
    assert all(m is not None and m["t_start"] == 0.004 for m in marks[1:])


def test_an_incident_that_starts_while_its_cause_is_on_is_not_its_aftermath() -> None:
    a, b = Inc(10.0, 11.0, 1), Inc(10.9, 11.5, 2)
    assert aftermath_of([a, b], [out(10.1, 12.0)], SETTLE) == [None, None]


def test_stretches_farther_apart_than_the_settling_time_are_two_spans() -> None:
    a, b = Inc(10.0, 10.3, 1), Inc(11.6, 11.8, 2)
    gap = 11.0 - 10.4  # > SETTLE
    assert gap > SETTLE
    assert aftermath_of([a, b], [out(10.1, 10.4), out(11.0, 11.7)], SETTLE) == [None, None]
    assert aftermath_of([a, b], [out(10.1, 10.4), out(10.9, 11.7)], SETTLE)[1] is not None


def test_no_stretch_no_mark_and_unordered_input_keeps_its_order() -> None:
    a, b = Inc(10.0, 10.3, 1), Inc(10.6, 10.8, 2)
    assert aftermath_of([a, b], [], SETTLE) == [None, None]
    marks = aftermath_of([b, a], [out(10.1, 10.9)], SETTLE)
    assert marks[1] is None and marks[0] is not None and marks[0]["incident"] == 1
    # an incident without a number (warm-up, a payload change) is named by its time
    warm = Inc(1.0, 1.2, None)
    (m,) = aftermath_of([warm, Inc(1.5, 1.6, 1)], [out(1.1, 1.5)], SETTLE)[1:]
    assert m is not None and aftermath_text(m).startswith(
        "in the aftermath of the incident at 1.000 s")
    marked = mark_aftermath([a, b], [out(10.1, 10.9)], SETTLE)
    assert marked[0] is a and marked[1].aftermath["text"] == aftermath_text(
        marked[1].aftermath)


def test_a_stretch_round_trips_through_its_mapping() -> None:
    s = out(1.0, 2.0, -7.5)
    assert MeasuredStretch.from_dict(s.to_dict()) == s
    assert s.score == pytest.approx(0.25)
    assert out(1.0, 2.0, 4.0).score == 0.0


@given(st.lists(st.integers(1, 400), min_size=1, max_size=6), st.integers(0, 2 ** 31 - 1))
def test_peak_runs_are_the_same_whatever_the_chunks(cuts: list[int], seed: int) -> None:
    """Runs joined across chunk boundaries and over the merge gap, each with its farthest
    sample: the same for any split of the same samples."""
    rng = np.random.default_rng(seed)
    n = 1200
    t = np.arange(n) * 0.004
    score = np.where(rng.random(n) < 0.05, rng.random(n), 0.0)
    score[300:360] = np.linspace(0.1, 2.0, 60)
    col = rng.integers(0, 2, n)
    qty = rng.integers(0, 2, n)
    val = rng.normal(size=n)

    def run(bounds: list[int]) -> list[list[float]]:
        pr = PeakRuns(0.1)
        for a, b in zip([0, *bounds], [*bounds, n], strict=True):
            pr.add(a, t[a:b], score[a:b], col[a:b], qty[a:b], val[a:b])
        return pr.runs

    whole = run([])
    assert run(sorted(set(c % n for c in cuts) - {0})) == whole
    # gaps ≤ 0.1 s merged: consecutive runs lie more than 0.1 s apart
    assert all(b[0] - a[1] > 0.1 for a, b in itertools.pairwise(whole))
    top = max(whole, key=lambda r: r[2])
    assert top[2] == pytest.approx(2.0) and top[5] == val[359]
