"""The replay of one log: a log source and a setup in, a detection result out.

:func:`detect_log` is the one routine every verb runs (a log file read in chunks, or a log
in memory: one chunk). It plans the run from the log's scan (:mod:`impactcli.run.plan`),
replays the chunks in order (:class:`impactcli.run.replay.Replayer`: state in, state out; a
pass that is threshold-free, :func:`replay_passes`), applies the thresholds — the
calibrated config's as it goes; without them, the log's own, from the statistics spilled
by the replay once the warm-up's end is known, then applied over the spill — and hands each
chunk's signals, decisions and ratios to ``on_chunk`` (the writers, or a collector). What it
keeps meanwhile is small: the warm-up's statistics
(:class:`~impactcli.detect.warmup.WarmupTracker`), the times at the gaps, and the *islands*:
the samples where some detector fires or a contact still presses
(:meth:`impactcli.detect.incident_builder.IncidentContext.pressing`), and those within
``merge_gap_s`` after one; and each joint's largest logged torque (the force plausibility
check). Events and incidents never span a sample outside an island, so each island gives
its events, incidents and lasting loads by :func:`~impactcli.detect.events.extract_events`
and :func:`~impactcli.detect.incident_builder.build_findings` once the warm-up's end is
known; the incidents are then numbered (:func:`~impactcli.detect.incident_builder.
number_incidents`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..config import THRESHOLD_KEYS, CalibrationRecord, DetectorConfig
from ..detect.adaptive import AdaptiveResult, default_threads
from ..detect.aftermath import close_behind, mark_aftermath
from ..detect.envelope import (
    EnvelopeCheck,
    MotionEnvelope,
    outside_share_text,
    posture_text,
)
from ..detect.events import extract_events
from ..detect.floor import FloorAccumulator, gain_per_sample
from ..detect.force import OFF_SCALE
from ..detect.incident_builder import (
    IncidentContext,
    beside,
    build_findings,
    incident_context,
    number_incidents,
    poorly_determined,
)
from ..detect.incidents import (
    BRIDGE_FRACTION,
    Incident,
    LastingLoad,
    adaptive_memory_s,
    blind_of,
    data_defects,
    defects_dict,
    mark_defects,
    mark_disagreeing,
    mark_payload_changes,
    mark_resumed,
    on_at_warmup_end,
    settle_s,
)
from ..detect.link_evidence import ResidualNoise
from ..detect.payload_change import mark_tried
from ..detect.probe import (
    MAX_STATE_BYTES,
    PROBES,
    ProbeRecorder,
    probe_indices,
    probe_window,
    probed_floor,
)
from ..detect.rates import resolve_rates
from ..detect.release import BLOCK_S as RELEASE_BLOCK_S
from ..detect.release import BlockTrace, mark_held
from ..detect.thresholds import compare_to_thresholds, uncalibrated_blocks
from ..detect.warmup import Warmup, WarmupTracker, past_least
from ..errors import ConfigError, ImpactWarning
from ..logs.reader import LogReader
from ..model.generators import choices_dict, summary_name, uses_correction
from ..model.rigid import RigidModel
from ..spill import ColumnFiles
from ..types import (
    DETECTORS,
    DetectionResult,
    Event,
    LogHeader,
    ReadOptions,
    RobotDescription,
    SignalsChunk,
)
from .islands import Islands
from .loads import (
    load_motion,
    mark_unseen,
    monitor_for,
    start_unknown,
    unseen_loads,
    unseen_spans,
    unwatched_reason,
    unweighed_reason,
    weighs_loads,
)
from .plan import ChunkFeed, Passes, RunPlan, calibrated_thresholds, plan_run, with_generator
from .replay import ChunkReplay, Replayer, ReplaySetup, ReplayState
from .run_warnings import (
    CaughtWarnings,
    moved_unchecked,
    unchecked_message,
    warn_beyond_effort,
    warn_defect_incidents,
    warn_events_after_gaps,
    warn_gaps,
    warn_implausible_forces,
    warn_late_warmup,
    warn_long_events,
    warn_outside_envelope,
    warn_uncalibrated,
    warn_unwatched_loads,
    warn_warmup,
)

#: Samples per chunk of a log read from a file (about 40 MB of signals for 7 joints): the
#: signals Parquet gets one row group per chunk.
CHUNK_ROWS = 65_536


@dataclass(frozen=True)
class RunSetup:
    """What a replay is run with, besides the log.

    Attributes:
        config: the detector config (``--config``), or None (Table I defaults, thresholds
            from the log's own statistics).
        model: ``--model``, or None (the config's, else identified from the log).
        robot: the robot description (kinematics, joint order).
        generator: ``--generator`` (:func:`impactcli.run.plan.with_generator`), None: the
            config's.
        model_from_log: identify the model from this log even with a config
            (:func:`impactcli.run.plan.resolve_model`); refused with ``model``.
        allow_slow: run even when the replay is estimated slower than real time.
        config_where: the config's file, for messages.
        read_options: how the log was read (recorded in the result).
        chunk_rows: samples per chunk (the result does not depend on it).
    """

    config: DetectorConfig | None = None
    model: RigidModel | None = None
    robot: RobotDescription | None = None
    generator: str | None = None
    model_from_log: bool = False
    allow_slow: bool = False
    config_where: str = "config"
    read_options: ReadOptions = field(default_factory=ReadOptions)
    chunk_rows: int = CHUNK_ROWS


@dataclass
class ReplayStep:
    """One chunk replayed: its first sample, (n,) times [s since the first sample] and
    [ns], the log's (n, J_all) positions, and the replay's (n, J) arrays
    (:class:`impactcli.run.replay.ChunkReplay`; ``gain``: a blow's gain through G_hat as it
    stood, :func:`impactcli.detect.floor.gain_per_sample`); the writers' arrays None where
    not kept."""

    start: int
    t: np.ndarray
    t_ns: np.ndarray
    q_full: np.ndarray
    r: np.ndarray
    loading: np.ndarray
    qd: np.ndarray
    r_rms: np.ndarray
    v_rms: np.ndarray
    gain: np.ndarray
    r_tilde: np.ndarray | None = None
    v_dyn: np.ndarray | None = None
    torque: np.ndarray | None = None
    position: np.ndarray | None = None
    position_ref: np.ndarray | None = None


#: What a step needs for the events and incidents; the rest only for ``on_chunk``.
_NEEDED = ("t", "t_ns", "q_full", "r", "loading", "qd", "r_rms", "v_rms", "gain", "torque")
_FOR_WRITERS = ("r_tilde", "v_dyn", "position", "position_ref")


@dataclass
class Replayed:
    """What a replay pass leaves: the warm-up and each joint's warm-up end [s], the (G, 2)
    times [s] of the samples at and just after each gap, the last chunk's evaluator result
    (its final filter), the threshold inputs' source and how they were made, and (J,) the
    largest |torque| logged per joint [N·m] (NaN where none is finite), and the probes of
    the measured floor (:mod:`impactcli.detect.probe`)."""

    warmup: Warmup
    warmup_times: list[float]
    gap_times: np.ndarray
    last: AdaptiveResult
    reference: str
    detail: str
    torque_peak: np.ndarray
    probes: ProbeRecorder | None = None


def probe_recorder(plan: RunPlan, n_samples: int, sample_rate_hz: float) -> ProbeRecorder:
    """The measured floor's probes (:mod:`impactcli.detect.probe`): after the warm-up's
    earliest possible end (``warmup.min_s``; those that fall before the end found are
    dropped, :func:`detect_log`), at least the RLS's memory apart (1 / (1 − lambda)
    samples), as many as the kept states' bytes allow."""
    cfg = plan.cfg
    rates = resolve_rates(cfg.adaptive, sample_rate_hz)
    window = probe_window(sample_rate_hz, rates.n1, rates.a1)
    hold = math.ceil(cfg.warmup.min_s * sample_rate_hz) + 1
    nu = cfg.adaptive.n_params(len(plan.joints))
    count = min(PROBES, MAX_STATE_BYTES // max(1, 8 * len(plan.joints) * nu * nu))
    memory = round(1.0 / max(1.0 - cfg.adaptive.forgetting_factor, 1e-12))
    return ProbeRecorder(probe_indices(n_samples, hold, window, count, memory), window)


def replay_passes(feed: ChunkFeed, plan: RunPlan, on_step: Callable[[ReplayStep], None],
                  passes: Passes | None = None, monitor: Any = None,
                  probe: bool = False) -> Replayed:
    """One threshold-free replay pass over the log's chunks (module docstring): each
    chunk's :class:`ReplayStep` to ``on_step``, in order; the warm-up tracked; ``monitor``
    the payload-change monitor (:func:`impactcli.run.loads.monitor_for`) or None;
    ``probe``: keep what the measured floor needs (:func:`probe_recorder`)."""
    scan = feed.scan
    n = scan.n_samples
    setup = ReplaySetup(plan.joints, plan.choices, plan.model, plan.cfg, scan.sample_rate_hz,
                        scan.sample_period_s, threads=default_threads(n), monitor=monitor)
    tracker = WarmupTracker(n, 0.0, scan.duration_s, len(plan.joints), plan.cfg.warmup)
    gaps = np.asarray(scan.gaps, dtype=np.int64)
    gap_times = np.full((gaps.size, 2), np.nan)
    last: list[Any] = [None, "", ""]
    peak = np.full(len(plan.joints), np.nan)
    gain_before: list[np.ndarray | None] = [None]  # the last sample's, for the next chunk
    probes = probe_recorder(plan, n, scan.sample_rate_hz) if probe else None
    rp = Replayer(setup, ReplayState.initial(setup), where=plan.where, consume=True,
                  probes=probes)

    def steps(done: list[tuple[Any, ChunkReplay]]) -> None:
        for (ch, t, a), out in done:
            ad = out.adaptive
            last[:] = [ad, out.inputs_source, out.inputs_detail]
            k0 = ch.start
            if probes is not None:
                probes.posture(k0, np.asarray(ch.position))
            tracker.update(ad.prediction_error, t)
            tau = np.abs(np.asarray(a.torque, dtype=np.float64))
            if tau.size:
                peak[:] = np.fmax(peak, np.max(np.where(np.isfinite(tau), tau, -np.inf), axis=0))
            for col, off in ((0, 0), (1, 1)):
                hit = (gaps + off >= k0) & (gaps + off < k0 + t.shape[0])
                gap_times[hit, col] = t[gaps[hit] + off - k0]
            gain = gain_per_sample(ad.theta_g, t.shape[0], k0, ad.rates.sample_rate_hz,
                                   ad.rates.a1, ad.rates.n1, gain_before[0])
            if gain.shape[0]:
                gain_before[0] = np.array(gain[-1])
            on_step(ReplayStep(k0, t, np.asarray(ch.t_ns, dtype=np.int64),
                               np.asarray(ch.position, dtype=np.float64), out.r, out.loading,
                               out.qd, ad.r_rms, ad.v_rms, gain, ad.r_tilde, ad.v_dyn,
                               a.torque, a.position, a.position_ref))
            if passes is not None:
                passes.at(float(t[-1]))

    try:
        for ch, t, a in feed.chunks(plan.joints):
            steps(rp.feed((ch, t, a), a))
        steps(rp.finish())  # the level under the start's load when it changed (warmup.py)
        wu = tracker.finish(monitor.changes[0].t_start if monitor and monitor.changes else None)
    except BaseException:  # nothing left behind: the tracker's spill is a temporary file
        tracker.close()
        raise
    finally:
        rp.close()
    if passes is not None:
        passes.next()
    assert last[0] is not None
    peak[~np.isfinite(peak)] = np.nan
    return Replayed(wu, tracker.times_at(wu.index), gap_times, last[0], last[1], last[2], peak,
                    probes)


def warn_replayed(caught: CaughtWarnings, since: int, plan: RunPlan, feed: ChunkFeed,
                  rp: Replayed) -> None:
    """The replay's warnings about the whole log: the gaps (before the replay's own
    warnings, recorded since ``since``), the threshold inputs, the warm-up."""
    scan = feed.scan
    moved = caught.cut(since)
    warn_gaps(plan.where, np.asarray(scan.gap_lengths_s), rp.gap_times[:, 0])
    caught.paste(moved)
    warn_warmup(plan.where, rp.warmup, rp.warmup_times, plan.joints, scan.n_samples,
                scan.duration_s, plan.cfg)


def detect_log(reader: LogReader, setup: RunSetup = RunSetup(), *,
               on_chunk: Callable[[SignalsChunk], None] | None = None,
               progress: Callable[[float, float], None] | None = None) -> DetectionResult:
    """Replay the detectors over a log exactly as the robot would have run them online
    (module docstring).

    Args:
        reader: the log (:func:`impactcli.logs.reader.open_log`); the caller closes it.
        setup: config, model, robot... (:class:`RunSetup`).
        on_chunk: called per chunk, in order, with its :class:`~impactcli.types.SignalsChunk`.
        progress: called with (seconds of log done, seconds to do), summed over the passes
            (identification, replay, comparison over the spill).
    Returns:
        The result (its ``log`` a :class:`~impactcli.types.LogHeader`, no per-sample
        signals); the ImpactWarnings raised on the way are in its ``warnings``.
    """
    cfg = with_generator(setup.config or DetectorConfig(), setup.generator, setup.config_where)
    if setup.model is not None and setup.model_from_log:
        raise ConfigError("--model and --model-from-log exclude each other")
    with CaughtWarnings() as caught, contextlib.ExitStack() as stack:
        scan = reader.scan()
        where = scan.source.path
        passes = Passes(scan.duration_s, progress)
        if not cfg.calibration.calibrated:
            passes.add()  # the comparison over the spill
        plan, feed = plan_run(reader, cfg, model=setup.model, robot=setup.robot,
                              model_from_log=setup.model_from_log,
                              allow_slow=setup.allow_slow, config_where=setup.config_where,
                              chunk_rows=setup.chunk_rows, passes=passes)
        joints = plan.joints
        given = calibrated_thresholds(cfg, joints)
        if given is not None:  # a joint a detector checks in name only
            warn_beyond_effort(cfg, joints, setup.robot, where)
        since = caught.mark()
        monitor = monitor_for(plan, given, scan.sample_rate_hz)
        rp, thr, margins, islands, envelope, floor_acc, trace = _detect_passes(
            feed, plan, given, on_chunk, passes, monitor)
        stack.callback(islands.close)
        warn_replayed(caught, since, plan, feed, rp)
        if given is None:
            cfg = uncalibrated_config(cfg, joints, margins)
            warn_uncalibrated(where, weighs_loads(plan), uncalibrated_blocks(
                scan.n_samples, rp.warmup.end_index, scan.sample_rate_hz))
        since = caught.mark()  # the incidents' warnings follow the events' (as ever)
        model_doc = None if plan.model is None else plan.model.to_dict()
        ctx = incident_context(joints, plan.full_joints, setup.robot, model_doc,
                               thr["static_loading"], scan.sample_period_s, scan.t0_ns,
                               scan.n_samples, cfg.events.merge_gap_s, where, rp.torque_peak,
                               plan.gravity_hold)
        if (uses_correction(plan.choices, cfg.residual.logged_correction)
                or any(c.generator != "inverse_dynamics" for c in plan.choices)
                or not poorly_determined(model_doc)):
            ctx = dataclasses.replace(ctx, torque_peak=None)  # r is not τ̂ − τ, or the
            # model is determined: its torque is not held against the logged one
        ctx_msgs = caught.cut(since)
        events, incidents, loads = _events_and_incidents(islands, rp.warmup, joints, cfg, ctx)
        incidents = mark_resumed(incidents, loads, settle_s(cfg.static_loading.cutoff_hz,
                                                            cfg.adaptive.n2_s))
        if (given is not None and any(not x.in_warmup for x in loads)
                and (why := unwatched_reason(plan)) is not None):  # a load, unweighed?
            warn_unwatched_loads(where, why, plan.start_load is not None)
        defects = data_defects(scan, rp.gap_times)
        settle = settle_s(cfg.static_loading.cutoff_hz, cfg.adaptive.n2_s)
        memory = adaptive_memory_s(cfg.adaptive.forgetting_factor, scan.sample_rate_hz)
        settled = rp.warmup.end_s if rp.warmup.end_s < cfg.warmup.max_s else None  # not capped
        changes = [] if monitor is None else start_unknown(monitor.changes, plan.start_load)
        if (unseen := unseen_loads(where, plan.model, changes)) is not None:
            warnings.warn(unseen, ImpactWarning, stacklevel=2)
        marked, changes = mark_payload_changes(
            mark_defects(incidents, defects, settle, memory, settled), changes, settle, settle,
            lambda inc, change: None if change.part is None else beside(ctx, inc, change.part))
        uncalibrated = unseen_spans(plan.model, plan.start_load, changes,
                                    scan.duration_s + scan.sample_period_s)
        incidents = mark_disagreeing(mark_unseen(number_incidents(marked), uncalibrated),
                                     scan.disagreements)  # the data's, maybe (velocity_check)
        incidents = mark_held(incidents, trace.finish(), trace.per_block,
                              scan.sample_period_s, joints, loads)  # a push released
        loads = mark_unseen(loads, uncalibrated)
        if monitor is not None:  # what the alarms the monitor weighed are not
            incidents = mark_tried(incidents, monitor.tried, cfg.events.merge_gap_s)
            loads = mark_tried(loads, monitor.tried, cfg.events.merge_gap_s)
        if plan.torque_scale is not None and plan.torque_scale.kind == "warn":
            start_kg = next((kg for t0, _, kg in uncalibrated if t0 == 0.0), None)
            incidents = off_scale(incidents, plan.torque_scale.scale, start_kg)
            loads = off_scale(loads, plan.torque_scale.scale, start_kg)
        warn_events_after_gaps(where, rp.gap_times[:, 1], events)
        warn_long_events(where, events)
        if plan.torque_scale is None or plan.torque_scale.kind != "warn":  # said already
            # the counted ones: not a data defect's, not the warm-up's (filters starting)
            warn_implausible_forces(where, [i for i in (*incidents, *loads)
                                            if getattr(i, "data_defect", None) is None
                                            and not getattr(i, "in_warmup", False)])
        warn_defect_incidents(where, defects, incidents, settle, memory)
        warn_late_warmup(where, past_least(incidents, cfg.warmup.min_s), cfg.warmup.min_s,
                         rp.warmup.end_s, scan.duration_s)
        caught.paste(ctx_msgs)
        outside = None
        measured_checked = False
        if envelope is not None:  # the motion the thresholds' rate was not measured on
            share = envelope.finish(rp.warmup.end_index)
            outside = share.to_dict()
            incidents = [dataclasses.replace(i, outside_envelope=share.touches(i.t_start,
                                                                              i.t_end))
                         for i in incidents]
            if share.measured is not None:  # alarms while the arm had not settled
                incidents = mark_aftermath(incidents, share.measured, settle)
                measured_checked = True
            warn_outside_envelope(where, outside_share_text(share), share.outside,
                                  sum(1 for i in incidents  # the counted ones
                                      if i.outside_envelope and i.number is not None),
                                  posture_text(share.posture), share.note)
        if envelope is not None and envelope.loads:  # a load on motion its log lacked
            incidents = load_motion(where, plan, envelope, incidents, rp.warmup.end_index,
                                    changes, scan.duration_s + scan.sample_period_s)
        incidents = close_behind(incidents, settle, measured_checked)
        floor = floor_acc.finish(rp.warmup.index, rp.warmup.end_index, joints, ctx.chain,
                                 ctx.index, ctx.chain_cols, ctx.jac)
        if rp.probes is not None and (probed := probed_floor(
                [p for p in rp.probes.done() if p.k >= rp.warmup.end_index],
                thr["adaptive"], thr["static_loading"],
                scan.sample_rate_hz,
                (cfg.static_loading.cutoff_hz, cfg.static_loading.order), joints,
                (cfg.events.merge_gap_s, cfg.events.min_duration_s),
                ctx.chain, ctx.index, ctx.chain_cols, ctx.jac)) is not None:
            floor = {**floor, "probed": probed}
        left_out = moved_unchecked(plan.left_out, scan.log.joint_names,
                                   scan.ranges.get("position"))
        moved = [x for x in left_out if "travel_rad" in x]
        if moved:
            warnings.warn(unchecked_message(where, moved), ImpactWarning, stacklevel=2)
            if outside is not None:
                outside["unchecked"] = sorted({*outside.get("unchecked", ()),
                                               *(x["name"] for x in moved)})
        header = LogHeader(joints, scan.source, scan.n_samples, scan.t0_ns, scan.duration_s,
                           scan.sample_rate_hz, scan.sample_period_s)
    caught.raise_again()
    freqs, gain = rp.last.g_gain()
    thresholds = {j: {key: float(thr[det][k]) for det, key in THRESHOLD_KEYS.items()}
                  for k, j in enumerate(joints)}
    rig = plan.model
    return DetectionResult(
        log=header, model=None if rig is None else rig.to_dict(),
        model_sha256=None if rig is None else rig.sha256, model_source=plan.model_source,
        config=cfg.to_dict(), calibrated=given is not None, thresholds=thresholds,
        reference_source="measured" if rp.reference == "measured" else "reference",
        threshold_inputs=rp.detail, torque_filtered=cfg.residual.filter_torque,
        events=tuple(events),
        warmup_end_s=rp.warmup.end_s, warmup_per_joint_s=dict(zip(joints, rp.warmup_times,
                                                                  strict=True)),
        filter_gain={"frequencies_hz": [float(f) for f in freqs],
                     "gain": {j: [float(g) for g in gain[k]] for k, j in enumerate(joints)}},
        residual_generator=summary_name(plan.choices), read_options=setup.read_options,
        generators=choices_dict(plan.choices, cfg.residual.logged_correction),
        joints_left_out=tuple(left_out),
        incidents=tuple(incidents), lasting_loads=tuple(loads), motion_envelope=outside,
        detection_floor=floor,
        data_defects=(defects_dict(defects, settle, scan.n_jumps,
                                   blind_of(defects, settle, memory, settled,
                                            rp.warmup.end_s, scan.duration_s))
                      if defects else None),
        torque_scale=None if plan.torque_scale is None else plan.torque_scale.to_dict(),
        payload=None if plan.start_load is None else plan.start_load.to_dict(),
        payload_changes=(None if monitor is None
                         else tuple(c.to_dict() for c in changes)),
        payloads_unwatched=unweighed_reason(plan),
        robot=None if setup.robot is None else setup.robot.to_dict(),
        warnings=tuple(dict.fromkeys((*scan.warnings, *caught.messages()))),  # scan's first
    )


def off_scale(findings: Sequence[Any], scale: float | None,
              start_kg: float | None = None) -> list[Any]:
    """Incidents or lasting loads of a log whose torque scale is off (the run warned,
    :mod:`impactcli.model.gravity`): each force is flagged implausible, saying why
    (:data:`~impactcli.detect.force.OFF_SCALE`; ``start_kg``: a load the log starts with
    that no calibration log carried, said as the other explanation)."""
    load = ("" if start_kg is None else
            f", or by the load it starts with that no calibration log carried "
            f"({start_kg:+.3g} kg): the tool cannot tell the two apart")
    why = (f"{OFF_SCALE} by ~{scale:.3g}×{load} (input.torque_scale): no force from it "
           "can be trusted")
    return [x if x.force_n is None else dataclasses.replace(
        x, force_plausible=False, force_check=why) for x in findings]


def _detect_passes(
    feed: ChunkFeed, plan: RunPlan, given: dict[str, np.ndarray] | None,
    on_chunk: Callable[[SignalsChunk], None] | None, passes: Passes, monitor: Any = None,
) -> tuple[Replayed, dict[str, np.ndarray], dict[str, np.ndarray], Islands,
           EnvelopeCheck | None, FloorAccumulator, BlockTrace]:
    """The replay and the comparison (module docstring): with thresholds ``given``, one
    pass that compares as it goes; without, a pass that spills, the thresholds from what it
    spilled, then the comparison over the spill. Returns the replay, the thresholds, their
    margins (uncalibrated), the islands (the caller closes them), the motion envelope's
    check (None without one) and the detection floor's accumulator."""
    made: list[_Compare] = []   # the comparison, once made (its islands closed on failure)

    def compare(thr: dict[str, np.ndarray]) -> _Compare:
        made.append(_Compare(thr, plan.cfg, on_chunk, plan.joints, feed.scan.sample_period_s,
                             envelope_check(plan.cfg, plan.joints, feed.scan.sample_rate_hz),
                             feed.scan.n_samples))
        return made[-1]

    margins: dict[str, np.ndarray] = {}
    try:
        if given is not None:
            thr = given
            comparing = compare(thr)
            rp = replay_passes(feed, plan, comparing.update, passes, monitor, probe=True)
        else:
            keys = _NEEDED + (_FOR_WRITERS if on_chunk is not None else ())
            with contextlib.closing(ColumnFiles()) as spill:
                rp = replay_passes(feed, plan, lambda st: spill.append(
                    {k: v for k in keys if (v := getattr(st, k)) is not None}), passes,
                    probe=True)
                scan = feed.scan
                thr, margins = _thresholds_from_spill(spill, rp.warmup, scan.n_samples,
                                                      scan.sample_rate_hz)
                comparing = compare(thr)
                for k0, arrays in spill.chunks():
                    comparing.update(ReplayStep(k0, **arrays))
                    passes.at(float(arrays["t"][-1]))
                passes.next()
        comparing.islands.finish()
    except BaseException:  # nothing left behind: the islands are temporary files
        for c in made:
            c.islands.close()
        raise
    return rp, thr, margins, comparing.islands, comparing.envelope, comparing.floor, \
        comparing.trace


def envelope_check(cfg: DetectorConfig, joints: tuple[str, ...], sample_rate_hz: float
                   ) -> EnvelopeCheck | None:
    """The check of the log's motion against the motion envelope the config's calibration
    recorded (:mod:`impactcli.detect.envelope`; docs/validation.md), None without one."""
    env = cfg.calibration.motion_envelope
    if not env:
        return None
    return EnvelopeCheck(MotionEnvelope.from_dict(env), sample_rate_hz, joints,
                         loads=cfg.calibration.load_envelopes or ())


def _thresholds_from_spill(spill: ColumnFiles, wu: Warmup, n: int, sample_rate_hz: float,
                           ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The uncalibrated rule's thresholds and margins per detector
    (:func:`impactcli.detect.thresholds.thresholds_from_maxima`) from the statistics after
    the warm-up's end (all of them if it covers the log), read back block by block."""
    from ..detect.thresholds import BlockMaxima, thresholds_from_maxima, uncalibrated_span

    start, block = uncalibrated_span(n, wu.end_index, sample_rate_hz)
    bms = {d: BlockMaxima(start, block) for d in DETECTORS}
    for k0, a in spill.chunks(("r", "loading", "r_rms", "v_rms")):
        if k0 + a["r"].shape[0] <= start:
            continue
        bms["adaptive"].update(k0, a["r_rms"] - a["v_rms"])
        bms["static_loading"].update(k0, a["loading"])
        bms["static_baseline"].update(k0, np.abs(a["r"]))
    cals = {d: thresholds_from_maxima(bm.finish(), bm.block) for d, bm in bms.items()}
    return ({d: c.thresholds for d, c in cals.items()},
            {d: c.margins for d, c in cals.items()})


def uncalibrated_config(cfg: DetectorConfig, joints: tuple[str, ...],
                        margins: dict[str, np.ndarray]) -> DetectorConfig:
    """The config an uncalibrated run records: its calibration record says the thresholds
    came from the log itself, by which rule and margins."""
    from ..detect.thresholds import UNCALIBRATED_RULE

    return dataclasses.replace(cfg, calibration=CalibrationRecord(
        calibrated=False, margin_rule=UNCALIBRATED_RULE,
        margins={d: {j: float(m) for j, m in zip(joints, ms, strict=True)}
                 for d, ms in margins.items()}))


class _Compare:
    """Thresholds applied to the replay's steps, in order (module docstring): decisions
    and ratios, the residual's running level and noise (the link's evidence,
    :class:`~impactcli.detect.link_evidence.ResidualNoise`), the islands, the writers'
    chunks."""

    def __init__(self, thr: dict[str, np.ndarray], cfg: DetectorConfig,
                 on_chunk: Callable[[SignalsChunk], None] | None,
                 joints: tuple[str, ...], dt: float,
                 envelope: EnvelopeCheck | None = None, n_samples: int = 0) -> None:
        self.thr, self.on_chunk, self.joints = thr, on_chunk, joints
        self.envelope = envelope
        # the detection floor; the warm-up ends by warmup.max_s (its samples held till then)
        self.floor = FloorAccumulator(len(joints), n_samples,
                                      math.ceil(cfg.warmup.max_s / dt) + 1,
                                      thr["static_loading"])
        self.islands = Islands(cfg.events.merge_gap_s)
        self.pressing_at = BRIDGE_FRACTION * np.maximum(thr["static_loading"], 1e-12)
        self.noise = ResidualNoise(len(joints), dt)
        self.trace = BlockTrace(len(joints), round(RELEASE_BLOCK_S / dt))  # a load released

    def update(self, st: ReplayStep) -> None:
        k0, t = st.start, st.t
        thr_ad, ratios, dec = compare_to_thresholds(self.thr, st.r_rms, st.v_rms, st.loading,
                                                    np.abs(st.r))
        any_d = np.asarray(dec["adaptive"].any(axis=1) | dec["static_loading"].any(axis=1)
                           | dec["static_baseline"].any(axis=1))
        pressing = np.any(st.loading >= self.pressing_at[None, :], axis=1)
        self.floor.update(st.loading, st.r_rms, thr_ad, st.q_full, st.gain)
        level, noise = self.noise.update(st.r)
        self.trace.update(st.r)
        if self.envelope is not None and st.position is not None:
            self.envelope.update_arrays(t, st.position, st.position_ref, k0)
        self.islands.update(k0, t, any_d, pressing, {
            "t": t, "r": st.r, "loading": st.loading, "qd": st.qd, "q_full": st.q_full,
            "r_level": level, "r_noise": noise,
            "tau": st.torque if st.torque is not None else np.full_like(st.r, np.nan),
            **{f"d.{d}": dec[d] for d in DETECTORS}, **{f"x.{d}": ratios[d] for d in DETECTORS}})
        if self.on_chunk is not None:
            assert st.torque is not None and st.r_tilde is not None and st.v_dyn is not None
            assert st.position is not None
            self.on_chunk(SignalsChunk(self.joints, t, st.t_ns, {
                "torque": st.torque, "residual": st.r, "filtered_residual": st.r_tilde,
                "dynamic_threshold": st.v_dyn, "residual_rms": st.r_rms, "threshold": thr_ad,
                "loading_statistic": st.loading}, dec, st.position, st.position_ref,
                ratios=ratios, start=k0))


def _events_and_incidents(islands: Islands, wu: Warmup, joints: tuple[str, ...],
                          cfg: DetectorConfig, ctx: IncidentContext,
                          ) -> tuple[list[Event], list[Incident], list[LastingLoad]]:
    """Every island's events (indices in the log, in timeline order), incidents (numbered)
    and lasting loads (:func:`impactcli.detect.incident_builder.build_findings`), each
    island read from its files once."""
    ev = cfg.events
    events: list[Event] = []
    incidents: list[Incident] = []
    loads: list[LastingLoad] = []
    for isl in islands.done:
        a = islands.arrays(isl)
        local: list[Event] = []
        for d in DETECTORS:
            local += extract_events(d, a[f"d.{d}"], a[f"x.{d}"], a["r"], a["t"], joints,
                                    wu.end_s, ev.merge_gap_s, ev.min_duration_s)
        local.sort(key=lambda e: (e.t_start, DETECTORS.index(e.detector)))
        incs, lds = build_findings(ctx, local, a["t"], a["r"], a["loading"], a["d.adaptive"],
                                   a["d.static_loading"], a["q_full"], a["qd"],
                                   offset=isl.start, event_offset=len(events),
                                   level=a["r_level"], noise=a["r_noise"], tau=a["tau"])
        incidents += incs
        loads += lds
        events += [dataclasses.replace(e, i_start=e.i_start + isl.start,
                                       i_end=e.i_end + isl.start) for e in local]
    return events, number_incidents(incidents), on_at_warmup_end(loads, events)
