"""``impactcli inspect LOG``: what a log holds — joints, channels, sources, rate, gaps, repairs."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import click

from .options import ROBOT_METAVAR, handle_errors, log_read_options, robot_help

if TYPE_CHECKING:
    from ..types import ReadOptions


@click.command("inspect")
@click.argument("log", type=click.Path(path_type=str))
@click.option("--robot", metavar=ROBOT_METAVAR,
              help=robot_help("needed to turn currents into torques"))
@log_read_options
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
@handle_errors
def inspect_cmd(log: str, robot: str | None, read_options: ReadOptions, as_json: bool) -> None:
    """Show what LOG holds: joints, channels used and ignored, torque and time source,
    duration, sample rate and jitter, gaps and repairs — and what it still needs (a current
    without gear ratio and torque constant is shown in A, and said).

    With --robot, the torque's scale is checked against the description's gravity torque,
    as every verb checks it (off by a unit's factor: exit 3, naming it).

    When LOG carries both .torque and .current, each is fitted by the same rigid model and
    its held-back error shown; --torque-source is named when the other source predicts
    clearly better (docs/formats.md, "Torque: .torque or .current")."""
    from ..logs import inspect_log
    from ..logs.describe import format_table
    from ..logs.robot_files import read_robot
    from ..run.plan import check_torque_scale
    from ..run.torque_sources import inspect_sources

    desc = read_robot(robot) if robot else None
    opts = read_options.as_dict()
    # a folder's one log, as every verb reads one; with --robot its torque's scale checked
    # as every verb checks it (a unit's factor: exit 3)
    d = inspect_log(log, check=None if desc is None else (
        lambda scan: check_torque_scale(scan, desc)), robot=desc, **opts)
    sources = inspect_sources(d, desc, read_options)
    if sources is not None:
        d["torque_sources"] = sources.as_dict()
    if as_json:
        click.echo(json.dumps(d, separators=(",", ":")))
        return
    click.echo(format_table(d))
    if sources is not None:
        click.echo("\n".join(sources.lines()))
        if (advice := sources.advice()) is not None:
            click.echo(f"impactcli: warning: {d['path']}: {advice}", err=True)
