"""Detector configuration: every parameter of detection, as frozen dataclasses.

Defaults are the paper's Table I where it gives them (eta = 2, rho = (2, 4), p = 20,
w1 = 10 Hz, w2 = 50 Hz, N1 = 40 ms, N2 = 160 ms, lambda = 0.999, P(1) = 10 I,
theta(1) = 0); every other default is documented at its field. A config file (TOML, YAML
or JSON, by suffix) holds ``DetectorConfig.to_dict()`` and is validated against
``schemas/config.schema.json``; any bad value raises :class:`ConfigError` naming the file
and the field (CLI exit 3).

Thresholds are per joint (mapping joint name → value in N·m). An empty mapping means "not
calibrated": the caller then uses the robust rule of
:func:`impactcli.detect.thresholds.thresholds_from_maxima`. Table I's v_stat = [0.45, 0.2]
N·m (ASSIST arm) is kept as :data:`TABLE_I_V_STAT` for reference and for 2-joint
simulations only; it is never applied to a real robot silently.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w
import yaml

from .errors import ConfigError
from .files import atomic_write_text, load_mapping
from .schema import omit_nulls, validate

#: Table I's static thresholds of the 2-joint ASSIST arm [N·m] (shoulder, elbow).
TABLE_I_V_STAT: tuple[float, float] = (0.45, 0.2)

ESTIMATES = ("a_priori", "a_posteriori")
#: Older spelling of ``inverse_dynamics`` still read from config files (written as the new).
GENERATOR_ALIASES = {"rigid_model": "inverse_dynamics"}


#: The adaptive evaluator's default regularisation delta (docs/method.md §3, measured).
REGULARIZATION = 10.0
#: The adaptive evaluator's formulations, recorded in every config ``calibrate`` writes
#: (``calibration.formulation``; :func:`formulation_of`): thresholds calibrated on another
#: formulation's statistic than the one a replay runs are warned about (docs/formats.md).
#: ``regularised-rls-1``: the regulariser at every 4th sample (docs/method.md §3); a
#: config without a record was calibrated on ``plain-eq39`` (releases before 2026-11-28).
FORMULATION = "regularised-rls-1"
PLAIN_FORMULATION = "plain-eq39"


@dataclass(frozen=True)
class AdaptiveConfig:
    """Adaptive evaluator (paper eq. 24–42, Table I).

    Attributes:
        eta: degree of G_j(z) (eq. 29) [samples].
        rho: numerator orders rho_i per input type (u1 = tanh(slope·x1_ref'), u2 = x1_ref'')
            [samples].
        p: degree of A_j(z), the dynamic threshold's denominator (eq. 48) [samples].
        w1_hz: F1 cut-off (filtered residual) [Hz].  w2_hz: F2 cut-off (threshold) [Hz].
        n1_s: RMS window of the residual (eq. 41) [s] (N1 = 10 samples at 4 ms).
        n2_s: RMS window of the threshold [s] (N2 = 40 samples at 4 ms).
        forgetting_factor: lambda (eq. 37–39).
        p0: P(1) = p0 I.  theta0: theta(1) = theta0 (all components).
        estimate: ``a_priori`` (theta(k-1)) or ``a_posteriori`` (theta(k)) used for r_tilde
            and v_dyn; default chosen by measurement (docs/method.md §3, "A priori or a
            posteriori").
        tanh_slope: slope of u1 = tanh(tanh_slope · x1_ref') [s/rad]; 50 s/rad makes
            |u1| > 0.96 above 0.04 rad/s (≈ 2.3 °/s), a sign() that stays continuous.
        max_trace: RLS wind-up guard (impactcli.detect.rls): bounds trace(P) by capping
            each diagonal element of P at max_trace / nu; None → 1e5 · nu · p0 (measured
            choice: docs/method.md §3, "The wind-up guard"); ``inf`` disables it (pure
            eq. 39).
        measured_input_cutoff_hz: cut-off of the causal 2nd-order Butterworth used to
            differentiate the *measured* position when no reference is logged [Hz].
        regularization: delta, the information about theta = theta0 the RLS keeps whatever
            it forgets (impactcli.detect.rls.rls_update_inplace): P stays below ~I/delta and
            the evaluator's answer a property of the log, not of the last bits of the
            arithmetic; 0 → plain eq. 39 (the paper; sensitive: docs/method.md §3,
            "Sensitivity, and the regularised form").
    """

    eta: int = 2
    rho: tuple[int, ...] = (2, 4)
    p: int = 20
    w1_hz: float = 10.0
    w2_hz: float = 50.0
    n1_s: float = 0.040
    n2_s: float = 0.160
    forgetting_factor: float = 0.999
    p0: float = 10.0
    theta0: float = 0.0
    estimate: str = "a_posteriori"
    tanh_slope: float = 50.0
    max_trace: float | None = None
    measured_input_cutoff_hz: float = 10.0
    regularization: float = REGULARIZATION

    def n_params(self, n_joints: int) -> int:
        """nu = eta + p + n·sum(rho) (34 for 2 joints, 64 for 7 with Table I)."""
        return self.eta + self.p + n_joints * sum(self.rho)

    @property
    def formulation(self) -> str:
        """The formulation these settings run: :data:`FORMULATION` when the regulariser acts
        (regularization > 0 and forgetting_factor < 1), else :data:`PLAIN_FORMULATION`."""
        active = self.regularization > 0.0 and self.forgetting_factor < 1.0
        return FORMULATION if active else PLAIN_FORMULATION


#: Each detector's threshold under its name in the files (a config's ``[thresholds]``, a
#: timeline's ``thresholds``: the paper's symbols) — the one translation between the two
#: vocabularies; inside the package thresholds go by detector.
THRESHOLD_KEYS: dict[str, str] = {"adaptive": "v_stat", "static_loading": "vL",
                                  "static_baseline": "v0"}


@dataclass(frozen=True)
class ThresholdsConfig:
    """Per-joint thresholds [N·m]; empty mapping = not calibrated (robust rule used).

    Attributes:
        v_stat: adaptive detector's static term (eq. 42).
        v0: static_baseline threshold on |r|.
        vL: static_loading threshold on |LP(r)|.
    """

    v_stat: dict[str, float] = field(default_factory=dict)
    v0: dict[str, float] = field(default_factory=dict)
    vL: dict[str, float] = field(default_factory=dict)

    def of(self, detector: str) -> dict[str, float]:
        """The per-joint thresholds of ``detector`` (:data:`THRESHOLD_KEYS`)."""
        table: dict[str, float] = getattr(self, THRESHOLD_KEYS[detector])
        return table

    def vector(self, kind: str, joint_names: Sequence[str], where: str = "config") -> (
            np.ndarray | None):
        """(J,) thresholds ``kind`` (``v_stat``, ``v0`` or ``vL``) in ``joint_names`` order
        [N·m]; None if not calibrated (empty). ConfigError if some joints are missing."""
        m: dict[str, float] = getattr(self, kind)
        if not m:
            return None
        missing = [j for j in joint_names if j not in m]
        if missing:
            raise ConfigError(
                f"{where}: thresholds/{kind}: no value for joint(s) {', '.join(missing)} "
                f"(config has {', '.join(m)})"
            )
        return np.array([m[j] for j in joint_names], dtype=np.float64)


@dataclass(frozen=True)
class StaticLoadingConfig:
    """static_loading detector: |LP(r)| > vL (docs/method.md §5).

    Attributes:
        cutoff_hz: LP cut-off [Hz]; 2 Hz passes contacts building over ≳ 0.1 s and cuts the
            residual's noise floor several-fold.
        order: 1 (first-order, unit DC gain) or 2 (2nd-order Butterworth).
    """

    cutoff_hz: float = 2.0
    order: int = 1


@dataclass(frozen=True)
class ResidualConfig:
    """Residual generation options (used by the residual generator, not by detect/).

    Attributes:
        generator: for every joint (docs/formats.md, "Model and detector config"): ``auto``
            (the default for new configs and for ``detect`` without one: per joint
            ``logged_external`` when the log carries ``torque_ext``, else ``logged_model``
            when it carries ``torque_model``, else ``inverse_dynamics``),
            ``inverse_dynamics`` (eq. 7–8; ``rigid_model`` is read as it),
            ``momentum_observer``, ``logged_model`` or ``logged_external``
            (:mod:`impactcli.model.generators`). Configs written before ``auto`` existed name
            their generator and keep it.
        generators: joint → generator frozen by ``calibrate`` (thresholds belong to the
            generator they were made with); wins over ``generator``.
        logged_correction: correct the controller's channels (``logged_model``,
            ``logged_external``) by what the tool's own model structure, identified on the
            calibration logs, finds they leave out in free motion
            (:mod:`impactcli.model.generators`); false takes them plain.
        derivative_cutoff_hz: causal low-pass of the estimated velocity/acceleration [Hz].
        filter_torque: pass the measured torque through the same causal filter as the
            estimate (docs/method.md §8: lowers the residual's high-frequency floor 2–5×).
        observer_gain: momentum-observer gain K [1/s].
    """

    generator: str = "auto"
    derivative_cutoff_hz: float = 15.0
    filter_torque: bool = True
    observer_gain: float = 50.0
    generators: dict[str, str] = field(default_factory=dict)
    logged_correction: bool = True


@dataclass(frozen=True)
class EventsConfig:
    """Event extraction (impactcli.detect.events).

    Attributes:
        merge_gap_s: bursts separated by at most this gap (last 1 → next 1) merge [s];
            0.1 s keeps one event per contact (a contact's alarm flickers at the RMS
            windows' 40–160 ms scale) while separating contacts a few tenths apart.
        min_duration_s: events with t_end − t_start below this are dropped [s]; 0 keeps
            single-sample alarms (the RMS already smooths; online, one sample stops the robot).
    """

    merge_gap_s: float = 0.1
    min_duration_s: float = 0.0


@dataclass(frozen=True)
class WarmupConfig:
    """Warm-up (docs/method.md §5b; impactcli.detect.warmup).

    Attributes:
        min_s: the RLS must have seen at least this long [s] (≈ one forgetting time
            constant Ts/(1−lambda) = 4 s at Table I's values would be the ideal; 3 s).
        window_s: rolling-RMS window of the a priori prediction error [s].
        tolerance: settled when that rolling RMS ≤ (1 + tolerance) × its later level
            (the median of the rolling RMS after ``min_s``).
        max_s: upper cap of the warm-up [s].
    """

    min_s: float = 3.0
    window_s: float = 0.5
    tolerance: float = 0.5
    max_s: float = 20.0


@dataclass(frozen=True)
class LogRecord:
    """A log a config was calibrated on: path as given, sha256 of its bytes, and the
    channel its torque was read from (``torque`` or ``current``; None: not recorded,
    configs before 2026-12-01). detect warns when an audited log's differs
    (:func:`impactcli.run.run_warnings.warn_torque_source`)."""

    path: str
    sha256: str
    torque_source: str | None = None


@dataclass(frozen=True)
class CalibrationRecord:
    """Where the thresholds come from.

    Attributes:
        calibrated: thresholds come from collision-free logs (False: defaults/robust rule).
        margin_rule: ``leave-one-out``, ``fixed-single-log`` or ``uncalibrated-block-quantile``
            (recorded in an uncalibrated run's timeline; such a config stays uncalibrated).
        margins: detector → joint → margin applied to the statistic's maximum.
        logs: the collision-free logs used.
        model_sha256: sha256 of the model the thresholds belong to.
        weak: the calibration is weaker than leave-one-out (one log / capped margin).
        joints_left_out: ``{name, reason}`` of the logged joints the calibration left out
            (no thresholds: detect leaves them out too).
        segments: stretches of collision-free log the margins were chosen over (long logs
            are cut into segments; leave-one-out is over segments).
        excluded: ``{log, start_s, end_s, reason}`` stretches left out of the calibration
            (labelled contacts; likely contacts found without labels).
        sample_rate_hz: the sample rate of the calibration logs [Hz]
            (:func:`impactcli.clock.sample_clock`; None: not recorded, older configs). A
            log sampled at another rate is refused
            (:func:`impactcli.clock.check_calibrated_rate`): thresholds depend on it.
        threshold_rule: how the product's thresholds (v_stat, vL) were set:
            ``false-alarm-rate`` (for a stated rate, ``false_alarm_rate``) or
            ``leave-one-out`` (``margin_rule``); None: not recorded (configs before the
            rate existed: ``margin_rule`` set them all). static_baseline's v0 always
            follows ``margin_rule``.
        false_alarm_rate: the false-alarm rate record (docs/formats.md, "Model and detector
            config"; :func:`impactcli.run.calibration.rate_record`): R per hour when asked
            (``false-alarm-rate``; without it, the rate the margin's thresholds are
            predicted to give), its confidence, the free-motion minutes it rests on, the
            predicted rate and its upper bound, the rate those minutes support and the
            sentence saying so, per detector and joint the threshold and its tail fit, and
            leave-one-log-out rows; None in older configs or when the free motion was too
            short for a tail fit.
        motion_envelope: the calibration's motion envelope
            (:meth:`impactcli.detect.envelope.MotionEnvelope.to_dict`): per joint the
            ranges of velocity, acceleration and position of the free motion, and its
            longest slow stretch.
        formulation: the adaptive evaluator's formulation the thresholds were calibrated
            on (:data:`FORMULATION`); None: before formulations were recorded (the plain
            eq. 39 of releases up to 2026-11-27). Another than the running one is warned
            about at detect.
        load_envelopes: when the calibration logs carried different loads, per log whose
            load differs from the model's: ``{log, mass_kg, envelope}`` — that load beyond
            the model's and the motion envelope of that log alone (the motion the
            thresholds' rate was measured on under that load); None otherwise.
        settings_sha256: the fingerprint of the detector settings the thresholds were set
            with (:func:`settings_sha256`); None: not recorded (configs before
            2026-11-30). A config whose settings differ (edited after ``calibrate``) is
            warned about at detect, and its stated rate is said not to apply.
    """

    calibrated: bool = False
    margin_rule: str = ""
    margins: dict[str, dict[str, float]] = field(default_factory=dict)
    logs: tuple[LogRecord, ...] = ()
    model_sha256: str | None = None
    weak: bool = False
    joints_left_out: tuple[dict[str, str], ...] = ()
    segments: int = 0
    excluded: tuple[dict[str, Any], ...] = ()
    sample_rate_hz: float | None = None
    threshold_rule: str | None = None
    false_alarm_rate: dict[str, Any] | None = None
    motion_envelope: dict[str, Any] | None = None
    formulation: str | None = None
    settings_sha256: str | None = None
    load_envelopes: tuple[dict[str, Any], ...] | None = None


#: The config's sections a calibration's thresholds depend on (:func:`settings_sha256`):
#: all but the thresholds, the calibration record and the embedded model (its own sha256,
#: ``calibration.model_sha256``); of ``residual``, all but the generator choice (checked on
#: its own: :func:`impactcli.run.plan.with_generator`).
SETTINGS_SECTIONS = ("adaptive", "static_loading", "residual", "events", "warmup")


def settings_sha256(config: DetectorConfig | dict[str, Any]) -> str:
    """The sha256 of the detector settings of a config (or of its mapping, as a timeline
    records it): :data:`SETTINGS_SECTIONS` as canonical JSON, numbers as floats (a TOML
    ``2`` and a JSON ``2.0`` are one setting)."""
    d = config.to_dict() if isinstance(config, DetectorConfig) else config

    def canon(v: Any) -> Any:
        if isinstance(v, dict):
            return {str(k): canon(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [canon(x) for x in v]
        if isinstance(v, int | float) and not isinstance(v, bool):
            return float(v)
        return v

    settings = {k: dict(d.get(k) or {}) for k in SETTINGS_SECTIONS}
    for k in ("generator", "generators"):
        settings["residual"].pop(k, None)
    text = json.dumps(canon(settings), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def settings_changed(config: DetectorConfig | dict[str, Any]) -> bool:
    """Whether a calibrated config's detector settings differ from those its thresholds
    were set with (a recorded :func:`settings_sha256` that does not match), or its
    thresholds from those its calibration recorded (:func:`thresholds_edited`)."""
    d = config.to_dict() if isinstance(config, DetectorConfig) else config
    cal = d.get("calibration") or {}
    recorded = cal.get("settings_sha256")
    return bool(cal.get("calibrated")) and (
        (recorded is not None and recorded != settings_sha256(d)) or bool(thresholds_edited(d)))


#: The thresholds a calibration's rate record holds per channel: detector → key.
RATED_THRESHOLDS = {"adaptive": "v_stat", "static_loading": "vL"}


def thresholds_edited(config: DetectorConfig | dict[str, Any]) -> list[str]:
    """The thresholds of a calibrated config that differ from those its calibration's rate
    record set (``false_alarm_rate.channels``: the rate was stated for those), each as
    ``shoulder v_stat 0 (calibrated 0.418)``; none when it records no channels."""
    d = config.to_dict() if isinstance(config, DetectorConfig) else config
    cal = d.get("calibration") or {}
    channels = ((cal.get("false_alarm_rate") or {}).get("channels") or {})
    out = []
    for det, key in RATED_THRESHOLDS.items():
        for joint, ch in (channels.get(det) or {}).items():
            now = ((d.get("thresholds") or {}).get(key) or {}).get(joint)
            was = ch.get("threshold") if isinstance(ch, dict) else None
            if now is not None and was is not None and not math.isclose(
                    float(now), float(was), rel_tol=1e-9, abs_tol=1e-12):
                out.append(f"{joint} {key} {float(now):.4g} (calibrated {float(was):.4g})")
    return out


@dataclass(frozen=True)
class DetectorConfig:
    """Every detection parameter (docs/formats.md, "Model and detector config").

    Attributes:
        adaptive, thresholds, static_loading, residual, events, warmup, calibration: see
            their classes.
        model: the embedded model mapping (model format) the thresholds belong to, or None.
    """

    adaptive: AdaptiveConfig = field(default_factory=AdaptiveConfig)
    thresholds: ThresholdsConfig = field(default_factory=ThresholdsConfig)
    static_loading: StaticLoadingConfig = field(default_factory=StaticLoadingConfig)
    residual: ResidualConfig = field(default_factory=ResidualConfig)
    events: EventsConfig = field(default_factory=EventsConfig)
    warmup: WarmupConfig = field(default_factory=WarmupConfig)
    calibration: CalibrationRecord = field(default_factory=CalibrationRecord)
    model: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.model is not None:  # one form in memory and in every file format
            object.__setattr__(self, "model", omit_nulls(self.model))

    def to_dict(self) -> dict[str, Any]:
        """The config's mapping, the same in TOML, YAML and JSON: a field without a value
        (None) is left out, the embedded model's included
        (:func:`impactcli.schema.omit_nulls`)."""
        d: dict[str, Any] = omit_nulls(dataclasses.asdict(self))
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any], where: str = "config") -> DetectorConfig:
        """Validate ``d`` against schemas/config.schema.json and build the config.

        Raises ConfigError ``"<where>: <field path>: <problem>"``.
        """
        validate(d, "config", ConfigError, where)
        try:
            return _build(d, where)
        except (TypeError, ValueError) as err:
            if isinstance(err, ConfigError):
                raise
            raise ConfigError(f"{where}: {err}") from err

    def replace(self, **changes: Any) -> DetectorConfig:
        """A copy with top-level fields replaced."""
        return dataclasses.replace(self, **changes)


def _embedded_model(m: dict[str, Any] | None, where: str) -> dict[str, Any] | None:
    """The config's embedded model, validated against schemas/model.schema.json so a bad
    one is reported naming the config file (nulls of older files left out)."""
    if m is None:
        return None
    model: dict[str, Any] = omit_nulls(m)
    validate(model, "model", ConfigError, f"{where}: model")
    return model


def _build(d: dict[str, Any], where: str) -> DetectorConfig:
    a = dict(d.get("adaptive", {}))
    if "rho" in a:
        a["rho"] = tuple(int(v) for v in a["rho"])
    adaptive = AdaptiveConfig(**a)
    if adaptive.w2_hz <= adaptive.w1_hz:
        raise ConfigError(f"{where}: adaptive/w2_hz: must exceed w1_hz ({adaptive.w1_hz})")
    if adaptive.n2_s < adaptive.n1_s:
        raise ConfigError(f"{where}: adaptive/n2_s: must be at least n1_s ({adaptive.n1_s})")
    t = d.get("thresholds", {})
    thresholds = ThresholdsConfig(
        **{k: {str(j): float(v) for j, v in t.get(k, {}).items()} for k in ("v_stat", "v0", "vL")}
    )
    c = dict(d.get("calibration", {}))
    c["logs"] = tuple(LogRecord(**lg) for lg in c.get("logs", []))
    c["joints_left_out"] = tuple({"name": str(x["name"]), "reason": str(x["reason"])}
                                 for x in c.get("joints_left_out", []))
    c["excluded"] = tuple(dict(x) for x in c.get("excluded", []))
    c["margins"] = {
        k: {str(j): float(v) for j, v in m.items()} for k, m in c.get("margins", {}).items()
    }
    if c.get("load_envelopes") is not None:
        c["load_envelopes"] = tuple(dict(x) for x in c["load_envelopes"])
    envelopes = [("calibration/motion_envelope", c.get("motion_envelope"))] + [
        (f"calibration/load_envelopes/{i}/envelope", x["envelope"])
        for i, x in enumerate(c.get("load_envelopes") or ())]
    for at, env in envelopes:
        for j, q in ((env or {}).get("joints") or {}).items():
            for k, rng in q.items():  # a range is [min, max]: reversed, every sample is out
                if not float(rng[0]) <= float(rng[1]):
                    raise ConfigError(f"{where}: {at}/joints/{j}/{k}: "
                                      f"[{rng[0]}, {rng[1]}] is not [min, max]")
    residual = dict(d.get("residual", {}))
    residual["generators"] = {str(j): str(g) for j, g in residual.get("generators", {}).items()}
    if "generator" in residual:
        residual["generator"] = GENERATOR_ALIASES.get(residual["generator"],
                                                      residual["generator"])
    model = _embedded_model(d.get("model"), where)
    if model is not None:
        known = list(model["joint_names"])
        for kind, table in (("v_stat", thresholds.v_stat), ("v0", thresholds.v0),
                            ("vL", thresholds.vL)):
            if table and set(table) != set(known):
                extra = sorted(set(table) - set(known))
                missing = [j for j in known if j not in table]
                raise ConfigError(
                    f"{where}: thresholds/{kind}: joints {sorted(table)} do not match the "
                    f"model's {known}" + (f" (unknown: {extra})" if extra else "")
                    + (f" (missing: {missing})" if missing else ""))
    return DetectorConfig(
        adaptive=adaptive,
        thresholds=thresholds,
        static_loading=StaticLoadingConfig(**d.get("static_loading", {})),
        residual=ResidualConfig(**residual),
        events=EventsConfig(**d.get("events", {})),
        warmup=WarmupConfig(**d.get("warmup", {})),
        calibration=CalibrationRecord(**c),
        model=model,
    )


def load_config(path: str | os.PathLike[str]) -> DetectorConfig:
    """Read and validate a detector config (TOML, YAML or JSON by suffix).

    Raises ConfigError naming the file and the offending field.
    """
    data = load_mapping(path, ConfigError, "detector config")
    if not data:
        raise ConfigError(f"{path}: the config is empty (make one with `impactcli calibrate`)")
    if {"kind", "joint_names", "parameters"} <= set(data):
        raise ConfigError(f"{path}: this is a model (from `impactcli identify`), not a "
                          "detector config — give it with --model")
    return DetectorConfig.from_dict(data, where=str(path))


def dumps_config(cfg: DetectorConfig, suffix: str) -> str:
    """Serialise ``cfg`` as TOML (``.toml``), YAML (``.yaml``/``.yml``) or JSON (else)."""
    d = cfg.to_dict()
    s = suffix.lower()
    if s == ".toml":
        return tomli_w.dumps(d)
    if s in (".yaml", ".yml"):
        return str(yaml.safe_dump(d, sort_keys=False))
    return json.dumps(d, indent=2) + "\n"


def save_config(cfg: DetectorConfig, path: str | os.PathLike[str]) -> None:
    """Write ``cfg`` atomically to ``path`` (format by suffix)."""
    atomic_write_text(path, dumps_config(cfg, Path(path).suffix))
