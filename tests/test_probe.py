"""The floor measured (impactcli.detect.probe): the state a probe starts from is the one
the log's own replay carries there; the amplitude it finds is what a whole-log replay with
that blow catches; half the blows of the median's size are caught at other moments; the
static-loading part is exact; the words say what was measured."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from impactcli.config import AdaptiveConfig
from impactcli.detect.adaptive import evaluate_chunk
from impactcli.detect.axes import AxisRunner, EvaluatorState
from impactcli.detect.floor import probed_line
from impactcli.detect.probe import (
    BISECTIONS,
    Probe,
    ProbeRecorder,
    half_sine,
    loading_response,
    probe_amplitudes,
    probe_indices,
    probe_window,
    probed_floor,
)
from impactcli.detect.static import causal_lowpass

from .helpers import motion_residual

FS = 250.0
LOADING = (2.0, 2)  # the static-loading low-pass (cutoff [Hz], order) of these tests
_FIELDS = ("theta", "P", "r_lags", "v_lags", "u_lags", "filters", "ring_r", "ring_v",
           "sums", "n_resets", "n_capped")


def _moving(seconds: float = 60.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(int(seconds * FS)) / FS
    pos = np.stack([0.8 * signal.sawtooth(2 * np.pi * t / p, 0.5) for p in (2.0, 2.6)], 1)
    return motion_residual(pos, FS, np.random.default_rng(seed))


def _thresholds(r: np.ndarray, u: np.ndarray, cfg: AdaptiveConfig) -> tuple[np.ndarray,
                                                                             np.ndarray]:
    """v_stat and vL just above what the free log reaches after 10 s (no alarm)."""
    base, _ = evaluate_chunk(EvaluatorState.initial(2, cfg, FS), r, u, FS, np.zeros(2), cfg)
    k = int(10 * FS)
    v_stat = 1.05 * np.max(base.r_rms[k:] - base.v_rms[k:], axis=0)
    v_l = 1.05 * np.max(np.abs(causal_lowpass(r, *LOADING[:1], FS, LOADING[1]))[k:], axis=0)
    return v_stat, v_l


def _probe(r: np.ndarray, u: np.ndarray, cfg: AdaptiveConfig, k: int, window: int) -> Probe:
    state = evaluate_chunk(EvaluatorState.initial(2, cfg, FS), r[:k], u[:, :k], FS,
                           np.zeros(2), cfg)[1]
    lp = causal_lowpass(r, LOADING[0], FS, LOADING[1])
    return Probe(k, lambda: state, [r[k:k + window]], [u[:, k:k + window]],
                 [lp[k:k + window]])


@pytest.mark.parametrize("threads", [1, 2])
def test_a_snapshot_is_the_state_a_replay_stopped_there_carries(threads: int) -> None:
    """Known truth: the evaluator run on the samples before k alone. The snapshot taken
    between two submitted chunks (queued behind the first on each axis's thread) holds the
    same bits, and the chunks' own results do not change."""
    cfg = AdaptiveConfig()
    r, u = _moving(20.0)
    k = 2345
    whole, _ = evaluate_chunk(EvaluatorState.initial(2, cfg, FS), r, u, FS, np.zeros(2), cfg)
    _, truth = evaluate_chunk(EvaluatorState.initial(2, cfg, FS), r[:k], u[:, :k], FS,
                              np.zeros(2), cfg)
    st = EvaluatorState.initial(2, cfg, FS)
    with AxisRunner(st, np.zeros(2), threads) as runner:
        a = runner.submit(np.ascontiguousarray(r[:k]), np.ascontiguousarray(u[:, :k]))
        snap = runner.snapshot()
        b = runner.submit(np.ascontiguousarray(r[k:]), np.ascontiguousarray(u[:, k:]))
        a.wait()
        b.wait()
    got = snap()
    assert got.n_samples == truth.n_samples == k
    for name in _FIELDS:
        assert np.array_equal(getattr(got, name), getattr(truth, name)), name
    rms = np.concatenate([a.out[4], b.out[4]])  # r_rms, in SIGNALS order
    assert np.array_equal(rms, whole.r_rms)


def test_the_recorder_holds_each_window_across_parts() -> None:
    """A probe's window that spans three parts is the log's rows from its sample on."""
    r = np.arange(40.0).reshape(20, 2)
    u = np.stack([r, -r])
    rec = ProbeRecorder([3, 9], 7)
    assert rec.cuts(0, 20) == [3, 9] and rec.cuts(3, 9) == []
    for a, b in ((0, 3), (3, 9), (9, 12), (12, 20)):
        rec.take(a, lambda: EvaluatorState.initial(2))
        rec.feed(a, r[a:b], u[:, a:b], 2 * r[a:b])
    assert [p.k for p in rec.done()] == [3, 9]
    for p in rec.done():
        assert np.array_equal(np.concatenate(p.r), r[p.k:p.k + 7])
        assert np.array_equal(np.concatenate(p.u, axis=1), u[:, p.k:p.k + 7])
        assert np.array_equal(np.concatenate(p.lp), 2 * r[p.k:p.k + 7])


def test_probes_spread_after_the_warm_up_and_fit_in_the_log() -> None:
    k = probe_indices(10_000, 1_000, 200, 32)
    assert k.size == 32 and k[0] >= 1_000 and k[-1] + 200 <= 10_000
    assert np.all(np.diff(k) > 200)
    assert probe_indices(1_300, 1_000, 200).size == 0  # no room after the warm-up
    few = probe_indices(2 * 58 + 100, 100, 58)  # a short log: fewer, a window apart
    assert few.size == 1


def test_the_amplitude_found_is_what_a_whole_log_replay_catches() -> None:
    """Known truth, by an independent run: the blow added to the whole log's residual at
    the probed sample and the log replayed from its first sample. At the amplitude the
    probe states the adaptive decision goes on in the window on that joint; one bisection
    step below it (the largest amplitude the probe saw missed), it stays off."""
    cfg = AdaptiveConfig()
    r, u = _moving()
    v_stat, v_l = _thresholds(r, u, cfg)
    base, _ = evaluate_chunk(EvaluatorState.initial(2, cfg, FS), r, u, FS, v_stat, cfg)
    rates = base.rates
    window = probe_window(FS, rates.n1, rates.a1)
    for k, sign in ((int(23.1 * FS), 1.0), (int(41.7 * FS), -1.0)):
        ans = probe_amplitudes(_probe(r, u, cfg, k, window), v_stat, v_l, FS, LOADING,
                               sign=sign)
        assert np.all(np.isfinite(ans.adaptive)) and not ans.adaptive_alarm.any()
        for j in range(2):
            for scale, caught in ((1.0, True), (2.0 ** (-1 / 2 ** BISECTIONS), False)):
                hit = r.copy()
                hit[k:k + window, j] += sign * scale * ans.adaptive[j] * half_sine(window, FS)
                res, _ = evaluate_chunk(EvaluatorState.initial(2, cfg, FS), hit, u, FS,
                                        v_stat, cfg)
                assert bool(res.decision[k:k + window, j].any()) is caught, (k, j, scale)
            assert ans.product[j] <= ans.adaptive[j]


def test_half_the_blows_of_the_median_are_caught_elsewhere_in_the_log() -> None:
    """Known truth by running it: blows at 48 moments the probes did not sample, on both
    joints, 5 s apart (the dynamic threshold settles between), replayed with the whole
    log: the adaptive detector alone (vL infinite). At half the probed median few are
    caught (16 probes sample the threshold's margin; a blow may fall where it is thinner),
    at the median some and not all, at twice the worst tenth all but a few."""
    cfg = AdaptiveConfig()
    r, u = _moving(130.0, seed=3)
    v_stat, _ = _thresholds(r, u, cfg)
    base, _ = evaluate_chunk(EvaluatorState.initial(2, cfg, FS), r, u, FS, v_stat, cfg)
    window = probe_window(FS, base.rates.n1, base.rates.a1)
    probes = [_probe(r, u, cfg, int(k), window)
              for k in probe_indices(r.shape[0], int(10 * FS), window, 16)]
    floor = probed_floor(probes, v_stat, np.full(2, np.inf), FS, LOADING, ("a", "b"))
    assert floor is not None
    rates = {}
    for j, name in enumerate(("a", "b")):
        row = floor["per_joint"][name]["adaptive"]
        for key, amp in (("half", 0.5 * row["median_nm"]), ("median", row["median_nm"]),
                         ("twice", 2.0 * row["worst_tenth_nm"])):
            caught = total = 0
            for offset in (12.3, 14.1, 15.7, 16.9):
                hit = r.copy()
                ks = [int(t * FS) for t in np.arange(offset, 125.0, 5.0)][:12]
                for i, k in enumerate(ks):
                    hit[k:k + window, j] += (-1) ** i * amp * half_sine(window, FS)
                res, _ = evaluate_chunk(EvaluatorState.initial(2, cfg, FS), hit, u, FS,
                                        v_stat, cfg)
                caught += sum(bool(res.decision[k:k + window, j].any()) for k in ks)
                total += len(ks)
            rates[(name, key)] = caught / total
    for name in ("a", "b"):
        assert rates[(name, "half")] <= 0.1, rates
        assert 0.15 <= rates[(name, "median")] <= 0.85, rates
        assert rates[(name, "twice")] >= 0.9, rates


def test_a_blow_adds_its_own_response_to_the_loading_statistic() -> None:
    """The static-loading part is exact: the low-pass is linear, so LP(r + A p) − LP(r)
    is A × the pulse's response from rest, wherever the blow falls."""
    r, _ = _moving(10.0)
    k, window, amp = 1234, 90, 3.7
    hit = r.copy()
    hit[k:k + window] += amp * half_sine(window, FS)[:, None]
    d = (causal_lowpass(hit, *LOADING[:1], FS, LOADING[1])
         - causal_lowpass(r, *LOADING[:1], FS, LOADING[1]))[k:k + window]
    h = loading_response(window, FS, *LOADING)
    assert np.allclose(d, amp * h[:, None], rtol=0, atol=1e-12)


def test_the_words_say_what_was_measured_and_what_was_not_judged() -> None:
    """The line says a median is where half the moments judged caught the blow, how many
    moments were judged of those probed, and what was not judged; a link ending on its
    joint's axis by its joint's torque."""
    row = {"median_n": 5.46, "worst_tenth_n": 7.33, "probes": 31, "in_alarm": 1,
           "uncaught": 0}
    floor = {"half_sine_s": 0.1, "probed": {
        "probes": 32, "window_s": 0.2,
        "per_joint": {"c": {"median_nm": 0.93, "worst_tenth_nm": 1.1, "probes": 32,
                            "in_alarm": 0, "uncaught": 0}},
        "per_link": [{"link": 1, "joint": "a", **row},
                     {"link": 2, "joint": "b", "median_n": None, "worst_tenth_n": None,
                      "probes": 30, "in_alarm": 2, "uncaught": 20},
                     {"link": 3, "joint": "c", "median_n": None, "worst_tenth_n": None,
                      "probes": 0, "in_alarm": 0, "uncaught": 0, "no_lever": True,
                      "own_joint": "c"}]}}
    line = probed_line(floor)
    assert line is not None
    assert line.startswith("a 100 ms blow was caught at half the moments judged from ~5.5 N "
                           "on link 1 (at nine in ten from ~7.3 N; 31 of 32 judged), ~0.93 "
                           "N·m on c (link 3 ends on its axis) (at nine in ten from ~1.1 N·m)"
                           " (N: a force at the link's end, normal to it; one nearer its "
                           "joint or aslant needs more); on link 2, no blow however large "
                           "was caught at 20 of 30 moments judged — 32 moments probed after "
                           "warm-up"), line
    assert "one where a detector was already alarming is not judged" in line
    per_joint = {"probes": 32, "window_s": 0.2, "per_link": None, "per_joint": {
        "a": {"median_nm": None, "worst_tenth_nm": None, "probes": 0, "in_alarm": 32,
              "uncaught": 0}}}
    assert probed_line({"half_sine_s": 0.1, "probed": per_joint}).startswith(  # type: ignore[union-attr]
        "on a, a detector was already alarming at 32 of 32 moments (none judged) — ")
    assert probed_line({"half_sine_s": 0.1}) is None
    # too few moments judged for a figure: none stated, and said (a new user read "nine
    # in ten" taken over 7 moments)
    from impactcli.detect.probe import _quantiles

    assert _quantiles(np.array([1.0, 2.0, 3.0, 4.0]), "_nm") == {
        "median_nm": None, "worst_tenth_nm": None}
    assert _quantiles(np.arange(1.0, 8.0), "_nm") == {"median_nm": 4.0,
                                                      "worst_tenth_nm": None}
    few = {"probes": 17, "window_s": 0.2, "per_link": None, "per_joint": {
        "a": {"median_nm": None, "worst_tenth_nm": None, "probes": 3, "in_alarm": 14,
              "uncaught": 0},
        "b": {"median_nm": 0.77, "worst_tenth_nm": None, "probes": 7, "in_alarm": 10,
              "uncaught": 0}}}
    line = probed_line({"half_sine_s": 0.1, "probed": few})
    assert line is not None and line.startswith(
        "a 100 ms blow was caught at half the moments judged from ~0.77 N·m on b (too few "
        "judged for nine in ten; 7 of 17 judged); on a, only 3 of 17 moments judged (a "
        "detector already alarming at the rest): too few for a figure — "), line
    # all of them judged, yet too few: no detector is said to have been alarming (a new
    # user read "only 3 of 3 moments judged (a detector already alarming at the rest)")
    all3 = {"probes": 3, "window_s": 0.2, "per_link": None, "per_joint": {
        "a": {"median_nm": None, "worst_tenth_nm": None, "probes": 3, "in_alarm": 0,
              "uncaught": 0}}}
    line = probed_line({"half_sine_s": 0.1, "probed": all3})
    assert line is not None and line.startswith(
        "on a, only 3 moments judged: too few for a figure — "), line
    # the same on every joint: said once, with why so few (a trial read six repeats of
    # it on the real UR log, 45 s with 3 moments the RLS's memory apart)
    b = dict(all3["per_joint"]["a"])
    line = probed_line({"half_sine_s": 0.1, "probed": {**all3, "per_joint": {
        "a": all3["per_joint"]["a"], "b": b}}})
    assert line is not None and line.startswith(
        "on every joint, only 3 moments judged: too few for a figure (the moments probed "
        "lie at least the adaptive filter's memory apart: a longer log gives more) — "), line
    one = {**all3, "probes": 1, "per_joint": {k: {**all3["per_joint"]["a"], "probes": 1}
                                              for k in ("a", "b")}}
    line = probed_line({"half_sine_s": 0.1, "probed": one})
    assert line is not None and line.startswith(
        "on every joint, only 1 moment judged: too few for a figure (the moments probed lie "
        "at least the adaptive filter's memory apart: a longer log gives more) — 1 moment "
        "probed after warm-up"), line
    busy2 = {**few, "per_joint": {k: {**few["per_joint"]["a"]} for k in ("a", "b")}}
    line = probed_line({"half_sine_s": 0.1, "probed": busy2})
    assert line is not None and line.startswith(
        "on every joint, only 3 of 17 moments judged (a detector already alarming at the "
        "rest): too few for a figure — "), line


def test_a_probe_is_caught_as_the_events_make_an_event() -> None:
    """With a least duration, a blow is caught where the events would make an event of the
    joint's decision (runs merged across the merge gap, lasting the least duration): the
    same answer as extract_events on random decisions."""
    from impactcli.detect.events import extract_events
    from impactcli.detect.probe import _caught

    rng = np.random.default_rng(5)
    t = np.arange(120) / 1000.0
    for _ in range(300):
        d = rng.random((120, 1)) < rng.uniform(0.02, 0.3)
        gap, least = float(rng.choice([0.0, 0.002, 0.005])), float(rng.choice([0.003, 0.008]))
        ev = extract_events("adaptive", d, d.astype(float), d.astype(float), t, ("a",), 0.0,
                            gap, least)
        assert bool(_caught(d, 1000.0, (gap, least))[0]) is bool(ev), (gap, least)


def test_a_joint_no_adaptive_threshold_checks_is_judged_by_the_loading_one() -> None:
    """A joint with an infinite v_stat has no adaptive figure and is not "in alarm": its
    blows are judged by the static-loading detector alone."""
    cfg = AdaptiveConfig()
    r, u = _moving()
    v_stat, v_l = _thresholds(r, u, cfg)
    base, _ = evaluate_chunk(EvaluatorState.initial(2, cfg, FS), r, u, FS, v_stat, cfg)
    window = probe_window(FS, base.rates.n1, base.rates.a1)
    ans = probe_amplitudes(_probe(r, u, cfg, int(30 * FS), window),
                           np.array([v_stat[0], np.inf]), v_l, FS, LOADING)
    assert np.isfinite(ans.adaptive[0]) and np.isnan(ans.adaptive[1])
    assert not ans.product_alarm.any() and not ans.adaptive_alarm.any()
    assert np.isfinite(ans.product[1]) and ans.product[1] > 0
