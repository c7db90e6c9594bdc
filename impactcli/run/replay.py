"""The causal replay, chunk by chunk: state in, state out (docs/architecture.md).

One chunk of a log (n consecutive samples, n ≥ 1) goes through every causal stage of
detection, each continuing from the state the previous chunk left:

  residual r per joint (eq. 7–8 or the momentum observer on the tool's model, or the
  controller's channels: :mod:`impactcli.model.generators`) → threshold inputs u (Table I)
  → adaptive evaluator (eq. 24–42, :func:`impactcli.detect.adaptive.evaluate_chunk`)
  beside the static-loading statistic |LP(r)| and the baseline statistic |r| (docs/method.md
  §5), and the joints' causal velocity (for the incidents' contact type).

:class:`Replayer` takes the chunks in order from :meth:`ReplayState.initial` (a log in
memory is one chunk). Guarantee: for any split of a log into consecutive chunks the
outputs concatenated are bit for bit those of the whole log, and so is the final state
(:mod:`impactcli.model.causal`, :mod:`impactcli.detect.adaptive`; model torques are summed per
row in a fixed order, :func:`impactcli.model.structures.rowdot`).
Nothing here reads a file or decides a threshold: the replay is threshold-free.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config import DetectorConfig
from ..detect.adaptive import (
    AdaptiveResult,
    EvaluatorState,
    ThresholdInputs,
    inputs_chunk,
    join_chunks,
    result_of,
)
from ..detect.axes import AxisJob, AxisRunner
from ..detect.probe import ProbeRecorder
from ..detect.static import causal_lowpass as loading_lowpass
from ..errors import ModelError
from ..model.causal import Carry
from ..model.generators import (
    LOGGED,
    OWN_MODEL,
    GeneratorChoice,
    plain_residual,
    target_torque,
    uses_correction,
)
from ..model.residual import ResidualOptions, causal_velocity, residual_chunk
from ..model.rigid import RigidModel
from ..sample_channels import REPLAYED_CHANNELS, Channels

#: Cut-off of the joints' causal velocity used for the incidents' contact type [Hz]
#: (at most 0.2 × the sample rate).
SPEED_CUTOFF_HZ = 10.0

#: Parts a chunk is fed to the evaluator's axes in (a log in memory is one chunk):
#: the calling thread makes a part's residual while the axes work on the one before.
PART_SAMPLES = 65_536
#: Parts the calling thread may run ahead of the axes (each held part costs its signals:
#: about 50 MB at 65,536 samples of 7 joints); 0: one part at a time.
AHEAD = 2

@dataclass(frozen=True)
class ChunkArrays(Channels):
    """n consecutive samples of a log, in the replay's joint order: the channels of
    :class:`~impactcli.sample_channels.Channels` it reads
    (:data:`~impactcli.sample_channels.REPLAYED_CHANNELS`; the others and those the log
    lacks are None) and ``time_s`` (n,) [s since the log's first sample]."""

    time_s: np.ndarray

    @property
    def n_samples(self) -> int:
        return int(self.time_s.shape[0])


def chunk_arrays(chunk: Channels, time_s: np.ndarray, columns: list[int] | None = None
                 ) -> ChunkArrays:
    """:class:`ChunkArrays` of a RobotLog or a reader's chunk (any
    :class:`~impactcli.sample_channels.Channels`), its joints picked and ordered by ``columns``
    (None: all)."""
    def pick(a: np.ndarray | None) -> np.ndarray | None:
        if a is None:
            return None
        a = np.asarray(a)
        return a if columns is None else a[:, columns]

    arrays = {name: pick(getattr(chunk, name)) for name in REPLAYED_CHANNELS}
    return ChunkArrays(time_s=np.asarray(time_s, dtype=np.float64), **arrays)  # type: ignore[arg-type]


@dataclass(frozen=True)
class ReplaySetup:
    """What a replay fixes before its first sample.

    Attributes:
        joint_names: the J joints replayed, in order (the model's, or the config's).
        choices: each joint's residual generator (:mod:`impactcli.model.generators`).
        model: the rigid model (None when no joint needs one).
        cfg: the detector config.
        sample_rate_hz, sample_period_s: the whole log's (:mod:`impactcli.clock`).
        threads: the adaptive evaluator's threads (results do not depend on it).
        monitor: the payload-change monitor
            (:class:`~impactcli.detect.payload_change.PayloadMonitor`), fed each part's
            residual on the calling thread, in order; None: none.
    """

    joint_names: tuple[str, ...]
    choices: tuple[GeneratorChoice, ...]
    model: RigidModel | None
    cfg: DetectorConfig
    sample_rate_hz: float
    sample_period_s: float
    threads: int = 1
    monitor: Any = None

    def residual_options(self, generator: str | None = None) -> ResidualOptions:
        """The own-model generator's options (``inverse_dynamics`` for the logged ones)."""
        rc = self.cfg.residual
        g = generator or rc.generator
        if g not in OWN_MODEL:
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


@dataclass
class _Part:
    """A part submitted to the axes: what the calling thread made, and the axes' job."""

    tag: Any
    last: bool  # the last part of its chunk
    r: np.ndarray
    inputs: ThresholdInputs
    loading: np.ndarray
    qd: np.ndarray
    job: AxisJob


class Replayer:
    """Chunks replayed in order, pipelined (module docstring): :meth:`feed` a chunk, get
    back the chunks whose replay is done, in order; :meth:`finish` for the rest, then
    :attr:`state` is the state after the last chunk.

    The calling thread makes each part's residual, threshold inputs, loading statistic and
    speed (they continue the carry in order) and hands the residual and inputs to the
    evaluator's axes (:class:`~impactcli.detect.axes.AxisRunner`, a thread per axis with
    ``setup.threads`` > 1); up to ``ahead`` parts run ahead of the axes. The results are the
    same bits as one part at a time on one thread.

    Args:
        setup: what the replay fixed before its first sample.
        state: the state after the previous chunk (:meth:`ReplayState.initial` first);
            left as it was unless ``consume``.
        where: the log's path, for messages.
        progress: the evaluator's per-axis progress of each part (slow replays).
    """

    def __init__(self, setup: ReplaySetup, state: ReplayState, *, where: str = "",
                 consume: bool = False, ahead: int = AHEAD,
                 progress: Callable[[int, int], None] | None = None,
                 probes: ProbeRecorder | None = None) -> None:
        self.setup, self.where, self.ahead, self.progress = setup, where, ahead, progress
        self.probes = probes
        self._st = state if consume else state.copy()
        self._runner = AxisRunner(self._st.evaluator, np.zeros(len(setup.joint_names)),
                                  setup.threads)
        self._pending: deque[_Part] = deque()
        self._done: list[_Part] = []  # finished parts of a chunk not finished yet
        self._inputs = (self._st.reference, self._st.threshold_inputs)
        self._closed = False
        self._k = self._st.n_samples  # the next part's first sample (the monitor's clock)

    def feed(self, tag: Any, chunk: ChunkArrays) -> list[tuple[Any, ChunkReplay]]:
        """Start replaying ``chunk`` (``tag`` comes back with its replay); returns the
        chunks done so far, oldest first."""
        setup, carry = self.setup, self._st.carry
        cfg, sample_rate_hz, dt = setup.cfg, setup.sample_rate_hz, setup.sample_period_s
        n = chunk.n_samples
        out: list[tuple[Any, ChunkReplay]] = []
        cuts = sorted({*range(0, max(n, 1), PART_SAMPLES), *(
            [] if self.probes is None else
            [k - self._k for k in self.probes.cuts(self._k, self._k + n)])})
        for a, b in zip(cuts, [*cuts[1:], n], strict=True):
            part = _part(chunk, a, b) if (a, b) != (0, n) else chunk
            if self.probes is not None and self.probes.wants(self._k):
                self.probes.take(self._k, self._runner.snapshot())  # the state before it
            r = residual_columns(setup, part, carry.scoped("residual."), self.where)
            if setup.monitor is not None:  # a payload change: the residual takes the load
                r = setup.monitor.process(self._k, part.time_s, part.position, r)
            k_part = self._k
            self._k += part.n_samples
            inputs = inputs_chunk(part, part.time_s, sample_rate_hz, cfg.adaptive,
                                  carry.scoped("inputs."), self.where)
            job = self._runner.submit(np.ascontiguousarray(r, dtype=np.float64),
                                      np.ascontiguousarray(inputs.u, dtype=np.float64))
            sl = cfg.static_loading  # while the axes run
            lp = loading_lowpass(r, sl.cutoff_hz, sample_rate_hz, sl.order,
                                 carry.scoped("static."))
            loading = np.abs(lp)
            if self.probes is not None:
                self.probes.feed(k_part, r, inputs.u, lp)
            qd = causal_velocity(dt, part.position, min(SPEED_CUTOFF_HZ, 0.2 / dt),
                                 carry.scoped("speed."), "q")
            self._inputs = (inputs.source, inputs.detail)
            self._pending.append(_Part(tag, b >= n, r, inputs, loading, qd, job))
            while len(self._pending) > self.ahead:
                out += self._collect()
        return out

    def finish(self) -> list[tuple[Any, ChunkReplay]]:
        """The chunks not returned yet, oldest first; then :attr:`state` is final."""
        out: list[tuple[Any, ChunkReplay]] = []
        try:
            while self._pending:
                out += self._collect()
        finally:
            self.close()
        return out

    def close(self) -> None:
        """End the axes' threads (an abandoned replay: its state is then unusable)."""
        if not self._closed:
            self._closed = True
            self._runner.close()

    @property
    def state(self) -> ReplayState:
        """The state after every chunk fed (after :meth:`finish`)."""
        if self._pending or not self._closed:
            raise RuntimeError("Replayer.state before finish()")
        n = self._runner.n_samples  # the evaluator's samples are the replay's
        ev = dataclasses.replace(self._st.evaluator, n_samples=n)
        return dataclasses.replace(self._st, evaluator=ev, n_samples=n,
                                   reference=self._inputs[0],
                                   threshold_inputs=self._inputs[1])

    def _collect(self) -> list[tuple[Any, ChunkReplay]]:
        """Wait for the oldest part; its chunk's replay when it was the chunk's last."""
        p = self._pending.popleft()
        p.job.wait(self.progress)
        self._done.append(p)
        if not p.last:
            return []
        parts, self._done = self._done, []
        ev = self._st.evaluator
        ads = [result_of(q.job, ev) for q in parts]
        one = len(parts) == 1

        def cat(xs: list[np.ndarray]) -> np.ndarray:
            return xs[0] if one else np.concatenate(xs)

        return [(p.tag, ChunkReplay(
            cat([q.r for q in parts]), ads[0] if one else join_chunks(ads),
            cat([q.loading for q in parts]), cat([q.qd for q in parts]),
            p.inputs.source, p.inputs.detail))]

