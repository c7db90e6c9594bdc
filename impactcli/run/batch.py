"""Running detection over many logs: one log = one job, failures kept per log.

``run_detect_job`` is a top-level function of plain arguments (paths and URLs, never file
contents) so that it runs unchanged in a worker process (``--jobs N``) or on a Dask worker
(``--scheduler``) — :mod:`impactcli.run.executors` chooses where. A job reads its log, robot
description, model and config (local paths or fsspec URLs, :mod:`impactcli.logs.urls`),
replays the detectors, writes the outputs atomically (a local folder or a URL prefix), and
returns a small :class:`JobOutcome` — or the error, so one bad log never stops the others.

Failures per log (``JobOutcome.error_class``, with the exit code a one-log run would give):

- ``data`` (3): the log, robot description, model or config is bad or missing
  (an :class:`~impactcli.errors.ImpactError`);
- ``output`` (2): an output cannot be written (a full disk, a read-only one, no
  permission, a folder in the way; also a full ``TMPDIR``): the line names the output;
- ``io`` (3): an I/O error that persisted: transient ones (timeouts, connection errors,
  ``EIO``…, see :func:`impactcli.logs.urls.is_transient`) are first retried
  :data:`~impactcli.logs.urls.IO_RETRIES` times with backoff
  (:data:`~impactcli.logs.urls.BACKOFF_S` × 2^k s); the whole job is retried;
- ``worker-lost`` (70): the worker process died on this log, also on its re-run;
- ``internal`` (70): an unexpected exception (a bug): the traceback is kept in the outcome.

A crash exits 70 (``EX_SOFTWARE``), never 1: exit 1 means "incidents found" to a CI gate.

:func:`batch_summary` folds outcomes into the batch summary (``detect --summary``).
"""

from __future__ import annotations

import contextlib
import time
import traceback
import warnings
from collections.abc import Generator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NotRequired, TypedDict

from ..config import settings_changed
from ..detect.events import chained_text
from ..detect.floor import floor_line, payload_floor, probed_line
from ..detect.force import FORCE_NOT_STATED, scale_untrusted
from ..detect.incidents import baseline_alone, floor_apart
from ..errors import (
    EXIT_DATA,
    EXIT_SOFTWARE,
    EXIT_USAGE,
    ImpactError,
    ImpactWarning,
    OutputError,
)
from ..files import OUTPUT_ERRNOS, temporary_folder
from ..logs.paths import log_stem
from ..types import DETECTORS, DetectionResult, ReadOptions
from .gates import Findings
from .job import run_log_from_paths

SUMMARY_SCHEMA_VERSION = "1.3"
#: Exit code a one-log run gives for a lost worker or a bug (EX_SOFTWARE; never 1, which
#: means "incidents found").
EXIT_CRASH = EXIT_SOFTWARE


@dataclass(frozen=True)
class DetectJob:
    """Everything one detection job needs (picklable: paths, URLs and plain values).

    ``log_path``, ``robot_path``, ``model_path``, ``config_path``: local paths or fsspec
    URLs; ``out_dir``: a local folder or a URL prefix.
    """

    log_path: str
    out_dir: str
    read_options: ReadOptions = field(default_factory=ReadOptions)
    robot_path: str | None = None
    model_path: str | None = None
    config_path: str | None = None
    signals: bool = False
    rerun: bool = False
    model_from_log: bool = False
    generator: str | None = None
    allow_slow: bool = False
    show_progress: bool = False


class IncidentRow(TypedDict):
    """A counted incident in a summary row (the timeline's ``incidents`` item, shortened)."""

    t_start: float
    link: int | None
    link_candidates: list[int]
    force_n: float | None
    contact: str
    detectors: list[str]
    force_plausible: bool | None
    payload_test: NotRequired[str]
    outside_envelope: NotRequired[bool]
    aftermath: NotRequired[str]
    close_behind: NotRequired[str]
    load_motion: NotRequired[str]
    no_force: NotRequired[str]
    force_at_least: NotRequired[bool]
    unseen_load_kg: NotRequired[float]
    off_scale: NotRequired[bool]
    resumes_load: NotRequired[str]
    velocity_disagrees: NotRequired[dict[str, Any]]
    held_before: NotRequired[str]
    chained_s: NotRequired[float]


def _incident_row(i: Any) -> IncidentRow:
    """A counted incident (:class:`~impactcli.detect.incidents.Incident`) as a summary row
    (``no_force``: why it has no force, when no single force at its link's end fits;
    ``force_at_least`` when its force is a lower bound; ``unseen_load_kg`` the load no
    calibration log carried that the arm carried then; ``off_scale`` when its force is
    not trusted because the log's torque scale is off)."""
    row = IncidentRow(t_start=i.t_start, link=i.link, link_candidates=list(i.link_candidates),
                      force_n=i.force_n, contact=i.contact, detectors=list(i.detectors),
                      force_plausible=i.force_plausible)
    if chained_text(i.t_end - i.t_start) is not None:
        row["chained_s"] = i.t_end - i.t_start
    if i.payload_test:
        row["payload_test"] = i.payload_test
    if i.outside_envelope:
        row["outside_envelope"] = True
    if i.aftermath:
        row["aftermath"] = i.aftermath["text"]
    if i.close_behind:
        row["close_behind"] = i.close_behind["text"]
    if i.load_motion:
        row["load_motion"] = i.load_motion["text"]
    if i.force_n is None and i.force_method.startswith(FORCE_NOT_STATED):
        row["no_force"] = i.force_method
    if i.force_at_least:
        row["force_at_least"] = True
    if i.unseen_load_kg is not None:
        row["unseen_load_kg"] = i.unseen_load_kg
    if scale_untrusted(i):  # untrusted for the log's torque scale
        row["off_scale"] = True
    if i.resumes_load is not None:
        row["resumes_load"] = i.resumes_load["text"]
    if i.velocity_disagrees is not None:
        row["velocity_disagrees"] = i.velocity_disagrees
    if i.held_before is not None:
        row["held_before"] = i.held_before["text"]
    return row


class DefectIncidentRow(TypedDict):
    """An incident at a data defect (not counted): when, the defect's kind and start."""

    t_start: float
    kind: str
    defect_t_start: float
    force_n: float | None


class SummaryRow(TypedDict):
    """One finished log's row of the batch summary (``schemas/batch_summary.schema.json``,
    ``results`` items, without ``outputs`` and ``attempts``): what the terminal table and the
    ``--summary`` file show of it. The three detectors' keys are the events each counted
    after warm-up."""

    log: str
    sha256: str
    model_source: str
    model_sha256: str | None
    duration_s: float
    truncated: NotRequired[bool]
    defect_blind: NotRequired[dict[str, Any]]
    settings_edited: NotRequired[bool]
    start_load_unknown: NotRequired[str]
    payloads_unwatched: NotRequired[str]
    payload_floor: NotRequired[dict[str, float]]
    joints: int
    calibrated: bool
    links: str
    torque_scale: str
    detection_floor: str | None
    detection_floor_measured: str | None
    warmup_end_s: float
    late_warmup: NotRequired[dict[str, float]]
    baseline_alone: NotRequired[list[dict[str, Any]]]
    generators: dict[str, str]
    generator_reasons: dict[str, str]
    incidents: int
    incident_list: list[IncidentRow]
    defect_incident_list: list[DefectIncidentRow]
    lasting_load_list: list[dict[str, Any]]
    payload_change_list: list[dict[str, Any]]
    start_load: str | None
    adaptive: int
    static_loading: int
    static_baseline: int


@dataclass(frozen=True)
class JobOutcome:
    """The result of one job: a summary row, or the error that stopped it.

    Attributes:
        log_path: the log as given (path or URL).
        ok: whether the outputs were written.
        summary: the log's summary row (ok jobs).
        outputs: files (or URLs) written.
        warnings: the run's warnings (ImpactWarning messages, deduplicated).
        error: one line naming the file and the problem (failed jobs).
        exit_code: what a one-log run would exit with (failed jobs).
        error_class: ``data``, ``io``, ``worker-lost`` or ``internal`` (module docstring).
        attempts: tries made (> 1 after transient I/O errors).
        traceback: of the error (printed for ``internal`` errors, for the others with
            ``--debug``; never in the batch summary).
        findings: what the gates judge (ok jobs): the typed incidents and lasting loads.
    """

    log_path: str
    ok: bool
    summary: SummaryRow | None = None
    outputs: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    error: str = ""
    exit_code: int = 0
    error_class: str = ""
    attempts: int = 1
    traceback: str = ""
    findings: Findings | None = None


def check_unique_stems(paths: Sequence[str]) -> None:
    """Refuse inputs that would write the same output names, naming both (docs/formats.md,
    "Detection timeline")."""
    seen: dict[str, str] = {}
    for p in paths:
        s = log_stem(p)
        if s in seen:
            raise ValueError(f"{seen[s]} and {p} would both write {s}.timeline.json; "
                             "put them in separate runs or rename one")
        seen[s] = p


def written_since(jobs: Sequence[DetectJob], done: set[str], since: float) -> list[str]:
    """The logs not in ``done`` whose timeline a local output folder holds, written at or
    after ``since`` (``time.time()``): after a stop, the logs a worker finished while the
    stop came, before its outcome reached the main process. A timeline is written last, so
    the log's other outputs are in place too."""
    found = []
    for job in jobs:
        if job.log_path in done or "://" in job.out_dir.removeprefix("file://"):
            continue
        timeline = Path(job.out_dir.removeprefix("file://")) / \
            f"{log_stem(job.log_path)}.timeline.json"
        with contextlib.suppress(OSError):
            # the file clock is the kernel's coarse one: up to a tick behind time.time()
            if timeline.stat().st_mtime >= since - 0.05:
                found.append(job.log_path)
    return found


def run_detect_job(job: DetectJob) -> JobOutcome:
    """Read, analyze and write one log; never raises for a bad input (module docstring)."""
    from ..logs.urls import IO_RETRIES, is_transient, retry_transient

    attempts = 0

    def attempt() -> tuple[tuple[str, ...], SummaryRow, tuple[str, ...], Findings]:
        nonlocal attempts
        attempts += 1
        return _run(job)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ImpactWarning)
        try:
            outputs, summary, extra, findings = retry_transient(attempt)
        except ImpactError as err:
            transient = is_transient(err)
            cls = ("output" if isinstance(err, OutputError) else
                   "io" if transient else "data")
            return JobOutcome(job.log_path, False, error=_with_tries(str(err), transient),
                              exit_code=err.exit_code, error_class=cls,
                              warnings=_msgs(caught), attempts=attempts, traceback=_tb(err))
        except OSError as err:
            where = getattr(err, "filename", None)
            why = err.strerror or str(err) or type(err).__name__
            if err.errno in OUTPUT_ERRNOS:  # the output side's fault, whoever met it
                return JobOutcome(job.log_path, False,
                                  error=f"{job.log_path}: cannot write "
                                        f"{where or 'its outputs in ' + job.out_dir}: {why}",
                                  exit_code=EXIT_USAGE, error_class="output",
                                  warnings=_msgs(caught), attempts=attempts,
                                  traceback=_tb(err))
            on = f" on {where}" if where else ""  # never blame the log for an error without a file
            msg = _with_tries(f"{job.log_path}: I/O error{on}: {why}",
                              is_transient(err) and attempts > IO_RETRIES)
            return JobOutcome(job.log_path, False, error=msg, exit_code=EXIT_DATA,
                              error_class="io", warnings=_msgs(caught), attempts=attempts,
                              traceback=_tb(err))
        except Exception as err:
            tb = _tb(err)
            return JobOutcome(job.log_path, False,
                              error=f"{job.log_path}: internal error (a bug): "
                                    f"{type(err).__name__}: {err}",
                              exit_code=EXIT_CRASH, error_class="internal",
                              warnings=_msgs(caught), attempts=attempts, traceback=tb)
    return JobOutcome(job.log_path, True, summary=summary, outputs=outputs,
                      warnings=tuple(dict.fromkeys(_msgs(caught) + extra)), attempts=attempts,
                      findings=findings)


def _with_tries(msg: str, transient: bool) -> str:
    from ..logs.urls import IO_RETRIES

    return f"{msg} (after {IO_RETRIES} retries)" if transient else msg


def _tb(err: BaseException) -> str:
    return "".join(traceback.format_exception(type(err), err, err.__traceback__))


def _msgs(caught: list[warnings.WarningMessage]) -> tuple[str, ...]:
    return tuple(str(w.message) for w in caught if issubclass(w.category, ImpactWarning))


def _run(job: DetectJob) -> tuple[tuple[str, ...], SummaryRow, tuple[str, ...], Findings]:
    from ..logs.urls import local_path

    local_out = local_path(job.out_dir)
    stem = log_stem(job.log_path)
    if local_out is not None:
        result, outputs = _run_streamed(job, local_out, stem)
    else:
        result, outputs = _run_remote(job, job.out_dir, stem)
    summary = _summary(job, result)
    return outputs, summary, result.warnings, Findings.of(job.log_path, result)


def _run_remote(job: DetectJob, prefix: str, stem: str) -> tuple[Any, tuple[str, ...]]:
    """Replay the log in bounded memory into a private temporary folder
    (:func:`_run_streamed`), then upload each output atomically under the remote URL
    ``prefix``."""
    from ..logs.urls import join_url, put_file_atomic

    with temporary_folder("impactcli-out-") as tmp:
        result, written = _run_streamed(job, Path(tmp), stem)
        # the timeline last: its presence says the run's outputs are all there
        order = [*written[1:], written[0]]
        targets = [join_url(prefix, Path(p).name) for p in written]
        done: list[str] = []
        try:
            for p in order:
                target = join_url(prefix, Path(p).name)
                put_file_atomic(Path(p), target)
                done.append(target)
        except BaseException:
            _remove_remote(done)  # no signals or .rrd left without their timeline
            raise
    return result, tuple(targets)


def _remove_remote(urls: list[str]) -> None:
    """Delete these uploaded objects, as far as possible (after a failed upload)."""
    import fsspec

    for url in urls:
        try:
            fs, path = fsspec.core.url_to_fs(url)
            fs.rm(path)
        except Exception:  # best effort: the upload's error is the one shown
            pass


def _run_streamed(job: DetectJob, out: Path, stem: str) -> tuple[Any, tuple[str, ...]]:
    """Replay the log chunk by chunk in bounded memory
    (:func:`impactcli.run.job.run_log_from_paths`) into a local folder: the signals written
    as the comparison with the thresholds goes, the Rerun recording from a spill file, the
    timeline at the end."""
    from ..outputs.timeline import write_timeline

    written = [out / f"{stem}.timeline.json"]
    signals = out / f"{stem}.signals.parquet" if job.signals else None
    rrd = out / f"{stem}.rrd" if job.rerun else None
    result, _ = run_log_from_paths(job.log_path, robot_path=job.robot_path,
                            model_path=job.model_path, config_path=job.config_path,
                            read_options=job.read_options, model_from_log=job.model_from_log,
                            generator=job.generator, allow_slow=job.allow_slow,
                            show_progress=job.show_progress, signals_path=signals,
                            rrd_path=rrd)
    written += [p for p in (signals, rrd) if p is not None]
    write_timeline(result, written[0])
    return result, tuple(str(p) for p in written)


def _summary(job: DetectJob, result: DetectionResult) -> SummaryRow:
    """The batch summary's row of one log."""
    log = result.log
    counted = result.summary()
    row: SummaryRow = {
        "log": job.log_path,
        "sha256": log.source.sha256,
        "model_source": result.model_source,
        "model_sha256": result.model_sha256,
        "duration_s": log.duration_s,
        "joints": len(log.joint_names),
        "calibrated": result.calibrated,
        "links": ("robot" if result.robot or (result.model or {}).get("robot")
                  else "column_order"),
        "torque_scale": (result.torque_scale or {}).get("verdict", "no_description"),
        "detection_floor": floor_line(result.detection_floor),
        "detection_floor_measured": probed_line(result.detection_floor),
        "warmup_end_s": result.warmup_end_s,
        "generators": {j: g["generator"] for j, g in result.generators.items()},
        "incidents": len(result.counted_incidents()),
        "incident_list": [_incident_row(i) for i in result.counted_incidents()],
        "defect_incident_list": [
            {"t_start": i.t_start, "kind": i.data_defect["kind"],
             "defect_t_start": i.data_defect["t_start"], "force_n": i.force_n}
            for i in result.defect_incidents()],
        "lasting_load_list": [x.to_dict() for x in result.counted_lasting_loads()],
        "payload_change_list": list(result.payload_changes or ()),
        "start_load": (None if result.payload is None or result.payload["verdict"] != "used"
                       else result.payload["message"]),
        "generator_reasons": {j: g["reason"] for j, g in result.generators.items()},
        "adaptive": counted["adaptive"]["events"],
        "static_loading": counted["static_loading"]["events"],
        "static_baseline": counted["static_baseline"]["events"],
    }
    if log.source.truncated:
        row["truncated"] = True
    dd = result.data_defects
    if dd and "blind_s" in dd:
        row["defect_blind"] = {"defects": int(dd["gaps"]) + int(dd["jumps"]),
                               "settle_s": dd["settle_s"], "blind_s": dd["blind_s"],
                               "adaptive_settle_s": dd["adaptive_settle_s"],
                               "adaptive_blind_s": dd["adaptive_blind_s"]}
    if result.payloads_unwatched is not None:
        row["payloads_unwatched"] = result.payloads_unwatched
    elif result.payload_changes is not None and not floor_apart(
            [x.to_dict() for x in result.counted_lasting_loads()],
            result.log.duration_s - result.warmup_end_s)[1] and (  # a floor outside them
            lightest := payload_floor(result.detection_floor)) is not None:
        row["payload_floor"] = {"kg": lightest[0], "link": lightest[1],
                                "force_n": lightest[2]}
    if result.payload is not None and result.payload["verdict"] == "unsupported":
        row["start_load_unknown"] = result.payload["message"]  # its findings may be it
    if result.calibrated and settings_changed(result.config):
        row["settings_edited"] = True  # its calibration does not hold for them
    from ..detect.warmup import least_s, past_least

    least = least_s(result.config)
    tl_events = [e.to_dict() for e in result.events]
    if alone := baseline_alone(tl_events, [i.to_dict() for i in result.incidents],
                               [x.to_dict() for x in result.lasting_loads]):
        row["baseline_alone"] = [{"t_start": e["t_start"], "t_end": e["t_end"],
                                  "joints": list(e["joints"]),
                                  "peak_ratio": e["peak_ratio"]} for e in alone]
    if late := past_least(result.incidents, least):  # not counted, not judged
        row["late_warmup"] = {"least_s": float(least or 0.0), "alarms": len(late)}
    return row


def events_of(row: SummaryRow) -> dict[str, int]:
    """The events each detector counted after warm-up, by detector."""
    return {"adaptive": row["adaptive"], "static_loading": row["static_loading"],
            "static_baseline": row["static_baseline"]}


def lost_outcome(job: DetectJob, reason: str, kind: str, tb: str = "") -> JobOutcome:
    """The outcome of a job whose worker died (``kind='worker-lost'``) or that raised."""
    cls = "worker-lost" if kind == "worker-lost" else "internal"
    return JobOutcome(job.log_path, False, error=f"{job.log_path}: {reason}",
                      exit_code=EXIT_CRASH, error_class=cls, traceback=tb)


def run_batch(jobs: Sequence[DetectJob], *, n_jobs: int | None = None,
              scheduler: str | None = None, client: Any = None
              ) -> Generator[JobOutcome, None, None]:
    """Run detection jobs where :func:`impactcli.run.executors.choose_executor` says; yield
    outcomes in completion order (every outcome carries its log path). A dead worker's
    jobs are re-run once, then reported failed (:mod:`impactcli.run.executors`)."""
    from .executors import TaskFailure, run_tasks

    tasks = run_tasks(run_detect_job, list(jobs), jobs=n_jobs, scheduler=scheduler,
                      client=client)
    try:
        for i, res in tasks:
            if isinstance(res, TaskFailure):
                yield lost_outcome(jobs[i], res.reason, res.kind, res.traceback)
            else:
                yield res
    finally:  # a consumer that stops early stops the executor now (its pool's workers)
        tasks.close()


def batch_summary(outcomes: Sequence[JobOutcome], *, wall_s: float,
                  executor: dict[str, Any] | None = None,
                  inputs: dict[str, dict[str, str]] | None = None,
                  n_inputs: int | None = None, stopped: bool = False,
                  gates: dict[str, Any] | None = None) -> dict[str, Any]:
    """The batch summary (``detect --summary``) as a JSON-ready mapping.

    Args:
        outcomes: one per input that finished or failed, in input order.
        wall_s: wall-clock time of the batch [s].
        executor: :meth:`impactcli.run.executors.ExecutorChoice.to_dict` of where it ran.
        inputs: ``robot``/``model``/``config`` → {path, sha256}, those given.
        n_inputs: the logs given (None: ``len(outcomes)``); stopped: the batch was stopped
            before the rest (a trial's stopped batch read "done 4, failed 0, total 4" of 8).
        gates: what the gates found and the exit code (:func:`impactcli.run.gates.judge`),
            when one was asked.
    Returns:
        The mapping ``schemas/batch_summary.schema.json`` describes: ``schema_version``,
        ``tool``, ``executor``, ``inputs``; ``logs`` {total, done, failed, not_run};
        ``stopped``; ``gates``; ``events`` per detector (after warm-up, summed);
        ``hours_analysed`` [h of log]; ``wall_s``; ``throughput`` {logs_per_s,
        log_hours_per_s}; ``results`` (per-log rows); ``failures`` (file, reason,
        exit_code, class, attempts).
    """
    from .. import TOOL_NAME, __version__

    ok = [(o, o.summary) for o in outcomes if o.summary is not None]
    failed = [o for o in outcomes if not o.ok]
    total = len(outcomes) if n_inputs is None else max(n_inputs, len(outcomes))
    hours = sum(row["duration_s"] for _, row in ok) / 3600.0

    def rate(x: float) -> float | None:
        return x / wall_s if wall_s > 0 else None

    return {
        "schema_version": SUMMARY_SCHEMA_VERSION,
        "tool": {"name": TOOL_NAME, "version": __version__},
        "executor": executor or {"kind": "serial"},
        "inputs": inputs or {},
        "logs": {"total": total, "done": len(ok), "failed": len(failed),
                 "not_run": total - len(ok) - len(failed)},
        "stopped": stopped,
        **({} if gates is None else {"gates": gates}),
        "events": {d: sum(events_of(row)[d] for _, row in ok) for d in DETECTORS},
        "incidents": sum(row["incidents"] for _, row in ok),
        "hours_analysed": hours,
        "wall_s": wall_s,
        "throughput": {"logs_per_s": rate(len(ok)), "log_hours_per_s": rate(hours)},
        "results": [{**row, "outputs": list(o.outputs), "attempts": o.attempts}
                    for o, row in ok],
        "failures": [{"file": o.log_path, "reason": o.error, "exit_code": o.exit_code,
                      "class": o.error_class, "attempts": o.attempts} for o in failed],
    }


def write_text_to(target: str, text: str) -> None:
    """Write ``text`` to a local path or URL atomically (summaries, reports)."""
    from ..files import atomic_write_text
    from ..logs.urls import local_path, put_file_atomic, url_name

    lp = local_path(target)
    if lp is not None:
        atomic_write_text(lp, text)
        return
    with temporary_folder("impactcli-out-") as tmp:
        p = Path(tmp) / url_name(target)
        p.write_text(text, "utf-8")
        put_file_atomic(p, target)


class Timer:
    """Wall-clock seconds since creation (``time.perf_counter``)."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()

    def elapsed(self) -> float:
        """Seconds since creation."""
        return time.perf_counter() - self.t0
