"""``impactcli simulate``: a simulated flexible-joint arm log with ground-truth labels."""

from __future__ import annotations

from pathlib import Path

import click

from .options import handle_errors

FORMATS = {"csv": ".csv", "csv.gz": ".csv.gz", "mcap-json": ".mcap", "mcap-ros2": ".mcap"}
ARMS = ("assist_like", "heavy_geared")
SCENARIO_NAMES = ("free_triangle", "free_fm_triangle", "free_p2p", "free_multisine",
                  "impacts", "pushes", "clamps", "payload", "pick_and_place")


@click.command("simulate")
@click.option("--arm", type=click.Choice(ARMS), default="assist_like", show_default=True,
              help="Arm preset (numbers in impactcli.sim.arm).")
@click.option("--scenario", "scenario_name", type=click.Choice(SCENARIO_NAMES),
              default="impacts", show_default=True, help="Named scenario.")
@click.option("--duration", type=click.FloatRange(min=0.1), default=None,
              help="Duration [s] (default 60 s; impacts: as long as its impacts take).")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Random seed (same seed, same files).")
@click.option("--robot-seed", type=int, default=None,
              help="Seed of the true robot alone: runs with the same --robot-seed simulate "
                   "the same physical robot [default: drawn from --seed].")
@click.option("--payload-kg", type=click.FloatRange(min=0.0), default=None,
              help="Unknown end-effector payload carried from the start [kg] (default: the "
                   "scenario's). pick_and_place still sets the load to its own at the pick "
                   "(1 kg on assist_like, 2 kg on heavy_geared) and to 0 kg at the release, "
                   "whatever this is: with this above that, the 'pick' is a release (the "
                   "labels' payload_changes say so).")
@click.option("--uncertainty", type=click.FloatRange(0.0, 0.9), default=None,
              help="Relative spread of the true parameters around nominal (default 0.2).")
@click.option("-o", "--output", "--out", "outdir", type=click.Path(file_okay=False, path_type=Path),
              required=True, help="Output folder (created).")
@click.option("--format", "formats", type=click.Choice(list(FORMATS)), multiple=True,
              default=("csv.gz",), show_default=True,
              help="Log format(s); repeat for several (mcap-json and mcap-ros2 exclude "
                   "each other: both write NAME.mcap).")
@click.option("--name", default=None, help="File stem (default: the scenario name).")
@click.option("--controller-channels/--no-controller-channels", "controller_channels",
              default=None,
              help="Also log the controller's own channels <joint>.torque_model and "
                   "<joint>.torque_ext (its nominal model's torque and its external-torque "
                   "estimate; docs/controller_channels.md) [default: on for assist_like, "
                   "off for heavy_geared, as in the sample logs].")
@handle_errors
def simulate_cmd(arm: str, scenario_name: str, duration: float | None, seed: int,
                 robot_seed: int | None, payload_kg: float | None,
                 uncertainty: float | None, outdir: Path, formats: tuple[str, ...],
                 name: str | None, controller_channels: bool | None) -> None:
    """Simulate a flexible-joint arm (the paper's eq. 1–2) with labelled contacts.

    Writes OUTDIR/NAME.<ext> per format, NAME.labels.json (ground truth) and
    NAME.robot.json (the NOMINAL robot description, which the true robot does not match).
    """
    if "mcap-json" in formats and "mcap-ros2" in formats:
        raise click.BadParameter("mcap-json and mcap-ros2 both write NAME.mcap; choose one",
                                 param_hint="--format")
    from ..logs import write_log
    from ..logs.robot_files import write_labels, write_robot
    from ..sim import scenario, simulate
    from ..sim.sample_logs import CONTROLLER_CHANNEL_ARMS

    if controller_channels is None:  # as the sample logs of this arm
        controller_channels = arm in CONTROLLER_CHANNEL_ARMS
    overrides: dict[str, float | int | bool] = {"controller_channels": controller_channels}
    if robot_seed is not None:
        overrides["robot_seed"] = robot_seed
    if payload_kg is not None:
        overrides["payload_kg"] = payload_kg
    if uncertainty is not None:
        overrides["uncertainty"] = uncertainty
    from ..files import prepare_output

    stem = name or scenario_name
    logs = {fmt: outdir / f"{stem}{FORMATS[fmt]}" for fmt in dict.fromkeys(formats)}
    labels_path = outdir / f"{stem}.labels.json"
    robot_path = outdir / f"{stem}.robot.json"
    for path in (*logs.values(), labels_path, robot_path):  # before the work: exit 2
        prepare_output(path)
    sc = scenario(scenario_name, arm, duration, **overrides)
    result = simulate(sc, seed=seed)
    written = []
    for fmt, path in logs.items():
        write_log(result.log, path, mcap_encoding="ros2" if fmt == "mcap-ros2" else "json")
        written.append(path)
    write_labels(result.labels, labels_path)
    write_robot(result.robot, robot_path)
    written += [labels_path, robot_path]
    load = (f", carrying {sc.payload_kg:g} kg at the flange from the start"
            if sc.payload_kg else "")
    moves = ("" if not sc.payload_changes else "; the load set to " + ", ".join(
        f"{kg:g} kg at {t:.3f} s" for t, kg in sc.payload_changes))
    click.echo(
        f"simulated {arm}/{scenario_name}: {result.log.duration_s:.1f} s at "
        f"{result.log.sample_rate_hz:.0f} Hz, {len(result.labels.events)} labelled contact(s)"
        f"{load}{moves}"
    )
    for p in written:
        click.echo(str(p))
