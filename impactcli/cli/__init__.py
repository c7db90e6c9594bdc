"""The ``impactcli`` command group: parses options, calls one function, picks the exit code
(docs/formats.md, "Command line").

Each verb lives in its own module ``impactcli/cli/<verb>.py`` and is imported only
when invoked, so ``impactcli --help`` stays fast.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from typing import Any

import click

from .. import __version__

#: Exit code when stdout's reader closed the pipe early (``impactcli detect ... | head -1``):
#: the shell's code for a process ended by SIGPIPE, 128 + 13, as ``yes | head -1`` reports
#: it under ``set -o pipefail``. Not 0: the run was cut short where it stood (what it had not
#: yet printed, and anything after, is lost); not 1 ("collision found") nor 70 (a bug).
EXIT_BROKEN_PIPE = 141


def _quiet_broken_pipe() -> None:
    """stdout's reader is gone: point stdout at devnull, as Python's docs recommend for
    SIGPIPE, so the interpreter's final flush of what is still buffered cannot fail (no
    "Exception ignored ... BrokenPipeError" at exit)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout without a file descriptor (e.g. captured)
        pass
    finally:
        os.close(devnull)


#: verb -> (module, attribute, one-line help)
VERBS: dict[str, tuple[str, str, str]] = {
    "inspect": ("impactcli.cli.inspect", "inspect_cmd",
                "Show what a log holds: joints, channels, rate, gaps."),
    "simulate": ("impactcli.cli.simulate", "simulate_cmd",
                 "Simulate a flexible-joint arm with labelled contacts."),
    "identify": ("impactcli.cli.identify", "identify_cmd",
                 "Identify a rough rigid model from a log."),
    "calibrate": ("impactcli.cli.calibrate", "calibrate_cmd",
                  "Calibrate thresholds on collision-free logs."),
    "detect": ("impactcli.cli.detect", "detect_cmd", "Replay the impact detectors over logs."),
    "report": ("impactcli.cli.report", "report_cmd", "Write a safety-audit report (HTML + JSON)."),
    "view": ("impactcli.cli.view", "view_cmd", "Open a run or a log in the Rerun viewer."),
    "evaluate": ("impactcli.cli.evaluate", "evaluate_cmd",
                 "Measure detection quality against labels."),
    "sensitivity": ("impactcli.cli.sensitivity", "sensitivity_cmd",
                    "Reproduce the paper's Table II on the simulator."),
    "robots": ("impactcli.cli.robots", "robots_cmd",
               "List the robots --robot NAME takes (the robots extra)."),
    "labels": ("impactcli.cli.labels", "labels_cmd",
               "Make ground-truth labels from a logged switch or force channel."),
    "channel-maps": ("impactcli.cli.channel_maps", "channel_maps_cmd",
                     "List the shipped channel maps, or print one to start your own."),
}


class LazyGroup(click.Group):
    """A click group whose subcommands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return [v for v, (mod, _, _) in VERBS.items() if importlib.util.find_spec(mod) is not None]

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in VERBS:
            return None
        mod, attr, _ = VERBS[cmd_name]
        if importlib.util.find_spec(mod) is None:
            return None
        cmd = getattr(importlib.import_module(mod), attr)
        assert isinstance(cmd, click.Command)
        return cmd

    def make_context(self, info_name: str | None, args: list[str],
                     parent: click.Context | None = None, **extra: Any) -> click.Context:
        try:  # the group's own --help and --version print here
            return super().make_context(info_name, args, parent, **extra)
        except BrokenPipeError:
            _quiet_broken_pipe()
            raise click.exceptions.Exit(EXIT_BROKEN_PIPE) from None

    def invoke(self, ctx: click.Context) -> Any:
        """Run the verb; stdout's reader closing early (``| head -1``) ends the run quietly
        with :data:`EXIT_BROKEN_PIPE` (click alone would exit 1, which reads as "collision
        found"). The outputs already written stay."""
        from ..errors import EXIT_SIGINT, Interrupted
        from ..run.stopping import stop_on_signals

        try:
            try:
                with stop_on_signals():
                    _remove_stale_temp()
                    return super().invoke(ctx)
            finally:  # a pipe broken under still-buffered output shows here, not at exit
                sys.stdout.flush()
        except BrokenPipeError:
            _quiet_broken_pipe()
            raise click.exceptions.Exit(EXIT_BROKEN_PIPE) from None
        except (Interrupted, KeyboardInterrupt) as stop:
            # 128 + the signal (130 SIGINT, 143 SIGTERM), over 1 and 4: a stopped run judged
            # nothing; the outputs already written stay, no temporary file is left
            name, code = ((stop.name, stop.exit_code) if isinstance(stop, Interrupted)
                          else ("SIGINT", EXIT_SIGINT))
            click.echo(f"impactcli: stopped by {name}: the outputs already written stay "
                       f"(exit {code})", err=True)
            raise click.exceptions.Exit(code) from None

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(v, VERBS[v][2]) for v in self.list_commands(ctx)]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)


def _remove_stale_temp() -> None:
    """Before a verb: the temporary folders killed runs left in TMPDIR go, said in one line
    (:func:`impactcli.files.remove_stale_temp`)."""
    import tempfile

    from ..files import remove_stale_temp

    count, size = remove_stale_temp()
    if count:
        click.echo(f"impactcli: removed {count} temporary folder(s) ({size / 1e6:.3g} MB) "
                   f"that runs since killed had left in {tempfile.gettempdir()}", err=True)


def run() -> None:
    """The ``impactcli`` program: :func:`main`, then a stop signal during the process's
    teardown is said and ignored (:func:`impactcli.run.stopping.after_finish`)."""
    from ..run.stopping import after_finish

    try:
        main(prog_name="impactcli")
    finally:
        after_finish()


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="impactcli")
@click.option("--debug", is_flag=True, help="Show tracebacks for data errors.")
@click.pass_context
def main(ctx: click.Context, debug: bool) -> None:
    """Find out whether, when and where a robot arm hit something.

    Exit codes: 0 success; 1 events found with --fail-on-detect, or a contact force above
    N with detect --fail-on-force N; 2 usage error (also an output that cannot be
    written, or no room in TMPDIR);
    3 bad input (log, config, model, labels); 4 a batch where some inputs failed;
    5 a gate could not judge (--fail-on-detect on a log that is all warm-up,
    --fail-on-force with an incident that has no force estimate or one that may be larger
    (≳) under N, a payload change not told from a steady press, a truncated file;
    1 wins over 5);
    69 this machine cannot do it (view without a display);
    70 an internal error (a bug; its traceback is printed); 130 stopped by SIGINT (Ctrl-C),
    143 by SIGTERM (outputs already written stay); 141 stdout's reader closed early
    (| head), as for SIGPIPE.
    """
    ctx.ensure_object(dict)
    obj: dict[str, Any] = ctx.obj
    obj["debug"] = debug

