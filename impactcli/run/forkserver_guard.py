"""Imported by the local pool's fork server, and only there
(:data:`impactcli.run.executors.POOL_PRELOAD`): the fork server asks for SIGKILL when the
process that started it dies, so that a killed ``detect --jobs N`` leaves no fork server
behind (:mod:`impactcli.run.stopping`). Imported anywhere else (a process not started as
a fork server) it does nothing."""

from __future__ import annotations

import sys

from .stopping import die_with_parent


def is_fork_server() -> bool:
    """Whether this process is multiprocessing's fork server (started as ``python -c``
    running ``multiprocessing.forkserver.main``)."""
    return sys.argv[:1] == ["-c"] and "multiprocessing.forkserver" in sys.modules


if is_fork_server():
    die_with_parent()
