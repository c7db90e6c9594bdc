"""Caveats: plain-language warnings an auditor reads before trusting the numbers (code,
text) — an uncalibrated or weak calibration, a model from the log itself or fitting it
poorly, a missing reference, the warm-up, an unfiltered torque, a filter blind to slow
contacts, a long event, repairs of the input.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ...config import settings_changed
from ...detect.events import LONG_EVENT_S
from ...detect.tail import capped_detectors, left_out_above, per_hour_text
from ...detect.thresholds import (
    MAX_MARGIN,
    UNCALIBRATED_BLOCK_S,
    UNCALIBRATED_MARGIN,
    UNCALIBRATED_QUANTILE,
)
from ...model.generators import LOGGED
from ...model.gravity import CLOSE_FACTOR
from ...types import DetectionResult
from .common import LOW_GAIN, POOR_FIT, share


def _poor_fit(result: DetectionResult) -> list[tuple[str, float, str]]:
    """Joints whose model error (hold-out part when there is one, else the fit) exceeds
    :data:`POOR_FIT` of the torque RMS: (joint, ratio, where) — of the joints whose
    residual is the tool's own model's: on a controller's channel (``logged_*``) the model
    fits only a correction to it, and its error against that small target says nothing of
    the measured torque (a trial read "56 % of the torque RMS" for a 0.036 N·m error)."""
    per = ((result.model or {}).get("fit") or {}).get("joints")
    if not isinstance(per, dict):
        return []
    part, where = (per.get("holdout"), " on held-out data") if per.get("holdout") else \
        (per.get("fit"), "")
    out = []
    for j in result.log.joint_names:
        if (result.generators.get(j) or {}).get("generator") in LOGGED:
            continue  # its residual is the controller's: the model fits a correction to it
        rel = ((part or {}).get(j) or {}).get("rms_rel_torque_rms")
        if isinstance(rel, int | float) and rel > POOR_FIT:
            out.append((j, float(rel), where))
    return out


#: A counted event of adaptive or static_loading at least this long gets a caveat [s].


def _left_out(rate: dict[str, Any]) -> list[dict[str, str]]:
    """``rate-left-out``: the calibration logs that, left out, false-alarmed above the bound
    the others' fit gave (:func:`~impactcli.detect.tail.left_out_above`), none when none."""
    above = left_out_above(rate)
    if not above:
        return []
    each = "; ".join(f"{Path(x['log']).name} at {x['observed_per_hour']:.3g} per hour "
                     f"(at least {x['low']:.3g}) against {x['upper_per_hour']:.3g}"
                     for x in above)
    return [{"code": "rate-left-out", "text": (
        f"Left out of the calibration in turn, {len(above)} of its logs false-alarmed above "
        f"the bound the other logs' fit gave ({each}): what such a log holds — its motion, "
        "or a load the model fits worse with that motion — is in no other calibration log, "
        "so the predicted rate rests on motion the logs do not share, and a log unlike "
        "them may false-alarm far above it. Calibrate on more of the robot's free motion, "
        "of each kind it runs.")}]


def rate_caveats(calib: dict[str, Any]) -> list[dict[str, str]]:
    """The false-alarm rate the thresholds were set for, when the free motion does not
    support it (``rate-not-supported``: what it supports and how much more it needs), and
    that the rate holds only for motion like the calibration's (``rate-envelope``), and the
    calibration logs that false-alarmed above the others' bound when left out
    (``rate-left-out``). Without
    R (leave-one-out thresholds): one ``rate-envelope`` with the rate they are predicted to
    give and how to ask for one."""
    rate = calib.get("false_alarm_rate")
    if not isinstance(rate, dict):
        return []
    out = _left_out(rate)
    r, conf = rate.get("per_hour"), rate.get("confidence")
    pct = "—" if conf is None else f"{100 * conf:.0f}"
    # the prediction a log left out contradicted: said first, as its own sentence
    unborne = ("Not borne out by leave-one-log-out: calibration logs left out false-alarmed "
               "above the others' bound (above). " if out else "")
    if r is None:  # leave-one-out thresholds: the rate they are predicted to give
        return [*out, {"code": "rate-envelope", "text": (
            f"{unborne}The thresholds were set by "
            f"{calib.get('margin_rule') or 'a margin rule'}, not "
            "for a false-alarm rate; on motion like the calibration logs' they are "
            f"predicted to give {per_hour_text(rate.get('predicted_per_hour', 0.0))} false "
            f"alarm(s) per hour, upper bound {per_hour_text(rate.get('upper_per_hour', 0.0))} "
            f"at {pct} % confidence "
            f"({rate.get('statement', '')}). For a rate you choose: calibrate "
            "--false-alarms-per-hour R. Where this log moves faster or accelerates harder "
            "than the calibration logs did, or moves slowly for longer (the motion envelope "
            "in the config), false alarms are not bounded by it.")}]
    if rate.get("supported") is False:
        widened = [f"{j}/{d}" for d, per in (rate.get("channels") or {}).items()
                   for j, c in per.items() if c.get("widened")]
        out.append({"code": "rate-not-supported", "text": (
            f"The thresholds were set for {r:g} false alarm(s) per hour, but the "
            f"{rate.get('free_minutes', 0.0):.1f} min of free motion they rest on do not "
            f"support it at {pct} % confidence: {rate.get('statement', '')}. "
            + (f"Widened beyond their fit: {', '.join(widened)}. " if widened else
               "The fits' own bounds were wider than the widening. ")
            + "The stated rate is not promised; calibrate on more of the robot's free motion.")})
    out.append({"code": "rate-envelope", "text": (
        f"{unborne}The false-alarm rate ({r:g} per hour asked; predicted "
        f"{per_hour_text(rate.get('predicted_per_hour', 0.0))}, upper bound "
        f"{per_hour_text(rate.get('upper_per_hour', 0.0))} at {pct} % confidence) holds for "
        "motion like "
        "the calibration logs': where this log moves faster or accelerates harder than they "
        "did, or moves slowly for longer (the motion envelope in the config), false alarms "
        "are not bounded by it.")})
    return out


def caveats(result: DetectionResult, tl: dict[str, Any]) -> list[dict[str, str]]:
    """Plain-language caveats an auditor must read before the numbers (code, text)."""
    out: list[dict[str, str]] = []
    cfg = result.config or {}
    calib = cfg.get("calibration") or {}
    if (not (result.robot or (result.model or {}).get("robot"))
            and (result.incidents or result.lasting_loads)):
        out.append({"code": "links-column-order",
                    "text": ("No robot description: the incidents' links are numbered in the "
                             "log's column order (joint k's link is k), which need not be the "
                             "arm's chain from its base; give --robot to number them along "
                             "it.")})
    load = getattr(result, "payload", None) or {}
    if load.get("verdict") in ("used", "unsupported"):
        out.append({"code": "start-load",
                    "text": (load["message"].split(": ", 1)[-1] + ".").replace("..", ".")})
    scale = getattr(result, "torque_scale", None) or {}
    order_only = scale.get("verdict") == "ok" and any(
        not 1.0 / CLOSE_FACTOR <= float(k) <= CLOSE_FACTOR
        for k in (scale.get("per_joint") or {}).values())
    if order_only and (result.incidents or result.lasting_loads):
        out.append({"code": "torque-scale",
                    "text": ("The forces are as good as the log's torque scale against the "
                             "gravity torque of the robot description's masses: "
                             f"{(scale.get('message') or '').split(': ', 1)[-1]}.")})
    elif scale.get("verdict") != "ok" and (result.incidents or result.lasting_loads):
        why = (scale.get("message") or "").split(": ", 1)[-1] or (
            "no robot description with masses (--robot) predicts the gravity torque to "
            "compare the log's torque with")
        out.append({"code": "torque-scale",
                    "text": ("The torques and forces are in the log's units, not checked "
                             f"against physics: {why}." if scale.get("verdict") != "warn"
                             else f"The log's torque scale looks wrong: {why}.")})
    if not result.calibrated:
        out.append(
            {
                "code": "uncalibrated",
                "text": (
                    "UNCALIBRATED: the thresholds were set from this log's own statistics "
                    f"({calib.get('margin_rule') or 'robust rule'}: {UNCALIBRATED_MARGIN:g} × the "
                    f"{UNCALIBRATED_QUANTILE:g}-quantile of its {UNCALIBRATED_BLOCK_S:g} s "
                    "maxima), not calibrated on separate collision-free logs. Only contacts "
                    "standing well above the log's own motion are found, and the events below "
                    "are not what the robot would have detected online; run `impactcli "
                    "calibrate` on collision-free logs and re-run with --config."
                ),
            }
        )
    elif calib.get("weak"):
        rule = calib.get("margin_rule") or "unknown rule"
        rated = "per_hour" in (calib.get("false_alarm_rate") or {})
        capped = capped_detectors(calib)
        single = rule == "fixed-single-log"
        if single or capped or not rated:  # else the rate's own caveat below says why
            why = ("the thresholds come from a single collision-free log with a fixed 1.5× "
                   "margin, not a leave-one-out margin over several logs." if single else
                   "the collision-free logs disagreed: the leave-one-out margin hit its cap "
                   f"of {MAX_MARGIN:g}× ({', '.join(capped) or 'some detector'}), so a log "
                   "like the most different one may still raise alarms.")
            out.append({"code": "weak-calibration",
                        "text": f"Weak calibration ({rule}): {why}"})
    if settings_changed(cfg):
        out.append({"code": "settings-changed", "text": (
            "The config's detector settings were edited after calibrate "
            "(calibration.settings_sha256 does not match them): its thresholds were not set "
            "for these settings, and no false-alarm rate stated here applies to them. "
            "Calibrate again.")})
    out += rate_caveats(calib)
    if result.model_source == "identified-from-log":
        out.append(
            {
                "code": "model-from-log",
                "text": (
                    "The rigid model was identified from this very log (an offline convenience): "
                    "its residual is smaller than a model made from other logs would give."
                ),
            }
        )
    poor = _poor_fit(result)
    if poor:
        out.append({"code": "model-poor-fit", "text": (
            "The rigid model explains the measured torque poorly on "
            + "; ".join(f"{j} (RMS error {100 * r:.0f} % of the torque RMS{where})"
                        for j, r, where in poor)
            + ": its residual carries that model error, so the thresholds there are high "
            "and small contacts can hide below them.")})
    unexcited = ((result.model or {}).get("fit") or {}).get("unexcited_parameters") or []
    if unexcited:
        out.append({"code": "model-unexcited", "text": (
            f"The log used for identification did not excite {len(unexcited)} model "
            f"parameter(s) ({', '.join(map(str, unexcited[:6]))}"
            + (", …" if len(unexcited) > 6 else "") + "); they were fixed at 0, so motions "
            "that excite them raise the residual.")})
    if result.reference_source == "measured":
        out.append(
            {
                "code": "reference-missing",
                "text": (
                    "No controller reference was logged: the adaptive detector's inputs (sign of "
                    "the reference velocity and the reference acceleration, Table I) were taken "
                    "from the causally filtered MEASURED position. A contact changes the measured "
                    "motion too, so the adaptive detector can partly absorb it."
                ),
            }
        )
    n_warm = sum(1 for e in result.events if e.in_warmup)
    n_inc = sum(1 for i in result.incidents if i.in_warmup)  # the figure the other lines give
    out.append(
        {
            "code": "warmup",
            "text": (
                f"Warm-up: the first {result.warmup_end_s:.3f} s (latest over joints"
                f"{share(result.warmup_end_s, result.log.duration_s)}) are the adaptive "
                "estimator's convergence; a contact in that interval may go undetected. "
                + (
                    f"{n_inc} incident(s) ({n_warm} event(s) of the three detectors, the "
                    "static baseline's among them) started in it: listed, not counted."
                    if n_warm
                    else "No alarm started in it."
                )
            ),
        }
    )
    if not result.torque_filtered:
        out.append(
            {
                "code": "torque-unfiltered",
                "text": (
                    "The measured torque was not passed through the estimate's causal filter: the "
                    "residual's high-frequency floor (and the thresholds) are higher than they"
                    " need be."
                ),
            }
        )
    fg = result.filter_gain or {}
    freqs = list(fg.get("frequencies_hz") or [])
    blind = []
    for joint in result.log.joint_names:
        gains = (fg.get("gain") or {}).get(joint) or []
        low = [
            (f, g)
            for f, g in zip(freqs, gains, strict=False)
            if f is not None and g is not None and f <= 10.0 and g < LOW_GAIN
        ]
        if low:
            f, g = low[-1]  # the highest such frequency
            blind.append(f"{joint} {100 * g:.0f} % at {f:g} Hz")
    if blind:
        out.append(
            {
                "code": "filter-blind",
                "text": (
                    "The adaptive filter G(z) passes little of slow signals ("
                    + "; ".join(blind)
                    + "): slowly building contacts vanish from its residual; only the"
                      " static-loading "
                    "detector covers them (README: the method as implemented)."
                ),
            }
        )
    long_ev = [e for e in result.events if not e.in_warmup
               and e.t_end - e.t_start >= LONG_EVENT_S and e.detector != "static_baseline"]
    if long_ev:
        e = max(long_ev, key=lambda x: x.t_end - x.t_start)
        out.append({
            "code": "long-event",
            "text": (
                f"{len(long_ev)} event(s) of the product's detectors last {LONG_EVENT_S:g} s or "
                f"more (the longest: {e.detector}, {e.t_start:.1f}–{e.t_end:.1f} s). A load "
                "that persists is either a real one (a clamp, a held object) or a model that "
                "does not fit this log (an unknown payload, a changed robot): if the robot "
                "changed, re-identify (`detect --config C --model-from-log`) or recalibrate."
            ),
        })
    for rep in tl["input"].get("repairs") or []:
        out.append({"code": "repair", "text": f"Input repaired while reading: {rep}"})
    return out

