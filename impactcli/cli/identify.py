"""``impactcli identify LOG -o model.json``: identify a rough rigid model and write it."""

from __future__ import annotations

from typing import Any

import click

from ._common import handle_errors


def format_fit_table(model: Any) -> str:
    """A short per-joint fit table (RMS error in N·m and relative to the torque RMS)."""
    fit = model.fit
    joints = fit["joints"]
    hold = joints.get("holdout")
    cond = fit.get("condition_number")
    head = (
        f"{model.kind} model: {len(model.theta)} parameters, condition number "
        f"{cond:.3g}, fit on {fit['n_samples_fit']} samples"
        + (f", held-back {fit['n_samples_holdout']} samples" if hold
           else " (nothing held back: log too short or --holdout 0)")
    )
    w = max(5, *(len(j) for j in model.joint_names))
    cols = f"{'joint':<{w}}  {'torque RMS':>10}  {'fit RMS':>8}  {'/RMS':>6}  {'/range':>6}"
    if hold:
        cols += f"  {'held RMS':>8}  {'/RMS':>6}  {'/range':>6}"
    lines = [head, cols + "   [N·m]"]
    for j in model.joint_names:
        f = joints["fit"][j]
        row = (f"{j:<{w}}  {f['torque_rms_nm']:>10.4g}  {f['rms_nm']:>8.4g}  "
               f"{_pct(f['rms_rel_torque_rms'])}  {_pct(f['rms_rel_range'])}")
        if hold:
            h = hold[j]
            row += (f"  {h['rms_nm']:>8.4g}  {_pct(h['rms_rel_torque_rms'])}  "
                    f"{_pct(h['rms_rel_range'])}")
        lines.append(row)
    if fit.get("still_joints"):
        lines.append(f"still joints (constant torque only): {', '.join(fit['still_joints'])}")
    if fit.get("unexcited_parameters"):
        lines.append(f"not excited (fixed at 0): {', '.join(fit['unexcited_parameters'])}")
    return "\n".join(lines)


def _pct(x: float | None) -> str:
    return f"{'—':>6}" if x is None else f"{100 * x:>5.1f}%"


@click.command("identify")
@click.argument("log", type=click.Path(path_type=str))
@click.option("-o", "--output", "--out", "output", required=True,
              type=click.Path(dir_okay=False, path_type=str), help="Model file to write (JSON).")
@click.option("--robot", metavar="FILE", type=click.Path(dir_okay=False, path_type=str),
              help="Robot description (joints, kinematics: planar or urdf).")
@click.option("--kind", type=click.Choice(["decoupled", "planar", "urdf"]),
              help="Model structure (default: the robot's kinematics type, else decoupled).")
@click.option("--channel-map", "channel_map", metavar="MAP",
              help="Channel map (JSON/YAML path, or a shipped map's name).")
@click.option("--torque-source", "torque_source", type=click.Choice(["current", "torque"]),
              help="Use logged torque or current × gear ratio × torque constant.")
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
@click.option("--allow-still-joints", "allow_still", is_flag=True,
              help="Model a joint that does not move by its constant torque only "
                   "(default: an error).")
@handle_errors
def identify_cmd(
    log: str, output: str, robot: str | None, kind: str | None, channel_map: str | None,
    torque_source: str | None, cutoff_hz: float, holdout_fraction: float, robust: str,
    coulomb_slope: float, allow_still: bool,
) -> None:
    """Identify a rough rigid model (tau = Y(q, q', q'') theta) from LOG and write it."""
    from .._fs import prepare_output
    from ..io import read_log
    from ..io.robot import read_robot
    from ..model import IdentifyOptions, identify, write_model

    prepare_output(output)  # a bad -o stops the run before any work
    desc = read_robot(robot) if robot else None
    data = read_log(log, channel_map=channel_map, robot=desc, torque_source=torque_source)
    options = IdentifyOptions(cutoff_hz=cutoff_hz, holdout_fraction=holdout_fraction,
                              robust=robust, coulomb_slope_rad_s=coulomb_slope,
                              allow_still_joints=allow_still)
    model = identify(data, robot=desc, kind=kind, options=options)
    write_model(model, output)
    click.echo(format_fit_table(model))
    click.echo(f"wrote {output}")
