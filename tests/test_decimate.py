"""The display decimation: min/max envelope per bucket, event windows at full rate."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.outputs.decimate import (
    DEFAULT_MAX_POINTS,
    EnvelopeStream,
    bucket_size,
    envelope_indices,
    select_samples,
    window_mask,
)


def _walk(n: int, k: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.standard_normal((n, k)), axis=0)


def test_short_series_are_kept_whole() -> None:
    v = _walk(1000, 2)
    assert bucket_size(1000, 2, max_points=1000) == 1
    np.testing.assert_array_equal(select_samples(v, max_points=1000), np.arange(1000))
    assert bucket_size(DEFAULT_MAX_POINTS, 1) == 1
    assert bucket_size(DEFAULT_MAX_POINTS + 1, 1) > 1


@pytest.mark.parametrize(("n", "bucket"), [(10_000, 7), (10_001, 50), (999, 1000)])
def test_envelope_keeps_every_bucket_min_and_max(n: int, bucket: int) -> None:
    v = _walk(n, 3, seed=n)
    rng = np.random.default_rng(1)
    keep = np.zeros(n, dtype=bool)
    keep[rng.integers(0, n, 5)] = True
    idx = envelope_indices(v, bucket, keep)
    assert np.all(np.diff(idx) > 0) and idx[0] == 0 and idx[-1] == n - 1
    sel = np.zeros(n, dtype=bool)
    sel[idx] = True
    for b0 in range(0, n, bucket):
        block = slice(b0, min(b0 + bucket, n))
        chosen = v[block][sel[block]]
        np.testing.assert_array_equal(chosen.max(axis=0), v[block].max(axis=0))
        np.testing.assert_array_equal(chosen.min(axis=0), v[block].min(axis=0))
    # at most 2 samples per series per bucket, plus kept samples and the two ends
    assert idx.size <= 2 * 3 * -(-n // bucket) + keep.sum() + 2


def test_one_sample_spike_survives_where_subsampling_loses_it() -> None:
    n = 1_000_003
    v = np.sin(np.arange(n) * 1e-3)
    spike = 123_457
    v[spike] = 50.0
    v[spike + 1000] = -50.0
    idx = select_samples(v, max_points=10_000)
    assert idx.size <= 10_000 + 2
    assert spike in idx and spike + 1000 in idx
    step = n // 10_000
    assert v[::step].max() < 2  # plain subsampling would hide the spike


def test_event_windows_are_full_rate() -> None:
    dt = 1_000_000  # 1 kHz
    t = np.arange(400_000, dtype=np.int64) * dt + 5 * 10**18
    events = [(t[100_000], t[100_050]), (t[300_000], t[300_000])]
    pad = 2 * 10**9
    keep = window_mask(t, events, pad)
    brute = np.zeros(t.size, dtype=bool)
    for a, b in events:
        brute |= (t >= a - pad) & (t <= b + pad)
    np.testing.assert_array_equal(keep, brute)
    assert keep.sum() == (2050 + 2001) + 4001
    v = _walk(t.size, 2)
    idx = select_samples(v, keep, max_points=20_000)
    assert np.isin(np.flatnonzero(keep), idx).all()
    outside = idx[~keep[idx]]
    assert outside.size <= 20_000 + 2
    assert idx.size < t.size / 10


def test_window_mask_clips_at_the_ends_and_handles_no_events() -> None:
    t = np.arange(100, dtype=np.int64) * 10
    assert not window_mask(t, [], 50).any()
    m = window_mask(t, [(0, 0), (990, 990)], 25)
    np.testing.assert_array_equal(np.flatnonzero(m), [0, 1, 2, 97, 98, 99])


def test_nan_samples_do_not_hide_the_extrema() -> None:
    v = _walk(5000, 1)[:, 0]
    v[100:300] = np.nan  # one bucket entirely NaN, others partly
    v[1234] = 99.0
    idx = envelope_indices(v, 100)
    assert 1234 in idx
    sel = v[idx]
    assert np.nanmax(sel) == np.nanmax(v) and np.nanmin(sel) == np.nanmin(v)


def test_bad_max_points_is_refused() -> None:
    with pytest.raises(ValueError, match="max_points"):
        bucket_size(10, 1, 0)


@pytest.mark.parametrize(("n", "k", "max_points", "chunks"), [
    (100_000, 2, 3000, [997]), (20_000, 1, 1000, [1, 7, 4096]),
    (12_345, 3, 500, [100, 12_345]), (9_999, 2, 5000, [3000]), (1_500, 2, 10**6, [7])])
def test_envelope_stream_selects_the_whole_series_envelope(
        n: int, k: int, max_points: int, chunks: list[int]) -> None:
    """EnvelopeStream over chunks selects exactly envelope_indices of the whole series (NaN,
    kept samples, a last bucket shorter than the others), each index once, its rows riding
    along bit for bit (an int64 time seen as float64)."""
    rng = np.random.default_rng(n)
    v = rng.normal(size=(n, k))
    v[rng.random(n) < 0.01, 0] = np.nan
    keep = rng.random(n) < 0.001
    t = np.arange(n, dtype=np.int64) - 3  # negative times: NaN bit patterns as float64
    want = envelope_indices([v[:, i] for i in range(k)], bucket_size(n, k, max_points), keep)
    es, old = EnvelopeStream(n, k, max_points), EnvelopeStream(n, k, max_points)
    got: list[int] = []
    a = i = 0
    while a < n:
        b = min(a + chunks[i % len(chunks)], n)
        cols = [np.ascontiguousarray(v[a:b, s]) for s in range(k)]
        sel, rows = es.select([*cols, t[a:b].view(np.float64)], k, keep[a:b])
        assert np.array_equal(np.ascontiguousarray(rows[:, -1]).view(np.int64), sel - 3)
        assert np.array_equal(rows[:, :k], v[sel], equal_nan=True)
        sel_old, rows_old = old.update(v[a:b], keep[a:b],
                                       np.arange(a, b, dtype=np.float64)[:, None])
        assert np.array_equal(sel_old, sel) and np.array_equal(rows_old[:, 0], sel)
        got += sel.tolist()
        a, i = b, i + 1
    assert sorted(got) == want.tolist() and len(set(got)) == len(got)
