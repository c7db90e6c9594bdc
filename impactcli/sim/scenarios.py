"""A small library of named scenarios: ``scenario(name, arm=..., duration_s=..., **overrides)``.

Names (see :data:`SCENARIOS`):

* ``free_triangle``, ``free_fm_triangle``, ``free_p2p``, ``free_multisine`` —
  collision-free motion of the four reference families (for calibration and false-alarm
  checks).
* ``impacts`` — the paper's experiment (its §IV-B): joint 1 moves the extended arm along
  triangles; on the way down the end effector meets an elastomer (2.12, 5.93, 10.12 N/mm
  by default, swapped between blocks of impacts) at varied speeds; the reference goes on
  below the surface by Δ = F_target × (Σ_j r_j² / kp_j) / reach (r_j: joint j to tip), so
  the servos' quasi-static pressing force is ≈ F_target (4–40 N), plus the impact
  transient. A collision-free lead-in (10 s) comes first.
* ``pushes`` — half-sine pushes of graded peak force (5–40 N) on both links during slow
  motion.
* ``clamps`` — slow clamping ramps (20–40 N over 3–4 s, held, released) during slow motion.
* ``payload`` — ``free_multisine`` with an unknown end-effector payload (0.5 kg on
  assist_like, 2 kg on heavy_geared).
* ``pick_and_place`` — ``free_multisine`` that picks a payload at a third of the run and
  releases it at two thirds (``Scenario.payload_changes``), with pushes before, while
  carrying it and after.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from .arm import ArmParams, preset
from .contacts import Clamp, Push, Surface
from .core import Scenario
from .reference import FMTriangle, MultiSine, PointToPoint, Triangle, Waypoints

#: Elastomer stiffnesses of the paper's Table II [N/mm].
PAPER_STIFFNESSES = (2.12, 5.93, 10.12)


def _speed(arm: ArmParams) -> float:
    """Motion speed scale: 1 for light arms, slower for heavy geared ones."""
    return 1.0 if arm.name == "assist_like" else 0.6


def _mid_amp(arm: ArmParams, frac: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    mid = tuple(0.5 * (lo + hi) for lo, hi in arm.joint_ranges)
    amp = tuple(frac * 0.5 * (hi - lo) for lo, hi in arm.joint_ranges)
    return mid, amp


def free_triangle(arm: ArmParams, duration_s: float) -> Scenario:
    mid, amp = _mid_amp(arm, 0.6)
    periods = tuple((4.0 + 1.3 * j) / _speed(arm) for j in range(arm.n_joints))
    return Scenario("free_triangle", arm, duration_s, Triangle(mid, amp, periods),
                    description="collision-free position triangles (velocity steps)")


def free_fm_triangle(arm: ArmParams, duration_s: float) -> Scenario:
    mid, amp = _mid_amp(arm, 0.5)
    periods = tuple((3.0 + 0.8 * j) / _speed(arm) for j in range(arm.n_joints))
    return Scenario("free_fm_triangle", arm, duration_s,
                    FMTriangle(mid, amp, periods, depth=0.5, mod_period_s=20.0),
                    description="collision-free frequency-modulated triangles")


def free_p2p(arm: ArmParams, duration_s: float) -> Scenario:
    lo = tuple(0.7 * a for a, _ in arm.joint_ranges)
    hi = tuple(0.7 * b for _, b in arm.joint_ranges)
    s = _speed(arm)
    ref = PointToPoint(arm.home, lo, hi, max_vel=(1.0 * s,) * arm.n_joints,
                       max_acc=(5.0 * s,) * arm.n_joints, dwell_s=0.5)
    return Scenario("free_p2p", arm, duration_s, ref,
                    description="collision-free point-to-point moves, trapezoidal velocity")


def free_multisine(arm: ArmParams, duration_s: float) -> Scenario:
    mid, amp = _mid_amp(arm, 0.6)
    ref = MultiSine(mid, amp, f_min=0.05, f_max=0.6 * _speed(arm), n_sines=4)
    return Scenario("free_multisine", arm, duration_s, ref,
                    description="collision-free smooth multi-sine motion")


def payload(arm: ArmParams, duration_s: float) -> Scenario:
    base = free_multisine(arm, duration_s)
    kg = 0.5 if arm.name == "assist_like" else 2.0
    return replace(base, name="payload", payload_kg=kg,
                   description=f"collision-free multi-sine with an unknown {kg} kg payload")


def pick_and_place(arm: ArmParams, duration_s: float) -> Scenario:
    """``free_multisine`` that picks a payload at a third of the run and releases it at two
    thirds (1.0 kg on assist_like, 2 kg on heavy_geared), with half-sine pushes of 20 and
    30 N before, while carrying it (two) and after."""
    base = free_multisine(arm, duration_s)
    kg = 1.0 if arm.name == "assist_like" else 2.0
    pick, place = duration_s / 3.0, 2.0 * duration_s / 3.0
    n = arm.n_joints
    at = (pick / 2.0, pick + (place - pick) * 0.4, pick + (place - pick) * 0.75,
          place + (duration_s - place) * 0.5)
    ps = tuple(Push(link=n if i % 2 == 0 else max(1, n - 1), t0_s=t, peak_n=(30.0, 20.0)[i % 2],
                    duration_s=0.3, point=0.7, direction_deg=-90.0 if i % 2 else 90.0)
               for i, t in enumerate(at))
    return replace(base, name="pick_and_place", pushes=ps,
                   payload_changes=((pick, kg), (place, 0.0)),
                   description=f"multi-sine motion picking a {kg:g} kg payload at {pick:.3g} s "
                   f"and releasing it at {place:.3g} s, pushes of 20–30 N before, while "
                   "carrying it and after")


def impacts(arm: ArmParams, duration_s: float | None,
            stiffnesses: tuple[float, ...] = PAPER_STIFFNESSES,
            forces_n: tuple[float, ...] = (4.0, 8.0, 15.0, 25.0, 40.0),
            speeds: tuple[float, ...] = (0.15, 0.3, 0.45, 0.3, 0.6)) -> Scenario:
    """End-effector impacts on elastomers (speeds are joint-1 rates [rad/s] before scaling)."""
    reach = sum(arm.link_lengths)
    th_top, th_s = 0.10, -0.08
    y_s = reach * math.sin(th_s)
    rest = tuple(arm.home[1:])
    sp = _speed(arm)
    # tip compliance of the PD servos, arm extended: sum over joints of r_j² / kp_j with r_j
    # the distance from joint j to the tip [m/N]; a reference Δ below contact makes the
    # shoulder push with ≈ Δ · reach / compliance
    compliance = sum(sum(arm.link_lengths[j:]) ** 2 / arm.kp[j] for j in range(arm.n_joints))
    times: list[float] = [0.0]
    pos: list[tuple[float, ...]] = [(th_top, *rest)]

    def go(th: float, omega: float, dwell: float) -> None:
        t = times[-1] + abs(th - pos[-1][0]) / omega
        times.append(t)
        pos.append((th, *rest))
        if dwell > 0:
            times.append(t + dwell)
            pos.append((th, *rest))

    # collision-free lead-in: triangles that stay above the surface
    while times[-1] < 10.0:
        go(th_s + 0.05, 0.4 * sp, 0.0)
        go(th_top, 0.4 * sp, 0.0)
    surfaces = []
    for k in stiffnesses:
        t_on = times[-1]
        for f, w in zip(forces_n if sp == 1.0 else tuple(0.5 * x for x in forces_n),
                        speeds, strict=True):
            delta = f * compliance / reach
            go(th_top, 1.0, 0.5)
            go(th_s - delta, w * sp, 0.4)
            go(th_top, w * sp, 1.0)
        surfaces.append(Surface(y_s, k, x_min_m=reach - 0.15, x_max_m=reach + 0.15,
                                t_on_s=t_on, t_off_s=times[-1]))
    natural = times[-1] + 1.0
    ref = Waypoints(tuple(times), tuple(pos))
    return Scenario("impacts", arm, duration_s or natural, ref, surfaces=tuple(surfaces),
                    description="end-effector impacts on elastomers "
                    f"{', '.join(f'{k} N/mm' for k in stiffnesses)} at varied speeds")


def _slow_motion(arm: ArmParams, duration_s: float, name: str) -> Scenario:
    mid, amp = _mid_amp(arm, 0.3)
    ref = MultiSine(mid, amp, f_min=0.03, f_max=0.15, n_sines=3)
    return Scenario(name, arm, duration_s, ref)


def pushes(arm: ArmParams, duration_s: float) -> Scenario:
    """Half-sine pushes of graded peak force, every 4 s from t = 8 s."""
    peaks = (5.0, 8.0, 12.0, 16.0, 20.0, 25.0, 30.0, 35.0, 40.0)
    durs = (0.15, 0.3, 0.2, 0.4, 0.25)
    n = arm.n_joints
    ps = []
    t = 8.0
    i = 0
    while t + 1.0 < duration_s:
        link = n if i % 2 == 0 else max(1, n - 1)
        ps.append(Push(link=link, t0_s=t, peak_n=peaks[i % len(peaks)],
                       duration_s=durs[i % len(durs)], point=0.5 + 0.1 * (i % 5),
                       direction_deg=-90.0 if i % 3 else 90.0))
        t += 4.0
        i += 1
    base = _slow_motion(arm, duration_s, "pushes")
    return replace(base, pushes=tuple(ps),
                   description="half-sine pushes of 5–40 N on the links during slow motion")


def clamps(arm: ArmParams, duration_s: float) -> Scenario:
    """Slow clamping ramps 20–40 N (rise 3–4 s, hold 2 s, release 0.1–0.3 s), every 12 s."""
    peaks = (20.0, 30.0, 40.0, 25.0)
    n = arm.n_joints
    cs = []
    t = 8.0
    i = 0
    while t + 8.0 < duration_s:
        cs.append(Clamp(link=n, t0_s=t, peak_n=peaks[i % len(peaks)],
                        rise_s=3.0 + 0.5 * (i % 3), hold_s=2.0,
                        release_s=(0.1, 0.3, 0.2)[i % 3], point=0.9,
                        direction_deg=-90.0 if i % 2 == 0 else 90.0))
        t += 12.0
        i += 1
    base = _slow_motion(arm, duration_s, "clamps")
    return replace(base, clamps=tuple(cs),
                   description="slow clamping ramps of 20–40 N during slow motion")


SCENARIOS: dict[str, Callable[..., Scenario]] = {
    "free_triangle": free_triangle,
    "free_fm_triangle": free_fm_triangle,
    "free_p2p": free_p2p,
    "free_multisine": free_multisine,
    "impacts": impacts,
    "pushes": pushes,
    "clamps": clamps,
    "payload": payload,
    "pick_and_place": pick_and_place,
}

#: Default durations [s] (``impacts``: its natural length, ≈ 60 s).
DEFAULT_DURATION_S = 60.0


def scenario(name: str, arm: str | ArmParams = "assist_like", duration_s: float | None = None,
             **overrides: Any) -> Scenario:
    """The named scenario on ``arm`` (a preset name or an :class:`ArmParams`).

    duration_s [s] defaults to 60 s (``impacts``: as long as its impacts take).
    ``overrides`` replace :class:`~impactcli.sim.core.Scenario` fields (e.g. ``payload_kg``,
    ``uncertainty``, ``noise``, ``t0_ns``).
    """
    if name not in SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; choose one of {sorted(SCENARIOS)}")
    a = preset(arm) if isinstance(arm, str) else arm
    if name == "impacts":
        sc = impacts(a, duration_s)
    else:
        sc = SCENARIOS[name](a, duration_s or DEFAULT_DURATION_S)
    return replace(sc, **overrides) if overrides else sc
