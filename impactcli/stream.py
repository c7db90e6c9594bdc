"""Detection over a log read chunk by chunk, in bounded memory (day-long logs).

:func:`analyze_stream` gives the same :class:`~impactcli.result.DetectionResult` fields
as :func:`impactcli.pipeline.analyze` — the same timeline, byte for byte — without holding
the log or its per-sample signals in memory. It needs what is fixed before the first
sample: a calibrated config (thresholds) and a model (given, or embedded in the config,
or none when every joint uses a controller channel as it is). Without them
:func:`streamable` is False and the caller replays the whole log.

Two passes over the file (:mod:`impactcli.io.stream`):

1. the scan: provenance and sha256, the number of samples, the sample clock, the gaps and
   the columns' screen — every decision the whole-log replay takes before its first
   sample (:func:`impactcli.pipeline.screen_plan`, the model's joints, the generators);
2. the replay, chunk by chunk (:func:`impactcli.replay.replay_chunk`, state in, state
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

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from .config import DetectorConfig
from .contacts import IncidentContext, build_incidents, incident_context
from .detect.adaptive import AdaptiveResult
from .detect.events import extract_events
from .detect.incidents import BRIDGE_FRACTION, Incident
from .detect.screen import LeftOut
from .detect.warmup import Warmup, WarmupTracker
from .errors import ImpactWarning
from .model.generators import (
    LOGGED,
    choices_dict,
    choose_generators,
    needs_own_model,
    summary_name,
    uses_correction,
)
from .model.rigid import RigidModel
from .replay import ChunkArrays, ReplaySetup, ReplayState, replay_chunk
from .result import DetectionResult
from .sampling import check_calibrated_rate
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


def streamable(config: DetectorConfig | None, model: RigidModel | None,
               model_from_log: bool) -> bool:
    """Whether :func:`analyze_stream` can replay with these inputs: calibrated thresholds
    and a model known before the first sample (or controller channels only)."""
    if config is None or not config.calibration.calibrated or model_from_log:
        return False
    if model is not None or config.model is not None:
        return True
    frozen = config.residual.generators
    return bool(frozen) and all(g in LOGGED for g in frozen.values()) and not (
        config.residual.logged_correction)


@dataclass
class _Island:
    """Consecutive samples near an alarm (module docstring): the island's first sample in
    the log and its rows [row_from, row_to) in the spill files."""

    start: int
    row_from: int
    row_to: int


class _Islands:
    """The islands of a streamed replay (module docstring), their rows spilled to
    temporary files (one per array: memory holds only where each island lies).

    A sample is kept when some detector fires on it, when it lies within the merge gap
    after one that fires, or when the contact still presses on it (the static-loading
    statistic of some joint at half its threshold) and the sample before it was kept —
    the stretch between two alarms that a pressing contact bridges. Pressing that does not
    follow an alarm is not kept: no event or incident reads it.
    """

    def __init__(self, merge_gap_s: float) -> None:
        import tempfile

        self.reach_s = merge_gap_s + 1e-9
        self.last_t = -np.inf          # time of the last alarm so far
        self.kept_last = False         # whether the previous chunk's last sample was kept
        self.done: list[_Island] = []
        self.open: _Island | None = None
        self.rows = 0
        self.dir = tempfile.TemporaryDirectory(prefix="impactcli-islands-")
        self.files: dict[str, Any] = {}
        self.layout: dict[str, tuple[np.dtype[Any], tuple[int, ...]]] = {}

    def update(self, k0: int, t: np.ndarray, alarm: np.ndarray, pressing: np.ndarray,
               arrays: dict[str, np.ndarray]) -> None:
        """Absorb a chunk starting at sample ``k0``: (n,) times [s], (n,) alarms, (n,)
        pressing, and the (n, ...) arrays to keep of the kept samples."""
        n = t.shape[0]
        idx = np.where(alarm, np.arange(n), -1)
        last = np.maximum.accumulate(idx)
        t_last = np.where(last >= 0, t[np.maximum(last, 0)], self.last_t)
        base = alarm | (t - t_last <= self.reach_s)
        if alarm.any():
            self.last_t = float(t[np.flatnonzero(alarm)[-1]])
        # kept = base, or pressing with the sample before kept: a pressing run continues
        # the state at its start; a sample neither base nor pressing resets it
        ar = np.arange(n)
        set_at = np.maximum.accumulate(np.where(base, ar, -1))
        reset_at = np.maximum.accumulate(np.where(~base & ~pressing, ar, -1))
        carried = self.kept_last & (reset_at < 0) & (set_at < 0)
        keep = base | (pressing & ((set_at > reset_at) | carried))
        self.kept_last = bool(keep[-1]) if n else self.kept_last
        if not keep.any():
            self._close()
            return
        edges = np.flatnonzero(np.diff(np.concatenate([[0], keep.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            if a > 0 or self.open is None:
                self._close()
                self.open = _Island(k0 + int(a), self.rows, self.rows)
            for key, v in arrays.items():
                self._write(key, v[a:b])
            self.rows += int(b - a)
            self.open.row_to = self.rows
            if b < n:
                self._close()

    def _write(self, key: str, v: np.ndarray) -> None:
        f = self.files.get(key)
        if f is None:
            import os

            f = self.files[key] = open(os.path.join(self.dir.name, key), "wb")  # noqa: SIM115
            self.layout[key] = (v.dtype, v.shape[1:])
        f.write(np.ascontiguousarray(v).tobytes())

    def _close(self) -> None:
        if self.open is not None:
            self.done.append(self.open)
            self.open = None

    def finish(self) -> list[_Island]:
        """The islands, in time order (their rows readable until :meth:`close`)."""
        self._close()
        for f in self.files.values():
            f.close()
        return self.done

    def arrays(self, isl: _Island) -> dict[str, np.ndarray]:
        """An island's arrays, read back from the spill files."""
        import os

        out = {}
        for key, (dtype, shape) in self.layout.items():
            width = int(np.prod(shape)) if shape else 1
            size = dtype.itemsize * width
            with open(os.path.join(self.dir.name, key), "rb") as f:
                f.seek(isl.row_from * size)
                a = np.fromfile(f, dtype=dtype, count=(isl.row_to - isl.row_from) * width)
            out[key] = a.reshape((-1, *shape))
        return out

    def close(self) -> None:
        """Remove the spill files."""
        for f in self.files.values():
            f.close()
        self.dir.cleanup()


def analyze_stream(
    log_path: str, *, config: DetectorConfig, model: RigidModel | None = None,
    robot: RobotDescription | None = None, read_options: dict[str, Any] | None = None,
    generator: str | None = None, config_where: str = "config", allow_slow: bool = False,
    chunk_rows: int = CHUNK_ROWS, scan: Any = None,
    on_chunk: Callable[[StreamChunk], None] | None = None,
    progress: Callable[[float, float], None] | None = None,
) -> DetectionResult:
    """Replay the detectors over a log read in chunks (module docstring).

    Args:
        log_path: the log (any format :func:`impactcli.io.read_log` reads; streamed from
            the file for CSV, :mod:`impactcli.io.stream`).
        config: a calibrated config (:func:`streamable`); model: ``--model`` or None.
        robot: the robot description (currents, kinematics); read_options: how to read.
        generator: ``--generator``; config_where: the config's file, for messages.
        allow_slow: as :func:`impactcli.pipeline.analyze`.
        chunk_rows: samples per chunk (the result does not depend on it).
        scan: the log's :func:`impactcli.io.stream.scan_log`, if already made.
        on_chunk: called per chunk with its :class:`StreamChunk` (signals, decisions).
        progress: called with (seconds of log replayed, the log's duration).
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
        warn_warmup,
        with_generator,
    )

    opts = dict(read_options or {})
    read_kw = dict(opts, robot=robot) if robot is not None else dict(opts)
    cfg = with_generator(config, generator, config_where)
    if not streamable(cfg, model, False):
        raise ValueError("analyze_stream needs a calibrated config and a known model")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ImpactWarning)
        if scan is None:
            scan = scan_log(log_path, **read_kw)
        where = scan.source.path
        check_calibrated_rate(scan.sample_rate_hz, cfg.calibration.sample_rate_hz, where)
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
        joints, choices, rig, model_source, extra_left = _plan(
            keep, scan.source, logged, model, cfg)
        check_replayable(where, len(joints), scan.sample_rate_hz, scan.n_samples,
                         scan.duration_s, cfg, allow_slow)
        thr = calibrated_thresholds(cfg, joints)
        assert thr is not None
        before = len(caught)
        _, gap_times, (wu, wu_times), islands, last, reference, detail = _replay_pass(
            log_path, scan, read_kw, chunk_rows, cfg, joints, choices, rig, full_joints,
            unlogged, keep, thr, on_chunk, progress, caught)
        replay_msgs = caught[before:]
        del caught[before:]
        header = LogHeader(joints, scan.source, scan.n_samples, scan.t0_ns, scan.duration_s,
                           scan.sample_rate_hz, scan.sample_period_s)
        warn_gaps(where, np.asarray(scan.gap_lengths_s), gap_times[:, 0])
        caught.extend(replay_msgs)
        if reference == "measured":
            warnings.warn(f"{where}: no reference logged: threshold inputs from the "
                          "measured position (no anticipation)", ImpactWarning, stacklevel=2)
        warn_warmup(where, wu, wu_times, joints, scan.n_samples, scan.duration_s, cfg)
        events, per_island = _events(islands, wu, joints, cfg)
        warn_events_after_gaps(where, gap_times[:, 1], events)
        from .pipeline import _warn_long_events

        _warn_long_events(cast(Any, header), events)
        ctx = incident_context(joints, full_joints, robot,
                               None if rig is None else rig.to_dict(), thr["static_loading"],
                               scan.sample_period_s, scan.t0_ns, scan.n_samples,
                               cfg.events.merge_gap_s, where)
        incidents = _incidents(islands, per_island, ctx)
        islands.close()
    msgs = tuple(dict.fromkeys(str(w.message) for w in caught
                               if issubclass(w.category, ImpactWarning)))
    for w in caught:
        if not issubclass(w.category, ImpactWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    freqs, gain = last.g_gain()
    thresholds = {j: {"v_stat": float(thr["adaptive"][k]), "v0": float(thr["static_baseline"][k]),
                      "vL": float(thr["static_loading"][k])} for k, j in enumerate(joints)}
    wu_s = dict(zip(joints, wu_times, strict=True))
    return DetectionResult(
        log=cast(Any, header), model=None if rig is None else rig.to_dict(),
        model_sha256=None if rig is None else rig.sha256, model_source=model_source,
        config=cfg.to_dict(), calibrated=True, thresholds=thresholds,
        reference_source="measured" if reference == "measured" else "reference",
        threshold_inputs=detail, torque_filtered=cfg.residual.filter_torque,
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


def _plan(keep: tuple[str, ...], source: LogSource, logged: dict[str, np.ndarray],
          model: RigidModel | None, cfg: DetectorConfig,
          ) -> tuple[tuple[str, ...], Any, RigidModel | None, str, tuple[LeftOut, ...]]:
    """The replayed joints (model order), their generators, the model and where it came
    from, and the logged joints the model lacks (:func:`impactcli.pipeline.replay`)."""
    where = source.path

    def choose(js: tuple[str, ...], lg: dict[str, np.ndarray]) -> Any:
        return choose_generators(cast(Any, _Header(js, source, lg)), cfg.residual.generator,
                                 cfg.residual.generators or None)

    choices = choose(keep, logged)
    extra_left: tuple[LeftOut, ...] = ()
    rig: RigidModel | None = None
    source_name = "none"
    joints = keep
    if needs_own_model(choices) or uses_correction(choices, cfg.residual.logged_correction):
        if model is not None:
            rig, source_name = model, "given"
            if cfg.calibration.model_sha256 not in (None, model.sha256):
                warnings.warn(
                    "--model overrides the config's model: its thresholds belong to the model "
                    "they were calibrated with (another model gives the residual another "
                    "scale)", ImpactWarning, stacklevel=3)
        else:
            assert cfg.model is not None
            rig, source_name = RigidModel.from_dict(cfg.model), "config"
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


def _replay_pass(
    log_path: str, scan: Any, read_kw: dict[str, Any], chunk_rows: int, cfg: DetectorConfig,
    joints: tuple[str, ...], choices: Any, rig: RigidModel | None,
    full_joints: tuple[str, ...], unlogged: dict[str, list[int]], keep: tuple[str, ...],
    thr: dict[str, np.ndarray], on_chunk: Any, progress: Any, caught: list[Any],
) -> tuple[list[Any], np.ndarray, tuple[Warmup, list[float]], _Islands, AdaptiveResult,
           str, str]:
    """The second pass (module docstring): returns the warnings it raised, the times of
    the samples at and after each gap, the warm-up, the islands, the last chunk's
    evaluator result, the threshold inputs' source and how they were made."""
    import os

    from .io.stream import iter_chunks

    fs, dt = scan.sample_rate_hz, scan.sample_period_s
    setup = ReplaySetup(joints, choices, rig, cfg, fs, dt,
                        threads=(os.cpu_count() or 1) if scan.n_samples >= 100_000 else 1)
    state = ReplayState.initial(setup)
    cols = [full_joints.index(j) for j in joints]
    # controller-channel columns read as not logged, in the replay's joint order
    nan_cols = {ch: [joints.index(keep[k]) for k in ks if keep[k] in joints]
                for ch, ks in unlogged.items()}
    tracker = WarmupTracker(scan.n_samples, 0.0, scan.duration_s, len(joints), cfg.warmup)
    islands = _Islands(cfg.events.merge_gap_s)
    pressing_at = BRIDGE_FRACTION * np.maximum(thr["static_loading"], 1e-12)
    gaps = np.asarray(scan.gaps, dtype=np.int64)
    gap_times = np.full((gaps.size, 2), np.nan)
    last: AdaptiveResult | None = None
    reference, detail = "", ""
    start = len(caught)
    t0 = scan.t0_ns
    for ch in iter_chunks(log_path, scan, chunk_rows, **read_kw):
        k0 = ch.start
        t = (np.asarray(ch.t_ns) - t0).astype(np.float64) * 1e-9
        arrays = _chunk_arrays(ch, t, cols, nan_cols)
        out, state = replay_chunk(setup, state, arrays, where=scan.source.path, consume=True)
        ad, r = out.adaptive, out.r
        last, reference, detail = ad, out.inputs_source, out.inputs_detail
        thr_ad = np.abs(thr["adaptive"][None, :] + ad.v_rms)
        baseline = np.abs(r)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratios = {
                "adaptive": np.where(thr_ad > 0, ad.r_rms / thr_ad, np.inf),
                "static_loading": out.loading / thr["static_loading"][None, :],
                "static_baseline": baseline / thr["static_baseline"][None, :],
            }
        dec = {"adaptive": ad.r_rms > thr_ad,
               "static_loading": out.loading > thr["static_loading"][None, :],
               "static_baseline": baseline > thr["static_baseline"][None, :]}
        tracker.update(ad.prediction_error, t)
        any_d = dec["adaptive"].any(axis=1) | dec["static_loading"].any(axis=1) | \
            dec["static_baseline"].any(axis=1)
        pressing = np.any(out.loading >= pressing_at[None, :], axis=1)
        islands.update(k0, t, any_d, pressing, {
            "t": t, "r": r, "loading": out.loading, "qd": out.qd,
            "q_full": np.asarray(ch.position, dtype=np.float64),
            **{f"d.{d}": dec[d] for d in DETECTORS}, **{f"x.{d}": ratios[d] for d in DETECTORS}})
        for g_col, off in ((0, 0), (1, 1)):
            hit = (gaps + off >= k0) & (gaps + off < k0 + t.shape[0])
            gap_times[hit, g_col] = t[gaps[hit] + off - k0]
        if on_chunk is not None:
            on_chunk(StreamChunk(joints, t, np.asarray(ch.t_ns, dtype=np.int64), {
                "torque": arrays.torque, "residual": r, "filtered_residual": ad.r_tilde,
                "dynamic_threshold": ad.v_dyn, "residual_rms": ad.r_rms, "threshold": thr_ad,
                "loading_statistic": out.loading}, dec, arrays.position, arrays.position_ref))
        if progress is not None:
            progress(float(t[-1]), scan.duration_s)
    assert last is not None
    msgs = caught[start:]
    wu = tracker.finish()
    islands.finish()
    return (msgs, gap_times, (wu, tracker.times_at(wu.index)), islands, last, reference,
            detail)


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


def _events(islands: _Islands, wu: Warmup, joints: tuple[str, ...],
            cfg: DetectorConfig) -> tuple[list[Event], list[tuple[int, list[Event]]]]:
    """Every island's events (indices in the log, in timeline order), and per island its
    first event's index and its events with indices in the island."""
    ev = cfg.events
    events: list[Event] = []
    per_island = []
    for isl in islands.done:
        a = islands.arrays(isl)
        local: list[Event] = []
        for d in DETECTORS:
            local += extract_events(d, a[f"d.{d}"], a[f"x.{d}"], a["r"], a["t"], joints,
                                    wu.end_s, ev.merge_gap_s, ev.min_duration_s)
        local.sort(key=lambda e: (e.t_start, DETECTORS.index(e.detector)))
        per_island.append((len(events), local))
        events += [dataclasses.replace(e, i_start=e.i_start + isl.start,
                                       i_end=e.i_end + isl.start) for e in local]
    return events, per_island


def _incidents(islands: _Islands, per_island: list[tuple[int, list[Event]]],
               ctx: IncidentContext) -> list[Incident]:
    """Every island's incidents (:func:`impactcli.contacts.build_incidents`)."""
    out: list[Incident] = []
    for isl, (e0, local) in zip(islands.done, per_island, strict=True):
        a = islands.arrays(isl)
        out += build_incidents(ctx, local, a["t"], a["r"], a["loading"], a["d.adaptive"],
                               a["d.static_loading"], a["q_full"], a["qd"],
                               offset=isl.start, event_offset=e0)
    return out
