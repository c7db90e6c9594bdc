"""The paper's Table II reproduced on the simulator, a false-alarm soak, and the comparison
of the detectors at matched false-alarm rates (``impactcli sensitivity``).

One simulated robot per arm preset (its parameters drawn from the seed; the identification
and the detectors get only the nominal description) is calibrated on collision-free runs
without payload (:func:`impactcli.calibration.calibrate`); that config replays every soak
run (collision-free, payload included: every alarm after warm-up is a false alarm) and every
Table II case (stiffness, amplitude, seed: joint 1's triangles hitting an elastomer).
Thresholds are compared as calibrated (scale 1) and *matched* (per detector, the smallest
swept scale from which on the soak has no false alarm). The study's design, definitions and
rates: docs/validation.md.

Where its parts live (:mod:`impactcli.study`, data flowing one way): ``spec`` (what runs),
``scenarios`` (the robot, references, scenarios), ``tasks`` (run in worker processes),
``summary`` (one JSON-ready mapping), ``tables`` (text and Markdown). This module runs the
study (:func:`run_study`) and re-exports their names (alias: removed in M).
Pure maths and simulation; no file I/O, no printing (the CLI does both).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from .study.scenarios import (
    amplitudes,
    case_scenario,
    free_scenario,
    servo_compliance,
    task_reference,
    the_robot,
)
from .study.spec import (
    ARM_GEOMETRY,
    G_N_PER_KG,
    PAPER_ADAPTIVE_N,
    PAPER_STATIC_N,
    PAPER_STIFFNESSES,
    SCHEMA_VERSION,
    SETTINGS,
    SOAK_FAMILIES,
    VARIANTS,
    StudySpec,
    Variant,
)
from .study.summary import (
    EARLIER_MIN_S,
    poisson_upper_95,
    summarize,
    zero_fa_index,
)
from .study.tables import (
    MD_ROC_PICKS,
    ROC_PICKS,
    ROW_LABELS,
    TABLE_DETECTORS,
    format_markdown,
    format_text,
    iter_detectors,
    table_rows,
)
from .study.tasks import (
    CalibOutcome,
    CalibTask,
    CaseOutcome,
    CaseTask,
    ContactRecord,
    SoakOutcome,
    SoakTask,
    run_calibration,
    run_case,
    run_soak,
    soak_false_alarms,
)

__all__ = [
    "ARM_GEOMETRY",
    "EARLIER_MIN_S",
    "G_N_PER_KG",
    "MD_ROC_PICKS",
    "PAPER_ADAPTIVE_N",
    "PAPER_STATIC_N",
    "PAPER_STIFFNESSES",
    "ROC_PICKS",
    "ROW_LABELS",
    "SCHEMA_VERSION",
    "SETTINGS",
    "SOAK_FAMILIES",
    "TABLE_DETECTORS",
    "VARIANTS",
    "CalibOutcome",
    "CalibTask",
    "CaseOutcome",
    "CaseTask",
    "ContactRecord",
    "Runner",
    "SoakOutcome",
    "SoakTask",
    "StudySpec",
    "Variant",
    "amplitudes",
    "case_scenario",
    "format_markdown",
    "format_text",
    "free_scenario",
    "iter_detectors",
    "poisson_upper_95",
    "run_calibration",
    "run_case",
    "run_soak",
    "run_study",
    "serial_runner",
    "servo_compliance",
    "soak_false_alarms",
    "summarize",
    "table_rows",
    "task_reference",
    "the_robot",
    "zero_fa_index",
]


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
