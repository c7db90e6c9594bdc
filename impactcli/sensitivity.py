"""The paper's Table II reproduced on the simulator, a false-alarm soak, and the comparison
of the detectors at matched false-alarm rates (``impactcli sensitivity``).

The paper's force-sensor experiment (Sec. IV-B, Table II): joint 1 of the extended arm runs
triangles around the horizontal; on the way down the end effector hits an elastomer on a
load cell; the trajectory amplitude sets the speed at impact. Table II gives the minimal
detected force per elastomer stiffness: 4.44 N @ 10.12, 5.61 N @ 5.93, 5.87 N @ 2.12 N/mm for
the adaptive method, > 20 N for a static threshold v0 on the residual.

How the study is built (all deterministic for ``StudySpec.seed``):

* **The robot.** Per arm preset, ONE simulated robot: the preset's parameters each drawn
  ±20 % from the seed (:func:`the_robot`), then simulated with ``uncertainty=0`` so every
  run of a variant is the same robot (only noise, friction drift and references vary with
  the run's seed). The identification and the detectors only get the preset's NOMINAL
  description. A *variant* is an arm plus an optional end-effector payload that the model
  and the calibration do not know (:data:`VARIANTS`).
* **Calibration** (what the robot could have run online): collision-free runs of the
  variant's arm WITHOUT payload — the experiment's task triangles without the elastomer,
  two-joint triangles, trapezoidal point-to-point moves, multi-sines — ``calib_run_s``
  each, seeds of their own. :func:`impactcli.calibration.calibrate` identifies the rigid model
  over them (``identify_many``) and sets every threshold by leave-one-out. The same
  config (model embedded) is used for every soak run and every case of the arm.
* **Cases** (Table II): one case = (stiffness k, amplitude A, seed). Joint 1 runs triangles
  0 → +A → −A → 0 of period T (:data:`ARM_GEOMETRY`; speed 4A/T), the other joints held at
  0 (extended arm). The elastomer lies ``gap`` rad below the horizontal under the end
  effector and is slid in at the top of a cycle after a collision-free lead-in of
  ≥ ``lead_in_s``; then ``impacts_per_case`` impacts follow. Amplitudes: A = gap +
  F · c / reach for each nominal pressing force F of ``forces_n``, c = Σ_j r_j² / kp_j the
  servo's tip compliance (r_j: joint j to tip), so a larger amplitude means both a faster
  impact and a deeper reference below the surface. The measured forces are the labelled
  peak contact forces, not these nominal ones.
* **Soak** (false alarms): collision-free runs of the variant (payload included) of the four
  families above, ``soak_run_s`` each, ``soak_runs`` per family, seeds of their own,
  replayed with the arm's config. Every alarm on after the warm-up is a false alarm (one
  stuck on since the warm-up included: :func:`soak_false_alarms`). Rate = alarms per hour
  of time after warm-up; its 95 % upper bound is the exact Poisson bound
  χ²₀.₉₅(2(n+1)) / 2 / T (3.00 / T for n = 0).
* **Threshold settings.** *calibrated*: scale 1 (the config as calibrated). *matched*:
  per detector, the smallest swept scale from which on (every larger swept scale too) the
  soak has zero false alarms — detectors compared at the same (zero) false-alarm rate on the
  soak, chosen on runs that are not the cases.

Definitions reported per (detector, stiffness, setting), over the counted contacts (onset
after warm-up) of all cases of that stiffness:

* **minimal detected force**: the smallest labelled peak force among detected contacts [N];
* **all detected above**: the largest peak force among *missed* contacts [N] — every contact
  with a larger force was detected (None: nothing missed);
* equivalent mass = force / 9.81 [kg] (the paper's third column).

Where its parts live (:mod:`impactcli.study`, data flowing one way): :mod:`~impactcli.study.spec`
(what the study runs: the paper's numbers, the variants, :class:`StudySpec`),
:mod:`~impactcli.study.scenarios` (the robot, references, scenarios),
:mod:`~impactcli.study.tasks` (calibration, soak and case tasks, run in worker processes),
:mod:`~impactcli.study.summary` (one JSON-ready mapping, verdicts included),
:mod:`~impactcli.study.tables` (Table II, the ROC table, text and Markdown). This module
runs the study (:func:`run_study`) and re-exports their names, so that callers and tests
keep one import path.

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
