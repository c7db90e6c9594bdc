"""Detection over a log read chunk by chunk, in bounded memory (day-long logs).

:func:`analyze_stream` gives the same :class:`~impactcli.result.DetectionResult` fields
as :func:`impactcli.pipeline.analyze` — the same timeline, byte for byte — without holding
the log or its per-sample signals in memory, for every input: with or without a config,
the model given, embedded in the config or identified from the log (``--model`` with
``--model-from-log`` is refused, as the whole-log replay refuses it). Without calibrated
thresholds they come from the log's own statistics once a first pass is over
(:data:`STRATEGIES`).

Two passes over the file (:mod:`impactcli.io.stream`):

1. the scan: provenance and sha256, the number of samples, the sample clock, the gaps and
   the columns' screen — every decision the whole-log replay takes before its first
   sample (:func:`impactcli.pipeline.screen_plan`, the model's joints, the generators);
2. the replay, chunk by chunk (:class:`impactcli.replay.Replayer`, state in, state
   out), thresholds applied to each chunk; per chunk the signals go to ``on_chunk`` (the
   Parquet writer appends a row group) and three small things are kept:

   - the warm-up's statistics (:class:`impactcli.detect.warmup.WarmupTracker`: the first
     ``warmup.max_s`` in memory, the later half's trailing RMS on disk);
   - the samples near an alarm — an *island*: every sample where some detector fires or
     the contact is still pressing (:meth:`impactcli.contacts.IncidentContext.pressing`),
     and those within ``events.merge_gap_s`` after one. Events and incidents never span
     a sample outside an island (two alarms further apart than the merge gap are two
     events, and a contact that bridges them presses at every sample between), so each
     island yields its events and incidents by the whole-log code
     (:func:`impactcli.detect.events.extract_events`,
     :func:`impactcli.contacts.build_incidents`) once the warm-up's end is known;
   - the times of the samples at the gaps, for the gap warnings.

Memory: the chunk (``chunk_rows`` samples) and its signals, the replay's state, the first
``warmup.max_s`` of the warm-up statistic, and the islands (about 14 floats per joint per
sample near an alarm: a log that alarms all the time keeps all of it).
"""

from __future__ import annotations

import contextlib
import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from .config import DetectorConfig
from .contacts import IncidentContext, build_incidents, incident_context
from .detect.adaptive import AdaptiveResult, default_threads
from .detect.events import extract_events
from .detect.incidents import BRIDGE_FRACTION, Incident
from .detect.screen import LeftOut
from .detect.warmup import Warmup, WarmupTracker
from .errors import ImpactWarning
from .model.generators import (
    choices_dict,
    choose_generators,
    needs_own_model,
    summary_name,
    uses_correction,
)
from .model.rigid import RigidModel
from .replay import ChunkArrays, ChunkReplay, Replayer, ReplaySetup, ReplayState
from .result import DetectionResult
from .sampling import check_calibrated_rate
from .spill import ChunkSpill, Islands
from .types import CONTROLLER_CHANNELS, DETECTORS, Event, LogSource, RobotDescription

#: Samples per chunk of a streamed replay (about 40 MB of signals for 7 joints).
CHUNK_ROWS = 65_536


@dataclass(frozen=True)
class StreamChunk:
    """What a streamed replay hands its writers per chunk: the replayed joints, (n,) times
    [s since the first sample] and [ns on the log's clock], signal name → (n, J)
    (:data:`impactcli.result.SIGNAL_NAMES`), detector → (n, J) decisions, and the (n, J)
    positions and reference positions (None when not logged)."""

    joints: tuple[str, ...]
    time_s: np.ndarray
    t_ns: np.ndarray
    signals: dict[str, np.ndarray]
    decisions: dict[str, np.ndarray]
    position: np.ndarray
    position_ref: np.ndarray | None


@dataclass(frozen=True)
class LogHeader:
    """What a streamed result tells of its log (a :class:`~impactcli.types.RobotLog`
    without its samples): the replayed joints, the provenance and the clock."""

    joint_names: tuple[str, ...]
    source: LogSource
    n_samples: int
    t0_ns: int
    duration_s: float
    sample_rate_hz: float
    sample_period_s: float

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)


class _Header:
    """The scan seen as a log by :func:`choose_generators` (joints, source, channels)."""

    def __init__(self, joint_names: tuple[str, ...], source: LogSource,
                 logged: dict[str, np.ndarray]) -> None:
        self.joint_names, self.source, self._logged = joint_names, source, logged

    def has_channel(self, signal: str) -> np.ndarray:
        return self._logged.get(signal, np.zeros(len(self.joint_names), dtype=bool))


#: How a run without calibrated thresholds gets them (module docstring): ``spill`` (the
#: replay's per-sample arrays to a temporary file, read back once the thresholds are
#: known) or ``reread`` (the statistics spilled, then the log read and replayed again).
STRATEGIES = ("spill", "reread")


@dataclass
class _Step:
    """One chunk replayed: its first sample, times, the log's (n, J_all) positions, the
    replay's arrays (:class:`impactcli.replay.ChunkArrays`, signals) and None for what the
    run does not keep."""

    k0: int
    t: np.ndarray
    t_ns: np.ndarray
    q_full: np.ndarray
    r: np.ndarray
    loading: np.ndarray
    qd: np.ndarray
    r_rms: np.ndarray
    v_rms: np.ndarray
    r_tilde: np.ndarray | None = None
    v_dyn: np.ndarray | None = None
    torque: np.ndarray | None = None
    position: np.ndarray | None = None
    position_ref: np.ndarray | None = None


#: What a step needs for the events and incidents; the rest only for ``on_chunk``.
_NEEDED = ("t", "t_ns", "q_full", "r", "loading", "qd", "r_rms", "v_rms")
_FOR_WRITERS = ("r_tilde", "v_dyn", "torque", "position", "position_ref")


def analyze_stream(
    log_path: str, *, config: DetectorConfig | None, model: RigidModel | None = None,
    robot: RobotDescription | None = None, read_options: dict[str, Any] | None = None,
    model_from_log: bool = False, generator: str | None = None, config_where: str = "config",
    allow_slow: bool = False, chunk_rows: int = CHUNK_ROWS, scan: Any = None,
    on_chunk: Callable[[StreamChunk], None] | None = None,
    progress: Callable[[float, float], None] | None = None, strategy: str = "spill",
) -> DetectionResult:
    """Replay the detectors over a log read in chunks (module docstring).

    Args:
        log_path: the log (any format :func:`impactcli.io.read_log` reads; streamed from
            the file for CSV, :mod:`impactcli.io.stream`).
        config: the config, or None (Table I defaults, thresholds from the log itself);
        model: ``--model`` or None (the config's, else identified from the log).
        robot: the robot description (currents, kinematics); read_options: how to read.
        model_from_log, generator: as :func:`impactcli.pipeline.analyze`.
        config_where: the config's file, for messages.
        allow_slow: as :func:`impactcli.pipeline.analyze`.
        chunk_rows: samples per chunk (the result does not depend on it).
        scan: the log's :func:`impactcli.io.stream.scan_log`, if already made.
        on_chunk: called per chunk with its :class:`StreamChunk` (signals, decisions).
        progress: called with (seconds of log done, seconds to do), summed over the passes.
        strategy: :data:`STRATEGIES` (without calibrated thresholds only).
    Returns:
        The result; its ``log`` is a :class:`LogHeader` and it holds no per-sample signals.
    """
    from .io.stream import scan_log
    from .pipeline import (
        _known_joints,
        calibrated_thresholds,
        check_replayable,
        screen_plan,
        warn_events_after_gaps,
        warn_gaps,
        warn_uncalibrated,
        warn_warmup,
        with_generator,
    )

    if strategy not in STRATEGIES:
        raise ValueError(f"strategy must be one of {STRATEGIES}, got {strategy!r}")
    opts = dict(read_options or {})
    read_kw = dict(opts, robot=robot) if robot is not None else dict(opts)
    cfg = with_generator(config or DetectorConfig(), generator, config_where)
    if model is not None and model_from_log:
        from .errors import ConfigError

        raise ConfigError("--model and --model-from-log exclude each other")
    with warnings.catch_warnings(record=True) as caught, contextlib.ExitStack() as stack:
        warnings.simplefilter("always", ImpactWarning)
        if scan is None:  # made here, so closed here (its cache file, io.stream_cache)
            scan = scan_log(log_path, **read_kw)
            stack.callback(getattr(scan, "close", lambda: None))
        where = scan.source.path
        check_calibrated_rate(scan.sample_rate_hz, cfg.calibration.sample_rate_hz, where,
                              f"its config ({config_where})")
        ref = scan.torque_ptp
        full_joints = tuple(scan.joint_names)
        keep, left, unlogged = screen_plan(
            where, full_joints, _known_joints(model, cfg), cfg.calibration.joints_left_out,
            scan.torque_screen,
            lambda ch, cols: scan.screens[ch].select(cols).unusable(ref)
            if ch in scan.screens else None)
        left_out = tuple(LeftOut(j, why) for j, why in scan.source.joints_dropped) + left
        logged = {ch: scan.screens[ch].select([full_joints.index(j) for j in keep]).logged
                  for ch in CONTROLLER_CHANNELS if ch in scan.screens}
        for ch, ks in unlogged.items():
            logged[ch] = logged[ch].copy()
            logged[ch][ks] = False
        check_replayable(where, len(keep), scan.sample_rate_hz, scan.n_samples,
                         scan.duration_s, cfg, allow_slow)
        passes = _Passes(scan.duration_s, progress)
        if not cfg.calibration.calibrated:
            passes.add()  # the comparison over the spill, or the replay again (strategy)
        reader = _Reader(log_path, scan, read_kw, chunk_rows, full_joints, keep, unlogged)

        def identify(choices: Any, kind: str | None, rbt: RobotDescription | None,
                     sanity: bool) -> RigidModel:
            return _identify_pass(reader, cfg, choices, kind, rbt, sanity, passes)

        joints, choices, rig, model_source, extra_left = _plan(
            keep, scan.source, logged, model, cfg, model_from_log, robot, identify)
        given = calibrated_thresholds(cfg, joints)
        before = len(caught)
        rp = _replay_passes(reader, cfg, joints, choices, rig, given, on_chunk, passes,
                            strategy)
        stack.callback(rp.islands.close)
        replay_msgs = caught[before:]
        del caught[before:]
        header = LogHeader(joints, scan.source, scan.n_samples, scan.t0_ns, scan.duration_s,
                           scan.sample_rate_hz, scan.sample_period_s)
        warn_gaps(where, np.asarray(scan.gap_lengths_s), rp.gap_times[:, 0])
        caught.extend(replay_msgs)
        if rp.reference == "measured":
            warnings.warn(f"{where}: no reference logged: threshold inputs from the "
                          "measured position (no anticipation)", ImpactWarning, stacklevel=2)
        wu, wu_times = rp.warmup
        warn_warmup(where, wu, wu_times, joints, scan.n_samples, scan.duration_s, cfg)
        thr = rp.thresholds
        if given is None:
            cfg = _uncalibrated_config(cfg, joints, rp.margins)
            warn_uncalibrated(where)
        before = len(caught)  # the incidents' warnings follow the events' (whole-log order)
        ctx = incident_context(joints, full_joints, robot,
                               None if rig is None else rig.to_dict(), thr["static_loading"],
                               scan.sample_period_s, scan.t0_ns, scan.n_samples,
                               cfg.events.merge_gap_s, where)
        ctx_msgs = caught[before:]
        del caught[before:]
        events, incidents = _events_and_incidents(rp.islands, wu, joints, cfg, ctx)
        warn_events_after_gaps(where, rp.gap_times[:, 1], events)
        from .pipeline import _warn_long_events

        _warn_long_events(cast(Any, header), events)
        caught.extend(ctx_msgs)
    msgs = tuple(dict.fromkeys(str(w.message) for w in caught
                               if issubclass(w.category, ImpactWarning)))
    for w in caught:
        if not issubclass(w.category, ImpactWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    freqs, gain = rp.last.g_gain()
    thresholds = {j: {"v_stat": float(thr["adaptive"][k]), "v0": float(thr["static_baseline"][k]),
                      "vL": float(thr["static_loading"][k])} for k, j in enumerate(joints)}
    wu_s = dict(zip(joints, wu_times, strict=True))
    return DetectionResult(
        log=cast(Any, header), model=None if rig is None else rig.to_dict(),
        model_sha256=None if rig is None else rig.sha256, model_source=model_source,
        config=cfg.to_dict(), calibrated=given is not None, thresholds=thresholds,
        reference_source="measured" if rp.reference == "measured" else "reference",
        threshold_inputs=rp.detail, torque_filtered=cfg.residual.filter_torque,
        signals={}, decisions={}, ratios={}, events=tuple(events),
        warmup_end_s=wu.end_s, warmup_per_joint_s=wu_s,
        filter_gain={"frequencies_hz": [float(f) for f in freqs],
                     "gain": {j: [float(g) for g in gain[k]] for k, j in enumerate(joints)}},
        residual_generator=summary_name(choices), read_options=opts,
        generators=choices_dict(choices, cfg.residual.logged_correction),
        joints_left_out=tuple(x.to_dict() for x in left_out) + tuple(
            x.to_dict() for x in extra_left),
        incidents=tuple(incidents), warnings=msgs,
    )


def _uncalibrated_config(cfg: DetectorConfig, joints: tuple[str, ...],
                         margins: dict[str, np.ndarray]) -> DetectorConfig:
    """The config recorded by an uncalibrated run (:func:`impactcli.pipeline.analyze`)."""
    from .config import CalibrationRecord
    from .detect.calibrate import UNCALIBRATED_RULE

    return dataclasses.replace(cfg, calibration=CalibrationRecord(
        calibrated=False, margin_rule=UNCALIBRATED_RULE,
        margins={d: {j: float(m) for j, m in zip(joints, ms, strict=True)}
                 for d, ms in margins.items()}))


class _Passes:
    """Progress over the passes that read the log (identification, replay, replay again):
    seconds of log done, summed over the passes, against the passes' total."""

    def __init__(self, duration_s: float, progress: Callable[[float, float], None] | None):
        self.duration_s, self.progress = duration_s, progress
        self.planned = 1
        self.done = 0

    def add(self, k: int = 1) -> None:
        """``k`` more passes than the one replay planned at first."""
        self.planned += k

    def at(self, t_s: float) -> None:
        if self.progress is not None:
            self.progress(self.done * self.duration_s + t_s, self.planned * self.duration_s)

    def next(self) -> None:
        self.done += 1


class _Reader:
    """The log's chunks (:func:`impactcli.io.stream.iter_chunks`) as the replay sees them:
    times [s since the first sample], and arrays in a given joint order with the flat
    controller channels read as not logged; each call reads the file again."""

    def __init__(self, log_path: str, scan: Any, read_kw: dict[str, Any], chunk_rows: int,
                 full_joints: tuple[str, ...], keep: tuple[str, ...],
                 unlogged: dict[str, list[int]]) -> None:
        self.log_path, self.scan, self.read_kw, self.chunk_rows = (
            log_path, scan, read_kw, chunk_rows)
        self.full_joints, self.keep, self.unlogged = full_joints, keep, unlogged

    def chunks(self, joints: tuple[str, ...]) -> Any:
        """(chunk, times, :class:`~impactcli.replay.ChunkArrays` of ``joints``) per chunk."""
        from .io.stream import iter_chunks

        cols = [self.full_joints.index(j) for j in joints]
        # controller-channel columns read as not logged, in this joint order
        nan_cols = {ch: [joints.index(self.keep[k]) for k in ks if self.keep[k] in joints]
                    for ch, ks in self.unlogged.items()}
        t0 = self.scan.t0_ns
        for ch in iter_chunks(self.log_path, self.scan, self.chunk_rows, **self.read_kw):
            t = (np.asarray(ch.t_ns) - t0).astype(np.float64) * 1e-9
            yield ch, t, _chunk_arrays(ch, t, cols, nan_cols)


def _identify_pass(reader: _Reader, cfg: DetectorConfig, choices: Any, kind: str | None,
                   robot: RobotDescription | None, sanity: bool,
                   passes: _Passes) -> RigidModel:
    """Identify the model from the log, read once more (:class:`IdentifyStream`: bounded
    memory, the same model as :func:`impactcli.model.identify` on the whole log)."""
    from .model import IdentifyOptions
    from .model.generators import target_torque
    from .model.identify import IdentifyStream

    scan = reader.scan
    ident = IdentifyStream.start(
        reader.keep, scan.n_samples, scan.sample_rate_hz, scan.duration_s, robot=robot,
        kind=kind, options=IdentifyOptions(allow_still_joints=True, check_sanity=sanity),
        where=scan.source.path, input_sha256=scan.source.sha256)
    passes.add()
    for _, t, a in reader.chunks(reader.keep):
        ident.feed(t, a.position, target_torque(a, choices, cfg.residual.logged_correction))
        passes.at(float(t[-1]))
    passes.next()
    return ident.finish()


def _plan(keep: tuple[str, ...], source: LogSource, logged: dict[str, np.ndarray],
          model: RigidModel | None, cfg: DetectorConfig, model_from_log: bool,
          robot: RobotDescription | None, identify: Callable[..., RigidModel],
          ) -> tuple[tuple[str, ...], Any, RigidModel | None, str, tuple[LeftOut, ...]]:
    """The replayed joints (model order), their generators, the model and where it came
    from, and the logged joints the model lacks (:func:`impactcli.pipeline.replay`,
    :func:`impactcli.pipeline.resolve_model`); ``identify(choices, kind, robot, sanity)``
    identifies the model from the log."""
    where = source.path

    def choose(js: tuple[str, ...], lg: dict[str, np.ndarray]) -> Any:
        return choose_generators(cast(Any, _Header(js, source, lg)), cfg.residual.generator,
                                 cfg.residual.generators or None)

    choices = choose(keep, logged)
    extra_left: tuple[LeftOut, ...] = ()
    rig: RigidModel | None = None
    source_name = "none"
    joints = keep
    correct = cfg.residual.logged_correction
    if needs_own_model(choices) or uses_correction(choices, correct):
        sanity = not uses_correction(choices, correct)
        if model_from_log:
            from .pipeline import from_log_structure

            kind, robot = from_log_structure(cfg, robot)
            rig, source_name = identify(choices, kind, robot, sanity), "identified-from-log"
        elif model is not None:
            rig, source_name = model, "given"
            if cfg.calibration.calibrated and cfg.calibration.model_sha256 not in (
                    None, model.sha256):
                warnings.warn(
                    "--model overrides the config's model: its thresholds belong to the model "
                    "they were calibrated with (another model gives the residual another "
                    "scale)", ImpactWarning, stacklevel=3)
        elif cfg.model is not None:
            rig, source_name = RigidModel.from_dict(cfg.model), "config"
        else:  # offline convenience: a joint that never moves keeps only its offset
            rig, source_name = identify(choices, None, robot, sanity), "identified-from-log"
        extra = [j for j in keep if j not in rig.joint_names]
        if extra and all(j in keep for j in rig.joint_names):
            for j in extra:
                warnings.warn(f"{where}: joint {j!r} left out of detection: not in the model",
                              ImpactWarning, stacklevel=3)
            extra_left = tuple(LeftOut(j, "not in the model") for j in extra)
        present = tuple(j for j in keep if j not in {x.name for x in extra_left})
        missing = [j for j in rig.joint_names if j not in present]
        other = [j for j in present if j not in rig.joint_names]
        if missing or other:
            from .errors import ModelError

            raise ModelError(
                f"{where}: joints {list(present)} do not match the model's "
                f"{list(rig.joint_names)}" + (f" (missing {missing})" if missing else "")
                + (f" (not in the model: {other})" if other else ""))
        joints = tuple(rig.joint_names)
    else:
        order = tuple(cfg.residual.generators)
        if set(order) == set(keep):
            joints = order
    idx = [keep.index(j) for j in joints]
    choices = choose(joints, {ch: v[idx] for ch, v in logged.items()})
    return joints, choices, rig, source_name, extra_left


@dataclass
class _Replayed:
    """What the replay passes leave: the times of the samples at and after each gap, the
    warm-up and its per-joint times, the islands, the last chunk's evaluator result, the
    threshold inputs' source and how they were made, the thresholds and (uncalibrated)
    their margins."""

    gap_times: np.ndarray
    warmup: tuple[Warmup, list[float]]
    islands: Islands
    last: AdaptiveResult
    reference: str
    detail: str
    thresholds: dict[str, np.ndarray]
    margins: dict[str, np.ndarray]


def _replay_passes(
    reader: _Reader, cfg: DetectorConfig, joints: tuple[str, ...], choices: Any,
    rig: RigidModel | None, given: dict[str, np.ndarray] | None, on_chunk: Any,
    passes: _Passes, strategy: str,
) -> _Replayed:
    """The replay (module docstring): with thresholds ``given``, one pass that compares
    and keeps as it goes; without, a pass that spills, the thresholds from what it spilled
    once the warm-up's end is known, then the comparison over the spill (``spill``) or
    over the log replayed again (``reread``)."""

    scan = reader.scan
    fs, dt = scan.sample_rate_hz, scan.sample_period_s
    setup = ReplaySetup(joints, choices, rig, cfg, fs, dt,
                        threads=default_threads(scan.n_samples))
    tracker = WarmupTracker(scan.n_samples, 0.0, scan.duration_s, len(joints), cfg.warmup)
    writers = on_chunk is not None
    margins: dict[str, np.ndarray] = {}
    last: list[Any] = [None, "", ""]

    def replayed() -> Any:
        """The replay's steps in order (the axes run ahead of the caller: replay.Replayer)."""
        rp = Replayer(setup, ReplayState.initial(setup), where=scan.source.path,
                      consume=True)

        def steps(done: list[tuple[Any, ChunkReplay]]) -> Any:
            for (ch, t, a), out in done:
                ad = out.adaptive
                last[:] = [ad, out.inputs_source, out.inputs_detail]
                yield _Step(ch.start, t, np.asarray(ch.t_ns, dtype=np.int64),
                            np.asarray(ch.position, dtype=np.float64), out.r, out.loading,
                            out.qd, ad.r_rms, ad.v_rms, ad.r_tilde, ad.v_dyn, a.torque,
                            a.position, a.position_ref), ad.prediction_error
                passes.at(float(t[-1]))

        try:
            for ch, t, a in reader.chunks(joints):
                yield from steps(rp.feed((ch, t, a), a))
            yield from steps(rp.finish())
        finally:
            rp.close()
        passes.next()

    made: list[_Compare] = []   # the comparison, once made (its islands closed on failure)

    def compare(thr: dict[str, np.ndarray]) -> _Compare:
        made.append(_Compare(thr, cfg, scan, on_chunk, joints))
        return made[-1]

    try:
        if given is not None:
            thr = given
            comparing = compare(thr)
            for step, pe in replayed():
                tracker.update(pe, step.t)
                comparing.update(step)
            wu = tracker.finish()
        else:
            with contextlib.closing(ChunkSpill()) as spill:
                for step, pe in replayed():
                    tracker.update(pe, step.t)
                    keys = _NEEDED + (_FOR_WRITERS if writers else ()) \
                        if strategy == "spill" else ("r", "loading", "r_rms", "v_rms")
                    spill.write({k: v for k in keys if (v := getattr(step, k)) is not None})
                wu = tracker.finish()
                thr, margins = _thresholds_from_spill(spill, wu, scan.n_samples, fs)
                comparing = compare(thr)
                if strategy == "spill":
                    for k0, arrays in spill.read_chunks():
                        comparing.update(_Step(k0, **arrays))
                        passes.at(float(arrays["t"][-1]))
                    passes.next()
                else:
                    spill.close()
                    for step, _ in replayed():
                        comparing.update(step)
        comparing.islands.finish()
    except BaseException:  # nothing left behind: the spills are temporary files
        tracker.close()
        for c in made:
            c.islands.close()
        raise
    assert last[0] is not None
    return _Replayed(comparing.gap_times, (wu, tracker.times_at(wu.index)), comparing.islands,
                     last[0], last[1], last[2], thr, margins)


def _thresholds_from_spill(spill: ChunkSpill, wu: Warmup, n: int, fs: float,
                           ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The uncalibrated rule's thresholds and margins per detector
    (:func:`impactcli.detect.calibrate.uncalibrated_thresholds`) from the statistics after
    the warm-up's end, read back from the spill block by block."""
    from .detect.calibrate import BlockMaxima, thresholds_from_maxima, uncalibrated_block

    start = wu.end_index if wu.end_index < n - 10 else 0  # pipeline.Replay.stats_after_warmup
    block = uncalibrated_block(n - start, fs)
    bms = {d: BlockMaxima(start, block) for d in DETECTORS}
    for k0, a in spill.read_chunks(("r", "loading", "r_rms", "v_rms")):
        if k0 + a["r"].shape[0] <= start:
            continue
        bms["adaptive"].update(k0, a["r_rms"] - a["v_rms"])
        bms["static_loading"].update(k0, a["loading"])
        bms["static_baseline"].update(k0, np.abs(a["r"]))
    cals = {d: thresholds_from_maxima(bm.finish(), bm.block) for d, bm in bms.items()}
    return ({d: c.thresholds for d, c in cals.items()},
            {d: c.margins for d, c in cals.items()})


class _Compare:
    """Thresholds applied to the replay's steps, in order (module docstring): decisions
    and ratios, the islands, the times at the gaps, the writers' chunks."""

    def __init__(self, thr: dict[str, np.ndarray], cfg: DetectorConfig, scan: Any,
                 on_chunk: Any, joints: tuple[str, ...]) -> None:
        self.thr, self.on_chunk, self.joints = thr, on_chunk, joints
        self.islands = Islands(cfg.events.merge_gap_s)
        self.pressing_at = BRIDGE_FRACTION * np.maximum(thr["static_loading"], 1e-12)
        self.gaps = np.asarray(scan.gaps, dtype=np.int64)
        self.gap_times = np.full((self.gaps.size, 2), np.nan)

    def update(self, st: _Step) -> None:
        from .pipeline import compare_to_thresholds

        k0, t = st.k0, st.t
        thr_ad, ratios, dec = compare_to_thresholds(self.thr, st.r_rms, st.v_rms, st.loading,
                                                    np.abs(st.r))
        any_d = np.asarray(dec["adaptive"].any(axis=1) | dec["static_loading"].any(axis=1)
                           | dec["static_baseline"].any(axis=1))
        pressing = np.any(st.loading >= self.pressing_at[None, :], axis=1)
        self.islands.update(k0, t, any_d, pressing, {
            "t": t, "r": st.r, "loading": st.loading, "qd": st.qd, "q_full": st.q_full,
            **{f"d.{d}": dec[d] for d in DETECTORS}, **{f"x.{d}": ratios[d] for d in DETECTORS}})
        gaps = self.gaps
        for g_col, off in ((0, 0), (1, 1)):
            hit = (gaps + off >= k0) & (gaps + off < k0 + t.shape[0])
            self.gap_times[hit, g_col] = t[gaps[hit] + off - k0]
        if self.on_chunk is not None:
            assert st.torque is not None and st.r_tilde is not None and st.v_dyn is not None
            assert st.position is not None
            self.on_chunk(StreamChunk(self.joints, t, st.t_ns, {
                "torque": st.torque, "residual": st.r, "filtered_residual": st.r_tilde,
                "dynamic_threshold": st.v_dyn, "residual_rms": st.r_rms, "threshold": thr_ad,
                "loading_statistic": st.loading}, dec, st.position, st.position_ref))


def _chunk_arrays(ch: Any, t: np.ndarray, cols: list[int],
                  nan_cols: dict[str, list[int]]) -> ChunkArrays:
    """The reader's chunk in the replay's joint order, flat controller channels unlogged."""
    from .replay import chunk_arrays

    a = chunk_arrays(ch, t, cols)
    changes = {}
    for name, ks in nan_cols.items():
        m = getattr(a, name)
        if m is not None and ks:
            m = np.array(m)
            m[:, ks] = np.nan
            changes[name] = m
    return dataclasses.replace(a, **changes) if changes else a


def _events_and_incidents(islands: Islands, wu: Warmup, joints: tuple[str, ...],
                          cfg: DetectorConfig, ctx: IncidentContext,
                          ) -> tuple[list[Event], list[Incident]]:
    """Every island's events (indices in the log, in timeline order) and incidents
    (:func:`impactcli.contacts.build_incidents`), each island read from its files once."""
    ev = cfg.events
    events: list[Event] = []
    incidents: list[Incident] = []
    for isl in islands.done:
        a = islands.arrays(isl)
        local: list[Event] = []
        for d in DETECTORS:
            local += extract_events(d, a[f"d.{d}"], a[f"x.{d}"], a["r"], a["t"], joints,
                                    wu.end_s, ev.merge_gap_s, ev.min_duration_s)
        local.sort(key=lambda e: (e.t_start, DETECTORS.index(e.detector)))
        incidents += build_incidents(ctx, local, a["t"], a["r"], a["loading"], a["d.adaptive"],
                                     a["d.static_loading"], a["q_full"], a["qd"],
                                     offset=isl.start, event_offset=len(events))
        events += [dataclasses.replace(e, i_start=e.i_start + isl.start,
                                       i_end=e.i_end + isl.start) for e in local]
    return events, incidents
