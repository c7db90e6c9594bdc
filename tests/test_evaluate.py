"""Detection quality against labels: hand-built events and contacts with known answers."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from impactcli.detect.events import extract_events
from impactcli.errors import ConfigError, ImpactWarning, LabelsError, LogFormatError
from impactcli.quality.evaluation import evaluate_events
from impactcli.quality.match import MatchTolerance, product_events, scored_event
from impactcli.quality.sweep import (
    EventIntervals,
    SweepRow,
    ThresholdSweep,
    event_intervals,
    event_settings,
    sweep_ratios,
)
from impactcli.quality.text import format_evaluation
from impactcli.quality.verdict import (
    adaptive_helps,
    at_zero_false_alarms,
    compare_at_zero,
    format_sweep,
    sweep_to_dict,
    verdict,
)
from impactcli.schema import validate
from impactcli.types import ContactLabel, Event, Labels

from .fakes import SWEEP_LABELS, contact, labels, sweep_result

H = 3600.0


def ev(det: str, t0: float, t1: float | None = None, warm: bool = False) -> Event:
    t1 = t0 + 0.05 if t1 is None else t1
    return Event(det, t0, t1, 0, 0, ("j1",), 1.5, {"j1": 1.0}, warm)


def run(events, lab, duration=10.0, warmup=1.0, **kw):
    return evaluate_events(events, lab, duration_s=duration, warmup_end_s=warmup, **kw)


def test_basic_counts_delays_forces_and_rates():
    lab = labels(contact(2.0, 2.1, 5.0, "impact"), contact(4.0, 4.5, 10.0, "push"),
                 contact(6.0, 7.0, 20.0, "clamp"))
    events = [ev("adaptive", 2.03), ev("adaptive", 4.6), ev("adaptive", 8.0),
              ev("static_loading", 6.2, 6.9)]
    e = run(events, lab)
    # windows [c.start - 0.02, c.end + 0.25]: 0.37 + 0.77 + 1.27 s of the 9 s after warm-up
    assert e.collision_free_s == pytest.approx(9.0 - 2.41)
    a = e.scores["adaptive"]
    assert (a.n_contacts, a.detected, a.missed, a.false_alarms, a.n_events) == (3, 2, 1, 1, 3)
    assert a.delay_median_s == pytest.approx((0.03 + 0.6) / 2)
    assert a.delay_max_s == pytest.approx(0.6)
    assert a.min_detected_force == 5.0 and a.max_missed_force == 20.0
    assert a.false_alarms_per_hour == pytest.approx(1 / ((9.0 - 2.41) / H))
    assert a.false_alarm_times == ((8.0, 8.05),)
    kinds = {k.kind: k for k in a.by_kind}
    assert [k.kind for k in a.by_kind] == ["impact", "push", "clamp"]
    assert (kinds["clamp"].detected, kinds["clamp"].max_missed_force) == (0, 20.0)
    assert kinds["push"].delay_median_s == pytest.approx(0.6)
    sl = e.scores["static_loading"]
    assert (sl.detected, sl.false_alarms, sl.min_detected_force) == (1, 0, 20.0)
    assert sl.delay_median_s == pytest.approx(0.2)
    p = e.scores["product"]
    assert (p.detected, p.false_alarms, p.min_detected_force) == (3, 1, 5.0)
    assert p.max_missed_force is None
    b = e.scores["static_baseline"]
    assert (b.detected, b.false_alarms, b.false_alarms_per_hour) == (0, 0, 0.0)
    assert b.delay_median_s is None
    assert b.max_missed_force == 20.0 and b.min_detected_force is None


def test_tolerance_window_edges():
    lab = labels(contact(2.0, 2.1))
    early = [ev("adaptive", 1.97)]  # 30 ms before onset
    assert run(early, lab).scores["adaptive"].detected == 0
    assert run(early, lab).scores["adaptive"].false_alarms == 1
    wide = run(early, lab, tolerance=MatchTolerance(pre_s=0.05, post_s=0.25)).scores["adaptive"]
    assert (wide.detected, wide.false_alarms) == (1, 0)
    assert wide.delay_median_s == pytest.approx(-0.03)
    late = run([ev("adaptive", 2.36)], lab).scores["adaptive"]  # end + 0.26 s
    assert (late.detected, late.false_alarms) == (0, 1)
    ok = run([ev("adaptive", 2.34)], lab).scores["adaptive"]  # end + 0.24 s: the release
    assert (ok.detected, ok.false_alarms) == (1, 0)
    with pytest.raises(ConfigError):
        MatchTolerance(pre_s=-0.1)


def test_overlapping_contacts_one_event_detects_both():
    lab = labels(contact(2.0, 2.3, 4.0), contact(2.2, 2.5, 8.0))
    e = run([ev("adaptive", 2.25, 2.4)], lab)
    a = e.scores["adaptive"]
    assert (a.detected, a.false_alarms, a.min_detected_force) == (2, 0, 4.0)
    assert sorted(c.delay_s["adaptive"] for c in e.contacts) == pytest.approx([0.05, 0.25])
    # union of overlapping windows counted once: [1.98, 2.75]
    assert e.collision_free_s == pytest.approx(9.0 - 0.77)


def test_alarms_and_contacts_during_warmup_are_listed_not_counted():
    lab = labels(contact(0.5, 0.6, 3.0), contact(5.0, 5.1, 7.0))
    events = [
        ev("adaptive", 0.2, warm=True),    # alarm in warm-up, no contact
        ev("adaptive", 0.52, warm=True),   # matches the warm-up contact
        ev("adaptive", 0.9),               # starts before warm-up end though not flagged
        ev("adaptive", 5.01),
    ]
    e = run(events, lab, warmup=1.0)
    a = e.scores["adaptive"]
    assert (a.n_events, a.n_events_in_warmup, a.false_alarms) == (1, 3, 0)
    assert (a.n_contacts, a.detected, a.max_missed_force) == (1, 1, None)
    assert len(a.warmup_events) == 3
    warm = e.contacts_with_status("in_warmup")
    assert [c.index for c in warm] == [0]
    assert warm[0].detected["adaptive"] is True        # informational
    assert warm[0].detected["static_loading"] is False  # not a miss: not counted
    assert e.scores["static_loading"].n_contacts == 1
    assert e.scores["static_loading"].max_missed_force == 7.0  # only the counted one
    assert "in warm-up (not counted as misses)" in format_evaluation(e)
    # a counted contact cannot be detected by an in-warm-up event
    e2 = run([ev("adaptive", 0.99, warm=True)], labels(contact(1.0, 1.1)), warmup=1.0)
    assert (e2.scores["adaptive"].detected, e2.scores["adaptive"].n_contacts) == (0, 1)


def test_contact_at_the_very_end_of_the_log():
    lab = labels(contact(9.95, 10.0, 6.0))
    e = run([ev("adaptive", 9.99, 10.0)], lab)
    assert e.scores["adaptive"].detected == 1
    assert e.scores["adaptive"].delay_median_s == pytest.approx(0.04)
    # its window [9.93, 10.25] is clipped at the log's end
    assert e.collision_free_s == pytest.approx(9.0 - 0.07)
    missed = run([], lab)
    assert missed.scores["adaptive"].max_missed_force == 6.0
    with pytest.warns(ImpactWarning, match="after the log's end"):
        out = run([], labels(contact(9.0, 9.1), contact(12.0, 12.1)))
    assert [c.status for c in out.contacts] == ["counted", "outside_log"]
    assert out.scores["adaptive"].n_contacts == 1


def test_event_spanning_two_contacts_detects_only_the_first():
    lab = labels(contact(2.0, 2.1, 5.0), contact(3.0, 3.1, 9.0))
    e = run([ev("adaptive", 2.05, 3.5)], lab)
    a = e.scores["adaptive"]
    assert (a.detected, a.false_alarms, a.max_missed_force) == (1, 0, 9.0)
    second = e.contacts[1]
    assert second.detected["adaptive"] is False
    assert second.alarm_on_at_onset["adaptive"] is True
    assert e.contacts[0].alarm_on_at_onset["adaptive"] is False
    assert second.alarm_on_at_onset["static_loading"] is False


def test_zero_contacts_every_counted_event_is_a_false_alarm():
    e = run([ev("adaptive", 3.0), ev("adaptive", 5.0), ev("static_loading", 5.02, 5.5)], labels())
    a = e.scores["adaptive"]
    assert (a.n_contacts, a.detected, a.false_alarms, a.recall) == (0, 0, 2, None)
    assert a.false_alarms_per_hour == pytest.approx(2 / (9.0 / H))
    assert a.delay_median_s is None and a.min_detected_force is None
    # product: adaptive 5.0-5.05 and loading 5.02-5.5 overlap: one alarm, not two
    assert e.scores["product"].false_alarms == 2
    assert e.scores["static_loading"].false_alarms == 1


def test_zero_events_and_zero_collision_free_time():
    lab = labels(contact(2.0, 2.1, 5.0), contact(4.0, 4.1, 15.0, "push"))
    e = run([], lab)
    for s in e.scores.values():
        assert (s.detected, s.false_alarms, s.n_events, s.max_missed_force) == (0, 0, 0, 15.0)
    e2 = run([], labels(contact(1.0, 10.0)), warmup=1.0)
    assert e2.collision_free_s == 0.0
    assert e2.scores["adaptive"].false_alarms_per_hour is None


def test_product_merges_overlapping_alarms():
    lab = labels(contact(5.4, 5.45, 3.0))
    # adaptive false alarm already on when loading fires on the contact: one product event,
    # a false alarm (its adaptive part matched nothing), and the contact detected by its
    # static_loading part — the product detects what any of its parts detects
    e = run([ev("adaptive", 5.0, 5.5), ev("static_loading", 5.41, 6.0)], lab)
    assert e.scores["static_loading"].detected == 1
    p = e.scores["product"]
    assert (p.n_events, p.false_alarms, p.detected) == (1, 1, 1)
    assert e.contacts[0].delay_s["product"] == pytest.approx(0.01)
    apart = run([ev("adaptive", 5.0, 5.1), ev("static_loading", 5.41, 6.0)], lab,
                product_merge_gap_s=0.0)
    assert (apart.scores["product"].n_events, apart.scores["product"].detected) == (2, 1)


def test_timeline_dicts_equal_events_and_output_is_deterministic_and_valid():
    lab = labels(contact(2.0, 2.1, 5.0), contact(4.0, 4.5, 10.0, "push"), contact(0.3, 0.4))
    events = [ev("adaptive", 2.03), ev("adaptive", 0.31, warm=True), ev("static_loading", 7.0),
              ev("static_baseline", 2.01)]
    a = run(events, lab)
    b = run([e.to_dict() for e in events], lab)
    ja = json.dumps(a.to_dict(), sort_keys=True)
    assert ja == json.dumps(b.to_dict(), sort_keys=True)
    assert ja == json.dumps(run(list(events), lab).to_dict(), sort_keys=True)
    doc = a.to_dict()
    validate(doc, "evaluation", LabelsError, "evaluation")
    assert doc["detectors"]["adaptive"]["delay_median_s"] == 0.03  # rounded: no float noise
    assert doc["n_contacts"] == {"counted": 2, "in_warmup": 1, "outside_log": 0}
    text = format_evaluation(a)
    assert "static_loading" in text and "1/2" in text and "30 ms" in text


def test_bad_event_dict_is_a_data_error():
    with pytest.raises(LogFormatError, match="events\\[0\\]"):
        run([{"t_start": 1.0}], labels())
    with pytest.raises(LogFormatError, match="unknown detector"):
        run([{"t_start": 1.0, "t_end": 1.1, "detector": "magic", "in_warmup": False}], labels())


# --- threshold sweep ------------------------------------------------------------------




def sweep_thresholds(res, lab, scales, *, merge_gap_s=None, min_duration_s=None, **kw):
    """The sweep of a fake run's (N, J) ratios, with its config's event settings."""
    gap, min_dur = event_settings(res.config, merge_gap_s, min_duration_s)
    return sweep_ratios(res.ratios, res.log.time_s, labels=lab, scales=scales,
                        warmup_end_s=res.warmup_end_s, merge_gap_s=gap, min_duration_s=min_dur,
                        **kw)


def test_sweep_rows_have_the_known_counts():
    rows = sweep_thresholds(sweep_result(), SWEEP_LABELS, [2.5, 1.0, 1.3, 1.6])
    got = {(r.detector, r.scale): (r.detected, r.false_alarms) for r in rows}
    assert [r.scale for r in rows if r.detector == "adaptive"] == [1.0, 1.3, 1.6, 2.5]
    assert got[("adaptive", 1.0)] == (2, 1)
    assert got[("adaptive", 1.3)] == (1, 1)
    assert got[("adaptive", 1.6)] == (1, 0)
    assert got[("adaptive", 2.5)] == (0, 0)
    assert got[("static_loading", 1.0)] == (1, 1)
    assert got[("static_loading", 1.3)] == (1, 0)
    assert got[("static_baseline", 1.0)] == (0, 0)
    assert got[("product", 1.0)] == (2, 2)
    a10 = next(r for r in rows if (r.detector, r.scale) == ("adaptive", 1.0))
    assert a10.min_detected_force == 1.5
    duration = 2499 * 0.004  # fake_result: 2500 samples at 4 ms
    assert a10.false_alarms_per_hour == pytest.approx(1 / ((duration - 1.0 - 2 * 0.37) / H))
    zero = at_zero_false_alarms(rows)
    assert zero["adaptive"] is not None and zero["adaptive"].scale == 1.6
    assert zero["adaptive"].min_detected_force == 3.0
    assert zero["adaptive"].delay_median_s == pytest.approx(0.0, abs=1e-9)
    assert zero["static_loading"] is not None and zero["static_loading"].scale == 1.3
    assert zero["static_loading"].delay_median_s == pytest.approx(0.048, abs=1e-6)
    assert zero["static_baseline"] is not None and zero["static_baseline"].scale == 1.0
    assert adaptive_helps(zero) is True  # same force, earlier on the shared contact
    cmp = compare_at_zero(zero)
    assert cmp is not None
    assert (cmp.both, cmp.adaptive_only, cmp.loading_only) == (1, 0, 0)
    assert cmp.paired_delay_gain_s == pytest.approx(0.048, abs=1e-6)
    assert zero["adaptive"].contact_delays_s[1] is None
    assert verdict(zero).startswith("The adaptive detector helps")
    doc = sweep_to_dict(rows)
    validate({**run([], SWEEP_LABELS).to_dict(), "sweep": doc}, "evaluation", LabelsError, "x")
    assert json.dumps(doc, sort_keys=True) == json.dumps(
        sweep_to_dict(sweep_thresholds(sweep_result(), SWEEP_LABELS, [1.0, 1.3, 1.6, 2.5])),
        sort_keys=True)
    assert "helps" in format_sweep(rows)


def test_sweep_verdict_when_adaptive_is_slower():
    rows = sweep_thresholds(sweep_result(adaptive_delay=0.1), SWEEP_LABELS, [1.0, 1.3, 1.6, 2.5])
    zero = at_zero_false_alarms(rows)
    assert zero["adaptive"] is not None
    assert zero["adaptive"].delay_median_s == pytest.approx(0.1, abs=1e-6)
    assert adaptive_helps(zero) is False
    assert verdict(zero).startswith("The adaptive detector does not help")
    assert "fires 52 ms later" in verdict(zero)


@pytest.mark.parametrize("gap, min_dur", [(0.0, 0.0), (0.02, 0.0), (0.1, 0.01), (0.3, 0.2)])
def test_event_intervals_equal_extract_events(gap, min_dur):
    rng = np.random.default_rng(3)
    n, J = 3000, 3
    t = np.cumsum(rng.uniform(0.003, 0.005, n))  # jittered 4 ms clock
    ratio = np.abs(rng.standard_normal((n, J)))
    decision = ratio > 2.5
    decision[-3:, 1] = True  # an event running to the last sample
    want = extract_events("adaptive", decision, ratio, ratio, t, ["a", "b", "c"], 0.0, gap, min_dur)
    i0, i1 = event_intervals(decision, t, gap, min_dur)
    assert len(want) >= 3
    assert [(e.i_start, e.i_end) for e in want] == list(zip(i0.tolist(), i1.tolist(), strict=True))
    # with a warm-up end inside a long alarm, both split it the same way
    dw = decision.copy()
    dw[500:900, 0] = True
    tw = float(t[700])
    want_w = extract_events("adaptive", dw, ratio, ratio, t, ["a", "b", "c"], tw, gap, min_dur)
    iw0, iw1 = event_intervals(dw, t, gap, min_dur, tw)
    assert [(e.i_start, e.i_end) for e in want_w] == list(zip(iw0.tolist(), iw1.tolist(),
                                                              strict=True))
    assert any(e.i_start == 700 and not e.in_warmup for e in want_w)
    # bursts exactly merge_gap apart and exactly min_duration long, on a float clock where
    # such differences land a few 1e-17 s above or below the nominal value
    t4 = (np.arange(2000) * 4_000_000).astype(np.int64) * 1e-9
    i = next(k for k in range(200, 1000) if t4[k + 25] - t4[k] > 0.1)
    j = next(k for k in range(1200, 1900) if t4[k + 10] - t4[k] < 0.04)
    d4 = np.zeros((2000, 1), dtype=bool)
    d4[[i, i + 25, j, j + 10], 0] = True
    want4 = extract_events("adaptive", d4, d4 * 1.0, d4 * 1.0, t4, ["a"], 0.0, 0.1, 0.04)
    assert [(e.i_start, e.i_end) for e in want4] == [(i, i + 25), (j, j + 10)]
    got4 = event_intervals(d4, t4, 0.1, 0.04)
    assert list(zip(got4[0].tolist(), got4[1].tolist(), strict=True)) == [(i, i + 25), (j, j + 10)]
    none = event_intervals(np.zeros((n, J), dtype=bool), t, gap, min_dur)
    assert none[0].size == 0 and none[1].size == 0


def _chunks(n: int, sizes: list[int]) -> list[tuple[int, int]]:
    out, a, k = [], 0, 0
    while a < n:
        b = min(a + sizes[k % len(sizes)], n)
        out.append((a, b))
        a, k = b, k + 1
    return out


@pytest.mark.parametrize("sizes", [[1], [7, 1, 300], [499], [2999, 1]])
@pytest.mark.parametrize("gap, min_dur, warm_at", [(0.0, 0.0, None), (0.02, 0.0, 700),
                                                    (0.1, 0.01, 0), (0.3, 0.2, 2999)])
def test_event_intervals_whatever_the_chunks(sizes, gap, min_dur, warm_at):
    """Fed in chunks of any size (runs and merged events across chunk boundaries, the
    warm-up's end at a boundary or inside an alarm), EventIntervals finds the events of the
    whole decision, which are extract_events'."""
    rng = np.random.default_rng(5)
    n, J = 3000, 2
    t = np.cumsum(rng.uniform(0.003, 0.005, n))
    ratio = np.abs(rng.standard_normal((n, J)))
    dec = ratio > 2.8
    dec[650:760, 0] = True  # a long alarm across sample 700
    dec[-2:, 1] = True
    wu = None if warm_at is None else float(t[warm_at])
    want = extract_events("adaptive", dec, ratio, ratio, t, ["a", "b"],
                          -1.0 if wu is None else wu, gap, min_dur)
    iv = EventIntervals(gap, min_dur, wu)
    for a, b in _chunks(n, sizes):
        iv.update(t[a:b], dec[a:b].any(axis=1))
    i0, t0, i1, t1 = iv.finish()
    assert len(want) >= 4
    assert [(e.i_start, e.i_end) for e in want] == list(zip(i0.tolist(), i1.tolist(),
                                                            strict=True))
    assert t0.tolist() == t[i0].tolist() and t1.tolist() == t[i1].tolist()


def test_sweep_rows_whatever_the_chunks():
    res = sweep_result()
    gap, min_dur = event_settings(res.config, None, None)
    scales = [0.9, 1.0, 1.3, 1.6, 2.5]
    whole = sweep_thresholds(res, SWEEP_LABELS, scales)
    t = res.log.time_s
    for sizes in ([1000], [1, 13, 250], [1012]):  # boundaries in events and at the warm-up
        sw = ThresholdSweep(scales, warmup_end_s=res.warmup_end_s, merge_gap_s=gap,
                            min_duration_s=min_dur)
        for a, b in _chunks(len(t), sizes):
            sw.update(t[a:b], {d: r[a:b] for d, r in res.ratios.items()})
        assert sw.rows(SWEEP_LABELS) == whole


def test_sweep_needs_event_settings():
    res = dataclasses.replace(sweep_result(), config={})
    with pytest.raises(ConfigError, match="merge_gap_s"):
        sweep_thresholds(res, SWEEP_LABELS, [1.0])
    rows = sweep_thresholds(res, SWEEP_LABELS, [1.6], merge_gap_s=0.0, min_duration_s=0.0,
                            detectors=("adaptive",))
    assert [(r.detector, r.detected, r.false_alarms) for r in rows] == [("adaptive", 1, 0)]
    with pytest.raises(ConfigError):
        sweep_thresholds(res, SWEEP_LABELS, [0.0], merge_gap_s=0.0, min_duration_s=0.0)


def row(det: str, scale: float, fa: int, *, det_n: int = 1, force: float | None = 2.0,
        delay: float | None = 0.03) -> SweepRow:
    return SweepRow(det, scale, fa + det_n, 3, det_n, fa, None, delay, force)


def test_median_delays_over_different_contacts_are_not_compared():
    """Adaptive catches one big contact fast, static_loading three smaller ones slower: the
    medians favour adaptive, the paired delays do not — it does not help."""
    a = SweepRow("adaptive", 1.0, 1, 4, 1, 0, 0.0, 0.01, 30.0, (None, None, None, 0.01))
    s = SweepRow("static_loading", 1.0, 3, 4, 3, 0, 0.0, 0.05, 10.0, (0.05, 0.05, None, 0.005))
    zero = {"adaptive": a, "static_loading": s}
    cmp = compare_at_zero(zero)
    assert cmp is not None and (cmp.adaptive_only, cmp.loading_only, cmp.both) == (0, 2, 1)
    assert cmp.paired_delay_gain_s == pytest.approx(-0.005)
    assert adaptive_helps(zero) is False
    faster = dataclasses.replace(a, contact_delays_s=(None, None, None, 0.001))
    assert adaptive_helps({"adaptive": faster, "static_loading": s}) is True


def test_zero_false_alarm_point_ignores_a_lone_silent_scale_and_undetermined_verdicts():
    rows = [row("adaptive", 1.0, 2), row("adaptive", 1.2, 0), row("adaptive", 1.4, 1),
            row("adaptive", 1.6, 0), row("adaptive", 2.0, 0),
            row("static_loading", 1.0, 3), row("static_loading", 2.0, 1)]
    zero = at_zero_false_alarms(rows)
    assert zero["adaptive"] is not None and zero["adaptive"].scale == 1.6
    assert zero["static_loading"] is None
    assert adaptive_helps(zero) is None
    assert verdict(zero).startswith("Undetermined: static_loading never reached zero")
    rows2 = [row("adaptive", 1.0, 0, force=4.0, delay=0.05),
             row("static_loading", 1.0, 0, force=6.0, delay=0.02)]
    assert adaptive_helps(at_zero_false_alarms(rows2)) is True  # smaller force wins
    rows3 = [row("adaptive", 1.0, 0, det_n=0, force=None, delay=None),
             row("static_loading", 1.0, 0)]
    assert adaptive_helps(at_zero_false_alarms(rows3)) is False
    # silent already at the smallest swept scale: not compared at matched rates
    rows5 = [row("adaptive", 0.5, 0), row("adaptive", 1.0, 0),
             row("static_loading", 0.5, 1), row("static_loading", 1.0, 0, force=9.0)]
    zero5 = at_zero_false_alarms(rows5)
    assert adaptive_helps(zero5) is True
    assert adaptive_helps(zero5, smallest_scale=0.5) is None
    assert verdict(zero5, smallest_scale=0.5).startswith(
        "Undetermined: adaptive had no false alarm even at the smallest swept scale (0.5)")
    assert sweep_to_dict(rows5)["adaptive_helps"] is None
    assert "<= 0.5" in format_sweep(rows5)
    rows4 = [row("adaptive", 1.0, 0),
             row("static_loading", 1.0, 0, det_n=0, force=None, delay=None)]
    assert adaptive_helps(at_zero_false_alarms(rows4)) is True


def test_product_keeps_an_alarm_after_warmup_apart_from_one_in_it():
    warm = Event("static_loading", 0.5, 0.996, 125, 249, ("a",), 2.0, {"a": 1.0}, True)
    tail = Event("static_loading", 1.0, 9.0, 250, 2250, ("a",), 2.0, {"a": 1.0}, False)
    adap = Event("adaptive", 0.9, 1.2, 225, 300, ("a",), 1.5, {"a": 1.0}, True)
    evs = [scored_event(e, 1.0, i) for i, e in enumerate((warm, tail, adap))]
    out = product_events(evs, 1.0)
    assert [(e.t_start, e.t_end, e.in_warmup) for e in out] == [(0.5, 1.2, True), (1.0, 9.0, False)]


# --- incidents: the answer (link, force, contact type) --------------------------------


def inc(t0: float, t1: float, link: int | None, force: float | None, contact: str,
        events: tuple[int, ...], warm: bool = False) -> dict:
    """A timeline ``incidents`` item."""
    return {"t_start": t0, "t_end": t1, "t_start_utc": None, "detectors": ["adaptive"],
            "joints": ["j1"], "link": link, "force_n": force, "force_method": "test",
            "contact": contact, "peak_residual": {"j1": 1.0}, "in_warmup": warm,
            "events": list(events)}


def answer_case():
    """Four contacts: A impact on link 2 (10 N), B push on link 1 (20 N), C clamp on link 2
    (30 N), D impact on link 1 (5 N, missed); incidents: one in warm-up, A right (+20 %),
    B on the wrong link (−25 %), C transient instead of quasi-static without a force, and
    a false one at 9.5 s."""
    lab = labels(ContactLabel(2.0, 2.1, 10.0, "impact", 2),
                 ContactLabel(4.0, 4.5, 20.0, "push", 1),
                 ContactLabel(6.0, 7.0, 30.0, "clamp", 2),
                 ContactLabel(8.5, 8.6, 5.0, "impact", 1))
    events = [ev("adaptive", 2.03), ev("static_loading", 2.05, 2.2), ev("static_loading", 4.1),
              ev("static_loading", 6.2, 6.9), ev("adaptive", 9.5), ev("adaptive", 0.3, warm=True)]
    incs = [inc(0.3, 0.35, 1, 1.0, "transient", (5,), warm=True),
            inc(2.03, 2.2, 2, 12.0, "transient", (0, 1)),
            inc(4.1, 4.15, 2, 15.0, "transient", (2,)),
            inc(6.2, 6.9, 2, None, "transient", (3,)),
            inc(9.5, 9.55, 1, 11.0, "transient", (4,))]
    return lab, events, incs


def test_incidents_are_scored_for_link_force_and_contact_type():
    lab, events, incs = answer_case()
    e = run(events, lab, incidents=incs)
    ie = e.incidents
    assert ie.available
    o = ie.overall
    assert (o.n_contacts, o.matched, o.link_right, o.contact_right) == (4, 3, 2, 2)
    assert o.link_accuracy == pytest.approx(2 / 3) and o.contact_accuracy == pytest.approx(2 / 3)
    assert o.force_rel_error_median == pytest.approx(0.225)   # |+20 %|, |−25 %|
    assert o.force_bias_median == pytest.approx(-0.025)
    rows = {c.label_index: c for c in ie.contacts}
    assert [rows[k].incident_index for k in range(4)] == [1, 2, 3, None]
    assert rows[0].force_rel_error == pytest.approx(0.2) and rows[0].link_right
    assert rows[1].link_right is False and rows[1].contact_right is True
    assert rows[2].expected_contact == "quasi_static" and rows[2].contact_right is False
    assert rows[2].force_rel_error is None  # no force estimate
    assert rows[3].link_right is None and rows[3].n_incidents == 0
    assert (ie.n_incidents, ie.n_incidents_in_warmup, ie.unmatched) == (4, 1, (4,))
    # per link and per type (the type the label's kind calls for)
    assert (ie.per_link[1].matched, ie.per_link[1].n_contacts, ie.per_link[1].link_right) == (
        1, 2, 0)
    assert (ie.per_link[2].matched, ie.per_link[2].link_right) == (2, 2)
    assert list(ie.per_type) == ["transient", "quasi_static"]
    assert (ie.per_type["transient"].matched, ie.per_type["transient"].contact_right) == (2, 2)
    assert (ie.per_type["quasi_static"].matched,
            ie.per_type["quasi_static"].contact_right) == (1, 0)
    # every detected contact (A, B, C) is exactly one incident
    assert (ie.detected, ie.one_incident_each, ie.split, ie.shared) == (3, True, (), ())
    doc = e.to_dict()
    validate(doc, "evaluation", LabelsError, "evaluation")
    d = doc["incidents"]
    assert [k for k in ("summary", "contacts") if k in d] == ["summary", "contacts"]
    assert set(d["contacts"][0]) >= {
        "label_index", "incident_index", "link_label", "link", "force_label_n", "force_n",
        "force_rel_error", "kind", "contact", "link_right", "contact_right"}
    assert d["link_accuracy"] == pytest.approx(2 / 3, abs=1e-6)
    assert d["force_rel_error_median"] == 0.225
    assert d["per_link"]["2"]["link_right"] == 2
    assert all(isinstance(a, str) and isinstance(b, str) for a, b in d["summary"])
    summary = dict(d["summary"])
    assert summary["link right"] == "2/3 (67%)"
    assert summary["every detected contact is exactly one incident"] == "yes (3/3)"
    text = format_evaluation(e)
    assert "link 2 / 2 ok" not in text  # columns are separate
    assert "2 / 2 ok" in text and "1 / 2 WRONG" in text and "quasi_static / transient WRONG" in text
    # incidents given as Incident objects score the same
    from impactcli.detect.incidents import Incident

    objs = [Incident(i["t_start"], i["t_end"], 0, 0, ("adaptive",), ("j1",), i["link"],
                     i["force_n"], "test", i["contact"], {"j1": 1.0}, i["in_warmup"], None,
                     tuple(i["events"])) for i in incs]
    assert json.dumps(run(events, lab, incidents=objs).to_dict(), sort_keys=True) == \
        json.dumps(doc, sort_keys=True)


def test_a_contact_split_over_incidents_or_sharing_one():
    lab = labels(ContactLabel(2.0, 3.0, 10.0, "push", 1))
    events = [ev("adaptive", 2.01), ev("static_loading", 2.9)]
    split = [inc(2.01, 2.06, 1, 9.0, "transient", (0,)),
             inc(2.9, 2.95, 1, 9.0, "transient", (1,))]
    ie = run(events, lab, incidents=split).incidents
    assert (ie.detected, ie.split, ie.one_incident_each) == (1, (0,), False)
    assert ie.contacts[0].n_incidents == 2 and ie.contacts[0].incident_index == 0
    assert ie.unmatched == ()  # the second starts in the window: no false incident
    assert "no (0/1); split over several incidents: labels #0" in dict(ie.summary())[
        "every detected contact is exactly one incident"]
    # without their events, alarms are given to the incident whose span holds them
    no_events = [{k: v for k, v in i.items() if k != "events"} for i in split]
    assert run(events, lab, incidents=no_events).incidents.split == (0,)
    # two contacts whose alarms one incident holds: each is still exactly one incident
    lab2 = labels(ContactLabel(2.0, 2.1, 5.0, "impact", 1),
                  ContactLabel(2.2, 2.3, 6.0, "impact", 1))
    ev2 = [ev("adaptive", 2.01, 2.3), ev("static_loading", 2.21)]
    ie2 = run(ev2, lab2, incidents=[inc(2.01, 2.3, 1, 5.0, "transient", (0, 1))]).incidents
    assert (ie2.shared, ie2.one_incident_each) == ((0,), True)
    assert [c.incident_index for c in ie2.contacts] == [0, None]  # an incident on at onset


def test_a_contact_held_by_an_incident_begun_before_it_is_said_beside_the_matched():
    """A contact whose alarm joined an incident that began with an earlier alarm (0.3 s
    before its window) is detected and exactly one incident, but no incident starts in
    its window: "matched 0/1" beside "yes (1/1)" read as a contradiction to a new user;
    the matched row now names it."""
    lab = labels(ContactLabel(2.0, 2.1, 5.0, "impact", 1))
    events = [ev("adaptive", 1.7, 1.8), ev("adaptive", 2.01, 2.1)]
    e = run(events, lab, incidents=[inc(1.7, 2.1, 1, 5.0, "transient", (0, 1))]).incidents
    rows = dict(e.summary())
    assert (e.overall.matched, e.detected, e.one_incident_each) == (0, 1, True)
    assert rows["every detected contact is exactly one incident"] == "yes (1/1)"
    assert rows["counted contacts matched by an incident"] == (
        "0/1 (0%); 1 more held by an incident that began before the contact's window (labels #0: "
        "an earlier alarm it merged with began first, so its start, link and force are not "
        "that contact's)")
    # ... and its own row says it, not "none" (a trial read "#0 push none" beside them)
    row = next(x for x in format_evaluation(run(events, lab, incidents=[
        inc(1.7, 2.1, 1, 5.0, "transient", (0, 1))])).splitlines() if x.startswith("#0 "))
    assert "in an earlier one" in row and " none " not in row, row
    e = run(events[1:], lab, incidents=[inc(2.01, 2.1, 1, 5.0, "transient", (0,))]).incidents
    assert dict(e.summary())["counted contacts matched by an incident"] == "1/1 (100%)"


def test_the_product_can_count_fewer_false_alarms_than_a_part_and_says_why():
    """Known truth: two adaptive false alarms inside one static-loading false alarm are one
    product alarm: adaptive 2, product 1 (a new user read 9 product against 37 adaptive
    false alarms as a contradiction); the text says how the product's alarms merge."""
    lab = labels(ContactLabel(2.0, 2.1, 5.0, "impact", 1))
    events = [ev("adaptive", 2.01), ev("static_loading", 5.0, 8.0),
              ev("adaptive", 5.5), ev("adaptive", 6.5)]
    e = run(events, lab, product_merge_gap_s=0.1)
    assert (e.scores["adaptive"].false_alarms, e.scores["product"].false_alarms) == (2, 1)
    assert ("(the product's alarms are its parts' merged where they overlap or follow "
            "within 0.1 s: one long alarm holds many of a part's, so the product can count "
            "fewer false alarms than one of its parts)") in format_evaluation(e)


def test_switch_labels_have_no_force_to_score():
    lab = Labels(events=(ContactLabel(2.0, 2.1, 0.0, "push", 1, {"peak_force_known": False}),
                         ContactLabel(4.0, 4.1, 0.0, "push", 1, {"peak_force_known": False})),
                 sample_rate=250.0, path="<switch>")
    e = run([ev("adaptive", 2.03)], lab, incidents=[inc(2.03, 2.08, 1, 9.0, "transient", (0,))])
    c = e.incidents.contacts[0]
    assert (c.force_label_n, c.force_rel_error, c.link_right) == (None, None, True)
    assert e.incidents.overall.force_rel_error_median is None
    a = e.scores["adaptive"]
    assert (a.detected, a.min_detected_force, a.max_missed_force) == (1, None, None)
    validate(e.to_dict(), "evaluation", LabelsError, "evaluation")
    assert "switch / 9 N" in format_evaluation(e)


def test_without_incidents_the_evaluation_says_so():
    lab, events, _ = answer_case()
    e = run(events, lab, incidents_note="arm.timeline.json is a 1.0 timeline: no incidents")
    d = e.to_dict()["incidents"]
    assert d["available"] is False and d["contacts"] == [] and d["link_accuracy"] is None
    assert d["summary"] == [["incidents", "arm.timeline.json is a 1.0 timeline: no incidents"]]
    assert "Incidents: arm.timeline.json is a 1.0 timeline" in format_evaluation(e)
    validate(e.to_dict(), "evaluation", LabelsError, "evaluation")


def test_a_link_among_the_candidates_is_said_so_not_wrong():
    """A new user's trial: an incident answered "link 2 or 3" for a push on link 3, and
    evaluate printed "3 / 2 WRONG". B's incident (link 2 for a push on link 1) now says it
    could not tell links 1 and 2 apart: the table reads "1 / 1 or 2 among", the summary
    counts it beside the right ones, and "link right" still judges its link."""
    lab, events, incs = answer_case()
    incs[2] = {**incs[2], "link_candidates": [1, 2]}
    e = run(events, lab, incidents=incs)
    ie = e.incidents
    rows = {c.label_index: c for c in ie.contacts}
    assert rows[1].link_right is False and rows[1].among and not rows[0].among
    assert ie.overall.link_right == 2  # unchanged: the incident's link is judged
    text = format_evaluation(e)
    assert "1 / 1 or 2 among" in text
    assert "2/3 (67%); 1 more among the links the incident could not tell apart" in text
    doc = e.to_dict()
    validate(doc, "evaluation", LabelsError, "evaluation")
    assert doc["incidents"]["contacts"][1]["link_candidates"] == [1, 2]
    assert "link_candidates" not in doc["incidents"]["contacts"][0]


def test_an_incident_at_a_data_defect_answers_no_contact():
    """A new user's trial: detect took a labelled 5 N push out of the count as an incident
    at a data defect, while evaluate matched it ("ok") and counted 14 incidents against
    detect's 12. The incident evaluation follows detect: B's incident, marked at a jump,
    answers no contact and is not counted; it is said apart."""
    lab, events, incs = answer_case()
    incs[2] = {**incs[2], "data_defect": {"kind": "jump", "t_start": 3.9, "t_end": 3.904}}
    e = run(events, lab, incidents=incs)
    ie = e.incidents
    assert (ie.overall.matched, ie.n_incidents, ie.n_data_defects) == (2, 3, 1)
    assert {c.label_index: c.incident_index for c in ie.contacts}[1] is None
    doc = e.to_dict()
    validate(doc, "evaluation", LabelsError, "evaluation")
    assert doc["incidents"]["n_data_defects"] == 1
    (row,) = [ln for ln in format_evaluation(e).splitlines() if "incidents after warm-up" in ln]
    assert "; besides them, not counted: " in row and row.endswith(
        "1 at a data defect (as detect does not: a contact there is missed)"), row


def test_the_alarm_of_a_payload_change_is_not_a_false_alarm():
    """The false incident at 9.5 s of answer_case, marked as a payload change's alarm (a
    load picked: detect neither counts nor gates it), is no false alarm of any detector
    and no counted incident; it is listed as such. The counts are otherwise the same."""
    lab, events, incs = answer_case()
    before = run(events, lab, incidents=incs)
    incs[4] = {**incs[4], "payload_change": 1}
    e = run(events, lab, incidents=incs)
    for d in ("adaptive", "product"):
        assert before.scores[d].false_alarms == 1
        assert e.scores[d].false_alarms == 0, d
        assert e.scores[d].payload_change_events == ((9.5, 9.55),)
        assert e.scores[d].detected == before.scores[d].detected
    ie = e.incidents
    assert (ie.n_incidents, ie.n_payload_changes, ie.unmatched) == (3, 1, ())
    doc = e.to_dict()
    validate(doc, "evaluation", LabelsError, "evaluation")
    assert doc["detectors"]["product"]["payload_change_events"] == [[9.5, 9.55]]
    assert "payload_change_events" not in before.to_dict()["detectors"]["product"]  # if any
    text = format_evaluation(e)
    assert "not false alarms: the alarms of payload changes" in text
    (row,) = [ln for ln in text.splitlines() if "incidents after warm-up" in ln]
    assert row.endswith("3 (each matches a labelled contact); besides them, not counted: 1 in "
                        "warm-up; 1 the alarm of a payload change"), row


def test_only_the_events_a_payload_change_holds_are_excused():
    """A payload change whose incident holds only its own loading event (9.0–9.9 s): the
    adaptive 9.5 s event inside that span but in no such incident is still a false alarm
    (membership, not time overlap); the loading event is the change's."""
    lab, events, incs = answer_case()
    events = [*events, ev("static_loading", 9.0, 9.9)]
    incs[4] = {**incs[4], "t_start": 9.0, "t_end": 9.9, "events": [6], "payload_change": 1}
    e = run(events, lab, incidents=incs)
    assert e.scores["adaptive"].false_alarms == 1
    assert e.scores["adaptive"].payload_change_events == ()
    assert e.scores["static_loading"].payload_change_events == ((9.0, 9.9),)
    assert e.scores["static_loading"].false_alarms == 0
    # the product alarm 9.0–9.9 holds the adaptive 9.5 s part too: not all the change's
    assert e.scores["product"].false_alarms == 1


def test_the_sweep_does_not_count_a_payload_changes_alarm():
    """sweep_result's false adaptive bump at 6.0 s, were it a payload change's alarm (onset
    5.95 s, classified 6.2 s), is no false alarm at any scale; the loading bump at 2.0 s
    still is."""
    scales = [1.0, 1.3, 1.6]
    plain = sweep_thresholds(sweep_result(), SWEEP_LABELS, scales)
    carried = sweep_thresholds(sweep_result(), SWEEP_LABELS, scales,
                               changes=[{"t_start": 5.95, "t_classified": 6.2}])
    fa = {(r.detector, r.scale): r.false_alarms for r in plain}
    fb = {(r.detector, r.scale): r.false_alarms for r in carried}
    assert (fa[("adaptive", 1.0)], fb[("adaptive", 1.0)]) == (1, 0)
    assert (fa[("adaptive", 1.3)], fb[("adaptive", 1.3)]) == (1, 0)
    assert fb[("static_loading", 1.0)] == fa[("static_loading", 1.0)] == 1
    assert fb[("product", 1.0)] == fa[("product", 1.0)] - 1
    assert {(r.detector, r.scale): r.detected for r in carried} == {
        (r.detector, r.scale): r.detected for r in plain}


def test_false_incidents_the_run_marked_as_a_resumed_load_are_said_apart():
    """Known truth: one contact at 2.0 s; incidents at 2.01 s (its), 5.0 s (false, marked
    as maybe a lasting load resumed) and 7.0 s (false, unmarked). The unmatched ones are
    the last two; the one marked is said apart, in the text and the JSON (the report's
    verdict says the same since the trial that read 8 incidents for 4 pushes)."""
    lab = labels(ContactLabel(2.0, 2.1, 5.0, "impact", 1))
    events = [ev("adaptive", 2.01), ev("adaptive", 5.0), ev("adaptive", 7.0)]
    resumed = {**inc(5.0, 5.05, 1, 4.0, "transient", (1,)),
               "resumes_load": {"t_start": 1.0, "t_end": 4.8, "gap_s": 0.2, "text": "x"}}
    e = run(events, lab, incidents=[inc(2.01, 2.06, 1, 5.0, "transient", (0,)), resumed,
                                    inc(7.0, 7.05, 1, 3.0, "transient", (2,))])
    ie = e.incidents
    assert ie.unmatched == (1, 2) and ie.unmatched_resuming == (1,)
    assert ie.to_dict()["unmatched_resuming_load"] == [1]
    assert dict(ie.summary())["incidents after warm-up"].startswith(
        "3 (2 matching no labelled contact, 1 of them just after a lasting load ended (maybe "
        "that load again))"), ie.summary()


def test_a_contact_held_only_by_payload_changes_alarms_is_said_taken_for_a_load() -> None:
    """A trial's 20 N clamp (8.08–13.1 s) on the heavy arm was weighed a +1.96 kg pick at
    9.806 s and a −1.84 kg release at 13.06 s: its alarms lie in the two changes' alarms,
    no counted incident. evaluate said "1 more held by an incident that began before the
    contact's window", "split over several incidents" and "in an earlier one". It now says
    it was taken for a payload change — missed as a contact, in no counted incident."""
    from impactcli.quality.incident_scores import evaluate_incidents
    from impactcli.quality.match import MatchTolerance, ScoredEvent
    from impactcli.types import ContactLabel

    evs = [ScoredEvent("static_loading", 9.806, 12.9, False, ("j1",)),
           ScoredEvent("static_loading", 13.06, 16.1, False, ("j1",)),
           ScoredEvent("static_loading", 12.95, 13.0, False, ("j1",))]
    load = {"link": 3, "force_n": None, "contact": "quasi_static", "payload_change": 1}
    incs = [dict(load, t_start=9.806, t_end=12.9, events=[0]),
            dict(load, t_start=13.06, t_end=16.1, events=[1, 2], payload_change=2)]
    clamp = ContactLabel(8.076, 13.096, 20.0, "clamp", 3)
    ev = evaluate_incidents(incs, evs, [clamp], ["counted"], MatchTolerance(), 3.0)
    (c,) = ev.contacts
    assert c.payload_change and c.incident_index is None and c.to_dict()["payload_change"]
    assert ev.split == () and ev.not_in_incident == (0,)
    rows = dict(ev.summary())
    assert rows["counted contacts matched by an incident"] == (
        "0/1 (0%); 1 taken for a payload change (labels #0: only payload changes' alarms, "
        "not counted, hold it — missed as a contact)")
    assert rows["every detected contact is exactly one incident"] == (
        "no (0/1); in no counted incident: labels #0")
    # the report's headline beside the product's hits (a trial's said "3/4 hit" only)
    from impactcli.outputs.report.common import incident_score, incident_score_text

    score = incident_score({"incidents": ev.to_dict()})
    assert score == {"as_incidents": 0, "taken_for_payload": 1}
    assert incident_score_text(score, 1) == (
        "; as incidents 0/1 (1 taken for a payload change, not counted)")
    # a counted incident among its holders: not taken for a load
    counted = [dict(incs[0]), dict(incs[1], payload_change=None)]
    (c,) = evaluate_incidents(counted, evs, [clamp], ["counted"], MatchTolerance(),
                              3.0).contacts
    assert not c.payload_change and "payload_change" not in c.to_dict()
