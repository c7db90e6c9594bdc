"""Run the study: the paper's Table II reproduced on the simulator, a false-alarm soak, and
the comparison of the detectors at matched false-alarm rates (``impactcli sensitivity``).

One simulated robot per arm preset is calibrated on collision-free runs without payload
(:func:`impactcli.run.calibration.calibrate`); that config replays every soak run (every alarm
after warm-up is a false alarm) and every Table II case. The study's design, definitions and
rates: docs/validation.md. Pure maths and simulation; no file I/O, no printing.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from .aggregate import summarize
from .arms import amplitudes
from .spec import SOAK_FAMILIES, VARIANTS, StudySpec
from .tasks import (
    CalibTask,
    CaseOutcome,
    CaseTask,
    SoakOutcome,
    SoakTask,
    run_calibration,
    run_case,
    run_soak,
)

__all__ = ["Runner", "run_study", "serial_runner"]


Runner = Callable[[Callable[[Any], Any], Sequence[Any], str], list[Any]]


def serial_runner(fn: Callable[[Any], Any], items: Sequence[Any], desc: str = "") -> list[Any]:
    """Run tasks one after the other in this process (results in input order)."""
    return [fn(x) for x in items]


def run_study(spec: StudySpec, runner: Runner = serial_runner) -> dict[str, Any]:
    """Run the whole study and summarise it (:func:`summarize`).

    ``runner(fn, items, desc)`` maps a top-level task function over picklable items and
    returns the results in input order (serial by default; the CLI passes a process pool).
    """
    arms = list(dict.fromkeys(VARIANTS[v].arm for v in spec.variants))
    calibs = runner(run_calibration, [CalibTask(a, spec) for a in arms], "calibrate")
    cfg_of = {c.arm: c.config for c in calibs}
    soak_tasks = [SoakTask(v, fam, r, spec, cfg_of[VARIANTS[v].arm])
                  for v in spec.variants for fam in SOAK_FAMILIES for r in range(spec.soak_runs)]
    case_tasks = []
    for v in spec.variants:
        arm = VARIANTS[v].arm
        amps = amplitudes(arm, spec.forces_n)
        for k in spec.stiffnesses:
            for a, f in zip(amps, spec.forces_n, strict=True):
                for s in range(spec.case_seeds):
                    case_tasks.append(CaseTask(v, k, a, f, s, spec, cfg_of[arm]))
    # long soak runs first so the pool ends on short cases
    mixed: list[Any] = [*soak_tasks, *case_tasks]
    out = runner(_run_any, mixed, "soak + cases")
    soaks = [o for o in out if isinstance(o, SoakOutcome)]
    cases = [o for o in out if isinstance(o, CaseOutcome)]
    return summarize(spec, calibs, soaks, cases)


def _run_any(task: Any) -> Any:
    if isinstance(task, SoakTask):
        return run_soak(task)
    return run_case(task)
