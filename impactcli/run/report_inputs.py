"""The inputs of ``impactcli report`` (and of ``evaluate``'s timelines): what a timeline
records for its re-run, the labels that go with each input, and one report input analysed
and rendered in any worker (:func:`analyze_input`).

A LOG (any format ``detect`` reads) is replayed with ``detect``'s options; a TIMELINE
(``*.timeline.json``) is re-run from the log it records (as recorded, else beside the
timeline) with the read options, model and config it records (its sha256 checked; events
that differ are warned about). Each replay streams its chunks to the report's collector
(:mod:`impactcli.outputs.report.samples`).

Labels: ``--labels FILE`` may be repeated — named ``<stem>.labels.json`` after distinct
inputs' stems they go by stem, else they pair with the inputs in order; an input without
one gets ``<stem>.labels.json`` from beside its log (a timeline's: beside it, then beside
its log) unless ``--no-auto-labels``.
"""

from __future__ import annotations

import contextlib
import functools
import json
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ImpactError, ImpactWarning, LogFormatError, UsageProblem
from ..logs.paths import is_log_path, log_stem
from ..types import ReadOptions
from .job import load_inputs

TIMELINE_SUFFIX = ".timeline.json"
LABELS_SUFFIX = ".labels.json"


def is_timeline(path: Path) -> bool:
    """Whether ``path`` names a detection timeline (``*.timeline.json``)."""
    return path.name.lower().endswith(TIMELINE_SUFFIX)


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


@dataclass(frozen=True)
class TimelineRerun:
    """What a timeline records for its re-run (:func:`analyze_for_report`): the timeline
    (its path and its contents, read once), its log, the read options, the config, the
    model when it was given (None: the config's, or identified from the log again),
    whether the config's thresholds go with a model identified from the log, and the robot
    (given, else the recorded one)."""

    path: Path
    timeline: dict[str, Any]
    log_path: Path
    read_options: ReadOptions
    config: Any
    model: Any
    model_from_log: bool
    robot: Any

    def check_log(self, sha256: str | None) -> None:
        """The log must be the one the timeline was made from (its recorded sha256)."""
        rec = self.timeline["input"].get("sha256")
        if rec and sha256 and sha256 != rec:
            raise LogFormatError(
                f"{self.path}: its log {self.log_path} changed since detection "
                f"(sha256 {sha256[:12]}…, recorded {rec[:12]}…)"
            )

    def origin(self) -> dict[str, Any]:
        """Where the re-run came from, for the report: the timeline, its schema version and
        the tool that wrote it (a "1.0" timeline records no incidents; the report says so)."""
        tl = self.timeline
        tool = tl.get("tool") or {}
        incidents = tl.get("incidents")
        return {"timeline": str(self.path), "timeline_schema_version": str(tl["schema_version"]),
                "recorded_by": f"{tool.get('name', '?')} {tool.get('version', '?')}",
                "recorded_incidents": len(incidents) if isinstance(incidents, list) else None}


def timeline_rerun(tl_path: Path, robot: Any) -> TimelineRerun:
    """The :class:`TimelineRerun` of the timeline ``tl_path`` (``robot``: given, or None)."""
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
    recorded = ReadOptions.of({k: opts.get(k) for k in RECORDED_READ_OPTIONS})
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
    return TimelineRerun(tl_path, tl, log_path, recorded, config, model, from_log, robot)


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

    from .job import run_log  # looked up at the call: a test may stand in for the replay

    inp = Path(task.inp)
    if is_timeline(inp):
        plan = timeline_rerun(inp, robot)
        result, samples = run_log(
            str(plan.log_path), robot=plan.robot, model=plan.model, config=plan.config,
            read_options=plan.read_options, allow_slow=task.allow_slow,
            show_progress=task.show_progress, model_from_log=plan.model_from_log,
            samples="report", check=lambda scan: plan.check_log(scan.source.sha256))
        try:
            _compare_events(inp, plan.timeline, result)
        except BaseException:
            samples.close()
            raise
        return result, plan.log_path, samples, plan.origin()
    result, samples = run_log(str(inp), robot=robot, model=model, config=config,
                                 read_options=task.read_options, allow_slow=task.allow_slow,
                                 show_progress=task.show_progress, samples="report")
    return result, inp, samples, None


def pair_labels(inputs: Sequence[Path], labels: Sequence[Path]) -> list[Path | None]:
    """Explicit ``--labels`` files per input (rule 1 of the module docstring)."""
    out: list[Path | None] = [None] * len(inputs)
    if not labels:
        return out
    stems = [log_stem(p) for p in inputs]
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
    raise UsageProblem(
        f"{len(labels)} labels file(s) for {len(inputs)} input(s): give one per input (in "
        "order) or name each <stem>.labels.json after its input",
        param_hint="'--labels'",
    )


def auto_labels(inp: Path, log_path: Path | None) -> Path | None:
    """``<stem>.labels.json`` beside the input, then beside its log (under the input's stem,
    then the log's), if present; a rosbag2 folder's are beside the folder, named after it."""
    stem = log_stem(inp)
    cands = [inp.parent / f"{stem}{LABELS_SUFFIX}"]
    if log_path is not None:
        cands += [log_path.parent / f"{st}{LABELS_SUFFIX}"
                  for st in (stem, log_stem(log_path))]
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
    read_options: ReadOptions
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
    robot_obj, model_obj, config_obj, _ = load_inputs(robot, model, config)
    return robot_obj, model_obj, config_obj


def analyze_input(task: ReportTask) -> ReportPart:
    """Analyse and render one report input in any worker.

    A LOG is detected, a TIMELINE re-run, in bounded memory (:func:`analyze_for_report`);
    the labels are the given
    file, else ``<stem>.labels.json`` found beside it when ``auto_labels``; the log's section
    is rendered here (:func:`impactcli.outputs.report.render_log`), so only it travels back.
    Warnings raised on the way come back as messages; an ImpactError comes back as the error.
    """
    from ..logs.robot_files import check_label_links, read_labels
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
            if lab is not None:
                check_label_links(lab, result.log.joint_names, result.detection_floor,
                                  str(inp))
            rendered = render_log(result, lab, task.key, origin=origin, samples=samples)
            run_warnings = result.warnings
        except ImpactError as e:
            err = e
        finally:
            if samples is not None:
                samples.close()
    msgs = tuple(str(w.message) for w in caught if issubclass(w.category, ImpactWarning))
    return ReportPart(rendered, tuple(run_warnings), msgs, err)


def local_inputs(patterns: Sequence[str]) -> tuple[Path, ...]:
    """Inputs as local paths: globs expanded, ``file://`` URLs resolved, a folder of no log
    as the timelines in it (``detect -o``'s); a remote URL is a usage error (download it
    first: the report reads its logs beside the timelines)."""
    from ..logs.paths import folder_logs, is_rosbag2_folder
    from ..logs.urls import expand_inputs, local_path

    def timelines(pat: str) -> list[str]:  # detect's -o folder: its timelines (a trial
        p = Path(pat)                       # gave it and read "a folder without any log")
        if not p.is_dir() or is_rosbag2_folder(p) or folder_logs(p):
            return [pat]
        return sorted(str(x) for x in p.glob("*.timeline.json")) or [pat]

    out = []
    for item in expand_inputs([x for pat in patterns for x in timelines(str(pat))]):
        local = local_path(item)
        if local is None:
            raise UsageProblem(f"{item}: report inputs must be local files or file:// URLs "
                           "(download remote ones first)")
        out.append(local)
    return tuple(out)
