"""What ``impactcli evaluate`` computes: detection quality of a timeline, or of a log
replayed first, against ground-truth labels (:func:`evaluate_source`), and the threshold
sweep (from the replay's ratios, or from a timeline's signals Parquet read row group by row
group). The matching rules are :mod:`impactcli.quality`'s.

A log is replayed with detect's ``--robot/--model/--config`` and log-reading options,
chunk by chunk in bounded memory as ``detect`` replays it (:func:`replay_log`). Labels
default to ``<stem>.labels.json`` beside the input (:func:`labels_beside`).
"""

from __future__ import annotations

import contextlib
import json
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ImpactWarning, LogFormatError, UsageProblem
from ..logs.paths import log_stem
from ..types import ReadOptions
from .job import run_log_from_paths
from .report_inputs import timeline_log_path


@dataclass(frozen=True)
class Evaluated:
    """What ``evaluate`` prints: the scores (:class:`impactcli.quality.evaluation`'s), and
    the sweep's rows with ``--sweep`` (else None)."""

    evaluation: Any
    sweep_rows: Any


def signals_beside(timeline: Path) -> Path:
    """``DIR/<stem>.signals.parquet`` for ``DIR/<stem>.timeline.json``."""
    return timeline.with_name(f"{log_stem(timeline)}.signals.parquet")


def labels_beside(source: Path) -> Path:
    """``<stem>.labels.json`` beside a log or a ``<stem>.timeline.json`` (as ``simulate``
    writes them; a rosbag2 folder's are beside the folder, named after it), for a timeline
    then beside the log it records (found as ``report`` finds it), under the timeline's
    stem, then the log's own; a usage error (exit 2) when there is none."""
    timeline = source.name.endswith(".timeline.json")
    stem = log_stem(source)
    cand = source.with_name(f"{stem}.labels.json")
    if cand.is_file():
        return cand
    if timeline:  # then beside the log the timeline records
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
    raise UsageProblem(f"--labels is needed: no {cand.name} beside {source}"
                       + (" or its log" if timeline else ""))


def events_settings(config: Any) -> dict[str, float]:
    ev = config.get("events") if isinstance(config, dict) else None
    return ev if isinstance(ev, dict) else {}


def check_rate(labels: Any, sample_rate_hz: float, where: str) -> None:
    if sample_rate_hz > 0 and abs(labels.sample_rate - sample_rate_hz) > 0.05 * sample_rate_hz:
        warnings.warn(
            f"{labels.path}: labels say {labels.sample_rate:g} Hz but {where} runs at "
            f"{sample_rate_hz:g} Hz: are they the labels of this log?", ImpactWarning, stacklevel=2)


def check_links(labels: Any, doc: dict[str, Any], where: str) -> None:
    """:func:`impactcli.logs.robot_files.check_label_links` against a timeline's arm: its
    logged joints, those left out of detection, and the links its detection floor lists."""
    from ..logs.robot_files import check_label_links

    inp = doc.get("input") or {}
    names = [*inp.get("joints", ()), *(x.get("name") for x in inp.get("joints_left_out", ()))]
    check_label_links(labels, names, doc.get("detection_floor"), where)


def replay_log(path: Path, *, robot: Path | None, model: Path | None, config: Path | None,
               read_options: ReadOptions, allow_slow: bool = False, sweep: bool = False
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
    return run_log_from_paths(str(path), robot_path=None if robot is None else str(robot),
                       model_path=None if model is None else str(model),
                       config_path=None if config is None else str(config),
                       read_options=read_options, allow_slow=allow_slow, show_progress=True,
                       samples="sweep" if sweep else None)


def timeline_sweep(source: Path, doc: dict[str, Any], labels: Any, scales: tuple[float, ...],
                    tolerance: Any) -> Any:
    """Sweep from a timeline and the signals Parquet beside it, read row group by row group
    (bounded memory: one replay chunk's rows at a time)."""
    from ..outputs.signals import signal_groups, signals_schema
    from ..quality.sweep import ThresholdSweep, ratios_from_signals
    from ..types import DETECTORS

    sig_path = signals_beside(source)
    if not sig_path.is_file():
        raise UsageProblem(
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
    settings = events_settings(doc["config"])
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
    return sweep.rows(labels, tolerance, list(doc.get("payload_changes") or ()))


def evaluate_source(source: Path, labels_path: Path | None, *, is_timeline: bool,
                    tolerance: Any, sweep: bool, scales: tuple[float, ...],
                    robot: Path | None, model: Path | None, config: Path | None,
                    read_options: ReadOptions, allow_slow: bool,
                    say: Callable[[str], None]) -> Evaluated:
    """Score a timeline (or a log, replayed first) against its labels (``labels_path``, else
    the ones beside it); ``say`` gets the replay's own warnings as they are known."""
    from ..logs.robot_files import read_labels
    from ..outputs.timeline import read_timeline
    from ..quality.evaluation import evaluate_events, evaluate_result, with_payload_changes

    if labels_path is None:
        labels_path = labels_beside(source)
    labels = read_labels(labels_path)
    rows = None
    if is_timeline:
        doc = read_timeline(source)
        check_rate(labels, float(doc["input"]["sample_rate_hz"]), str(source))
        check_links(labels, doc, str(source))
        gap = float(events_settings(doc["config"]).get("merge_gap_s", 0.0))
        incidents = doc.get("incidents")
        note = "" if incidents is not None else (
            f"{source} is a {doc.get('schema_version', '1.0')} timeline: it has no incidents "
            "(link, force, contact type) to score; run `impactcli detect` again for them")
        ev = evaluate_events(doc["events"], labels, duration_s=float(doc["input"]["duration_s"]),
                             warmup_end_s=float(doc["warmup_end_s"]), tolerance=tolerance,
                             product_merge_gap_s=gap, incidents=incidents,
                             incidents_note=note,
                             truncated=bool(doc["input"].get("truncated", False)))
        ev = with_payload_changes(ev, labels, doc.get("payload_changes"))
        if sweep:
            rows = timeline_sweep(source, doc, labels, scales, tolerance)
        return Evaluated(ev, rows)
    result, samples = replay_log(source, model=model, config=config, robot=robot,
                                 read_options=read_options, allow_slow=allow_slow,
                                 sweep=sweep)
    try:
        for msg in result.warnings:
            say(msg)
        check_rate(labels, result.log.sample_rate_hz, str(source))
        check_links(labels, {"input": {"joints": list(result.log.joint_names)},
                             "detection_floor": result.detection_floor}, str(source))
        ev = with_payload_changes(evaluate_result(result, labels, tolerance=tolerance),
                                  labels, result.payload_changes)
        if samples is not None:  # --sweep
            rows = samples.sweep(result, labels, scales, tolerance=tolerance)
    finally:
        if samples is not None:
            samples.close()
    return Evaluated(ev, rows)
