"""The numba kernels compiled once into numba's on-disk cache before the test workers
start: ``python -m tests.jit_warmup PART``, the two parts side by side, run by
tests/conftest.py when pytest-xdist shares the tests out. Each worker would otherwise
compile the same kernels itself: on 2 vCPUs the replay's take about 15 s, the
simulator's 14 s and the tests' RLS reference 7 s; from the cache they load in well
under a second. Which process compiles a kernel changes no result: a worker that finds
no cache compiles as before."""

from __future__ import annotations

import dataclasses
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def simulator() -> None:
    """The simulator's kernels: a short run with a push and the controller's channels."""
    from impactcli.sim import scenario, simulate
    from impactcli.sim.contacts import Push

    sc = dataclasses.replace(scenario("free_p2p", "assist_like", 2.0),
                             controller_channels=True, pushes=(Push(2, 1.0, 10.0, 0.1),))
    simulate(sc, seed=0)


def rls_reference() -> None:
    """The tests' reference RLS (eq. 37-40), which runs the package's RLS update alone."""
    import numpy as np

    from .reference.rls import rls_run

    rls_run(np.eye(3), np.ones(3), forgetting_factor=0.99)


def replay() -> None:
    """The replay's kernels: a sample log detected with its arm's config."""
    from impactcli.config import load_config
    from impactcli.logs import read_log
    from impactcli.run.collect import detect_in_memory

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = read_log(SAMPLES / "csv" / "assist_free_p2p.csv.gz")
        detect_in_memory(log, config=load_config(SAMPLES / "assist_like.config.toml"))


#: The parts, about equally long, that tests/conftest.py runs side by side.
PARTS: dict[str, tuple[Callable[[], None], ...]] = {
    "simulator": (simulator, rls_reference),
    "replay": (replay,),
}

if __name__ == "__main__":
    for step in PARTS[sys.argv[1]]:
        step()
