"""Per-sample arrays of a replay, for the callers that want them in memory (a short log).

A replay keeps none of its per-sample arrays (:func:`impactcli.run.one_log.detect_log`): a
caller that wants them collects them from the chunks as they pass —
:class:`SignalsCollector` (the signals, decisions and ratios, on ``on_chunk``) and
:class:`StatsCollector` (the threshold-free statistics of a replay pass, for calibration).
:func:`detect_in_memory` is the replay of a log in memory with its signals collected,
:func:`stats_in_memory` its threshold-free pass with its statistics collected.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config import DetectorConfig
from ..logs.reader import MemoryReader
from ..types import DetectionResult, RobotLog, SignalsChunk
from .one_log import Replayed, ReplayStep, RunSetup, detect_log, replay_passes, warn_replayed
from .plan import RunPlan, plan_run, with_generator
from .run_warnings import CaughtWarnings


@dataclass(frozen=True)
class Signals:
    """A replay's per-sample arrays, (N, J) in the replayed joints' order.

    Attributes:
        joints: the J joints. time_s: (N,) [s since the first sample]; t_ns: (N,) [ns].
        signals: name → (N, J) (:data:`impactcli.types.SIGNAL_NAMES`) [N·m].
        decisions: detector → (N, J) bool. ratios: detector → (N, J) statistic / threshold.
        position: (N, J) [rad]; position_ref: (N, J) [rad] or None.
    """

    joints: tuple[str, ...]
    time_s: np.ndarray
    t_ns: np.ndarray
    signals: dict[str, np.ndarray]
    decisions: dict[str, np.ndarray]
    ratios: dict[str, np.ndarray]
    position: np.ndarray
    position_ref: np.ndarray | None


def _cat(parts: list[np.ndarray]) -> np.ndarray:
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


class SignalsCollector:
    """``on_chunk`` that keeps every chunk; :meth:`signals` joins them."""

    def __init__(self) -> None:
        self.chunks: list[SignalsChunk] = []

    def __call__(self, chunk: SignalsChunk) -> None:
        self.chunks.append(chunk)

    def signals(self) -> Signals:
        """The chunks joined, in order."""
        cs = self.chunks
        if not cs:
            raise ValueError("no chunk was collected")

        def each(name: str) -> dict[str, np.ndarray]:
            keys = getattr(cs[0], name)
            return {k: _cat([getattr(c, name)[k] for c in cs]) for k in keys}

        ref = None if cs[0].position_ref is None else _cat(
            [c.position_ref for c in cs if c.position_ref is not None])
        return Signals(cs[0].joints, _cat([c.time_s for c in cs]), _cat([c.t_ns for c in cs]),
                       each("signals"), each("decisions"), each("ratios"),
                       _cat([c.position for c in cs]), ref)


@dataclass(frozen=True)
class ReplayStats:
    """The threshold-free statistics of a replay pass, (N, J) in the replayed joints' order.

    Attributes:
        time_s: (N,) [s since the first sample]. r: the residual [N·m].
        stats: detector → the statistic its threshold must beat: adaptive r_rms − v_rms
            (eq. 42), static_loading |LP(r)|, static_baseline |r| [N·m].
    """

    time_s: np.ndarray
    r: np.ndarray
    stats: dict[str, np.ndarray]


class StatsCollector:
    """``on_step`` of :func:`impactcli.run.one_log.replay_passes` that keeps the
    statistics of every step; :meth:`stats` joins them."""

    def __init__(self) -> None:
        self.steps: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []

    def __call__(self, step: ReplayStep) -> None:
        from ..detect.thresholds import adaptive_statistic

        self.steps.append((step.t, step.r, adaptive_statistic(step.r_rms, step.v_rms),
                           step.loading))

    def stats(self) -> ReplayStats:
        """The steps joined, in order."""
        t, r, ad, loading = (_cat([s[k] for s in self.steps]) for k in range(4))
        return ReplayStats(t, r, {"adaptive": ad, "static_loading": loading,
                                  "static_baseline": np.abs(r)})


def detect_in_memory(log: RobotLog, **setup: Any) -> tuple[DetectionResult, Signals]:
    """:func:`impactcli.run.one_log.detect_log` of a log in memory (one chunk), with its
    per-sample arrays. ``setup``: :class:`~impactcli.run.one_log.RunSetup`'s fields
    (``chunk_rows`` defaults to the log's length)."""
    setup.setdefault("chunk_rows", max(log.n_samples, 1))
    run = RunSetup(**setup)
    collector = SignalsCollector()
    with MemoryReader(log, run.read_options.as_dict()) as reader:
        result = detect_log(reader, run, on_chunk=collector)
    return result, collector.signals()


def stats_in_memory(log: RobotLog, **setup: Any) -> tuple[ReplayStats, Replayed, RunPlan]:
    """The threshold-free pass of a log in memory (one chunk,
    :func:`impactcli.run.one_log.replay_passes`) with its statistics collected, what it
    left, and its plan; the warnings raised as a detection run orders them.
    ``setup``: :class:`~impactcli.run.one_log.RunSetup`'s fields but ``chunk_rows``."""
    run = RunSetup(**setup)
    cfg = with_generator(run.config or DetectorConfig(), run.generator, run.config_where)
    caught = CaughtWarnings()
    try:
        with MemoryReader(log, run.read_options.as_dict()) as reader, caught:
            plan, feed = plan_run(reader, cfg, model=run.model, robot=run.robot,
                                  model_from_log=run.model_from_log,
                                  allow_slow=run.allow_slow, config_where=run.config_where,
                                  chunk_rows=max(log.n_samples, 1))
            since = caught.mark()
            collected = StatsCollector()
            rp = replay_passes(feed, plan, collected)
            warn_replayed(caught, since, plan, feed, rp)
    finally:
        caught.raise_again(impact=True)
    return collected.stats(), rp, plan
