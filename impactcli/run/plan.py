"""What a replay decides before its first sample, from the log's scan and the setup.

The joints detection can use (the screen of the log's columns, what the model or the
calibrated config covers, what a calibration left out), each joint's residual generator,
the rigid model (given, embedded in the config, or identified from the log in one more
pass over its chunks: :class:`~impactcli.model.identification.IdentifyStream`) and the joint order
(the model's, or the calibrated config's). Every decision left out of detection is warned
about once. Nothing here replays a sample.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..clock import check_calibrated_rate
from ..config import (
    PLAIN_FORMULATION,
    THRESHOLD_KEYS,
    DetectorConfig,
    settings_changed,
    thresholds_edited,
)
from ..detect.adaptive import check_scale
from ..errors import ConfigError, ImpactError, ImpactWarning, LogFormatError, ModelError
from ..logs.reader import LogChunk, LogReader, LogScan
from ..logs.screen import LeftOut
from ..model.generators import (
    GeneratorChoice,
    choose_generators,
    needs_own_model,
    target_torque,
    uses_correction,
)
from ..model.gravity import ScaleVerdict
from ..model.identification import check_shares_joints
from ..model.rigid import RigidModel
from ..sample_channels import CONTROLLER_CHANNELS
from ..types import LogSource, RobotDescription, RobotLog
from .replay import ChunkArrays, chunk_arrays
from .run_warnings import warn_formulation, warn_settings, warn_torque_source

if TYPE_CHECKING:
    from .loads import StartLoad


def known_joints(model: RigidModel | None, cfg: DetectorConfig) -> tuple[str, ...] | None:
    """The joints detection can run on by what was given: the model's (``--model``), else
    the config's model's, else a calibrated config's thresholds'; None: any."""
    if model is not None:
        return tuple(model.joint_names)
    if cfg.model is not None:
        return tuple(cfg.model["joint_names"])
    if cfg.calibration.calibrated and cfg.thresholds.v_stat:
        return tuple(cfg.thresholds.v_stat)
    return None


def screen_plan(
    where: str, joint_names: tuple[str, ...], known: tuple[str, ...] | None,
    recorded: tuple[dict[str, str], ...], torque_why: list[str | None],
    channel_why: Callable[[str, list[int]], list[str | None] | None],
) -> tuple[tuple[str, ...], tuple[LeftOut, ...], dict[str, list[int]]]:
    """The joints detection cannot use and the controller channels read as not logged,
    from the screen of the log's columns (:mod:`impactcli.logs.screen`), each warned
    about once.

    Args:
        where: the log's path. joint_names: as logged.
        known: the joints the model or the calibrated config covers (None: any). A logged
            joint outside them is left out (a joint they need that the log lacks stays an
            error, raised later).
        recorded: joints a calibration left out (``calibration.joints_left_out``).
        torque_why: per logged joint, why its torque is not usable (None: usable).
        channel_why: (controller channel, kept columns) → why each of those columns is not
            usable, or None when the log has no such channel.
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


@dataclass(frozen=True)
class Screened:
    """A log's columns screened (:func:`screen_scan`).

    Attributes:
        keep: the joints kept, in the log's order.
        left_out: the joints left out, with why.
        unlogged: controller channel → columns of ``keep`` read as not logged.
        logged: controller channel → (len(keep),) whether each kept joint carries it.
    """

    keep: tuple[str, ...]
    left_out: tuple[LeftOut, ...]
    unlogged: dict[str, list[int]]
    logged: dict[str, np.ndarray]


def screen_scan(scan: LogScan, known: tuple[str, ...] | None,
                recorded: tuple[dict[str, str], ...] = (),
                joints: tuple[str, ...] | None = None,
                measured: frozenset[str] = frozenset()) -> Screened:
    """:func:`screen_plan` of a log's scan (``joints``: only these of its joints, as if the
    log held no others; None: all; ``measured``: joints whose torque is taken as measured
    whatever its screen says here — calibration: measured in another of its logs)."""
    full = tuple(scan.joint_names)
    joints = full if joints is None else joints
    cols = [full.index(j) for j in joints]
    torque = scan.screens["torque"].select(cols)
    ref = float(np.max(torque.ptp)) if torque.ptp.size else 0.0
    torque_why = [None if j in measured else why for j, why in zip(
        joints, torque.unusable(ref, None if scan.torque_posed is None
                                else scan.torque_posed[cols]), strict=True)]
    keep, left, unlogged = screen_plan(
        scan.source.path, joints, known, recorded, torque_why,
        lambda ch, kept: scan.screens[ch].select([cols[k] for k in kept]).unusable(ref)
        if ch in scan.screens else None)
    logged = {ch: scan.screens[ch].select([full.index(j) for j in keep]).logged
              for ch in CONTROLLER_CHANNELS if ch in scan.screens}
    for ch, ks in unlogged.items():
        logged[ch] = logged[ch].copy()
        logged[ch][ks] = False
    return Screened(keep, left, unlogged, logged)


def generator_choices(joints: tuple[str, ...], logged: dict[str, np.ndarray],
                      source: LogSource, cfg: DetectorConfig) -> tuple[GeneratorChoice, ...]:
    """Each joint's residual generator under ``cfg`` (frozen choices win), by the controller
    channels each joint carries (``logged``: channel → (J,) bool)."""
    return choose_generators(_channels_log(joints, logged, source), cfg.residual.generator,
                             cfg.residual.generators or None)


def _channels_log(joints: tuple[str, ...], logged: dict[str, np.ndarray],
                  source: LogSource) -> RobotLog:
    """A two-sample log that carries each controller channel where ``logged`` says: what
    :func:`~impactcli.model.generators.choose_generators` reads of a log."""
    zeros = np.zeros((2, len(joints)))
    return RobotLog(
        t_ns=np.arange(2, dtype=np.int64), joint_names=joints, position=zeros, torque=zeros,
        source=source, **{ch: np.where(flags[None, :], 0.0, np.nan) * np.ones((2, 1))
                          for ch, flags in logged.items()})


def needs_model(choices: tuple[GeneratorChoice, ...], cfg: DetectorConfig) -> bool:
    """Whether a rigid model is needed: some joint uses the tool's own model, or a logged
    channel is corrected by one (``residual.logged_correction``)."""
    return needs_own_model(choices) or uses_correction(choices, cfg.residual.logged_correction)


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


def calibrated_thresholds(
    cfg: DetectorConfig, joints: tuple[str, ...],
) -> dict[str, np.ndarray] | None:
    """Per-detector (J,) threshold vectors from a calibrated config, in ``joints`` order;
    None if not calibrated."""
    th = cfg.thresholds
    if not cfg.calibration.calibrated:
        return None
    out = {}
    for det in THRESHOLD_KEYS:
        table = th.of(det)
        missing = [j for j in joints if j not in table]
        if missing:
            raise ConfigError(f"calibrated config has no {det} threshold for joint(s) {missing}")
        out[det] = np.array([table[j] for j in joints], dtype=np.float64)
    return out


def check_replayable(where: str, n_joints: int, sample_rate_hz: float, n_samples: int,
                     duration_s: float, cfg: DetectorConfig, allow_slow: bool,
                     identify_kind: str | None = None) -> None:
    """Before any work: the replay's cost and, when a model of ``identify_kind`` must be
    identified from the log, identification's (both depend on the joints, not the duration;
    refused above the limit unless ``allow_slow``), then a log longer than the warm-up."""
    if not allow_slow:
        check_scale(n_joints, sample_rate_hz, cfg.adaptive, where)
        if identify_kind is not None:
            check_identification(where, identify_kind, n_joints, sample_rate_hz)
    if duration_s < cfg.warmup.min_s:
        raise LogFormatError(
            f"{where}: {n_samples} samples ({duration_s:.3g} s), shorter than "
            f"the detectors' warm-up (warmup.min_s = {cfg.warmup.min_s:g} s): nothing after it "
            "could be detected")


def identified_kind(model: RigidModel | None, cfg: DetectorConfig,
                    robot: RobotDescription | None, model_from_log: bool) -> str | None:
    """The kind of model a run will identify from its log (None: it is given)."""
    from ..model import default_kind

    if model is not None or (cfg.model is not None and not model_from_log):
        return None
    if model_from_log and cfg.model is not None:
        return str(cfg.model.get("kind") or default_kind(robot))
    return default_kind(robot)


def check_identification(where: str, kind: str, n_joints: int, sample_rate_hz: float
                         ) -> None:
    """ScaleLimitError (exit 2) when identifying a ``kind`` model from the log is estimated
    slower than real time (:func:`impactcli.model.identification.identification_cost`); its
    memory is bounded by the row caps and, for a coupled model, refused where it cannot be
    held (:func:`impactcli.model.identification.check_coupled_size`)."""
    from ..detect.adaptive import MAX_COST_PER_LOG_SECOND
    from ..errors import ScaleLimitError
    from ..model.identification import identification_cost

    cost = identification_cost(kind, n_joints, sample_rate_hz)
    if cost > MAX_COST_PER_LOG_SECOND:
        raise ScaleLimitError(
            f"{where}: {n_joints} joints at {sample_rate_hz:.4g} Hz: identifying a {kind} model "
            f"from the log is estimated at {cost:.3g} s of compute per second of log, above "
            f"the limit of {MAX_COST_PER_LOG_SECOND:g} s: give a model (--model, or a config "
            "with one), or --allow-slow to run it anyway")


def from_log_structure(cfg: DetectorConfig, robot: RobotDescription | None,
                       ) -> tuple[str | None, RobotDescription | None]:
    """``--model-from-log``: the kind and robot of the config's model, to identify the same
    structure from the log (warned about when the config's thresholds were calibrated:
    they belong to the config's model)."""
    kind = None
    if cfg.model is not None:
        kind = cfg.model.get("kind")
        if robot is None and cfg.model.get("robot"):
            from ..logs.robot_files import robot_from_dict

            robot = robot_from_dict(cfg.model["robot"], "the config's model")
    if cfg.calibration.calibrated:
        warnings.warn(
            "--model-from-log: the config's thresholds were calibrated with another model; "
            "this run is offline only (not what the robot could have run)",
            ImpactWarning, stacklevel=4,
        )
    return kind, robot


class Passes:
    """Progress over the passes that read the log (identification, replay, comparison):
    seconds of log done, summed over the passes, against the passes' total."""

    def __init__(self, duration_s: float,
                 progress: Callable[[float, float], None] | None = None) -> None:
        self.duration_s, self.progress = duration_s, progress
        self.planned = 1
        self.done = 0

    def add(self, k: int = 1) -> None:
        """``k`` more passes than the one replay planned at first."""
        self.planned += k

    def at(self, t_s: float) -> None:
        """The current pass is at ``t_s`` seconds of log."""
        if self.progress is not None:
            self.progress(self.done * self.duration_s + t_s, self.planned * self.duration_s)

    def next(self) -> None:
        """The current pass is over."""
        self.done += 1


class ChunkFeed:
    """A log's chunks as a replay reads them: times [s since the first sample], and the
    arrays of given joints in a given order, the flat controller channels read as not
    logged (``unlogged``: channel → columns of ``keep``); each call reads the log again.

    Args:
        reader: the log. chunk_rows: samples per chunk.
        keep: the joints kept by the screen, in the log's order.
    """

    def __init__(self, reader: LogReader, chunk_rows: int, keep: tuple[str, ...],
                 unlogged: dict[str, list[int]]) -> None:
        self.reader, self.scan = reader, reader.scan()
        self.chunk_rows, self.keep, self.unlogged = chunk_rows, keep, unlogged
        self.full_joints = tuple(self.scan.joint_names)

    def chunks(self, joints: tuple[str, ...]
               ) -> Iterator[tuple[LogChunk, np.ndarray, ChunkArrays]]:
        """(chunk, (n,) times [s], :class:`~impactcli.run.replay.ChunkArrays` of ``joints``)."""
        cols = [self.full_joints.index(j) for j in joints]
        nan_cols = {ch: [joints.index(self.keep[k]) for k in ks if self.keep[k] in joints]
                    for ch, ks in self.unlogged.items()}
        t0 = self.scan.t0_ns
        for ch in self.reader.chunks(self.chunk_rows):
            t = (np.asarray(ch.t_ns) - t0).astype(np.float64) * 1e-9
            yield ch, t, _chunk_arrays(ch, t, cols, nan_cols)


def _chunk_arrays(ch: LogChunk, t: np.ndarray, cols: list[int],
                  nan_cols: dict[str, list[int]]) -> ChunkArrays:
    """A chunk's arrays in the replay's joint order, flat controller channels unlogged."""
    a = chunk_arrays(ch, t, cols)
    changes = {}
    for name, ks in nan_cols.items():
        m = getattr(a, name)
        if m is not None and ks:
            m = np.array(m)
            m[:, ks] = np.nan
            changes[name] = m
    return dataclasses.replace(a, **changes) if changes else a


def identify_from_chunks(feed: ChunkFeed, cfg: DetectorConfig,
                         choices: tuple[GeneratorChoice, ...], kind: str | None,
                         robot: RobotDescription | None, sanity: bool,
                         passes: Passes | None = None) -> RigidModel:
    """The rigid model identified from the log, read once more
    (:class:`~impactcli.model.identification.IdentifyStream`: bounded memory, the model
    :func:`impactcli.model.identification` makes of the whole log). The tool's own model
    (``sanity``: not a correction of the controller's channels) of a kind nobody named —
    no ``kind``, no kinematics in ``robot`` — is the kind that predicts contiguous
    stretches of the log best held back (:class:`~impactcli.model.selection.SelectStream`,
    docs/models.md, "Choosing the model"); a correction keeps the decoupled model."""
    from ..model import IdentifyOptions, default_kind
    from ..model.identification import IdentifyStream
    from ..model.selection import SelectStream

    scan = feed.scan
    options = IdentifyOptions(allow_still_joints=True, check_sanity=sanity)
    ident: IdentifyStream | SelectStream
    if kind is None and sanity and default_kind(robot) == "decoupled":
        ident = SelectStream.start(
            feed.keep, scan.n_samples, scan.sample_rate_hz, scan.duration_s, robot=robot,
            options=options, where=scan.source.path, input_sha256=scan.source.sha256)
    else:
        ident = IdentifyStream.start(
            feed.keep, scan.n_samples, scan.sample_rate_hz, scan.duration_s, robot=robot,
            kind=kind, options=options, where=scan.source.path,
            input_sha256=scan.source.sha256)
    if passes is not None:
        passes.add()
    for _, t, a in feed.chunks(feed.keep):
        ident.feed(t, a.position, target_torque(a, choices, cfg.residual.logged_correction))
        if passes is not None:
            passes.at(float(t[-1]))
    if passes is not None:
        passes.next()
    return ident.finish()


#: identify(choices, kind, robot, sanity) -> the model identified from the log.
Identify = Callable[[tuple[GeneratorChoice, ...], str | None, RobotDescription | None, bool],
                    RigidModel]


def resolve_model(
    keep: tuple[str, ...], source: LogSource, logged: dict[str, np.ndarray],
    model: RigidModel | None, cfg: DetectorConfig, model_from_log: bool,
    robot: RobotDescription | None, identify: Identify, left_out: tuple[LeftOut, ...] = (),
) -> tuple[tuple[str, ...], tuple[GeneratorChoice, ...], RigidModel | None, str,
           tuple[LeftOut, ...]]:
    """The replayed joints and their order, their generators, the model and where it came
    from (``given``, ``config``, ``identified-from-log`` or ``none``), and the kept joints
    the model lacks (left out, warned about).

    ``model_from_log`` identifies the model from this log even when the config embeds one,
    with the config model's structure (kind and robot description), keeping the config's
    thresholds: offline only, for a robot whose dynamics changed since calibration (an
    unknown payload) — the identification absorbs the change for the static detectors.
    Without a model needed, the joints keep the log's order, or the calibrated config's.
    ``left_out``: the joints the screen left out, with why (named when the model needs one).
    """
    where = source.path
    check_shares_joints(keep, robot, where)  # with a config as without one
    choices = generator_choices(keep, logged, source, cfg)
    extra_left: tuple[LeftOut, ...] = ()
    rig: RigidModel | None = None
    source_name = "none"
    joints = keep
    correct = cfg.residual.logged_correction
    if needs_model(choices, cfg):
        sanity = not uses_correction(choices, correct)
        if model_from_log:
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
            for j in extra:  # e.g. a logged joint the URDF does not have
                warnings.warn(f"{where}: joint {j!r} left out of detection: not in the model",
                              ImpactWarning, stacklevel=3)
            extra_left = tuple(LeftOut(j, "not in the model") for j in extra)
        present = tuple(j for j in keep if j not in {x.name for x in extra_left})
        missing = [j for j in rig.joint_names if j not in present]
        other = [j for j in present if j not in rig.joint_names]
        why = {x.name: x.reason for x in left_out}
        if missing and all(j in why for j in missing) and not other:
            raise ModelError(
                f"{where}: " + "; ".join(f"joint {j!r} was left out ({why[j]})"
                                         for j in missing)
                + f", but the {source_name} model's residual needs every joint it was "
                f"identified with ({list(rig.joint_names)}), so with it no joint can be "
                "checked: mend the channel, or detect without the model (no --config or "
                "--model: the log's own model on the joints left)")
        if missing or other:
            raise ModelError(
                f"{where}: joints {list(present)} do not match the model's "
                f"{list(rig.joint_names)}" + (f" (missing {missing})" if missing else "")
                + (f" (not in the model: {other})" if other else ""))
        joints = tuple(rig.joint_names)
    else:
        order = tuple(cfg.residual.generators)
        if set(order) == set(keep):  # a calibrated config's joint order
            joints = order
    idx = [keep.index(j) for j in joints]
    choices = generator_choices(joints, {ch: v[idx] for ch, v in logged.items()}, source, cfg)
    return joints, choices, rig, source_name, extra_left


@dataclass(frozen=True)
class RunPlan:
    """What a replay fixed before its first sample.

    Attributes:
        cfg: the detector config (``--generator`` applied).
        where: the log's path, for messages.
        full_joints: the log's joints as read.
        joints: the J joints replayed, in the replay's order (the model's or the config's).
        choices: their residual generators.
        model: the rigid model (None when no joint needs one); model_source: where it came
            from (:func:`resolve_model`).
        left_out: the logged joints left out of detection, with why (by the reader, the
            screen, the model).
        torque_scale: the log's torque scale against the description's gravity
            (:func:`check_torque_scale`); gravity_hold: (J,) per replayed joint the largest
            gravity torque the description says it holds over the log's poses [N·m] (NaN
            where not known; None without masses).
        start_load: the load the log starts with, weighed on its first seconds
            (:mod:`impactcli.run.loads`; None: not weighed); ``model`` carries it
            when its verdict is ``used``.
    """

    cfg: DetectorConfig
    where: str
    full_joints: tuple[str, ...]
    joints: tuple[str, ...]
    choices: tuple[GeneratorChoice, ...]
    model: RigidModel | None
    model_source: str
    left_out: tuple[LeftOut, ...]
    torque_scale: ScaleVerdict | None = None
    gravity_hold: np.ndarray | None = None
    start_load: StartLoad | None = None


def plan_run(reader: LogReader, cfg: DetectorConfig, *, model: RigidModel | None,
             robot: RobotDescription | None, model_from_log: bool, allow_slow: bool,
             config_where: str, chunk_rows: int,
             passes: Passes | None = None) -> tuple[RunPlan, ChunkFeed]:
    """The replay's plan for a log (module docstring), and its chunks as the replay reads
    them. Raises before any sample is replayed: a config calibrated at another rate, no
    joint left, a replay too costly (unless ``allow_slow``), a log shorter than the warm-up,
    joints that do not match the model."""
    scan = reader.scan()
    where = scan.source.path
    check_calibrated_rate(scan.sample_rate_hz, cfg.calibration.sample_rate_hz, where,
                          f"its config ({config_where})")
    calibrated_on = cfg.calibration.formulation or PLAIN_FORMULATION
    if cfg.calibration.calibrated and calibrated_on != cfg.adaptive.formulation:
        warn_formulation(where, config_where, calibrated_on, cfg.adaptive.formulation)
    if settings_changed(cfg):
        warn_settings(where, config_where, thresholds_edited(cfg))
    _check_degrees(scan, cfg, where)
    sc = screen_scan(scan, known_joints(model, cfg), cfg.calibration.joints_left_out)
    described = robot or description_of(model, cfg)
    scale, hold = check_torque_scale(scan, described, sc.keep, warn=False)  # warned below
    check_replayable(where, len(sc.keep), scan.sample_rate_hz, scan.n_samples,
                     scan.duration_s, cfg, allow_slow, identified_kind(model, cfg, robot,
                                                                       model_from_log))
    feed = ChunkFeed(reader, chunk_rows, sc.keep, sc.unlogged)

    def identify(choices: tuple[GeneratorChoice, ...], kind: str | None,
                 rbt: RobotDescription | None, sanity: bool) -> RigidModel:
        return identify_from_chunks(feed, cfg, choices, kind, rbt, sanity, passes)

    joints, choices, rig, model_source, extra = resolve_model(
        sc.keep, scan.source, sc.logged, model, cfg, model_from_log, robot, identify,
        sc.left_out)
    _check_torque_source(cfg, scan.source.torque_source, choices, where, config_where)
    start = None
    if rig is not None and model_source in ("config", "given"):  # fitted on other logs
        from .loads import weigh_start

        rig, start = weigh_start(feed, rig, choices, cfg)
        if start is not None and start.verdict != "same":
            warnings.warn(start.message, ImpactWarning, stacklevel=2)
    if scale is not None and (scale.kind == "warn" or scale.order_only):  # a load's?
        scale = _unloaded_scale(scan, described, sc.keep, scale, rig, start)
        if scale.kind == "warn":
            warnings.warn(scale.message, ImpactWarning, stacklevel=2)
    if scale is not None and scale.order_only:  # not a unit error, not an agreement
        warnings.warn(scale.message, ImpactWarning, stacklevel=2)
    left_out = (tuple(LeftOut(j, why) for j, why in scan.source.joints_dropped)
                + sc.left_out + extra)
    held = None if hold is None else np.array(
        [hold.get(j, np.nan) for j in joints], dtype=np.float64)
    return RunPlan(cfg, where, feed.full_joints, joints, choices, rig, model_source,
                   left_out, scale, held, start), feed


def _check_degrees(scan: LogScan, cfg: DetectorConfig, where: str) -> None:
    """Warn when positions given as degrees travel as the calibration's radians did
    (:func:`impactcli.logs.plausibility.degrees_against_calibration`)."""
    env = cfg.calibration.motion_envelope
    pos = scan.ranges.get("position")
    if scan.options.get("position_unit") != "deg" or not env or pos is None:
        return
    from ..logs.plausibility import degrees_against_calibration

    ranges = {j: q["position"] for j, q in (env.get("joints") or {}).items()
              if "position" in q}
    said = degrees_against_calibration(where, scan.log.joint_names, pos[1] - pos[0], ranges)
    if said is not None:
        warnings.warn(said, ImpactWarning, stacklevel=3)


def _check_torque_source(cfg: DetectorConfig, used: str, choices: tuple[GeneratorChoice, ...],
                         where: str, config_where: str) -> None:
    """Warn when the log's torque comes from another channel than every calibration log's
    did (:attr:`impactcli.config.LogRecord.torque_source`) and a replayed joint's residual
    reads it (all but ``logged_external``)."""
    recorded = {lg.torque_source for lg in cfg.calibration.logs}
    calibrated_on = recorded.pop() if len(recorded) == 1 else None
    if (not cfg.calibration.calibrated or calibrated_on is None or calibrated_on == used
            or all(c.generator == "logged_external" for c in choices)):
        return
    warn_torque_source(where, config_where, used, calibrated_on, len(cfg.calibration.logs))


def _unloaded_scale(scan: LogScan, robot: RobotDescription | None, kept: tuple[str, ...],
                    scale: ScaleVerdict, rig: RigidModel | None, start: Any,
                    ) -> ScaleVerdict:
    """A torque scale off the description's gravity torque (or of its order only), judged
    again with the load the log starts with taken off the log's torque, when that load was
    weighed and used (a trial's +1.47 kg start read "~2.3×, of the order only"): the
    description holds the arm, not its load. The verdict then, if it is no longer off
    (its message saying so) and the load is one the calibration logs carried (their
    range, or one of theirs); ``scale`` still off, saying both explanations, when the
    load is beyond theirs (a wrong unit weighs as a load too); else ``scale`` as it was."""
    from ..model import payload
    from .loads import beyond_calibrated, start_pi

    if rig is None or start is None or start.verdict != "used" or scan.poses is None:
        return scale
    bb = payload.basis(rig.kind, rig.joint_names, rig.structure)
    joints = scan.log.joint_names
    if bb is None or not set(rig.joint_names) <= set(joints):
        return scale
    cols = [joints.index(j) for j in rig.joint_names]
    q = np.asarray(scan.poses.q, dtype=np.float64)[:, cols]
    zero = np.zeros_like(q)
    less = np.zeros_like(np.asarray(scan.poses.tau, dtype=np.float64))
    less[:, cols] = rig.regressor(q, zero, zero) @ bb[0] @ start_pi(rig, bb[1], start)
    try:
        again, _ = check_torque_scale(scan, robot, kept, warn=False, less=less)
    except LogFormatError:  # a unit's factor only once the load is off: not the log's own
        return scale        # scale (a trial's 2 kg start: 1.7× as logged, 0.036× without)
    if again is None or again.kind != "ok" or (again.order_only and scale.kind == "ok"):
        return scale  # no nearer without the load (of one order only, both)
    if start.as_log is None and beyond_calibrated(start.calibrated, float(start.mass_kg),
                                                  float(start.mass_se_kg)):
        # a load no calibration log carried may be a unit error weighed as a load (a ×4
        # torque weighs as +6 kg): both are said, neither is taken
        return dataclasses.replace(scale, message=(
            f"{scale.message}; or the log starts with a load no calibration log carried "
            f"({start.mass_kg:+.3g} kg, weighed): without it the scale reads "
            f"~{again.scale:.3g}× — a wrong unit or that load, which the tool cannot tell "
            "apart"))
    return dataclasses.replace(again, message=(
        f"{again.message}; judged without the load the log starts with "
        f"({start.mass_kg:+.3g} kg, weighed), which the description's masses do not hold: "
        f"with it the scale read ~{scale.scale:.3g}×"))


def description_of(model: RigidModel | None, cfg: DetectorConfig) -> RobotDescription | None:
    """The robot description a model (``--model``, else the config's) was made with."""
    from ..logs.robot_files import robot_from_dict

    d = model.robot if model is not None else (cfg.model or {}).get("robot")
    if not isinstance(d, dict):
        return None
    try:
        return robot_from_dict(d)
    except ImpactError:
        return None


def check_torque_scale(scan: LogScan, robot: RobotDescription | None,
                       kept: tuple[str, ...] | None = None, *, warn: bool = True,
                       less: np.ndarray | None = None,
                       ) -> tuple[ScaleVerdict | None, dict[str, float] | None]:
    """The log's torque scale against the description's gravity torque over the scan's
    poses (:mod:`impactcli.model.gravity`): raises LogFormatError (exit 3) when it is off by
    a clean unit factor, warns (when ``warn``) when it is off otherwise. Returns the verdict
    (None without a description) and per joint the largest |gravity torque| over the poses
    [N·m] (None without masses). Only the joints ``kept`` by the screen are judged (None:
    all): a flat or unmeasured torque says nothing of the scale. ``less``: (n, J) a torque
    taken off the log's at the poses first (a weighed load's, :func:`_unloaded_scale`)."""
    from ..model.gravity import nominal_gravity, scale_check

    poses, where = scan.poses, scan.source.path
    if robot is None or poses is None or not len(poses.idx):
        return None, None
    joints = scan.log.joint_names
    g = nominal_gravity(robot, joints, poses.q)
    if g is None:
        return ScaleVerdict("unverified", message=(
            f"{where}: the torque scale is not verified: no gravity torque from the robot "
            "description to compare the log's torque with (it gives no masses — robot JSON "
            "nominal.link_masses, a URDF's inertials — or a chain joint is not logged, or "
            "its URDF could not be loaded: the urdf extra)")), None
    ratios = {j.name: j.gear_ratio for j in robot.joints}
    cols = [k for k, j in enumerate(joints) if kept is None or j in kept]
    judged = tuple(joints[k] for k in cols)
    tau = poses.tau if less is None else poses.tau - less
    verdict = scale_check(where, judged, g[:, cols], tau[:, cols],
                          np.abs(poses.qd[:, cols]), [ratios.get(j, 1.0) for j in judged])
    if verdict.kind == "refuse":
        raise LogFormatError(verdict.message)
    if verdict.kind == "warn" and warn:
        warnings.warn(verdict.message, ImpactWarning, stacklevel=3)
    peak = (np.where(np.isfinite(g), np.abs(g), -np.inf).max(axis=0) if len(g)
            else np.full(len(joints), -np.inf))  # -inf: a joint the description lacks
    return verdict, {j: float(v) for j, v in zip(joints, peak, strict=True)
                     if np.isfinite(v)}

