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

Pure maths and simulation; no file I/O, no printing (the CLI does both).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .config import DetectorConfig
from .evaluate import (
    EVALUATED,
    MatchTolerance,
    geometric_scales,
    sweep_thresholds,
)

SCHEMA_VERSION = "1.0"
G_N_PER_KG = 9.81
#: The paper's Table II: minimal detected force [N] of the proposed method per stiffness
#: [N/mm]; the static threshold v0 needs > 20 N at every stiffness.
PAPER_ADAPTIVE_N: dict[float, float] = {10.12: 4.44, 5.93: 5.61, 2.12: 5.87}
PAPER_STATIC_N = 20.0
#: Table II's row labels for our detectors (static_loading is ours, not in the paper).
ROW_LABELS: dict[str, str] = {
    "adaptive": "Proposed method (adaptive)",
    "static_baseline": "Static threshold v0",
    "static_loading": "Static loading vL (ours)",
    "product": "Product (adaptive OR vL)",
}
TABLE_DETECTORS: tuple[str, ...] = ("adaptive", "static_baseline", "static_loading", "product")
PAPER_STIFFNESSES: tuple[float, ...] = (10.12, 5.93, 2.12)
SETTINGS: tuple[str, ...] = ("calibrated", "matched")


@dataclass(frozen=True)
class Variant:
    """An arm preset and an end-effector payload [kg] that the model does not know."""

    name: str
    arm: str
    payload_kg: float
    description: str


VARIANTS: dict[str, Variant] = {
    "assist_like": Variant("assist_like", "assist_like", 0.0,
                           "light cable-driven 2-joint arm (the paper's ASSIST class)"),
    "assist_like+payload": Variant("assist_like+payload", "assist_like", 0.5,
                                   "assist_like with an unknown 0.5 kg payload"),
    "heavy_geared": Variant("heavy_geared", "heavy_geared", 0.0,
                            "heavy geared 3-joint arm, strong Coulomb friction"),
    "heavy_geared+payload": Variant("heavy_geared+payload", "heavy_geared", 2.0,
                                    "heavy_geared with an unknown 2 kg payload"),
}

#: Per arm preset: (gap [rad]: elastomer surface angle below the horizontal for joint 1,
#: period T [s] of the task triangles).
ARM_GEOMETRY: dict[str, tuple[float, float]] = {
    "assist_like": (0.10, 2.0),
    "heavy_geared": (0.05, 3.0),
}

SOAK_FAMILIES: tuple[str, ...] = ("task", "triangle", "trapezoid", "multisine")
_SCENARIO_OF = {"triangle": "free_triangle", "trapezoid": "free_p2p",
                "multisine": "free_multisine"}


def _default_scales() -> tuple[float, ...]:
    """0.2 … 20 in 5 % steps, and 1 (the calibrated thresholds): wider than
    ``impactcli evaluate``'s default so a detector stuck on under an unknown payload can
    still find its zero-false-alarm point."""
    return tuple(sorted({*geometric_scales(0.2, 20.0, 1.05), 1.0}))


@dataclass(frozen=True)
class StudySpec:
    """What the study runs (defaults: the README run; :meth:`quick` for tests and CI).

    Attributes:
        variants: names in :data:`VARIANTS`.
        stiffnesses: elastomer stiffnesses [N/mm].
        forces_n: nominal pressing forces that set the amplitudes (module docstring) [N].
        case_seeds: cases per (stiffness, amplitude), each with its own seed.
        impacts_per_case: impacts after the lead-in.
        lead_in_s: collision-free task triangles before the elastomer is slid in [s].
        soak_run_s: duration of one soak run [s]; soak_runs: runs per soak family.
        calib_run_s: duration of one calibration run [s] (one per family).
        scales: swept threshold scales (must contain 1.0, the calibrated setting).
        tolerance: when an alarm matches a contact (:class:`MatchTolerance`).
        seed: the study's seed (robot, references, noise, drift all derive from it).
    """

    variants: tuple[str, ...] = ("assist_like", "assist_like+payload", "heavy_geared",
                                 "heavy_geared+payload")
    stiffnesses: tuple[float, ...] = PAPER_STIFFNESSES
    forces_n: tuple[float, ...] = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0)
    case_seeds: int = 2
    impacts_per_case: int = 3
    lead_in_s: float = 10.0
    soak_run_s: float = 900.0
    soak_runs: int = 1
    calib_run_s: float = 120.0
    scales: tuple[float, ...] = field(default_factory=_default_scales)
    tolerance: MatchTolerance = field(default_factory=MatchTolerance)
    seed: int = 0

    def __post_init__(self) -> None:
        from .errors import ConfigError

        bad = [v for v in self.variants if v not in VARIANTS]
        if bad or not self.variants:
            raise ConfigError(f"sensitivity: unknown variant(s) {bad}; choose from "
                              f"{sorted(VARIANTS)}")
        if not self.stiffnesses or any(not (k > 0) for k in self.stiffnesses):
            raise ConfigError("sensitivity: stiffnesses must be positive [N/mm]")
        if not self.forces_n or any(not (f > 0) for f in self.forces_n):
            raise ConfigError("sensitivity: forces must be positive [N]")
        if 1.0 not in self.scales or any(not (s > 0) for s in self.scales):
            raise ConfigError("sensitivity: scales must be positive and contain 1.0")
        if min(self.case_seeds, self.impacts_per_case, self.soak_runs) < 1:
            raise ConfigError("sensitivity: case seeds, impacts and soak runs must be >= 1")
        if min(self.soak_run_s, self.calib_run_s, self.lead_in_s) <= 0:
            raise ConfigError("sensitivity: durations must be positive")

    @classmethod
    def quick(cls, **changes: Any) -> StudySpec:
        """A small study for tests and CI (seconds, not minutes): one variant, 3 forces,
        one seed, 1 impact per case, 60 s soak runs, 40 s calibration runs, coarse scales."""
        base = cls(variants=("assist_like",), forces_n=(2.0, 8.0, 24.0), case_seeds=1,
                   impacts_per_case=2, lead_in_s=8.0, soak_run_s=60.0, calib_run_s=40.0,
                   scales=(0.5, 0.7, 1.0, 1.4, 2.0, 3.0, 5.0))
        return replace(base, **changes)

    @property
    def soak_hours_per_variant(self) -> float:
        """Simulated soak time per variant (warm-up included) [h]."""
        return len(SOAK_FAMILIES) * self.soak_runs * self.soak_run_s / 3600.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping."""
        return {
            "variants": list(self.variants), "stiffnesses": list(self.stiffnesses),
            "forces_n": list(self.forces_n), "case_seeds": self.case_seeds,
            "impacts_per_case": self.impacts_per_case, "lead_in_s": self.lead_in_s,
            "soak_run_s": self.soak_run_s, "soak_runs": self.soak_runs,
            "soak_families": list(SOAK_FAMILIES), "calib_run_s": self.calib_run_s,
            "scales": list(self.scales),
            "tolerance": {"pre_s": self.tolerance.pre_s, "post_s": self.tolerance.post_s},
            "seed": self.seed,
        }


def _seed(*key: int | float | str) -> int:
    """A 32-bit seed from a key (deterministic across processes and runs)."""
    ints = [int(x) if isinstance(x, int) else sum(ord(c) * 131**i for i, c in enumerate(str(x)))
            for x in key]
    return int(np.random.SeedSequence(ints).generate_state(1)[0])


# ---------------------------------------------------------------------------------------
# The robot, its references and scenarios


def the_robot(arm_name: str, seed: int, uncertainty: float = 0.2) -> Any:
    """The one simulated robot of a study: the preset with every physical parameter scaled
    by 1 + U(−u, u) (COM fractions by 1 + U(−u/2, u/2)), drawn from ``seed``.

    Returns an :class:`impactcli.sim.ArmParams` (same name, kinematics, drives and
    controller as the preset). Simulate it with ``uncertainty=0``.
    """
    from .sim import preset

    arm = preset(arm_name)
    rng = np.random.default_rng(_seed("robot", arm_name, seed))

    def sc(v: tuple[float, ...], u: float = uncertainty) -> tuple[float, ...]:
        return tuple(float(x * (1.0 + rng.uniform(-u, u))) for x in v)

    return replace(
        arm, link_masses=sc(arm.link_masses), com_fractions=sc(arm.com_fractions, uncertainty / 2),
        link_inertias=sc(arm.link_inertias), motor_inertias=sc(arm.motor_inertias),
        stiffness=sc(arm.stiffness), transmission_damping=sc(arm.transmission_damping),
        motor_viscous=sc(arm.motor_viscous), motor_coulomb=sc(arm.motor_coulomb),
        link_viscous=sc(arm.link_viscous), link_coulomb=sc(arm.link_coulomb),
    )


def servo_compliance(arm: Any) -> float:
    """Tip compliance of the PD servos, arm extended: Σ_j r_j² / kp_j [m/N]."""
    ll = arm.link_lengths
    return float(sum(sum(ll[j:]) ** 2 / arm.kp[j] for j in range(len(ll))))


def amplitudes(arm_name: str, forces_n: Sequence[float]) -> tuple[float, ...]:
    """Joint-1 triangle amplitudes [rad]: gap + F · c / reach per nominal force F [N]."""
    from .sim import preset

    arm = preset(arm_name)
    gap, _ = ARM_GEOMETRY[arm_name]
    c = servo_compliance(arm)
    reach = sum(arm.link_lengths)
    return tuple(round(gap + f * c / reach, 6) for f in forces_n)


def task_reference(arm: Any, amps: Sequence[float], period_s: float) -> Any:
    """Waypoints: joint-1 triangles 0 → +A → −A → 0 (period T, one amplitude per cycle),
    the other joints at 0. Velocity steps and acceleration impulses, like the paper's."""
    from .sim import Waypoints

    n = arm.n_joints
    rest = (0.0,) * (n - 1)
    times, pos = [0.0], [(0.0, *rest)]
    t = 0.0
    for a in amps:
        for frac, th in ((0.25, a), (0.5, -a), (0.25, 0.0)):
            t += frac * period_s
            times.append(round(t, 9))
            pos.append((th, *rest))
    return Waypoints(tuple(times), tuple(pos))


def case_scenario(arm: Any, stiffness: float, amplitude: float, spec: StudySpec,
                  payload_kg: float = 0.0) -> Any:
    """One Table II case: lead-in triangles, then the elastomer slid in at a cycle's top and
    ``spec.impacts_per_case`` impacts of amplitude ``amplitude`` [rad] on ``stiffness``."""
    from .sim import Scenario, Surface

    gap, period = ARM_GEOMETRY[arm.name]
    n_lead = max(1, math.ceil(spec.lead_in_s / period))
    n_cyc = n_lead + spec.impacts_per_case
    reach = sum(arm.link_lengths)
    t_on = n_lead * period + 0.25 * period  # the tip is at +A, far above the surface
    surface = Surface(reach * math.sin(-gap), stiffness, x_min_m=reach - 0.2,
                      x_max_m=reach + 0.2, t_on_s=t_on)
    return Scenario(
        "sensitivity_case", arm, n_cyc * period + 0.5, task_reference(arm, [amplitude] * n_cyc,
                                                                      period),
        surfaces=(surface,), payload_kg=payload_kg, uncertainty=0.0,
        description=f"joint-1 triangles A={amplitude:.4f} rad, T={period:g} s onto "
                    f"{stiffness} N/mm")


def free_scenario(arm: Any, family: str, duration_s: float, payload_kg: float,
                  amps: Sequence[float]) -> Any:
    """A collision-free run of ``family`` (:data:`SOAK_FAMILIES`) on ``arm``."""
    from .sim import Scenario, scenario

    if family == "task":
        _, period = ARM_GEOMETRY[arm.name]
        n_cyc = math.ceil(duration_s / period) + 1
        ref = task_reference(arm, [amps[k % len(amps)] for k in range(n_cyc)], period)
        return Scenario("task", arm, duration_s, ref, payload_kg=payload_kg, uncertainty=0.0,
                        description="joint-1 task triangles over every case amplitude, "
                                    "no elastomer")
    return scenario(_SCENARIO_OF[family], arm=arm, duration_s=duration_s,
                    payload_kg=payload_kg, uncertainty=0.0)


# ---------------------------------------------------------------------------------------
# Tasks (top-level functions: they run in worker processes)


@dataclass(frozen=True)
class CalibTask:
    arm: str
    spec: StudySpec


@dataclass(frozen=True)
class CalibOutcome:
    """The config calibrated for one arm and what it was calibrated on."""

    arm: str
    config: DetectorConfig
    runs: tuple[str, ...]
    margins: dict[str, dict[str, float]]
    model_fit: dict[str, Any]


def run_calibration(task: CalibTask) -> CalibOutcome:
    """Calibrate one arm on its collision-free, payload-free runs (module docstring)."""
    import warnings

    from .calibration import calibrate
    from .errors import ImpactWarning
    from .sim import preset, simulate

    spec = task.spec
    arm = the_robot(task.arm, spec.seed)
    amps = amplitudes(task.arm, spec.forces_n)
    logs, names = [], []
    for fam in SOAK_FAMILIES:
        sc = free_scenario(arm, fam, spec.calib_run_s, 0.0, amps)
        seed = _seed("calib", task.arm, fam, spec.seed)
        logs.append(simulate(sc, seed=seed).log)
        names.append(f"{fam} seed={seed} {spec.calib_run_s:g} s")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        cfg = calibrate(logs, robot=preset(task.arm).robot_description())
    fit = dict((cfg.model or {}).get("fit", {})) if isinstance(cfg.model, dict) else {}
    return CalibOutcome(task.arm, cfg, tuple(names), cfg.calibration.margins, fit)


@dataclass(frozen=True)
class SoakTask:
    variant: str
    family: str
    run: int
    spec: StudySpec
    config: DetectorConfig


@dataclass(frozen=True)
class SoakOutcome:
    """False alarms of one collision-free run, per detector and swept scale.

    false_alarms: detector → (S,) counts at ``spec.scales``; free_s: time after warm-up [s].
    """

    variant: str
    family: str
    run: int
    seed: int
    duration_s: float
    warmup_end_s: float
    free_s: float
    false_alarms: dict[str, tuple[int, ...]]
    n_warnings: int


def _quiet_analyze(log: Any, cfg: DetectorConfig) -> Any:
    from .pipeline import analyze

    return analyze(log, config=cfg)


def soak_false_alarms(ratios: dict[str, np.ndarray], time_s: np.ndarray, warmup_end_s: float,
                      scales: Sequence[float], merge_gap_s: float,
                      min_duration_s: float) -> dict[str, tuple[int, ...]]:
    """False alarms of a collision-free run per detector at each scale (in ``scales`` order).

    At scale s a detector decides ``ratio > s`` ((N, J), ORed over joints; the product ORs
    adaptive and static_loading); events are the intervals of
    :func:`impactcli.evaluate.event_intervals` (the run's merge gap and minimum duration).
    Every event still on at or after ``warmup_end_s`` is a false alarm — including one that
    began in the warm-up and never ended (a detector stuck on, e.g. a static threshold under
    an unknown payload, is not silent).
    """
    from .evaluate import event_intervals

    t = np.asarray(time_s, dtype=np.float64)
    out: dict[str, tuple[int, ...]] = {}
    for d in EVALUATED:
        counts = []
        for s in scales:
            if d == "product":
                dec = ((np.asarray(ratios["adaptive"]) > s)
                       | (np.asarray(ratios["static_loading"]) > s))
            else:
                dec = np.asarray(ratios[d]) > s
            _, i1 = event_intervals(dec, t, merge_gap_s, min_duration_s)
            counts.append(int(np.count_nonzero(t[i1] >= warmup_end_s - 1e-9)))
        out[d] = tuple(counts)
    return out


def run_soak(task: SoakTask) -> SoakOutcome:
    """Simulate and replay one soak run; count false alarms at every swept scale."""
    from .sim import simulate

    spec, var = task.spec, VARIANTS[task.variant]
    arm = the_robot(var.arm, spec.seed)
    sc = free_scenario(arm, task.family, spec.soak_run_s, var.payload_kg,
                       amplitudes(var.arm, spec.forces_n))
    seed = _seed("soak", task.variant, task.family, task.run, spec.seed)
    log = simulate(sc, seed=seed).log
    res = _quiet_analyze(log, task.config)
    ev = res.config.get("events", {})
    fa_t = soak_false_alarms(res.ratios, log.time_s, res.warmup_end_s, spec.scales,
                             float(ev.get("merge_gap_s", 0.0)),
                             float(ev.get("min_duration_s", 0.0)))
    return SoakOutcome(task.variant, task.family, task.run, seed, log.duration_s,
                       res.warmup_end_s, max(0.0, log.duration_s - res.warmup_end_s), fa_t,
                       len(res.warnings))


@dataclass(frozen=True)
class CaseTask:
    variant: str
    stiffness: float
    amplitude: float
    force_n: float
    seed_index: int
    spec: StudySpec
    config: DetectorConfig


@dataclass(frozen=True)
class ContactRecord:
    """One counted impact of a case.

    delays: detector → (S,) delay [s] at each swept scale (NaN = missed);
    peak_ratio: detector → the largest statistic / threshold (calibrated, scale 1) inside the
    contact's match window, max over joints (> 1 ⇔ above the calibrated threshold there).
    """

    variant: str
    stiffness: float
    amplitude: float
    nominal_force_n: float
    seed: int
    start_s: float
    peak_force: float
    tip_speed_m_s: float
    delays: dict[str, tuple[float, ...]]
    peak_ratio: dict[str, float]


@dataclass(frozen=True)
class CaseOutcome:
    """A case's counted contacts, false alarms per scale on its collision-free parts,
    uncounted contacts, and the adaptive filter G's gain at the run's end per joint."""

    variant: str
    stiffness: float
    amplitude: float
    seed: int
    contacts: tuple[ContactRecord, ...]
    uncounted: int
    free_s: float
    false_alarms: dict[str, tuple[int, ...]]
    g_gain: dict[str, Any]


def run_case(task: CaseTask) -> CaseOutcome:
    """Simulate one case, replay it at the arm's calibrated config, sweep every scale."""
    from .evaluate import evaluate_result
    from .sim import simulate

    spec, var = task.spec, VARIANTS[task.variant]
    arm = the_robot(var.arm, spec.seed)
    sc = case_scenario(arm, task.stiffness, task.amplitude, spec, var.payload_kg)
    seed = _seed("case", task.variant, task.stiffness, task.amplitude, task.seed_index,
                 spec.seed)
    sim = simulate(sc, seed=seed)
    res = _quiet_analyze(sim.log, task.config)
    rows = sweep_thresholds(res, sim.labels, spec.scales, tolerance=spec.tolerance)
    ev = evaluate_result(res, sim.labels, tolerance=spec.tolerance)
    order = np.argsort(np.argsort(spec.scales))
    by_det: dict[str, list[Any]] = {d: [] for d in EVALUATED}
    for r in rows:
        by_det[r.detector].append(r)
    t = sim.log.time_s
    contacts = []
    for k, c in enumerate(sim.labels.events):
        if ev.contacts[k].status != "counted":
            continue
        lo, hi = spec.tolerance.window(c)
        sel = (t >= lo) & (t <= hi)
        peak = {}
        for d in ("adaptive", "static_loading", "static_baseline"):
            rr = res.ratios[d][sel]
            peak[d] = float(np.max(rr)) if rr.size else float("nan")
        peak["product"] = max(peak["adaptive"], peak["static_loading"])
        delays = {d: tuple(float("nan") if (v := by_det[d][i].contact_delays_s[k]) is None
                           else float(v) for i in order) for d in EVALUATED}
        contacts.append(ContactRecord(
            task.variant, task.stiffness, task.amplitude, task.force_n, seed, c.start,
            c.peak_force, float(c.extra.get("tip_speed_m_s", float("nan"))), delays, peak))
    fa = {d: tuple(int(by_det[d][i].false_alarms) for i in order) for d in EVALUATED}
    n_unc = sum(1 for c in ev.contacts if c.status != "counted")
    return CaseOutcome(task.variant, task.stiffness, task.amplitude, seed, tuple(contacts),
                       n_unc, ev.collision_free_s, fa, res.filter_gain)


# ---------------------------------------------------------------------------------------
# Running the study


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


# ---------------------------------------------------------------------------------------
# Summary


def poisson_upper_95(n: int, hours: float) -> float | None:
    """Exact one-sided 95 % upper bound on a Poisson rate [1/h] after ``n`` events in
    ``hours``: χ²₀.₉₅(2(n+1)) / (2 T). For n = 0 it is −ln(0.05) / T ≈ 3.00 / T."""
    from scipy.stats import chi2

    if hours <= 0:
        return None
    return float(chi2.ppf(0.95, 2 * (n + 1)) / 2.0 / hours)


def zero_fa_index(false_alarms: Sequence[int]) -> int | None:
    """Index of the smallest scale from which on every (larger) scale has zero false alarms,
    given counts at ascending scales; None when even the largest scale false-alarms."""
    best = None
    for i in range(len(false_alarms) - 1, -1, -1):
        if false_alarms[i]:
            break
        best = i
    return best


def _r(x: float | None, nd: int = 4) -> float | None:
    if x is None or not math.isfinite(x):
        return None
    return round(float(x), nd)


def _cell(contacts: Sequence[ContactRecord], det: str, i: int) -> dict[str, Any]:
    """Scores of one detector at scale index i over a set of contacts."""
    hit = [c for c in contacts if math.isfinite(c.delays[det][i])]
    miss = [c for c in contacts if not math.isfinite(c.delays[det][i])]
    fmin = min((c.peak_force for c in hit), default=None)
    return {
        "n_contacts": len(contacts), "detected": len(hit),
        "min_detected_force_n": _r(fmin, 3),
        "equivalent_mass_kg": _r(fmin / G_N_PER_KG, 3) if fmin is not None else None,
        "all_detected_above_n": _r(max((c.peak_force for c in miss), default=None), 3),
        "delay_median_s": _r(statistics.median(c.delays[det][i] for c in hit) if hit else None,
                             4),
    }


def summarize(spec: StudySpec, calibs: Sequence[CalibOutcome],
              soaks: Sequence[SoakOutcome], cases: Sequence[CaseOutcome]) -> dict[str, Any]:
    """The study's results as one JSON-ready mapping (schemas/sensitivity.schema.json)."""
    scales = list(spec.scales)
    order = sorted(range(len(scales)), key=lambda i: scales[i])
    i_one = scales.index(1.0)
    calib_of = {c.arm: c for c in calibs}
    variants = []
    for v in spec.variants:
        var = VARIANTS[v]
        so = sorted((s for s in soaks if s.variant == v), key=lambda s: (s.family, s.run))
        cs = sorted((c for c in cases if c.variant == v),
                    key=lambda c: (c.stiffness, c.amplitude, c.seed))
        contacts = [x for c in cs for x in c.contacts]
        free_h = sum(s.free_s for s in so) / 3600.0
        fa = {d: [sum(s.false_alarms[d][i] for s in so) for i in range(len(scales))]
              for d in EVALUATED}
        case_fa = {d: [sum(c.false_alarms[d][i] for c in cs) for i in range(len(scales))]
                   for d in EVALUATED}
        case_free_h = sum(c.free_s for c in cs) / 3600.0
        # matched: the smallest scale from which on the soak stays silent
        matched: dict[str, int | None] = {}
        for d in EVALUATED:
            asc = [fa[d][i] for i in order]
            z = zero_fa_index(asc)
            matched[d] = None if z is None else order[z]
        settings: dict[str, dict[str, Any]] = {}
        for setting in SETTINGS:
            per_det: dict[str, dict[str, Any]] = {}
            for d in EVALUATED:
                i = i_one if setting == "calibrated" else matched[d]
                if i is None:
                    per_det[d] = {"scale": None, "reached": False}
                    continue
                by_k = {}
                for k in spec.stiffnesses:
                    by_k[f"{k:g}"] = _cell([c for c in contacts if c.stiffness == k], d, i)
                per_det[d] = {
                    "scale": scales[i], "reached": True,
                    "at_sweep_edge": setting == "matched" and i == order[0],
                    "soak_false_alarms": fa[d][i],
                    "soak_false_alarms_per_hour": _r(fa[d][i] / free_h if free_h else None, 4),
                    "soak_false_alarms_per_hour_upper95": _r(poisson_upper_95(fa[d][i], free_h),
                                                             4),
                    "case_false_alarms": case_fa[d][i],
                    "all": _cell(contacts, d, i),
                    "by_stiffness": by_k,
                }
            settings[setting] = per_det
        roc = {d: [{
            "scale": scales[i], "soak_false_alarms": fa[d][i],
            "soak_false_alarms_per_hour": _r(fa[d][i] / free_h if free_h else None, 4),
            "soak_false_alarms_per_hour_upper95": _r(poisson_upper_95(fa[d][i], free_h), 4),
            **_cell(contacts, d, i)} for i in order] for d in EVALUATED}
        cal = calib_of[var.arm]
        variants.append({
            "name": v, "arm": var.arm, "payload_kg": var.payload_kg,
            "description": var.description,
            "calibration": {"runs": list(cal.runs), "margins": cal.margins,
                            "thresholds": {"v_stat": cal.config.thresholds.v_stat,
                                           "v0": cal.config.thresholds.v0,
                                           "vL": cal.config.thresholds.vL},
                            "model_sha256": cal.config.calibration.model_sha256},
            "soak": {
                "hours_after_warmup": _r(free_h, 4),
                "runs": [{"family": s.family, "run": s.run, "seed": s.seed,
                          "duration_s": _r(s.duration_s, 3),
                          "warmup_end_s": _r(s.warmup_end_s, 3),
                          "false_alarms_calibrated": {d: s.false_alarms[d][i_one]
                                                      for d in EVALUATED}} for s in so],
            },
            "cases": {"n_cases": len(cs), "n_contacts": len(contacts),
                      "uncounted_contacts": sum(c.uncounted for c in cs),
                      "collision_free_hours": _r(case_free_h, 4),
                      "amplitudes_rad": list(amplitudes(var.arm, spec.forces_n)),
                      "period_s": ARM_GEOMETRY[var.arm][1],
                      "gap_rad": ARM_GEOMETRY[var.arm][0]},
            "settings": settings,
            "roc": roc,
            "verdict": _verdict(v, contacts, matched, order, scales),
            "contacts": [{
                "stiffness": c.stiffness, "amplitude_rad": c.amplitude,
                "nominal_force_n": c.nominal_force_n, "seed": c.seed,
                "start_s": _r(c.start_s, 4), "peak_force_n": _r(c.peak_force, 3),
                "tip_speed_m_s": _r(c.tip_speed_m_s, 4),
                "peak_ratio_calibrated": {d: _r(x, 4) for d, x in c.peak_ratio.items()},
                "delay_calibrated_s": {d: _r(c.delays[d][i_one], 4) for d in EVALUATED},
                "delay_matched_s": {d: (_r(c.delays[d][i], 4) if (i := matched[d]) is not None
                                        else None) for d in EVALUATED},
            } for c in contacts],
            "g_gain": _mean_gain(cs),
        })
    return {
        "schema_version": SCHEMA_VERSION,
        "spec": spec.to_dict(),
        "paper": {"adaptive_min_detected_force_n": {f"{k:g}": v
                                                    for k, v in PAPER_ADAPTIVE_N.items()},
                  "static_threshold_min_detected_force_n": f"> {PAPER_STATIC_N:g}"},
        "definitions": {
            "min_detected_force": "smallest labelled peak force among detected contacts [N]",
            "all_detected_above": "largest labelled peak force among missed contacts [N]: "
                                  "every contact above it was detected (null: none missed)",
            "calibrated": "thresholds as calibrated (scale 1) by leave-one-out on the arm's "
                          "collision-free, payload-free calibration runs",
            "matched": "per detector, the smallest swept threshold scale from which on the "
                       "soak has zero false alarms",
            "upper95": "exact one-sided 95 % Poisson upper bound on false alarms per hour "
                       "(3.00 / T for none in T hours)",
        },
        "variants": variants,
    }


def _mean_gain(cs: Sequence[CaseOutcome]) -> dict[str, Any]:
    """G_hat's gain at the end of each case run, mean and range over cases, per joint."""
    gains: dict[str, list[list[float]]] = {}
    freqs: list[float] = []
    for c in cs:
        g = c.g_gain or {}
        freqs = list(g.get("frequencies_hz", freqs))
        for j, vals in (g.get("gain") or {}).items():
            gains.setdefault(j, []).append(list(vals))
    return {"frequencies_hz": freqs,
            "mean": {j: [_r(x, 4) for x in np.mean(v, axis=0)] for j, v in gains.items()},
            "min": {j: [_r(x, 4) for x in np.min(v, axis=0)] for j, v in gains.items()},
            "max": {j: [_r(x, 4) for x in np.max(v, axis=0)] for j, v in gains.items()}}


#: Paired median delay gain needed to call the adaptive detector earlier [s] (one sample at
#: the paper's 4 ms period).
EARLIER_MIN_S = 0.004


def _verdict(variant: str, contacts: Sequence[ContactRecord], matched: dict[str, int | None],
             order: Sequence[int], scales: Sequence[float]) -> dict[str, Any]:
    """Does the adaptive detector help on this robot, at matched (zero) soak false alarms?

    Adaptive and static_loading each at its own zero-false-alarm scale on the soak; their
    OR (the product) is then silent on the soak too. The adaptive detector *helps* when,
    added to static_loading, it catches impacts static_loading misses, or fires at least
    :data:`EARLIER_MIN_S` earlier (median over the impacts both catch). The text also
    compares the two alone: impacts detected, smallest detected force, force above which
    all were detected.
    """
    ia, il = matched["adaptive"], matched["static_loading"]
    if not contacts:
        return {"adaptive_helps": None, "text": f"{variant}: undetermined — no counted contact."}
    if ia is not None and il is None:
        a = _cell(contacts, "adaptive", ia)
        return {"adaptive_helps": True, "adaptive_only": a["detected"], "static_loading_only": 0,
                "both": 0, "paired_delay_gain_s": None,
                "text": f"{variant}: YES by default — static_loading false-alarms on the soak at "
                        f"every swept scale up to {max(scales):g} × its calibrated threshold, so "
                        "it cannot run without false alarms; adaptive is silent from scale "
                        f"{scales[ia]:g} and there detects {a['detected']}/{a['n_contacts']} "
                        f"impacts (smallest {_f(a['min_detected_force_n'], ' N')}, all above "
                        f"{_f(a['all_detected_above_n'], ' N')})."}
    if ia is None or il is None:
        miss = [d for d, i in (("adaptive", ia), ("static_loading", il)) if i is None]
        return {"adaptive_helps": None,
                "text": f"{variant}: undetermined — {' and '.join(miss)} never reached zero "
                        "false alarms on the soak within the swept scales."}
    a = _cell(contacts, "adaptive", ia)
    s = _cell(contacts, "static_loading", il)
    da = [c.delays["adaptive"][ia] for c in contacts]
    ds = [c.delays["static_loading"][il] for c in contacts]
    pairs = [(math.isfinite(x), math.isfinite(y), y - x) for x, y in zip(da, ds, strict=True)]
    both = [g for fa_, fs_, g in pairs if fa_ and fs_]
    a_only = sum(1 for fa_, fs_, _ in pairs if fa_ and not fs_)
    s_only = sum(1 for fa_, fs_, _ in pairs if fs_ and not fa_)
    gain = statistics.median(both) if both else None
    earlier = gain is not None and gain >= EARLIER_MIN_S - 1e-9
    edge = [d for d, i in (("adaptive", ia), ("static_loading", il)) if i == order[0]]
    helps: bool | None = (a_only > 0 or earlier) if not edge else None

    def alone(name: str, c: dict[str, Any], i: int) -> str:
        return (f"{name} (scale {scales[i]:g}) {c['detected']}/{c['n_contacts']}, smallest "
                f"{_f(c['min_detected_force_n'], ' N')}, all above "
                + ("none missed" if c["all_detected_above_n"] is None
                   else _f(c["all_detected_above_n"], " N")))

    facts = (f"added to static_loading it catches {a_only} impact(s) static_loading misses"
             + (f" and fires {abs(gain) * 1e3:.0f} ms {'earlier' if gain >= 0 else 'later'} "
                f"(median) on the {len(both)} both catch" if gain is not None else "")
             + f"; alone: {alone('adaptive', a, ia)}; {alone('static_loading', s, il)} "
             f"({s_only} impact(s) only static_loading catches)")
    if 2 * max(a["detected"], s["detected"]) < a["n_contacts"]:
        facts += ("; neither detects half of the impacts at zero soak false alarms on this "
                  "robot")
    if edge:
        text = (f"{variant}: undetermined — {' and '.join(edge)} already silent at the smallest "
                f"swept scale; {facts}.")
    elif helps:
        text = f"{variant}: YES, the adaptive detector helps at zero soak false alarms — {facts}."
    else:
        text = (f"{variant}: NO, the adaptive detector does not help at zero soak false "
                f"alarms — {facts}.")
    return {"adaptive_helps": helps, "adaptive_only": a_only, "static_loading_only": s_only,
            "both": len(both), "paired_delay_gain_s": _r(gain, 4), "text": text}


# ---------------------------------------------------------------------------------------
# Tables


def _f(x: float | None, unit: str = "", nd: str = ".3g") -> str:
    return "-" if x is None else f"{x:{nd}}{unit}"


def _ms(x: float | None) -> str:
    return "-" if x is None else f"{x * 1e3:.0f}"


def table_rows(variant: dict[str, Any], setting: str) -> list[list[str]]:
    """Table II's rows for one variant and threshold setting (header first)."""
    head = ["Detector", "Scale", "Environment stiffness (N/mm)", "Minimal detected force (N)",
            "Equivalent mass (kg)", "All detected above (N)", "Detected", "Delay med (ms)",
            "Soak FA/h (95 % bound)", "Paper (N)"]
    rows = [head]
    for d in TABLE_DETECTORS:
        cell = variant["settings"][setting][d]
        if not cell.get("reached"):
            rows.append([ROW_LABELS[d], "never", "-", "-", "-", "-", "-", "-", "-",
                         _paper(d, None)])
            continue
        sc = f"{'<=' if cell.get('at_sweep_edge') else ''}{cell['scale']:g}"
        fa = (f"{_f(cell['soak_false_alarms_per_hour'])} "
              f"(<= {_f(cell['soak_false_alarms_per_hour_upper95'])})")
        first = True
        for k, c in cell["by_stiffness"].items():
            rows.append([
                ROW_LABELS[d] if first else "", sc if first else "", f"k = {k}",
                _f(c["min_detected_force_n"], nd=".2f"), _f(c["equivalent_mass_kg"], nd=".3f"),
                "none missed" if c["all_detected_above_n"] is None and c["detected"]
                else _f(c["all_detected_above_n"], nd=".2f"),
                f"{c['detected']}/{c['n_contacts']}", _ms(c["delay_median_s"]),
                fa if first else "", _paper(d, float(k))])
            first = False
    return rows


def _paper(det: str, k: float | None) -> str:
    if det == "adaptive" and k is not None:
        for kk, v in PAPER_ADAPTIVE_N.items():
            if abs(kk - k) < 1e-9:
                return f"{v:.2f}"
        return "-"
    if det == "static_baseline":
        return f"> {PAPER_STATIC_N:g}"
    return "-"


def _text_table(rows: Sequence[Sequence[str]]) -> list[str]:
    w = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    out = []
    for n, r in enumerate(rows):
        out.append("  ".join(c.ljust(w[i]) if i < 3 else c.rjust(w[i])
                             for i, c in enumerate(r)).rstrip())
        if n == 0:
            out.append("  ".join("-" * x for x in w))
    return out


def _soak_line(v: dict[str, Any]) -> str:
    fams = sorted({r["family"] for r in v["soak"]["runs"]})
    return (f"soak: {v['soak']['hours_after_warmup']:.2f} h collision-free after warm-up "
            f"({len(v['soak']['runs'])} runs: {', '.join(fams)}); cases: {v['cases']['n_cases']} "
            f"runs, {v['cases']['n_contacts']} counted impacts")


def _roc_rows(v: dict[str, Any], picks: Sequence[float],
              detectors: Sequence[str] = TABLE_DETECTORS) -> list[list[str]]:
    rows = [["Detector", "Scale", "Soak FA", "FA/h (95 % bound)", "Detected",
             "Min detected (N)", "All above (N)", "Delay med (ms)"]]
    for d in detectors:
        pts = v["roc"][d]
        chosen = []
        for p in picks:
            best = min(pts, key=lambda r: abs(math.log(r["scale"] / p)))
            if best not in chosen:
                chosen.append(best)
        first = True
        for r in chosen:
            rows.append([d if first else "", f"{r['scale']:g}", str(r["soak_false_alarms"]),
                         f"{_f(r['soak_false_alarms_per_hour'])} "
                         f"(<= {_f(r['soak_false_alarms_per_hour_upper95'])})",
                         f"{r['detected']}/{r['n_contacts']}",
                         _f(r["min_detected_force_n"], nd=".2f"),
                         _f(r["all_detected_above_n"], nd=".2f"), _ms(r["delay_median_s"])])
            first = False
    return rows


ROC_PICKS: tuple[float, ...] = (0.25, 0.35, 0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0, 8.0, 16.0)


MD_ROC_PICKS: tuple[float, ...] = (0.5, 0.7, 1.0, 1.4, 2.0, 4.0)


def format_text(summary: dict[str, Any]) -> str:
    """Plain-text report: Table II per variant and setting, the ROC table, the verdicts."""
    lines = []
    for v in summary["variants"]:
        lines.append(f"=== {v['name']}: {v['description']} ===")
        lines.append(_soak_line(v))
        for setting in SETTINGS:
            lines += ["", f"TABLE II (reproduced) — {v['name']}, thresholds {setting}: "
                          + summary["definitions"][setting], *_text_table(table_rows(v, setting))]
        lines += ["", "Detection vs false alarms (threshold scale sweep):",
                  *_text_table(_roc_rows(v, ROC_PICKS)), "", v["verdict"]["text"], ""]
    return "\n".join(lines) + "\n"


def _md(rows: Sequence[Sequence[str]]) -> list[str]:
    out = ["| " + " | ".join(rows[0]) + " |",
           "|" + "|".join("---" if i < 3 else "---:" for i in range(len(rows[0]))) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return out


def format_markdown(summary: dict[str, Any], command: str = "") -> str:
    """Markdown tables to paste in the README (Table II per variant and setting, verdicts)."""
    sp = summary["spec"]
    lines = ["### Table II, reproduced on the simulator", ""]
    if command:
        lines += ["Made with:", "", "```sh", command, "```", ""]
    lines += [
        f"Stiffnesses {', '.join(f'{k:g}' for k in sp['stiffnesses'])} N/mm; "
        f"{len(sp['forces_n'])} amplitudes × {sp['case_seeds']} seeds × "
        f"{sp['impacts_per_case']} impacts per stiffness; soak {len(SOAK_FAMILIES)} families × "
        f"{sp['soak_runs']} × {sp['soak_run_s']:g} s per variant; seed {sp['seed']}. "
        "Minimal detected force = smallest labelled peak force detected; all detected above = "
        "largest peak force missed. Paper (N): Makarov et al. 2014, Table II.", ""]
    for v in summary["variants"]:
        lines += [f"#### {v['name']} — {v['description']}", "", _soak_line(v) + ".", ""]
        for setting in SETTINGS:
            lines += [f"*Thresholds {setting}* — {summary['definitions'][setting]}.", "",
                      *_md(table_rows(v, setting)), ""]
        lines += ["*Detection vs soak false alarms (threshold scale sweep, all stiffnesses)*",
                  "", *_md(_roc_rows(v, MD_ROC_PICKS, ("adaptive", "static_loading"))), "",
                  f"**Verdict.** {v['verdict']['text']}", ""]
    return "\n".join(lines)


def iter_detectors() -> Iterable[str]:
    """The detectors of the tables, in order."""
    return iter(TABLE_DETECTORS)
