"""Benchmark: peak memory and speed of ``impactcli detect`` on long logs, streamed.

Run: ``python tests/benchmarks/bench_stream.py [--minutes 10 60 180] [--joints 7]
[--repeat N] [--busy]
[--release REF] [--keep DIR]``.

A synthetic arm (J joints, 1 kHz; each joint a sum of three sines, torque from a decoupled
rigid model — inertia, gravity, viscous and Coulomb friction — plus noise; the reference
is the commanded position with its velocity and acceleration) is written as canonical CSV
into a temporary folder: a 5-minute collision-free log to calibrate on, and one log per
duration asked for. ``impactcli calibrate`` makes the config once; then, for each
duration, ``impactcli detect LOG --config C`` runs in a fresh process as a user runs it —
plain (``plain``), with ``--signals`` (``signals``), and with ``--rerun`` (``rerun``) — and
``impactcli detect LOG`` without a config (``noconfig``: the model identified from the log,
thresholds from its own statistics; ``noconfig-signals`` with ``--signals``). The
benchmark reports each run's wall time, the
real-time factor and its peak resident memory (ru_maxrss of that process alone, read by a
wrapper process). ``--release REF`` (default the tag ``v0.1.0``, the release before the
streaming replay; skipped when the ref does not exist) runs that release's code from a git
worktree in the same environment on the same files, for durations up to
``--release-max-minutes`` (default 60: it holds the whole log in memory).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RATE_HZ = 1000.0
ROOT = Path(__file__).resolve().parents[2]


def write_log(path: Path, minutes: float, joints: int, seed: int) -> int:
    """Write the synthetic log (module docstring), block by block; returns its rows.
    One robot and one task (the sines' amplitudes and frequencies, drawn once: a
    calibration on one log covers the others' motion); ``seed`` draws the phases and the
    noise."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    robot = np.random.default_rng(0)
    inertia = robot.uniform(0.05, 2.0, joints)
    grav = robot.uniform(0.0, 8.0, joints)
    fv = robot.uniform(0.05, 0.5, joints)
    fc = robot.uniform(0.05, 0.4, joints)
    amp = robot.uniform(0.2, 0.8, (3, joints))
    freq = robot.uniform(0.05, 0.6, (3, joints))
    rng = np.random.default_rng(seed)
    n = round(minutes * 60.0 * RATE_HZ)
    phase = rng.uniform(0, 2 * np.pi, (3, joints))
    names = [f"j{k + 1}" for k in range(joints)]
    block = 200_000
    with pacsv.CSVWriter(str(path), _schema(names)) as w:
        for a in range(0, n, block):
            k = np.arange(a, min(a + block, n))
            t = k / RATE_HZ
            w_t = 2 * np.pi * freq[None, :, :] * t[:, None, None] + phase[None]
            q = np.sum(amp * np.sin(w_t), axis=1)
            qd = np.sum(amp * 2 * np.pi * freq * np.cos(w_t), axis=1)
            qdd = -np.sum(amp * (2 * np.pi * freq) ** 2 * np.sin(w_t), axis=1)
            tau = inertia * qdd + grav * np.cos(q) + fv * qd + fc * np.tanh(qd / 0.01)
            tau = tau + rng.normal(0.0, 0.02, tau.shape)
            qm = q + rng.normal(0.0, 1e-5, q.shape)
            cols: dict[str, np.ndarray] = {"time": np.round(t, 6)}
            for j, nm in enumerate(names):
                cols[f"{nm}.position"] = np.round(qm[:, j], 7)
                cols[f"{nm}.torque"] = np.round(tau[:, j], 5)
                cols[f"{nm}.position_ref"] = np.round(q[:, j], 7)
                cols[f"{nm}.velocity_ref"] = np.round(qd[:, j], 6)
                cols[f"{nm}.acceleration_ref"] = np.round(qdd[:, j], 5)
            w.write_table(pa.table(cols, schema=_schema(names)))
    return n


def _schema(names: list[str]):  # type: ignore[no-untyped-def]
    import pyarrow as pa

    fields = [pa.field("time", pa.float64())]
    for nm in names:
        fields += [pa.field(f"{nm}.{s}", pa.float64()) for s in
                   ("position", "torque", "position_ref", "velocity_ref", "acceleration_ref")]
    return pa.schema(fields)


_WRAP = ("import resource, subprocess, sys, time; t = time.perf_counter(); "
         "p = subprocess.run(sys.argv[2:], capture_output=True, text=True, env=None); "
         "w = time.perf_counter() - t; "
         "print(p.returncode, w, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); "
         "sys.stderr.write(p.stderr[-2000:] if p.returncode else '')")


def measure(cmd: list[str], cwd: Path, env: dict[str, str] | None = None
            ) -> tuple[float, float]:
    """Wall time [s] and peak RSS [MB] of ``cmd`` alone (a wrapper process reads it), run in
    ``cwd`` (not the repository: ``python -m`` puts the working folder first on the path,
    which would import the repository's code instead of the release's)."""
    p = subprocess.run([sys.executable, "-c", _WRAP, "x", *cmd], capture_output=True,
                       text=True, env=env, cwd=cwd, check=False)
    rc, wall, rss = p.stdout.split()
    if int(rc) != 0:
        sys.exit(f"failed ({rc}): {' '.join(cmd)}\n{p.stderr}")
    return float(wall), float(rss) / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[10.0, 60.0, 180.0])
    ap.add_argument("--joints", type=int, default=7)
    ap.add_argument("--release", default="v0.1.0")
    ap.add_argument("--release-max-minutes", type=float, default=60.0)
    ap.add_argument("--variants", nargs="+", default=["plain", "signals", "rerun"],
                    choices=sorted(VARIANTS))
    ap.add_argument("--keep", type=Path)
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs of each code, interleaved (this, release, this, ...); the "
                         "table then gives each run and the medians")
    ap.add_argument("--busy", action="store_true",
                    help="keep one core busy (a spinning process) during the runs")
    args = ap.parse_args()
    spinner = (subprocess.Popen([sys.executable, "-c", "while 1: pass"])
               if args.busy else None)
    tmp = Path(args.keep or tempfile.mkdtemp(prefix="impactcli-bench-stream-"))
    tmp.mkdir(parents=True, exist_ok=True)
    exe = str(Path(sys.executable).with_name("impactcli"))
    rows = []
    release = _release(args.release, tmp)
    try:
        cal = tmp / "free.csv"
        write_log(cal, 5.0, args.joints, seed=1)
        cfg = tmp / "config.toml"
        subprocess.run([exe, "calibrate", str(cal), "-o", str(cfg)], check=True,
                       capture_output=True)
        cfg_release = tmp / "config_release.toml"  # the release's own calibrate: its schema
        if release is not None:
            subprocess.run([sys.executable, "-m", "impactcli", "calibrate", str(cal), "-o",
                            str(cfg_release)], check=True, capture_output=True, cwd=tmp,
                           env=dict(os.environ, PYTHONPATH=str(release)))
        for minutes in args.minutes:
            log = tmp / f"log_{minutes:g}min.csv"
            t = time.perf_counter()
            write_log(log, minutes, args.joints, seed=2)
            size = log.stat().st_size / 1e6
            print(f"{minutes:g} min: wrote {size:.0f} MB in {time.perf_counter() - t:.0f} s",
                  file=sys.stderr)
            for variant, _ in itertools.product(args.variants, range(args.repeat)):
                out = tmp / f"out_{variant}"
                cmd = _command(variant, exe, log, cfg, out)
                wall, rss = measure(cmd, tmp)
                rows.append(_row("this", minutes, variant, wall, rss, size))
                print(json.dumps(rows[-1]), file=sys.stderr)
                shutil.rmtree(out, ignore_errors=True)
                if release is not None and minutes <= args.release_max_minutes:
                    env = dict(os.environ, PYTHONPATH=str(release))
                    cmd = [sys.executable, "-m", "impactcli",
                           *_command(variant, exe, log, cfg_release, out)[1:]]
                    wall, rss = measure(cmd, tmp, env)
                    rows.append(_row(args.release, minutes, variant, wall, rss, size))
                    print(json.dumps(rows[-1]), file=sys.stderr)
                    shutil.rmtree(out, ignore_errors=True)
            log.unlink()
    finally:
        if spinner is not None:
            spinner.kill()
        if release is not None:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                            str(release)], check=False, capture_output=True)
        if args.keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}; {args.joints} joints at {RATE_HZ:g} Hz, "
          "calibrated config (decoupled model)"
          + ("; one core kept busy by a spinning process" if args.busy else "")
          + f"; load average at the end {os.getloadavg()[0]:.1f}")
    print("| code | log | outputs | wall | × real time | peak RSS |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['code']} | {r['minutes']:g} min ({r['csv_mb']:.0f} MB) | {r['variant']} "
              f"| {r['wall_s']:.1f} s | {r['x_real_time']:.0f}× | {r['peak_rss_mb']:.0f} MB |")
    if args.repeat > 1:
        print(f"medians of {args.repeat} interleaved runs:")
        groups: dict[tuple[object, ...], list[dict[str, object]]] = {}
        for r in rows:
            groups.setdefault((r["code"], r["minutes"], r["variant"]), []).append(r)
        for (code, minutes, variant), rs in groups.items():
            each = [float(x["x_real_time"]) for x in rs]  # type: ignore[arg-type]
            runs = ", ".join(f"{v:.0f}" for v in each)
            print(f"| {code} | {minutes:g} min | {variant} | median "
                  f"{float(np.median(each)):.1f}× real time ({runs}) |")


#: Each variant's command-line options after the log.
VARIANTS: dict[str, list[str]] = {
    "plain": ["--config"], "signals": ["--config", "--signals"],
    "rerun": ["--config", "--rerun"], "noconfig": [], "noconfig-signals": ["--signals"],
}


def _command(variant: str, exe: str, log: Path, cfg: Path, out: Path) -> list[str]:
    """The process a variant runs (module docstring)."""
    opts = VARIANTS[variant]
    extra = [o if o != "--config" else f"--config={cfg}" for o in opts]
    return [exe, "detect", str(log), "-o", str(out), *extra]


def _row(code: str, minutes: float, variant: str, wall: float, rss: float,
         size: float) -> dict[str, object]:
    return {"code": code, "minutes": minutes, "variant": variant, "wall_s": wall,
            "x_real_time": minutes * 60.0 / wall, "peak_rss_mb": rss, "csv_mb": size}


#: The commit the tag v0.1.0 names (a clone without tags still finds the release).
RELEASE_COMMIT = "504e5ae194b6f66afa8778b2583a1a49010abbe7"


def _release(ref: str, tmp: Path) -> Path | None:
    """A worktree of ``ref`` (its ``impactcli`` package importable from it), or None."""
    where = tmp / "release"
    if ref == "v0.1.0" and subprocess.run(["git", "-C", str(ROOT), "rev-parse", "-q",
                                           "--verify", "refs/tags/v0.1.0"],
                                          capture_output=True, check=False).returncode:
        ref = RELEASE_COMMIT
    p = subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(where),
                        ref], capture_output=True, text=True, check=False)
    if p.returncode != 0:
        print(f"release {ref!r} not measured: {p.stderr.strip()}", file=sys.stderr)
        return None
    return where


if __name__ == "__main__":
    main()
