"""Fit quality of the rough rigid model on the flexible-joint simulator (issue 3's bar).

    python tests/benchmarks/fit_quality.py

For the ASSIST-like arm — the preset, and three robots whose every physical parameter is
drawn ±20 % off it (``impactcli.sensitivity.the_robot``) — a ``planar`` model is identified
on a 60 s collision-free multi-sine run and judged on *other* trajectories of the same
robot (multi-sine, triangles, point-to-point, 30 s each, another seed): RMS torque error
relative to the joint's torque RMS (both zero-phase filtered at 10 Hz, as identification
sees them). Then the residual during two slow 2 s, 20 N pushes against the applied
external torque at the push's peak. Prints markdown tables and the machine.
"""

from __future__ import annotations

import os
import platform
import warnings
from dataclasses import replace

import numpy as np

from impactcli.model import (
    ResidualOptions,
    compute_residual,
    identify,
    zero_phase_derivatives,
    zero_phase_lowpass,
)
from impactcli.sensitivity import the_robot
from impactcli.sim import Push, preset, scenario, simulate


def _rel_error(model, log) -> np.ndarray:  # type: ignore[no-untyped-def]
    qf, qd, qdd = zero_phase_derivatives(log.time_s, log.position, 10.0)
    tau = zero_phase_lowpass(log.torque, log.sample_rate_hz, 10.0)
    inner = slice(100, -100)
    err = model.predict(qf, qd, qdd)[inner] - tau[inner]
    return np.sqrt(np.mean(err**2, axis=0)) / np.sqrt(np.mean(tau[inner] ** 2, axis=0))


def main() -> None:
    warnings.simplefilter("ignore")
    robots = [("preset", preset("assist_like"))] + [
        (f"±20 % robot {k}", the_robot("assist_like", k)) for k in range(3)]
    tests = ("free_multisine", "free_triangle", "free_p2p")
    print("| robot | " + " | ".join(f"{t} (shoulder / elbow)" for t in tests)
          + " | push residual error at peak (link 2 / link 1) |")
    print("|---|" + "---|" * (len(tests) + 1))
    for label, arm in robots:
        train = simulate(scenario("free_multisine", arm, 60.0, uncertainty=0.0), seed=1)
        model = identify(train.log, robot=train.robot)
        cells = []
        for name in tests:
            log = simulate(scenario(name, arm, 30.0, uncertainty=0.0), seed=7).log
            rel = _rel_error(model, log)
            cells.append(" / ".join(f"{100 * x:.1f} %" for x in rel))
        pushes = (Push(link=2, t0_s=10.0, peak_n=20.0, duration_s=2.0, point=0.8),
                  Push(link=1, t0_s=20.0, peak_n=20.0, duration_s=2.0, point=0.8,
                       direction_deg=90.0))
        run = simulate(replace(scenario("pushes", arm, 25.0, uncertainty=0.0), pushes=pushes),
                       seed=3)
        r = compute_residual(model, run.log, ResidualOptions()).r
        ext, t = run.truth["tau_ext"], run.log.time_s
        errs = []
        for start in (10.0, 20.0):
            k = np.flatnonzero((t >= start) & (t <= start + 2.0))
            peak = k[np.argmax(np.abs(ext[k]).max(axis=1))]
            j = int(np.argmax(np.abs(ext[peak])))
            errs.append(f"{100 * abs(r[peak, j] - ext[peak, j]) / abs(ext[peak, j]):.1f} %")
        print(f"| {label} | " + " | ".join(cells) + " | " + " / ".join(errs) + " |")
    print(f"\nmachine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}")


if __name__ == "__main__":
    main()
