"""Event extraction with hand-built decisions."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.detect.events import extract_events

T = np.arange(100) * 0.01    # 10 ms samples


def _dec(*spans: tuple[int, int, int]) -> np.ndarray:
    d = np.zeros((100, 2), dtype=bool)
    for j, a, b in spans:
        d[a : b + 1, j] = True
    return d


def test_or_over_joints_first_to_fire_first_and_peaks() -> None:
    d = _dec((1, 10, 14), (0, 12, 20))
    ratio = np.ones((100, 2))
    ratio[13, 0] = 3.0
    ratio[50, 1] = 9.0                           # outside the event: ignored
    r = np.zeros((100, 2))
    r[11, 0], r[15, 0] = 0.5, -0.9               # joint 0's largest |r| is negative
    r[12, 1] = 0.4
    ev = extract_events("adaptive", d, ratio, r, T, ("shoulder", "elbow"), 0.05, 0.0, 0.0)
    assert len(ev) == 1
    e = ev[0]
    assert (e.i_start, e.i_end) == (10, 20)
    assert e.t_start == pytest.approx(0.10) and e.t_end == pytest.approx(0.20)
    assert e.joints == ("elbow", "shoulder")
    assert e.peak_ratio == 3.0
    assert e.peak_residual == {"elbow": 0.4, "shoulder": -0.9}
    assert e.in_warmup is False


def test_merge_gap_and_min_duration() -> None:
    d = _dec((0, 10, 12), (0, 16, 18), (0, 40, 40), (1, 70, 75))
    ratio, r = np.ones((100, 2)), np.zeros((100, 2))
    args = (ratio, r, T, ("a", "b"), 0.0)
    ev = extract_events("static_loading", d, *args, 0.04, 0.0)
    assert [(e.i_start, e.i_end) for e in ev] == [(10, 18), (40, 40), (70, 75)]
    ev = extract_events("static_loading", d, *args, 0.03, 0.0)   # gap 12→16 is 0.04 s
    assert [(e.i_start, e.i_end) for e in ev] == [(10, 12), (16, 18), (40, 40), (70, 75)]
    ev = extract_events("static_loading", d, *args, 0.04, 0.02)  # drops the 1-sample event
    assert [(e.i_start, e.i_end) for e in ev] == [(10, 18), (70, 75)]
    assert ev[1].joints == ("b",)


def test_in_warmup_and_empty() -> None:
    d = _dec((0, 3, 5), (1, 60, 61))
    ev = extract_events("static_baseline", d, np.ones((100, 2)), np.zeros((100, 2)), T,
                        ("a", "b"), 0.5)
    assert [e.in_warmup for e in ev] == [True, False]
    assert extract_events("adaptive", np.zeros((100, 2), bool), np.ones((100, 2)),
                          np.zeros((100, 2)), T, ("a", "b"), 0.0) == []
    with pytest.raises(ValueError, match="unknown detector"):
        extract_events("nope", d, d, d, T, ("a", "b"), 0.0)


def test_alarm_straddling_warmup_end_is_split_and_counted() -> None:
    # on from sample 10 to 80 with a short gap at 29-30; warm-up ends at 0.3 s (sample 30)
    d = _dec((0, 10, 28), (1, 31, 80))
    ev = extract_events("static_loading", d, np.ones((100, 2)), np.zeros((100, 2)), T,
                        ("a", "b"), 0.3, 0.1)
    assert [(e.i_start, e.i_end, e.in_warmup) for e in ev] == [(10, 28, True), (31, 80, False)]
    assert ev[1].joints == ("b",)
    # an alarm that starts before the end and is on at it: cut exactly at the end
    d = _dec((0, 5, 90))
    ev = extract_events("adaptive", d, np.ones((100, 2)), np.zeros((100, 2)), T, ("a", "b"), 0.5)
    assert [(e.i_start, e.i_end, e.in_warmup) for e in ev] == [(5, 49, True), (50, 90, False)]
