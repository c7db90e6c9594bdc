"""``impactcli labels LOG --from-channel NAME --above X --link N -o labels.json``: ground-truth
labels from a logged switch or force sensor (docs/formats.md, "Ground-truth labels").

What a channel name may be and how its stretches above X become contacts:
:mod:`impactcli.logs.channel_labels`. ``--link`` is required: a label names the link
touched (1-based). The file (schemas/labels.schema.json, validated) is written atomically
with its ``source``. Exit 0; 2 bad options; 3 a log or channel that cannot be read (one line
naming the file and what it has).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import click
import numpy as np

from .options import (
    ROBOT_METAVAR,
    check_log_path,
    handle_errors,
    log_read_options,
    robot_help,
)

if TYPE_CHECKING:
    from ..types import ReadOptions

#: How a channel's contacts are labelled (:func:`impactcli.logs.channel_labels.labels_doc`).
CHANNEL_KINDS: tuple[str, ...] = ("auto", "force", "switch")
#: What --link is, in its help and in the message when it is missing.
LINK_HELP = ("the link the contacts are on: 1-based, counted from the base along the robot's "
             "chain (1: the link the first joint moves); a label names the link touched, and "
             "evaluate scores the incidents' link against it")


class _ExplainedOption(click.Option):
    """A required option whose "Missing option" message also says what it is."""

    def __init__(self, *args: Any, missing: str = "", **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.missing = missing

    def process_value(self, ctx: click.Context, value: Any) -> Any:
        try:
            return super().process_value(ctx, value)
        except click.MissingParameter:
            raise click.MissingParameter(message=self.missing, ctx=ctx, param=self) from None


@click.command("labels")
@click.argument("log", type=click.Path(path_type=Path))
@click.option("--from-channel", "channel", required=True, metavar="NAME",
              help="The switch or force channel: a CSV column (one the reader ignores, or "
                   "any), <joint>.<signal>, an .npz array (key or key[i]), or in an MCAP / "
                   "bag a message field /topic/field[i] (or /topic/array[joint]).")
@click.option("--above", type=float, required=True, metavar="X",
              help="A contact is where the channel is above X (in its own unit).")
@click.option("--link", type=click.IntRange(min=1), required=True, metavar="N",
              cls=_ExplainedOption, missing=f"--link N is {LINK_HELP}",
              help=f"The {LINK_HELP[4:]}.")
@click.option("--kind", type=click.Choice(["impact", "push", "clamp"]), default="push",
              show_default=True, help="The contacts' kind.")
@click.option("--channel-kind", "channel_is", type=click.Choice(CHANNEL_KINDS),
              default="auto", show_default=True,
              help="force: peak_force is the channel's peak [N]; switch: no force "
                   "(peak_force_known false); auto: a switch when the channel has two values.")
@click.option("--min-duration", type=click.FloatRange(min=0.0), default=0.0, show_default=True,
              help="Drop stretches shorter than this [s].")
@click.option("--merge-gap", type=click.FloatRange(min=0.0), default=0.0, show_default=True,
              help="Merge stretches this close (last sample to next first sample) [s].")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              required=True, help="The labels JSON to write.")
@click.option("--robot", metavar=ROBOT_METAVAR, type=click.Path(dir_okay=False, path_type=Path),
              default=None, help=robot_help("for a log whose torque comes from currents"))
@log_read_options
@handle_errors
def labels_cmd(log: Path, channel: str, above: float, link: int, kind: str, channel_is: str,
               min_duration: float, merge_gap: float, output: Path, robot: Path | None,
               read_options: ReadOptions) -> None:
    """Make ground-truth labels from a logged switch or force channel.

    Contiguous stretches where the channel is above X become contacts (start and end in
    seconds since the log's first sample); peak_force is the channel's peak for a force,
    unknown for a switch. Writes LABELS.json (schemas/labels.schema.json) for
    `impactcli evaluate LOG --labels LABELS.json`.
    """
    from ..files import prepare_output
    from ..logs.channel_labels import make_labels
    from ..logs.robot_files import read_robot, write_labels

    if not np.isfinite(above):
        raise click.BadParameter(f"{above!r} is not a finite number", param_hint="'--above'")
    prepare_output(output)
    log = check_log_path(log)  # a folder's one log
    desc = read_robot(robot) if robot is not None else None
    doc, labels, ch = make_labels(log, channel, above=above, kind=kind, link=link,
                                  channel_is=channel_is, merge_gap_s=merge_gap,
                                  min_duration_s=min_duration, robot=desc,
                                  read_options=read_options, output=output)
    write_labels(labels, output)
    src = doc["source"]
    click.echo(f"{len(doc['events'])} contact(s) where {channel} > {above:g} "
               f"({ch.what}; a {src['channel_kind']}), kind {kind}, link {link}:")
    for k, e in enumerate(doc["events"]):
        force = (f"peak {e['peak_force']:.4g} N" if src["channel_kind"] == "force"
                 else f"switch value {e['peak_value']:.4g}")
        click.echo(f"  #{k}  {e['start']:.3f}–{e['end']:.3f} s  {force}")
    click.echo(f"wrote {output}")
