"""``impactcli evaluate TIMELINE|LOG [--labels LABELS.json]``: detection quality against labels.

Labels default to ``<stem>.labels.json`` beside the input (as ``impactcli simulate`` writes).

A ``*.json`` input is a detection timeline (``impactcli detect`` output, validated against
schemas/timeline.schema.json); anything else is a log, on which the detectors are replayed
first, with detect's ``--robot/--model/--config`` and log-reading options, chunk by chunk
in bounded memory as ``detect`` replays it (:func:`replay_log`). The matching rules are
:mod:`impactcli.quality`'s.

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

import contextlib
import json
import math
import warnings
from pathlib import Path
from typing import Any

import click
import numpy as np

from ..errors import ImpactWarning, LogFormatError
from .options import (
    check_log_path,
    handle_errors,
    log_read_options,
    model_options,
    not_found,
    read_options_from,
)

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


def signals_beside(timeline: Path) -> Path:
    """``DIR/<stem>.signals.parquet`` for ``DIR/<stem>.timeline.json``."""
    name = timeline.name
    stem = name[: -len(".timeline.json")] if name.endswith(".timeline.json") else timeline.stem
    return timeline.with_name(f"{stem}.signals.parquet")


def labels_beside(source: Path) -> Path:
    """``<stem>.labels.json`` beside a log or a ``<stem>.timeline.json`` (as ``simulate``
    writes them; a rosbag2 folder's are beside the folder, named after it), for a timeline
    then beside the log it records (found as ``report`` finds it), under the timeline's
    stem, then the log's own; a usage error (exit 2) when there is none."""
    from ..logs import log_stem

    name = source.name
    timeline = name.endswith(".timeline.json")
    stem = name[: -len(".timeline.json")] if timeline else log_stem(source)
    cand = source.with_name(f"{stem}.labels.json")
    if cand.is_file():
        return cand
    if timeline:  # then beside the log the timeline records
        from .report import timeline_log_path

        log_path: Path | None
        try:
            log_path = Path(str(json.loads(source.read_text("utf-8"))["input"]["path"]))
        except (OSError, ValueError, KeyError, TypeError):
            log_path = None
        if log_path is not None:
            # a moved log: relative to the timeline, or beside it; else as recorded
            with contextlib.suppress(LogFormatError):
                log_path = timeline_log_path(source, str(log_path))
        if log_path is not None:
            for st in dict.fromkeys((stem, log_stem(log_path))):
                beside_log = log_path.with_name(f"{st}.labels.json")
                if beside_log.is_file():
                    return beside_log
    raise click.UsageError(f"--labels is needed: no {cand.name} beside {source}"
                           + (" or its log" if timeline else ""))


def _events_settings(config: Any) -> dict[str, float]:
    ev = config.get("events") if isinstance(config, dict) else None
    return ev if isinstance(ev, dict) else {}


def _check_rate(labels: Any, rate_hz: float, where: str) -> None:
    if rate_hz > 0 and abs(labels.sample_rate - rate_hz) > 0.05 * rate_hz:
        warnings.warn(
            f"{labels.path}: labels say {labels.sample_rate:g} Hz but {where} runs at "
            f"{rate_hz:g} Hz: are they the labels of this log?", ImpactWarning, stacklevel=2)


def replay_log(path: Path, *, robot: Path | None, model: Path | None, config: Path | None,
               read_options: dict[str, Any], allow_slow: bool = False, sweep: bool = False
               ) -> tuple[Any, Any]:
    """Replay the detectors on the log ``path`` for its evaluation: (result, samples).

    Chunk by chunk (:func:`impactcli.run.job.run_log_from_paths`: a day-long log in bounded memory,
    as ``detect`` replays it); the scores need only the run's events and incidents. The
    sweep needs every sample's ratio to the thresholds: with ``sweep`` the report's
    collector, keeping only the ratios
    (:class:`impactcli.outputs.report.samples.ReportCollector`), spills them to a temporary
    file as the replay goes, and ``samples``
    (:class:`~impactcli.outputs.report.samples.Samples`) sweeps them row group by row
    group; the caller closes ``samples`` (it removes the spill file); without ``sweep`` it
    is None.
    """
    from ..run.job import run_log_from_paths

    return run_log_from_paths(str(path), robot_path=None if robot is None else str(robot),
                       model_path=None if model is None else str(model),
                       config_path=None if config is None else str(config),
                       read_options=read_options, allow_slow=allow_slow, show_progress=True,
                       samples="sweep" if sweep else None)


def _timeline_sweep(source: Path, doc: dict[str, Any], labels: Any, scales: tuple[float, ...],
                    tolerance: Any) -> Any:
    """Sweep from a timeline and the signals Parquet beside it, read row group by row group
    (bounded memory: one replay chunk's rows at a time)."""
    from ..outputs.signals import signal_groups, signals_schema
    from ..quality.sweep import ThresholdSweep, ratios_from_signals
    from ..types import DETECTORS

    sig_path = signals_beside(source)
    if not sig_path.is_file():
        raise click.UsageError(
            f"--sweep needs a LOG, or a timeline with its signals beside it ({sig_path} is "
            "missing: run detect with --signals)")

    def unreadable(err: Exception) -> LogFormatError:
        msg = str(err).splitlines()[0] if str(err) else type(err).__name__
        return LogFormatError(f"{sig_path}: not a readable signals Parquet ({msg})")

    try:
        names, _meta, _ = signals_schema(sig_path)
    except (OSError, ValueError) as err:  # pyarrow's ArrowInvalid is a ValueError
        raise unreadable(err) from err
    joints = list(doc["input"]["joints"])
    thresholds = doc["thresholds"]
    try:  # every column and threshold there before reading any row
        ratios_from_signals({n: np.zeros(0) for n in names}, joints, thresholds)
    except LogFormatError as err:
        raise LogFormatError(f"{sig_path}: {err}") from None
    if "time" not in names:
        raise LogFormatError(f"{sig_path}: column 'time' missing")
    settings = _events_settings(doc["config"])
    try:
        gap, min_dur = float(settings["merge_gap_s"]), float(settings["min_duration_s"])
    except (KeyError, TypeError, ValueError):
        gap = min_dur = math.nan  # refused below, after the check of the decisions
    sweep = None if math.isnan(gap) or math.isnan(min_dur) else ThresholdSweep(
        scales, warmup_end_s=float(doc["warmup_end_s"]), merge_gap_s=gap,
        min_duration_s=min_dur)
    stored = {d: [f"{j}.{d}" for j in joints] for d in DETECTORS}
    stored = {d: keys for d, keys in stored.items() if all(k in names for k in keys)}
    wanted = ["time", *[f"{j}.{c}" for j in joints
                        for c in ("residual_rms", "threshold", "loading_statistic", "residual")],
              *[k for keys in stored.values() for k in keys]]
    differ = dict.fromkeys(stored, 0)
    total = 0
    try:
        for cols in signal_groups(sig_path, wanted):
            ratios = ratios_from_signals(cols, joints, thresholds)
            # the rebuilt ratios must reproduce the run's own decisions at scale 1
            for d, keys in stored.items():
                dec = np.column_stack([np.asarray(cols[k]) != 0 for k in keys])
                differ[d] += int(np.count_nonzero(dec != (ratios[d] > 1.0)))
            total += len(cols["time"]) * len(joints)
            if sweep is not None:
                sweep.update(np.asarray(cols["time"], dtype=np.float64), ratios)
    except (OSError, ValueError) as err:
        raise unreadable(err) from err
    for d, k in differ.items():
        if total and k / total > 1e-3:
            warnings.warn(
                f"{sig_path}: {d} decisions rebuilt from the signals differ from the "
                f"stored ones on {100 * (k / total):.2g}% of samples: the sweep may not match "
                "the run", ImpactWarning, stacklevel=2)
    if sweep is None:
        raise LogFormatError(f"{source}: config.events needs merge_gap_s and min_duration_s "
                             "to re-extract events for --sweep")
    return sweep.rows(labels, tolerance)


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
                 model: Path | None, config: Path | None, channel_map: str | None,
                 topic: str | None, reference_topic: str | None, time_source: str | None,
                 torque_source: str | None, allow_slow: bool = False) -> None:
    """Measure detection quality of a timeline (or a log, detected first) against labels.

    An event matches a contact when it starts within [start - PRE, end + POST]. Events in
    warm-up are listed, never counted; contacts in warm-up are reported, not counted as
    misses. 'product' is adaptive OR static_loading. The incidents (the answer) are scored
    too: link against the label's link, force against peak_force, contact type against the
    kind (impact, push: transient; clamp: quasi_static).
    """
    from ..logs.robot_files import read_labels
    from ..outputs.timeline import read_timeline
    from ..quality.evaluation import evaluate_events, evaluate_result
    from ..quality.match import MatchTolerance
    from ..quality.text import format_evaluation
    from ..quality.verdict import format_sweep, sweep_to_dict

    tolerance = MatchTolerance(pre_s=pre_s, post_s=post_s)
    is_timeline = source.name.lower().endswith(".json")
    read_options = read_options_from(channel_map, topic, reference_topic, time_source,
                                     torque_source)
    if is_timeline and (read_options or any(v is not None for v in (model, config, robot))):
        raise click.UsageError("--robot, --model, --config and the log-reading options apply "
                               "to a LOG, not to a timeline")
    # say so before looking for labels beside it
    if is_timeline and not source.is_file():
        raise (not_found(source, "timeline file") if not source.exists()
               else LogFormatError(f"{source}: a timeline is a file, not a folder"))
    if not is_timeline:
        source = check_log_path(source)  # a file, a rosbag2 folder, a folder's one log
    if labels_path is None:
        labels_path = labels_beside(source)
    labels = read_labels(labels_path)
    rows = None
    if is_timeline:
        doc = read_timeline(source)
        _check_rate(labels, float(doc["input"]["sample_rate_hz"]), str(source))
        gap = float(_events_settings(doc["config"]).get("merge_gap_s", 0.0))
        incidents = doc.get("incidents")
        note = "" if incidents is not None else (
            f"{source} is a {doc.get('schema_version', '1.0')} timeline: it has no incidents "
            "(link, force, contact type) to score; run `impactcli detect` again for them")
        ev = evaluate_events(doc["events"], labels, duration_s=float(doc["input"]["duration_s"]),
                             warmup_end_s=float(doc["warmup_end_s"]), tolerance=tolerance,
                             product_merge_gap_s=gap, incidents=incidents,
                             incidents_note=note)
        if sweep:
            rows = _timeline_sweep(source, doc, labels, scales, tolerance)
    else:
        result, samples = replay_log(source, model=model, config=config, robot=robot,
                                     read_options=read_options, allow_slow=allow_slow,
                                     sweep=sweep)
        try:
            for msg in result.warnings:
                click.echo(f"impactcli: warning: {msg}", err=True)
            _check_rate(labels, result.log.sample_rate_hz, str(source))
            ev = evaluate_result(result, labels, tolerance=tolerance)
            if samples is not None:  # --sweep
                rows = samples.sweep(result, labels, scales, tolerance=tolerance)
        finally:
            if samples is not None:
                samples.close()
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
