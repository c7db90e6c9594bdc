"""The loads a log carries (docs/models.md, "Payloads"): the one it starts with, weighed
on its first seconds with the model's parameters held before the replay's first sample
(:func:`weigh_start`), and the monitor of its changes mid-log (:func:`monitor_for`,
:mod:`impactcli.detect.payload_change`). Both run for the tool's own model's generators
(:data:`OWN`; the monitor for ``inverse_dynamics`` alone) and for the controller's channels
corrected by the tool's model (:func:`weighable`).

The stretch weighed lies within the warm-up (its least length, ``[warmup] min_s``, and at
most :data:`impactcli.model.payload.START_S`), where detection is off: the load found
there is the one the replay uses from the first sample, and every decision after the
warm-up still depends only on samples before it. The stretch passes through the replay's
own causal filters (the inverse-dynamics residual, whatever the generator: a load is a
mass, not a filter) and the load is weighed by :func:`impactcli.model.payload.weigh`. It
is used when the motion determines it (mass and centre of mass), its mass is three
standard errors from the model's own, its torque over the stretch exceeds the model's own
held-back error on some joint and stays within :data:`HOLD_FACTOR` times the largest
torque the joints exerted there (a load no motor held is not one), its centre of mass lies
within the arm's reach, and it accounts for at least 90 % of what the model leaves out
there (a model error is not a mass); otherwise it is said, not used.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..config import DetectorConfig
from ..detect.payload_finding import SHORTFALL
from ..detect.payload_words import OWN_LOAD, beyond_words
from ..errors import ImpactWarning
from ..model import RigidModel, payload
from ..model.generators import LOGGED, OWN_MODEL, GeneratorChoice, target_torque

#: The generators whose residual is the tool's own model's (eq. 7–8, the observer).
OWN = OWN_MODEL

#: A load whose torque over the stretch exceeds this many times the largest torque the
#: joints exerted there is one no motor held: not a load.
HOLD_FACTOR = 3.0


#: A load weighed on a log's start that explains at least this share of what the model
#: leaves out there, but not :data:`~impactcli.model.payload.EXPLAINED`, is partly a load:
#: a step in the stretch (a load picked, a contact) — not known. Below it, what the model
#: leaves out is its own error, and the log starts with the model's load.
PARTLY = 0.25


@dataclass(frozen=True)
class StartLoad:
    """The load a log starts with, beyond the model's own (module docstring).

    Attributes:
        verdict: ``used`` (the residual carries it), ``same`` (within what the model
            tells), ``unsupported`` (the stretch does not determine it: not used).
        seconds: the stretch weighed [s from the log's first sample].
        mass_kg, mass_se_kg: its mass beyond the model's load and standard error (None:
            not determined).
        values: its parameters (:func:`impactcli.model.payload.basis`' names, SI).
        relative_to: the calibration log whose load the model carries (None: the model
            was fitted with one load).
        calibrated: the calibration logs' masses beyond ``relative_to`` [kg].
        message: the sentence the run says.
        explained: the share of what the model leaves out over the stretch that the load
            accounts for (None: not weighed); used only from
            :data:`impactcli.model.payload.EXPLAINED` on.
        as_log: the calibration log whose load it is
            (:func:`impactcli.model.payload.known_load`): the residual carries that log's
            fitted load, not the stretch's (None: the stretch's, or not used).
    """

    verdict: str
    seconds: float
    mass_kg: float | None
    mass_se_kg: float | None
    values: dict[str, float]
    relative_to: str | None
    calibrated: dict[str, float]
    message: str
    explained: float | None = None
    as_log: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (the timeline's ``input.payload``); absent values left out."""
        d = dataclasses.asdict(self)
        return {k: v for k, v in d.items() if v is not None}


def weighable(choices: tuple[GeneratorChoice, ...], logged_correction: bool,
              own: tuple[str, ...] = OWN) -> bool:
    """Whether every joint's residual can weigh and carry a load: one of ``own``'s
    generators (the tool's model), or a controller's channel corrected by the tool's model
    (``logged_correction``: r = Ŷθ − G(target), :mod:`impactcli.model.generators`, as linear
    in a load at the flange as eq. 7–8 is). A load the controller's model does not know
    shows in its channel as the torque of that mass, which is what is weighed; one it knows
    (a payload set in the controller) shows nothing, and nothing is found. A channel taken
    plain (r = torque_ext) has no model of the tool's to carry a load."""
    return all(c.generator in own or (logged_correction and c.generator in LOGGED)
               for c in choices)


def weigh_start(feed: Any, model: RigidModel, choices: tuple[GeneratorChoice, ...],
                cfg: DetectorConfig) -> tuple[RigidModel, StartLoad | None]:
    """The model carrying the load the log starts with, and what was found (None: a model
    without kinematics, or a warm-up too short to weigh in)."""
    bb = payload.basis(model.kind, model.joint_names, model.structure)
    seconds = min(payload.START_S, float(cfg.warmup.min_s))
    if bb is None or seconds <= 0 or not weighable(choices, cfg.residual.logged_correction):
        return model, None
    b, names = bb
    scan = feed.scan
    fs = float(scan.sample_rate_hz)
    n_want = int(np.floor(seconds * fs))
    q_parts, tau_parts = [], []
    got = 0
    for _, t, a in feed.chunks(model.joint_names):
        k = min(t.shape[0], n_want - got)
        q_parts.append(np.asarray(a.position)[:k])
        tau_parts.append(target_torque(a, choices, cfg.residual.logged_correction)[:k])
        got += k
        if got >= n_want:
            break
    rel, cal = _calibration(model)
    rows = _rows(model, np.concatenate(q_parts), np.concatenate(tau_parts), fs,
                 cfg) if got else None
    if rows is None:
        return model, StartLoad("unsupported", seconds, None, None, {}, rel, cal, (
            f"{scan.source.path}: the load the log starts with was not weighed: its first "
            f"{seconds:g} s are too short for the residual's filters; the residual "
            f"assumes the model's load{_whose(rel)}"))
    y, left, tau = rows
    yb = y @ b
    w, keep = payload.weigh_trimmed(yb, left, names)
    yb, left, tau = yb[keep], left[keep], tau[keep]
    if not keep.all():  # a transient no load explains (the arm settling, the filters)
        seconds_words = (f"{seconds:g} s ({_left_out(keep, fs)}: a transient no load "
                         f"explains, beyond {payload.OUTLIER_SIGMAS:g} robust standard "
                         "deviations of what the load leaves)")
    else:
        seconds_words = f"{seconds:g} s"
    values = {nm: float(v) for nm, v in zip(names, w.pi, strict=True)}
    where = scan.source.path
    mass = f"{w.mass_kg:+.3g} ± {w.mass_se_kg:.2g} kg"
    carried = yb @ w.pi  # (n, J) the load's torque over the stretch [N·m]
    own = _model_error(model)
    felt = own is not None and bool(np.any(np.sqrt(np.mean(carried**2, axis=0)) > own))
    share = payload.explained(left, yb, w.pi)
    held = float(np.max(np.abs(carried)))
    top = float(np.max(np.abs(tau))) if tau.size else 0.0
    same = not w.weighed or not felt or share < payload.EXPLAINED
    why = None
    if not w.supported:
        why = "do not move the arm through poses that tell its mass from its centre of mass"
    elif w.weighed and held > HOLD_FACTOR * top:  # a load no motor held: not a load
        why = (f"give a load ({mass}) whose torque, up to {held:.3g} N·m, is beyond "
               f"{HOLD_FACTOR:g}× the largest the joints exerted there ({top:.3g} N·m)")
    elif not same and not payload.within_reach(names, w.pi, payload.reach_m(model)):
        why = f"give a centre of mass beyond the arm's reach ({mass})"
    elif felt and PARTLY <= share < payload.EXPLAINED:  # partly a load (a step in the
        # stretch is a misfit over many rows: its mass's error counts them as few, and may
        # not tell it from none)
        why = (f"hold a torque the model does not explain, of which a steady load ({mass}) "
               f"explains only {100 * share:.0f} % (a load picked, or a contact, in them?)")
        return model, StartLoad(  # its weighing kept (not used): a change that weighs
            "unsupported", seconds, w.mass_kg, w.mass_se_kg, {}, rel, cal, (  # the same
            f"{where}: the load the log starts with is not known: its first {seconds:g} s "
            f"{why}; the residual assumes the model's load{_whose(rel)}"), share)
    if why is not None:
        return model, StartLoad("unsupported", seconds, None, None, {}, rel, cal, (
            f"{where}: the load the log starts with is not known: its first {seconds:g} s "
            f"{why}; the residual assumes the model's load{_whose(rel)}"))
    if same:
        why = ("within what the model tells" if not w.weighed or not felt else
               f"it explains {100 * share:.0f} % of what the model leaves out there: the "
               "model's own error, not a load")
        return model, StartLoad("same", seconds, w.mass_kg, w.mass_se_kg, values, rel, cal, (
            f"{where}: starts with the model's load{_whose(rel)} ({mass} beyond it, "
            f"weighed on its first {seconds_words}: {why})"), share)
    unseen = beyond_calibrated(cal, w.mass_kg, w.mass_se_kg)
    # the model carries the lightest calibration log's load: a known load is relative to it
    known = payload.known_load(payload.calibration_loads(model, names), np.zeros_like(w.pi),
                               w.pi, w.mass_se_kg, yb, left, names)
    pi = w.pi if known is None else known[1]
    kg, side = beyond_words(w.mass_kg)
    return payload.carrying(model, pi), StartLoad(
        "used", seconds, w.mass_kg, w.mass_se_kg, values, rel, cal, (
            f"{where}: carrying ~{kg} kg (s.e. ≥ {w.mass_se_kg:.2g} kg, the model's own "
            f"error not counted; it explains {100 * share:.0f} % of what the model leaves "
            f"out — a load, or a model error that acts as one: another unit of the arm, "
            f"a tool changed) {side} the model's "
            f"load{_whose(rel)}{_calibrated_with(cal)}, weighed on its first "
            f"{seconds_words}: "
            + ("the residual uses it" if known is None else
               f"it is {known[0]}'s load, and the residual uses that log's fit of it")
            + ("; no calibration log carried a load like it, so the thresholds' false-alarm "
               "rate was not measured with it (a load unlike theirs brings errors the "
               "rigid model was not calibrated with): calibrate with a log that carries it"
               if unseen
               else "")), share, None if known is None else known[0])


def _rows(model: RigidModel, q: np.ndarray, tau: np.ndarray, fs: float,
          cfg: DetectorConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The stretch's regressor (n, J, P), the torque the model leaves out and the torque
    (n, J) [N·m],
    through the replay's own causal filters (the inverse-dynamics residual, eq. 7–8, is
    linear in θ: the load π changes it by Y B π), without the filters' first
    :data:`SETTLE_PERIODS` periods of the derivative cut-off; None when the stretch is too
    short."""
    from ..model.causal import Carry
    from ..model.residual import ResidualOptions, residual_chunk

    rc = cfg.residual
    skip = int(np.ceil(SETTLE_PERIODS * fs / rc.derivative_cutoff_hz))
    if q.shape[0] < skip + MIN_ROWS:
        return None
    res = residual_chunk(model, q, tau, 1.0 / fs, ResidualOptions(
        cutoff_hz=rc.derivative_cutoff_hz, filter_torque=rc.filter_torque,
        generator="inverse_dynamics"), Carry())
    y = model.regressor(res.q_f[skip:], res.qd[skip:], res.qdd[skip:])
    # r = τ̂ − τ: the torque beyond the model is −r
    return y, -np.asarray(res.r[skip:]), np.asarray(res.tau_used[skip:])


def _left_out(keep: np.ndarray, fs: float) -> str:
    """How much of a stretch :func:`impactcli.model.payload.weigh_trimmed` left out, and
    where: "0.17 s of its rows left out, all within the first 0.2 s weighed"."""
    out = np.flatnonzero(~keep)
    return (f"{out.size / fs:.2g} s of its rows left out, all within the first "
            f"{(out[-1] + 1) / fs:.2g} s weighed")


#: The derivative filter's start is left out for this many periods of its cut-off.
SETTLE_PERIODS = 5.0
#: Samples the weighed stretch needs at least beyond that.
MIN_ROWS = 100


def _calibration(model: RigidModel) -> tuple[str | None, dict[str, float]]:
    rec = (model.fit or {}).get("payloads")
    if not rec:
        return None, {}
    return rec["relative_to"], {e["log"]: float(e["values"]["m"]) for e in rec["logs"]}


def _whose(rel: str | None) -> str:
    return "" if rel is None else f" ({rel}'s)"


def _calibrated_with(cal: dict[str, float]) -> str:
    if len(cal) < 2:
        return ""
    return "; calibrated with " + ", ".join(f"{m:+.3g} kg ({log})" for log, m in cal.items())


def beyond_calibrated(cal: dict[str, float], mass_kg: float, se_kg: float) -> bool:
    """A load [kg, beyond the model's] that no calibration log carried (``cal``: their
    masses beyond the model's; none: the model's own, 0): beyond every one by
    :data:`~impactcli.model.payload.WEIGH_SIGMAS` standard errors."""
    loads = list(cal.values()) or [0.0]
    tol = payload.WEIGH_SIGMAS * se_kg
    return not min(loads) - tol <= mass_kg <= max(loads) + tol


def _model_error(model: RigidModel) -> np.ndarray | None:
    """(J,) the model's own held-back RMS error per joint [N·m] (its fit's when nothing was
    held back), None when the model records neither."""
    joints = ((model.fit or {}).get("joints") or {})
    part = joints.get("holdout") or joints.get("fit")
    if not part:
        return None
    try:
        return np.array([float(part[j]["rms_nm"]) for j in model.joint_names])
    except (KeyError, TypeError, ValueError):
        return None


def load_basis(plan: Any) -> tuple[np.ndarray, tuple[str, ...]] | None:
    """The payload basis (B, names) of a replay whose model can weigh a payload and whose
    residual can carry it — kinematics, and every joint on ``inverse_dynamics`` (the tool's
    own model's eq. 7–8; the observer's state holds the old load) or on a controller's
    channel corrected by that model (:func:`weighable`) — else None."""
    model = plan.model
    if model is None or not weighable(plan.choices, plan.cfg.residual.logged_correction,
                                      ("inverse_dynamics",)):
        return None
    return payload.basis(model.kind, model.joint_names, model.structure)


#: What each generator's residual is, as the note on an unwatched replay says it.
_RESIDUAL_OF = {"logged_external": "the controller's external-torque estimate taken plain, "
                                   "with no model of the tool's to carry a load",
                "logged_model": "the log's torque less the controller's model torque taken "
                                "plain, with no model of the tool's to carry a load",
                "momentum_observer": "the momentum observer's, whose state holds the old load "
                                     "(the load a log starts with is weighed; a change is "
                                     "not carried)"}


def unwatched_reason(plan: Any) -> str | None:
    """Why a replay's payload changes are not looked for (:func:`load_basis` is None), in
    words; None when they are."""
    if load_basis(plan) is not None:
        return None
    correct = plan.cfg.residual.logged_correction
    other = [c for c in plan.choices if not weighable((c,), correct, ("inverse_dynamics",))]
    if other:
        gens = sorted({c.generator for c in other})
        whose = ", ".join(c.joint for c in other) if len(other) < len(plan.choices) \
            else "every joint"
        mend = ("calibrate with residual.logged_correction = true (the default), or with "
                "--generator inverse_dynamics" if any(c.generator in LOGGED for c in other)
                else "calibrate with --generator inverse_dynamics")
        return (f"the residual of {whose} is {' and '.join(_RESIDUAL_OF.get(g, g) for g in gens)}"
                f" ({mend}, and a robot description with kinematics, to weigh them)")
    kind = "none" if plan.model is None else plan.model.kind
    return (f"the model (kind {kind}) has no kinematics to weigh a load with (a robot "
            "description with planar or URDF kinematics gives them)")


def unweighed_reason(plan: Any) -> str | None:
    """Why a replay weighs no load at all — neither the one the log starts with
    (:func:`weigh_start`) nor its changes — in words (:func:`unwatched_reason`); None when
    it weighs one (the momentum observer weighs the start's but watches no change: the
    replay's warning on a lasting load says that)."""
    model = plan.model
    if (model is not None and weighable(plan.choices, plan.cfg.residual.logged_correction)
            and payload.basis(model.kind, model.joint_names, model.structure) is not None):
        return None
    return unwatched_reason(plan)


def weighs_loads(plan: Any) -> bool:
    """Whether a replay's model can weigh a payload (:func:`load_basis`)."""
    return load_basis(plan) is not None


def monitor_for(plan: Any, given: dict[str, np.ndarray] | None,
                sample_rate_hz: float) -> Any:
    """The payload-change monitor of a replay (:class:`~impactcli.detect.payload_change.
    PayloadMonitor`), None where it cannot run: no thresholds calibrated, or a model that
    cannot weigh a load (:func:`weighs_loads`)."""
    from ..detect.incidents import settle_s
    from ..detect.payload_change import PayloadMonitor

    model, cfg = plan.model, plan.cfg
    bb = load_basis(plan)
    if given is None or bb is None:
        return None
    start = plan.start_load
    used = start if start is not None and start.verdict == "used" else None
    pi0 = start_pi(model, bb[1], used)
    return PayloadMonitor(
        model, bb[0], bb[1], np.asarray(given["static_loading"], dtype=np.float64),
        sample_rate_hz, cfg.residual.derivative_cutoff_hz, cfg.static_loading.cutoff_hz,
        cfg.static_loading.order, float(cfg.warmup.min_s),
        settle_s(cfg.static_loading.cutoff_hz, cfg.adaptive.n2_s),
        payload.reach_m(model), base_kg=float(pi0[bb[1].index("m")]),
        known=known_loads(model, bb[1], pi0), merge_gap_s=float(cfg.events.merge_gap_s),
        start_weighed=start is not None and start.verdict in ("used", "same"),
        base_se_kg=(float(used.mass_se_kg or 0.0)
                    if used is not None and used.as_log is None else 0.0))


def start_pi(model: RigidModel, names: tuple[str, ...], start: StartLoad | None,
             ) -> np.ndarray:
    """The load π the replay's model carries beyond the config's: a used start load's —
    its calibration log's fit (``as_log``) or the weighed one — else none (zeros)."""
    if start is None:
        return np.zeros(len(names))
    fitted = None if start.as_log is None else payload.log_payload(model, start.as_log)
    return fitted if fitted is not None else np.array([start.values[n] for n in names])


def known_loads(model: RigidModel, names: tuple[str, ...], pi0: np.ndarray,
                ) -> tuple[tuple[str, np.ndarray], ...]:
    """The loads the calibration logs carried — each (log, π) relative to the replay's
    model, which carries ``pi0`` beyond the config's (:func:`start_pi`) — or, for a model
    fitted with one load, that load (:data:`OWN_LOAD`, π = 0 beyond the config's)."""
    cal = payload.calibration_loads(model, names)
    if not cal:
        return ((OWN_LOAD, -pi0),)
    return tuple((log, pi - pi0) for log, pi in cal)


def unseen_spans(model: RigidModel | None, start: StartLoad | None, changes: Any,
                 t_end: float) -> list[tuple[float, float, float]]:
    """The stretches where the arm carried a load no calibration log carried
    (:func:`beyond_calibrated`, the test of the start's and the changes' warnings): each
    (from [s], to [s], the load beyond the model's [kg]) — from the log's start while it
    carries such a start load, from a payload change's onset to the next one's (or
    ``t_end``) while the load after it is such a load. The thresholds' false-alarm rate was
    not measured there."""
    if model is None:
        return []
    _, cal = _calibration(model)
    marks: list[tuple[float, float | None]] = []  # (from, its load when unseen)
    if start is not None and start.verdict == "used" and start.as_log is None and \
            start.mass_kg is not None and beyond_calibrated(cal, start.mass_kg,
                                                            float(start.mass_se_kg or 0.0)):
        marks.append((0.0, float(start.mass_kg)))
    for c in changes or ():
        marks.append((float(c.t_start), float(c.mass_after_kg) if beyond_calibrated(
            cal, c.mass_after_kg, c.mass_se_kg) else None))
    if not marks:
        return []
    ends = [t for t, _ in marks[1:]] + [t_end]
    return [(t, z, kg) for (t, kg), z in zip(marks, ends, strict=True) if kg is not None]


def mark_unseen(incidents: list[Any], spans: list[tuple[float, float, float]]) -> list[Any]:
    """The incidents (or lasting loads) that start within one of :func:`unseen_spans`, with
    its load (``unseen_load_kg``); the others as they are."""
    if not spans:
        return incidents
    return [next((dataclasses.replace(i, unseen_load_kg=kg) for a, z, kg in spans
                  if a <= i.t_start < z), i) for i in incidents]


def start_unknown(changes: list[Any], start: StartLoad | None) -> list[Any]:
    """The payload changes, marked ``start_unknown`` when the log's start could not weigh
    the load it started with (verdict ``unsupported``) and the change is most likely that
    load, not a pick: one found on an alarm already on when the watch began
    (``at_watch_start``), or the first change, a gain, with its onset within as long again
    as the stretch weighed after it, whose mass is the one the start's weighing found in
    part (``mass_kg`` of a start that a steady load explained only partly: within
    :data:`~impactcli.detect.payload_finding.SHORTFALL` of it or three standard errors) —
    a load carried from the first sample whose torque the motion grew past the thresholds
    (a trial: 0.5 kg from the start of the heavy arm's run, weighed +0.471 kg in part, then
    "picked" at 3.944 s as +0.503 kg)."""
    if start is None or start.verdict != "unsupported":
        return changes

    def same_as_start(k: int, c: Any) -> bool:
        if k != 0 or start.mass_kg is None or not c.mass_kg > 0:
            return False
        if c.t_start - start.seconds > start.seconds:
            return False
        se = float(np.hypot(c.mass_se_kg, start.mass_se_kg or 0.0))
        return abs(c.mass_kg - start.mass_kg) <= max(SHORTFALL * abs(c.mass_kg), 3.0 * se)

    return [dataclasses.replace(c, start_unknown=True)
            if c.at_watch_start or same_as_start(k, c) else c
            for k, c in enumerate(changes)]


def unseen_loads(where: str, model: RigidModel | None, changes: Any) -> str | None:
    """The warning when a payload change left the arm carrying a load no calibration log
    carried (beyond every one by three standard errors; ``mass_after_kg`` counts the load
    the log started with), else None: the thresholds' false-alarm rate was not measured
    with it."""
    if model is None or not changes:
        return None
    _, cal = _calibration(model)
    out = [c for c in changes if beyond_calibrated(cal, c.mass_after_kg, c.mass_se_kg)]
    if not out:
        return None
    what = ", ".join(f"{c.mass_after_kg:+.3g} kg from {c.t_start:.3f} s (classified at "
                     f"{c.t_classified:.3f} s)" for c in out)
    return (f"{where}: after its payload changes the arm carried loads no calibration log "
            f"carried ({what}, beyond the model's load): the thresholds' false-alarm rate "
            "was not measured with them (a load unlike theirs brings errors the rigid "
            "model was not calibrated with; incidents while carrying them may be such "
            "errors): "
            "calibrate with a log that carries each load")


def load_motion(where: str, plan: Any, envelope: Any, incidents: list[Any],
                start_index: int, changes: Any, t_end: float) -> list[Any]:
    """The incidents marked where the arm carried a calibration log's load on motion no
    calibration log with that load covered (a load :func:`unseen_spans` finds no calibration
    log carried is none's) (:func:`impactcli.detect.load_motion.mark_load_motion`: the
    load the log starts with, when its weighing used one, and after each payload change
    (``changes``) up to ``t_end``; ``envelope``: the
    :class:`~impactcli.detect.envelope.EnvelopeCheck` with its ``loads``, finished from
    ``start_index``, the warm-up's end), warned of once with their count."""
    from ..detect.load_motion import carried_spans, mark_load_motion

    start = getattr(plan, "start_load", None)
    carried = ((start.as_log, start.mass_kg) if start is not None and start.verdict == "used"
               else (None, None))
    masses = {e["log"]: float(e["mass_kg"]) for e, _ in envelope.loads}
    _, cal = _calibration(plan.model) if plan.model is not None else (None, {})
    unseen = {t for t, _, _ in unseen_spans(plan.model, start, changes, t_end)}
    spans = [s for s in carried_spans(carried, changes, t_end, masses,
                                      [m for log, m in cal.items() if log not in masses])
             if s[0] not in unseen]  # a load no calibration log carried is not one's
    if not spans:
        return incidents
    shares = {e["log"]: check.finish(start_index) for e, check in envelope.loads}
    marked = mark_load_motion(incidents, spans, shares)
    n = sum(1 for i in marked if i.load_motion is not None)
    if n:
        logs = "; ".join(sorted({i.load_motion["log"] + "'s" for i in marked
                                 if i.load_motion is not None}))
        warnings.warn(f"{where}: {n} counted incident(s) came while the arm carried a "
                      f"calibration log's load ({logs}) on motion no calibration log with "
                      "that load covered: the thresholds' false-alarm rate was measured for "
                      "that load on those logs' motion only (load_motion in the timeline)",
                      ImpactWarning, stacklevel=2)
    return marked
