"""``impactcli report LOG|TIMELINE... -o report.html [--json report.json] [--labels L]``.

Inputs:

- a LOG (``.csv``, ``.csv.gz``, ``.mcap``, ``.npz``) is read and the detectors replayed on
  it with ``detect``'s options (``--robot``, ``--model``, ``--config``, ``--channel-map``);
- a TIMELINE (``*.timeline.json`` written by ``detect``) is re-run from the log it records
  (path resolved as recorded, else beside the timeline), with the read options, model and
  config it records — ``--model``/``--config``/``--channel-map`` apply to LOG inputs only.
  The log's sha256 must match the recorded one, and a re-run whose events differ from the
  recorded ones is warned about.

Labels (ground truth, enabling the detection-quality section):

1. ``--labels FILE`` may be repeated. When every file is named ``<stem>.labels.json`` after
   a distinct input's stem, files go to the inputs of that stem; otherwise their number
   must equal the number of inputs and they pair with the inputs in order.
2. An input with no ``--labels`` gets ``<stem>.labels.json`` from beside the log (for a
   timeline: beside the timeline, then beside its log) when that file exists, unless
   ``--no-auto-labels``. The report names every labels file it used.

A batch where some inputs fail writes the report of the others, lists the failures in it,
and exits 4; when every input fails the first error is raised (exit 3).
"""

# Imports inside functions are deliberate: `impactcli --help` must stay fast.
# ruff: noqa: PLC0415

from __future__ import annotations

import json
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import click

from ..errors import EXIT_BATCH, ImpactError, ImpactWarning, LogFormatError
from ._common import handle_errors, progress

TIMELINE_SUFFIX = ".timeline.json"
LABELS_SUFFIX = ".labels.json"
#: read_log keyword arguments a timeline's ``input.read_options`` may carry.
READ_KEYS = ("channel_map", "topic", "reference_topic", "time_source", "torque_source")


def input_stem(path: Path) -> str:
    """The stem outputs are named by (``x.csv.gz`` → ``x``, ``x.timeline.json`` → ``x``)."""
    from ..outputs.report import log_stem

    return log_stem(str(path))


def is_timeline(path: Path) -> bool:
    """Whether ``path`` names a detection timeline (``*.timeline.json``)."""
    return path.name.lower().endswith(TIMELINE_SUFFIX)


def _read_robot(path: str | Path | None) -> Any:
    if path is None:
        return None
    from ..io.robot import read_robot

    return read_robot(path)


def analyze_log(
    path: Path,
    *,
    model: Path | None,
    config: Path | None,
    robot: Path | None,
    channel_map: str | None,
) -> Any:
    """Read ``path`` and replay the detectors (:func:`impactcli.pipeline.analyze`)."""
    from ..io import read_log
    from ..pipeline import analyze

    robot_desc = _read_robot(robot)
    model_obj = None
    if model is not None:
        from ..model.rigid import read_model

        model_obj = read_model(model)
    config_obj = None
    if config is not None:
        from ..config import load_config

        config_obj = load_config(config)
    log = read_log(path, channel_map=channel_map, robot=robot_desc)
    return analyze(log, model=model_obj, config=config_obj, robot=robot_desc)


def load_timeline(path: Path) -> dict[str, Any]:
    """Read and validate a timeline JSON (LogFormatError naming the file when bad)."""
    from ..schema import validate

    try:
        doc = json.loads(path.read_text("utf-8"))
    except FileNotFoundError:
        raise LogFormatError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise LogFormatError(f"{path}: not a readable timeline JSON ({err})") from None
    if not isinstance(doc, dict):
        raise LogFormatError(f"{path}: a timeline must be a JSON object")
    validate(doc, "timeline", LogFormatError, str(path))
    return doc


def timeline_log_path(tl_path: Path, recorded: str) -> Path:
    """The log a timeline records: as recorded (relative to the working folder), else
    relative to the timeline's folder, else its file name beside the timeline."""
    rec = Path(recorded)
    for cand in (rec, tl_path.parent / rec, tl_path.parent / rec.name):
        if cand.is_file():
            return cand
    raise LogFormatError(
        f"{tl_path}: the log it records, {recorded}, is not found (looked "
        f"in the working folder and beside the timeline)"
    )


def rerun_timeline(tl_path: Path, *, robot: Path | None) -> tuple[Any, Path]:
    """Re-run detection as a timeline records it; returns (DetectionResult, log path)."""
    from ..config import DetectorConfig
    from ..io import read_log
    from ..pipeline import analyze

    tl = load_timeline(tl_path)
    inp = tl["input"]
    log_path = timeline_log_path(tl_path, inp["path"])
    opts = dict(inp.get("read_options") or {})
    robot_spec = robot if robot is not None else opts.pop("robot", None)
    opts.pop("robot", None)
    kwargs = {k: opts.pop(k) for k in READ_KEYS if opts.get(k) is not None}
    for k in READ_KEYS:
        opts.pop(k, None)
    if opts:
        warnings.warn(
            f"{tl_path}: read options {sorted(opts)} not understood by report; ignored",
            ImpactWarning,
            stacklevel=2,
        )
    if isinstance(robot_spec, dict):
        from ..io.robot import robot_from_dict

        robot_desc = robot_from_dict(robot_spec, f"{tl_path}: read_options.robot")
    else:
        robot_desc = _read_robot(robot_spec)
    log = read_log(log_path, robot=robot_desc, **kwargs)
    if inp.get("sha256") and log.source.sha256 and log.source.sha256 != inp["sha256"]:
        raise LogFormatError(
            f"{tl_path}: its log {log_path} changed since detection "
            f"(sha256 {log.source.sha256[:12]}…, recorded {inp['sha256'][:12]}…)"
        )
    config = DetectorConfig.from_dict(tl["config"], where=f"{tl_path}: config")
    model = None
    if tl["model"]["source"] == "given":
        from ..model.rigid import RigidModel

        model = RigidModel.from_dict(tl["model"]["model"], where=f"{tl_path}: model")
    result = analyze(log, model=model, config=config, robot=robot_desc)
    recorded = [
        (e["detector"], round(e["t_start"], 9), round(e["t_end"], 9), tuple(e["joints"]))
        for e in tl["events"]
    ]
    now = [
        (e.detector, round(e.t_start, 9), round(e.t_end, 9), tuple(e.joints)) for e in result.events
    ]
    if recorded != now or bool(tl["calibrated"]) != bool(result.calibrated):
        warnings.warn(
            f"{tl_path}: re-running detection gave {len(now)} event(s) where the "
            f"timeline records {len(recorded)} (or a different calibration); the "
            "report shows the re-run",
            ImpactWarning,
            stacklevel=2,
        )
    return result, log_path


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
    """``<stem>.labels.json`` beside the input (then beside its log), if present."""
    stem = input_stem(inp)
    cands = [inp.parent / f"{stem}{LABELS_SUFFIX}"]
    if log_path is not None:
        cands.append(log_path.parent / f"{input_stem(log_path)}{LABELS_SUFFIX}")
    return next((c for c in cands if c.is_file()), None)


@click.command("report")
@click.argument(
    "inputs", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False, path_type=Path)
)
@click.option(
    "-o",
    "--output",
    "html_path",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The HTML report to write.",
)
@click.option(
    "--json",
    "json_path",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Also write the same facts as JSON (schemas/report.schema.json).",
)
@click.option(
    "--labels",
    "labels",
    multiple=True,
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Ground-truth labels JSON; repeat per input (in order, or named <stem>.labels.json).",
)
@click.option(
    "--no-auto-labels",
    is_flag=True,
    help="Do not pick up <stem>.labels.json files found beside the inputs.",
)
@click.option(
    "--model",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="Model JSON to detect with (LOG inputs).",
)
@click.option(
    "--config",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="Detector config (TOML/YAML/JSON) to detect with (LOG inputs).",
)
@click.option(
    "--robot",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="Robot description (JSON/YAML).",
)
@click.option(
    "--channel-map",
    default=None,
    help="Channel map file or shipped map name, for foreign layouts (LOG inputs).",
)
@handle_errors
def report_cmd(
    *,
    inputs: tuple[Path, ...],
    html_path: Path,
    json_path: Path | None,
    labels: tuple[Path, ...],
    no_auto_labels: bool,
    model: Path | None,
    config: Path | None,
    robot: Path | None,
    channel_map: str | None,
) -> None:
    """Write a safety-audit report (one self-contained HTML file, and --json) over logs
    or timelines: what was analysed, with what, the events, false-alarm margins, plots,
    caveats, and detection quality when labels are given."""
    from ..io.robot import read_labels
    from ..outputs.report import write_report

    explicit = pair_labels(inputs, labels)
    results: list[Any] = []
    labs: list[Any] = []
    failed: list[tuple[Path, ImpactError]] = []
    for inp, given_labels in progress(list(zip(inputs, explicit, strict=True)), desc="report"):
        try:
            if is_timeline(inp):
                result, log_path = rerun_timeline(inp, robot=robot)
            else:
                result = analyze_log(
                    inp, model=model, config=config, robot=robot, channel_map=channel_map
                )
                log_path = inp
            lab_path = given_labels
            if lab_path is None and not no_auto_labels:
                lab_path = auto_labels(inp, log_path)
            lab = read_labels(lab_path) if lab_path is not None else None
        except ImpactError as err:
            click.echo(f"impactcli: error: {err}", err=True)
            failed.append((inp, err))
            continue
        results.append(result)
        labs.append(lab)
    if not results:
        raise failed[0][1]
    write_report(
        results, html_path, json_path, labels=labs, failed=[(str(p), str(e)) for p, e in failed]
    )
    click.echo(
        f"impactcli: report of {len(results)} log(s) written to {html_path}"
        + (f" and {json_path}" if json_path else ""),
        err=True,
    )
    if failed:
        click.get_current_context().exit(EXIT_BATCH)
