"""``impactcli inspect LOG``: what a log holds — joints, channels, sources, rate, gaps, repairs."""

from __future__ import annotations

import json

import click

from ._common import handle_errors


@click.command("inspect")
@click.argument("log", type=click.Path(path_type=str))
@click.option("--channel-map", "channel_map", metavar="MAP",
              help="Channel map (JSON/YAML path, or a shipped map's name such as ur_ext_observer).")
@click.option("--robot", metavar="FILE", type=click.Path(dir_okay=False, path_type=str),
              help="Robot description (needed to turn currents into torques).")
@click.option("--topic", help="MCAP joint-state topic (default: the only one, else /joint_states).")
@click.option("--reference-topic", "reference_topic",
              help="MCAP reference topic (default: <topic>_ref when present).")
@click.option("--time-source", "time_source", type=click.Choice(["log", "publish", "header"]),
              help="MCAP clock (default: header stamp when non-zero, else log time).")
@click.option("--torque-source", "torque_source", type=click.Choice(["current", "torque"]),
              help="Use logged torque or current × gear ratio × torque constant "
                   "(default: torque when logged).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
@handle_errors
def inspect_cmd(log: str, channel_map: str | None, robot: str | None, topic: str | None,
                reference_topic: str | None, time_source: str | None,
                torque_source: str | None, as_json: bool) -> None:
    """Show what LOG holds: joints, channels used and ignored, torque and time source,
    duration, sample rate and jitter, gaps and repairs."""
    from ..io import inspect_log
    from ..io.inspect import format_table
    from ..io.robot import read_robot

    desc = read_robot(robot) if robot else None
    d = inspect_log(log, channel_map=channel_map, robot=desc, topic=topic,
                    reference_topic=reference_topic, time_source=time_source,
                    torque_source=torque_source)
    if as_json:
        click.echo(json.dumps(d, separators=(",", ":")))
    else:
        click.echo(format_table(d))
