"""What every verb shares: turning ImpactError into one line + exit code, warnings, progress,
what a log path may be (a file, or a rosbag2 folder), and the options several verbs take
(how to read a log, the model and config, the residual generator, where batch work runs).

Imports of the package inside the option factories keep ``impactcli --help`` fast."""

from __future__ import annotations

import functools
import sys
import traceback
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from ..errors import (
    EXIT_SOFTWARE,
    EXIT_USAGE,
    ImpactError,
    ImpactWarning,
    LogFormatError,
    UsageProblem,
    one_line,
)

if TYPE_CHECKING:
    from ..types import ReadOptions

F = TypeVar("F", bound=Callable[..., Any])
T = TypeVar("T")


#: --robot's metavar: a robot description file, or a shipped robot's name (``impactcli
#: robots``); detect also fetches a URL (:data:`ROBOT_URL_METAVAR`).
ROBOT_METAVAR = "FILE|NAME"
ROBOT_URL_METAVAR = "FILE|URL|NAME"


def robot_help(what: str, url: bool = False) -> str:
    """--robot's help: ``what`` the description serves, then what the value may be."""
    where = "a file or an fsspec URL" if url else "a file"
    return (f"Robot description ({what}): {where} (JSON/YAML), or a shipped robot's name "
            "(`impactcli robots` lists them).")


def _show_warning(message: Warning | str, category: type[Warning], *args: Any, **kw: Any) -> None:
    if issubclass(category, ImpactWarning):
        click.echo(one_line(f"impactcli: warning: {message}"), err=True)
    else:  # a library's warning: still one line
        click.echo(one_line(f"impactcli: warning: {category.__name__}: {message}"), err=True)


def handle_errors(func: F) -> F:
    """Decorate a click command: ImpactError → ``impactcli: error: <msg>`` on stderr, its exit code.

    With the group's ``--debug``, the traceback is shown too (same exit code). Any other
    exception is a bug: ``impactcli: error: internal error (a bug): <type>: <msg>`` and its
    traceback on stderr, exit :data:`~impactcli.errors.EXIT_SOFTWARE` (70) — never 1, which
    a CI gate reads as "collision found". click's own exits (usage errors, ``ctx.exit``),
    interrupts and a broken stdout pipe (the command group exits 141 on it) pass through.
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        ctx = click.get_current_context()
        debug = bool((ctx.find_root().obj or {}).get("debug"))
        old = warnings.showwarning
        warnings.showwarning = _show_warning  # type: ignore[assignment]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("always", ImpactWarning)
                warnings.showwarning = _show_warning  # type: ignore[assignment]
                return func(*args, **kwargs)
        except UsageProblem as err:  # as click's own usage errors
            if err.param_hint is not None:
                raise click.BadParameter(str(err), param_hint=err.param_hint) from None
            raise click.UsageError(str(err)) from None
        except ImpactError as err:
            if debug:
                click.echo(traceback.format_exc().rstrip(), err=True)
            click.echo(f"impactcli: error: {one_line(err)}", err=True)
            ctx.exit(err.exit_code)
        except (click.exceptions.ClickException, click.exceptions.Exit,
                click.exceptions.Abort):
            raise
        except BrokenPipeError:  # stdout's reader left (`| head`): the entry point's exit
            raise
        except Exception as err:
            click.echo(f"impactcli: error: internal error (a bug): {type(err).__name__}: "
                       f"{err}", err=True)
            click.echo(traceback.format_exc().rstrip(), err=True)
            ctx.exit(EXIT_SOFTWARE)
        finally:
            warnings.showwarning = old

    return wrapper  # type: ignore[return-value]


def progress(items: Iterable[T], total: int | None = None, desc: str = "") -> Iterator[T]:
    """A progress bar on stderr over ``items``: shown for two or more items when stderr is
    a terminal (a CI log or a pipe gets no carriage-return noise)."""
    from tqdm import tqdm

    seq = list(items) if total is None else items
    n = total if total is not None else len(seq)  # type: ignore[arg-type]
    disable = n < 2 or not sys.stderr.isatty()
    yield from tqdm(seq, total=n, desc=desc, disable=disable, file=sys.stderr, leave=False)


def not_found(path: Path | str, what: str = "log file") -> LogFormatError:
    """The error for a missing input, as :func:`impactcli.logs.read_log` words it: a glob
    (``*``, ``?``, ``[``) that matched nothing says so, else ``<what> not found``."""
    where = str(path)
    if any(c in where for c in "*?["):
        return LogFormatError(f"{where}: the pattern matches no file")
    return LogFormatError(f"{where}: {what} not found")


def check_log_path(path: Path) -> Path:
    """The log a verb that reads one log reads for ``path`` (``path`` itself, or the one
    log of a folder that is not a rosbag2 folder: :func:`impactcli.logs.paths.one_log_in`),
    raising what :func:`impactcli.logs.read_log` would for a missing log, a folder without
    a log (exit 3) or of several (exit 2, listing them) — for verbs that look beside a log
    (labels) before reading it. Log arguments take folders (``click.Path()`` without
    ``dir_okay=False``): a folder is resolved here or by ``read_log``, never by click."""
    from ..logs.paths import one_log_in

    if not path.exists():
        raise not_found(path)
    return one_log_in(path)


def read_options_of(values: dict[str, Any]) -> ReadOptions:
    """The :class:`~impactcli.types.ReadOptions` of the options given on the command line;
    ``--rate`` with ``--time-unit`` or ``--time-column`` is a usage error (exit 2)."""
    from ..types import ReadOptions  # here: `impactcli --help` stays fast

    if values.get("rate") is not None and (values.get("time_unit") is not None
                                           or values.get("time_column") is not None):
        raise click.UsageError("--rate places sample i at i / rate: it excludes "
                               "--time-unit and --time-column")
    return ReadOptions(**{k: v for k, v in values.items() if v is not None})


def check_channel_map(ctx: click.Context, param: click.Parameter, value: str | None
                      ) -> str | None:
    """``--channel-map``: a file that exists or a shipped map's name, else a usage error
    (exit 2) listing the shipped maps; a file's content is checked when it is read (a bad
    one is a data error, exit 3)."""
    if value is None or "://" in value:
        return value
    from ..errors import ChannelMapError
    from ..logs.channel_map import resolve_channel_map_path

    try:
        resolve_channel_map_path(value)
    except ChannelMapError as err:
        raise click.BadParameter(str(err), ctx=ctx, param=param) from None
    return value


def log_read_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The options that say how to read a log (shared by the verbs that read logs), given
    to the command as one ``read_options`` (:class:`~impactcli.types.ReadOptions`)."""

    @functools.wraps(func)
    def with_read_options(*args: Any, **kwargs: Any) -> Any:
        import dataclasses

        from ..types import ReadOptions  # here: `impactcli --help` stays fast

        values = {f.name: kwargs.pop(f.name, None) for f in dataclasses.fields(ReadOptions)}
        return func(*args, read_options=read_options_of(values), **kwargs)

    wrapped: Callable[..., Any] = with_read_options
    for opt in reversed([
        click.option("--channel-map", metavar="MAP", callback=check_channel_map,
                     help="Channel map (path, or a shipped name) for foreign CSV / .npz logs."),
        click.option("--topic", help="MCAP: the JointState/state topic."),
        click.option("--reference-topic", help="MCAP: the reference topic."),
        click.option("--time-source", type=click.Choice(["log", "publish", "header"]),
                     help="MCAP: which clock stamps samples [default: header, else log]."),
        click.option("--torque-source", type=click.Choice(["current", "torque"]),
                     help="Use logged torque or current × gear ratio × torque constant."),
        click.option("--time-unit", type=click.Choice(["s", "ms", "us", "ns"]),
                     help="CSV / .npz: the unit of the time column [default: the unit its "
                          "name says (time_ms, stamp_us, ...), else s, or the channel "
                          "map's]. A time implying a rate outside 20 Hz – 100 kHz is an "
                          "error."),
        click.option("--time-column", metavar="NAME",
                     help="CSV / .npz: the time column (or array) [default: one named time, "
                          "timestamp, stamp, t or __time, any case, with an optional unit "
                          "suffix _s/_ms/_us/_ns; or the channel map's]."),
        click.option("--rate", metavar="HZ", type=click.FloatRange(min=0, min_open=True),
                     help="CSV / .npz without a time column: sample i is at i / HZ seconds "
                          "(recorded in the log's repairs and the timeline)."),
        click.option("--position-unit", type=click.Choice(["rad", "deg"]),
                     help="The unit of the logged positions (and their references, "
                          "velocities and accelerations, per second), converted to rad as "
                          "they are read [default: rad; a log whose positions cannot be "
                          "radians is refused, naming this option]."),
        click.option("--repair-order", is_flag=True, default=None,
                     help="Rows out of time order or sharing a stamp: keep the longest "
                          "increasing run of stamps and drop the others, warned [default: "
                          "an error naming the row]."),
    ]):
        wrapped = opt(wrapped)
    return wrapped


def generator_option(func: Callable[..., Any]) -> Callable[..., Any]:
    """--generator (calibrate, detect): which residual each joint's detectors evaluate."""
    from ..model.generators import GENERATOR_CHOICES

    return click.option(
        "--generator", type=click.Choice(GENERATOR_CHOICES), default=None,
        help="Residual generator for every joint: auto (per joint the log's torque_ext, else "
             "its torque_model with an identified correction, else the tool's own model), "
             "inverse_dynamics, momentum_observer, logged_model, logged_external  [default: "
             "the config's (frozen per joint by calibrate), else auto]")(func)


def model_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--robot, --model, --config (shared by detect, report, view, evaluate)."""
    for opt in reversed([
        click.option("--robot", metavar=ROBOT_METAVAR,
                     type=click.Path(dir_okay=False, path_type=Path),
                     help=robot_help("joints, gear ratios, kinematics")),
        click.option("--model", type=click.Path(dir_okay=False, path_type=Path),
                     help="Rigid model from `impactcli identify` [default: the config's, "
                          "else identified from the log itself]."),
        click.option("--config", type=click.Path(dir_okay=False, path_type=Path),
                     help="Detector config from `impactcli calibrate` (TOML/YAML) "
                          "[default: Table I, uncalibrated thresholds from the log]."),
    ]):
        func = opt(func)
    return func


def model_url_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--robot, --model, --config as paths or fsspec URLs (detect: workers read them)."""
    for opt in reversed([
        click.option("--robot", metavar=ROBOT_URL_METAVAR,
                     help=robot_help("joints, gear ratios, kinematics", url=True)),
        click.option("--model", metavar="PATH|URL",
                     help="Rigid model from `impactcli identify` [default: the config's, "
                          "else identified from the log itself]."),
        click.option("--config", metavar="PATH|URL",
                     help="Detector config from `impactcli calibrate` (TOML/YAML) "
                          "[default: Table I, uncalibrated thresholds from the log]."),
    ]):
        func = opt(func)
    return func


def executor_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--jobs and --scheduler: where batch work runs (impactcli.run.executors)."""
    for opt in reversed([
        click.option("--jobs", "-j", type=click.IntRange(min=1), default=None,
                     help="Inputs processed in parallel by N local processes (no Dask); with "
                          "--scheduler local, the number of Dask workers  [default: 1]"),
        click.option("--scheduler", metavar="local|ADDRESS|FILE", default=None,
                     help="Run on Dask (extra impactcli[dask]): `local` starts a LocalCluster, "
                          "tcp://host:8786 or a scheduler.json file joins a running one "
                          "[default: $DASK_SCHEDULER_ADDRESS when set, else local "
                          "processes per --jobs]."),
    ]):
        func = opt(func)
    return func


def resolve_executor(jobs: int | None, scheduler: str | None) -> Any:
    """The :class:`~impactcli.run.executors.ExecutorChoice` for the options; a bad combination
    is a usage error (exit 2), a missing Dask extra one line saying how to install it."""
    from ..run.executors import choose_executor, require_dask

    try:
        choice = choose_executor(jobs, scheduler)
    except ValueError as err:
        raise click.BadParameter(str(err), param_hint="'--jobs'") from None
    if choice.kind == "dask":
        from ..run.executors import DaskMissingError

        try:
            require_dask()
        except DaskMissingError as err:
            fail_usage(str(err))
    return choice


def fail_usage(msg: str) -> None:
    """One line on stderr and exit 2 (a command-line or environment problem)."""
    click.echo(f"impactcli: error: {one_line(msg)}", err=True)
    click.get_current_context().exit(EXIT_USAGE)
