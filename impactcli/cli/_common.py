"""alias: removed in M — what every verb shares is :mod:`impactcli.cli.options`; verbs of
other work packages still import it from here."""

from .options import (  # alias: removed in M
    ROBOT_METAVAR,
    ROBOT_URL_METAVAR,
    check_log_path,
    handle_errors,
    is_log_path,
    not_found,
    progress,
    robot_help,
)

__all__ = [
    "ROBOT_METAVAR",
    "ROBOT_URL_METAVAR",
    "check_log_path",
    "handle_errors",
    "is_log_path",
    "not_found",
    "progress",
    "robot_help",
]
