"""The sample clock and the gap rule chunk by chunk (impactcli.clock): the step histogram
of consecutive chunks gives the whole log's clock to the bit, and chunked gap finding the
whole log's gaps, whatever the chunking."""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Iterator

import numpy as np
import pytest

from impactcli.clock import (
    TAIL_STAMPS,
    GapStream,
    SampleClock,
    StepHistogram,
    chunk_gap_steps,
    clock_from_histogram,
    gap_steps,
    sample_clock,
    step_histogram,
)

MS = 1_000_000


def _series() -> dict[str, np.ndarray]:
    """Stamp series [ns] with the timing faults of real logs."""
    rng = np.random.default_rng(7)
    n = 6000
    grid = np.arange(n, dtype=np.int64) * MS
    jitter = np.sort(grid + rng.normal(0, 0.12 * MS, n).astype(np.int64))
    repeated = grid.copy()
    rep = np.flatnonzero(rng.random(n) < 0.05)
    repeated[rep[rep > 0]] = repeated[rep[rep > 0] - 1]
    dropped = grid[~(rng.random(n) < 0.06)]
    dropped = np.concatenate([dropped[:2000], dropped[2000:] + 50 * MS])
    late = grid.copy()
    k = np.flatnonzero(rng.random(n) < 0.04)
    k = k[k < n - 1]
    late[k] = late[k + 1] - 20_000
    late[[300, 301]] = late[[300, 301]] + 7 * MS  # a hole given back, then a real gap
    late[4000:] += 9 * MS
    holes = np.delete(grid, [1, 2, 500, 2999, 3000, n - 3, n - 2])
    holes[10:] += 40 * MS
    ragged = np.cumsum(rng.choice([999_000, 1_000_000, 1_001_000, 2_000_000, 30_000_000],
                                  size=n, p=[0.3, 0.4, 0.25, 0.04, 0.01]))
    return {"jitter": jitter, "repeated": repeated, "dropped": dropped, "late": late,
            "holes": holes, "ragged": ragged, "short": grid[:3], "two": grid[:2],
            "same": np.array([5, 5, 5], dtype=np.int64)}


def _chunkings(n: int, seed: int) -> Iterator[tuple[str, list[int]]]:
    """Chunk boundaries: fixed sizes and random ones."""
    for size in (1, 2, 7, 1000):
        yield f"{size}", [*range(0, n, size), n]
    rng = np.random.default_rng(seed)
    cuts = np.unique(rng.integers(1, max(n, 2), size=max(1, n // 50)))
    yield "random", [0, *[int(c) for c in cuts if 0 < c < n], n]


def _same_clock(a: SampleClock, b: SampleClock) -> bool:
    def eq(x: float, y: float) -> bool:
        return x == y or (math.isnan(x) and math.isnan(y))

    return all(eq(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))


@pytest.mark.parametrize("name", list(_series()))
def test_chunked_clock_and_gaps_are_the_whole_logs(name: str) -> None:
    t = _series()[name]
    whole = sample_clock(t)
    gaps = gap_steps(t, whole)
    for label, bounds in _chunkings(t.size, len(name)):
        hist = StepHistogram()
        for a, b in itertools.pairwise(bounds):
            hist.add(t[a:b])
        assert hist.n_stamps == t.size
        assert _same_clock(hist.clock(), whole), (name, label)
        # the clock known: decide chunk by chunk with the carried tail
        idx, lengths = [], []
        for a, b in itertools.pairwise(bounds):
            i, ln = chunk_gap_steps(t[a:b], a, t[max(0, a - TAIL_STAMPS):a], whole,
                                    last=b == t.size)
            idx.append(i)
            lengths.append(ln)
        assert np.array_equal(np.concatenate(idx), gaps[0]), (name, label)
        assert np.array_equal(np.concatenate(lengths), gaps[1]), (name, label)
        # the clock not known yet: candidates above a floor below the threshold
        stream = GapStream()
        for a, b in itertools.pairwise(bounds):
            floor = 0.9 * whole.gap_threshold_s * 1e9 if whole.period_s > 0 else 0.0
            stream.add(t[a:b], floor, last=b == t.size)
        assert stream.exact_for(whole)
        got = stream.gaps(whole)
        assert np.array_equal(got[0], gaps[0]) and np.array_equal(got[1], gaps[1]), label


def test_a_final_empty_chunk_closes_the_stream() -> None:
    t = _series()["holes"]
    c = sample_clock(t)
    stream = GapStream()
    for a in range(0, t.size, 333):
        stream.add(t[a:a + 333], 0.0)
    stream.add(t[:0], 0.0, last=True)
    assert np.array_equal(stream.gaps(c)[0], gap_steps(t, c)[0])
    i, _ = chunk_gap_steps(t[:0], t.size, t[-TAIL_STAMPS:], c, last=True)
    j, _ = chunk_gap_steps(t[-1:], t.size - 1, t[-1 - TAIL_STAMPS:-1], c, last=True)
    whole = gap_steps(t, c)[0]
    assert set(i.tolist()) | set(j.tolist()) <= set(whole.tolist())


def test_histogram_counts_are_exact() -> None:
    rng = np.random.default_rng(3)
    # a dense window and far outliers (gaps, negative steps)
    s = np.concatenate([rng.integers(990_000, 1_010_000, 50_000),
                        rng.integers(-10**15, 10**15, 300), [0, 0, 2**62, -(2**62)]])
    v, c = step_histogram(s)
    u, k = np.unique(s, return_counts=True)
    assert np.array_equal(v, u) and np.array_equal(c, k)
    assert clock_from_histogram(v, c).n_repeated == 2


def _old_clock(t: np.ndarray) -> tuple[float, float, float]:
    """The estimator before the histogram (floating sums over every step): period,
    jitter and envelope [ns]."""
    steps = np.diff(t).astype(np.float64)
    steps = steps[steps != 0]
    p = float(np.median(steps))
    for _ in range(50):
        one = np.abs(steps - p) < 0.5 * p
        new = float(np.sum(steps, where=one)) / int(np.count_nonzero(one))
        if abs(new - p) <= 1e-9 * p:
            p = new
            break
        p = new
    dev = steps - p
    jitter = 1.4826 * float(np.median(np.abs(dev - np.median(dev))))
    return p, jitter, float(np.quantile(np.abs(dev), 0.95))


@pytest.mark.parametrize("name", ["jitter", "repeated", "dropped", "late", "ragged"])
def test_the_estimates_are_the_float_estimators_to_rounding(name: str) -> None:
    t = _series()[name]
    c = sample_clock(t)
    p, jitter, envelope = _old_clock(t)
    assert c.period_s * 1e9 == pytest.approx(p, rel=1e-12)
    assert c.jitter_s * 1e9 == pytest.approx(jitter, rel=1e-9, abs=1e-6)
    assert c.envelope_s * 1e9 == pytest.approx(envelope, rel=1e-9, abs=1e-6)
