"""The line a benchmark prints of the machine it ran on (the README and docs name it next
to every figure)."""

from __future__ import annotations

import os
import platform
import time


def machine_line(t0: float | None = None) -> str:
    """``machine: <platform>, <processor>, N CPUs, Python X.Y.Z; load average L`` and, given
    the run's start (``time.perf_counter()``), ``; total T s``."""
    total = "" if t0 is None else f"; total {time.perf_counter() - t0:.1f} s"
    return (f"machine: {platform.platform()}, {platform.processor() or platform.machine()}, "
            f"{os.cpu_count()} CPUs, Python {platform.python_version()}; load average "
            f"{os.getloadavg()[0]:.1f}{total}")
