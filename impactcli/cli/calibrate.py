"""``impactcli calibrate FREE_LOG... -o CONFIG``: thresholds from collision-free logs."""

from __future__ import annotations

from pathlib import Path

import click

from .options import (
    ROBOT_METAVAR,
    generator_option,
    handle_errors,
    log_read_options,
    read_options_from,
    robot_help,
)


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
                  base_config: Path | None, labels_paths: tuple[Path, ...], keep_suspect: bool,
                  generator: str | None, channel_map: str | None,
                  topic: str | None, reference_topic: str | None, time_source: str | None,
                  torque_source: str | None, allow_slow: bool = False) -> None:
    """Set v_stat, vL and v0 per joint so that the collision-free LOGS raise no alarm.

    With two or more logs the margin over the statistic's maximum is chosen by
    leave-one-out (the smallest margin for which every log left out stays silent);
    with one log a fixed 1.5× margin is used and the calibration is flagged weak.
    Give logs that cover the motions the robot really makes: thresholds calibrated on
    one motion family false-alarm on another.

    Long logs are cut into 30 s segments after warm-up, so leave-one-out works on one long
    log too. Contacts labelled in <stem>.labels.json beside a log (or --labels) are left out;
    in a log without labels, a stretch that alone would set a threshold far above all the
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
    from ..model import read_model
    from ..run.calibration import calibrate

    if out_path.suffix.lower() not in (".toml", ".yaml", ".yml", ".json"):
        raise click.BadParameter(f"{str(out_path)!r}: a config is written as .toml, .yaml or "
                                 ".json — name the file with one of these", param_hint="'-o'")
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
    out = calibrate(read, model=model_m, config=cfg, robot=robot_d, generator=generator,
                    labels=labels, drop_suspect=not keep_suspect, allow_slow=allow_slow)
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
    click.echo(f"calibrated on {len(read)} log(s) ({c.segments} stretch(es) of collision-free "
               f"motion), rule {c.margin_rule}{weak}; {what}")
    if kind == "decoupled" and robot_d is None and model_m is None and out.model is not None:
        click.echo("impactcli: warning: no --robot: the model is 'decoupled' (each joint "
                   "alone, no kinematics); a robot description with kinematics gives the "
                   "planar or urdf model", err=True)
    if out.model is not None:  # the same fit table as `identify` prints
        from ..model import RigidModel
        from .fit_table import format_fit_table

        click.echo(format_fit_table(RigidModel.from_dict(out.model)))
    click.echo(f"{'joint':<16} {'generator':<17} {'v_stat':>9} {'vL':>9} {'v0':>9}   "
               "margins (adaptive/loading/baseline)")
    th = out.thresholds
    for j in th.v_stat:
        m = [c.margins[d][j] for d in ("adaptive", "static_loading", "static_baseline")]
        click.echo(f"{j:<16} {gens.get(j, '?'):<17} {th.v_stat[j]:>9.4f} {th.vL[j]:>9.4f} "
                   f"{th.v0[j]:>9.4f}   " + " / ".join(f"{x:.2f}" for x in m))
    click.echo(f"wrote {out_path}")
