"""What every verb shares: turning ImpactError into one line + exit code, warnings, progress,
and what a log path may be (a file, or a rosbag2 folder)."""

from __future__ import annotations

import functools
import sys
import traceback
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import click

from ..errors import EXIT_SOFTWARE, ImpactError, ImpactWarning, LogFormatError

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
        click.echo(f"impactcli: warning: {message}", err=True)
    else:  # a library's warning: still one line
        click.echo(f"impactcli: warning: {category.__name__}: {message}", err=True)


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
        except ImpactError as err:
            if debug:
                click.echo(traceback.format_exc().rstrip(), err=True)
            click.echo(f"impactcli: error: {err}", err=True)
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


def is_log_path(path: Path) -> bool:
    """Whether ``path`` can be a local log: a file, or a rosbag2 folder (``metadata.yaml``)."""
    from ..io.bags import is_rosbag2_folder

    return path.is_file() or is_rosbag2_folder(path)


def not_found(path: Path | str, what: str = "log file") -> LogFormatError:
    """The error for a missing input, as :func:`impactcli.io.read_log` words it: a glob
    (``*``, ``?``, ``[``) that matched nothing says so, else ``<what> not found``."""
    where = str(path)
    if any(c in where for c in "*?["):
        return LogFormatError(f"{where}: the pattern matches no file")
    return LogFormatError(f"{where}: {what} not found")


def check_log_path(path: Path) -> None:
    """Raise the LogFormatError :func:`impactcli.io.read_log` would (exit 3, one line) for a
    missing log or a folder that is not a rosbag2 folder — for verbs that look beside a log
    (labels) before reading it. Log arguments take folders (``click.Path()`` without
    ``dir_okay=False``): a folder is refused here or by ``read_log``, never by click."""
    if not path.exists():
        raise not_found(path)
    if path.is_dir() and not is_log_path(path):
        raise LogFormatError(f"{path}: not a rosbag2 folder (no metadata.yaml)")
