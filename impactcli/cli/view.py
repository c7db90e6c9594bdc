"""``impactcli view RUN.rrd|LOG``: open a run (or a log, detected first) in the Rerun viewer.

An ``.rrd`` is checked (a missing or garbled file is a data error, exit 3) and handed to
the ``rerun`` viewer shipped in the rerun-sdk wheel. Any other path is read as a log, the
detectors are replayed on it (:func:`record_log`: chunk by chunk in bounded memory as
``detect --rerun`` does, :func:`impactcli.run.job.run_log_from_paths`), the recording is written to
a temporary folder (or ``--save PATH``) and opened. ``--no-open`` only writes
(for scripts and machines without a display). The command waits until the viewer closes.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import click

from ..errors import LogFormatError, UnavailableError
from ..outputs.decimate import DEFAULT_EVENT_WINDOW_S, DEFAULT_MAX_POINTS
from .options import handle_errors, log_read_options, model_options, not_found

if TYPE_CHECKING:
    from ..types import ReadOptions

if TYPE_CHECKING:
    from ..types import DetectionResult


NO_VIEWER_HINT = ("write the recording with --no-open --save PATH and open it where there "
                  "is a screen (rerun PATH)")


def check_display() -> None:
    """Refuse before any work when the viewer cannot open a window here: on Linux, neither
    ``DISPLAY`` nor ``WAYLAND_DISPLAY`` is set (exit 69)."""
    if sys.platform.startswith("linux") and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise UnavailableError("no display here (DISPLAY and WAYLAND_DISPLAY are not set): "
                               f"the Rerun viewer needs one; {NO_VIEWER_HINT}")


def check_rrd(path: Path) -> None:
    """Raise LogFormatError (one line naming ``path``) unless it is a readable Rerun recording."""
    if not path.exists():
        raise not_found(path, "Rerun file")
    if not path.is_file():
        raise LogFormatError(f"{path}: not a file")
    from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "no footer/manifest" before the real error
            recordings = RrdReader(path).recordings()
    except (RuntimeError, OSError, ValueError) as err:
        lines = str(err).replace(f" at {path}", "").splitlines()
        detail = lines[0] if lines else type(err).__name__
        raise LogFormatError(f"{path}: not a readable Rerun recording ({detail})") from err
    if not recordings:
        raise LogFormatError(f"{path}: Rerun file holds no recording")


def viewer_command(path: Path) -> list[str]:
    """The command that opens ``path`` in the viewer shipped with rerun-sdk."""
    exe = Path(sys.executable).with_name("rerun")
    if exe.is_file():
        return [str(exe), str(path)]
    return [sys.executable, "-m", "rerun_cli", str(path)]


def open_viewer(path: Path) -> None:
    """Run the Rerun viewer on ``path`` and wait for it to close."""
    check_display()
    cmd = viewer_command(path)
    click.echo(f"impactcli: opening {path} in the Rerun viewer (close it to return)", err=True)
    try:
        rc = subprocess.call(cmd)
    except OSError as err:
        raise UnavailableError(f"{path}: cannot start the Rerun viewer ({err}); "
                               f"{NO_VIEWER_HINT}") from err
    if rc != 0:
        raise UnavailableError(f"{path}: the Rerun viewer exited with status {rc} "
                               f"(no display?); {NO_VIEWER_HINT}")


def record_log(source: Path, rrd: Path, *, robot: Path | None, model: Path | None,
               config: Path | None, read_options: ReadOptions, max_points: int,
               event_window_s: float) -> DetectionResult:
    """Replay the detectors on the log ``source`` and write its Rerun recording to ``rrd``
    (atomically); returns the run.

    Chunk by chunk (:func:`impactcli.run.job.run_log_from_paths`, as ``detect --rerun`` does: a
    day-long log in bounded memory, the chunks handed to
    :class:`impactcli.outputs.rerun.RerunWriter`, which writes the recording once the
    answer is known). Progress in seconds of log on a terminal, as ``detect``.
    """
    from ..run.job import run_log_from_paths

    opts: dict[str, Any] = {"max_points": max_points, "event_window_s": event_window_s}
    result, _ = run_log_from_paths(str(source), robot_path=None if robot is None else str(robot),
                            model_path=None if model is None else str(model),
                            config_path=None if config is None else str(config),
                            read_options=read_options, show_progress=True, rrd_path=rrd,
                            rrd_options=opts)
    return cast("DetectionResult", result)


@click.command("view")
@click.argument("source", type=click.Path(dir_okay=True, path_type=Path))
@model_options
@log_read_options
@click.option("--save", "save_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Also keep the recording at this .rrd path.")
@click.option("--no-open", is_flag=True, help="Do not start the viewer (only check or write).")
@click.option("--max-points", type=click.IntRange(min=1000), default=DEFAULT_MAX_POINTS,
              show_default=True, help="Samples per series above which plots are decimated "
              "(min/max envelope; events stay full rate).")
@click.option("--event-window", type=click.FloatRange(min=0.0), default=DEFAULT_EVENT_WINDOW_S,
              show_default=True, help="Full-rate window kept around each event [s].")
@handle_errors
def view_cmd(source: Path, robot: Path | None, model: Path | None,
             config: Path | None, read_options: ReadOptions,
             save_path: Path | None, no_open: bool, max_points: int,
             event_window: float) -> None:
    """Open a run (RUN.rrd) or a log (detected first) in the Rerun viewer.

    SOURCE is an .rrd written by `detect --rerun` (or `view --save`), or any log that
    `detect` reads; for a log the detect options given here are used.
    """
    from ..files import atomic_write_bytes, prepare_output

    if save_path is not None:  # a bad --save stops the run before any work
        prepare_output(save_path)
    if source.suffix.lower() == ".rrd":
        check_rrd(source)
        if save_path is not None and save_path.resolve() != source.resolve():
            atomic_write_bytes(save_path, source.read_bytes())
        if save_path is not None and save_path.resolve() != source.resolve():
            click.echo(str(save_path))
        if no_open:
            click.echo(f"impactcli: {source}: a readable Rerun recording "
                       f"({source.stat().st_size / 1e6:.1f} MB); not opened (--no-open)",
                       err=True)
        else:
            open_viewer(source)
        return
    if not source.exists():
        raise not_found(source)  # as every verb says it
    if source.name.lower().endswith(".json"):  # a timeline or another output: said before
        raise LogFormatError(                  # the display is asked for (a trial: exit 69)
            f"{source}: a JSON file, not a log nor a Rerun recording: view the .rrd "
            "`detect --rerun` writes beside a timeline, or the log itself")
    if no_open and save_path is None:
        raise click.UsageError("--no-open on a LOG needs --save PATH (else nothing is kept)")

    if not no_open:
        check_display()  # before the replay's work

    def record(rrd: Path) -> None:
        result = record_log(source, rrd, robot=robot, model=model, config=config,
                            read_options=read_options, max_points=max_points,
                            event_window_s=event_window)
        for msg in result.warnings:
            click.echo(f"impactcli: warning: {msg}", err=True)

    if save_path is not None:
        record(save_path)
        click.echo(str(save_path))
        if not no_open:
            open_viewer(save_path)
        return
    from ..files import temporary_folder
    from ..logs import log_stem

    with temporary_folder("impactcli-view-") as tmp:
        rrd = Path(tmp) / f"{log_stem(source)}.rrd"
        record(rrd)
        open_viewer(rrd)
