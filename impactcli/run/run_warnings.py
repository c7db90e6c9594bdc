"""The warnings of a run: each one's text in one place, and how a run gathers them.

A run's warnings end up in its timeline (``warnings``), so their texts and their order are
part of the output: :class:`CaughtWarnings` records them in the order raised, lets the
replay move a stretch of them (a warning about the whole log, known only once the replay
is over, goes before the replay's own), and gives them de-duplicated. Warnings of other
categories are not ours to swallow: they are raised again.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from types import TracebackType
from typing import Any

import numpy as np

from ..clock import GAP_FACTOR
from ..config import PLAIN_FORMULATION, DetectorConfig
from ..detect.events import LONG_EVENT_S
from ..detect.force import force_mark
from ..detect.thresholds import (
    UNCALIBRATED_BLOCK_S,
    UNCALIBRATED_MARGIN,
    UNCALIBRATED_QUANTILE,
    self_set_text,
)
from ..detect.warmup import Warmup
from ..errors import ImpactError, ImpactWarning
from ..logs.defects import MAX_ACCEL_RAD_S2
from ..logs.screen import LeftOut
from ..types import DETECTORS, Event, RobotDescription

#: Events starting this long after a time gap are named in a warning [s].
GAP_SETTLE_S = 0.5


class CaughtWarnings:
    """Every :class:`~impactcli.errors.ImpactWarning` raised inside the ``with`` block,
    recorded in order (each raised, not filtered away); other warnings as the filters say.
    """

    def __init__(self) -> None:
        self._cm = warnings.catch_warnings(record=True)
        self.caught: list[warnings.WarningMessage] = []

    def __enter__(self) -> CaughtWarnings:
        got = self._cm.__enter__()
        assert got is not None
        self.caught = got
        warnings.simplefilter("always", ImpactWarning)
        return self

    def __exit__(self, kind: type[BaseException] | None, err: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._cm.__exit__(kind, err, tb)

    def mark(self) -> int:
        """Where the next warning will be recorded (for :meth:`cut`)."""
        return len(self.caught)

    def cut(self, mark: int) -> list[warnings.WarningMessage]:
        """The warnings recorded since ``mark``, taken out (:meth:`paste` puts them back
        later, after the warnings raised meanwhile)."""
        out = self.caught[mark:]
        del self.caught[mark:]
        return out

    def paste(self, cut: list[warnings.WarningMessage]) -> None:
        """Put back what :meth:`cut` took out, after the warnings recorded since."""
        self.caught.extend(cut)

    def messages(self) -> tuple[str, ...]:
        """The ImpactWarnings' texts, each once, in the order first raised."""
        return tuple(dict.fromkeys(str(w.message) for w in self.caught
                                   if issubclass(w.category, ImpactWarning)))

    def raise_again(self, impact: bool = False) -> None:
        """Raise the recorded warnings again, outside the block: the other categories
        (``impact``: the ImpactWarnings too, every one, in order)."""
        for w in self.caught:
            if impact or not issubclass(w.category, ImpactWarning):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def warn_uncalibrated(where: str, weighs_loads: bool = False, blocks: int = 0) -> None:
    """The warning of a run whose thresholds come from the log itself; ``weighs_loads``:
    its model could weigh a payload (kinematics, the tool's own residual), which a config
    would have it tell from a contact (docs/method.md §5c) and this run does not;
    ``blocks``: how many blocks the quantile was taken over — on a short log it is one of
    its few largest block maxima, so an event that fills that many blocks sets the
    thresholds itself (a real UR arm's braking, 11 blocks, went unfound)."""
    loads = (", and a load picked or placed mid-log may show as an incident (payload "
             "changes are told from contacts only against a config's model and thresholds, "
             "not ones taken from a log that may carry the load)" if weighs_loads else "")
    if short := self_set_text(blocks):  # an event of a few blocks sets its own thresholds
        loads += f"; {short}"
    warnings.warn(
        f"{where}: uncalibrated run — thresholds set from this log's own "
        f"statistics ({UNCALIBRATED_MARGIN:g} × the {UNCALIBRATED_QUANTILE:g}-quantile of "
        f"its {UNCALIBRATED_BLOCK_S:g} s maxima after warm-up): only contacts that stand "
        f"out well above its motion are found{loads}; calibrate on collision-free logs "
        "(impactcli calibrate) for sensitivity and a replay the robot could have run",
        ImpactWarning, stacklevel=3,
    )


def warn_unwatched_loads(where: str, reason: str, start_weighed: bool) -> None:
    """The warning of a calibrated replay with a lasting load that does not look for
    payload changes (:func:`impactcli.run.loads.unwatched_reason` says why), nor, unless
    ``start_weighed``, weigh the load it starts with: the lasting load may be such a load
    (docs/method.md §5c)."""
    what, loads = (("payload changes are not looked for", "picked mid-log") if start_weighed
                   else ("payloads are not weighed", "carried from the start or picked "
                         "mid-log"))
    warnings.warn(f"{where}: {what} — {reason}: its lasting loads may be a load {loads}",
                  ImpactWarning, stacklevel=3)


def warn_formulation(where: str, config_where: str, calibrated_on: str, runs: str) -> None:
    """The warning of a config calibrated on another formulation of the adaptive evaluator
    than the one its settings run (:attr:`impactcli.config.AdaptiveConfig.formulation`)."""
    mend = ("calibrate again (impactcli calibrate), or set adaptive.regularization = 0 in "
            "the config to replay the statistic its thresholds were calibrated on"
            if calibrated_on == PLAIN_FORMULATION else "calibrate again (impactcli calibrate)")
    was = (f"{calibrated_on!r} (plain eq. 39: a config without a record, made before "
           "2026-11-28)" if calibrated_on == PLAIN_FORMULATION else repr(calibrated_on))
    warnings.warn(
        f"{where}: its config ({config_where}) was calibrated on the adaptive evaluator's "
        f"formulation {was} but runs {runs!r}, whose statistic differs, so its adaptive "
        f"thresholds (v_stat) may not fit: {mend}",
        ImpactWarning, stacklevel=3,
    )


def warn_settings(where: str, config_where: str, edited: Sequence[str] = ()) -> None:
    """The warning of a calibrated config whose detector settings, or thresholds
    (``edited``: :func:`impactcli.config.thresholds_edited`), were edited after
    ``calibrate`` (:func:`impactcli.config.settings_changed`)."""
    what = (f"thresholds other than those its calibration set ({', '.join(edited)}: edited "
            "after calibrate): their stated false-alarm rate was measured for the others "
            "and does not apply"
            if edited else
            "detector settings other than those its thresholds were calibrated with "
            "(calibration.settings_sha256 does not match: a setting was edited after "
            "calibrate): the thresholds were not set for them, and their stated false-alarm "
            "rate does not apply")
    warnings.warn(f"{where}: its config ({config_where}) has {what}; calibrate again "
                  "(impactcli calibrate)", ImpactWarning, stacklevel=3)


#: What each torque source is, for the warnings that name one (docs/formats.md).
TORQUE_SOURCE_SIDE = {"torque": ".torque (the joint torque: a sensor's, link side, or the "
                                "drive's, motor side)",
                      "current": ".current (motor side, through the gear ratio and torque "
                                 "constant)"}


def warn_torque_source(where: str, config_where: str, used: str, calibrated: str,
                       n_logs: int) -> None:
    """The warning of a log whose torque is read from another channel (``used``) than the
    one all ``n_logs`` calibration logs of its config were read from (``calibrated``): the
    thresholds were set on another signal."""
    logs = {1: "its calibration log", 2: "both its calibration logs"}.get(
        n_logs, f"all {n_logs} of its calibration logs")
    warnings.warn(
        f"{where}: its torque is read from {TORQUE_SOURCE_SIDE[used]}, but its config "
        f"({config_where}) was calibrated on {TORQUE_SOURCE_SIDE[calibrated]} in {logs}: the "
        "thresholds were set on another signal and their stated false-alarm rate does not "
        "apply; give "
        f"--torque-source {calibrated} if the log has it, or calibrate on logs read as this "
        "one is", ImpactWarning, stacklevel=3)


def warn_mixed_torque_sources(sources: Sequence[tuple[str, str]]) -> None:
    """The warning of calibration logs (``(path, torque source)``) whose torques were read
    from different channels: one threshold per joint over two signals."""
    kinds = sorted({s for _, s in sources})
    if len(kinds) < 2:
        return
    said = "; ".join(f"{TORQUE_SOURCE_SIDE[k].split(' ')[0]} in "
                     + ", ".join(p for p, s in sources if s == k) for k in kinds)
    warnings.warn(
        f"the calibration logs' torques are read from different channels ({said}): one "
        "threshold per joint is set over two signals; give --torque-source to read them "
        "all from one", ImpactWarning, stacklevel=3)


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


def warn_warmup(where: str, wu: Warmup, times_s: Sequence[float], joints: tuple[str, ...],
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


def warn_late_warmup(where: str, late: Sequence[Any], least: float, end_s: float,
                     duration_s: float) -> None:
    """Warn of the incidents in a warm-up that ran on past its least length ``least`` [s]
    (:func:`impactcli.detect.warmup.past_least`): not counted, and not judged — the
    evaluator's prediction error had not settled, so no figure of the run speaks for them;
    a gate says it could not judge them."""
    if not late:
        return
    def said(x: Any) -> str:
        return f"{x.t_start:.3f} s" + ("" if x.force_n is None else
                                       f" {force_mark(x)}{x.force_n:.3g} N")

    listed = ", ".join(said(x) for x in late[:5])
    more = f" and {len(late) - 5} more" if len(late) > 5 else ""
    forced = [x for x in late if x.force_n is not None]
    top = max(forced, key=lambda x: float(x.force_n)) if forced else None
    if top is not None and all(top is not x for x in late[:5]):  # the largest, said
        more += f"; the largest at {said(top)}"
    warnings.warn(
        f"{where}: the warm-up ran to {end_s:.1f} s ({100 * end_s / max(duration_s, 1e-9):.0f} "
        f"% of the log; its least is {least:g} s) while the adaptive filter's prediction "
        f"error settled: {len(late)} alarm(s) in it after {least:g} s are not counted and not "
        f"judged (at {listed}{more}) — a contact there may be among them; a gate exits 5",
        ImpactWarning, stacklevel=3)


def warn_events_after_gaps(where: str, after_s: np.ndarray, events: Sequence[Event]) -> None:
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


def warn_defect_incidents(where: str, defects: Sequence[Any], incidents: Sequence[Any],
                          settle_s: float, memory_s: float | None = None) -> None:
    """Warn of the incidents that start at a data defect (``data_defect``): not counted as
    contacts; and of the position jumps (a recording splice, a glitch) whether or not an
    incident follows. ``memory_s``: the adaptive evaluator's memory [s], within which its
    alarms alone are the defect's (said in seconds: a new user read "within 0.56 s" beside
    incidents 4.5 s after a jump)."""
    jumps = [d for d in defects if d.kind == "jump"]
    if jumps:
        d = jumps[0]
        warnings.warn(
            f"{where}: the positions jump at {len(jumps)} sample(s) further than the "
            f"samples around them move (the first from {d.t_start:.3f} to {d.t_end:.3f} s: "
            f"{', '.join(d.joints)}, up to {d.size:.3g} rad): a recording splice or a "
            f"glitch, or a jolt harder than an arm's joint moves (over {MAX_ACCEL_RAD_S2:g} "
            "rad/s² between samples)", ImpactWarning, stacklevel=3)
    marked = [i for i in incidents if getattr(i, "data_defect", None) is not None]
    if marked:
        listed = ", ".join(f"{i.t_start:.3f} s ({i.data_defect['kind']})" for i in marked[:5])
        more = f" and {len(marked) - 5} more" if len(marked) > 5 else ""
        warnings.warn(
            f"{where}: {len(marked)} incident(s) start at a data defect or within "
            f"{settle_s:.2g} s after it (the adaptive detector's alone: within its memory"
            + ("" if memory_s is None else f", {memory_s:.2g} s") + "; "
            f"{listed}{more}): marked data_defect in the timeline and not counted as "
            "contacts", ImpactWarning, stacklevel=3)


def warn_implausible_forces(where: str, findings: Sequence[Any]) -> None:
    """Warn once, naming the largest, when estimated forces (incidents' or lasting loads')
    are beyond what the arm can exert (``force_plausible`` false: docs/incidents.md)."""
    bad = [x for x in findings if x.force_plausible is False and x.force_n is not None]
    if not bad:
        return
    x = max(bad, key=lambda y: y.force_n)
    more = f" ({len(bad)} estimates are)" if len(bad) > 1 else ""
    link = f"link {x.link}" if x.link is not None else "an unknown link"
    warnings.warn(
        f"{where}: estimated {x.force_n:,.0f} N at {link} ({x.t_start:.3f} s): beyond what "
        f"the arm can exert{more}; positions in degrees? a wrong gear ratio or torque "
        "constant?", ImpactWarning, stacklevel=3)


def warn_long_events(where: str, events: Sequence[Any]) -> None:
    """Warn about product events after warm-up lasting LONG_EVENT_S or more."""
    long_ev = [e for e in events if not e.in_warmup and e.detector != "static_baseline"
               and e.t_end - e.t_start >= LONG_EVENT_S]
    if long_ev:
        e = max(long_ev, key=lambda x: x.t_end - x.t_start)
        warnings.warn(
            f"{where}: {len(long_ev)} alarm(s) last {LONG_EVENT_S:g} s or more (the "
            f"longest: {e.detector} {e.t_start:.1f}–{e.t_end:.1f} s): a lasting load, or a "
            "model that no longer fits this log (an unknown payload, a changed robot)",
            ImpactWarning, stacklevel=3)


def warn_outside_envelope(where: str, text: str, outside: int, touching: int,
                          posture: str = "", note: str = "") -> None:
    """The log moved outside the calibration's motion envelope after warm-up
    (:func:`impactcli.detect.envelope.outside_share_text`): the thresholds' stated
    false-alarm rate does not hold there (docs/validation.md); ``touching``: the counted
    incidents that touch it; ``posture``: its poses left
    the calibration's (:func:`impactcli.detect.envelope.posture_text`), "" if not;
    ``note``: what the check could not compare (said here when nothing was outside: the
    outside's text carries it otherwise)."""
    if outside > 0:
        tail = (f"; {touching} counted incident(s) touch it (outside_envelope in the "
                "timeline)"
                if touching else "")
        warnings.warn(f"{where}: {text}: the thresholds' stated false-alarm rate was not "
                      f"measured on such motion{tail}", ImpactWarning, stacklevel=2)
    elif note:
        warnings.warn(f"{where}: motion envelope: {note} (motion_envelope.note in the "
                      "timeline)", ImpactWarning, stacklevel=2)
    if posture:
        warnings.warn(f"{where}: {posture} (motion_envelope.posture_outside in the timeline)",
                      ImpactWarning, stacklevel=2)


def warn_beyond_effort(cfg: DetectorConfig, joints: Sequence[str],
                       robot: RobotDescription | None = None, where: str | None = None,
                       ) -> None:
    """One warning naming each threshold above its joint's effort limit (a URDF's ``<limit
    effort>``: the model's, else the robot description's when its kinematics are a URDF):
    a contact would have to load that joint beyond what its motor exerts to be seen by that
    detector there — a joint checked in name only. ``where``: None at calibrate (the
    calibration logs' residual is why), else the log a detect run replays with ``cfg``."""
    from ..detect.incident_builder import effort_limits, urdf_efforts
    from ..model.identification import urdf_source

    effort = urdf_efforts(cfg.model, tuple(joints))
    kin = None if robot is None else robot.kinematics
    if (robot is not None and kin is not None and kin.get("type") == "urdf"
            and not np.isfinite(effort).any()):
        try:
            xml = urdf_source(kin)[0]
        except (ImpactError, OSError):
            xml = None
        if xml:
            effort = effort_limits(xml, dict(robot.joint_map or {}), tuple(joints))
    over = [f"{j} {d} {cfg.thresholds.of(d)[j]:.4g} > {effort[k]:.4g}"
            for k, j in enumerate(joints) if np.isfinite(effort[k])
            for d in DETECTORS if cfg.thresholds.of(d).get(j, 0.0) > effort[k]]
    if not over:
        return
    said = (f"thresholds above their joint's effort limit (the URDF's, N·m): {', '.join(over)}"
            ": a contact would have to load the joint beyond what its motor exerts to be "
            "seen there")
    if where is None:
        said += (" — the calibration logs' residual on it is that large (a wrong unit or "
                 "torque constant, a model that does not fit them, or too little free motion "
                 "for the rate asked)")
    else:
        said = (f"{where}: the config's {said}: that detector checks the joint in name only "
                "(the detection floor's figure on it says how large a contact it needs)")
    warnings.warn(said, ImpactWarning, stacklevel=3)


#: A joint left out of detection whose positions span more than this [rad] moved in the
#: log: it is named as not checked (terminal, verdict, motion_envelope.unchecked).
MOVED_RAD = 0.05


def moved_unchecked(left_out: Sequence[LeftOut], names: Sequence[str],
                    position_range: tuple[np.ndarray, np.ndarray] | None,
                    ) -> list[dict[str, Any]]:
    """The joints left out of detection as timeline items, each with ``travel_rad`` when
    its positions in the log span more than :data:`MOVED_RAD`."""
    out = []
    for x in left_out:
        d: dict[str, Any] = x.to_dict()
        if position_range is not None and x.name in names:
            k = list(names).index(x.name)
            travel = float(position_range[1][k] - position_range[0][k])
            if math.isfinite(travel) and travel > MOVED_RAD:
                d["travel_rad"] = travel
        out.append(d)
    return out


def unchecked_message(where: str, moved: Sequence[dict[str, Any]]) -> str:
    """The warning naming the joints that moved but were not checked."""
    each = "; ".join(f"{x['name']} (travels {x['travel_rad']:.3g} rad; {x['reason']})"
                     for x in moved)
    return (f"{where}: joint(s) moved but were not checked — no contact on them or the "
            f"links they carry alone can be seen: {each}")
