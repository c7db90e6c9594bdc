"""``impactcli calibrate FREE_LOG... -o CONFIG``: thresholds from collision-free logs."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .options import (
    ROBOT_METAVAR,
    generator_option,
    handle_errors,
    log_read_options,
    robot_help,
)

if TYPE_CHECKING:
    from ..types import ReadOptions

if TYPE_CHECKING:
    from ..config import DetectorConfig


def threshold_lines(out: DetectorConfig) -> list[str]:
    """What calibrate prints after the model, read from the config it wrote: per joint its
    generator and thresholds; the rate's fit per joint and detector, what the free minutes
    support and the leave-one-log-out rows; the motion envelope."""
    c, th, gens = out.calibration, out.thresholds, out.residual.generators
    rate = c.false_alarm_rate
    asked = "per_hour" in (rate or {})
    head = "v0 margin" if asked else "margins (adaptive/loading/baseline)"
    lines = [f"{'joint':<16} {'generator':<17} {'v_stat':>9} {'vL':>9} {'v0':>9}   {head}"]
    dets = ("static_baseline",) if asked else ("adaptive", "static_loading", "static_baseline")
    for j in th.v_stat:
        m = [c.margins.get(d, {}).get(j) for d in dets]
        lines.append(f"{j:<16} {gens.get(j, '?'):<17} {th.v_stat[j]:>9.4f} {th.vL[j]:>9.4f} "
                     f"{th.v0[j]:>9.4f}   "
                     + " / ".join("—" if x is None else f"{x:.2f}" for x in m))
    if rate:
        lines += rate_lines(rate, c.margin_rule, _lone_loads(c.load_envelopes or ()))
    env = c.motion_envelope
    if env:
        from ..detect.envelope import MotionEnvelope

        src = {"position_ref": "reference", "position": "measured position"}
        lines.append(f"motion envelope ({src.get(env['source'], env['source'])}, "
                     f"{env['samples']} samples): a rate holds for motion inside it")
        lines += MotionEnvelope.from_dict(env).lines()
    return lines


def _lone_loads(entries: Any) -> dict[str, float]:
    """The calibration logs (file name → load beyond the model's [kg]) whose load differs
    from the model's enough to matter (``calibration.load_envelopes``) and from every other
    such log's by more than a quarter: a load no other calibration log carried."""
    kg = {Path(str(e["log"])).name: float(e["mass_kg"]) for e in entries}
    return {n: m for n, m in kg.items()
            if all(abs(m - o) > 0.25 * max(abs(m), abs(o)) for p, o in kg.items() if p != n)}


def rate_lines(rate: dict[str, Any], margin_rule: str = "leave-one-out",
               lone_loads: dict[str, float] | None = None) -> list[str]:
    """The rate's record as calibrate prints it: totals, one line per joint and detector
    (threshold, fit, predicted rate and bound), the support statement, notes, and the
    leave-one-log-out rows (``lone_loads``: :func:`_lone_loads`, whose left-out line names
    the load first)."""
    from ..detect.tail import minutes_text
    from ..detect.tail import per_hour_text as ph

    conf = float(rate["confidence"])
    pct = f"{100 * conf:.0f} %"
    asked = (f"asked {rate['per_hour']:g}" if "per_hour" in rate
             else f"not asked (thresholds by {margin_rule})")
    sup = rate.get("supported_per_hour")
    # a bound below what the free minutes support is the tail fits' extrapolation only
    beyond = ("" if sup is None or sup <= rate["upper_per_hour"] else
              f" by the tail fits alone — the free motion bounds no rate below {ph(sup)}, so "
              "neither is promised (below)")
    from ..detect.tail import left_out_above

    n_above = len(left_out_above(rate))
    lines = [f"false alarms per hour: {asked}; "
             + (f"NOT borne out: {n_above} calibration log(s), left out, false-alarmed above "
                "the others' bound (leave-one-log-out, below); " if n_above else "")
             + "predicted "
             f"{ph(rate['predicted_per_hour'])}, upper bound {ph(rate['upper_per_hour'])} at "
             f"{pct} confidence{beyond}, on {minutes_text(rate['free_minutes'])} min of free "
             "motion"]
    floor = " (log-start floor)" if "per_hour" in rate else " (below log-start floor)"
    for det, per in rate.get("channels", {}).items():
        for j, ch in per.items():
            tag = (" (widened)" if ch.get("widened") else
                   floor if ch.get("log_start_floor") else "")
            shape = ("exponential" if ch.get("shape") == "exponential"
                     else f"GPD ξ={ch.get('xi', 0.0):.2f}")
            lines.append(f"  {j + '/' + det:28s} threshold {ch['threshold']:.4g}{tag}: free max "
                         f"{ch.get('free_max', math.nan):.4g}, u {ch.get('level', math.nan):.4g}, "
                         f"{ch.get('clusters', 0)} clusters, {shape}, σ "
                         f"{ch.get('sigma', math.nan):.3g}; rate "
                         f"{ph(ch['predicted_per_hour'])}/h, bound {ph(ch['upper_per_hour'])}/h"
                         + (" (tail fit alone)" if sup is not None
                            and ch["upper_per_hour"] < sup else ""))
    if rate.get("statement"):
        lines.append("  " + rate["statement"])
    if "per_hour" not in rate:
        lines.append("  --false-alarms-per-hour R sets v_stat and vL for R false alarms per "
                     "hour instead (1 for an audit; fewer small contacts caught)")
    lines += [f"  note: {n}" for n in rate.get("notes", [])]
    rows = rate.get("leave_one_log_out") or []
    if rows:
        from ..detect.tail import SETTLE_S, left_out_above, poisson_interval

        lines.append("leave-one-log-out (thresholds set for R on the other logs, R a rate "
                     "a few minutes can show; each log left out counted against them, its "
                     "min the whole log after warm-up, where the tails above leave out each "
                     f"log's first {SETTLE_S:g} s, held to the log-start floor):")
        lines.append(f"  {'log':<40} {'min':>5} {'R [1/h]':>8} {'observed':>9} "
                     f"{'obs. [1/h]':>10} {pct + ' interval':>17} {'predicted':>9} "
                     f"{'bound':>7}")
        for r in rows:
            hours = r["minutes"] / 60.0
            lo, hi = poisson_interval(int(r["observed"]), hours, conf)
            lines.append(f"  {Path(r['log']).name:<40.40} {r['minutes']:>5.2f} "
                         f"{r['per_hour']:>8g} {r['observed']:>9d} "
                         f"{r['observed'] / hours:>10.3g} {f'{lo:.3g}–{hi:.3g}':>17} "
                         f"{r['predicted_per_hour']:>9.3g} {r['upper_per_hour']:>7.3g}")
        lone = lone_loads or {}
        lines += [f"  {name}: observed above its bound (the interval's low end {k:.3g}× it): "
                  "what it holds is not in the other logs — "
                  + (f"its load ({lone[name]:+.3g} kg beyond the model's, carried by no other "
                     "calibration log: the model's error under it is not the others'), or "
                     "its motion —" if name in lone else "its motion, or a load the model "
                     "fits worse with that motion —")
                  + " and thresholds made without it false-alarm on such a log"
                  for name, k in ((Path(x["log"]).name, x["ratio"])
                                  for x in left_out_above(rate))]
        if not left_out_above(rate):
            lines.append(_within_bound_line(rows, conf))
    return lines


def _within_bound_line(rows: list[dict[str, Any]], conf: float) -> str:
    """The line under a leave-one-log-out table none of whose logs false-alarmed clearly
    above its bound: when a log's observed rate is above its bound but its interval reaches
    down to it (a few events in a few minutes), say so rather than "within its bound"."""
    from ..detect.tail import per_hour_text as ph
    from ..detect.tail import poisson_interval

    over = []
    for r in rows:
        hours = r["minutes"] / 60.0
        if hours > 0 and r["observed"] / hours > r["upper_per_hour"]:
            lo, hi = poisson_interval(int(r["observed"]), hours, conf)
            over.append(f"{Path(r['log']).name} observed {ph(r['observed'] / hours)}/h in "
                        f"{r['minutes']:.2g} min against {ph(r['upper_per_hour'])}/h, its "
                        f"{100 * conf:.0f} % interval {lo:.3g}–{hi:.3g}/h")
    if not over:
        return "  (every log left out within its bound)"
    return ("  (no log left out false-alarmed clearly above its bound: " + "; ".join(over)
            + " — above it, but its interval reaches down to the bound: too few minutes to "
            "tell)")


#: A threshold this many times its free motion's maximum is warned about.
FAR_ABOVE_FREE_MAX = 5.0
#: A default calibration whose stated bound exceeds this rate [1/h] is warned about.
HIGH_STATED_RATE = 10.0


def rate_warnings(rate: dict[str, Any] | None) -> list[str]:
    """What a safety engineer must not miss in the rate record: a rate-rule threshold far
    above everything the free motion showed (contacts that move its statistic less are not
    seen), and default thresholds stated to false-alarm often."""
    if not rate:
        return []
    from ..detect.tail import at_most_text, left_out_text
    from ..detect.tail import per_hour_text as ph

    out = []
    if "per_hour" in rate:
        for det, per in (rate.get("channels") or {}).items():
            for j, ch in per.items():
                top, thr = float(ch.get("free_max", 0.0)), float(ch["threshold"])
                if top > 0 and thr >= FAR_ABOVE_FREE_MAX * top:
                    shape = ("exponential tail" if ch.get("shape") == "exponential"
                             else f"GPD tail ξ {ch.get('xi', 0.0):.2f}")
                    out.append(f"{j}/{det}: threshold {thr:.4g} is {thr / top:.0f}× the free "
                               f"motion's maximum {top:.4g} ({shape} on "
                               f"{ch.get('clusters', 0)} clusters): a contact moving it less "
                               "is not seen; more free motion, a higher R or a lower "
                               "--confidence narrows it")
    elif float(rate.get("upper_per_hour", 0.0)) > HIGH_STATED_RATE:
        left = left_out_text(rate)  # the contradiction first, the prediction after
        out.append((f"{left.removeprefix('but ')}; and " if left else "")
                   + f"these thresholds are predicted to give {ph(rate['predicted_per_hour'])} "
                   f"false alarm(s) per hour ({at_most_text(rate['upper_per_hour'])}) on "
                   "motion like the free logs'"
                   + ": calibrate on more of the robot's free "
                   "motion, or set them for a rate (--false-alarms-per-hour R)")
    return out


def _channel_payload_line(out: Any, generators: list[str]) -> str:
    """What calibrate says of payloads per log when the residual is the controller's
    channel and the model was identified in this run from two or more logs: corrected by
    the tool's model with kinematics, a payload per log is fitted where it predicts clearly
    better held out (:func:`impactcli.model.selection.identify_correction`), else one load
    for all logs; taken plain, or without kinematics, logs that carry different loads are
    not told apart."""
    from ..model import RigidModel, payload

    model = out.model or {}
    choice = (model.get("fit") or {}).get("payload_choice")
    if choice is not None:
        from ..model.selection import payload_lines

        return "\n".join(payload_lines(choice))
    which = ", ".join(generators)
    rig = RigidModel.from_dict(model) if model else None
    if (out.residual.logged_correction and rig is not None
            and payload.basis(rig.kind, rig.joint_names, rig.structure) is not None):
        return (f"  payload per log: one load for all logs — the residual is the controller's "
                f"({which}) corrected by the tool's {model['kind']} model, and a payload per "
                "log predicted no better held out")
    return (f"  payload per log: not fitted: the residual is the controller's ({which}) "
            + ("taken plain" if not out.residual.logged_correction else
               "corrected by a model without kinematics")
            + ": logs that carry different loads are not told apart, and their difference "
            "widens the thresholds (residual.logged_correction = true, the default, and a "
            "robot description with kinematics fit a payload per log)")


def _labels_for(logs: tuple[Path, ...], given: tuple[Path, ...]) -> list:  # type: ignore[type-arg]
    """Labels per log: ``--labels`` paired as ``report`` pairs them, else
    ``<stem>.labels.json`` beside the log when present, else None."""
    from ..logs.robot_files import read_labels
    from ..run.report_inputs import auto_labels, pair_labels

    paths = pair_labels(list(logs), list(given)) if given else [
        auto_labels(p, None) for p in logs]
    return [None if p is None else read_labels(p) for p in paths]


@click.command("calibrate")
@click.argument("logs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--out", "--output", "out_path", required=True,
              type=click.Path(dir_okay=False, path_type=Path),
              help="Config to write (.toml, .yaml or .json), accepted by `detect --config`.")
@click.option("--robot", metavar=ROBOT_METAVAR, type=click.Path(dir_okay=False, path_type=Path),
              help=robot_help("kinematics for the model, joint order"))
@click.option("--model", type=click.Path(dir_okay=False, path_type=Path),
              help="Rigid model to calibrate for [default: identified from these logs].")
@click.option("--config", "base_config", type=click.Path(dir_okay=False, path_type=Path),
              help="Start from this config's parameters (its thresholds are replaced).")
@click.option("--labels", "labels_paths", multiple=True,
              type=click.Path(dir_okay=False, path_type=Path),
              help="Labels of contacts in the LOGS (one per log, or named <stem>.labels.json): "
                   "their stretches are left out [default: <stem>.labels.json beside each "
                   "log, when present].")
@click.option("--false-alarms-per-hour", "fa_rate", type=click.FloatRange(min=0, min_open=True),
              metavar="R",
              help="Set v_stat and vL for R false alarms per hour (incidents of the "
                   "product's detectors after warm-up, all joints together): the upper "
                   "bound of the predicted rate, at --confidence, is R. Where the free logs "
                   "are too short to support R, the thresholds are widened and calibrate "
                   "says how many minutes of free motion R needs. For an audit: 1. "
                   "[default: the leave-one-out margin, its predicted rate stated]")
@click.option("--confidence", type=click.FloatRange(min=0.5, max=1.0, max_open=True),
              default=0.9, show_default=True,
              help="One-sided confidence of the rate's upper bound.")
@click.option("--threshold-rule", type=click.Choice(["false-alarm-rate", "leave-one-out"]),
              help="How v_stat and vL are set: for a false-alarm rate (R of "
                   "--false-alarms-per-hour, 1 per hour when not given), or by the "
                   "leave-one-out margin over the free logs' maxima, with the rate the tail "
                   "fits predict for it stated [default: false-alarm-rate with "
                   "--false-alarms-per-hour, else leave-one-out]. v0 (static_baseline, a "
                   "comparison detector) always follows leave-one-out.")
@click.option("--keep-suspect", is_flag=True,
              help="Keep stretches that alone would set a threshold (likely contacts; "
                   "left out by default, with a warning).")
@generator_option
@log_read_options
@click.option("--allow-slow", is_flag=True,
              help="Calibrate on logs whose replay is estimated slower than real time or "
                   "above 2 GiB of covariance (many joints: the adaptive evaluator's cost "
                   "grows with the cube of the joint count); without it such a log is "
                   "refused before the model is identified (exit 2).")
@handle_errors
def calibrate_cmd(logs: tuple[Path, ...], out_path: Path, robot: Path | None, model: Path | None,
                  base_config: Path | None, labels_paths: tuple[Path, ...], fa_rate: float | None,
                  confidence: float, threshold_rule: str | None, keep_suspect: bool,
                  generator: str | None, read_options: ReadOptions,
                  allow_slow: bool = False) -> None:
    """Set v_stat, vL and v0 per joint from the collision-free LOGS.

    Every threshold by default, and v0 always: the margin over the statistic's maximum
    chosen by leave-one-out over the logs (the smallest margin for which every log left out
    stays silent); with one log a fixed 1.5× margin, flagged weak. The false-alarm rate
    these v_stat and vL are predicted to give is stated beside them.

    With --false-alarms-per-hour R, v_stat and vL are set for that rate instead: the tail
    of each joint's and detector's statistic on the free logs (peaks over a level,
    declustered as incidents are, fitted by a generalized Pareto tail) gives the threshold
    whose predicted rate's upper bound, over all joints and both detectors, is R. Either
    way calibrate prints per joint the threshold, its fit, predicted rate and bound, what
    the free minutes support, and, with two or more logs, each log left out against the
    others' prediction. The rate holds for motion like the free logs': the config records
    their motion envelope, and thresholds calibrated on one motion family false-alarm on
    another.

    For the margin, long logs are cut into 30 s segments (the tail fits use whole logs).
    Contacts labelled in <stem>.labels.json beside a log (or --labels) are left out; in a
    log without labels, a stretch that alone would set a threshold far above all the
    others (> 20× the median second) is reported as a likely contact and left out
    (--keep-suspect keeps it).

    Each joint's residual generator is frozen in the config (thresholds belong to the
    generator they were made with): with --generator auto (the default for a new config)
    the controller's own external-torque estimate (torque_ext) where every log carries it,
    else its model torque (torque_model, with a correction identified on these logs), else
    the tool's own identified model.
    """
    from ..config import load_config, save_config
    from ..files import prepare_output
    from ..logs import read_log
    from ..logs.robot_files import read_robot
    from ..run import calibration
    from ..run.calibration import MARGIN_RULE, RATE_RULE
    from ..run.model_files import read_model

    if out_path.suffix.lower() not in (".toml", ".yaml", ".yml", ".json"):
        raise click.BadParameter(f"{str(out_path)!r}: a config is written as .toml, .yaml or "
                                 ".json — name the file with one of these", param_hint="'-o'")
    if fa_rate is not None and not math.isfinite(fa_rate):
        raise click.BadParameter(f"{fa_rate} is not a finite rate (false alarms per hour)",
                                 param_hint="'--false-alarms-per-hour'")
    if threshold_rule is None:
        threshold_rule = RATE_RULE if fa_rate is not None else MARGIN_RULE
    if fa_rate is not None and threshold_rule != RATE_RULE:
        raise click.BadParameter("--false-alarms-per-hour sets thresholds for a rate; "
                                 f"--threshold-rule {threshold_rule} sets them by the "
                                 "margin (and states the rate they give)",
                                 param_hint="'--false-alarms-per-hour'")
    prepare_output(out_path)  # a bad -o stops the run before any work
    from ..logs.urls import expand_inputs

    logs = tuple(Path(p) for p in expand_inputs([str(p) for p in logs]))  # folders, globs
    robot_d = read_robot(robot) if robot else None
    model_m = read_model(model) if model else None
    cfg = load_config(base_config) if base_config else None
    ropts = read_options.as_dict()
    read = [read_log(p, robot=robot_d, **ropts) for p in logs]
    if not allow_slow:  # before identification and replay: the cost is the joints', not time's
        from ..config import DetectorConfig
        from ..detect.adaptive import check_scale
        from ..run.plan import check_identification, identified_kind

        kind = identified_kind(model_m, cfg or DetectorConfig(), robot_d, False)
        for log in read:
            check_scale(log.n_joints, log.sample_rate_hz, cfg.adaptive if cfg else None,
                        log.source.path)
            if kind is not None:
                check_identification(log.source.path, kind, log.n_joints, log.sample_rate_hz)
    labels = _labels_for(logs, labels_paths)
    for p, lab in zip(logs, labels, strict=True):
        if lab is not None and lab.events:
            click.echo(f"{p}: {len(lab.events)} labelled contact(s) left out ({lab.path})")
    from ..detect.tail import DEFAULT_FALSE_ALARMS_PER_HOUR

    out = calibration.calibrate(
        read, model=model_m, config=cfg, robot=robot_d, generator=generator, labels=labels,
        drop_suspect=not keep_suspect, allow_slow=allow_slow, threshold_rule=threshold_rule,
        confidence=confidence,
        false_alarms_per_hour=DEFAULT_FALSE_ALARMS_PER_HOUR if fa_rate is None else fa_rate)
    save_config(out, out_path)
    c = out.calibration
    weak = " (weak: add collision-free logs covering the robot's motions)" if c.weak else ""
    kind = (out.model or {}).get("kind", "?")
    source = ("given" if model_m is not None else "the base config's" if cfg and cfg.model
              else f"identified on the {len(read)} log(s)")
    gens = out.residual.generators
    logged = {g for g in gens.values() if g.startswith("logged_")}
    if out.model is None:
        what = "no model (every joint reads the controller's channels plain)"
    elif logged and logged == set(gens.values()):
        what = f"model {kind} ({source}) of what the controller's channels leave out"
    else:
        what = f"model {kind} ({source})"
    from ..detect.tail import per_hour_text as ph

    fa = c.false_alarm_rate or {}
    from ..detect.tail import left_out_text, zero_count_bound

    tail = ("" if not fa or fa["upper_per_hour"] >= (zero := zero_count_bound(
        fa["free_minutes"] / 60.0, fa["confidence"])) else
            f": the tail fits' extrapolation, where the free motion with no alarm bounds "
            f"{ph(zero)} by itself")
    # a log left out that false-alarmed above the others' bound is said before the
    # prediction it contradicts, not after it (nor 60 lines on)
    left = left_out_text(fa) if fa else ""
    lead = f": NOT borne out — {left.removeprefix('but ')}" if left else ""
    pred = (f"predicted {ph(fa['predicted_per_hour'])} false alarm(s) per hour, upper "
            f"bound {ph(fa['upper_per_hour'])}{tail}" if fa else "")
    rule = (f"v_stat and vL for {fa['per_hour']:g} false alarm(s) per hour{lead}"
            f"{';' if lead else ','} v0 by {c.margin_rule}" if "per_hour" in fa
            else f"rule {c.margin_rule}" + (f"{lead}; {pred}" if lead and pred
                                              else f" ({pred})" if pred else lead))
    click.echo(f"calibrated on {len(read)} log(s) ({c.segments} stretch(es) of collision-free "
               f"motion), {rule}{weak}; {what}")
    if kind == "decoupled" and robot_d is None and model_m is None and out.model is not None:
        click.echo("impactcli: warning: no --robot: the model is 'decoupled' (each joint "
                   "alone, no kinematics); a robot description with kinematics gives the "
                   "planar or urdf model", err=True)
    if out.model is not None:  # the same fit table as `identify` prints
        from ..model import RigidModel
        from .fit_table import format_fit_table

        fitted = RigidModel.from_dict(out.model)
        click.echo(format_fit_table(fitted))
        if model_m is None and "selection" in fitted.fit:  # which kind, and why
            from ..model.selection import describe

            click.echo("\n".join(describe(fitted.fit["selection"])))
        from ..model.payload_table import differ_warning

        if (differ := differ_warning(fitted)) is not None:
            click.echo(f"impactcli: warning: {differ}", err=True)
    from ..model.generators import OWN_MODEL

    elsewhere = sorted({g for g in out.residual.generators.values() if g not in OWN_MODEL})
    identified = model_m is None and not (cfg and cfg.model)  # in this run, not given
    if elsewhere and len(read) > 1 and identified:  # the controller's channel: per log too?
        click.echo(_channel_payload_line(out, elsewhere))
    from ..run.torque_sources import judge_sources

    sources = judge_sources(read, robot_d, read_options)  # both .torque and .current logged
    if sources is not None:
        click.echo("\n".join(sources.lines()))
        if (advice := sources.advice()) is not None:
            click.echo(f"impactcli: warning: {advice}", err=True)
    click.echo("\n".join(threshold_lines(out)))
    for line in rate_warnings(c.false_alarm_rate):
        click.echo(f"impactcli: warning: {line}", err=True)
    click.echo(f"wrote {out_path}")
