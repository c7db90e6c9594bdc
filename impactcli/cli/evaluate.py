"""``impactcli evaluate TIMELINE|LOG [--labels LABELS.json]``: detection quality against labels.

Labels default to ``<stem>.labels.json`` beside the input (as ``impactcli simulate`` writes).

A ``*.json`` input is a detection timeline (``impactcli detect`` output, validated against
schemas/timeline.schema.json); anything else is a log, on which the detectors are replayed
first, with detect's ``--robot/--model/--config`` and log-reading options, chunk by chunk
in bounded memory as ``detect`` replays it (:mod:`impactcli.run.evaluate_run` computes; this
verb parses and prints). The matching rules are :mod:`impactcli.quality`'s.

The incidents (link, force, contact type) are scored too: a timeline's ``incidents`` (a
1.0 timeline has none, and the output says so), or for a log the run's own.
``--sweep`` rescales every threshold over ``--scales`` and reports, per detector, the
smallest scale with zero false alarms and what it still detects, then a one-sentence
verdict: does the adaptive detector help on this robot and log? It needs the per-sample
ratios: a LOG (collected as the replay goes), or a timeline with its
``<stem>.signals.parquet`` beside it (``detect --signals``), read row group by row group.

Output: a text table, or with ``--json`` one JSON object on stdout
(schemas/evaluation.schema.json). Exit 0; 2 bad options; 3 bad timeline, log or labels;
70 an internal error (a bug).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import click

from ..errors import LogFormatError
from .options import (
    check_log_path,
    handle_errors,
    log_read_options,
    model_options,
    not_found,
)

if TYPE_CHECKING:
    from ..types import ReadOptions

#: impactcli.quality.sweep.DEFAULT_SWEEP_SCALES: 0.2 … 5 in 5 % steps (66 scales).
DEFAULT_SCALES = "0.2:5:x1.05"


def parse_scales(text: str) -> tuple[float, ...]:
    """Threshold scales from ``"a:b:step"`` (linear), ``"a:b:xF"`` (geometric, factor F > 1),
    both inclusive of b, or ``"s1,s2,..."`` → sorted positive scales.

    Raises ValueError with a one-line message on anything else.
    """
    from ..quality.sweep import geometric_scales

    text = text.strip()
    try:
        if ":" in text:
            parts = text.split(":")
            if len(parts) != 3:
                raise ValueError
            a, b = float(parts[0]), float(parts[1])
            last = parts[2].strip()
            if last.lower().startswith("x"):
                values = list(geometric_scales(a, b, float(last[1:])))
            else:
                step = float(last)
                if not (b >= a > 0 and step > 0):
                    raise ValueError
                n = math.floor((b - a) / step + 1e-9)
                if n > 10_000:
                    raise ValueError
                values = [round(a + k * step, 9) for k in range(n + 1)]
        else:
            values = [float(p) for p in text.split(",") if p.strip()]
    except (ValueError, OverflowError, ZeroDivisionError):
        raise ValueError(f"{text!r} is not 'start:stop:step', 'start:stop:xfactor' or a "
                         "comma-separated list") from None
    if not values or any(not (math.isfinite(v) and v > 0) for v in values):
        raise ValueError(f"{text!r}: scales must be positive numbers")
    return tuple(sorted(set(values)))


def _scales_option(ctx: click.Context, param: click.Parameter, value: str) -> tuple[float, ...]:
    try:
        return parse_scales(value)
    except ValueError as err:
        raise click.BadParameter(str(err)) from None


@click.command("evaluate")
@click.argument("source", type=click.Path(path_type=Path), metavar="TIMELINE|LOG")
@click.option("--labels", "labels_path", default=None,
              type=click.Path(dir_okay=False, path_type=Path),
              help="Ground-truth labels JSON (schemas/labels.schema.json) "
                   "[default: <stem>.labels.json beside the input].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
@click.option("--sweep", is_flag=True,
              help="Sweep threshold scales; compare detectors at zero false alarms "
                   "(needs a LOG, or a timeline with its .signals.parquet beside it).")
@click.option("--scales", default=DEFAULT_SCALES, show_default=True, callback=_scales_option,
              help="Threshold scales for --sweep: 'start:stop:step', 'start:stop:xfactor' "
                   "(geometric) or 's1,s2,...'.")
@click.option("--pre", "pre_s", type=click.FloatRange(min=0.0), default=0.02, show_default=True,
              help="An alarm up to this long before a contact's start matches it [s].")
@click.option("--post", "post_s", type=click.FloatRange(min=0.0), default=0.25,
              show_default=True,
              help="An alarm up to this long after a contact's end matches it (release) [s].")
@model_options
@log_read_options
@click.option("--allow-slow", is_flag=True,
              help="With a LOG: run a replay estimated slower than real time or above 2 GiB "
                   "of covariance (many joints: the adaptive evaluator's cost grows with the "
                   "cube of the joint count), as detect --allow-slow.")
@handle_errors
def evaluate_cmd(source: Path, labels_path: Path | None, as_json: bool, sweep: bool,
                 scales: tuple[float, ...], pre_s: float, post_s: float, robot: Path | None,
                 model: Path | None, config: Path | None, read_options: ReadOptions,
                 allow_slow: bool = False) -> None:
    """Measure detection quality of a timeline (or a log, detected first) against labels.

    An event matches a contact when it starts within [start - PRE, end + POST]. Events in
    warm-up are listed, never counted; contacts in warm-up are reported, not counted as
    misses. 'product' is adaptive OR static_loading. The incidents (the answer) are scored
    too: link against the label's link, force against peak_force, contact type against the
    kind (impact, push: transient; clamp: quasi_static).
    """
    from ..quality.match import MatchTolerance
    from ..quality.text import format_evaluation
    from ..quality.verdict import format_sweep, sweep_to_dict
    from ..run.evaluate_run import evaluate_source

    tolerance = MatchTolerance(pre_s=pre_s, post_s=post_s)
    is_timeline = source.name.lower().endswith(".json")
    log_only = (read_options.as_dict(), model, config, robot)
    if is_timeline and (log_only[0] or any(v is not None for v in log_only[1:])):
        raise click.UsageError("--robot, --model, --config and the log-reading options apply "
                               "to a LOG, not to a timeline")
    # say so before looking for labels beside it
    if is_timeline and not source.is_file():
        raise (not_found(source, "timeline file") if not source.exists()
               else LogFormatError(f"{source}: a timeline is a file, not a folder"))
    if not is_timeline:
        source = check_log_path(source)  # a file, a rosbag2 folder, a folder's one log
    done = evaluate_source(
        source, labels_path, is_timeline=is_timeline, tolerance=tolerance, sweep=sweep,
        scales=scales, robot=robot, model=model, config=config, read_options=read_options,
        allow_slow=allow_slow, say=lambda m: click.echo(f"impactcli: warning: {m}", err=True))
    ev, rows = done.evaluation, done.sweep_rows
    if as_json:
        out = ev.to_dict()
        out["input"] = str(source)
        if rows is not None:
            out["sweep"] = sweep_to_dict(rows)
        click.echo(json.dumps(out, sort_keys=True, indent=1, allow_nan=False))
    else:
        click.echo(format_evaluation(ev), nl=False)
        if rows is not None:
            click.echo("")
            click.echo(format_sweep(rows), nl=False)
