"""The one scan of a log's rows (:func:`scan_layout`): what every format's reader does
with the blocks of rows its layout gives (:mod:`impactcli.logs.layout`).

The rows are repaired across block boundaries (:class:`~impactcli.logs.repair.Repairer`),
converted by the layout's plan, counted (the sample clock and gaps of
:mod:`impactcli.clock`, the screens of the torque-like channels) and kept in a cache of
the repaired rows (:mod:`impactcli.logs.row_cache`) that the passes after the scan read
(:func:`pass_chunks`). A layout may ask for another pass (a CSV whose cells its first pass
did not read as the whole file must be read); ``--repair-order`` first finds the rows to
keep over the file's stamps (:func:`~impactcli.logs.repair.increasing_run`). The errors are
raised in the order the whole file is refused with: the layout's, the repairs', the time
unit's, the plan's.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from ..clock import GAP_FACTOR, MAX_STATS_STEPS, GapStream, SampleClock, StepHistogram
from ..columns import column_all, column_any, column_range
from ..errors import ImpactWarning, LogFormatError
from ..sample_channels import CONTROLLER_CHANNELS, OPTIONAL_CHANNELS, REQUIRED_CHANNELS
from ..types import LogSource, RobotLog
from .defects import SHUFFLED_STEP_SHARE, DefectScan, Jump, Wrap, unwrap_positions
from .layout import LogChunk, ScanPass, StreamLayout, chunked
from .plausibility import (
    MotionSketch,
    UnitVerdict,
    limit_warnings,
    position_unit_verdict,
    robot_joint_limits,
)
from .poses import PoseSample, pose_explained
from .repair import MAX_RATE_HZ, MIN_RATE_HZ, Repairer, RepairOrderNeeded, increasing_run
from .row_cache import RowCache
from .screen import ColumnScreen, ScreenAccumulator
from .velocity_check import (
    VelocityAgreement,
    disagreement_message,
    disagreement_stretches,
)

#: The first pass keeps the steps longer than this fraction of 1.5 provisional periods as
#: gap candidates (exact while the final threshold is above; else a second pass).
FLOOR_FRACTION = 0.8
#: The logged velocity against the positions' steps: a joint counts where |v| is at least
#: MOVING_RAD_S [rad/s], over at least MIN_MOVING_SAMPLES samples; the rate it implies is
#: warned of when off the clock's by more than RATE_FACTOR (and the joints agree within it).
MOVING_RAD_S = 0.05
MIN_MOVING_SAMPLES = 100
RATE_FACTOR = 1.5


class ScanReader(Protocol):
    """The reader a scan was made by (:class:`impactcli.logs.reader.LogReader`)."""

    def chunks(self, rows: int) -> Iterator[LogChunk]: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class LogScan:
    """The first pass over a log (:meth:`LogReader.scan`): what needs the whole log.

    Attributes:
        log: the log's header: a :class:`~impactcli.types.RobotLog` of its first 2 samples
            with the whole log's ``joint_names``, ``source`` (sha256 of the whole file,
            format, torque and time source, repairs, ignored channels, joints dropped) and
            optional channels (an array where the whole log has one).
        n_samples: N, the log's samples.
        t0_ns, t_last_ns: its first and last sample time [ns].
        clock: its sample clock (``RobotLog.sample_clock``).
        gaps: (G,) int64 the gap steps i (t[i] → t[i+1]), and ``gap_lengths_s`` (G,) their
            lengths [s], as :func:`impactcli.logs.describe.time_gaps` on the whole log.
        torque_screen: ``unusable_columns(log.torque)`` of the whole log.
        screens: ``torque`` and each controller channel the log has → its
            :class:`ColumnScreen` (``screens[ch].unusable(ref)`` is
            ``unusable_columns(getattr(log, ch), ref)``).
        options: the read options the scan was made with.
        ranges: each array the log has → (J,) its smallest and (J,) its largest finite
            value per joint (NaN where a joint does not log it).
        position_unit: whether the positions can be radians
            (:func:`~impactcli.logs.plausibility.position_unit_verdict` of the motion; None
            for a log in memory).
        warnings: what the scan warned of besides the repairs (the position unit, positions
            far outside a URDF's limits, whole turns unwrapped), in order.
        jumps: the position steps no motion explains (:mod:`impactcli.logs.defects`; the
            first :data:`~impactcli.logs.defects.MAX_KEPT`, ``joint`` among the log's
            joints), and ``n_jumps`` how many there are.
        poses: a bounded sample of the log's poses (:mod:`impactcli.logs.poses`), and
            ``torque_posed`` (J,) whether each joint's torque varies with them (a measured
            channel, :func:`~impactcli.logs.poses.pose_explained`).
        disagreements: where the logged velocity and the positions tell two motions
            (:func:`~impactcli.logs.velocity_check.disagreement_stretches`: from, to [s],
            joints).
    """

    log: RobotLog
    n_samples: int
    t0_ns: int
    t_last_ns: int
    clock: SampleClock
    gaps: np.ndarray
    gap_lengths_s: np.ndarray
    torque_screen: list[str | None]
    screens: dict[str, ColumnScreen]
    options: dict[str, Any] = field(default_factory=dict, repr=False)
    reader: ScanReader | None = field(default=None, repr=False, compare=False)
    ranges: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict,
                                                              repr=False, compare=False)
    position_unit: UnitVerdict | None = field(default=None, compare=False)
    warnings: tuple[str, ...] = field(default=(), compare=False)
    jumps: tuple[Jump, ...] = field(default=(), compare=False)
    n_jumps: int = 0
    poses: PoseSample | None = field(default=None, repr=False, compare=False)
    torque_posed: np.ndarray | None = field(default=None, repr=False, compare=False)
    disagreements: tuple[tuple[float, float, tuple[str, ...]], ...] = field(
        default=(), compare=False)

    def close(self) -> None:
        """Close the reader the scan was made by (its cache of the repaired rows, a URL's
        local copy; deleted anyway when the scan is garbage collected or at exit)."""
        if self.reader is not None:
            self.reader.close()

    def __enter__(self) -> LogScan:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The log's J joints."""
        return self.log.joint_names

    @property
    def source(self) -> LogSource:
        """The log's provenance."""
        return self.log.source

    @property
    def channels(self) -> tuple[str, ...]:
        """The optional arrays the log has (names of :data:`OPTIONAL_CHANNELS`)."""
        return tuple(s for s in OPTIONAL_CHANNELS if getattr(self.log, s) is not None)

    @property
    def sample_period_s(self) -> float:
        """``RobotLog.sample_period_s`` of the whole log [s]."""
        return self.clock.period_s

    @property
    def sample_rate_hz(self) -> float:
        """``RobotLog.sample_rate_hz`` of the whole log [Hz]."""
        return 1.0 / self.clock.period_s

    @property
    def duration_s(self) -> float:
        """From the first to the last sample [s]."""
        return float(self.t_last_ns - self.t0_ns) * 1e-9

    @property
    def torque_ptp(self) -> float:
        """The largest peak-to-peak of the log's torque columns [N·m] (the reference of
        the screen)."""
        s = self.screens["torque"]
        return float(np.max(s.ptp)) if s.ptp.size else 0.0


def _blocks(ctx: StreamLayout, rep: Repairer) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The repaired rows of one pass over the layout's rows, in blocks ``(t, mat)``."""
    for raw in ctx.raw_batches():
        out = rep.push(raw)
        if out is not None:
            yield out
    out = rep.finish()
    if out is not None:
        yield out


def _order_pass(ctx: StreamLayout) -> tuple[np.ndarray, str]:
    """``--repair-order``: the rows of the file kept (a bool per row) and the repair's
    message, from the stamps of a pass without exact duplicates."""
    while True:
        rep = Repairer(ctx, None)
        ts, origs = [], []
        n = 0
        for raw in ctx.raw_batches():
            t, orig = rep.deduplicated(raw)
            ts.append(t)
            origs.append(orig)
            n = raw.row0 + raw.t.shape[0]
        if not ctx.pass_again():
            break
    t_all = np.concatenate(ts) if ts else np.zeros(0, np.int64)
    o_all = np.concatenate(origs) if origs else np.zeros(0, np.int64)
    keep, msg = increasing_run(t_all, o_all, ctx.where, ctx.label, ctx.time_name)
    mask = np.zeros(n, dtype=bool)
    mask[o_all[keep]] = True
    return mask, msg


class Sink:
    """What a pass does with the repaired rows (the scan's statistics and cache)."""

    def add(self, t: np.ndarray, mat: np.ndarray) -> None:
        raise NotImplementedError

    def discard(self) -> None:
        """The pass is given up (the rows are read again)."""


def passes(ctx: StreamLayout, sink: Any) -> Repairer:
    """Passes over the layout's rows until one reads them as the whole file is read (the
    layout may ask for another, ``--repair-order`` needs the stamps first); each pass's
    repaired rows go to a new ``sink()``. Returns the last pass's repairer."""
    order_keep: np.ndarray | None = None
    order_repair: str | None = None
    while True:
        rep = Repairer(ctx, None, order_keep, order_repair)
        out = sink()
        try:
            for t, mat in _blocks(ctx, rep):
                out.add(t, mat)
        except RepairOrderNeeded:
            out.discard()
            order_keep, order_repair = _order_pass(ctx)
            continue
        except BaseException:
            out.discard()
            raise
        if ctx.pass_again():
            out.discard()
            continue
        return rep


def raise_read_errors(ctx: StreamLayout, rep: Repairer, rate_error: str | None) -> None:
    """The first error of the rows read: the layout's, the repairs', the time unit's."""
    if ctx.read_error is not None:
        raise ctx.read_error
    err = rep.first_error() or rate_error
    if err is not None:
        raise LogFormatError(err)


def scan_layout(ctx: StreamLayout, options: dict[str, Any], reader: ScanReader
                ) -> tuple[LogScan, ScanPass]:
    """The scan of a layout's rows (module docstring): passes over them until the layout
    has read them as the whole file must be read, then the statistics, checks and cache.

    Raises:
        LogFormatError: the first error the whole file is refused with.
    """
    from concurrent.futures import ThreadPoolExecutor

    from .paths import log_sha256

    hasher = ThreadPoolExecutor(max_workers=1)
    digest = hasher.submit(log_sha256, ctx.path)
    hasher.shutdown(wait=False)
    sinks: list[_ScanSink] = []

    def sink() -> _ScanSink:
        sinks.append(_ScanSink(ctx))
        return sinks[-1]

    rep = passes(ctx, sink)
    last = sinks[-1]
    try:
        if last.cache is not None:
            last.cache.finish()
        raise_read_errors(ctx, rep, last.acc.rate_error())
        if isinstance(ctx.plan, LogFormatError):
            raise ctx.plan
        out = last.acc.finish(rep, digest.result(), options, last.cache, reader)
        if out[1].cache is not None:
            ctx.release()
        return out
    except BaseException:
        last.discard()
        raise


class _ScanSink(Sink):
    """The scan's statistics and cache of one pass."""

    def __init__(self, ctx: StreamLayout) -> None:
        self.acc = _ScanAcc(ctx)
        self.cache: RowCache | None = RowCache(len(ctx.names))

    def add(self, t: np.ndarray, mat: np.ndarray) -> None:
        self.acc.add(t, mat)
        if self.cache is not None:
            self.cache.add(t, mat)

    def discard(self) -> None:
        if self.cache is not None:
            self.cache.close()


class RowsKept(Sink):
    """The rows of a pass, kept (:func:`read_columns`) with the first steps' rate."""

    def __init__(self) -> None:
        self.t: list[np.ndarray] = []
        self.mat: list[np.ndarray] = []
        self.rate = StepHistogram()

    def add(self, t: np.ndarray, mat: np.ndarray) -> None:
        if self.rate.n_stamps < MAX_STATS_STEPS + 1:
            self.rate.add(t[: MAX_STATS_STEPS + 1 - self.rate.n_stamps])
        self.t.append(t)
        self.mat.append(mat)


class _ScanAcc:
    """The first pass's statistics over the repaired rows."""

    def __init__(self, ctx: StreamLayout) -> None:
        self.ctx = ctx
        self.hist = StepHistogram()
        self.rate = StepHistogram()  # the first MAX_STATS_STEPS steps: the unit check
        self.gaps = GapStream()
        self.n = 0
        self.head_t = np.zeros(0, dtype=np.int64)
        self.head: dict[str, np.ndarray] = {}
        j = len(ctx.joints)
        self.pos_finite = np.zeros(j, dtype=bool)
        self.torque_finite = np.zeros(j, dtype=bool)
        # optional signal → (J,) whether each joint's column holds a finite value
        self.opt_finite: dict[str, np.ndarray] = {}
        self.screens = {s: ScreenAccumulator(j) for s in ("torque", *CONTROLLER_CHANNELS)}
        self.ranges: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # other arrays' lo, hi
        self.floor = float("-inf")
        self.bad_row: dict[str, np.ndarray] = {}  # signal → (J,) first non-finite sample
        self.sketch: MotionSketch | None = None  # the positions' travel and speeds
        self.sketch_wait: list[np.ndarray] = []  # positions before the period is known
        # the logged velocity against the positions' steps, where a joint moves: per joint
        # the sums of |v| and |Δq| (the rate the velocity implies, :func:`velocity_rate`)
        self.v_sum = np.zeros(j)
        self.dq_sum = np.zeros(j)
        self.v_n = np.zeros(j, dtype=np.int64)
        self.q_last: np.ndarray | None = None
        self.agreement = VelocityAgreement(j)  # stretches where the two tell two motions
        self.defects = DefectScan(j)  # whole-turn steps unwrapped, jumps (splices) found
        self.ref_turns = DefectScan(j, unwrap_only=True)  # the reference's whole turns
        self.poses = PoseSample(j)  # strided poses: the torque scale against physics

    def _first_bad(self, signal: str, a: np.ndarray) -> None:
        """Note each column's first non-finite sample (RobotLog refuses it)."""
        fin = np.isfinite(a)
        if fin.all():
            return
        rows = self.bad_row.setdefault(signal, np.full(a.shape[1], -1, dtype=np.int64))
        new = (rows < 0) & ~column_all(fin)
        rows[new] = self.n - a.shape[0] + np.argmax(~fin, axis=0)[new]

    def check_finite(self, keep: list[int], gone: list[str]) -> None:
        """RobotLog's error for a non-finite value left in a kept joint's column (a value
        scaled out of range); the signals ``gone`` are not in the log."""
        for s in (*REQUIRED_CHANNELS, *OPTIONAL_CHANNELS):
            rows = self.bad_row.get(s) if s not in gone else None
            if rows is None or not (rows[keep] >= 0).any():
                continue
            r = rows[keep]
            row = int(np.min(r[r >= 0]))
            j = int(np.flatnonzero(r == row)[0])
            raise LogFormatError(f"{self.ctx.where}: {s} is not finite at sample {row} "
                                 f"of joint {j}")

    def add(self, t: np.ndarray, mat: np.ndarray) -> None:
        """Count repaired rows ``t`` (n,) int64 [ns], ``mat`` (n, C)."""
        from .channels import assemble

        if self.rate.n_stamps < MAX_STATS_STEPS + 1:
            self.rate.add(t[: MAX_STATS_STEPS + 1 - self.rate.n_stamps])
        self.hist.add(t)
        period = self.hist.period_ns()
        self.floor = FLOOR_FRACTION * GAP_FACTOR * period if period > 0 else float("-inf")
        self.gaps.add(t, self.floor)
        self.n += t.size
        if isinstance(self.ctx.plan, LogFormatError):
            return
        arrays = assemble(self.ctx.plan, self.ctx.channels(t, mat))
        arrays["position"] = self.defects.add(t, arrays["position"])
        if arrays.get("position_ref") is not None:  # the reference's turns too
            arrays["position_ref"] = self.ref_turns.add(t, arrays["position_ref"])
        self.poses.add(t, arrays["position"], arrays["torque"])
        if self.head_t.size < 2:
            k = 2 - self.head_t.size
            self.head_t = np.concatenate((self.head_t, t[:k]))
            self.head = {s: np.concatenate((self.head[s], a[:k])) if s in self.head else a[:k]
                         for s, a in arrays.items()}
        self.pos_finite |= column_any(np.isfinite(arrays["position"]))
        self._sketch(arrays["position"])
        if arrays.get("velocity") is not None:
            self._velocity(arrays["position"], arrays["velocity"])
            self.agreement.add(t, arrays["position"], arrays["velocity"])
        self.torque_finite |= column_any(np.isfinite(arrays["torque"]))
        for s in self.ctx.plan.optional:
            fin = column_any(np.isfinite(arrays[s]))
            self.opt_finite[s] = self.opt_finite[s] | fin if s in self.opt_finite else fin
        for s, a in arrays.items():
            if s not in CONTROLLER_CHANNELS:
                self._first_bad(s, a)
        for s, acc in self.screens.items():
            if s in arrays:
                acc.add(arrays[s])
        for s, a in arrays.items():
            if s not in self.screens:  # NaN: not logged (a finite log has no ±inf left)
                lo, hi = column_range(a, skip_nan=True)
                if s in self.ranges:
                    lo, hi = np.fmin(self.ranges[s][0], lo), np.fmax(self.ranges[s][1], hi)
                self.ranges[s] = (lo, hi)

    def _velocity(self, q: np.ndarray, v: np.ndarray) -> None:
        """Sum |v| and |Δq| over the samples where the logged velocity says the joint
        moves (|v| ≥ :data:`MOVING_RAD_S`; Δq from the sample before, across blocks)."""
        prev = q[:1] if self.q_last is None else self.q_last[None, :]
        dq = np.abs(np.diff(np.concatenate((prev, q)), axis=0))
        with np.errstate(invalid="ignore"):
            use = (np.abs(v) >= MOVING_RAD_S) & np.isfinite(dq) & np.isfinite(v)
        self.v_sum += np.where(use, np.abs(v), 0.0).sum(axis=0)
        self.dq_sum += np.where(use, dq, 0.0).sum(axis=0)
        self.v_n += use.sum(axis=0)
        self.q_last = q[-1].copy()

    def velocity_rate(self, keep: list[int], sample_rate_hz: float) -> str | None:
        """The warning when the logged velocity implies another sample rate than the
        log's clock (or ``--rate``): per moving joint sum|v| / sum|Δq| [Hz], their median,
        when it is off by more than :data:`RATE_FACTOR`, the joints agree and it is a rate
        a log can have (20 Hz – 100 kHz: else the velocity is not these positions'
        derivative, and says nothing of the rate); else None."""
        k = [c for c in keep if self.v_n[c] >= MIN_MOVING_SAMPLES and self.dq_sum[c] > 0]
        if not k or not sample_rate_hz > 0:
            return None
        implied = self.v_sum[k] / self.dq_sum[k]
        med = float(np.median(implied))
        if not MIN_RATE_HZ <= med <= MAX_RATE_HZ:  # not these positions' derivative at all
            return None
        agree = float(np.max(implied) / np.min(implied)) <= RATE_FACTOR
        if agree and not 1.0 / RATE_FACTOR <= med / sample_rate_hz <= RATE_FACTOR:
            return (f"{self.ctx.where}: the logged velocity implies a sample rate of about "
                    f"{med:.3g} Hz (its |v| over the positions' steps, {len(k)} moving "
                    f"joint(s)), the log's clock {sample_rate_hz:.3g} Hz: check --rate or the time "
                    "unit (or that .velocity is in rad/s, per s of the positions' unit)")
        return None

    def velocity_is_derivative(self, keep: list[int], sample_rate_hz: float) -> bool:
        """Whether the logged velocity is these positions' derivative: on every moving
        joint the rate it implies (:meth:`velocity_rate`) is within :data:`RATE_FACTOR` of
        the clock's (then where the two disagree, they tell two motions)."""
        k = [c for c in keep if self.v_n[c] >= MIN_MOVING_SAMPLES and self.dq_sum[c] > 0]
        if not k or not sample_rate_hz > 0:
            return False
        ratio = self.v_sum[k] / self.dq_sum[k] / sample_rate_hz
        return bool(np.all((ratio >= 1 / RATE_FACTOR) & (ratio <= RATE_FACTOR)))

    def _sketch(self, q: np.ndarray) -> None:
        """Feed (n, J) positions [rad] to the motion sketch (made once the provisional
        period is known: its speed window is in samples)."""
        if self.sketch is None:
            period = self.hist.period_ns()
            if not period > 0:
                self.sketch_wait.append(q)
                return
            self.sketch = MotionSketch(q.shape[1], period * 1e-9)
            for w in self.sketch_wait:
                self.sketch.update(w)
            self.sketch_wait = []
        self.sketch.update(q)

    def unit_verdict(self, keep: list[int], kept: tuple[str, ...],
                     options: dict[str, Any]) -> tuple[UnitVerdict, list[str]]:
        """Whether the kept joints' positions can be radians (docs/formats.md, "Canonical
        wide CSV"), and the warnings of positions far outside a URDF's limits."""
        sk = self.sketch
        if sk is None:
            return UnitVerdict("ok"), []
        limits = robot_joint_limits(options.get("robot"), kept)
        verdict = position_unit_verdict(self.ctx.where, kept, sk.travel()[keep],
                                        sk.speed()[keep], limits, sk.smooth()[keep])
        return verdict, limit_warnings(self.ctx.where, kept, sk.lo[keep], sk.hi[keep], limits)

    def rate_error(self) -> str | None:
        """The time-unit check on the first steps, with the duration read."""
        dur = (float(self.hist.last - self.head_t[0]) * 1e-9
               if self.head_t.size and self.hist.last is not None else None)
        return self.ctx.rate_error(self.rate.clock().sample_rate_hz, dur)

    def finish(self, rep: Repairer, sha256: str, options: dict[str, Any],
               cache: RowCache | None, reader: ScanReader) -> tuple[LogScan, ScanPass]:
        """The scan: drop the joints without data, warn, the header, clock, gaps, screen."""
        from .channels import (
            describing_only,
            drop_empty_signals,
            drop_message,
            empty_joint_reasons,
            warn_dropped,
        )

        ctx, plan = self.ctx, self.ctx.plan
        joints = ctx.joints
        dropped = empty_joint_reasons(joints, self.pos_finite, self.torque_finite,
                                      plan.torque_source)
        if len(dropped) == len(joints):
            raise LogFormatError(drop_message(ctx.where, dropped, plan.torque_source))
        repairs = ctx.pre_repairs() + rep.repairs()
        for msg in repairs:
            warnings.warn(msg, ImpactWarning, stacklevel=3)
        warn_dropped(ctx.where, dropped)
        out = {j for j, _ in dropped}
        keep = [k for k, j in enumerate(joints) if j not in out]
        kept = tuple(joints[k] for k in keep)
        gone, ignored, msgs = drop_empty_signals(
            ctx.where, kept, {s: self.opt_finite[s][keep] for s in plan.optional})
        allbad = frozenset(int(c) for c in np.flatnonzero(rep.empty))
        shift = int(self.head_t[0]) if ctx.start_at_zero and self.head_t.size else 0
        source = LogSource(path=ctx.where, sha256=sha256, format=ctx.fmt,
                           torque_source=plan.torque_source,
                           time_source=ctx.time_source,  # type: ignore[arg-type]
                           ignored_channels=plan.ignored + tuple(ignored),
                           repairs=tuple(repairs) + tuple(msgs),
                           notes=plan.notes, joints_dropped=tuple(dropped),
                           truncated=ctx.cut_short())
        head = {s: _nan_where_empty(a, s, ctx, allbad)[:, keep] for s, a in self.head.items()
                if s not in gone}
        log = RobotLog(t_ns=self.head_t - shift, joint_names=kept, source=source, **head)
        self.check_finite(keep, gone)
        found = self.defects
        found.finish()
        if found.shuffled:
            raise LogFormatError(shuffled_message(ctx.where, found, joints))
        wraps = tuple(dataclasses.replace(w, t_ns=w.t_ns - shift) for w in found.wraps
                      if w.joint in keep)
        ref_wraps = tuple(dataclasses.replace(w, t_ns=w.t_ns - shift)
                          for w in self.ref_turns.wraps if w.joint in keep)
        jumps = tuple(dataclasses.replace(x, joint=keep.index(x.joint), t_ns=x.t_ns - shift)
                      for x in found.jumps if x.joint in keep)
        verdict, limit_msgs = self.unit_verdict(keep, kept, options)
        given = options.get("position_unit") is not None
        if verdict.kind == "refuse" and not given and not describing_only():
            raise LogFormatError(verdict.message)
        said = [verdict.message] if verdict.kind != "ok" else []
        said += [wrap_message(ctx.where, wraps, joints)] if wraps else []
        said += ([wrap_message(ctx.where, ref_wraps, joints, "the reference of ")]
                 if ref_wraps else [])
        clock = self.hist.clock()
        vel = self.velocity_rate(keep, clock.sample_rate_hz)
        said += [vel] if vel is not None else []
        two: tuple[tuple[float, float, tuple[str, ...]], ...] = ()
        if self.velocity_is_derivative(keep, clock.sample_rate_hz):
            told = disagreement_message(ctx.where, self.agreement, keep, joints,
                                        int(self.head_t[0]), int(self.hist.last or 0))
            said += [told] if told is not None else []
            two = disagreement_stretches(self.agreement, keep, joints, int(self.head_t[0]))
        for msg in (*said, *limit_msgs):
            warnings.warn(msg, ImpactWarning, stacklevel=3)
        optional = tuple(s for s in OPTIONAL_CHANNELS if getattr(log, s) is not None)
        ps = ScanPass(ctx, allbad, keep, optional, shift, self.n, rep.order_keep,
                      cache if cache is not None and cache.usable else None,
                      rep.order_repair, wraps, ref_wraps)
        self.gaps.add(np.zeros(0, dtype=np.int64), self.floor, last=True)
        if not self.gaps.exact_for(clock):  # the rate moved: a second pass at the threshold
            self.gaps = _gap_pass(ps, clock)
        idx, lengths = self.gaps.gaps(clock)
        screens = {s: self.screens[s].result().select(keep) for s in self.screens
                   if getattr(log, s) is not None}
        poses = self.poses.select(keep)
        posed = pose_explained(poses)
        ranges = {s: (lo[keep], hi[keep]) for s, (lo, hi) in self.ranges.items()}
        ranges.update({s: (sc.lo, sc.hi) for s, sc in screens.items()})
        scan = LogScan(log=log, n_samples=self.n, t0_ns=int(self.head_t[0]) - shift,
                       t_last_ns=int(self.hist.last or 0) - shift, clock=clock, gaps=idx,
                       gap_lengths_s=lengths,
                       torque_screen=screens["torque"].unusable(posed=posed),
                       screens=screens, options=dict(options), reader=reader,
                       ranges={s: ranges[s] for s in _arrays_of(log)},
                       position_unit=verdict, warnings=(*said, *limit_msgs), jumps=jumps,
                       n_jumps=len(jumps), poses=poses, torque_posed=posed,
                       disagreements=two)
        return scan, ps


def _arrays_of(log: RobotLog) -> list[str]:
    """The arrays a log has, in :class:`~impactcli.types.RobotLog`'s order."""
    return [s for s in (*REQUIRED_CHANNELS, *OPTIONAL_CHANNELS) if getattr(log, s) is not None]


def _nan_where_empty(a: np.ndarray, signal: str, ctx: StreamLayout,
                     allbad: frozenset[int]) -> np.ndarray:
    """``a`` with NaN in the columns of joints whose column holds no finite value (such a
    column is NaN in the log; a ±inf would survive in the first rows). The log's torque
    comes from the torque source's column: an empty ``.torque`` column does not touch a
    torque read from ``.current``."""
    names = ctx.names
    column = ctx.plan.torque_source if signal == "torque" else signal
    out = np.array(a, dtype=np.float64)
    for (sig, j), key in ctx.keys.items():
        if names.index(key) in allbad and sig == column:
            out[:, j] = np.nan
    return out


def _repaired(ps: ScanPass) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The repaired rows of a pass over the layout's rows after the scan (as the scan's)."""
    rep = Repairer(ps.layout, ps.allbad, ps.order_keep, ps.order_repair)
    n = 0
    try:
        for t, mat in _blocks(ps.layout, rep):
            n += t.size
            yield t, mat
    except RepairOrderNeeded:
        raise LogFormatError(f"{ps.layout.where}: changed since it was scanned") from None
    if rep.first_error() is not None or n != ps.n_samples:
        raise LogFormatError(f"{ps.layout.where}: changed since it was scanned")


def _gap_pass(ps: ScanPass, clock: SampleClock) -> GapStream:
    """Gap candidates at the final threshold: a second pass over the times (the scan's
    cache, else the layout's rows)."""
    gs = GapStream()
    cache = ps.cache
    if cache is not None and cache.usable:
        times: Iterator[tuple[np.ndarray, Any]] = cache.blocks(1 << 20, times_only=True)
    else:
        times = _repaired(ps)
    for t, _ in times:
        gs.add(t, clock.gap_threshold_s * 1e9)
    gs.add(np.zeros(0, dtype=np.int64), clock.gap_threshold_s * 1e9, last=True)
    return gs


def pass_chunks(ps: ScanPass, chunk_rows: int) -> Iterator[LogChunk]:
    """A pass after the scan: chunks of ``chunk_rows`` repaired samples, from the scan's
    cache of the repaired rows (:mod:`impactcli.logs.row_cache`), else from the layout."""
    from . import row_cache as stream_cache

    if ps.cache is not None and ps.cache.usable:
        chunks = stream_cache.chunks(ps, ps.cache, chunk_rows)
    else:
        chunks = chunked((ps.arrays(t, mat) for t, mat in _repaired(ps)), chunk_rows)
    if not ps.wraps and not ps.ref_wraps:
        return chunks
    return _unwrapped(chunks, ps.wraps, ps.ref_wraps, ps.keep)


def _unwrapped(chunks: Iterator[LogChunk], wraps: tuple[Wrap, ...],
               ref_wraps: tuple[Wrap, ...], keep: list[int]) -> Iterator[LogChunk]:
    """The chunks with the scan's whole turns removed from their positions and references
    (:mod:`impactcli.logs.defects`)."""
    for ch in chunks:
        ref = ch.position_ref
        yield dataclasses.replace(
            ch, position=unwrap_positions(ch.position, ch.start, wraps, keep),
            position_ref=None if ref is None else unwrap_positions(ref, ch.start, ref_wraps,
                                                                   keep))


def wrap_message(where: str, wraps: tuple[Wrap, ...], joints: tuple[str, ...],
                 what: str = "") -> str:
    """The warning that the positions (``what``: the reference's) were unwrapped
    (``wraps`` on the layout's joints)."""
    names = sorted({joints[w.joint] for w in wraps}, key=joints.index)
    first = wraps[0]
    return (f"{where}: {what}joint(s) {', '.join(names)} step by a whole turn ({len(wraps)} "
            f"step(s), the first on {joints[first.joint]} at sample {first.i}, "
            f"{first.t_ns * 1e-9:.3f} s): unwrapped, as an angle logged modulo 2π")


def shuffled_message(where: str, found: DefectScan, joints: tuple[str, ...]) -> str:
    """The refusal of rows that cannot be consecutive."""
    return (f"{where}: rows that cannot be consecutive: the joints move, in the median, by "
            f"more than {SHUFFLED_STEP_SHARE:g} of their range from one sample to the next "
            f"({found.describe(joints)}); the rows are shuffled or several recordings "
            "interleaved: sort them by time, or split the recordings into separate logs")
