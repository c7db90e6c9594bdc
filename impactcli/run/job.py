"""One log replayed for a verb (``detect``, ``report``, ``view``, ``evaluate``): the inputs
read, the log read in chunks, and the writers each verb asked for fed chunk by chunk.

:func:`run_log` is the one place that wires writers to a replay's ``on_chunk``: the signals
Parquet (a row group per chunk), the Rerun recording (a spill of what it plots, written
once the answer is known), the report's or the sweep's samples. Nothing of the replay's
per-sample data stays in memory.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any, NamedTuple

from ..config import DetectorConfig
from ..logs.paths import log_stem
from ..logs.reader import open_log
from ..model.rigid import RigidModel
from ..types import ReadOptions, RobotDescription, SignalsChunk
from .one_log import RunSetup, detect_log


class Inputs(NamedTuple):
    """The robot description, model and config of a run (None when not given), and their
    provenance: ``{"robot"|"model"|"config": {"path", "sha256"}}`` for those given."""

    robot: RobotDescription | None
    model: RigidModel | None
    config: DetectorConfig | None
    provenance: dict[str, dict[str, str]]


def load_inputs(robot_path: str | None, model_path: str | None, config_path: str | None
                ) -> Inputs:
    """The one loader of ``--robot``, ``--model`` and ``--config`` (paths or URLs; a shipped
    robot's name): each read once, in that order, and named in its error — what every
    replay of a log starts from, and what a batch reads up front so that a bad one stops the
    run before any work. A shipped robot's provenance is its URDF's sha256."""
    from ..config import load_config
    from ..files import sha256_file
    from ..logs.robot_files import named_robot_sha256, read_robot
    from ..logs.urls import load_by_url
    from .model_files import read_model

    provenance: dict[str, dict[str, str]] = {}

    def load(key: str, path: str | None, loader: Callable[[Path], Any], what: str) -> Any:
        if path is None:
            return None
        path = str(path)
        if key == "robot" and (named := named_robot_sha256(path)) is not None:
            provenance[key] = {"path": path, "sha256": named}
            return read_robot(path)

        def read(lp: Path) -> tuple[Any, str]:
            return loader(lp), sha256_file(lp)

        obj, sha = load_by_url(path, read, what)
        provenance[key] = {"path": path, "sha256": sha}
        return obj

    robot = load("robot", robot_path, read_robot, "robot description")
    model = load("model", model_path, read_model, "model")
    config = load("config", config_path, load_config, "config")
    return Inputs(robot, model, config, provenance)


def progress_bar(log_path: str, show: bool, what: str, unit: str) -> Any:
    """A progress bar on stderr named after the log, when ``show`` and stderr is a
    terminal (None when not ``show``)."""
    if not show:
        return None
    import sys

    from tqdm import tqdm

    return tqdm(total=0, desc=f"{log_stem(log_path)}: {what}", unit=unit,
                file=sys.stderr, leave=False, disable=not sys.stderr.isatty())


def run_log_from_paths(
    log_path: str, *, robot_path: str | None = None, model_path: str | None = None,
    config_path: str | None = None, **options: Any,
) -> tuple[Any, Any]:
    """:func:`run_log` with the robot description, model and config read from these
    paths or URLs (:func:`load_inputs`; the config's path named in messages).
    ``options``: :func:`run_log`'s."""
    robot, model, config, _ = load_inputs(robot_path, model_path, config_path)
    return run_log(log_path, robot=robot, model=model, config=config,
                   config_where=config_path or "config", **options)


def run_log(
    log_path: str, *, robot: RobotDescription | None, model: RigidModel | None,
    config: DetectorConfig | None, read_options: ReadOptions | None = None,
    model_from_log: bool = False,
    generator: str | None = None, config_where: str = "config", allow_slow: bool = False,
    show_progress: bool = False, signals_path: Path | None = None,
    rrd_path: Path | None = None, rrd_options: dict[str, Any] | None = None,
    samples: str | None = None, check: Callable[[Any], None] | None = None,
) -> tuple[Any, Any]:
    """Replay one log chunk by chunk in bounded memory, feeding the writers asked for.

    The log is scanned (``check(scan)`` is called before the replay, e.g. a timeline's
    sha256 check), then replayed (:func:`impactcli.run.one_log.detect_log`) with the loaded
    ``robot``, ``model`` and ``config`` (``config_where``: its file, for messages; the other
    arguments as :class:`~impactcli.run.one_log.RunSetup`'s). ``signals_path`` gets the
    signals Parquet, written as the replay goes; ``rrd_path`` the Rerun recording
    (``rrd_options``: ``max_points``, ``event_window_s``) — both atomically, and not at
    all when the replay fails; ``samples="report"`` keeps what a report reads of the
    samples (:mod:`impactcli.outputs.report.samples`), ``samples="sweep"`` only what the
    threshold sweep reads (the ratios' columns). Progress in seconds of log, summed over the
    passes, when ``show_progress`` and stderr is a terminal.

    Returns:
        (the :class:`impactcli.types.DetectionResult`; the
        :class:`impactcli.outputs.report.samples.Samples` asked for, else None),
        the caller closing the samples (they remove their spill file).
    """
    from ..outputs.signals import SignalsWriter

    opts = read_options or ReadOptions()
    from ..config import DetectorConfig
    from .plan import description_of

    # a current is turned into torque by --robot, else the model's robot (--model, else the
    # config's): a trial's current-only log needed --robot again beside its config
    described = robot if robot is not None else description_of(model,
                                                                config or DetectorConfig())
    read_kw = (opts.as_dict() if described is None
               else dict(opts.as_dict(), robot=described))
    reader = open_log(log_path, **read_kw)
    bar = None
    collector = None
    try:
        scan = reader.scan()
        if check is not None:
            check(scan)
        bar = progress_bar(log_path, show_progress, "replay", "s of log (all passes)")
        with ExitStack() as stack:
            writers: list[Callable[[SignalsChunk], None]] = []
            if signals_path is not None:
                sig = stack.enter_context(SignalsWriter(
                    signals_path, scan.t0_ns, scan.source.sha256, scan.source.path))
                writers.append(lambda c: sig.append(c.joints, c.time_s, c.signals,
                                                    c.decisions))
            rerun = None
            if rrd_path is not None:
                from ..outputs.rerun import RerunWriter

                rerun = stack.enter_context(RerunWriter())
                writers.append(rerun)
            if samples is not None:
                from ..outputs.report.samples import ReportCollector

                collector = ReportCollector(scan.n_samples, scan.gaps, scan.gap_lengths_s,
                                            plots=samples == "report")
                writers.append(collector)

            def on_chunk(c: SignalsChunk) -> None:
                for w in writers:
                    w(c)

            def progress(done_s: float, total_s: float) -> None:
                assert bar is not None
                bar.total = round(total_s)
                bar.n = round(done_s)
                bar.refresh()

            setup = RunSetup(config=config, model=model, robot=robot, generator=generator,
                             model_from_log=model_from_log, allow_slow=allow_slow,
                             config_where=config_where, read_options=opts)
            result = detect_log(reader, setup, on_chunk=on_chunk if writers else None,
                                progress=progress if bar is not None else None)
            if rerun is not None and rrd_path is not None:
                rerun.write(result, rrd_path, **(rrd_options or {}))
            return result, None if collector is None else collector.finish(result)
    except BaseException:
        if collector is not None:
            collector.close()
        raise
    finally:
        if bar is not None:
            bar.close()
        reader.close()
