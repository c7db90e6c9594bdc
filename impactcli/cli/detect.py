"""``impactcli detect LOG... -o DIR``: replay the detectors, write timelines (and signals, .rrd)."""

# ruff: noqa: PLC0415  (imports inside functions keep `impactcli --help` fast)

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from ..errors import EXIT_BATCH, EXIT_DETECTED
from ._common import handle_errors, progress

#: the product's detectors: what --fail-on-detect counts (static_baseline is for comparison)
PRODUCT_DETECTORS = ("adaptive", "static_loading")


def read_options_from(channel_map: str | None, topic: str | None, reference_topic: str | None,
                      time_source: str | None, torque_source: str | None) -> dict[str, Any]:
    """The read_log keyword arguments given on the command line (None values dropped)."""
    opts = {"channel_map": channel_map, "topic": topic, "reference_topic": reference_topic,
            "time_source": time_source, "torque_source": torque_source}
    return {k: v for k, v in opts.items() if v is not None}


def log_read_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The options that say how to read a log (shared by the verbs that read logs)."""
    for opt in reversed([
        click.option("--channel-map", metavar="MAP",
                     help="Channel map (path, or a shipped name) for foreign CSV / .npz logs."),
        click.option("--topic", help="MCAP: the JointState/state topic."),
        click.option("--reference-topic", help="MCAP: the reference topic."),
        click.option("--time-source", type=click.Choice(["log", "publish", "header"]),
                     help="MCAP: which clock stamps samples [default: header, else log]."),
        click.option("--torque-source", type=click.Choice(["current", "torque"]),
                     help="Use logged torque or current × gear ratio × torque constant."),
    ]):
        func = opt(func)
    return func


def model_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--robot, --model, --config (shared by detect, report, view, evaluate)."""
    for opt in reversed([
        click.option("--robot", type=click.Path(dir_okay=False, path_type=Path),
                     help="Robot description (JSON/YAML): joints, gear ratios, kinematics."),
        click.option("--model", type=click.Path(dir_okay=False, path_type=Path),
                     help="Rigid model from `impactcli identify` [default: the config's, "
                          "else identified from the log itself]."),
        click.option("--config", type=click.Path(dir_okay=False, path_type=Path),
                     help="Detector config from `impactcli calibrate` (TOML/YAML) "
                          "[default: Table I, uncalibrated thresholds from the log]."),
    ]):
        func = opt(func)
    return func


def preload(robot: Path | None, model: Path | None, config: Path | None) -> None:
    """Read robot, model and config once up front: a bad one stops the run before any work."""
    from ..config import load_config
    from ..io.robot import read_robot
    from ..model import read_model

    if robot is not None:
        read_robot(robot)
    if model is not None:
        read_model(model)
    if config is not None:
        load_config(config)


def _fmt_row(s: dict[str, Any]) -> str:
    return (f"{Path(s['log']).name:<36} {s['duration_s']:>9.1f} {'yes' if s['calibrated'] else 'no':>10} "
            f"{s['warmup_end_s']:>7.2f} {s['adaptive']:>8} {s['static_loading']:>8} "
            f"{s['static_baseline']:>8}")


@click.command("detect")
@click.argument("logs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder: <stem>.timeline.json per log (+ .signals.parquet, .rrd).")
@model_options
@log_read_options
@click.option("--signals", is_flag=True, help="Also write the per-sample signals (Parquet).")
@click.option("--rerun", is_flag=True, help="Also write a Rerun recording (<stem>.rrd).")
@click.option("--fail-on-detect", is_flag=True,
              help="Exit 1 when adaptive or static_loading found events after warm-up.")
@click.option("--jobs", "-j", type=click.IntRange(min=1), default=1, show_default=True,
              help="Logs processed in parallel (local processes).")
@handle_errors
def detect_cmd(logs: tuple[Path, ...], out_dir: Path, robot: Path | None, model: Path | None,
               config: Path | None, channel_map: str | None, topic: str | None,
               reference_topic: str | None, time_source: str | None, torque_source: str | None,
               signals: bool, rerun: bool, fail_on_detect: bool, jobs: int) -> None:
    """Replay the adaptive impact detector (Makarov et al. 2014) and the static detectors
    over LOGS, exactly as the robot would have run them online, and write one
    DIR/<stem>.timeline.json per log.

    Without --model or --config the model is identified from each log itself and the
    thresholds come from the log's own statistics: the run is marked uncalibrated.
    Exit 0 whether or not collisions are found (unless --fail-on-detect); 3 on a bad
    input; 4 when some logs of a batch failed (the others' outputs are written).
    """
    from ..batch import DetectJob, check_unique_stems, run_jobs

    paths = [str(p) for p in logs]
    try:
        check_unique_stems(paths)
    except ValueError as err:
        raise click.UsageError(str(err)) from None
    preload(robot, model, config)
    ropts = read_options_from(channel_map, topic, reference_topic, time_source, torque_source)
    job_list = [
        DetectJob(p, str(out_dir), ropts, str(robot) if robot else None,
                  str(model) if model else None, str(config) if config else None, signals, rerun)
        for p in paths
    ]
    outcomes = []
    for outcome in progress(run_jobs(job_list, jobs), total=len(job_list), desc="detect"):
        name = Path(outcome.log_path).name
        for w in outcome.warnings:
            click.echo(f"impactcli: warning: {name}: {w}" if name not in w else f"impactcli: warning: {w}",
                       err=True)
        if not outcome.ok:
            click.echo(f"impactcli: error: {outcome.error}", err=True)
        outcomes.append(outcome)
    order = {p: i for i, p in enumerate(paths)}
    outcomes.sort(key=lambda o: order[o.log_path])
    ok = [o for o in outcomes if o.ok]
    if ok:
        click.echo(f"{'log':<36} {'duration_s':>9} {'calibrated':>10} {'warmup':>7} "
                   f"{'adaptive':>8} {'loading':>8} {'baseline':>8}")
        for o in ok:
            click.echo(_fmt_row(o.summary))
        click.echo(f"(events after warm-up; timelines in {out_dir})")
    failed = [o for o in outcomes if not o.ok]
    ctx = click.get_current_context()
    if failed:
        if len(outcomes) == 1:
            ctx.exit(failed[0].exit_code)
        click.echo(f"impactcli: {len(failed)} of {len(outcomes)} logs failed", err=True)
        ctx.exit(EXIT_BATCH)
    if fail_on_detect and any(o.summary[d] > 0 for o in ok for d in PRODUCT_DETECTORS):
        ctx.exit(EXIT_DETECTED)
