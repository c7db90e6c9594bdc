"""The sample logs shipped in ``sample_logs/``: a manifest and a deterministic generator.

``python -m impactcli.sim.sample_logs OUTDIR`` regenerates every file (same bytes for the same
code and library versions): ``OUTDIR/csv/<name>.csv.gz`` and ``OUTDIR/mcap/<name>.mcap``
(separate folders: a CSV and an MCAP of one log share their stem, hence their timeline
name), each folder with ``<name>.labels.json`` and ``<name>.robot.json``, and
``OUTDIR/README.md`` with the table of what each log holds.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from .arm import preset
from .core import Scenario, SimResult, simulate
from .scenarios import impacts, scenario


@dataclass(frozen=True)
class Sample:
    """One shipped log: name (file stem), how to build its scenario, seed, MCAP encoding."""

    name: str
    arm: str
    scenario: str
    duration_s: float | None
    seed: int
    mcap_encoding: str
    use: str
    build: Callable[[], Scenario] | None = None

    def make(self) -> Scenario:
        sc = self.build() if self.build else scenario(self.scenario, self.arm, self.duration_s)
        return replace(sc, name=self.name, robot_seed=ROBOT_SEEDS[self.arm],
                       controller_channels=self.arm in CONTROLLER_CHANNEL_ARMS)


#: One physical robot per arm: every sample log of an arm is recorded on the same true
#: robot (its parameters drawn once, from this seed), as a robot's own logs are; the run
#: seed of each log draws its reference details, noise and friction drift. Fixed before
#: any result was looked at (the arm's seed series: 101–108 → 100, 201–204 → 200).
ROBOT_SEEDS: dict[str, int] = {"assist_like": 100, "heavy_geared": 200}

#: Arms whose sample logs carry the controller's own channels ``torque_model`` and
#: ``torque_ext`` (:mod:`impactcli.sim.controller`); the others log neither, as most robots'
#: logs in the wild. The channels are computed from the logged data after the simulation,
#: so every other column is the same as without them.
CONTROLLER_CHANNEL_ARMS: frozenset[str] = frozenset({"assist_like"})


def _heavy_impacts() -> Scenario:
    return impacts(preset("heavy_geared"), None, stiffnesses=(2.12, 5.93, 10.12),
                   forces_n=(4.0, 12.0, 30.0), speeds=(0.15, 0.45, 0.3))


MANIFEST: tuple[Sample, ...] = (
    Sample("assist_free_triangle", "assist_like", "free_triangle", 40.0, 101, "json",
           "collision-free: calibration"),
    Sample("assist_free_fm_triangle", "assist_like", "free_fm_triangle", 40.0, 102, "json",
           "collision-free: fast motion no contact log has (not in the shipped config)"),
    Sample("assist_free_p2p", "assist_like", "free_p2p", 40.0, 103, "ros2",
           "collision-free: calibration"),
    Sample("assist_free_multisine", "assist_like", "free_multisine", 40.0, 104, "json",
           "collision-free: calibration"),
    Sample("assist_impacts", "assist_like", "impacts", None, 105, "ros2",
           "detection: end-effector impacts on 2.12 / 5.93 / 10.12 N/mm elastomers"),
    Sample("assist_pushes", "assist_like", "pushes", 44.0, 106, "json",
           "detection: pushes of graded force on both links"),
    Sample("assist_clamps", "assist_like", "clamps", 44.0, 107, "json",
           "detection: slow clamping (static_loading detector)"),
    Sample("assist_payload", "assist_like", "payload", 40.0, 108, "json",
           "collision-free with an unknown 0.5 kg payload: robustness"),
    Sample("heavy_free_multisine", "heavy_geared", "free_multisine", 30.0, 201, "ros2",
           "collision-free: calibration (heavy geared arm)"),
    Sample("heavy_free_triangle", "heavy_geared", "free_triangle", 30.0, 204, "json",
           "collision-free: calibration (heavy geared arm; the impacts log's lead-in)"),
    Sample("heavy_free_p2p", "heavy_geared", "free_p2p", 40.0, 203, "json",
           "collision-free: calibration (heavy geared arm; the impacts log's moves)"),
    Sample("heavy_impacts", "heavy_geared", "impacts", None, 202, "json",
           "detection: impacts on elastomers (heavy geared arm)", _heavy_impacts),
)


def _contacts_summary(res: SimResult) -> str:
    evs = res.labels.events
    if not evs:
        return "none"
    kinds = sorted({e.kind for e in evs})
    lo = min(e.peak_force for e in evs)
    hi = max(e.peak_force for e in evs)
    return f"{len(evs)} {'/'.join(kinds)}, peak {lo:.1f}–{hi:.1f} N"


def generate(outdir: str | Path, names: list[str] | None = None) -> list[Path]:
    """Simulate the manifest (or the named entries) and write every file under ``outdir``.

    Returns the paths written (logs, labels, robot descriptions, README.md).
    """
    from ..logs import write_log
    from ..logs.robot_files import write_labels, write_robot

    out = Path(outdir)
    written: list[Path] = []
    rows = []
    for entry in MANIFEST:
        if names and entry.name not in names:
            continue
        sc = entry.make()
        res = simulate(sc, seed=entry.seed)
        for sub, suffix in (("csv", ".csv.gz"), ("mcap", ".mcap")):
            folder = out / sub
            folder.mkdir(parents=True, exist_ok=True)
            log_path = folder / f"{entry.name}{suffix}"
            write_log(res.log, log_path, mcap_encoding=entry.mcap_encoding)
            write_labels(res.labels, folder / f"{entry.name}.labels.json")
            write_robot(res.robot, folder / f"{entry.name}.robot.json")
            written += [log_path, folder / f"{entry.name}.labels.json",
                        folder / f"{entry.name}.robot.json"]
        rows.append(
            f"| `{entry.name}` | {entry.arm} | {sc.description or entry.scenario} | "
            f"{res.log.duration_s:.0f} s @ {res.log.sample_rate_hz:.0f} Hz | "
            f"{sc.payload_kg:g} kg | {_contacts_summary(res)} | {entry.use} | "
            f"{'ROS 2 JointState' if entry.mcap_encoding == 'ros2' else 'JSON'} | "
            f"{entry.seed} |"
        )
    if not names:
        readme = out / "README.md"
        seeds = ", ".join(f"{a} {s}" for a, s in ROBOT_SEEDS.items())
        readme.write_text(_README.format(rows="\n".join(rows), robot_seeds=seeds),
                          encoding="utf-8")
        written.append(readme)
    return written


_README = """# Sample logs (simulated)

Generated by `python -m impactcli.sim.sample_logs sample_logs` (deterministic: same code and
library versions, same bytes) from the flexible-joint simulator `impactcli.sim` — the
paper's eq. 1–2 for a planar arm in a vertical plane, PD motor-position control at the
sample period with gravity feed-forward from the nominal model, encoder quantisation,
noisy quantised motor current (`torque = gear_ratio × torque_constant × current`). The
simulated robot is NOT the nominal one in `*.robot.json`: its masses, inertias, stiffness
and friction differ by up to ±20 %, friction drifts slowly, and `assist_payload` carries a
payload the description does not mention. All logs of an arm come from ONE such robot
(true parameters drawn once per arm, robot seed {robot_seeds}), as a robot's own logs do;
each log's seed draws its reference details, noise and friction drift.

The `assist_*` logs also carry the controller's own channels, as a real controller logs
them: `torque_model` (the torque its NOMINAL rigid model expects for the measured motion,
without contact) and `torque_ext` (its external-torque estimate: a generalized-momentum
observer on that model, gain 50 1/s, low-passed at 20 Hz, sign = the external torque
acting on the joint), both on a 0.01 N·m grid and both carrying the model's errors (wrong
parameters, friction drift, the flexible transmissions a rigid model ignores — and in
`assist_payload` the unknown payload, an external load to that model too); `heavy_*` logs
have neither, like most logs in the wild.

Layout: `csv/<name>.csv.gz` (canonical wide CSV) and `mcap/<name>.mcap` hold the SAME log
(MCAP encoding in the table; the ROS 2 files carry position, velocity and effort = torque
on `/joint_states`, the reference on `/joint_states_ref` and the controller's channels as
the effort of `/joint_states_model` and `/joint_states_ext`; not current or acceleration
reference). They are in separate folders because their
stems — hence their timeline names — are the same. Each folder also has
`<name>.labels.json` (ground truth: `start`/`end` = first/last sample where that contact's
true force exceeds 0.5 N, in s since the first sample; `peak_force` N; `kind`; 1-based
`link`; extra fields: `source`, elastomer `stiffness_n_per_mm` and `tip_speed_m_s` for
impacts, `duration_s` for pushes, `rise_s`/`hold_s` for clamps) and `<name>.robot.json`
(nominal description).

Arms (numbers in `impactcli/sim/arm.py`): `assist_like` — 2 joints, 0.4/0.4 m, cable
reduction 20:1, soft joints (800/300 N·m/rad), low friction, Ts = 4 ms; `heavy_geared` —
3 joints, 0.5/0.4/0.2 m, 100:1 gears, strong Coulomb friction, stiffer joints, Ts = 2 ms.

Suggested use: calibrate thresholds on some collision-free logs, check false alarms on the
others, then detect on the contact logs and `evaluate` against their labels.

| name | arm | what | duration | payload | labelled contacts | use | MCAP | seed |
|---|---|---|---|---|---|---|---|---|
{rows}
"""


def main(argv: list[str] | None = None) -> int:
    """``python -m impactcli.sim.sample_logs OUTDIR [NAME ...]``."""
    args = sys.argv[1:] if argv is None else argv
    if not args or args[0] in ("-h", "--help"):
        print("usage: python -m impactcli.sim.sample_logs OUTDIR [NAME ...]")
        print("names: " + ", ".join(e.name for e in MANIFEST))
        return 0 if args else 2
    for p in generate(args[0], args[1:] or None):
        print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
