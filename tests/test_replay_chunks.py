"""The causal replay in chunks equals the replay of one chunk bit for bit (impactcli.run.replay).

Every stage — residual (inverse dynamics, momentum observer, the controller's channels
with and without correction), threshold inputs (logged references, position reference,
measured position), the adaptive evaluator, the static-loading low-pass and the speed
used by the incidents — is run on chunks of 1, 7, 1000 samples and at random
boundaries, and compared with ``np.array_equal`` against one chunk holding the log.
"""

from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path

import numpy as np
import pytest

from impactcli.config import DetectorConfig, load_config
from impactcli.logs import read_log
from impactcli.logs.layout import LogChunk
from impactcli.model import RigidModel, identify
from impactcli.model.generators import choose_generators
from impactcli.run.replay import (
    ChunkArrays,
    ChunkReplay,
    Replayer,
    ReplaySetup,
    ReplayState,
    chunk_arrays,
)

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def replay_chunk(setup: ReplaySetup, state: ReplayState, chunk: ChunkArrays
                 ) -> tuple[ChunkReplay, ReplayState]:
    """One chunk through a :class:`Replayer` that continues from ``state`` (left as it
    was): (the chunk's replay, the state after it)."""
    rp = Replayer(setup, state)
    try:
        done = rp.feed(None, chunk)
        done += rp.finish()
    finally:
        rp.close()
    ((_, out),) = done
    return out, rp.state


def _setup(log, cfg: DetectorConfig, model: RigidModel | None) -> ReplaySetup:
    choices = choose_generators(log, cfg.residual.generator, cfg.residual.generators or None)
    return ReplaySetup(log.joint_names, choices, model, cfg, log.sample_rate_hz,
                       log.sample_period_s)


def _run(setup: ReplaySetup, log, bounds: list[int]) -> tuple[list[ChunkReplay], ReplayState]:
    state = ReplayState.initial(setup)
    outs = []
    t = log.time_s
    for a, b in itertools.pairwise(bounds):
        ch = chunk_arrays(log.slice(a, b) if b - a >= 2 else _one(log, a, b), t[a:b])
        out, state = replay_chunk(setup, state, ch)
        outs.append(out)
    return outs, state


def _one(log, a: int, b: int) -> LogChunk:
    """Samples a:b of a log as a reader's chunk (a RobotLog needs 2 samples)."""
    return LogChunk(start=a, t_ns=log.t_ns[a:b],
                    **{name: None if v is None else v[a:b] for name, v in log.channels().items()})


def _cat(outs: list[ChunkReplay], name: str) -> np.ndarray:
    if name.startswith("adaptive."):
        return np.concatenate([getattr(o.adaptive, name.split(".")[1]) for o in outs])
    return np.concatenate([getattr(o, name) for o in outs])


FIELDS = ("r", "loading", "qd", "adaptive.r_tilde", "adaptive.v_dyn", "adaptive.r_rms",
          "adaptive.v_rms", "adaptive.prediction_error")


def _assert_same(setup, log, n: int) -> None:
    whole, s_whole = _run(setup, log, [0, n])
    rng = np.random.default_rng(5)
    splits = [
        [*list(range(0, min(n, 150))), n],            # single samples, then the rest
        [*list(range(0, n, 97)), n],
        [*list(range(0, n, 1000)), n],
        [0, *sorted(rng.choice(np.arange(1, n), 12, replace=False).tolist()), n],
    ]
    for bounds in splits:
        outs, state = _run(setup, log, bounds)
        for f in FIELDS:
            assert np.array_equal(_cat(outs, f), _cat(whole, f)), (f, bounds[:5])
        assert state.carry == s_whole.carry
        for k in ("theta", "P", "r_lags", "v_lags", "u_lags", "filters", "ring_r",
                  "ring_v", "sums"):
            assert np.array_equal(getattr(state.evaluator, k), getattr(s_whole.evaluator, k))


def test_logged_generators_with_correction_chunks() -> None:
    """ASSIST-like sample: the controller's channels, corrected by the config's model."""
    cfg = load_config(SAMPLES / "assist_like.config.toml")
    log = read_log(SAMPLES / "csv" / "assist_impacts.csv.gz").slice(0, 2500)
    model = RigidModel.from_dict(cfg.model) if cfg.model else None
    setup = _setup(log, cfg, model)
    assert {c.generator for c in setup.choices} & {"logged_external", "logged_model"}
    _assert_same(setup, log, log.n_samples)


@pytest.mark.parametrize("generator", ["inverse_dynamics", "momentum_observer"])
def test_own_model_chunks(generator: str) -> None:
    """Heavy arm, planar model: both own-model generators."""
    cfg = load_config(SAMPLES / "heavy_geared.config.toml")
    cfg = dataclasses.replace(cfg, residual=dataclasses.replace(
        cfg.residual, generator=generator, generators={}))
    log = read_log(SAMPLES / "csv" / "heavy_impacts.csv.gz").slice(0, 2000)
    model = RigidModel.from_dict(cfg.model)
    setup = _setup(log, cfg, model)
    assert {c.generator for c in setup.choices} == {generator}
    _assert_same(setup, log, log.n_samples)


@pytest.mark.filterwarnings("ignore::impactcli.errors.ImpactWarning")
def test_coupled_model_and_measured_inputs_chunks() -> None:
    """A coupled model (BLAS-free row sums) and no reference logged (measured inputs),
    plain logged channels (no correction)."""
    log = read_log(SAMPLES / "csv" / "heavy_free_p2p.csv.gz").slice(0, 2000)
    log = dataclasses.replace(log, position_ref=None, velocity_ref=None,
                              acceleration_ref=None)
    model = identify(log, kind="coupled")
    cfg = DetectorConfig()
    cfg = dataclasses.replace(cfg, residual=dataclasses.replace(
        cfg.residual, generator="inverse_dynamics"))
    setup = _setup(log, cfg, model)
    _assert_same(setup, log, log.n_samples)


def test_position_reference_only_chunks() -> None:
    """Inputs by backward differences of the position reference."""
    cfg = load_config(SAMPLES / "heavy_geared.config.toml")
    log = read_log(SAMPLES / "csv" / "heavy_impacts.csv.gz").slice(0, 2000)
    log = dataclasses.replace(log, velocity_ref=None, acceleration_ref=None)
    setup = _setup(log, cfg, RigidModel.from_dict(cfg.model))
    _assert_same(setup, log, log.n_samples)


@pytest.mark.parametrize("sizes", [[10_000_000], [1, 2, 997], [4096], [333, 5000, 1]])
def test_warmup_tracker_equals_whole_log(sizes: list[int]) -> None:
    """WarmupTracker fed in chunks gives warmup_end's answer bit for bit (a synthetic
    prediction error that settles at different times per joint, with a contact late on)."""
    from impactcli.config import WarmupConfig
    from impactcli.detect.warmup import WarmupTracker

    from .reference.warmup import warmup_end

    rng = np.random.default_rng(3)
    n, fs = 12_000, 500.0
    t = np.arange(n) / fs
    e = rng.normal(size=(n, 3)) * (1.0 + 30.0 * np.exp(-t[:, None] / np.array([1.0, 4.0, 9.0])))
    e[9000:9100, 1] += 50.0
    for cfg in (WarmupConfig(), WarmupConfig(max_s=6.0), WarmupConfig(min_s=1.0, window_s=0.1)):
        for until in (None, 5.0, 11.0, 17.9, 2.0):  # a payload change's onset, or none
            whole = warmup_end(e, t, cfg, until)
            tr = WarmupTracker(n, float(t[0]), float(t[-1]), 3, cfg)
            k, i = 0, 0
            while k < n:
                m = sizes[i % len(sizes)]
                tr.update(e[k:k + m], t[k:k + m])
                k, i = k + m, i + 1
            got = tr.finish(until)
            assert np.array_equal(got.index, whole.index) and got.end_index == whole.end_index
            assert got.end_s == whole.end_s


@pytest.mark.parametrize("m", [1, 2, 7, 1000, 250_001])
def test_spilled_median_is_numpys(m: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """The warm-up level's median read back from its spill file in bounded memory equals
    np.median exactly (values narrowed by value bins: ties, a constant column, values over
    600 decades, subnormals, adjacent floats, heavy tails)."""
    import tempfile

    from impactcli import spill

    monkeypatch.setattr(spill, "SELECT_IN_MEMORY", 1000)
    rng = np.random.default_rng(m)
    wide = rng.normal(size=m) * 10.0 ** rng.integers(-300, 300, m)  # bins of every scale
    tiny = rng.uniform(0, 1, m) * 5e-324 * rng.integers(1, 4, m)    # subnormals, zeros
    near = 1.0 + rng.integers(0, 3, m) * np.finfo(float).eps         # adjacent floats
    for x in (rng.normal(size=m), rng.integers(0, 5, m).astype(float), np.full(m, 2.5),
              wide, tiny, near, np.abs(rng.standard_cauchy(m))):
        with tempfile.TemporaryFile() as f:
            f.write(x.tobytes())
            f.flush()
            assert spill.spilled_median(f, m) == float(np.median(x))


def _pipelined(setup: ReplaySetup, log, bounds: list[int], ahead: int
               ) -> tuple[list[ChunkReplay], ReplayState]:
    """The chunks through one Replayer (fed in turn, results as they come)."""
    rp = Replayer(setup, ReplayState.initial(setup), ahead=ahead)
    t = log.time_s
    got: list[tuple[int, ChunkReplay]] = []
    for i, (a, b) in enumerate(itertools.pairwise(bounds)):
        got += rp.feed(i, chunk_arrays(log.slice(a, b) if b - a >= 2 else _one(log, a, b),
                                       t[a:b]))
    got += rp.finish()
    assert [i for i, _ in got] == list(range(len(bounds) - 1))  # in order, each once
    return [out for _, out in got], rp.state


@pytest.mark.parametrize("generator", ["inverse_dynamics", "momentum_observer"])
def test_pipelined_replay_is_the_same(generator: str, monkeypatch: pytest.MonkeyPatch
                                      ) -> None:
    """The Replayer's pipeline (chunks cut into parts, the axes on threads of their own
    working on one part while the calling thread makes the next ones): every output and
    the state are those of one chunk at a time on one thread, bit for bit."""
    from impactcli.detect.adaptive import SIGNALS
    from impactcli.run import replay

    monkeypatch.setattr(replay, "PART_SAMPLES", 64)  # chunks of several parts
    cfg = load_config(SAMPLES / "heavy_geared.config.toml")
    cfg = dataclasses.replace(cfg, residual=dataclasses.replace(
        cfg.residual, generator=generator, generators={}))
    log = read_log(SAMPLES / "csv" / "heavy_impacts.csv.gz").slice(0, 3000)
    one = _setup(log, cfg, RigidModel.from_dict(cfg.model))
    two = dataclasses.replace(one, threads=2)
    for bounds in ([0, log.n_samples], [0, 63, 64, 65, 1000, 1999, log.n_samples]):
        monkeypatch.setattr(replay, "PART_SAMPLES", 1 << 20)
        a, sa = _run(one, log, bounds)
        monkeypatch.setattr(replay, "PART_SAMPLES", 64)
        for setup, ahead in ((two, 2), (two, 0), (one, 3)):
            b, sb = _pipelined(setup, log, bounds, ahead)
            for f in (*FIELDS, *(f"adaptive.{x}" for x in SIGNALS)):
                assert np.array_equal(_cat(a, f), _cat(b, f)), (f, bounds)
            for x, y in zip(a, b, strict=True):
                assert x.r.shape == y.r.shape
                for k in ("theta", "n_resets", "n_capped"):
                    assert np.array_equal(getattr(x.adaptive, k), getattr(y.adaptive, k))
            _same_state(sa, sb)


def _same_state(sa: ReplayState, sb: ReplayState) -> None:
    assert sa.carry == sb.carry and sa.n_samples == sb.n_samples
    assert sa.evaluator.n_samples == sb.evaluator.n_samples == sa.n_samples
    assert (sa.reference, sa.threshold_inputs) == (sb.reference, sb.threshold_inputs)
    for k in ("theta", "P", "r_lags", "v_lags", "u_lags", "filters", "ring_r",
              "ring_v", "sums", "n_resets", "n_capped"):
        assert np.array_equal(getattr(sa.evaluator, k), getattr(sb.evaluator, k))
