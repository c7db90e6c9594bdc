"""Running detection over many logs: one log = one job, failures kept per log.

``run_detect_job`` is a top-level function of plain arguments so that it can run in a
worker process (``--jobs N``, a ``concurrent.futures`` executor). It reads the log,
replays the detectors, writes the outputs atomically, and returns a small summary —
or the error, so one bad log never stops the others.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import ImpactError, ImpactWarning

#: read_log keyword arguments recorded in a timeline's ``input.read_options``.
READ_KEYS = ("channel_map", "topic", "reference_topic", "time_source", "torque_source")


@dataclass(frozen=True)
class DetectJob:
    """Everything one detection job needs (picklable: paths and plain values)."""

    log_path: str
    out_dir: str
    read_options: dict[str, Any] = field(default_factory=dict)
    robot_path: str | None = None
    model_path: str | None = None
    config_path: str | None = None
    signals: bool = False
    rerun: bool = False


@dataclass(frozen=True)
class JobOutcome:
    """The result of one job: a summary row, or the error that stopped it."""

    log_path: str
    ok: bool
    summary: dict[str, Any] = field(default_factory=dict)
    outputs: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    error: str = ""
    exit_code: int = 0


def output_stem(path: str) -> str:
    """Stem outputs are named by: the file name without its format extension."""
    from .io import log_stem

    return str(log_stem(path))


def check_unique_stems(paths: Sequence[str]) -> None:
    """Refuse inputs that would write the same output names, naming both (formats.md)."""
    seen: dict[str, str] = {}
    for p in paths:
        s = output_stem(p)
        if s in seen:
            raise ValueError(f"{seen[s]} and {p} would both write {s}.timeline.json; "
                             "put them in separate runs or rename one")
        seen[s] = p


def run_detect_job(job: DetectJob) -> JobOutcome:
    """Read, analyze and write one log; never raises an ImpactError (it is returned)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ImpactWarning)
        try:
            outputs, summary, extra = _run(job)
        except ImpactError as err:
            return JobOutcome(job.log_path, False, error=str(err), exit_code=err.exit_code,
                              warnings=_msgs(caught))
    return JobOutcome(job.log_path, True, summary=summary, outputs=outputs,
                      warnings=tuple(dict.fromkeys(_msgs(caught) + extra)))


def _msgs(caught: list[warnings.WarningMessage]) -> tuple[str, ...]:
    return tuple(str(w.message) for w in caught if issubclass(w.category, ImpactWarning))


def _run(job: DetectJob) -> tuple[tuple[str, ...], dict[str, Any], tuple[str, ...]]:
    from .config import load_config
    from .io import read_log
    from .io.robot import read_robot
    from .model import read_model
    from .outputs.timeline import write_timeline
    from .pipeline import analyze

    robot = read_robot(job.robot_path) if job.robot_path else None
    model = read_model(job.model_path) if job.model_path else None
    config = load_config(job.config_path) if job.config_path else None
    log = read_log(job.log_path, robot=robot, **job.read_options)
    result = analyze(log, model=model, config=config, robot=robot, read_options=job.read_options)
    stem = output_stem(job.log_path)
    out = Path(job.out_dir)
    written = [out / f"{stem}.timeline.json"]
    write_timeline(result, written[0])
    if job.signals:
        from .outputs.signals import write_signals

        written.append(out / f"{stem}.signals.parquet")
        write_signals(result, written[-1])
    if job.rerun:
        from .outputs.rerun import write_rrd

        written.append(out / f"{stem}.rrd")
        write_rrd(result, written[-1])
    summary = {
        "log": job.log_path,
        "duration_s": log.duration_s,
        "joints": len(log.joint_names),
        "calibrated": result.calibrated,
        "warmup_end_s": result.warmup_end_s,
        **{d: v["events"] for d, v in result.summary().items()},
    }
    return tuple(str(p) for p in written), summary, result.warnings


def run_jobs(
    jobs: Sequence[DetectJob], n_jobs: int = 1,
    executor_factory: Callable[[int], Executor] | None = None,
) -> Iterator[JobOutcome]:
    """Run jobs serially (``n_jobs`` ≤ 1 or one job) or on an executor; yield as they finish.

    Every outcome carries its own log path; order is completion order.
    """
    if n_jobs <= 1 or len(jobs) <= 1:
        for job in jobs:
            yield run_detect_job(job)
        return
    factory = executor_factory or (lambda n: ProcessPoolExecutor(max_workers=n))
    with factory(min(n_jobs, len(jobs), os.cpu_count() or 1)) as ex:
        futures = [ex.submit(run_detect_job, job) for job in jobs]
        for fut in as_completed(futures):
            yield fut.result()
