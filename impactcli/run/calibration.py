"""Calibration: thresholds per joint from collision-free logs (docs/method.md §5b).

Each calibration log is replayed by the one replay (its threshold-free pass,
:func:`impactcli.run.one_log.replay_passes`, statistics collected per chunk) with the model
(given, the config's, or identified over all the logs); the statistic of every detector
after warm-up — labelled contacts cut out, and, in logs without labels, stretches that
alone would set a threshold far above the rest left out as likely contacts — gives the
thresholds: by default every detector's by the leave-one-out margin over 30 s segments
(:mod:`impactcli.detect.thresholds`), with the rate the tail fits of whole free logs
predict for v_stat and vL stated; with the ``false-alarm-rate`` rule, v_stat and vL for a
stated rate from those fits (:mod:`impactcli.detect.tail`; docs/method.md §5b,
"Thresholds for a false-alarm rate"; v0 keeps the margin). The motion the logs cover is
recorded as the calibration's envelope (:mod:`impactcli.detect.envelope`). Each joint's residual
generator is frozen in the config. The logs are in memory: the suspect rule pools every
log's per-sample statistics.
Nothing here reads or writes files.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config import DetectorConfig, settings_sha256
from ..detect.envelope import (
    SLOW_RAD_S,
    Motion,
    MotionTrace,
    slow_speed,
)
from ..detect.tail import (
    CONF,
    DEFAULT_FALSE_ALARMS_PER_HOUR,
    LoloRow,
    RateCalibration,
    fit_channels,
    leave_one_log_out,
    minutes_needed,
    rates_for_thresholds,
    stack_detectors,
    thresholds_for_rate,
)
from ..detect.tail import DETECTORS as TAIL_DETECTORS
from ..detect.warmup import Warmup
from ..errors import ConfigError, ImpactWarning, LogFormatError
from ..logs.reader import LogScan, MemoryReader
from ..logs.screen import LeftOut
from ..model import IdentifyOptions, RigidModel
from ..model.generators import GeneratorChoice, target_log, uses_correction
from ..model.payload import own_load
from ..types import DETECTORS, Labels, RobotDescription, RobotLog
from .collect import StatsCollector
from .load_envelopes import load_envelopes_of, union_envelope
from .one_log import ReplayStep, replay_passes, warn_replayed
from .plan import (
    ChunkFeed,
    RunPlan,
    Screened,
    check_replayable,
    check_torque_scale,
    description_of,
    generator_choices,
    identify_from_chunks,
    known_joints,
    needs_model,
    resolve_model,
    screen_scan,
)
from .run_warnings import (
    MOVED_RAD,
    CaughtWarnings,
    warn_beyond_effort,
    warn_mixed_torque_sources,
)

#: ``calibrate``'s threshold rules for the product's detectors (adaptive, static_loading):
#: thresholds for a false-alarm rate the user asks for, or the leave-one-out margin over
#: the free logs' maxima (the default: it keeps contacts the rate's bound costs, and its
#: predicted rate is stated; static_baseline, a comparison detector, always keeps it).
RATE_RULE = "false-alarm-rate"
MARGIN_RULE = "leave-one-out"
THRESHOLD_RULES: tuple[str, ...] = (RATE_RULE, MARGIN_RULE)
#: Rates [1/h] the leave-one-log-out rows are made at: what a left-out log of minutes can
#: show (the asked rate, ~1 per hour, cannot be seen in minutes).
LOLO_RATES: tuple[float, ...] = (30.0, 100.0, 300.0)
#: A collision-free stretch between cut-outs shorter than this is not fitted [samples].
MIN_STRETCH = 10


@dataclass(frozen=True)
class Calibrated:
    """What :func:`calibrate_run` made (its record holds the leave-one-log-out rows and
    the motion envelope too).

    Attributes:
        config: the calibrated config.
        rate: the false-alarm rate: asked (``rate.rate``) or, under the leave-one-out
            rule, predicted for its thresholds (``rate.rate`` None; None when the free
            motion is too short for a tail fit).
    """

    config: DetectorConfig
    rate: RateCalibration | None


def calibrate(logs: list[RobotLog], **options: Any) -> DetectorConfig:
    """The calibrated config of :func:`calibrate_run` (same arguments)."""
    return calibrate_run(logs, **options).config


def calibrate_run(
    logs: list[RobotLog], *, model: RigidModel | None = None,
    config: DetectorConfig | None = None, robot: RobotDescription | None = None,
    generator: str | None = None, labels: Sequence[Labels | None] | None = None,
    drop_suspect: bool = True, allow_slow: bool = False,
    threshold_rule: str = MARGIN_RULE,
    false_alarms_per_hour: float = DEFAULT_FALSE_ALARMS_PER_HOUR, confidence: float = CONF,
    payload_per_log: bool = True,
) -> Calibrated:
    """Thresholds v_stat, vL, v0 per joint from collision-free logs (docs/method.md §5b).

    The model is ``model``, else the config's, else identified from the logs
    (:func:`impactcli.model.selection.select_model` over all of them; for the controller's
    channels :func:`~impactcli.model.selection.identify_correction`). Each log is replayed
    with it;
    its statistics after warm-up, without the stretches ``labels`` mark as contacts (and,
    without labels, stretches that alone would set a product detector's threshold: warned
    about as likely contacts and, with ``drop_suspect``, left out) give the thresholds:

    - ``threshold_rule`` ``false-alarm-rate`` (``calibrate --false-alarms-per-hour``):
      v_stat and vL from the tail fits
      of the whole free logs (:func:`impactcli.detect.tail.calibrate_rate`): the upper
      ``confidence`` bound of the predicted incident rate, over all joints and both
      product detectors, is ``false_alarms_per_hour``; below what the free time supports
      the thresholds are widened and the record says so. v0 (static_baseline) by the
      leave-one-out margin. With ≥ 2 logs, leave-one-log-out rows (predicted against
      observed, at :data:`LOLO_RATES`).
    - ``leave-one-out`` (the default): every threshold by the leave-one-out margin over
      30 s segments (≥ 2 segments) or a fixed margin (1, flagged weak)
      (:mod:`impactcli.detect.thresholds`); the same tail fits state the rate v_stat and
      vL are predicted to give (:func:`impactcli.detect.tail.rates_for_thresholds`), with
      the leave-one-log-out rows as above.

    With planar or URDF kinematics the identified model weighs a payload per log
    (``payload_per_log``; docs/models.md, "Payloads") and each log is replayed with its own.
    The motion envelope of the kept samples is recorded either way
    (:mod:`impactcli.detect.envelope`). Returns the config (every parameter, the
    thresholds, the calibration record, the embedded model) and what ``calibrate`` prints.
    """
    import dataclasses

    from ..config import CalibrationRecord, LogRecord, ThresholdsConfig
    from ..detect.thresholds import calibrate_thresholds
    from ..model.selection import identify_correction, select_model

    if threshold_rule not in THRESHOLD_RULES:
        raise ValueError(f"threshold rule {threshold_rule!r}: one of {THRESHOLD_RULES}")
    cfg = config or DetectorConfig()
    logs = _one_load_each(logs, labels)
    warn_mixed_torque_sources([(lg.source.path, lg.source.torque_source) for lg in logs])
    readers = [MemoryReader(lg) for lg in logs]
    scans = [r.scan() for r in readers]
    screens, left_out = _screen_calibration_logs(scans, model, cfg)
    described = robot or description_of(model, cfg)
    for scan, sc in zip(scans, screens, strict=True):  # a unit's factor: exit 3, as detect
        check_torque_scale(scan, described, sc.keep)   # (a trial's mA currents passed here)
    if generator is not None:  # a new calibration: choose afresh
        cfg = dataclasses.replace(cfg, residual=dataclasses.replace(
            cfg.residual, generator=generator, generators={}))
    frozen = common_generators(scans, screens, cfg)
    cfg = dataclasses.replace(cfg, residual=dataclasses.replace(cfg.residual,
                                                                generators=frozen))
    choices = [generator_choices(sc.keep, sc.logged, scan.source, cfg)
               for scan, sc in zip(scans, screens, strict=True)]
    if needs_model(choices[0], cfg):
        if model is None:
            # the tool's own model: its kind and ridge chosen by held-back error
            # (docs/models.md, "Choosing the model"); a correction model is the robot's
            # kind, with a payload per log where that predicts clearly better held out
            correction = uses_correction(choices[0], cfg.residual.logged_correction)
            fit = identify_correction if correction else select_model
            # in the order of the logs' contents, not of the command line: the same logs
            # give the same model to the last bit (a least-squares fit's sums depend on
            # the row order, and the adaptive replay magnifies the difference)
            order = sorted(range(len(logs)), key=lambda i: (logs[i].source.sha256,
                                                            logs[i].source.path))
            model = RigidModel.from_dict(cfg.model) if cfg.model is not None else fit(
                [target_log(logs[i].select(screens[i].keep), choices[i],
                            cfg.residual.logged_correction) for i in order],
                robot=robot, options=IdentifyOptions(allow_still_joints=True,
                                                     check_sanity=not correction,
                                                     payload_per_log=payload_per_log))
    else:
        model = None
    joints = tuple(model.joint_names) if model is not None else tuple(frozen)
    excluded: list[dict[str, Any]] = []
    # each log replayed with the load its fit found on it (docs/method.md §2, "Payloads")
    replays = [_replay(reader, sc, own_load(model, reader.scan().source.path), cfg, robot,
                       allow_slow) for reader, sc in zip(readers, screens, strict=True)]
    keeps = [_calibration_mask(rp, labels[i] if labels is not None and i < len(labels)
                               else None, excluded) for i, rp in enumerate(replays)]
    if drop_suspect:
        unlabelled = [labels is None or i >= len(labels) or labels[i] is None
                      for i in range(len(replays))]
        _drop_suspects(replays, keeps, joints, excluded, unlabelled)
    segs = [s for rp, keep in zip(replays, keeps, strict=True) for s in _segments(rp, keep)]
    if not segs:
        raise LogFormatError("no collision-free stretch left to calibrate on: "
                             + ", ".join(lg.source.path for lg in logs))
    per_det = {d: [x[3][d] for x in segs] for d in DETECTORS}
    cal = {d: calibrate_thresholds(per_det[d], joints=joints, detector=d) for d in DETECTORS}
    table = {d: {j: float(cal[d].thresholds[k]) for k, j in enumerate(joints)} for d in DETECTORS}
    margins = {d: {j: float(cal[d].margins[k]) for k, j in enumerate(joints)} for d in DETECTORS}
    weak = any(c.weak for c in cal.values())
    envelope = union_envelope(replays, keeps, joints)
    rated = threshold_rule == RATE_RULE
    use = _rate_logs(replays, excluded, warn=rated)
    given = None if rated else np.array([table[d][j] for d in TAIL_DETECTORS for j in joints])
    rate: RateCalibration | None = None
    lolo: list[LoloRow] = []
    try:
        rate, lolo = _rate_thresholds([replays[i] for i in use], [keeps[i] for i in use],
                                      joints, cfg, false_alarms_per_hour, confidence, given)
    except (ConfigError, LogFormatError):
        if rated:
            raise
        # too little free motion to fit a tail: the margin's thresholds stand unstated
    if rate is not None and len(use) < len(replays):
        rate = dataclasses.replace(rate, notes=(*rate.notes, *(
            f"{replays[i].path}: left out of the rate's fit (contacts found in it)"
            for i in range(len(replays)) if i not in use)))
        lolo = [dataclasses.replace(r, log=use[r.log]) for r in lolo]
    if rated and rate is not None:
        table.update(rate.table())
        # the product's margins say what the rate's thresholds are over the free maximum
        for d in TAIL_DETECTORS:
            top = np.max([np.max(x, axis=0) for x in per_det[d]], axis=0)
            margins[d] = {j: float(table[d][j] / top[k]) for k, j in enumerate(joints)
                          if top[k] > 0 and table[d][j] / top[k] > 0}
        weak = cal["static_baseline"].weak or rate.below_support
    paths = tuple(lg.source.path for lg in logs)
    load_envelopes = load_envelopes_of(model, replays, keeps, joints,
                                       table["static_loading"])
    record = CalibrationRecord(
        calibrated=True, margin_rule=cal["adaptive"].rule, margins=margins,
        logs=tuple(LogRecord(lg.source.path, lg.source.sha256, lg.source.torque_source)
                   for lg in logs),
        model_sha256=None if model is None else model.sha256,
        weak=weak,
        joints_left_out=tuple(x.to_dict() for x in left_out),
        segments=len(segs), excluded=tuple(excluded),
        sample_rate_hz=float(np.median([lg.sample_rate_hz for lg in logs])),
        threshold_rule=threshold_rule,
        false_alarm_rate=None if rate is None else rate_record(rate, joints, lolo, paths),
        motion_envelope=None if envelope is None else envelope.to_dict(),
        formulation=cfg.adaptive.formulation,
        load_envelopes=load_envelopes,
    )
    out = dataclasses.replace(
        cfg,
        thresholds=ThresholdsConfig(v_stat=table["adaptive"], v0=table["static_baseline"],
                                    vL=table["static_loading"]),
        calibration=record, model=None if model is None else model.to_dict(),
    )
    out = dataclasses.replace(out, calibration=dataclasses.replace(  # the settings as written
        record, settings_sha256=settings_sha256(out)))
    warn_beyond_effort(out, joints, robot)
    return Calibrated(out, rate)


def _rate_logs(replays: list[_Replayed], excluded: list[dict[str, Any]], warn: bool = True
               ) -> list[int]:
    """The logs the rate's tail is fitted on: those without likely contacts found in them
    (all of them if every log has some). A log in which the suspect rule found contacts
    holds smaller ones it cannot find (it flags only stretches 20× above the usual level),
    and their peaks make the tail look heavy: with the old rule they only raised the
    maximum, here they are extrapolated (measured on the sample pushes log given as free:
    vL 17× the clean calibration's). Warned about; the log still counts for v0."""
    found = {x["log"] for x in excluded if str(x["reason"]).startswith("alone")}
    use = [i for i, rp in enumerate(replays) if rp.path not in found]
    if not use:
        return list(range(len(replays)))
    for rp in replays:
        if warn and rp.path in found:
            warnings.warn(f"{rp.path}: left out of the false-alarm-rate fit: contacts were "
                          "found in it, and smaller ones the 20× rule cannot find would be "
                          "fitted as free motion (give the log's labels to use it)",
                          ImpactWarning, stacklevel=3)
    return use


def _stretches(rp: _Replayed, keep: np.ndarray) -> list[tuple[int, int, bool]]:
    """[a, b) sample ranges of a calibration log's kept samples (after warm-up, cut-outs
    removed), each with whether it begins at the warm-up's end (a log start: the adaptive
    statistic still settles there, :func:`impactcli.detect.tail.split_settle`)."""
    start = _fit_start(rp)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], keep.astype(np.int8), [0]])))
    return [(int(a), int(b), int(a) == start) for a, b in zip(edges[::2], edges[1::2],
                                                              strict=True)
            if b - a >= MIN_STRETCH]


def _rate_thresholds(replays: list[_Replayed], keeps: list[np.ndarray],
                     joints: tuple[str, ...], cfg: DetectorConfig, rate: float, conf: float,
                     given: np.ndarray | None = None
                     ) -> tuple[RateCalibration, list[LoloRow]]:
    """The product's thresholds for ``rate`` false alarms per hour — or, ``given`` (C,)
    thresholds set another way, the rate they are predicted to give — from the tails of
    whole logs (never their 30 s segments: a cluster must not be cut), and the
    leave-one-log-out rows."""
    stats, dts, starts, groups = [], [], [], []
    names: tuple[str, ...] = ()
    for i, (rp, keep) in enumerate(zip(replays, keeps, strict=True)):
        x, names = stack_detectors(rp.stats, joints)
        for a, b, first in _stretches(rp, keep):
            stats.append(x[a:b])
            dts.append(1.0 / rp.sample_rate_hz)
            starts.append(first)
            groups.append(i)
    if not stats:
        raise LogFormatError("no collision-free stretch left to calibrate on: "
                             + ", ".join(rp.path for rp in replays))
    gap = cfg.events.merge_gap_s
    try:
        fits = fit_channels(stats, dts, names=names, merge_gap_s=gap, log_start=starts)
        cal = (thresholds_for_rate(fits, rate, conf=conf) if given is None
               else rates_for_thresholds(fits, given, conf=conf))
    except ValueError as err:
        raise ConfigError(f"--false-alarms-per-hour: {err}") from err
    lolo: list[LoloRow] = []
    if len(set(groups)) >= 2:
        lolo = leave_one_log_out(stats, dts, LOLO_RATES, conf=conf, merge_gap_s=gap,
                                 log_start=starts, groups=groups)
    return cal, lolo


def rate_record(cal: RateCalibration, joints: Sequence[str], lolo: Sequence[LoloRow],
                paths: Sequence[str]) -> dict[str, Any]:
    """The config's ``calibration.false_alarm_rate`` table (docs/formats.md): R when asked
    (with ``supported`` and ``minutes_needed``), confidence, the free-motion time, predicted
    rate and bound, the support, and per detector and joint the threshold and its fit;
    leave-one-log-out rows. No null (TOML)."""
    channels: dict[str, dict[str, Any]] = {}
    for k, (name, fit) in enumerate(zip(cal.names, cal.fits, strict=True)):
        joint, det = name.rsplit("/", 1)
        channels.setdefault(det, {})[joint] = {
            "threshold": float(cal.thresholds[k]),
            "predicted_per_hour": float(cal.predicted[k]),
            "upper_per_hour": float(cal.upper[k]),
            "shape": "exponential" if fit.xi_fixed or fit.xi <= 0 else "gpd",
            "xi": float(fit.xi), "sigma": float(fit.sigma), "level": float(fit.u),
            "clusters": int(fit.n), "free_max": float(fit.max_stat),
            "widened": bool(cal.widened[k]), "log_start_floor": bool(cal.floored[k]),
        }
    asked = {} if cal.rate is None else {
        "per_hour": float(cal.rate), "supported": not cal.below_support,
        "minutes_needed": float(minutes_needed(cal.rate, cal.conf))}
    return {
        **asked, "confidence": float(cal.conf),
        "free_minutes": float(cal.hours * 60.0),
        "predicted_per_hour": cal.predicted_total, "upper_per_hour": cal.upper_total,
        "supported_per_hour": float(cal.rate_supported),
        "statement": cal.support_statement(),
        "channels": channels, "notes": list(cal.notes),
        "leave_one_log_out": [
            {"log": str(paths[r.log]), "minutes": float(r.hours * 60.0),
             "per_hour": float(r.rate), "observed": int(r.observed),
             "predicted_per_hour": float(r.predicted), "upper_per_hour": float(r.upper)}
            for r in lolo],
    }


@dataclass(frozen=True)
class _Replayed:
    """A calibration log replayed: its path, (N,) times [s], sample rate [Hz], warm-up,
    detector → (N, J) statistic (:class:`impactcli.run.collect.ReplayStats`), and its
    motion (:class:`impactcli.detect.envelope.MotionTrace`), what it was made of and the
    speed its slow clock was read with [rad/s] (twice the model's Coulomb scale)."""

    path: str
    time_s: np.ndarray
    sample_rate_hz: float
    warmup: Warmup
    stats: dict[str, np.ndarray]
    motion: Motion | None = None
    motion_source: str = "position"
    slow_rad_s: float = SLOW_RAD_S

    @property
    def n_samples(self) -> int:
        return int(self.time_s.shape[0])


def _replay(reader: MemoryReader, sc: Screened, model: RigidModel | None,
            cfg: DetectorConfig, robot: RobotDescription | None,
            allow_slow: bool) -> _Replayed:
    """One calibration log's threshold-free replay (the joints screened ``sc``), its
    warnings raised in the order a detection run gives them."""
    scan = reader.scan()
    where = scan.source.path
    caught = CaughtWarnings()
    try:
        with caught:
            check_replayable(where, len(sc.keep), scan.sample_rate_hz, scan.n_samples,
                             scan.duration_s, cfg, allow_slow)
            feed = ChunkFeed(reader, max(scan.n_samples, 1), sc.keep, sc.unlogged)

            def identify(choices: tuple[GeneratorChoice, ...], kind: str | None,
                         rbt: RobotDescription | None, sanity: bool) -> RigidModel:
                return identify_from_chunks(feed, cfg, choices, kind, rbt, sanity)

            joints, choices, rig, source, extra = resolve_model(
                sc.keep, scan.source, sc.logged, model, cfg, False, robot, identify,
                sc.left_out)
            plan = RunPlan(cfg, where, feed.full_joints, joints, choices, rig, source, extra)
            since = caught.mark()
            collected = StatsCollector()
            trace = MotionTrace(scan.sample_rate_hz, slow_rad_s=slow_speed(
                plan.model if plan.model is not None else model))
            moved: list[Motion] = []

            def on_step(step: ReplayStep) -> None:
                collected(step)
                assert step.position is not None
                moved.append(trace.update(step.t, step.position, step.position_ref))

            rp = replay_passes(feed, plan, on_step)
            warn_replayed(caught, since, plan, feed, rp)
    finally:
        caught.raise_again(impact=True)
    st = collected.stats()
    motion = Motion.joined(moved) if moved else None
    return _Replayed(where, st.time_s, scan.sample_rate_hz, rp.warmup, st.stats, motion,
                     trace.source or "position", trace.slow_rad_s)


#: Labelled contacts are cut out of a calibration log's statistic from this long before
#: their start to this long after their end [s] (the residual's filters and the RMS windows
#: spread a contact's effect after it).
LABEL_GUARD_S = (0.1, 1.0)


def _one_load_each(logs: list[RobotLog], labels: Sequence[Labels | None] | None,
                   ) -> list[RobotLog]:
    """Each log up to its first labelled payload change (the labels' ``payload_changes``,
    a step of non-zero mass at ``t_s``; :data:`LABEL_GUARD_S` before it), warned of: the
    model weighs one load per log, and a log that carries two would be fitted with their
    mean and widen every threshold (a trial's pick-and-place log among the free logs: vL
    30× wider, every push of an audited log missed, "predicted 18 false alarms per hour")."""
    from ..quality.payload_scores import labelled_steps

    out = []
    for i, lg in enumerate(logs):
        lab = labels[i] if labels is not None and i < len(labels) else None
        steps = sorted(float(x["t_s"]) for x in labelled_steps(
            lab.extra.get("payload_changes") or () if lab is not None else ()))
        if not steps:
            out.append(lg)
            continue
        t = lg.time_s
        stop = int(np.searchsorted(t, steps[0] - LABEL_GUARD_S[0]))
        warnings.warn(
            f"{lg.source.path}: its labels list {len(steps)} payload change(s), the first at "
            f"{steps[0]:g} s: used up to {t[max(stop - 1, 0)]:.1f} s only — the model weighs "
            "one load per log (split the log at its changes to calibrate on the rest)",
            ImpactWarning, stacklevel=3)
        out.append(lg.slice(0, stop))
    return out


def _fit_start(rp: _Replayed) -> int:
    """The first sample that counts: the warm-up's end (the log's start if warm-up covers
    nearly all of it)."""
    return rp.warmup.end_index if rp.warmup.end_index < rp.n_samples - 10 else 0


def _calibration_mask(rp: _Replayed, labels: Labels | None,
                      excluded: list[dict[str, Any]]) -> np.ndarray:
    """(N,) samples of a calibration log that count: after warm-up, outside labelled
    contacts (each recorded in ``excluded``)."""
    path, t, n = rp.path, rp.time_s, rp.n_samples
    start = _fit_start(rp)
    keep = np.zeros(n, dtype=bool)
    keep[start:] = True
    if labels is not None:
        for e in labels.events:
            a, b = e.start - LABEL_GUARD_S[0], e.end + LABEL_GUARD_S[1]
            keep &= ~((t >= a) & (t <= b))
            excluded.append({"log": path, "start_s": float(max(a, 0.0)),
                             "end_s": float(min(b, t[-1])),
                             "reason": f"labelled {e.kind} ({e.peak_force:g} N)"})
    return keep


def _drop_suspects(replays: list[_Replayed], keeps: list[np.ndarray], joints: tuple[str, ...],
                   excluded: list[dict[str, Any]], searched: list[bool]) -> None:
    """Clear, in ``keeps``, the 1 s blocks that alone would set a product detector's
    threshold (:func:`impactcli.detect.thresholds.suspect_blocks`), with a guard around
    them; each stretch is warned about and recorded in ``excluded``."""
    from ..detect.thresholds import (
        SUSPECT_BLOCK_S,
        SUSPECT_GUARD_S,
        SUSPECT_RATIO,
        suspect_blocks,
    )

    rows = []  # (log index, block start, block stop, (J,) max over product detectors)
    for i, (rp, keep) in enumerate(zip(replays, keeps, strict=True)):
        b = max(1, round(SUSPECT_BLOCK_S * rp.sample_rate_hz))
        for a in range(0, rp.n_samples, b):
            k = keep[a:a + b]
            if k.sum() < b // 2:
                continue
            m = np.max([np.max(rp.stats[d][a:a + b][k], axis=0)
                        for d in ("adaptive", "static_loading")], axis=0)
            rows.append((i, a, min(a + b, rp.n_samples), m))
    if not rows:
        return
    bad, ratio = suspect_blocks(np.array([r[3] for r in rows]))
    for (i, a, b, m), is_bad, q in zip(rows, bad, ratio, strict=True):
        if not is_bad or not searched[i]:  # a labelled log: its labels say where
            continue
        rp = replays[i]
        t = rp.time_s
        lo, hi = t[a] - SUSPECT_GUARD_S, t[b - 1] + SUSPECT_GUARD_S
        keeps[i] &= ~((t >= lo) & (t <= hi))
        j = joints[int(np.argmax(m))] if len(joints) == len(m) else "?"
        why = (f"alone it would set a threshold of {j} {q:.3g}× above the calibration's usual "
               f"level (> {SUSPECT_RATIO:g}×): a likely contact")
        last = excluded[-1] if excluded else None
        if last is not None and last["log"] == rp.path and \
                last["reason"].startswith("alone") and lo <= last["end_s"] + SUSPECT_BLOCK_S:
            last["end_s"] = float(min(hi, t[-1]))  # merge with the previous stretch
            last["reason"] = max(last["reason"], why, key=_ratio_of)
            continue
        excluded.append({"log": rp.path, "start_s": float(max(lo, 0.0)),
                         "end_s": float(min(hi, t[-1])), "reason": why})
    for x in excluded:
        if x["reason"].startswith("alone"):
            warnings.warn(f"{x['log']}: {x['start_s']:.1f}–{x['end_s']:.1f} s: {x['reason']}; "
                          "left out of the calibration (give the log's labels, or "
                          "--keep-suspect to keep it)", ImpactWarning, stacklevel=3)


def _ratio_of(reason: str) -> float:
    """The ratio a suspect stretch's reason states (``... 125× above ...``)."""
    import re

    m = re.search(r" ([0-9.e+]+)× above", reason)
    return float(m.group(1)) if m else 0.0


def _segments(
    rp: _Replayed, keep: np.ndarray,
) -> list[tuple[str, float, float, dict[str, np.ndarray]]]:
    """(log path, start s, end s, detector → (n, J) statistic) per segment after warm-up
    (:func:`impactcli.detect.thresholds.segment_bounds`), over the ``keep`` samples."""
    from ..detect.thresholds import segment_bounds

    path, t, n = rp.path, rp.time_s, rp.n_samples
    start = int(np.argmax(keep)) if keep.any() else n
    out = []
    for a, b in segment_bounds(n - start, rp.sample_rate_hz):
        idx = np.arange(start + a, start + b)
        idx = idx[keep[idx]]
        if idx.size < 10:
            continue
        out.append((path, float(t[start + a]), float(t[start + b - 1]),
                    {d: s[idx] for d, s in rp.stats.items()}))
    return out


def _screen_calibration_logs(
    scans: list[LogScan], model: RigidModel | None, cfg: DetectorConfig,
) -> tuple[list[Screened], tuple[LeftOut, ...]]:
    """Every calibration log screened (:func:`impactcli.run.plan.screen_scan`). A joint whose
    torque is measured in some log is kept in a log where it stands still (its positions
    span :data:`~impactcli.run.run_warnings.MOVED_RAD` or less: a still joint shows a flat or
    few-valued torque there, and moves in another); a joint left out of a log for any other
    reason — a flat torque while it moves is a channel that failed — or unmeasured in all,
    is left out of all (a threshold needs every log), with the first reason found. Only the
    final screen warns."""
    known = known_joints(model, cfg)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", ImpactWarning)
        per = [screen_scan(scan, known) for scan in scans]
    measured = frozenset(j for sc in per for j in sc.keep)
    reasons: dict[str, str] = {}
    rescued: set[tuple[str, str]] = set()  # (log, joint) kept: measured in another log
    for scan, sc in zip(scans, per, strict=True):
        for x in sc.left_out:
            if x.reason.startswith("torque ") and x.name in measured and _still(scan, x.name):
                rescued.add((scan.source.path, x.name))
                warnings.warn(f"{scan.source.path}: joint {x.name!r}: its {x.reason} here, "
                              "but it is measured in another calibration log: kept",
                              ImpactWarning, stacklevel=3)
                continue
            reasons.setdefault(x.name, f"{x.reason}, in {scan.source.path}")
    for w in said:  # the first screen's warnings, but of the joints kept after all
        if not any(str(w.message).startswith(f"{p}: joint {j!r} left out") for p, j in rescued):
            warnings.warn(w.message, stacklevel=3)
    out = []
    for scan in scans:
        keep = tuple(j for j in scan.joint_names if j not in reasons)
        if not keep:
            raise LogFormatError(f"{scan.source.path}: no joint left to calibrate")
        with warnings.catch_warnings():  # said above, once
            warnings.simplefilter("ignore", ImpactWarning)
            out.append(screen_scan(scan, None if reasons else known, joints=keep,
                                   measured=measured))
    return out, tuple(LeftOut(j, r) for j, r in reasons.items())


def _still(scan: LogScan, joint: str) -> bool:
    """Whether ``joint`` stands still in the scanned log: its positions span no more than
    :data:`~impactcli.run.run_warnings.MOVED_RAD`, what moving means for a joint left out."""
    rng = scan.ranges.get("position")
    if rng is None or joint not in scan.joint_names:
        return False
    k = scan.joint_names.index(joint)
    span = float(rng[1][k] - rng[0][k])
    return bool(np.isfinite(span) and span <= MOVED_RAD)


#: The order ``auto`` prefers, best first.
_PREFERENCE = ("logged_external", "logged_model", "inverse_dynamics")


def common_generators(scans: list[LogScan], screens: list[Screened],
                      cfg: DetectorConfig) -> dict[str, str]:
    """joint → generator to freeze for calibration logs (each joint gets the best generator
    that every log supports: a channel missing from one log rules it out for all)."""
    per_log = [{c.joint: c.generator
                for c in generator_choices(sc.keep, sc.logged, scan.source, cfg)}
               for scan, sc in zip(scans, screens, strict=True)]
    joints = list(per_log[0])
    out: dict[str, str] = {}
    for j in joints:
        if any(j not in m for m in per_log):
            continue  # joint names differ between logs: the model/replay reports it
        gens = [m[j] for m in per_log]
        out[j] = max(gens, key=lambda g: _PREFERENCE.index(g) if g in _PREFERENCE else -1)
    return out
