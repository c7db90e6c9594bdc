"""The calibration's motion envelope (impactcli.detect.envelope) against known motion:
sinusoids whose velocity and acceleration ranges are known in closed form, chunk splits
that must not change a bit, a check that finds exactly the faster stretch, and the slow
clock against piecewise-constant velocities whose slow time is known."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from impactcli.detect.envelope import (
    HELD_RAD_S,
    SLOW_RAD_S,
    EnvelopeAccumulator,
    EnvelopeCheck,
    Motion,
    MotionEnvelope,
    MotionTrace,
    outside_share_text,
    slow_text,
)

FS = 500.0


def sine(amp: float, hz: float, seconds: float, phase: float = 0.0) -> tuple[np.ndarray,
                                                                             np.ndarray]:
    t = np.arange(round(seconds * FS)) / FS
    return t, amp * np.sin(2 * math.pi * hz * t + phase)


def trace_in_chunks(t: np.ndarray, q: np.ndarray, cuts: list[int], ref: bool = True
                    ) -> tuple[np.ndarray, np.ndarray]:
    tr = MotionTrace(FS)
    parts = [tr.update(t[a:b], q[a:b] * 0.0 if ref else q[a:b], q[a:b] if ref else None)
             for a, b in zip([0, *cuts], [*cuts, t.size], strict=True)]
    assert tr.source == ("position_ref" if ref else "position")
    return (np.concatenate([p.velocity for p in parts]),
            np.concatenate([p.acceleration for p in parts]))


def test_motion_is_the_same_bit_for_bit_whatever_the_chunks() -> None:
    t, q1 = sine(0.5, 0.7, 20.0)
    q = np.stack([q1, 0.3 * q1 ** 2], axis=1)
    whole = trace_in_chunks(t, q, [])
    rng = np.random.default_rng(3)
    cuts = sorted(rng.choice(np.arange(1, t.size), 7, replace=False).tolist())
    for a, b in zip(whole, trace_in_chunks(t, q, cuts), strict=True):
        assert np.array_equal(a, b)
    # the reference is preferred; without one the measured position is used
    v_meas, _ = trace_in_chunks(t, q, cuts, ref=False)
    assert np.array_equal(v_meas, whole[0])


def test_ranges_of_a_sinusoid_are_its_amplitude_times_omega() -> None:
    amp, hz = 0.4, 0.5  # 0.5 Hz, far below the 10 Hz low-pass: gain ≈ 1
    t, q = sine(amp, hz, 30.0)
    tr = MotionTrace(FS)
    m = tr.update(t, q[:, None], q[:, None])
    acc = EnvelopeAccumulator(["j"], tr.source or "")
    keep = t >= 5.0  # the filters' start left out, as calibrate leaves out warm-up
    acc.add(m, keep)
    env = acc.finish()
    assert env is not None and env.samples == int(keep.sum()) and env.source == "position_ref"
    w = 2 * math.pi * hz
    lo, hi = env.joints["j"]["velocity"]
    assert lo == pytest.approx(-amp * w, rel=2e-3) and hi == pytest.approx(amp * w, rel=2e-3)
    lo, hi = env.joints["j"]["acceleration"]
    assert lo == pytest.approx(-amp * w * w, rel=5e-3) and hi == pytest.approx(amp * w * w,
                                                                                rel=5e-3)
    lo, hi = env.joints["j"]["position"]
    assert lo == pytest.approx(-amp, rel=1e-3) and hi == pytest.approx(amp, rel=1e-3)
    assert EnvelopeAccumulator(["j"]).finish() is None  # nothing kept: no envelope


def test_envelope_round_trips_through_its_mapping() -> None:
    env = MotionEnvelope({"a": {"velocity": (-1.0, 2.0), "acceleration": (-3.0, 4.0),
                                "position": (-0.5, 0.25)}}, "position", 1234, 10.0)
    d = env.to_dict()
    assert d == {"source": "position", "samples": 1234, "cutoff_hz": 10.0,
                 "joints": {"a": {"velocity": [-1.0, 2.0], "acceleration": [-3.0, 4.0],
                                  "position": [-0.5, 0.25]}}}
    assert MotionEnvelope.from_dict(d) == env
    assert "velocity -1 … 2 rad/s" in env.lines()[0]


def envelope_of(t: np.ndarray, q: np.ndarray, start_s: float = 5.0) -> MotionEnvelope:
    tr = MotionTrace(FS)
    acc = EnvelopeAccumulator(["j1", "j2"], "position_ref")
    acc.add(tr.update(t, q, q), t >= start_s)
    env = acc.finish()
    assert env is not None
    return env


def test_check_finds_the_faster_stretch_and_nothing_else() -> None:
    t, a = sine(0.4, 0.5, 40.0)
    q = np.stack([a, 0.5 * a], axis=1)
    env = envelope_of(t, q)
    # the same motion stays inside (after the filters' start)
    same = EnvelopeCheck(env, FS, ["j1", "j2"])
    same.update_arrays(t, q, q)
    res = same.finish(round(5.0 * FS))
    assert res.outside == 0 and res.share == 0.0 and res.stretches.shape == (0, 2)
    # 20–24 s: joint 2 moves at twice the frequency (4× the acceleration)
    _, fast = sine(0.25, 1.0, 40.0)
    q2 = q.copy()
    inside = (t >= 20.0) & (t < 24.0)
    q2[inside, 1] = fast[inside]
    chk = EnvelopeCheck(env, FS, ["j1", "j2", "j3"])
    q3 = np.c_[q2, np.zeros(t.size)]  # a third joint the envelope lacks
    masks = [chk.update_arrays(t[i:i + 777], q3[i:i + 777], q3[i:i + 777], start=i)
             for i in range(0, t.size, 777)]  # in chunks
    mask = np.concatenate(masks)
    out = chk.finish(round(5.0 * FS))
    assert out.unchecked == ("j3",)
    assert mask[(t < 19.9) & (t > 5.0)].sum() == 0 and mask[(t > 24.5)].sum() == 0
    assert mask[inside].mean() > 0.5
    assert out.outside == int(mask[round(5.0 * FS):].sum())
    assert out.per_joint["j1"] == 0.0
    assert out.per_joint["j2"] == pytest.approx(out.share)
    assert out.stretches[0, 0] >= 19.9 and out.stretches[-1, 1] <= 24.5
    end = float(out.stretches[-1, 1])
    assert out.touches(end + 0.15, end + 1.0) and not out.touches(end + 0.25, end + 1.0)
    assert not out.touches(10.0, 12.0)
    assert "moved outside the calibration's motion envelope" in outside_share_text(out)
    # samples before ``start`` are not counted
    late = EnvelopeCheck(env, FS, ["j1", "j2"])
    late.update_arrays(t, q2, q2)
    after = late.finish(round(22.0 * FS))
    assert 0 < after.outside < out.outside and after.samples == t.size - round(22.0 * FS)


def test_margin_widens_the_ranges() -> None:
    t, a = sine(0.4, 0.5, 30.0)
    q = np.stack([a, a], axis=1)
    env = envelope_of(t, q)
    q2 = 1.05 * q  # 5 % more velocity and acceleration
    shares = []
    for margin in (0.0, 0.1):
        chk = EnvelopeCheck(env, FS, ["j1", "j2"], margin=margin)
        chk.update_arrays(t, q2, q2)
        shares.append(chk.finish(round(5.0 * FS)).share)
    assert shares[0] > 0.05 and shares[1] == 0.0


def test_a_log_without_reference_is_compared_across_sources() -> None:
    t, a = sine(0.4, 0.5, 30.0)
    q = np.stack([a, a], axis=1)
    chk = EnvelopeCheck(envelope_of(t, q), FS, ["j1", "j2"])
    chk.update_arrays(t, q, None)
    res = chk.finish(round(5.0 * FS))
    assert res.source == "position" and "across sources" in res.note


def ramps(pieces: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Times and a position whose velocity is ``v`` [rad/s] for ``s`` seconds per piece."""
    v = np.concatenate([np.full(round(sec * FS), vel) for sec, vel in pieces])
    t = np.arange(v.size) / FS
    return t, np.cumsum(v) / FS


#: 0–5 s fast; 5–7 s slow (2 s); 7–10 s at rest (not counted, not ending it); 10–11 s slow
#: (3 s in all); 11–15 s fast (reset); 15–15.5 s slow; 15.5–20 s fast.
PIECES = [(5.0, 0.5), (2.0, 0.01), (3.0, 0.0), (1.0, -0.01), (4.0, 0.5), (0.5, 0.01),
          (4.5, 0.5)]


def test_slow_clock_counts_slow_time_pauses_at_rest_and_resets_when_fast() -> None:
    assert HELD_RAD_S < 0.01 < SLOW_RAD_S < 0.5
    t, q = ramps(PIECES)
    clock = MotionTrace(FS).update(t, q[:, None], q[:, None]).slow[:, 0]
    at = {s: clock[round(s * FS) - 1] for s in (7.0, 7.5, 10.0, 11.0, 14.0, 15.5, 20.0)}
    lag = 0.15  # the 10 Hz low-pass takes ~0.1 s to bring 0.5 rad/s under SLOW_RAD_S
    assert at[7.0] == pytest.approx(2.0, abs=lag)
    assert at[10.0] == at[7.5] > at[7.0]  # at rest (once the filter has settled): paused
    assert at[11.0] == pytest.approx(3.0, abs=lag)
    assert at[14.0] == 0.0  # fast again: reset
    assert at[15.5] == pytest.approx(0.5, abs=lag)
    assert at[20.0] == 0.0 and clock.max() == pytest.approx(3.0, abs=lag)
    # whatever the chunks, bit for bit
    rng = np.random.default_rng(5)
    cuts = sorted(rng.choice(np.arange(1, t.size), 9, replace=False).tolist())
    tr = MotionTrace(FS)
    parts = [tr.update(t[a:b], q[a:b, None], q[a:b, None]).slow[:, 0]
             for a, b in zip([0, *cuts], [*cuts, t.size], strict=True)]
    assert np.array_equal(np.concatenate(parts), clock)


def test_a_gap_adds_at_most_two_sample_periods() -> None:
    t, q = ramps([(2.0, 0.5), (2.0, 0.01)])
    t = t.copy()
    t[round(3.0 * FS):] += 60.0  # a minute missing inside the slow stretch
    clock = MotionTrace(FS).update(t, q[:, None], q[:, None]).slow[:, 0]
    assert clock[-1] == pytest.approx(2.0, abs=0.15)


def test_envelope_records_the_longest_slow_stretch_after_warm_up_and_check_flags_longer(
        ) -> None:
    t, q = ramps(PIECES)
    tr = MotionTrace(FS)
    acc = EnvelopeAccumulator(["j"], "position_ref")
    acc.add(tr.update(t, q[:, None], q[:, None]), t >= 1.0, round(1.0 * FS))
    env = acc.finish()
    dwell = env.slow_dwell_s["j"] if env is not None else 0.0
    assert env is not None and dwell == pytest.approx(3.0, abs=0.15)
    assert f"slower than 0.02 rad/s for at most {dwell:.3g} s at a stretch" in env.lines()[0]
    assert MotionEnvelope.from_dict(env.to_dict()) == env
    # only samples after ``from_index`` count: a slow stretch that ends before it is not
    acc2 = EnvelopeAccumulator(["j"], "position_ref")
    acc2.add(MotionTrace(FS).update(t, q[:, None], q[:, None]), None, round(12.0 * FS))
    env2 = acc2.finish()
    assert env2 is not None and env2.slow_dwell_s["j"] == pytest.approx(0.5, abs=0.15)
    # the same motion is inside; a slow stretch of 5 s is outside for its last 2 s
    same = EnvelopeCheck(env, FS, ["j"])
    same.update_arrays(t, q[:, None], q[:, None])
    assert same.finish(round(1.0 * FS)).outside == 0
    t2, q2 = ramps([(5.0, 0.5), (5.0, 0.01), (5.0, 0.5)])  # steps the calibration had
    chk = EnvelopeCheck(env, FS, ["j"])
    chk.update_arrays(t2, q2[:, None], q2[:, None])
    out = chk.finish(round(1.0 * FS))
    assert out.outside / FS == pytest.approx(2.0, abs=0.1)
    assert out.slow == {"j": pytest.approx(out.share)}
    assert out.slow_dwell_s == {"j": env.slow_dwell_s["j"]}
    assert out.stretches.shape == (1, 2)
    assert out.stretches[0, 0] == pytest.approx(5.0 + 0.1 + dwell, abs=0.1)
    assert out.stretches[0, 1] == pytest.approx(10.0, abs=0.1)
    assert out.touches(8.5, 9.0) and not out.touches(5.0, 7.5)
    text = outside_share_text(out)
    assert slow_text(out.slow, out.slow_dwell_s) in text
    assert "velocity or acceleration beyond" not in text  # the ranges held
    assert outside_share_text(out.to_dict()) == text
    # faster than calibrated, then slow for longer: each reason with its own share
    t3, q3 = ramps([(5.0, 0.9), (5.0, 0.01), (5.0, 0.5)])
    mixed = EnvelopeCheck(env, FS, ["j"])
    mixed.update_arrays(t3, q3[:, None], q3[:, None])
    both = mixed.finish(round(1.0 * FS))
    assert both.ranges["j"] > 0.1 and both.slow["j"] > 0.05
    assert both.per_joint["j"] == pytest.approx(both.ranges["j"] + both.slow["j"], abs=0.02)
    said = outside_share_text(both)
    assert f"beyond the ranges calibrated on: j {100 * both.ranges['j']:.3g} %" in said
    assert slow_text(both.slow, both.slow_dwell_s) in said
    # a config written before the slow clock was recorded: slow motion is not checked
    old = MotionEnvelope(env.joints, env.source, env.samples, env.cutoff_hz)
    assert "slow_dwell_s" not in old.to_dict()
    chk_old = EnvelopeCheck(old, FS, ["j"])
    chk_old.update_arrays(t2, q2[:, None], q2[:, None])
    assert chk_old.finish(round(1.0 * FS)).outside == 0


def test_slow_stretches_are_read_on_the_reference_only() -> None:
    """A measured position's noise at rest reads as slow motion through the low-pass, so
    neither an envelope of measured motion records slow stretches nor a log without a
    reference is checked for them (its ranges still are)."""
    t, q = ramps(PIECES)
    measured = EnvelopeAccumulator(["j"], "position")
    measured.add(MotionTrace(FS).update(t, q[:, None], None), None, round(1.0 * FS))
    got = measured.finish()
    assert got is not None and got.slow_dwell_s == {} and "slow_dwell_s" not in got.to_dict()
    acc = EnvelopeAccumulator(["j"], "position_ref")
    acc.add(MotionTrace(FS).update(t, q[:, None], q[:, None]), None, round(1.0 * FS))
    env = acc.finish()
    assert env is not None and env.slow_dwell_s
    t2, q2 = ramps([(5.0, 0.5), (5.0, 0.01), (5.0, 0.5)])
    for ref, outside in ((q2[:, None], True), (None, False)):
        chk = EnvelopeCheck(env, FS, ["j"])
        chk.update_arrays(t2, q2[:, None], ref)
        res = chk.finish(round(1.0 * FS))
        assert bool(res.slow) is outside and (res.outside > 0) is outside
        assert ("slow stretches not checked: this log has no reference" in res.note) is (
            not outside)


def ringing(t: np.ndarray, t0: float, amp: float, hz: float, tau: float) -> np.ndarray:
    """A decaying oscillation from ``t0``: amp·e^(−(t−t0)/τ)·sin(2πf(t−t0)), 0 before."""
    s = np.clip(t - t0, 0.0, None)
    return np.where(t >= t0, amp * np.exp(-s / tau) * np.sin(2 * math.pi * hz * s), 0.0)


def test_the_measured_motion_is_traced_beside_the_reference_bit_for_bit() -> None:
    """With a reference, the measured position goes through the same low-pass and
    differences: equal, bit for bit, to the motion a log without a reference gives, and
    the same whatever the chunks; without a reference it is not traced (it is the motion)."""
    t, a = sine(0.4, 0.5, 20.0)
    ref = np.stack([a, 0.5 * a], axis=1)
    meas = ref + np.stack([ringing(t, 8.0, 0.05, 2.0, 0.8), np.zeros(t.size)], axis=1)
    whole = MotionTrace(FS).update(t, meas, ref)
    alone = MotionTrace(FS).update(t, meas, None)
    assert whole.measured_velocity is not None and whole.measured_acceleration is not None
    assert np.array_equal(whole.measured_velocity, alone.velocity)
    assert np.array_equal(whole.measured_acceleration, alone.acceleration)
    assert alone.measured_velocity is None and alone.measured_acceleration is None
    tr = MotionTrace(FS)
    cuts = [0, 1, 777, 4000, 4001, t.size]
    parts = [tr.update(t[i:j], meas[i:j], ref[i:j]) for i, j in itertools.pairwise(cuts)]
    joined = Motion.joined(parts)
    for k in ("velocity", "acceleration", "measured_velocity", "measured_acceleration"):
        assert np.array_equal(joined.get(k), whole.get(k)), k


def test_the_measured_ranges_are_recorded_and_their_stretches_kept_apart() -> None:
    """The calibration records the measured motion's ranges beside the reference's; a log
    whose arm rings under the same calm reference stays inside the envelope (share 0) while
    its measured stretches date the ringing, each with its farthest sample — the same
    whatever the chunks."""
    t, a = sine(0.4, 0.5, 40.0)
    ref = np.stack([a, 0.5 * a], axis=1)
    tr = MotionTrace(FS)
    acc = EnvelopeAccumulator(["j1", "j2"], "position_ref")
    acc.add(tr.update(t, ref, ref), t >= 5.0)
    env = acc.finish()
    assert env is not None
    w = 2 * math.pi * 0.5
    lo, hi = env.joints["j1"]["measured_acceleration"]
    assert hi == pytest.approx(0.4 * w * w, rel=5e-3) and lo == pytest.approx(-hi, rel=5e-3)
    assert MotionEnvelope.from_dict(env.to_dict()) == env
    assert "measured acceleration" in env.lines()[0]
    # 2 Hz ringing of 0.05 rad on j1 from 20 s: its acceleration (2π·2)²·0.05 ≈ 7.9 rad/s²
    # against 0.99 calibrated, decaying below it after ~2 s (τ = 1 s)
    meas = ref + np.stack([ringing(t, 20.0, 0.05, 2.0, 1.0), np.zeros(t.size)], axis=1)
    found = []
    for step in (t.size, 997):
        chk = EnvelopeCheck(env, FS, ["j1", "j2"])
        for i in range(0, t.size, step):
            chk.update_arrays(t[i:i + step], meas[i:i + step], ref[i:i + step], start=i)
        found.append(chk.finish(round(5.0 * FS)))
    res = found[0]
    assert res.outside == 0 and res.share == 0.0  # the reference stayed inside
    assert res.measured == found[1].measured
    # over the whole log: the filters' start (in any warm-up) aside, only the ringing
    ring = [m for m in res.measured if m.t_end > 1.0]
    assert ring and all(m.t_start < 1.0 for m in res.measured if m not in ring)
    first, last = ring[0], ring[-1]
    assert 20.0 <= first.t_start < 20.2 and last.t_end < 24.0
    assert all(m.joint == "j1" for m in ring)
    far = max(ring, key=lambda m: m.score)
    assert far.quantity == "measured_acceleration"
    # the ringing's peak (2π·2)²·0.05 = 7.9 rad/s², and its onset's velocity step through
    # the low-pass: within twice that
    peak = (2 * math.pi * 2.0) ** 2 * 0.05
    assert 0.9 * peak < abs(far.value) < 2.0 * peak and far.hi == pytest.approx(hi)
    assert res.to_dict()["measured_stretches"][len(res.measured) - len(ring)] == first.to_dict()
    # a log without a reference: not checked (None), said by the mapping's absence
    chk = EnvelopeCheck(env, FS, ["j1", "j2"])
    chk.update_arrays(t, meas, None)
    none = chk.finish(round(5.0 * FS))
    assert none.measured is None and "measured_stretches" not in none.to_dict()


def test_a_joint_without_measured_ranges_is_said_unchecked() -> None:
    """A config whose envelope lacks one joint's measured ranges (edited out) checks the
    others' and says which joint it could not."""
    t, a = sine(0.4, 0.5, 20.0)
    q = np.stack([a, 0.5 * a], axis=1)
    env = envelope_of(t, q)
    joints = {j: dict(r) for j, r in env.joints.items()}
    for k in ("measured_velocity", "measured_acceleration"):
        del joints["j2"][k]
    chk = EnvelopeCheck(MotionEnvelope(joints, env.source, env.samples), FS, ["j1", "j2"])
    chk.update_arrays(t, q, q)
    res = chk.finish(round(5.0 * FS))
    assert res.measured is not None  # j1's checked
    assert "measured motion not checked on j2" in res.note
    full = EnvelopeCheck(env, FS, ["j1", "j2"])
    full.update_arrays(t, q, q)
    assert "measured motion" not in full.finish(round(5.0 * FS)).note


def test_the_trace_dates_a_reversal_at_most_its_lag_late_and_touches_allows_for_it() -> None:
    """Known truth: a triangle reference reverses at 10 s (its acceleration an impulse
    there). The trace's acceleration first passes half its peak within ``lag_s`` after
    10 s — later than the reversal, which the residual feels at once (a trial's 12 false
    alarms on a heavy arm ended 8 ms before their outside stretch began and were said to
    touch no outside motion). An incident ending at the reversal touches the stretch the
    trace reports; one ending more than ``lag_s`` before that stretch does not."""
    t = np.arange(round(20.0 * FS)) / FS
    q = np.where(t < 10.0, 0.5 * t, 10.0 - 0.5 * t)[:, None]
    tr = MotionTrace(FS)
    acc = np.abs(tr.update(t, q, q).acceleration[:, 0])
    first = float(t[np.flatnonzero(acc >= 0.5 * acc.max())[0]])
    assert 10.0 < first <= 10.0 + tr.lag_s
    # the envelope of the slow ramps, against the reversal: outside from about `first`
    calm = np.zeros_like(t) + 0.5 * t
    env = envelope_of(t, np.c_[calm, calm])
    chk = EnvelopeCheck(env, FS, ["j1"])
    chk.update_arrays(t, q, q)
    out = chk.finish(round(5.0 * FS))
    start = float(out.stretches[0, 0])
    assert 10.0 < start <= 10.0 + tr.lag_s and out.lag_s == tr.lag_s
    assert out.touches(9.99, 10.0)                     # ended at the reversal itself
    assert not out.touches(9.0, start - tr.lag_s - 0.01)
