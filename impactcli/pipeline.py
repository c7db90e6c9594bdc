"""analyze(log, ...) -> DetectionResult: the one entry for the CLI, tests and batch runs.

The flow, one direction (architecture.md):
  RobotLog → rigid model (given, embedded in the config, or identified from the log)
           → causal residual r = tau_hat − tau (eq. 7–8; tau through the same causal filter)
           → adaptive evaluator (eq. 24–42) beside static_loading (|LP(r)| > vL) and
             static_baseline (|r| > v0)
           → warm-up, thresholds (calibrated, or the log's own robust rule), decisions, events.
Nothing here reads or writes files; everything it decided is in the result.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .config import CalibrationRecord, DetectorConfig
from .detect.adaptive import (
    AdaptiveResult,
    check_scale,
    default_threads,
    replay_cost,
)
from .detect.calibrate import (
    UNCALIBRATED_BLOCK_S,
    UNCALIBRATED_MARGIN,
    UNCALIBRATED_QUANTILE,
    UNCALIBRATED_RULE,
    adaptive_statistic,
    uncalibrated_thresholds,
)
from .detect.events import LONG_EVENT_S, extract_events
from .detect.incidents import Incident
from .detect.screen import LeftOut, unusable_columns
from .detect.warmup import Warmup, warmup_end
from .errors import ConfigError, ImpactWarning, LogFormatError, ModelError
from .io.inspect import GAP_FACTOR, time_gaps
from .model import IdentifyOptions, ResidualOptions, RigidModel, identify
from .model.generators import (
    OWN_MODEL,
    GeneratorChoice,
    choices_dict,
    choose_generators,
    needs_own_model,
    summary_name,
    target_log,
    uses_correction,
)
from .replay import ReplaySetup, ReplayState, chunk_arrays, replay_chunk
from .result import DetectionResult
from .sampling import check_calibrated_rate
from .types import CONTROLLER_CHANNELS, DETECTORS, RobotDescription, RobotLog

#: The adaptive evaluator reports its progress per axis when its estimated cost is this
#: long or longer [s] (many joints; :func:`impactcli.detect.adaptive.replay_cost`).
PROGRESS_AFTER_S = 10.0


def residual_options(cfg: DetectorConfig, generator: str | None = None) -> ResidualOptions:
    """The own-model residual generator's options from the detector config (``generator``:
    ``inverse_dynamics`` or ``momentum_observer``; default the config's, ``auto`` and the
    logged generators falling back to ``inverse_dynamics``)."""
    rc = cfg.residual
    g = generator or rc.generator
    if g not in OWN_MODEL:
        g = "inverse_dynamics"
    return ResidualOptions(cutoff_hz=rc.derivative_cutoff_hz, filter_torque=rc.filter_torque,
                           generator=g, observer_gain=rc.observer_gain)


def generator_choices(log: RobotLog, cfg: DetectorConfig) -> tuple[GeneratorChoice, ...]:
    """Each joint's residual generator for ``log`` under ``cfg`` (frozen choices win)."""
    return choose_generators(log, cfg.residual.generator, cfg.residual.generators or None)


def needs_model(choices: tuple[GeneratorChoice, ...], cfg: DetectorConfig) -> bool:
    """Whether a rigid model is needed: some joint uses the tool's own model, or a logged
    channel is corrected by one (``residual.logged_correction``)."""
    return needs_own_model(choices) or uses_correction(choices, cfg.residual.logged_correction)


def reorder_log(log: RobotLog, joints: tuple[str, ...], what: str) -> RobotLog:
    """The log with its joints in ``joints`` order; ModelError naming what is missing."""
    if log.joint_names == joints:
        return log
    missing = [j for j in joints if j not in log.joint_names]
    extra = [j for j in log.joint_names if j not in joints]
    if missing or extra:
        raise ModelError(
            f"{log.source.path}: joints {list(log.joint_names)} do not match the {what}'s "
            f"{list(joints)}" + (f" (missing {missing})" if missing else "")
            + (f" (not in the {what}: {extra})" if extra else "")
        )
    return log.select(joints)


def resolve_model(
    log: RobotLog, model: RigidModel | None, cfg: DetectorConfig, robot: RobotDescription | None,
    model_from_log: bool = False, sanity: bool = True,
) -> tuple[RigidModel, str]:
    """The model to use and where it came from (``given``, ``config``, ``identified-from-log``).

    ``model_from_log`` identifies the model from this log even when the config embeds one,
    with the config model's structure (kind and robot description), keeping the config's
    thresholds: offline only, for a robot whose dynamics changed since calibration (an
    unknown payload) — the identification absorbs the change for the static detectors.
    """
    if model_from_log:
        if model is not None:
            raise ConfigError("--model and --model-from-log exclude each other")
        kind, robot = from_log_structure(cfg, robot)
        return identify(log, robot=robot, kind=kind,
                        options=IdentifyOptions(allow_still_joints=True, check_sanity=sanity)), \
            "identified-from-log"
    if model is not None:
        if cfg.calibration.calibrated and cfg.calibration.model_sha256 not in (None, model.sha256):
            warnings.warn(
                "--model overrides the config's model: its thresholds belong to the model they "
                "were calibrated with (another model gives the residual another scale)",
                ImpactWarning, stacklevel=3,
            )
        return model, "given"
    if cfg.model is not None:
        return RigidModel.from_dict(cfg.model), "config"
    # offline convenience: a joint that never moves keeps only its offset (warned about)
    return identify(log, robot=robot, options=IdentifyOptions(
        allow_still_joints=True, check_sanity=sanity)), "identified-from-log"


def from_log_structure(cfg: DetectorConfig, robot: RobotDescription | None,
                       ) -> tuple[str | None, RobotDescription | None]:
    """``--model-from-log``: the kind and robot of the config's model, to identify the same
    structure from the log (warned about when the config's thresholds were calibrated:
    they belong to the config's model)."""
    kind = None
    if cfg.model is not None:
        kind = cfg.model.get("kind")
        if robot is None and cfg.model.get("robot"):
            from .io.robot import robot_from_dict

            robot = robot_from_dict(cfg.model["robot"], "the config's model")
    if cfg.calibration.calibrated:
        warnings.warn(
            "--model-from-log: the config's thresholds were calibrated with another model; "
            "this run is offline only (not what the robot could have run)",
            ImpactWarning, stacklevel=4,
        )
    return kind, robot


def calibrated_thresholds(
    cfg: DetectorConfig, joints: tuple[str, ...],
) -> dict[str, np.ndarray] | None:
    """Per-detector threshold vectors from a calibrated config, or None if not calibrated."""
    th = cfg.thresholds
    if not cfg.calibration.calibrated:
        return None
    out = {}
    pairs = (("adaptive", th.v_stat), ("static_loading", th.vL), ("static_baseline", th.v0))
    for det, table in pairs:
        missing = [j for j in joints if j not in table]
        if missing:
            raise ConfigError(f"calibrated config has no {det} threshold for joint(s) {missing}")
        out[det] = np.array([table[j] for j in joints], dtype=np.float64)
    return out


def analyze(
    log: RobotLog, *, model: RigidModel | None = None, config: DetectorConfig | None = None,
    robot: RobotDescription | None = None, read_options: dict[str, Any] | None = None,
    model_from_log: bool = False, generator: str | None = None, config_where: str = "config",
    allow_slow: bool = False, progress: Callable[[int, int], None] | None = None,
) -> DetectionResult:
    """Replay the detectors over ``log`` exactly as the robot would have run them online.

    Args:
        log: the recording.
        model: a rigid model (``--model``); else the config's embedded model; else one is
            identified from this log (robust fit; an offline convenience, recorded as such).
        config: detector config (``--config``); None → Table I defaults, uncalibrated.
        robot: robot description, used only when identifying (kinematics, joint order).
        read_options: how the log was read (recorded so the run can be repeated).
        model_from_log: identify the model from this log even with a config (keeping the
            config's thresholds; see :func:`resolve_model`).
        generator: ``--generator`` (:func:`with_generator`); None keeps the config's.
        config_where: the config's file, for messages.
        allow_slow: run even when the replay's estimated cost is above the limit
            (:func:`impactcli.detect.adaptive.check_scale`).
        progress: called with (axes done, axes) by the adaptive evaluator when its
            estimated cost is ``PROGRESS_AFTER_S`` or more.
    Returns:
        The :class:`DetectionResult`; ImpactWarnings raised on the way are in ``warnings``.
    """
    cfg = with_generator(config or DetectorConfig(), generator, config_where)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ImpactWarning)
        known = _known_joints(model, cfg)
        check_calibrated_rate(log.sample_rate_hz, cfg.calibration.sample_rate_hz, log.source.path,
                              f"its config ({config_where})")
        full = log
        log, left_out = screen_log(log, known, cfg.calibration.joints_left_out)
        left_out = tuple(LeftOut(j, why) for j, why in log.source.joints_dropped) + left_out
        result = _analyze(log, model, cfg, robot, read_options or {}, model_from_log,
                          allow_slow, progress)
        result = dataclasses.replace(result, incidents=tuple(
            find_incidents(result, full, robot, cfg.events.merge_gap_s)))
        result = dataclasses.replace(result, joints_left_out=tuple(
            x.to_dict() for x in left_out) + result.joints_left_out)
    msgs = tuple(dict.fromkeys(
        str(w.message) for w in caught if issubclass(w.category, ImpactWarning)))
    for w in caught:  # foreign warnings are not ours to swallow
        if not issubclass(w.category, ImpactWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return _with_warnings(result, msgs)


def find_incidents(
    result: DetectionResult, full: RobotLog, robot: RobotDescription | None,
    merge_gap_s: float,
) -> list[Incident]:
    """The incidents of a whole-log replay (:mod:`impactcli.contacts`): grouped product
    events, the isolated link, the force at it (with kinematics), the contact type."""
    from .contacts import build_incidents, incident_context
    from .model.derivatives import causal_derivatives
    from .replay import SPEED_CUTOFF_HZ

    log = result.log
    vl = np.array([result.thresholds[j]["vL"] for j in log.joint_names])
    dt = log.sample_period_s
    ctx = incident_context(log.joint_names, full.joint_names, robot, result.model, vl, dt,
                           log.t0_ns, log.n_samples, merge_gap_s, log.source.path)
    _, qd, _ = causal_derivatives(dt, np.asarray(log.position), min(SPEED_CUTOFF_HZ, 0.2 / dt))
    return build_incidents(ctx, list(result.events), log.time_s, result.signals["residual"],
                           result.signals["loading_statistic"], result.decisions["adaptive"],
                           result.decisions["static_loading"], np.asarray(full.position), qd)


def _known_joints(model: RigidModel | None, cfg: DetectorConfig) -> tuple[str, ...] | None:
    """The joints detection can run on by what was given: the model's (``--model``), else
    the config's model's, else a calibrated config's thresholds'; None: any."""
    if model is not None:
        return tuple(model.joint_names)
    if cfg.model is not None:
        return tuple(cfg.model["joint_names"])
    if cfg.calibration.calibrated and cfg.thresholds.v_stat:
        return tuple(cfg.thresholds.v_stat)
    return None


def screen_log(
    log: RobotLog, known: tuple[str, ...] | None = None,
    recorded: tuple[dict[str, str], ...] = (),
) -> tuple[RobotLog, tuple[LeftOut, ...]]:
    """The log without the joints detection cannot use, and those joints with why
    (:mod:`impactcli.detect.screen`), each warned about once.

    Args:
        log: the log as read.
        known: the joints the model or the calibrated config covers (None: any). A logged
            joint outside them is left out (a joint they need that the log lacks stays an
            error, raised later).
        recorded: joints a calibration left out (``calibration.joints_left_out``).
    Also reads a flat or unmeasured controller channel as not logged for that joint.
    """
    ref = float(np.max(np.ptp(log.torque, axis=0)))
    keep, left, unlogged = screen_plan(
        log.source.path, log.joint_names, known, recorded,
        unusable_columns(log.torque, ref),
        lambda ch, cols: unusable_columns(getattr(log, ch)[:, cols], ref)
        if getattr(log, ch) is not None else None)
    if left:
        log = log.select(keep)
    changes: dict[str, Any] = {}
    for ch, ks in unlogged.items():
        m = np.array(getattr(log, ch))
        m[:, ks] = np.nan
        changes[ch] = m
    if changes:
        log = dataclasses.replace(log, **changes)
    return log, left


def screen_plan(
    where: str, joint_names: tuple[str, ...], known: tuple[str, ...] | None,
    recorded: tuple[dict[str, str], ...], torque_why: list[str | None],
    channel_why: Callable[[str, list[int]], list[str | None] | None],
) -> tuple[tuple[str, ...], tuple[LeftOut, ...], dict[str, list[int]]]:
    """What :func:`screen_log` decides, from the screen of the whole log's columns (each
    decision warned about once; a streamed replay gives the screen of its first pass).

    Args:
        where: the log's path. joint_names: as logged. known, recorded: as screen_log.
        torque_why: per logged joint, ``unusable_columns`` of its torque.
        channel_why: (controller channel, kept columns) → ``unusable_columns`` of those
            columns of the channel, or None when the log has no such channel.
    Returns:
        (the joints kept, the joints left out with why, controller channel → the kept
        columns read as not logged).
    """
    left: list[LeftOut] = []
    at_cal = {d["name"]: d["reason"] for d in recorded}
    for j in joint_names:
        if j in at_cal:
            left.append(LeftOut(j, f"left out at calibration ({at_cal[j]})"))
        elif known is not None and j not in known:
            left.append(LeftOut(j, "not in the model or the calibrated config"))
    out = {x.name for x in left}
    for j, why in zip(joint_names, torque_why, strict=True):
        if why is not None and j not in out:
            left.append(LeftOut(j, f"torque {why}"))
    for x in left:
        warnings.warn(f"{where}: joint {x.name!r} left out of detection: {x.reason}",
                      ImpactWarning, stacklevel=3)
    keep = tuple(j for j in joint_names if j not in {x.name for x in left})
    if not keep:
        raise LogFormatError(f"{where}: no joint left to detect on ("
                             + "; ".join(f"{x.name}: {x.reason}" for x in left) + ")")
    cols = [joint_names.index(j) for j in keep]
    unlogged: dict[str, list[int]] = {}
    for ch in CONTROLLER_CHANNELS:
        bad = channel_why(ch, cols)
        if bad is None or not any(bad):
            continue
        unlogged[ch] = [k for k, why in enumerate(bad) if why is not None]
        for k, why in enumerate(bad):
            if why is not None:
                warnings.warn(f"{where}: joint {keep[k]!r}: its {ch} is "
                              f"{why}; read as not logged", ImpactWarning, stacklevel=3)
    return keep, tuple(left), unlogged


def with_generator(cfg: DetectorConfig, generator: str | None,
                   where: str = "config") -> DetectorConfig:
    """``cfg`` with ``--generator`` applied. ``auto`` or None keeps a calibrated config's
    frozen choices; another generator where the config froze a different one is a
    ConfigError (its thresholds belong to the generator they were made with)."""
    if generator is None:
        return cfg
    frozen = cfg.residual.generators if cfg.calibration.calibrated else {}
    if generator != "auto":
        other = {j: g for j, g in frozen.items() if g != generator}
        if other:
            j, g = next(iter(other.items()))
            raise ConfigError(
                f"{where}: its thresholds were calibrated with the {g} generator for joint "
                f"{j!r}; --generator {generator} cannot use them (calibrate again with "
                f"--generator {generator})")
    elif frozen:
        return cfg
    return dataclasses.replace(cfg, residual=dataclasses.replace(
        cfg.residual, generator=generator, generators=dict(frozen)))


def _with_warnings(result: DetectionResult, msgs: tuple[str, ...]) -> DetectionResult:
    import dataclasses

    return dataclasses.replace(result, warnings=result.warnings + msgs)


@dataclass(frozen=True)
class Replay:
    """The threshold-free part of a replay: residual, adaptive signals, statistics, warm-up.

    ``stats`` maps each detector to the (N, J) statistic its threshold must beat:
    adaptive r_rms − v_rms (eq. 42), static_loading |LP(r)|, static_baseline |r|.
    """

    log: RobotLog
    model: RigidModel | None
    model_source: str
    residual_options: ResidualOptions
    r: np.ndarray
    adaptive: AdaptiveResult
    reference_source: str
    warmup: Warmup
    stats: dict[str, np.ndarray]
    threshold_inputs: str = ""
    gaps: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    choices: tuple[GeneratorChoice, ...] = ()
    left_out: tuple[LeftOut, ...] = ()

    def stats_after_warmup(self) -> dict[str, np.ndarray]:
        """Each statistic from the warm-up's end on (all of it if the warm-up covers the log)."""
        start = self.warmup.end_index if self.warmup.end_index < self.log.n_samples - 10 else 0
        return {d: s[start:] for d, s in self.stats.items()}


def check_replayable(where: str, n_joints: int, sample_rate_hz: float, n_samples: int,
                     duration_s: float, cfg: DetectorConfig, allow_slow: bool) -> None:
    """Before any work: the replay's cost (it depends on the joints, not the duration;
    refused above the limit unless ``allow_slow``), then a log longer than the warm-up."""
    if not allow_slow:
        check_scale(n_joints, sample_rate_hz, cfg.adaptive, where)
    if duration_s < cfg.warmup.min_s:
        raise LogFormatError(
            f"{where}: {n_samples} samples ({duration_s:.3g} s), shorter than "
            f"the detectors' warm-up (warmup.min_s = {cfg.warmup.min_s:g} s): nothing after it "
            "could be detected")


def replay(
    log: RobotLog, model: RigidModel | None, cfg: DetectorConfig,
    robot: RobotDescription | None = None, v_stat: np.ndarray | None = None,
    model_from_log: bool = False, allow_slow: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> Replay:
    """Residual → adaptive evaluator and static statistics → warm-up (all causal)."""
    check_replayable(log.source.path, log.n_joints, log.sample_rate_hz, log.n_samples,
                     log.duration_s, cfg, allow_slow)
    choices = generator_choices(log, cfg)
    model_source = "none"
    left_out: tuple[LeftOut, ...] = ()
    if needs_model(choices, cfg):
        target = target_log(log, choices, cfg.residual.logged_correction)
        model, model_source = resolve_model(
            target, model, cfg, robot, model_from_log,
            sanity=not uses_correction(choices, cfg.residual.logged_correction))
        extra = [j for j in log.joint_names if j not in model.joint_names]
        if extra and all(j in log.joint_names for j in model.joint_names):
            for j in extra:  # e.g. a logged joint the URDF does not have
                warnings.warn(f"{log.source.path}: joint {j!r} left out of detection: not in "
                              "the model", ImpactWarning, stacklevel=3)
            left_out += tuple(LeftOut(j, "not in the model") for j in extra)
            log = log.select(tuple(model.joint_names))
        log = reorder_log(log, tuple(model.joint_names), "model")
    else:
        model = None
        order = tuple(cfg.residual.generators)
        if set(order) == set(log.joint_names):  # a calibrated config's joint order
            log = reorder_log(log, order, "config")
    choices = generator_choices(log, cfg)
    target = target_log(log, choices, cfg.residual.logged_correction)
    fs = log.sample_rate_hz
    gaps, lengths = time_gaps(log)
    warn_gaps(log.source.path, lengths, log.time_s[gaps])
    ropts = residual_options(cfg)
    cost, _ = replay_cost(log.n_joints, fs, cfg.adaptive)
    shown = progress if progress is not None and cost * log.duration_s >= PROGRESS_AFTER_S \
        else None
    setup = ReplaySetup(log.joint_names, choices, model, cfg, fs, log.sample_period_s,
                        threads=default_threads(log.n_samples))
    out, _ = replay_chunk(setup, ReplayState.initial(setup), chunk_arrays(log, log.time_s),
                          where=log.source.path, progress=shown, consume=True)
    r, ad = out.r, out.adaptive
    if out.inputs_source == "measured":
        warnings.warn(f"{log.source.path}: no reference logged: threshold inputs from the "
                      "measured position (no anticipation)", ImpactWarning, stacklevel=3)
    wu = warmup_end(ad.prediction_error, log.time_s, cfg.warmup)
    ts = log.time_s
    warn_warmup(log.source.path, wu, [float(ts[i]) if i < log.n_samples else wu.end_s
                                      for i in wu.index],
                log.joint_names, log.n_samples, log.duration_s, cfg)
    loading = out.loading
    stats = {"adaptive": adaptive_statistic(ad.r_rms, ad.v_rms), "static_loading": loading,
             "static_baseline": np.abs(r)}
    return Replay(log, model, model_source, ropts, r, ad,
                  "measured" if out.inputs_source == "measured" else "reference", wu, stats,
                  out.inputs_detail, gaps, choices, left_out)


def _analyze(
    log: RobotLog, model: RigidModel | None, cfg: DetectorConfig,
    robot: RobotDescription | None, read_options: dict[str, Any], model_from_log: bool = False,
    allow_slow: bool = False, progress: Callable[[int, int], None] | None = None,
) -> DetectionResult:
    rp = replay(log, model, cfg, robot, model_from_log=model_from_log, allow_slow=allow_slow,
                progress=progress)
    log, ad, wu, r = rp.log, rp.adaptive, rp.warmup, rp.r
    joints = log.joint_names
    t = log.time_s
    given = calibrated_thresholds(cfg, joints)  # None when not calibrated; model joint order
    if given is None:
        after = rp.stats_after_warmup()
        cals = {d: uncalibrated_thresholds(after[d], log.sample_rate_hz) for d in DETECTORS}
        thr = {d: c.thresholds for d, c in cals.items()}
        cfg = dataclasses.replace(cfg, calibration=CalibrationRecord(
            calibrated=False, margin_rule=UNCALIBRATED_RULE,
            margins={d: {j: float(m) for j, m in zip(joints, c.margins, strict=True)}
                     for d, c in cals.items()},
        ))
        warn_uncalibrated(log.source.path)
    else:
        thr = given
    loading = rp.stats["static_loading"]
    threshold_adaptive, ratios, decisions = compare_to_thresholds(
        thr, ad.r_rms, ad.v_rms, loading, rp.stats["static_baseline"])
    ev = cfg.events
    events = []
    for d in DETECTORS:
        events += extract_events(d, decisions[d], ratios[d], r, t, joints, wu.end_s,
                                 ev.merge_gap_s, ev.min_duration_s)
    events.sort(key=lambda e: (e.t_start, DETECTORS.index(e.detector)))
    _warn_events_after_gaps(log, rp.gaps, events)
    _warn_long_events(log, events)

    freqs, gain = ad.g_gain()
    signals = {
        "torque": np.asarray(log.torque), "residual": r, "filtered_residual": ad.r_tilde,
        "dynamic_threshold": ad.v_dyn, "residual_rms": ad.r_rms, "threshold": threshold_adaptive,
        "loading_statistic": loading,
    }
    thresholds = {
        j: {"v_stat": float(thr["adaptive"][k]), "v0": float(thr["static_baseline"][k]),
            "vL": float(thr["static_loading"][k])}
        for k, j in enumerate(joints)
    }
    return DetectionResult(
        log=log, model=None if rp.model is None else rp.model.to_dict(),
        model_sha256=None if rp.model is None else rp.model.sha256,
        model_source=rp.model_source, config=cfg.to_dict(), calibrated=given is not None,
        thresholds=thresholds, reference_source=rp.reference_source,
        threshold_inputs=rp.threshold_inputs,
        torque_filtered=rp.residual_options.filter_torque,
        signals=signals, decisions=decisions, ratios=ratios, events=tuple(events),
        warmup_end_s=wu.end_s,
        warmup_per_joint_s={j: float(t[i]) if i < len(t) else wu.end_s
                            for j, i in zip(joints, wu.index, strict=True)},
        filter_gain={"frequencies_hz": [float(f) for f in freqs],
                     "gain": {j: [float(g) for g in gain[k]] for k, j in enumerate(joints)}},
        residual_generator=summary_name(rp.choices), read_options=read_options,
        generators=choices_dict(rp.choices, cfg.residual.logged_correction),
        joints_left_out=tuple(x.to_dict() for x in rp.left_out),
    )


def detector_ratios(r_rms: np.ndarray, threshold_adaptive: np.ndarray, loading: np.ndarray,
                    baseline: np.ndarray, v_loading: np.ndarray | float,
                    v_baseline: np.ndarray | float) -> dict[str, np.ndarray]:
    """Each detector's statistic over its threshold (an event's peak ratio; the sweep's
    decision at scale s is ``ratio > s``): adaptive r_rms / |v_stat + v_rms| (eq. 42; inf
    where that threshold is 0), static_loading |LP(r)| / vL, static_baseline |r| / v0.

    Args:
        r_rms, threshold_adaptive, loading, baseline: (n, J) residual RMS, adaptive
            threshold, loading statistic and |r| [N·m] (or a joint's (n,) columns).
        v_loading, v_baseline: vL and v0 [N·m], broadcast against them ((1, J), or a
            joint's scalars).
    Returns:
        detector → ratio, shaped as the statistics.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return {"adaptive": np.where(threshold_adaptive > 0, r_rms / threshold_adaptive, np.inf),
                "static_loading": loading / v_loading,
                "static_baseline": baseline / v_baseline}


def compare_to_thresholds(
    thr: dict[str, np.ndarray], r_rms: np.ndarray, v_rms: np.ndarray, loading: np.ndarray,
    baseline: np.ndarray,
) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The thresholds applied to a replay's statistics (the whole log, or a chunk of it).

    Args:
        thr: detector → (J,) threshold (v_stat, vL, v0) [N·m].
        r_rms, v_rms: (n, J) the adaptive evaluator's residual RMS and its dynamic part of
            the threshold; loading: (n, J) |LP(r)|; baseline: (n, J) |r| [N·m].
    Returns:
        ((n, J) adaptive threshold |v_stat + v_rms|, detector → (n, J) ratio
        (:func:`detector_ratios`), detector → (n, J) decision: statistic above threshold).
    """
    thr_ad = np.abs(thr["adaptive"][None, :] + v_rms)
    v_l, v_0 = thr["static_loading"][None, :], thr["static_baseline"][None, :]
    ratios = detector_ratios(r_rms, thr_ad, loading, baseline, v_l, v_0)
    decisions = {"adaptive": np.greater(r_rms, thr_ad), "static_loading": np.greater(loading, v_l),
                 "static_baseline": np.greater(baseline, v_0)}
    return thr_ad, ratios, decisions


def _warn_long_events(log: RobotLog, events: list[Any]) -> None:
    """Warn about product events after warm-up lasting LONG_EVENT_S or more."""
    long_ev = [e for e in events if not e.in_warmup and e.detector != "static_baseline"
               and e.t_end - e.t_start >= LONG_EVENT_S]
    if long_ev:
        e = max(long_ev, key=lambda x: x.t_end - x.t_start)
        warnings.warn(
            f"{log.source.path}: {len(long_ev)} alarm(s) last {LONG_EVENT_S:g} s or more (the "
            f"longest: {e.detector} {e.t_start:.1f}–{e.t_end:.1f} s): a lasting load, or a "
            "model that no longer fits this log (an unknown payload, a changed robot)",
            ImpactWarning, stacklevel=3)


#: Events starting this long after a time gap are named in a warning [s].
GAP_SETTLE_S = 0.5


def _warn_events_after_gaps(log: RobotLog, gaps: np.ndarray, events: list[Any]) -> None:
    """Warn naming the events that start within GAP_SETTLE_S after a time gap (``gaps``:
    indices i of the steps t[i] → t[i+1] that are gaps, from :func:`replay`)."""
    if gaps.size:
        warn_events_after_gaps(log.source.path, log.time_s[gaps + 1], events)


def warn_uncalibrated(where: str) -> None:
    """The warning of a run whose thresholds come from the log itself."""
    warnings.warn(
        f"{where}: uncalibrated run — thresholds set from this log's own "
        f"statistics ({UNCALIBRATED_MARGIN:g} × the {UNCALIBRATED_QUANTILE:g}-quantile of "
        f"its {UNCALIBRATED_BLOCK_S:g} s maxima after warm-up): only contacts that stand "
        "out well above its motion are found; calibrate on collision-free logs "
        "(impactcli calibrate) for sensitivity and a replay the robot could have run",
        ImpactWarning, stacklevel=3,
    )


def warn_gaps(where: str, lengths_s: np.ndarray, starts_s: np.ndarray) -> None:
    """The time-gap warning: (G,) gap lengths [s] and the times of the samples before them."""
    if not len(lengths_s):
        return
    k = int(np.argmax(lengths_s))
    warnings.warn(
        f"{where}: {len(lengths_s)} time gap(s) longer than {GAP_FACTOR:g} sample "
        f"periods (longest {lengths_s[k] * 1e3:.4g} ms after {starts_s[k]:.3f} s, "
        f"first after {starts_s[0]:.3f} s): the detectors assume uniform sampling, "
        "so alarms just after a gap may be artefacts of it", ImpactWarning, stacklevel=3)


def warn_warmup(where: str, wu: Any, times_s: Sequence[float], joints: tuple[str, ...],
                n_samples: int, duration_s: float, cfg: DetectorConfig) -> None:
    """The warm-up warnings: it covers the whole log, or it reached its cap on some joints
    (``times_s``: each joint's warm-up end [s])."""
    if wu.end_index >= n_samples - 10:
        warnings.warn(f"{where}: the warm-up covers the whole log "
                      f"({duration_s:.1f} s)", ImpactWarning, stacklevel=3)
        return
    capped = [j for j, i, ts in zip(joints, wu.index, times_s, strict=True)
              if i < n_samples and ts >= cfg.warmup.max_s - 1e-9]
    if capped:
        warnings.warn(
            f"{where}: the warm-up reached its cap (warmup.max_s = "
            f"{cfg.warmup.max_s:g} s) on joint(s) {', '.join(capped)}: the adaptive "
            "filter's prediction error had not settled; alarms soon after it may be "
            "artefacts", ImpactWarning, stacklevel=3)


def warn_events_after_gaps(where: str, after_s: np.ndarray, events: list[Any]) -> None:
    """Warn naming the events that start within GAP_SETTLE_S after a time gap (``after_s``:
    the times of the samples just after the gaps [s])."""
    if not len(after_s) or not events:
        return
    near = [e for e in events
            if np.any((e.t_start >= after_s - 1e-9) & (e.t_start <= after_s + GAP_SETTLE_S))]
    if near:
        listed = ", ".join(f"{e.detector} at {e.t_start:.3f} s" for e in near[:5])
        more = f" and {len(near) - 5} more" if len(near) > 5 else ""
        warnings.warn(f"{where}: {len(near)} event(s) start within "
                      f"{GAP_SETTLE_S:g} s after a time gap ({listed}{more}): check them",
                      ImpactWarning, stacklevel=3)
