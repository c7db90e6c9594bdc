"""Running the command line in a test: ``impactcli ARGS`` in-process (click's runner), the
one helper every CLI test uses."""

from __future__ import annotations

from collections.abc import Sequence

from click.testing import CliRunner, Result

from impactcli.cli import main


def _argv(args: tuple[object, ...]) -> list[str]:
    """The arguments as strings (paths, numbers); one list or tuple stands for its items."""
    if len(args) == 1 and isinstance(args[0], list | tuple):
        args = tuple(args[0])
    return [str(a) for a in args]


def invoke(*args: object) -> Result:
    """``impactcli ARGS``: click's result (exit code, stdout, stderr, exception). An
    exception the CLI does not turn into an exit code propagates to the test."""
    return CliRunner().invoke(main, _argv(args), catch_exceptions=False)


def cli(*args: object | Sequence[object]) -> tuple[int, str, str]:
    """``impactcli ARGS``: (exit code, stdout, stderr)."""
    r = invoke(*args)
    return r.exit_code, r.stdout, r.stderr
