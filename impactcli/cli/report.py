"""``impactcli report LOG|TIMELINE... -o report.html [--json report.json] [--labels L]``.

A LOG (any format ``detect`` reads) is replayed with ``detect``'s options (``--robot``,
``--model``, ``--config``, ``--channel-map``); a TIMELINE (``*.timeline.json``) is re-run
from the log it records (as recorded, else beside the timeline) with the read options,
model and config it records (its sha256 checked; events that differ are warned about) —
``--model``/``--config``/``--channel-map`` apply to LOG inputs only. Each replay streams its
chunks to the report's collector (:mod:`impactcli.outputs.report.samples`).

Labels: ``--labels FILE`` may be repeated — named ``<stem>.labels.json`` after distinct
inputs' stems they go by stem, else they pair with the inputs in order; an input without
one gets ``<stem>.labels.json`` from beside its log (a timeline's: beside it, then beside
its log) unless ``--no-auto-labels``. The report names every labels file it used.

A batch where some inputs fail writes the report of the others, lists the failures in it,
and exits 4; when every input fails the first error is raised (exit 3).
"""

# Imports inside functions are deliberate: `impactcli --help` must stay fast.

from __future__ import annotations

import contextlib
import functools
import json
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click

from ..errors import (
    EXIT_BATCH,
    EXIT_SOFTWARE,
    ImpactError,
    ImpactWarning,
    LogFormatError,
    one_line,
)
from .options import (
    executor_options,
    handle_errors,
    is_log_path,
    log_read_options,
    model_options,
    progress,
    read_options_from,
    resolve_executor,
)

TIMELINE_SUFFIX = ".timeline.json"
LABELS_SUFFIX = ".labels.json"
def input_stem(path: Path) -> str:
    """The stem outputs are named by (``x.csv.gz`` → ``x``, ``x.timeline.json`` → ``x``, a
    rosbag2 folder ``run/`` → ``run``)."""
    from ..outputs.report import log_stem

    return log_stem(str(path))


def is_timeline(path: Path) -> bool:
    """Whether ``path`` names a detection timeline (``*.timeline.json``)."""
    return path.name.lower().endswith(TIMELINE_SUFFIX)


def _read_robot(path: str | Path | None) -> Any:
    if path is None:
        return None
    from ..logs.robot_files import read_robot

    return read_robot(path)


def load_inputs(robot: Path | None, model: Path | None,
                config: Path | None) -> tuple[Any, Any, Any]:
    """Read --robot, --model and --config once (a bad one stops the run before any work)."""
    from ..config import load_config
    from ..model import read_model

    return (_read_robot(robot), read_model(model) if model is not None else None,
            load_config(config) if config is not None else None)


def timeline_log_path(tl_path: Path, recorded: str, absolute: str | None = None) -> Path:
    """The log a timeline records — a file or a rosbag2 folder: as recorded (relative to the
    working folder), else at its recorded absolute path (timeline 2.x ``input.abs_path``),
    else relative to the timeline's folder, else its name beside the timeline."""
    rec = Path(recorded)
    if absolute is None:
        with contextlib.suppress(OSError, ValueError, KeyError, TypeError):
            absolute = json.loads(tl_path.read_text("utf-8"))["input"].get("abs_path")
    cands = [rec] + ([Path(absolute)] if absolute and "://" not in absolute else [])
    for cand in (*cands, tl_path.parent / rec, tl_path.parent / rec.name):
        if is_log_path(cand):
            return cand
    raise LogFormatError(
        f"{tl_path}: the log it records, {recorded}, is not found (looked "
        f"in the working folder and beside the timeline)"
    )


def _timeline_plan(tl_path: Path, robot: Any) -> dict[str, Any]:
    """What a timeline records for a re-run (see :func:`analyze_for_report`): the timeline,
    its log, read options, config, model, whether the model comes from the log, and the
    robot."""
    from ..config import DetectorConfig
    from ..logs.paths import RECORDED_READ_OPTIONS  # what input.read_options may carry
    from ..logs.robot_files import robot_from_dict
    from ..model import RigidModel
    from ..outputs.timeline import read_timeline

    tl = read_timeline(tl_path)
    inp = tl["input"]
    log_path = timeline_log_path(tl_path, inp["path"], inp.get("abs_path"))
    opts = dict(inp.get("read_options") or {})
    unknown = sorted(set(opts) - set(RECORDED_READ_OPTIONS))
    if unknown:
        warnings.warn(f"{tl_path}: read options {unknown} not understood by report; ignored",
                      ImpactWarning, stacklevel=3)
    kwargs = {k: opts[k] for k in RECORDED_READ_OPTIONS if opts.get(k) is not None}
    tl_model = tl["model"] or {"source": "none", "model": {}}
    recorded_model = tl_model["model"] or {}
    if robot is None and isinstance(recorded_model.get("robot"), dict):
        robot = robot_from_dict(recorded_model["robot"], f"{tl_path}: model.robot")
    config = DetectorConfig.from_dict(tl["config"], where=f"{tl_path}: config")
    model = None
    if tl_model["source"] == "given":
        model = RigidModel.from_dict(recorded_model, where=f"{tl_path}: model")
    # a config's thresholds with a model identified from the log (detect --model-from-log)
    from_log = tl_model["source"] == "identified-from-log" and config.model is not None
    return {"tl": tl, "log_path": log_path, "read_options": kwargs, "config": config,
            "model": model, "model_from_log": from_log, "robot": robot}


def _check_sha(tl_path: Path, plan: dict[str, Any], sha256: str | None) -> None:
    """The log must be the one the timeline was made from."""
    rec = plan["tl"]["input"].get("sha256")
    if rec and sha256 and sha256 != rec:
        raise LogFormatError(
            f"{tl_path}: its log {plan['log_path']} changed since detection "
            f"(sha256 {sha256[:12]}…, recorded {rec[:12]}…)"
        )


def _compare_events(tl_path: Path, tl: dict[str, Any], result: Any) -> None:
    """Warn when the re-run's events or calibration differ from the recorded ones."""
    recorded = [(e["detector"], round(e["t_start"], 9), round(e["t_end"], 9), tuple(e["joints"]))
                for e in tl["events"]]
    now = [(e.detector, round(e.t_start, 9), round(e.t_end, 9), tuple(e.joints))
           for e in result.events]
    if recorded != now or bool(tl["calibrated"]) != bool(result.calibrated):
        warnings.warn(
            f"{tl_path}: re-running detection gave {len(now)} event(s) where the timeline "
            f"records {len(recorded)} (or a different calibration); the report shows the re-run",
            ImpactWarning, stacklevel=3)


def analyze_for_report(task: ReportTask, robot: Any, model: Any, config: Any
                       ) -> tuple[Any, Path, Any, dict[str, Any] | None]:
    """(result, log path, samples, origin) of one report input, replayed chunk by chunk
    (:func:`impactcli.run.job.run_log`: bounded memory, collecting what its report plots).

    A LOG is detected with the loaded ``robot``, ``model`` and ``config``; a TIMELINE is
    re-run as it records it: the log read with the recorded read options, sha256 checked;
    the model the recorded one when it was given (a config's model comes with the config;
    an identified one is identified again, deterministically); the recorded config;
    ``robot`` when given, else the description embedded in the recorded model. The caller
    closes the samples.
    """
    from ..run.job import run_log

    inp = Path(task.inp)
    if is_timeline(inp):
        plan = _timeline_plan(inp, robot)
        origin = timeline_origin(inp)
        result, samples = run_log(
            str(plan["log_path"]), robot=plan["robot"], model=plan["model"],
            config=plan["config"], read_options=plan["read_options"],
            allow_slow=task.allow_slow, show_progress=task.show_progress,
            model_from_log=plan["model_from_log"], samples="report",
            check=lambda scan: _check_sha(inp, plan, scan.source.sha256))
        try:
            _compare_events(inp, plan["tl"], result)
        except BaseException:
            samples.close()
            raise
        return result, plan["log_path"], samples, origin
    result, samples = run_log(str(inp), robot=robot, model=model, config=config,
                                 read_options=task.read_options, allow_slow=task.allow_slow,
                                 show_progress=task.show_progress, samples="report")
    return result, inp, samples, None


def timeline_origin(tl_path: Path) -> dict[str, Any]:
    """Where a re-run came from, for the report: the timeline, its schema version and the
    tool that wrote it (a "1.0" timeline records no incidents; the report says so)."""
    from ..outputs.timeline import read_timeline

    tl = read_timeline(tl_path)
    tool = tl.get("tool") or {}
    return {"timeline": str(tl_path), "timeline_schema_version": str(tl["schema_version"]),
            "recorded_by": f"{tool.get('name', '?')} {tool.get('version', '?')}",
            "recorded_incidents": (len(tl["incidents"]) if isinstance(tl.get("incidents"), list)
                                   else None)}


def pair_labels(inputs: Sequence[Path], labels: Sequence[Path]) -> list[Path | None]:
    """Explicit ``--labels`` files per input (rule 1 of the module docstring)."""
    out: list[Path | None] = [None] * len(inputs)
    if not labels:
        return out
    stems = [input_stem(p) for p in inputs]
    by_name = []
    for lab in labels:
        name = lab.name
        st = name[: -len(LABELS_SUFFIX)] if name.lower().endswith(LABELS_SUFFIX) else None
        by_name.append(st if st is not None and stems.count(st) == 1 else None)
    if all(s is not None for s in by_name) and len(set(by_name)) == len(by_name):
        for lab, st in zip(labels, by_name, strict=True):
            out[stems.index(st)] = lab  # type: ignore[arg-type]
        return out
    if len(labels) == len(inputs):
        return list(labels)
    raise click.BadParameter(
        f"{len(labels)} labels file(s) for {len(inputs)} input(s): give one per input (in "
        "order) or name each <stem>.labels.json after its input",
        param_hint="'--labels'",
    )


def auto_labels(inp: Path, log_path: Path | None) -> Path | None:
    """``<stem>.labels.json`` beside the input, then beside its log (under the input's stem,
    then the log's), if present; a rosbag2 folder's are beside the folder, named after it."""
    stem = input_stem(inp)
    cands = [inp.parent / f"{stem}{LABELS_SUFFIX}"]
    if log_path is not None:
        cands += [log_path.parent / f"{st}{LABELS_SUFFIX}"
                  for st in (stem, input_stem(log_path))]
    return next((c for c in dict.fromkeys(cands) if c.is_file()), None)


@dataclass(frozen=True)
class ReportTask:
    """One report input for a worker (picklable: paths and plain values); ``key`` is its
    input index."""

    inp: str
    labels: str | None
    auto_labels: bool
    robot: str | None
    model: str | None
    config: str | None
    read_options: dict[str, Any]
    key: int = 0
    allow_slow: bool = False
    show_progress: bool = False


@dataclass(frozen=True)
class ReportPart:
    """What a worker sends back: the rendered log (small — never the per-sample signals),
    the run's own warnings, the warnings raised on the way, or the error."""

    rendered: Any
    run_warnings: tuple[str, ...]
    messages: tuple[str, ...]
    error: ImpactError | None


@functools.lru_cache(maxsize=8)
def _loaded(robot: str | None, model: str | None, config: str | None) -> tuple[Any, Any, Any]:
    """robot, model, config read once per worker process."""
    return load_inputs(Path(robot) if robot else None, Path(model) if model else None,
                       Path(config) if config else None)


def analyze_input(task: ReportTask) -> ReportPart:
    """Analyse and render one report input in any worker.

    A LOG is detected, a TIMELINE re-run, in bounded memory (:func:`analyze_for_report`);
    the labels are the given
    file, else ``<stem>.labels.json`` found beside it when ``auto_labels``; the log's section
    is rendered here (:func:`impactcli.outputs.report.render_log`), so only it travels back.
    Warnings raised on the way come back as messages; an ImpactError comes back as the error.
    """
    from ..logs.robot_files import read_labels
    from ..outputs.report import render_log

    inp = Path(task.inp)
    rendered, run_warnings, err = None, (), None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ImpactWarning)
        samples = None
        try:
            robot_obj, model_obj, config_obj = _loaded(task.robot, task.model, task.config)
            result, log_path, samples, origin = analyze_for_report(task, robot_obj, model_obj,
                                                                   config_obj)
            lab_path = Path(task.labels) if task.labels else None
            if lab_path is None and task.auto_labels:
                lab_path = auto_labels(inp, log_path)
            lab = read_labels(lab_path) if lab_path is not None else None
            rendered = render_log(result, lab, task.key, origin=origin, samples=samples)
            run_warnings = result.warnings
        except ImpactError as e:
            err = e
        finally:
            if samples is not None:
                samples.close()
    msgs = tuple(str(w.message) for w in caught if issubclass(w.category, ImpactWarning))
    return ReportPart(rendered, tuple(run_warnings), msgs, err)


def _local_inputs(patterns: Sequence[str]) -> tuple[Path, ...]:
    """Inputs as local paths: globs expanded, ``file://`` URLs resolved; a remote URL is a
    usage error (download it first: the report reads its logs beside the timelines)."""
    from ..logs.urls import expand_inputs, local_path

    out = []
    for item in expand_inputs(patterns):
        local = local_path(item)
        if local is None:
            raise click.UsageError(f"{item}: report inputs must be local files or file:// "
                                   "URLs (download remote ones first)")
        out.append(local)
    return tuple(out)


@click.command("report")
@click.argument("inputs", nargs=-1, required=True)
@click.option("-o", "--output", "--out", "html_path", required=True,
              type=click.Path(dir_okay=False, path_type=Path), help="The HTML report to write.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Also write the same facts as JSON (schemas/report.schema.json).")
@click.option("--labels", "labels", multiple=True,
              type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Ground-truth labels JSON; repeat per input (in order, or named "
                   "<stem>.labels.json).")
@click.option("--no-auto-labels", is_flag=True,
              help="Do not pick up <stem>.labels.json files found beside the inputs.")
@model_options
@log_read_options
@click.option("--allow-slow", is_flag=True,
              help="Run a replay estimated slower than real time or above 2 GiB of "
                   "covariance (many joints: the adaptive evaluator's cost grows with the "
                   "cube of the joint count), as detect --allow-slow.")
@executor_options
@handle_errors
def report_cmd(*, inputs: tuple[str, ...], html_path: Path, json_path: Path | None,
               labels: tuple[Path, ...], no_auto_labels: bool, robot: Path | None,
               model: Path | None, config: Path | None, channel_map: str | None,
               topic: str | None, reference_topic: str | None, time_source: str | None,
               torque_source: str | None, allow_slow: bool = False, jobs: int | None = None,
               scheduler: str | None = None) -> None:
    """Write a safety-audit report: one self-contained HTML file (and --json) over LOGs or
    TIMELINEs — per log a verdict and the incidents (when, where, how hard, what kind),
    what the audit could not see, plots around each incident, caveats, what was analysed
    with what, the events per detector, and detection quality when labels are given.

    A LOG is detected first with the options below; a TIMELINE (*.timeline.json) is re-run
    from its log with the read options, model and config it records (--robot still
    applies). Labels: --labels per input (in order, or named <stem>.labels.json), else
    <stem>.labels.json found beside the input. Exit 4 when some inputs failed (the report
    lists them), 3 when all did. --jobs/--scheduler analyse the inputs in parallel (as
    detect does); the report is the same.
    """
    from ..files import prepare_output
    from ..outputs.report import write_report
    from ..run.executors import TaskFailure, run_tasks

    for out in (html_path, json_path):  # a bad -o/--json stops the run before any work
        if out is not None:
            prepare_output(out)
    paths = _local_inputs(inputs)
    explicit = pair_labels(paths, labels)
    resolve_executor(jobs, scheduler)
    load_inputs(robot, model, config)  # a bad one stops the run before any work
    ropts = read_options_from(channel_map, topic, reference_topic, time_source, torque_source)
    log_only = [n for n, v in (("--model", model), ("--config", config)) if v is not None]
    log_only += [f"--{k.replace('_', '-')}" for k in ropts]
    if log_only and any(is_timeline(p) for p in paths):
        warnings.warn(f"{', '.join(log_only)} apply to LOG inputs only: a TIMELINE is re-run "
                      "with the read options, model and config it records", ImpactWarning,
                      stacklevel=2)
    tasks = [ReportTask(str(inp), str(lab) if lab is not None else None, not no_auto_labels,
                        str(robot) if robot else None, str(model) if model else None,
                        str(config) if config else None, ropts, k, allow_slow,
                        (jobs or 1) == 1 and scheduler is None)
             for k, (inp, lab) in enumerate(zip(paths, explicit, strict=True))]
    done: dict[int, Any] = {}
    errors: dict[int, ImpactError] = {}
    stream = run_tasks(analyze_input, tasks, jobs=jobs, scheduler=scheduler)
    for i, res in progress(stream, total=len(tasks), desc="report"):
        if isinstance(res, TaskFailure):
            click.echo(one_line(f"impactcli: error: {paths[i]}: {res.reason}"), err=True)
            if res.traceback:  # a bug: keep its traceback
                click.echo(res.traceback.rstrip(), err=True)
            err = ImpactError(f"{paths[i]}: {res.reason}")
            err.exit_code = EXIT_SOFTWARE  # a bug or a lost worker: never a data error
            errors[i] = err
            continue
        for m in res.messages:
            click.echo(one_line(f"impactcli: warning: {m}"), err=True)
        if res.error is not None:
            click.echo(one_line(f"impactcli: error: {res.error}"), err=True)
            errors[i] = res.error
            continue
        for w in res.run_warnings:
            click.echo(one_line(f"impactcli: warning: {w}"), err=True)
        done[i] = res.rendered
    results = [done[i] for i in sorted(done)]  # input order, whatever finished first
    failed = [(paths[i], errors[i]) for i in sorted(errors)]
    if not results:  # every input failed: each was reported above; nothing is written
        click.get_current_context().exit(failed[0][1].exit_code)
    write_report(results, html_path, json_path,
                 failed=[(str(p), str(e)) for p, e in failed])
    click.echo(f"impactcli: report of {len(results)} log(s) written to {html_path}"
               + (f" and {json_path}" if json_path else ""), err=True)
    if failed:
        click.get_current_context().exit(EXIT_BATCH)
