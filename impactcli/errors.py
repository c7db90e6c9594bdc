"""One error hierarchy for impactcli.

Every error that is the *input's* fault (a log, config, model, labels or robot
description that is bad) is an :class:`ImpactError`; the CLI turns it into one
line on stderr and the exit code in ``exit_code`` (docs/formats.md, "Command line": 3
for data errors, 4 for a batch in which some inputs failed). Anything else is a bug: it
keeps its traceback (printed on stderr) and exits :data:`EXIT_SOFTWARE` (70,
sysexits' ``EX_SOFTWARE``) — never 1, which a CI gate reads as "collision found".

Messages name the offending thing: ``f"{path}: column {name!r} missing"``.
"""

from __future__ import annotations

#: Exit codes of the command line (docs/formats.md, "Command line").
EXIT_OK = 0
EXIT_DETECTED = 1
EXIT_USAGE = 2
EXIT_DATA = 3
EXIT_BATCH = 4
#: A gate (``--fail-on-detect``, ``--fail-on-force``) could not judge what it was asked to:
#: no time after warm-up analysed, an incident without a force estimate, or a recording
#: the file holds only up to a cut (a truncated MCAP or CSV). A judged
#: failure (1) wins over it; a batch's 4 keeps its priority.
EXIT_UNJUDGED = 5
#: The machine cannot do what was asked (no display for the viewer): sysexits.h
#: EX_UNAVAILABLE. Not the input's fault.
EXIT_UNAVAILABLE = 69
#: An internal error (a bug, or a worker that died): sysexits.h EX_SOFTWARE.
EXIT_SOFTWARE = 70
#: Stopped by SIGINT (Ctrl-C) or SIGTERM: the shell's 128 + the signal's number. They win
#: over 1 and 4: a run that was stopped judged nothing.
EXIT_SIGINT = 130
EXIT_SIGTERM = 143


class ImpactError(Exception):
    """Base of all errors caused by bad input; carries the CLI exit code."""

    exit_code: int = EXIT_DATA


class LogFormatError(ImpactError, ValueError):
    """A log file is missing, unreadable, malformed or of an unknown format."""


class ChannelMapError(LogFormatError):
    """A channel map is malformed or points at nothing in its log."""


class ConfigError(ImpactError, ValueError):
    """A detector config file or value is invalid."""


class RobotDescriptionError(ImpactError, ValueError):
    """A robot description (or its URDF) is invalid or does not match the log."""


class ModelError(ImpactError, ValueError):
    """A model file is invalid, or a model cannot be identified from the log."""


class LabelsError(ImpactError, ValueError):
    """A ground-truth labels file is invalid."""


class OutputError(ImpactError):
    """An output path that cannot be written (its folder is a file, no permission, ...):
    a bad ``-o``/``--json`` value, exit 2."""

    exit_code = EXIT_USAGE


class TempSpaceError(OutputError):
    """The temporary folder (``TMPDIR``) cannot take what a streamed replay spills there
    (full, or not writable): exit 2, set ``TMPDIR`` elsewhere."""


class ScaleLimitError(ImpactError):
    """A replay whose estimated cost is above the documented limit (exit 2: say
    ``--allow-slow`` to go on anyway)."""

    exit_code = EXIT_USAGE


class UsageProblem(ImpactError):
    """A bad option or combination of options found below the CLI (exit 2): the CLI shows it
    as click shows its own usage errors — for ``param_hint`` (e.g. ``'--labels'``) as a bad
    value of that option."""

    exit_code = EXIT_USAGE

    def __init__(self, message: str, param_hint: str | None = None) -> None:
        super().__init__(message)
        self.param_hint = param_hint


class UnavailableError(ImpactError):
    """This machine cannot do it — the viewer needs a display (exit 69): not the input's
    fault, and the message says what works instead."""

    exit_code = EXIT_UNAVAILABLE


class BatchError(ImpactError):
    """A batch finished but some inputs failed (their outputs are not written)."""

    exit_code = EXIT_BATCH


class Interrupted(BaseException):
    """The run was stopped by a signal (SIGINT or SIGTERM): raised where the main process
    stands, so that every ``with`` and ``finally`` on the way out runs (temporary files
    removed, outputs already moved into place kept). Not an :class:`ImpactError` (nothing
    was wrong with the input) and not an ``Exception`` (a batch's per-log ``except
    Exception`` must not swallow it)."""

    def __init__(self, signum: int, name: str) -> None:
        super().__init__(name)
        self.signum = signum
        self.name = name
        self.exit_code = 128 + signum


def one_line(text: object) -> str:
    """``text`` with its control characters escaped (a newline as ``\\n``), so that a
    message naming a file called ``a\\nb.csv`` stays one line."""
    s = str(text)
    if s.isprintable():
        return s
    return "".join(c if c.isprintable() or c == " " else
                   c.encode("unicode_escape").decode("ascii") for c in s)


class ImpactWarning(UserWarning):
    """A repair or fallback the user must know about (printed as one line by the CLI)."""
