"""What the sensitivity study runs: the paper's Table II numbers, the arm variants and their
task geometry, the soak's run families, and :class:`StudySpec` (sizes, scales, seed).

Everything else of the study (:mod:`impactcli.study`) reads these; nothing here
simulates or scores. Seeds derive from ``StudySpec.seed`` through :func:`seed_of`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..quality.match import MatchTolerance
from ..quality.sweep import geometric_scales

SCHEMA_VERSION = "1.0"
#: The paper's Table II: minimal detected force [N] of the proposed method per stiffness
#: [N/mm]; the static threshold v0 needs > 20 N at every stiffness.
PAPER_ADAPTIVE_N: dict[float, float] = {10.12: 4.44, 5.93: 5.61, 2.12: 5.87}
PAPER_STATIC_N = 20.0
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
        forces_n: nominal pressing forces that set the amplitudes
            (:mod:`impactcli.study`) [N].
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
        from ..errors import ConfigError

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


def seed_of(*key: int | float | str) -> int:
    """A 32-bit seed from a key (deterministic across processes and runs)."""
    ints = [int(x) if isinstance(x, int) else sum(ord(c) * 131**i for i, c in enumerate(str(x)))
            for x in key]
    return int(np.random.SeedSequence(ints).generate_state(1)[0])
