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


def test_an_incident_of_alarms_chained_over_ten_seconds_says_contacts_in_it_are_not_apart(
        ) -> None:
    """A trial's incident of 28 alarms chained over 17.7 s (each under 10 s, so no lasting
    load) under a load no calibration log carried held a 30 N push: the terminal's row,
    the batch row and the report's row say that contacts within it are not told apart."""
    from types import SimpleNamespace

    from impactcli.cli.detect import _incident_line
    from impactcli.detect.events import LONG_EVENT_S, chained_text
    from impactcli.outputs.report.summary import incident_table_html
    from impactcli.run.batch import _incident_row

    assert chained_text(LONG_EVENT_S - 0.01) is None
    assert chained_text(17.684) == (
        "alarms chained over 17.7 s (none 10 s alone): the contacts within it are not told "
        "apart — a lasting condition (a load no calibration log carried, a model that no "
        "longer fits?)")
    inc = SimpleNamespace(t_start=5.604, t_end=23.288, link=2, link_candidates=(2,),
                          force_n=22.1, contact="quasi_static",
                          detectors=("adaptive", "static_loading"), force_plausible=True,
                          force_method="", force_at_least=True, payload_test=None,
                          outside_envelope=None, aftermath=None, close_behind=None,
                          load_motion=None, unseen_load_kg=None, resumes_load=None,
                          velocity_disagrees=None, held_before=None)
    row = _incident_row(inc)
    assert row["chained_s"] == 23.288 - 5.604
    line = _incident_line(2, row)
    assert line.endswith("  alarms chained over 17.7 s (none 10 s alone): contacts in it not "
                         "told apart"), line
    short = _incident_row(SimpleNamespace(**{**vars(inc), "t_end": 15.6}))
    assert "chained_s" not in short and "chained" not in _incident_line(2, short)
    html = incident_table_html([{"label": "2", "number": 2, "t_start": 5.604, "t_end": 23.288,
                                 "duration_s": 17.688, "force_n": 22.1, "link": 2,
                                 "contact": "quasi_static", "detectors": ["adaptive"],
                                 "peak_ratio": 3.0, "peak_ratio_detector": "adaptive",
                                 "peak_residual": {}}], "log1", 0)
    assert '<span class="bad">alarms chained over 17.7 s (none 10 s alone)' in html
