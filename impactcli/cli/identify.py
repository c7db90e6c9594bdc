"""``impactcli identify LOG -o model.json``: identify a rough rigid model and write it."""

from __future__ import annotations

from typing import TYPE_CHECKING

import click

from .fit_table import format_fit_table
from .options import ROBOT_METAVAR, handle_errors, log_read_options, robot_help

if TYPE_CHECKING:
    from ..types import ReadOptions

__all__ = ["format_fit_table", "identify_cmd"]


@click.command("identify")
@click.argument("log", type=click.Path(path_type=str))
@click.option("-o", "--output", "--out", "output", required=True,
              type=click.Path(dir_okay=False, path_type=str), help="Model file to write (JSON).")
@click.option("--robot", metavar=ROBOT_METAVAR, type=click.Path(dir_okay=False, path_type=str),
              help=robot_help("joints, kinematics: planar or urdf"))
@click.option("--kind", type=click.Choice(["decoupled", "coupled", "planar", "urdf"]),
              help="Model structure [default: the robot's kinematics type (planar, urdf); "
                   "without kinematics, decoupled or coupled, whichever predicts contiguous "
                   "stretches of the log best held back (one-standard-error rule, "
                   "docs/models.md)]. coupled: a spatial arm without kinematics, every "
                   "joint's motion in every joint's torque.")
@log_read_options
@click.option("--cutoff", "cutoff_hz", type=click.FloatRange(min=0, min_open=True),
              default=10.0, show_default=True,
              help="Zero-phase filter cut-off for positions, torques and regressor [Hz].")
@click.option("--holdout", "holdout_fraction", type=click.FloatRange(0.0, 0.9, max_open=True),
              default=0.2, show_default=True,
              help="Last fraction of the log held back to validate the fit (0: none).")
@click.option("--robust", type=click.Choice(["bisquare", "huber", "none"]), default="bisquare",
              show_default=True, help="Robust weighting against contacts in the log.")
@click.option("--coulomb-slope", "coulomb_slope", type=click.FloatRange(min=0, min_open=True),
              default=0.01, show_default=True,
              help="v_s of the smooth Coulomb sign tanh(q'/v_s) [rad/s].")
@click.option("--allow-still-joints/--no-allow-still-joints", "allow_still", default=True,
              show_default=True,
              help="Model a joint that does not move by its constant torque only, with a "
                   "warning, as calibrate and detect do; --no-allow-still-joints makes it "
                   "an error.")
@handle_errors
def identify_cmd(
    log: str, output: str, robot: str | None, kind: str | None, read_options: ReadOptions,
    cutoff_hz: float, holdout_fraction: float, robust: str, coulomb_slope: float,
    allow_still: bool,
) -> None:
    """Identify a rough rigid model (tau = Y(q, q', q'') theta) from LOG and write it.

    Without --kind the robot's kinematics name the model (planar, urdf); without
    kinematics the kind, decoupled or coupled (and the coupled model's ridge penalty per
    joint), is the one that predicts contiguous stretches of the log best held back —
    the richer only when clearly better (one-standard-error rule). The choice and why are
    printed and recorded in the model (fit.selection).

    A multi-arm MCAP or bag: --topic picks the arm's JointState topic, as in the other
    verbs."""
    from ..files import prepare_output
    from ..logs import read_log
    from ..logs.robot_files import read_robot
    from ..model import IdentifyOptions, identify
    from ..model.selection import describe, select_model
    from ..run.model_files import write_model

    prepare_output(output)  # a bad -o stops the run before any work
    desc = read_robot(robot) if robot else None
    ropts = read_options.as_dict()
    data = read_log(log, robot=desc, **ropts)
    if desc is not None:  # a unit's factor off the description's gravity torque: exit 3
        from ..logs.reader import MemoryReader
        from ..run.plan import check_torque_scale

        check_torque_scale(MemoryReader(data).scan(), desc)
    options = IdentifyOptions(cutoff_hz=cutoff_hz, holdout_fraction=holdout_fraction,
                              robust=robust, coulomb_slope_rad_s=coulomb_slope,
                              allow_still_joints=allow_still)
    if kind is None:  # the kind (and coupled penalty) that predicts best held back
        model = select_model([data], robot=desc, options=options)
    else:
        model = identify(data, robot=desc, kind=kind, options=options)
    write_model(model, output)
    click.echo(format_fit_table(model))
    if "selection" in model.fit:
        click.echo("\n".join(describe(model.fit["selection"])))
    click.echo(f"wrote {output}")
