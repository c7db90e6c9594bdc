"""``impactcli calibrate FREE_LOG... -o CONFIG``: thresholds from collision-free logs."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from .options import (
    ROBOT_METAVAR,
    generator_option,
    handle_errors,
    log_read_options,
    read_options_from,
    robot_help,
)

if TYPE_CHECKING:
    from ..run.calibration import Calibrated


def threshold_lines(done: Calibrated) -> list[str]:
    """What calibrate prints after the model: per joint its generator and thresholds; the
    rate's fit per joint and detector, its support and leave-one-log-out rows; the motion
    envelope."""
    out = done.config
    c, th, gens = out.calibration, out.thresholds, out.residual.generators
    rate = done.rate is not None
    head = ("v0 margin" if rate else "margins (adaptive/loading/baseline)")
    lines = [f"{'joint':<16} {'generator':<17} {'v_stat':>9} {'vL':>9} {'v0':>9}   {head}"]
    for j in th.v_stat:
        dets = ("static_baseline",) if rate else ("adaptive", "static_loading",
                                                  "static_baseline")
        m = [c.margins.get(d, {}).get(j) for d in dets]
        lines.append(f"{j:<16} {gens.get(j, '?'):<17} {th.v_stat[j]:>9.4f} {th.vL[j]:>9.4f} "
                     f"{th.v0[j]:>9.4f}   "
                     + " / ".join("—" if x is None else f"{x:.2f}" for x in m))
    if done.rate is not None:
        lines += done.rate.lines()
    if done.lolo:
        lines.append("leave-one-log-out (calibrated on the other logs; rates a few minutes "
                     "can show):")
        lines.append(f"  {'log':<40} {'min':>5} {'R [1/h]':>8} {'observed':>9} "
                     f"{'obs. [1/h]':>10} {'90 % interval':>17} {'predicted':>9} {'bound':>7}")
        conf = done.rate.conf if done.rate is not None else 0.9
        for r in done.lolo:
            lo, hi = r.interval(conf)
            name = Path(done.log_paths[r.log]).name
            lines.append(f"  {name:<40.40} {r.hours * 60:>5.2f} {r.rate:>8g} {r.observed:>9d} "
                         f"{r.observed / r.hours:>10.3g} {f'{lo:.3g}–{hi:.3g}':>17} "
                         f"{r.predicted:>9.3g} {r.upper:>7.3g}")
        lines.append("  (a log observed above its bound moves unlike the others: its motion "
                     "is not in their envelope)")
    if done.envelope is not None:
        src = {"position_ref": "reference", "position": "measured position"}
        lines.append(f"motion envelope ({src.get(done.envelope.source, done.envelope.source)}"
                     f", {done.envelope.samples} samples): a rate holds for motion inside it")
        lines += done.envelope.lines()
    return lines


def _labels_for(logs: tuple[Path, ...], given: tuple[Path, ...]) -> list:  # type: ignore[type-arg]
    """Labels per log: ``--labels`` paired as ``report`` pairs them, else
    ``<stem>.labels.json`` beside the log when present, else None."""
    from ..logs.robot_files import read_labels
    from .report import auto_labels, pair_labels

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
@click.option("--false-alarms-per-hour", "rate", type=click.FloatRange(min=0, min_open=True),
              metavar="R",
              help="False alarms per hour (incidents of the product's detectors after "
                   "warm-up, all joints together) the thresholds are set for: the upper "
                   "bound of the predicted rate, at --confidence, is R. Where the free logs "
                   "are too short to support R, the thresholds are widened and calibrate "
                   "says how many minutes of free motion R needs [default: 1].")
@click.option("--confidence", type=click.FloatRange(min=0.5, max=1.0, max_open=True),
              default=0.9, show_default=True,
              help="One-sided confidence of the rate's upper bound.")
@click.option("--threshold-rule", type=click.Choice(["false-alarm-rate", "leave-one-out"]),
              default="false-alarm-rate", show_default=True,
              help="How v_stat and vL are set: for the false-alarm rate R, or by the older "
                   "leave-one-out margin over the free logs' maxima (no stated rate; kept "
                   "to compare with and for configs made by it). v0 (static_baseline, a "
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
                  base_config: Path | None, labels_paths: tuple[Path, ...], rate: float | None,
                  confidence: float, threshold_rule: str, keep_suspect: bool,
                  generator: str | None, channel_map: str | None,
                  topic: str | None, reference_topic: str | None, time_source: str | None,
                  torque_source: str | None, allow_slow: bool = False) -> None:
    """Set v_stat, vL and v0 per joint from the collision-free LOGS.

    By default v_stat and vL are set for a false-alarm rate: the tail of each joint's and
    detector's statistic on the free logs (peaks over a level, declustered as incidents
    are, fitted by a generalized Pareto tail) gives the threshold whose predicted rate's
    upper bound, over all joints and both detectors, is --false-alarms-per-hour (1 per
    hour). calibrate prints per joint the threshold, its fit, predicted rate and bound,
    what the free minutes support, and, with two or more logs, each log left out against
    the others' prediction. The rate holds for motion like the free logs': the config
    records their motion envelope, and thresholds calibrated on one motion family
    false-alarm on another.

    v0 (and, with --threshold-rule leave-one-out, every threshold): the margin over the
    statistic's maximum chosen by leave-one-out over the logs (the smallest margin for
    which every log left out stays silent); with one log a fixed 1.5× margin, flagged weak.
    Long logs are cut into 30 s segments for it. Contacts labelled in <stem>.labels.json
    beside a log (or --labels) are left out; in a log without labels, a stretch that alone
    would set a threshold far above all the others (> 20× the median second) is reported
    as a likely contact and left out (--keep-suspect keeps it).

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
    from ..model import read_model
    from ..run.calibration import RATE_RULE, calibrate_run

    if out_path.suffix.lower() not in (".toml", ".yaml", ".yml", ".json"):
        raise click.BadParameter(f"{str(out_path)!r}: a config is written as .toml, .yaml or "
                                 ".json — name the file with one of these", param_hint="'-o'")
    if rate is not None and threshold_rule != RATE_RULE:
        raise click.BadParameter("--false-alarms-per-hour sets thresholds for a rate; "
                                 f"--threshold-rule {threshold_rule} has none",
                                 param_hint="'--false-alarms-per-hour'")
    prepare_output(out_path)  # a bad -o stops the run before any work
    robot_d = read_robot(robot) if robot else None
    model_m = read_model(model) if model else None
    cfg = load_config(base_config) if base_config else None
    ropts = read_options_from(channel_map, topic, reference_topic, time_source, torque_source)
    read = [read_log(p, robot=robot_d, **ropts) for p in logs]
    if not allow_slow:  # before identification and replay: the cost is the joints', not time's
        from ..detect.adaptive import check_scale

        for log in read:
            check_scale(log.n_joints, log.sample_rate_hz, cfg.adaptive if cfg else None,
                        log.source.path)
    labels = _labels_for(logs, labels_paths)
    for p, lab in zip(logs, labels, strict=True):
        if lab is not None and lab.events:
            click.echo(f"{p}: {len(lab.events)} labelled contact(s) left out ({lab.path})")
    from ..detect.tail import DEFAULT_FALSE_ALARMS_PER_HOUR

    done = calibrate_run(read, model=model_m, config=cfg, robot=robot_d, generator=generator,
                         labels=labels, drop_suspect=not keep_suspect, allow_slow=allow_slow,
                         threshold_rule=threshold_rule, confidence=confidence,
                         false_alarms_per_hour=DEFAULT_FALSE_ALARMS_PER_HOUR if rate is None
                         else rate)
    out = done.config
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
    rule = (f"v_stat and vL for {done.rate.rate:g} false alarm(s) per hour, v0 by "
            f"{c.margin_rule}" if done.rate is not None else f"rule {c.margin_rule}")
    click.echo(f"calibrated on {len(read)} log(s) ({c.segments} stretch(es) of collision-free "
               f"motion), {rule}{weak}; {what}")
    if kind == "decoupled" and robot_d is None and model_m is None and out.model is not None:
        click.echo("impactcli: warning: no --robot: the model is 'decoupled' (each joint "
                   "alone, no kinematics); a robot description with kinematics gives the "
                   "planar or urdf model", err=True)
    if out.model is not None:  # the same fit table as `identify` prints
        from ..model import RigidModel
        from .fit_table import format_fit_table

        click.echo(format_fit_table(RigidModel.from_dict(out.model)))
    click.echo("\n".join(threshold_lines(done)))
    click.echo(f"wrote {out_path}")
