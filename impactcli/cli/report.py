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

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from ..errors import EXIT_BATCH, EXIT_SOFTWARE, ImpactError, ImpactWarning, one_line
from .options import (
    executor_options,
    fail_usage,
    handle_errors,
    log_read_options,
    model_options,
    progress,
    resolve_executor,
)

if TYPE_CHECKING:
    from ..types import ReadOptions


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
               model: Path | None, config: Path | None, read_options: ReadOptions,
               allow_slow: bool = False, jobs: int | None = None,
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
    from ..run.job import load_inputs
    from ..run.report_inputs import (
        ReportTask,
        analyze_input,
        is_timeline,
        local_inputs,
        pair_labels,
    )

    if html_path.suffix.lower() not in (".html", ".htm"):  # a trial's -o r.pdf got HTML
        fail_usage(f"{html_path}: the report is HTML: name it .html (for a PDF, print the "
                   "HTML from a browser: one log per page)")
    if json_path is not None and json_path.suffix.lower() in (".html", ".htm"):
        fail_usage(f"{json_path}: --json writes JSON: name it .json")
    for out in (html_path, json_path):  # a bad -o/--json stops the run before any work
        if out is not None:
            prepare_output(out)
    paths = local_inputs(inputs)
    explicit = pair_labels(paths, labels)
    resolve_executor(jobs, scheduler)
    rob, mod, cfg = (None if p is None else str(p) for p in (robot, model, config))
    load_inputs(rob, mod, cfg)  # a bad one stops the run before any work
    log_only = [n for n, v in (("--model", model), ("--config", config)) if v is not None]
    log_only += [f"--{k.replace('_', '-')}" for k in read_options.as_dict()]
    if log_only and any(is_timeline(p) for p in paths):
        warnings.warn(f"{', '.join(log_only)} apply to LOG inputs only: a TIMELINE is re-run "
                      "with the read options, model and config it records", ImpactWarning,
                      stacklevel=2)
    tasks = [ReportTask(str(inp), str(lab) if lab is not None else None, not no_auto_labels,
                        rob, mod, cfg, read_options, k, allow_slow,
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
