"""``impactcli detect LOG... -o DIR``: replay the detectors, write timelines (and signals, .rrd)."""

# Imports inside functions keep `impactcli --help` fast.

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import click

from ..detect.events import LONG_EVENT_S, chained_text
from ..detect.incidents import (
    baseline_alone_text,
    blind_text,
    defect_blind_words,
    floor_apart,
)
from ..errors import EXIT_BATCH, EXIT_DETECTED, EXIT_UNJUDGED, Interrupted, one_line
from ..run.gates import count, gate_notes, shown
from .options import (
    executor_options,
    fail_usage,
    generator_option,
    handle_errors,
    log_read_options,
    model_url_options,
    progress,
    resolve_executor,
)

if TYPE_CHECKING:
    from ..run.batch import DefectIncidentRow, IncidentRow, JobOutcome, SummaryRow
    from ..types import ReadOptions

__all__ = ["PRODUCT_DETECTORS", "detect_cmd"]

#: the product's detectors: what --fail-on-detect counts (static_baseline is for comparison)
PRODUCT_DETECTORS = ("adaptive", "static_loading")


def _fmt_row(s: SummaryRow, lasting: int) -> str:
    cal = "edited" if s.get("settings_edited") else "yes" if s["calibrated"] else "no"
    dur = f"{s['duration_s']:.1f}" + (" cut" if s.get("truncated") else "")
    warm = f"{s['warmup_end_s']:.2f}" + ("*" if s.get("late_warmup") else "")
    incs = f"{s['incidents']}" + ("†" if _unseen(s) or any(
        "unseen_load_kg" in x for x in s["lasting_load_list"]) else "")
    return (f"{shown(s['log']):<36} {dur:>9} {cal:>10} "
            f"{warm:>7} {incs:>9} {lasting:>7} | "
            f"{s['adaptive']:>8} {s['static_loading']:>8} {s['static_baseline']:>8}")


def _unseen(s: SummaryRow) -> list[IncidentRow]:
    """The counted incidents that began while the arm carried a load no calibration log
    carried (``unseen_load_kg``)."""
    return [i for i in s["incident_list"] if "unseen_load_kg" in i]


def _unseen_note(rows: list[SummaryRow]) -> str | None:
    """The † footnote of the logs' rows: how many counted incidents (and lasting loads) lie
    under loads no calibration log carried, and what that leaves unknown (None: none do)."""
    under = [i for s in rows for i in _unseen(s)]
    lasting = [x for s in rows for x in s["lasting_load_list"] if "unseen_load_kg" in x]
    if not under and not lasting:
        return None
    kg = ", ".join(sorted({f"{x['unseen_load_kg']:+.3g}" for x in [*under, *lasting]}))
    also = f" and {len(lasting)} lasting load(s)" if lasting else ""
    return (f"(†: {len(under)} counted incident(s){also} began while the arm carried a load "
            f"no calibration log carried ({kg} kg beyond the model's): the thresholds' "
            "false-alarm rate was not measured with it, so how many of them are the rigid "
            "model's own error under that load is not known — calibrate with a log that "
            "carries it; unseen_load_kg in the timeline)")


def _link_cell(inc: IncidentRow) -> str:
    """``link 2``, ``link 5 or 6`` (the residuals cannot tell), ``link ?``."""
    from ..detect.incidents import link_words

    return link_words(inc["link"], inc["link_candidates"], unknown="link ?")


def _incident_line(k: int, inc: IncidentRow, link_width: int = 7,
                   unseen_flag: bool = True) -> str:
    """``  1  12.040 s  link 2  ~14.5 N  transient  (adaptive, static_loading)``; ``k`` is
    the incident's number (the report's: 1, 2, … over the counted incidents), ``link_width``
    the link column's (``link 5 or 6`` when the residuals cannot tell)."""
    from ..detect.force import force_mark

    link = _link_cell(inc)
    force = (f"{force_mark(inc)}{inc['force_n']:.3g} N" if inc["force_n"] is not None
             else "force ?")
    flag = ("  force not plausible (force_check in the timeline)"  # off-scale: said below
            if inc["force_plausible"] is False and not inc.get("off_scale") else "")
    if inc.get("no_force"):  # up to its colon, or its first comma
        flag += (f"  {inc['no_force'].split(':')[0].split(', more than')[0]} (force_method "
                 "in the timeline)")
    if "chained_s" in inc:  # up to its colon: "alarms chained over 17.7 s (none 10 s alone)"
        flag += (f"  {str(chained_text(inc['chained_s'])).split(':')[0]}: contacts in it "
                 "not told apart")
    if inc.get("payload_test"):  # up to its colon: "a contact beside payload change P2, …"
        flag += f"  {inc['payload_test'].split(':')[0]} (payload_test in the timeline)"
    if inc.get("outside_envelope"):
        flag += "  outside the calibrated motion (outside_envelope in the timeline)"
    if inc.get("load_motion"):
        flag += ("  its load on motion no calibration log with it covered (load_motion in "
                 "the timeline)")
    if unseen_flag and "unseen_load_kg" in inc:  # said once above when all of them are
        flag += "  under a load no calibration log carried (unseen_load_kg in the timeline)"
    if inc.get("velocity_disagrees"):  # the residual there may be the data's
        flag += (f"  the logged velocity and positions disagree from "
                 f"{inc['velocity_disagrees']['t_start']:.3f} s (velocity_disagrees in the "
                 "timeline)")
    if inc.get("aftermath"):  # up to its colon: "in the aftermath of incident 5 at 35.048 s"
        flag += f"  {inc['aftermath'].split(':')[0]} (aftermath in the timeline)"
    if inc.get("close_behind"):  # up to its colon: "close behind incident 3 (21.2 N at …)"
        flag += (f"  {inc['close_behind'].split(':')[0]}, maybe its ringing (close_behind in "
                 "the timeline)")
    if inc.get("held_before"):  # up to its colon: "ended a load held since 11.909 s"
        flag += f"  {inc['held_before'].split(':')[0]} (held_before in the timeline)"
    if inc.get("resumes_load"):  # up to its colon: "resumes the lasting load of … dip"
        flag += f"  {inc['resumes_load'].split(':')[0]} (resumes_load in the timeline)"
    return (f"  {k:>3}  {inc['t_start']:>9.3f} s  {link:<{link_width}} {force:>9}  "
            f"{inc['contact']:<12} ({', '.join(inc['detectors'])}){flag}")


def _lasting_line(k: int, x: dict[str, Any]) -> str:
    """``  L1   6.500–40.000 s (to the log's end) static_loading on j2, j3, up to 14× …``."""
    from ..detect.force import force_mark

    said = (["to the log's end"] if x.get("ends_with_log") else []) + (
        ["on already when the warm-up ended: it began then or before"]
        if x.get("on_at_warmup_end") else [])
    end = f" ({'; '.join(said)})" if said else ""
    force = (f", {force_mark(x)}{x['force_n']:.3g} N at link {x['link']}"
             if x.get("force_n") is not None else "")
    if x.get("force_plausible") is False:
        force += " (beyond what the arm can exert)"
    test = f"; {x['payload_test']}" if x.get("payload_test") else ""
    if x.get("unseen_load_kg") is not None:
        test += (f"; under a load no calibration log carried ({x['unseen_load_kg']:+.3g} kg): "
                 "the rigid model's error under it alarms so too")
    return (f"  L{k:<2} {x['t_start']:>9.3f}–{x['t_end']:.3f} s{end}  {x['detector']} on "
            f"{', '.join(x['joints'])}, up to {x['peak_ratio']:.3g}× its threshold{force}"
            f"{test}")


def payload_changes_head(name: str, changes: list[dict[str, Any]]) -> str:
    """The line above a log's payload changes: not incidents, failing no gate — or, when
    some were not told from a steady press (:func:`~impactcli.detect.payload_words.
    press_text`), how many, which the gates cannot judge."""
    from ..detect.payload_words import press_text

    doubt = sum(1 for c in changes if press_text(c) is not None)
    gates = ("failing no gate" if not doubt else
             f"{doubt} of them not told from a steady press, which the gates cannot judge "
             "(--fail-on-detect: exit 5; --fail-on-force N: when its press would pass N)")
    return (f"payload changes of {name} (a load picked or released: not incidents, {gates}; "
            "the residual takes the new load from the classification on):")


def payload_change_line(k: int, c: dict[str, Any]) -> str:
    """``  P1   20.092 s  +0.994 kg (s.e. ≥ 0.004 kg; 99.7 % of the step a mass, …),
    classified at 23.092 s; now carrying …``."""
    from ..detect.payload_words import carrying_text, change_text

    doubt = "its mass cannot be trusted (why: at the end) — " if c.get("mass_check") else ""
    return (f"  P{k:<2} {c['t_start']:>9.3f} s  {doubt}{change_text(c)}, classified at "
            f"{c['t_classified']:.3f} s; now carrying {carrying_text(c)}")


def lasting_loads_of(outcome: JobOutcome) -> list[dict[str, Any]]:
    """The counted lasting loads of a log (timeline ``lasting_loads`` items after warm-up),
    from its batch summary row (which lists only those); none for a failed log."""
    return [] if outcome.summary is None else list(outcome.summary["lasting_load_list"])


#: incidents listed per log when one log is analysed (all of them are in the timeline)
MAX_INCIDENTS_LISTED = 20


#: per-log rows printed at most (the --summary JSON has them all)
MAX_ROWS = 50


@click.command("detect")
@click.argument("logs", nargs=-1, required=True, metavar="LOG...")
@click.option("-o", "--out", "--output", "out_dir", required=True, metavar="DIR|URL",
              help="Output folder or URL prefix: <stem>.timeline.json per log "
                   "(+ .signals.parquet, .rrd), each written atomically.")
@model_url_options
@log_read_options
@click.option("--signals", is_flag=True, help="Also write the per-sample signals (Parquet).")
@click.option("--rerun", is_flag=True, help="Also write a Rerun recording (<stem>.rrd).")
@click.option("--model-from-log", is_flag=True,
              help="With --config: keep its thresholds but identify the model from each log "
                   "(offline only; e.g. an unknown payload).")
@click.option("--fail-on-detect", is_flag=True,
              help="Exit 1 when an incident (a contact found by adaptive or static_loading) "
                   "or a lasting load (an alarm of 10 s or more) lies after warm-up; exit 5 "
                   "(could not judge) when a log's warm-up covers all of it.")
@click.option("--fail-on-force", type=click.FloatRange(min=0), default=None, metavar="N",
              help="Exit 1 when an incident's or a lasting load's estimated contact force "
                   "exceeds N newtons; exit 5 (could not judge) when none exceeds N but "
                   "one has no force estimate, or one marked ≳ (part of the force unseen) "
                   "or a payload change not told from a steady press may exceed it.")
@generator_option
@click.option("--allow-slow", is_flag=True,
              help="Run a replay estimated slower than real time or above 2 GiB of "
                   "covariance (many joints: the adaptive evaluator's cost grows with the "
                   "cube of the joint count).")
@executor_options
@click.option("--summary", "summary_path", metavar="PATH|URL", default=None,
              help="Write the batch summary JSON: logs done/failed, events per detector, "
                   "hours analysed, throughput, one row per log, failures.")
@handle_errors
def detect_cmd(logs: tuple[str, ...], out_dir: str, robot: str | None, model: str | None,
               config: str | None, read_options: ReadOptions, signals: bool, rerun: bool,
               model_from_log: bool, fail_on_detect: bool, fail_on_force: float | None,
               generator: str | None, allow_slow: bool, jobs: int | None,
               scheduler: str | None, summary_path: str | None) -> None:
    """Replay the adaptive impact detector (Makarov et al. 2014) and the static detectors
    over LOGS, exactly as the robot would have run them online, and write one
    DIR/<stem>.timeline.json per log.

    LOGS are paths or fsspec URLs (file://, s3://, ...), globs allowed ('runs/*.mcap',
    's3://bucket/day1/*.csv.gz'). Without --model or --config the model is identified
    from each log itself and the thresholds come from the log's own statistics: the run is
    marked uncalibrated. A log that fails is reported and the others go on. Exit 0
    whether or not collisions are found (unless --fail-on-detect or --fail-on-force: 1,
    with the incident or lasting load above the force named on stderr); 2 when an output
    cannot be written (a full disk: the output named); 3 on a bad input; 4 when some logs
    of a batch failed (the others' outputs are written); 5 when a gate could not judge (a
    log all warm-up with --fail-on-detect, an incident without a force estimate or with
    one marked ≳ under N with --fail-on-force, a payload change not told from a steady
    press or a truncated file with either; 1 wins over 5); 70 on an internal error (a bug,
    with its traceback) — never 1; 130 on SIGINT (Ctrl-C) and 143 on SIGTERM (the logs
    finished are listed, their outputs kept); 141 when stdout's reader closed early
    (| head). Run into a folder it wrote before, it redoes every log and removes the
    temporary .part files a killed run left there.
    """
    from ..logs.paths import prefetch_sha256

    if (jobs or 1) == 1 and scheduler is None:  # this process reads the first log next:
        prefetch_sha256(logs[0])  # its hash overlaps the start-up (a local file only)
    from ..logs.urls import expand_inputs
    from ..run.batch import DetectJob, Timer, check_unique_stems, run_batch, written_since
    from ..run.gates import judge
    from ..run.job import load_inputs

    paths = expand_inputs(logs)
    try:
        check_unique_stems(paths)
    except ValueError as err:
        raise click.UsageError(str(err)) from None
    if model_from_log and model is not None:
        raise click.UsageError("--model and --model-from-log exclude each other")
    local_out = out_dir[len("file://"):] if out_dir.startswith("file://") else out_dir
    if "://" not in local_out:
        from ..errors import OutputError
        from ..files import check_output_folder

        try:
            check_output_folder(local_out)
        except OutputError as err:
            raise click.BadParameter(str(err).replace(f"cannot write into {local_out}: ", ""),
                                     param_hint="'-o'") from None
    if summary_path is not None and "://" not in summary_path:
        from ..files import prepare_output

        prepare_output(summary_path)  # a bad --summary stops the batch before any work
    choice = resolve_executor(jobs, scheduler)
    loaded = load_inputs(robot, model, config)  # a bad one stops the run here
    inputs, thresholds = loaded.provenance, _thresholds_line(config, loaded.config)
    serial = (jobs or 1) == 1 and scheduler is None
    job_list = [DetectJob(p, out_dir, read_options, robot, model, config, signals, rerun,
                          model_from_log, generator, allow_slow, serial) for p in paths]
    debug = bool((click.get_current_context().find_root().obj or {}).get("debug"))
    if "://" not in local_out:
        from ..files import remove_stale_parts

        remove_stale_parts(local_out)  # of a run killed before: a rerun redoes every log
    timer, started = Timer(), time.time()
    outcomes: list[JobOutcome] = []
    stream = run_batch(job_list, n_jobs=jobs, scheduler=scheduler)
    try:
        for outcome in progress(stream, total=len(job_list), desc="detect"):
            _echo_outcome(outcome, debug, len(job_list) == 1)
            outcomes.append(outcome)
    except BrokenPipeError:  # stdout's reader left: not the scheduler (the group's exit)
        raise
    except OSError as err:  # the Dask scheduler cannot be reached
        fail_usage(f"cannot use {choice.describe()}: {err}")
    except Interrupted:  # stopped: nothing more dispatched, the running logs abandoned
        stream.close()   # (their temporary files removed); what finished is listed
        _finish(outcomes, paths, choice, inputs, timer.elapsed(), out_dir, summary_path,
                thresholds, stopped=True)
        late = written_since(job_list, {o.log_path for o in outcomes}, started)
        click.echo(f"impactcli: {len(outcomes) + len(late)} of {len(paths)} logs finished "
                   "before the stop; run the same command again to redo the batch", err=True)
        if late:
            click.echo(f"impactcli: {', '.join(map(shown, late))}: finished as the stop came; "
                       "its outputs are written but not in the table", err=True)
        raise
    failed = [o for o in outcomes if not o.ok]
    ok = [o for o in outcomes if o.ok]
    ctx = click.get_current_context()
    # judged: exit 1, each line saying why; asked to judge and could not: exit 5 — the
    # logs that finished are judged and said even when others failed (4 wins the code)
    failing, unjudged = judge([o.findings for o in ok if o.findings is not None],
                              fail_on_detect=fail_on_detect, fail_on_force=fail_on_force)
    code = ((EXIT_BATCH if ok else failed[0].exit_code) if failed else
            EXIT_DETECTED if failing else EXIT_UNJUDGED if unjudged else 0)
    gates = (None if not fail_on_detect and fail_on_force is None else {
        "fail_on_detect": bool(fail_on_detect), "fail_on_force_n": fail_on_force,
        "failing": failing, "unjudged": unjudged, "exit_code": code})
    _finish(outcomes, paths, choice, inputs, timer.elapsed(), out_dir, summary_path,
            thresholds, gates=gates)
    batch = " — a log that failed wins: exit 4" if failed else ""
    for line in failing:  # why the exit code, per log
        click.echo(line + batch, err=True)
    for line in unjudged:  # a judged failure wins over "could not judge"
        click.echo(line + (batch or (" — a judged failure wins: exit 1" if failing else "")),
                   err=True)
    for line in gate_notes([o.findings for o in ok if o.findings is not None],
                           fail_on_detect=fail_on_detect, fail_on_force=fail_on_force):
        click.echo(line, err=True)  # what the exit code does not speak for
    if failed and len(outcomes) > 1:
        click.echo(f"impactcli: {len(failed)} of {len(outcomes)} logs failed", err=True)
    # some failed: 4; every one failed: the (first) failure's own code, as `report` does
    if code:
        ctx.exit(code)


def _finish(outcomes: list[JobOutcome], paths: list[str], choice: Any,
            inputs: dict[str, dict[str, str]], wall: float, out_dir: str,
            summary_path: str | None, thresholds: str | None, *, stopped: bool = False,
            gates: dict[str, Any] | None = None) -> None:
    """The table of the logs finished (in input order) and the ``--summary`` file: after
    the batch, or after a stop (``stopped``: then it lists what finished, of all the logs
    given); ``thresholds``: the line on the config's thresholds (:func:`_thresholds_line`);
    ``gates``: what the gates found and the exit code, for the summary."""
    from ..run.batch import batch_summary

    order = {p: i for i, p in enumerate(paths)}
    outcomes.sort(key=lambda o: order[o.log_path])
    summary = batch_summary(outcomes, wall_s=wall,
                            executor={**choice.to_dict(), "description": choice.describe()},
                            inputs=inputs, n_inputs=len(paths), stopped=stopped, gates=gates)
    loads = {o.log_path: lasting_loads_of(o) for o in outcomes if o.ok}
    _echo_table(outcomes, summary, out_dir, loads, thresholds)
    if summary_path is not None:
        import json

        from ..run.batch import write_text_to

        write_text_to(summary_path, json.dumps(summary, indent=1, sort_keys=True,
                                               allow_nan=False) + "\n")


#: Why a run's torque scale was not checked (the summary's ``torque_scale``).
UNVERIFIED = {
    "no_description": "no robot description with masses (--robot) to compare the log's "
                      "torque with the gravity torque they predict",
    "warn": "the log's torque is off the gravity torque the robot description's masses "
            "predict (input.torque_scale in the timeline; warned above)",
    "unverified": "the log's slow poses do not load a joint enough to compare its torque "
                  "with the description's gravity torque, or the description gives no "
                  "masses (input.torque_scale in the timeline)",
}


def _defect_line(name: str, marked: list[DefectIncidentRow]) -> str:
    """The terminal line of the incidents at a data defect (not counted as contacts)."""
    listed = ", ".join(f"{i['t_start']:.3f} s (a {i['kind']} at {i['defect_t_start']:.3f} s)"
                       for i in marked[:MAX_INCIDENTS_LISTED])
    more = (f" and {len(marked) - MAX_INCIDENTS_LISTED} more"
            if len(marked) > MAX_INCIDENTS_LISTED else "")
    return (f"not counted, at a data defect of {name}: {count(len(marked), 'incident')} "
            f"at {listed}{more} (the residual shows the defect, not a force; data_defect "
            "in the timeline)")


def _echo_outcome(outcome: JobOutcome, debug: bool, single: bool) -> None:
    """Warnings and the error of one finished log, on stderr; its traceback with --debug,
    or for a bug (``internal``) in a one-log run."""
    name = shown(outcome.log_path)
    for w in outcome.warnings:
        click.echo(one_line(f"impactcli: warning: {w}" if name in w
                            else f"impactcli: warning: {name}: {w}"),
                   err=True)
    if not outcome.ok:
        # in a batch every line names its log (an output's or TMPDIR's error names those)
        error = (outcome.error if single or outcome.log_path in outcome.error
                 else f"{outcome.log_path}: {outcome.error}")
        click.echo(f"impactcli: error: {one_line(error)}", err=True)
        if outcome.traceback and (debug or (single and outcome.error_class == "internal")):
            click.echo(outcome.traceback.rstrip(), err=True)


def _generators_line(row: SummaryRow) -> str:
    """``logged_external (all joints)`` or ``j1 logged_external, j2 inverse_dynamics``."""
    g = row["generators"]
    why = row["generator_reasons"]
    if len(set(g.values())) == 1 and len(set(why.values())) <= 1:
        reason = f"; {next(iter(why.values()))}" if why else ""
        return f"{next(iter(g.values()))} (all joints{reason})"
    return ", ".join(f"{j} {x} ({why.get(j, '')})" for j, x in g.items())


def _thresholds_line(path: str | None, config: Any) -> str | None:
    """What a calibrated config's thresholds promise, said once for the batch
    (:func:`impactcli.detect.tail.calibration_text`); None without one (an uncalibrated
    run warns of its own)."""
    if path is None or config is None or not config.calibration.calibrated:
        return None
    import dataclasses

    from ..config import settings_changed
    from ..detect.tail import calibration_text

    return (f"thresholds of {shown(path)}: "
            + calibration_text(dataclasses.asdict(config.calibration),
                               settings_changed(config)))


def _echo_table(outcomes: list[JobOutcome], summary: dict[str, Any], out_dir: str,
                loads: dict[str, list[dict[str, Any]]], thresholds: str | None) -> None:
    """Per-log rows (at most MAX_ROWS) and the batch totals, on stdout; ``loads``: each
    log's counted lasting loads; ``thresholds``: the config's line, after the rows."""
    ok = [o for o in outcomes if o.summary is not None]
    rows = {o.log_path: o.summary for o in ok if o.summary is not None}
    if ok:
        _echo_rows(ok, rows, out_dir, loads, thresholds)
    if len(outcomes) > 1 or summary["logs"]["total"] > 1:
        n, ev, tp = summary["logs"], summary["events"], summary["throughput"]
        lps = tp["logs_per_s"] or 0.0
        hps = tp["log_hours_per_s"] or 0.0
        stop = f", stopped before {n['not_run']}" if summary.get("stopped") else ""
        click.echo(f"batch: {n['done']} done, {n['failed']} failed of {n['total']} logs{stop}; "
                   f"{summary['hours_analysed']:.3f} h analysed in {summary['wall_s']:.1f} s "
                   f"({lps:.2f} logs/s, {hps * 3600:.0f} h of log per hour) on "
                   f"{summary['executor']['description']}")
        n_loads = sum(len(v) for v in loads.values())
        click.echo(f"incidents: {summary['incidents']}; lasting loads: {n_loads}; events: "
                   + ", ".join(f"{d} {ev[d]}" for d in ev))


def _echo_rows(ok: list[JobOutcome], rows: dict[str, SummaryRow], out_dir: str,
               loads: dict[str, list[dict[str, Any]]], thresholds: str | None) -> None:
    """The finished logs' rows (at most MAX_ROWS), their residual generators, the config's
    ``thresholds`` line and, for one log, its incidents, lasting loads and what their
    figures rest on."""
    one = rows[ok[0].log_path]  # the first log's row
    click.echo(f"{'log':<36} {'duration_s':>9} {'calibrated':>10} {'warmup':>7} "
               f"{'incidents':>9} {'lasting':>7} | {'adaptive':>8} {'loading':>8} "
               f"{'baseline':>8}")
    for o in ok[:MAX_ROWS]:
        click.echo(_fmt_row(rows[o.log_path], len(loads[o.log_path])))
    if len(ok) > MAX_ROWS:
        click.echo(f"... {len(ok) - MAX_ROWS} more logs (all of them in --summary)")
    late = [rows[o.log_path]["late_warmup"] for o in ok[:MAX_ROWS]
            if rows[o.log_path].get("late_warmup")]
    if late:
        n = sum(int(x["alarms"]) for x in late)
        least = sorted({f"{x['least_s']:g}" for x in late})
        click.echo(f"(*: the warm-up ran on past its least length ({' or '.join(least)} s) "
                   f"while the evaluator's prediction error settled: {n} alarm(s) in it after "
                   "that are neither counted nor judged — a contact may be among them; the "
                   "warning names them, and a gate exits 5)")
    if (note := _unseen_note([rows[o.log_path] for o in ok[:MAX_ROWS]])) is not None:
        click.echo(note)
    if any(rows[o.log_path].get("truncated") for o in ok[:MAX_ROWS]):
        click.echo("(cut: the file is truncated — its recording went on after that; what "
                   "came before is analysed, the gates could not judge the rest)")
    gens = {tuple(sorted(rows[o.log_path]["generators"].items())) for o in ok}
    if len(gens) == 1:
        click.echo("residual generator: " + _generators_line(one))
    else:
        for o in ok[:MAX_ROWS]:
            click.echo(f"residual generator of {shown(o.log_path)}: "
                       + _generators_line(rows[o.log_path]))
    if thresholds is not None:
        click.echo(thresholds)
    for why in dict.fromkeys(rows[o.log_path].get("payloads_unwatched") for o in ok):
        if why is not None:  # said where the answer is read, not only with a lasting load
            click.echo(f"payloads: not weighed — {why}: a load carried, picked or placed may "
                       "show among the incidents and lasting loads")
    for o in ok[:MAX_ROWS]:  # said where the answer is read, not only on stderr
        row = rows[o.log_path]
        if row.get("start_load_unknown") and (row["incidents"] or row["lasting_load_list"]):
            click.echo(f"payloads: the load {shown(o.log_path)} starts with could not be "
                       "weighed, so its incidents and lasting loads may be that load's, not "
                       "contacts (input.payload in the timeline; the warning says why)")
    click.echo(f"(incidents, lasting loads and events per detector after warm-up; an "
               f"incident is one contact, made of the adaptive and loading events; a "
               f"lasting load an alarm of {LONG_EVENT_S:g} s or more; timelines in "
               f"{out_dir})")
    if len(ok) == 1 and one["incident_list"]:
        lst = one["incident_list"]
        first = shown(ok[0].log_path)
        cells = [_link_cell(inc) for inc in lst[:MAX_INCIDENTS_LISTED]]
        width = max(7, *(len(c) for c in cells))
        every_unseen = len(_unseen(one)) == len(lst)  # the † note says it of them all
        click.echo(f"incidents of {first}:  #  alarm at    {'link':<{width}}   "
                   "force  contact      detectors  (a contact begins before its alarm, "
                   "unless the incident merged an earlier alarm)")
        # the counted incidents in time order: k is the incident's number (the report's)
        for k, inc in enumerate(lst[:MAX_INCIDENTS_LISTED], 1):
            click.echo(_incident_line(k, inc, width, not every_unseen))
        if len(lst) > MAX_INCIDENTS_LISTED:
            click.echo(f"  ... {len(lst) - MAX_INCIDENTS_LISTED} more (in the timeline)")
        if any(" or " in c for c in cells):
            click.echo("  (link A or B: the joints' residuals cannot tell which of those "
                       "links was touched; link_candidates in the timeline)")
        if any(inc.get("force_at_least") for inc in lst[:MAX_INCIDENTS_LISTED]):
            from ..detect.force import AT_LEAST_TEXT

            click.echo(f"  ({AT_LEAST_TEXT})")
    if (len(ok) == 1 and one["torque_scale"] in UNVERIFIED
            and (one["incident_list"] or one["detection_floor"] or loads[ok[0].log_path]
                 or one["payload_change_list"])):  # forces, the floor's N or N·m, masses
        what = ("torques, forces and masses" if one["payload_change_list"]
                or one.get("payload_floor") else "torques and forces")
        click.echo(f"{what} of {shown(ok[0].log_path)} "
                   + ("cannot be trusted: " if one["torque_scale"] == "warn" else
                      "are in the log's units, not checked against physics: ")
                   + UNVERIFIED[one["torque_scale"]])
    if len(ok) == 1 and one.get("baseline_alone"):
        said = baseline_alone_text(one["baseline_alone"])
        click.echo(f"{said[0].upper()}{said[1:]} ({shown(ok[0].log_path)})")
    if len(ok) == 1 and one["defect_incident_list"]:
        click.echo(_defect_line(shown(ok[0].log_path), one["defect_incident_list"]))
    # a lasting load's detector alarms throughout it: the floor holds only outside it
    words, all_held = (floor_apart(loads[ok[0].log_path], one["duration_s"]
                                   - one["warmup_end_s"]) if len(ok) == 1 else ("", False))
    apart = f" ({words})" if words and not all_held else ""
    if len(ok) == 1 and all_held:
        click.echo(f"detection floor of {shown(ok[0].log_path)}: not stated — {words} "
                   "(the timeline's detection_floor has what the detectors' state gave)")
    elif len(ok) == 1 and one["detection_floor"]:
        click.echo(f"detection floor of {shown(ok[0].log_path)}{apart}: "
                   f"{one['detection_floor']} — the median over the log after warm-up, "
                   "the smaller of a step for the loading detector and a 100 ms blow for "
                   "the adaptive one (the timeline's detection_floor has both, per joint, "
                   "and the worst tenth); evaluate with labels measures what is caught")
    if len(ok) == 1 and one.get("detection_floor_measured"):
        click.echo(f"detection floor of {shown(ok[0].log_path)}, measured{apart}: "
                   f"{one['detection_floor_measured']}")
    if len(ok) == 1 and (blind := defect_blind_words(one.get("defect_blind") or {})):
        click.echo(f"blind at data defects of {shown(ok[0].log_path)}: {blind}")
    by_column = [o for o in ok if rows[o.log_path]["links"] == "column_order"
                 and (rows[o.log_path]["incident_list"] or loads[o.log_path])]
    if by_column:
        which = "" if len(ok) == 1 else f" of {len(by_column)} log(s)"
        click.echo(f"links{which} are numbered in the log's column order (joint k's link "
                   "is k): no robot description says the chain; --robot gives it")
    if (len(ok) == 1 and not one["payload_change_list"] and not all_held  # the floor holds
            and (lightest := one.get("payload_floor"))):  # outside a lasting load only
        click.echo(f"payload changes of {shown(ok[0].log_path)}{apart}: none found — a load "
                   f"under ~{lightest['kg']:.2g} kg picked or released at the flange (the end "
                   f"of link {lightest['link']}) would not have crossed the loading "
                   f"thresholds (its weight, under ~{lightest['force_n']:.2g} N, turns no "
                   "joint to its threshold at the log's median moment); a lower bound, not a "
                   "promise that a heavier one was seen")
    if len(ok) == 1 and one["payload_change_list"]:
        click.echo(payload_changes_head(shown(ok[0].log_path), one["payload_change_list"]))
        for k, c in enumerate(one["payload_change_list"], 1):
            click.echo(payload_change_line(k, c))
    if len(ok) == 1 and loads[ok[0].log_path]:
        first = shown(ok[0].log_path)
        click.echo(f"lasting loads of {first} (an unknown payload, a "
                   "clamp, or a model that no longer fits):")
        for k, x in enumerate(loads[ok[0].log_path], 1):
            click.echo(_lasting_line(k, x))
        click.echo(f"  ({blind_text(loads[ok[0].log_path], listed=True)})")
