"""How many cores this process may give its own threads: the adaptive evaluator's axes and
the measured floor's probes (:func:`impactcli.detect.adaptive.default_threads`,
:mod:`impactcli.detect.probe`). The machine's, or — in one of N pool workers
(``detect --jobs N``), after :func:`set_workers` — its share of them: N workers each
starting one thread per core would put N times the cores' threads on the cores. The
results never depend on it (docs/performance.md)."""

from __future__ import annotations

import os

_WORKERS = [1]  # the processes sharing the machine's cores (set in a pool worker)


def cores() -> int:
    """The cores this process's own threads may use (at least 1)."""
    return max(1, (os.cpu_count() or 1) // _WORKERS[0])


def set_workers(workers: int) -> None:
    """Declare this process one of ``workers`` pool workers sharing the cores."""
    _WORKERS[0] = max(1, int(workers))
