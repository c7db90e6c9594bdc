"""Frozen data types passed between layers (io → model → detect → run → outputs).

Arrays are float64 with their shape and unit stated here; time is int64 ns on the
log's own clock. Validation happens on construction, so every later layer can
trust what it is given.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from .clock import SampleClock, sample_clock
from .errors import LabelsError, LogFormatError, RobotDescriptionError
from .sample_channels import CONTROLLER_CHANNELS, OPTIONAL_CHANNELS, REQUIRED_CHANNELS, Channels

#: Gravity [m/s²]: a robot description's when it gives none, the simulator's arms', and a
#: load's weight per kilogram wherever a mass is turned into a force (|m| g) or back.
GRAVITY_M_S2 = 9.81

TorqueSource = Literal["torque", "current"]
TimeSource = Literal["column", "log", "publish", "header"]


@dataclass(frozen=True)
class LogSource:
    """Provenance of a log: where it came from and how it was read.

    Attributes:
        path: the file path (or URL) as given by the user.
        sha256: hex sha256 of the file's bytes.
        format: reader used: ``csv``, ``csv-mapped``, ``npz``, ``mcap-json``, ``mcap-ros2``
            (or ``memory`` for logs made in code, e.g. by the simulator).
        torque_source: ``torque`` (logged torque/effort) or ``current`` (current × gear
            ratio × torque constant).
        time_source: ``column`` (CSV/NPZ time column), or MCAP ``log``/``publish``/``header``.
        ignored_channels: channels present in the file but not used.
        repairs: human-readable repairs applied while reading (also warned about).
        notes: what could not be made of the file when it was read for description only
            (``inspect``: a current not converted to torque).
        joints_dropped: ``(name, reason)`` of the logged joints the reader left out of the
            log (a position or torque column without a finite value), each warned about;
            the pipeline records them with the joints it leaves out of detection.
        truncated: the file ends before its recording did (an MCAP whose records stop
            early): the log is what came before the cut (also a repair, warned about).
    """

    path: str
    sha256: str
    format: str
    torque_source: TorqueSource = "torque"
    time_source: TimeSource = "column"
    ignored_channels: tuple[str, ...] = ()
    repairs: tuple[str, ...] = ()
    joints_dropped: tuple[tuple[str, str], ...] = ()
    notes: tuple[str, ...] = ()
    truncated: bool = False


@dataclass(frozen=True)
class ReadOptions:
    """How to read a log, as the command line gives it (docs/formats.md): the one typed
    record the CLI hands to the readers (``--robot`` is given apart, as the description
    itself). None (or False) where not given.

    Attributes:
        channel_map: a channel map's path or shipped name (foreign CSV, ``.npz``, messages).
        topic, reference_topic: a message log's state and reference topics.
        time_source: which clock stamps a message log's samples (log, publish, header).
        torque_source: ``torque`` or ``current`` (× gear ratio × torque constant).
        time_unit, time_column: a CSV's or ``.npz``'s time column and its unit.
        rate: [Hz] sample i at i / rate (excludes ``time_unit`` and ``time_column``).
        position_unit: ``rad`` or ``deg``. repair_order: keep the longest increasing run of
            stamps instead of refusing rows out of order.
    """

    channel_map: str | None = None
    topic: str | None = None
    reference_topic: str | None = None
    time_source: str | None = None
    torque_source: str | None = None
    time_unit: str | None = None
    time_column: str | None = None
    rate: float | None = None
    position_unit: str | None = None
    repair_order: bool = False

    def as_dict(self) -> dict[str, Any]:
        """The readers' keyword arguments (and a timeline's ``input.read_options``): the
        options given."""
        return {f.name: v for f in dataclasses.fields(self)
                if (v := getattr(self, f.name)) is not None and v is not False}

    @classmethod
    def of(cls, options: Mapping[str, Any] | None) -> ReadOptions:
        """The options of a mapping of them (:meth:`as_dict`'s, a timeline's
        ``input.read_options``); None values are not given. TypeError on an unknown key."""
        return cls(**{k: v for k, v in (options or {}).items() if v is not None})


def _as_matrix(name: str, a: Any, n: int, j: int, where: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=np.float64)
    if arr.shape != (n, j):
        raise LogFormatError(f"{where}: {name} has shape {arr.shape}, expected ({n}, {j})")
    finite = np.isfinite(arr)
    if name in CONTROLLER_CHANNELS:
        # a column that is entirely NaN means "not logged for this joint"
        finite = finite | np.all(np.isnan(arr), axis=0)[None, :]
    if not np.all(finite):
        bad = np.argwhere(~finite)[0]
        raise LogFormatError(
            f"{where}: {name} is not finite at sample {bad[0]} of joint {bad[1]}"
        )
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class RobotLog(Channels):
    """One robot recording, in memory, validated: N samples of J joints, the per-joint
    channels of :class:`~impactcli.sample_channels.Channels` (n = N) and these.

    Attributes:
        t_ns: (N,) int64, sample times in ns on the log's own clock, strictly increasing.
        joint_names: J joint names (no dots, unique).
        source: provenance (path, sha256, format, torque/time source, repairs).
    """

    t_ns: np.ndarray
    joint_names: tuple[str, ...]
    source: LogSource = field(default_factory=lambda: LogSource("<memory>", "", "memory"))

    def __post_init__(self) -> None:
        where = self.source.path
        t = np.ascontiguousarray(self.t_ns)
        if t.ndim != 1:
            raise LogFormatError(f"{where}: time must be one-dimensional, got shape {t.shape}")
        if t.dtype != np.int64:
            if not np.issubdtype(t.dtype, np.integer):
                raise LogFormatError(f"{where}: time must be int64 nanoseconds, got {t.dtype}")
            t = t.astype(np.int64)
        n = t.shape[0]
        if n < 2:
            raise LogFormatError(f"{where}: log holds {n} sample(s); at least 2 are needed")
        dt = np.diff(t)
        if np.any(dt <= 0):
            k = int(np.argmax(dt <= 0)) + 1
            raise LogFormatError(
                f"{where}: time is not strictly increasing at sample {k} "
                f"({t[k - 1]} ns then {t[k]} ns)"
            )
        t.setflags(write=False)
        object.__setattr__(self, "t_ns", t)
        names = tuple(str(s) for s in self.joint_names)
        if not names:
            raise LogFormatError(f"{where}: no joints")
        if len(set(names)) != len(names):
            raise LogFormatError(f"{where}: duplicate joint names {names}")
        for s in names:
            if "." in s or not s:
                raise LogFormatError(f"{where}: invalid joint name {s!r} (empty or with a dot)")
        object.__setattr__(self, "joint_names", names)
        j = len(names)
        for name in REQUIRED_CHANNELS:
            object.__setattr__(self, name, _as_matrix(name, getattr(self, name), n, j, where))
        for name in OPTIONAL_CHANNELS:
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _as_matrix(name, value, n, j, where))
        for name in CONTROLLER_CHANNELS:  # a channel no joint has is no channel
            value = getattr(self, name)
            if value is not None and not self._logged(value).any():
                object.__setattr__(self, name, None)

    @staticmethod
    def _logged(a: np.ndarray) -> np.ndarray:
        return ~np.all(np.isnan(a), axis=0)

    def has_channel(self, signal: str) -> np.ndarray:
        """(J,) bool: which joints carry ``signal`` (``torque_model``, ``torque_ext``, ...)."""
        a = getattr(self, signal)
        if a is None:
            return np.zeros(self.n_joints, dtype=bool)
        return np.asarray(self._logged(a)) if signal in CONTROLLER_CHANNELS else np.ones(
            self.n_joints, dtype=bool)

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.t_ns.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joints J."""
        return len(self.joint_names)

    @property
    def t0_ns(self) -> int:
        """Absolute time of the first sample on the log's own clock [ns]."""
        return int(self.t_ns[0])

    @property
    def time_s(self) -> np.ndarray:
        """(N,) seconds since the first sample (float64)."""
        return (self.t_ns - self.t_ns[0]).astype(np.float64) * 1e-9

    @property
    def duration_s(self) -> float:
        """Duration from first to last sample [s]."""
        return float(self.t_ns[-1] - self.t_ns[0]) * 1e-9

    @functools.cached_property
    def sample_clock(self) -> SampleClock:
        """The log's sample clock: period, jitter, gap threshold (:mod:`impactcli.clock`,
        the one estimator every format and check uses)."""
        return sample_clock(self.t_ns)

    @property
    def sample_period_s(self) -> float:
        """Sample period [s], robust to jitter, dropped samples and late stamps
        (:func:`impactcli.clock.sample_clock`)."""
        return self.sample_clock.period_s

    @property
    def sample_rate_hz(self) -> float:
        """Sample rate 1 / :attr:`sample_period_s` [Hz]."""
        return 1.0 / self.sample_period_s

    @property
    def has_reference(self) -> bool:
        """Whether the controller's reference position was logged."""
        return self.position_ref is not None

    def slice(self, start: int, stop: int) -> RobotLog:
        """Samples ``start:stop`` as a new log with the same provenance."""
        cut: dict[str, Any] = {name: None if a is None else a[start:stop]
                               for name, a in self.channels().items()}
        return RobotLog(t_ns=self.t_ns[start:stop], joint_names=self.joint_names,
                        source=self.source, **cut)

    def select(self, joints: tuple[str, ...]) -> RobotLog:
        """The log with only ``joints``, in that order (each must be in the log)."""
        idx = [self.joint_names.index(j) for j in joints]
        picked: dict[str, Any] = {name: None if a is None else a[:, idx]
                                  for name, a in self.channels().items()}
        return RobotLog(t_ns=self.t_ns, joint_names=joints, source=self.source, **picked)


@dataclass(frozen=True)
class JointSpec:
    """One joint of a robot description.

    Attributes:
        name: joint name as in the logs.
        gear_ratio: reduction ratio (motor turns per joint turn) [-].
        torque_constant: motor torque constant [N·m/A], motor side.
    """

    name: str
    gear_ratio: float = 1.0
    torque_constant: float | None = None


@dataclass(frozen=True)
class RobotDescription:
    """A robot description (docs/formats.md, "Robot description").

    Attributes:
        joints: joint specs in chain order.
        kinematics: ``None`` (no kinematics: decoupled model only), or a mapping with
            ``type`` ``planar`` (``link_lengths`` [m], ``gravity`` [m/s²] 2-vector) or
            ``urdf`` (``path``, or ``robot``: the name of a robot the tool ships,
            :mod:`impactcli.logs.robot_catalogue`).
        nominal: optional nominal dynamic parameters (may be wrong: the model is identified).
        name: a human-readable name.
        path: where it was read from ("" if made in code).
        joint_map: {log joint name: URDF joint name} for the joints whose names differ
            (URDF kinematics only); None: the names are the URDF's.
    """

    joints: tuple[JointSpec, ...]
    kinematics: dict[str, Any] | None = None
    nominal: dict[str, Any] | None = None
    name: str = ""
    path: str = ""
    joint_map: dict[str, str] | None = None

    def __post_init__(self) -> None:
        names = [j.name for j in self.joints]
        if not names:
            raise RobotDescriptionError(f"{self.path or 'robot description'}: no joints")
        if len(set(names)) != len(names):
            raise RobotDescriptionError(f"{self.path or 'robot description'}: duplicate joints")

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in chain order."""
        return tuple(j.name for j in self.joints)

    def torque_scale(self) -> np.ndarray:
        """(J,) current → torque factor gear_ratio × torque_constant [N·m/A].

        Raises RobotDescriptionError naming the first joint without a torque constant.
        """
        out = []
        for j in self.joints:
            if j.torque_constant is None:
                raise RobotDescriptionError(
                    f"{self.path or 'robot description'}: joint {j.name!r} has no "
                    "torque_constant, needed to convert current to torque"
                )
            out.append(j.gear_ratio * j.torque_constant)
        return np.asarray(out, dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping in the robot-description format."""
        d: dict[str, Any] = {
            "name": self.name,
            "joints": [
                {"name": j.name, "gear_ratio": j.gear_ratio}
                | ({} if j.torque_constant is None else {"torque_constant": j.torque_constant})
                for j in self.joints
            ],
        }
        if self.kinematics is not None:
            d["kinematics"] = self.kinematics
        if self.joint_map:
            d["joint_map"] = dict(self.joint_map)
        if self.nominal is not None:
            d["nominal"] = self.nominal
        return d


@dataclass(frozen=True)
class ContactLabel:
    """One ground-truth contact (docs/formats.md, "Ground-truth labels").

    Attributes:
        start, end: contact interval [s since the log's first sample].
        peak_force: peak contact force [N].
        kind: ``impact``, ``push`` or ``clamp``.
        link: 1-based index of the link touched.
    """

    start: float
    end: float
    peak_force: float
    kind: str
    link: int
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Labels:
    """Ground truth for one log: its contacts, sample rate [Hz], the file it came from and
    the file's other top-level fields (kept, so a labels file reads back unchanged)."""

    events: tuple[ContactLabel, ...]
    sample_rate: float
    path: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        where = self.path or "labels"
        if not (self.sample_rate > 0):
            raise LabelsError(f"{where}: sample_rate must be positive")
        for i, e in enumerate(self.events):
            if not (e.end >= e.start):
                raise LabelsError(f"{where}: event {i} ends before it starts")
            if e.kind not in ("impact", "push", "clamp"):
                raise LabelsError(f"{where}: event {i} has unknown kind {e.kind!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping in the labels format."""
        return {
            "events": [
                {"start": e.start, "end": e.end, "peak_force": e.peak_force,
                 "kind": e.kind, "link": e.link, **e.extra}
                for e in self.events
            ],
            "sample_rate": self.sample_rate,
            **self.extra,
        }


DETECTORS: tuple[str, ...] = ("adaptive", "static_loading", "static_baseline")


@dataclass(frozen=True)
class AlarmSpan:
    """Where one detector alarmed: the fields an event and a lasting load share.

    Attributes:
        detector: ``adaptive``, ``static_loading`` or ``static_baseline``.
        t_start, t_end: first and last sample whose decision is 1, both inclusive
            [s since the log's first sample].
        i_start, i_end: the same as sample indices (inclusive).
        joints: names of the joints that fired, first to fire first.
    """

    detector: str
    t_start: float
    t_end: float
    i_start: int
    i_end: int
    joints: tuple[str, ...]


@dataclass(frozen=True)
class Event(AlarmSpan):
    """One detection event (docs/formats.md, "Detection timeline"): an
    :class:`AlarmSpan` and these.

    Attributes:
        peak_ratio: max over those joints and samples of statistic / threshold [-].
        peak_residual: per joint that fired, the residual r of largest magnitude during
            the event (signed) [N·m] — the contact-torque estimate.
        in_warmup: the event starts before the warm-up ends (listed, never counted).
    """

    peak_ratio: float
    peak_residual: dict[str, float]
    in_warmup: bool

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (timeline ``events`` item)."""
        return {
            "t_start": self.t_start, "t_end": self.t_end,
            "detector": self.detector, "joints": list(self.joints),
            "peak_ratio": self.peak_ratio,
            "peak_residual": dict(self.peak_residual),
            "in_warmup": self.in_warmup,
            "i_start": self.i_start, "i_end": self.i_end,
        }


@dataclass(frozen=True)
class LogHeader:
    """What a detection result tells of its log: the replayed joints (in the replay's
    order), the provenance and the clock — a :class:`RobotLog` without its samples.

    Attributes:
        joint_names: the J joints replayed.
        source: the log's provenance (:class:`LogSource`).
        n_samples: N, the log's samples.
        t0_ns: its first sample time on its own clock [ns].
        duration_s: from its first to its last sample [s].
        sample_rate_hz, sample_period_s: its sample clock (:mod:`impactcli.clock`).
    """

    joint_names: tuple[str, ...]
    source: LogSource
    n_samples: int
    t0_ns: int
    duration_s: float
    sample_rate_hz: float
    sample_period_s: float

    @property
    def n_joints(self) -> int:
        """Number of joints J."""
        return len(self.joint_names)


@dataclass(frozen=True)
class SignalsChunk:
    """What a replay hands its writers per chunk of n consecutive samples (J replayed joints).

    Attributes:
        joints: the J joints, in the replay's order.
        time_s: (n,) [s since the log's first sample]; t_ns: (n,) int64 [ns, the log's clock].
        signals: name → (n, J) float64 (:data:`impactcli.types.SIGNAL_NAMES`) [N·m].
        decisions: detector → (n, J) bool (:data:`DETECTORS`).
        position: (n, J) [rad]; position_ref: (n, J) [rad], None when not logged.
        ratios: detector → (n, J) statistic / threshold, the decision being ratio > 1
            (:func:`impactcli.detect.thresholds.detector_ratios`).
        start: index of the chunk's first sample in the log.
    """

    joints: tuple[str, ...]
    time_s: np.ndarray
    t_ns: np.ndarray
    signals: dict[str, np.ndarray]
    decisions: dict[str, np.ndarray]
    position: np.ndarray
    position_ref: np.ndarray | None
    ratios: dict[str, np.ndarray] = field(default_factory=dict)
    start: int = 0


#: Per-sample signal names (docs/formats.md, "Per-sample signals"), each an (N, J) array.
SIGNAL_NAMES: tuple[str, ...] = (
    "torque",             # measured torque, after any current scaling, before filtering [N·m]
    "residual",           # r = tau_hat - tau (eq. 7) [N·m]
    "filtered_residual",  # r_tilde = G(z) r [N·m]
    "dynamic_threshold",  # v_dyn [N·m]
    "residual_rms",       # r_tilde_rms after F1 (eq. 41) [N·m]
    "threshold",          # |v_stat + v_rms| (eq. 42) [N·m]
    "loading_statistic",  # |LP(r)|, the static-loading detector's statistic [N·m]
)


@dataclass(frozen=True)
class DetectionResult:
    """Everything one replay produced.

    Attributes:
        log: the analysed log: a :class:`~impactcli.types.LogHeader` (the replayed joints
            in order; its ``source`` carries path and sha256).
        model: the rigid model used, as its JSON mapping (``RigidModel.to_dict()``) — for
            joints on a logged generator, the model of what the controller's channel leaves
            out; None when no joint needs one (controller channels taken plain).
        model_sha256: sha256 of that model's canonical JSON (None without a model).
        model_source: ``given`` (--model), ``config`` (embedded in --config),
            ``identified-from-log`` (offline convenience) or ``none``.
        generators: joint → {generator, reason, residual} (:mod:`impactcli.model.generators`).
        incidents: :class:`impactcli.detect.incidents.Incident` per physical contact.
        lasting_loads: :class:`impactcli.detect.incidents.LastingLoad` per product alarm
            of 10 s or more (a finding of its own, in no incident).
        motion_envelope: the share of the log after warm-up that moved outside the
            calibration's motion envelope (:meth:`impactcli.detect.envelope.EnvelopeShare.
            to_dict`); None when the config recorded none.
        detection_floor: the smallest contact the run could have seen
            (:mod:`impactcli.detect.floor`): per joint the torque, per link the force (with
            kinematics), median and worst tenth after warm-up; None when not made.
        joints_left_out: ``{name, reason}`` of each logged joint left out of detection
            (:mod:`impactcli.logs.screen`; not in the model or config; left out at
            calibration).
        config: the detector config used, as its mapping, thresholds included.
        calibrated: thresholds came from a calibration on other logs (else the log's own
            statistics — an uncalibrated run).
        thresholds: per joint ``{"v_stat": .., "v0": .., "vL": ..}`` [N·m].
        reference_source: ``reference`` (logged controller reference) or ``measured``
            (fallback: causally filtered measured position).
        threshold_inputs: how u1, u2 were made, in words (which reference signals were
            logged, which were differentiated).
        torque_filtered: the measured torque went through the estimate's causal filter.
        events: all events, every detector, sorted by start time.
        warmup_end_s: the latest warm-up end over joints [s since first sample].
        warmup_per_joint_s: per joint warm-up end [s].
        filter_gain: ``{"frequencies_hz": [...], "gain": {joint: [...]}}`` of G_hat.
        warnings: one-line warnings raised during the run (also shown by the CLI).
        read_options: the options the log was read with (to re-run exactly).
        payloads_unwatched: why the replay weighed no load at all, neither the start's
            nor changes (None: it weighed one; :func:`impactcli.run.loads.unweighed_reason`);
            not in the timeline, whose ``input.payload`` and ``payload_changes`` are then
            absent.
        robot: the robot description given to the run (``--robot``), as its mapping, or
            None: with the model's own (``model["robot"]``) it says the links' chain and
            kinematics where the model records none (a controller channel taken plain
            replays no model); not in the timeline.
    """

    log: LogHeader
    model: dict[str, Any] | None
    model_sha256: str | None
    model_source: str
    config: dict[str, Any]
    calibrated: bool
    thresholds: dict[str, dict[str, float]]
    reference_source: str
    torque_filtered: bool
    events: tuple[Event, ...]
    warmup_end_s: float
    warmup_per_joint_s: dict[str, float]
    filter_gain: dict[str, Any]
    residual_generator: str = "inverse_dynamics"
    warnings: tuple[str, ...] = ()
    threshold_inputs: str = ""
    read_options: ReadOptions = field(default_factory=ReadOptions)
    generators: dict[str, dict[str, str]] = field(default_factory=dict)
    joints_left_out: tuple[dict[str, str], ...] = ()
    incidents: tuple[Any, ...] = ()
    lasting_loads: tuple[Any, ...] = ()
    motion_envelope: dict[str, Any] | None = None
    detection_floor: dict[str, Any] | None = None
    data_defects: dict[str, Any] | None = None
    torque_scale: dict[str, Any] | None = None
    payload: dict[str, Any] | None = None
    payload_changes: tuple[dict[str, Any], ...] | None = None
    payloads_unwatched: str | None = None
    robot: dict[str, Any] | None = None

    @property
    def online_equivalent(self) -> bool:
        """Model (or correction model) and thresholds came from other logs: the robot could
        have run this online."""
        return self.calibrated and self.model_source != "identified-from-log"

    def counted_events(self, detector: str) -> list[Event]:
        """Events of ``detector`` that start after warm-up (the ones summaries count)."""
        return [e for e in self.events if e.detector == detector and not e.in_warmup]

    def counted_incidents(self) -> list[Any]:
        """Incidents after warm-up that are not at a data defect nor a payload change (the
        ones summaries count; an incident never spans the warm-up's end)."""
        return [i for i in self.incidents
                if not i.in_warmup and getattr(i, "data_defect", None) is None
                and getattr(i, "payload_change", None) is None]

    def payload_incidents(self) -> list[Any]:
        """Incidents after warm-up that were a payload change (counted apart)."""
        return [i for i in self.incidents
                if not i.in_warmup and getattr(i, "payload_change", None) is not None]

    def defect_incidents(self) -> list[Any]:
        """Incidents after warm-up that start at a data defect (counted apart)."""
        return [i for i in self.incidents
                if not i.in_warmup and getattr(i, "data_defect", None) is not None]

    def counted_lasting_loads(self) -> list[Any]:
        """Lasting loads after warm-up (counted, like incidents, by the summaries and the
        gates)."""
        return [x for x in self.lasting_loads if not x.in_warmup]

    def counts(self) -> dict[str, dict[str, int]]:
        """Incidents and lasting loads: counted (after warm-up) and in warm-up (the
        timeline's ``counts``)."""
        return {
            "incidents": {"counted": len(self.counted_incidents()),
                          "in_warmup": sum(1 for i in self.incidents if i.in_warmup),
                          **({"data_defect": n} if (n := len(self.defect_incidents()))
                             else {}),
                          **({"payload_change": n} if (n := len(self.payload_incidents()))
                             else {})},
            "lasting_loads": {"counted": len(self.counted_lasting_loads()),
                              "in_warmup": len(self.lasting_loads)
                              - len(self.counted_lasting_loads())},
        }

    def summary(self) -> dict[str, dict[str, int]]:
        """Per detector: events counted (after warm-up) and events in warm-up."""
        return {
            d: {
                "events": len(self.counted_events(d)),
                "in_warmup": sum(1 for e in self.events if e.detector == d and e.in_warmup),
            }
            for d in DETECTORS
        }
