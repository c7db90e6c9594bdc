"""The causal replay, chunk by chunk: state in, state out (architecture.md, "Streaming").

One chunk of a log (n consecutive samples, n ≥ 1) goes through every causal stage of
detection, each continuing from the state the previous chunk left:

  residual r per joint (eq. 7–8 or the momentum observer on the tool's model, or the
  controller's channels: :mod:`impactcli.model.generators`) → threshold inputs u (Table I)
  → adaptive evaluator (eq. 24–42, :func:`impactcli.detect.adaptive.evaluate_chunk`)
  beside the static-loading statistic |LP(r)| and the baseline statistic |r| (method.md
  §5), and the joints' causal velocity (for the incidents' contact type).

:func:`replay_chunk` ``(setup, state, chunk) -> (ChunkReplay, new state)``. The whole-log
replay (:func:`impactcli.pipeline.replay`) is one chunk of the same code from
:meth:`ReplayState.initial`. Guarantee: for any split of a log into consecutive chunks
the outputs concatenated are bit for bit those of the whole log, and so is the final
state (:mod:`impactcli.causal`, :mod:`impactcli.detect.adaptive`; model torques are
summed per row in a fixed order, :func:`impactcli.model.structures.rowdot`).
Nothing here reads a file or decides a threshold: the replay is threshold-free.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .causal import Carry
from .config import DetectorConfig
from .detect.adaptive import (
    AdaptiveResult,
    EvaluatorState,
    ThresholdInputs,
    evaluate_chunk,
    inputs_chunk,
    join_chunks,
)
from .detect.static import causal_lowpass as loading_lowpass
from .errors import ModelError
from .model.generators import (
    LOGGED,
    GeneratorChoice,
    plain_residual,
    target_torque,
    uses_correction,
)
from .model.residual import ResidualOptions, causal_velocity, residual_chunk
from .model.rigid import RigidModel

#: Cut-off of the joints' causal velocity used for the incidents' contact type [Hz]
#: (at most 0.2 × the sample rate).
SPEED_CUTOFF_HZ = 10.0

#: With threads, a chunk of at least MIN_SPLIT_SAMPLES samples of at least
#: MIN_SPLIT_JOINTS joints is replayed in two parts: the evaluator's axes start on the
#: first 1/FIRST_PART of it while the calling thread makes the rest's residual and inputs
#: (before, one core waited while the whole chunk's were made: about 1.4 s per 10 minutes
#: of a 7-joint 1 kHz log). A quarter: at 7 joints the evaluator costs about 4 times the
#: residual per sample, so the first part's axes take about as long as the rest's
#: residual. With few joints the evaluator is cheap (nu² per axis: 34² at 2 joints
#: against 64² at 7) and the second residual call's fixed cost (its filters' design, the
#: parts joined) ate the gain (2 joints, 10 min: 2.1 s replay against 1.8 s unsplit, on
#: a loaded machine; 7 joints: 12.2 s against 13.1 s). The parts are chunks: the result
#: is the same bit for bit (module docstring).
FIRST_PART = 4
MIN_SPLIT_SAMPLES = 8192
MIN_SPLIT_JOINTS = 4

#: The chunk's arrays a replay reads (optional ones may be None).
CHUNK_ARRAYS: tuple[str, ...] = (
    "position", "torque", "position_ref", "velocity_ref", "acceleration_ref",
    "torque_model", "torque_ext",
)


@dataclass(frozen=True)
class ChunkArrays:
    """n consecutive samples of a log, in the replay's joint order: (n, J) arrays like
    :class:`~impactcli.types.RobotLog`'s (optional ones None) and ``time_s`` (n,) [s since
    the log's first sample]."""

    time_s: np.ndarray
    position: np.ndarray
    torque: np.ndarray
    position_ref: np.ndarray | None = None
    velocity_ref: np.ndarray | None = None
    acceleration_ref: np.ndarray | None = None
    torque_model: np.ndarray | None = None
    torque_ext: np.ndarray | None = None

    @property
    def n_samples(self) -> int:
        return int(self.time_s.shape[0])


def chunk_arrays(chunk: Any, time_s: np.ndarray, columns: list[int] | None = None
                 ) -> ChunkArrays:
    """:class:`ChunkArrays` of a RobotLog or a reader's chunk (anything with the arrays of
    :data:`CHUNK_ARRAYS`), its joints picked and ordered by ``columns`` (None: all)."""
    def pick(a: np.ndarray | None) -> np.ndarray | None:
        if a is None:
            return None
        a = np.asarray(a)
        return a if columns is None else a[:, columns]

    arrays = {name: pick(getattr(chunk, name, None)) for name in CHUNK_ARRAYS}
    return ChunkArrays(time_s=np.asarray(time_s, dtype=np.float64), **arrays)  # type: ignore[arg-type]


@dataclass(frozen=True)
class ReplaySetup:
    """What a replay fixes before its first sample.

    Attributes:
        joint_names: the J joints replayed, in order (the model's, or the config's).
        choices: each joint's residual generator (:mod:`impactcli.model.generators`).
        model: the rigid model (None when no joint needs one).
        cfg: the detector config.
        sample_rate_hz, sample_period_s: the whole log's (:mod:`impactcli.sampling`).
        threads: the adaptive evaluator's threads (results do not depend on it).
    """

    joint_names: tuple[str, ...]
    choices: tuple[GeneratorChoice, ...]
    model: RigidModel | None
    cfg: DetectorConfig
    sample_rate_hz: float
    sample_period_s: float
    threads: int = 1

    def residual_options(self, generator: str | None = None) -> ResidualOptions:
        """The own-model generator's options (``inverse_dynamics`` for the logged ones)."""
        rc = self.cfg.residual
        g = generator or rc.generator
        if g not in ("inverse_dynamics", "momentum_observer"):
            g = "inverse_dynamics"
        return ResidualOptions(cutoff_hz=rc.derivative_cutoff_hz,
                               filter_torque=rc.filter_torque, generator=g,
                               observer_gain=rc.observer_gain)


@dataclass(frozen=True)
class ReplayState:
    """What the replay carries from one chunk to the next: the filters and differences
    (``carry``), the adaptive evaluator's state and the samples absorbed so far."""

    carry: Carry
    evaluator: EvaluatorState
    n_samples: int = 0
    reference: str = ""
    threshold_inputs: str = ""

    @classmethod
    def initial(cls, setup: ReplaySetup) -> ReplayState:
        """The state before the log's first sample."""
        return cls(Carry(), EvaluatorState.initial(
            len(setup.joint_names), setup.cfg.adaptive, setup.sample_rate_hz))

    def copy(self) -> ReplayState:
        return dataclasses.replace(self, carry=self.carry.copy(),
                                   evaluator=self.evaluator.copy())


@dataclass(frozen=True)
class ChunkReplay:
    """One chunk's replay; arrays (n, J) in the setup's joint order unless stated.

    Attributes:
        r: residual [N·m]; adaptive: the evaluator's signals (r_tilde, v_dyn, r_rms, v_rms,
        prediction error, ...); loading: |LP(r)|, the static-loading statistic [N·m];
        speed_qd: the joints' causal velocity [rad/s] (incidents' contact type);
        inputs_source: ``velocity_ref``, ``position_ref`` or ``measured``.
    """

    r: np.ndarray
    adaptive: AdaptiveResult
    loading: np.ndarray
    qd: np.ndarray
    inputs_source: str
    inputs_detail: str


def residual_columns(setup: ReplaySetup, chunk: ChunkArrays, carry: Carry,
                     where: str = "") -> np.ndarray:
    """(n, J) causal residual of the chunk, each joint from its own generator."""
    rc = setup.cfg.residual
    choices = setup.choices
    correct = uses_correction(choices, rc.logged_correction)
    cols: dict[str, np.ndarray] = {} if correct else plain_residual(
        chunk, choices, rc.derivative_cutoff_hz, rc.filter_torque,
        dt=setup.sample_period_s, carry=carry.scoped("plain."))
    wanted = {c.joint: ("inverse_dynamics" if c.generator in LOGGED else c.generator)
              for c in choices if c.joint not in cols}
    if wanted:
        model = setup.model
        if model is None:
            raise ModelError(f"{where}: the {sorted(set(wanted.values()))[0]} generator "
                             "needs a model")
        tau = target_torque(chunk, choices, rc.logged_correction)
        idx = [setup.joint_names.index(j) for j in model.joint_names]
        for g in sorted(set(wanted.values())):
            res = residual_chunk(model, chunk.position[:, idx], tau[:, idx],
                                 setup.sample_period_s, setup.residual_options(g),
                                 carry.scoped(g + "."))
            for j, gj in wanted.items():
                if gj == g:
                    cols[j] = res.r[:, model.joint_names.index(j)]
    return np.column_stack([cols[j] for j in setup.joint_names])


def _part(chunk: ChunkArrays, a: int, b: int) -> ChunkArrays:
    """Samples ``a`` to ``b`` of a chunk."""
    return dataclasses.replace(chunk, **{
        f.name: getattr(chunk, f.name)[a:b] for f in dataclasses.fields(chunk)
        if getattr(chunk, f.name) is not None})


def replay_chunk(
    setup: ReplaySetup, state: ReplayState, chunk: ChunkArrays, *, where: str = "",
    progress: Callable[[int, int], None] | None = None, consume: bool = False,
) -> tuple[ChunkReplay, ReplayState]:
    """Replay one chunk, continuing from ``state`` (module docstring).

    Args:
        setup: what the replay fixed before its first sample.
        state: the state after the previous chunk (:meth:`ReplayState.initial` first);
            left as it was unless ``consume``.
        chunk: the chunk's samples in ``setup.joint_names`` order.
        where: the log's path, for messages.
        progress: the adaptive evaluator's per-axis progress (slow replays).
    Returns:
        (the chunk's replay, the state after it).
    """
    st = state if consume else state.copy()
    carry = st.carry
    fs = setup.sample_rate_hz
    cfg = setup.cfg.adaptive
    n = chunk.n_samples
    split = n // FIRST_PART if setup.threads > 1 and n >= MIN_SPLIT_SAMPLES and len(
        setup.joint_names) >= MIN_SPLIT_JOINTS else 0

    def made(part: ChunkArrays) -> tuple[np.ndarray, ThresholdInputs]:
        """A part's residual and threshold inputs, continuing the carry."""
        return (residual_columns(setup, part, carry.scoped("residual."), where),
                inputs_chunk(part, part.time_s, fs, cfg, carry.scoped("inputs."), where))

    v_stat = np.zeros(len(setup.joint_names))
    ev = st.evaluator
    head: AdaptiveResult | None = None
    if split:  # the evaluator starts on the first part while the rest's residual is made
        from concurrent.futures import ThreadPoolExecutor

        r_head, in_head = made(_part(chunk, 0, split))
        with ThreadPoolExecutor(max_workers=1) as ex:
            job = ex.submit(evaluate_chunk, ev, r_head, in_head.u, fs, v_stat, cfg,
                            setup.threads, None, _consume=True)
            r_tail, inputs = made(_part(chunk, split, n))
            head, ev = job.result()
        r = np.concatenate([r_head, r_tail])
    else:
        r_tail, inputs = made(chunk)
        r = r_tail
    sl = setup.cfg.static_loading
    dt = setup.sample_period_s
    rest: list[np.ndarray] = []

    def statistics() -> None:
        """The static-loading statistic and the speed: on this thread while the
        evaluator's axes run on theirs (they read neither's carry)."""
        rest.append(np.abs(loading_lowpass(r, sl.cutoff_hz, fs, sl.order,
                                           carry.scoped("static."))))
        rest.append(causal_velocity(dt, chunk.position, min(SPEED_CUTOFF_HZ, 0.2 / dt),
                                    carry.scoped("speed."), "q"))

    ad, ev = evaluate_chunk(ev, r_tail, inputs.u, fs, v_stat, cfg, setup.threads, progress,
                            _consume=True, alongside=statistics)
    if head is not None:
        ad = join_chunks([head, ad])
    loading, qd = rest
    new = dataclasses.replace(st, evaluator=ev, n_samples=st.n_samples + chunk.n_samples,
                              reference=inputs.source, threshold_inputs=inputs.detail)
    return ChunkReplay(r, ad, loading, qd, inputs.source, inputs.detail), new
