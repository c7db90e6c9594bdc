"""Benchmark: the threshold sweep of ``impactcli evaluate --sweep`` on a long synthetic run.

Run: ``python tests/benchmarks/bench_evaluate_sweep.py [minutes] [--release REF]`` (default
60 minutes of log at 250 Hz, 6 joints, 100 contacts, the CLI's default scales 0.2:5:x1.05).
The run's ratios are swept in memory (one chunk) and, where the code has the chunked sweep,
fed in chunks of 65,536 samples as a replay's spill or a signals Parquet feeds it.
``--release REF`` measures REF's code in the same run (a git worktree, each code in a fresh
process).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
CHUNK_ROWS = 65_536


def _run(minutes: float) -> tuple[Any, Any, Any]:
    import numpy as np
    from scipy.signal import lfilter

    from impactcli.types import ContactLabel, Labels

    fs, n_j = 250.0, 6
    n = int(minutes * 60 * fs)
    rng = np.random.default_rng(0)
    t = np.arange(n) / fs
    # ratio-like noise: |AR(1)| with a floor near 0.4, max around 1–1.5
    ratios = {}
    for d in ("adaptive", "static_loading", "static_baseline"):
        e = rng.standard_normal((n, n_j))
        a = 0.9 if d != "static_baseline" else 0.0
        x = lfilter([1.0], [1.0, -a], e, axis=0)
        ratios[d] = 0.25 * np.abs(x) / np.sqrt(1 / (1 - a * a))
    contacts = []
    for i, c0 in enumerate(np.linspace(30.0, t[-1] - 30.0, 100)):
        force = 1.0 + 0.2 * i
        m = (t >= c0) & (t <= c0 + 0.2)
        for r in ratios.values():
            r[m, i % n_j] += 0.05 * force
        contacts.append(ContactLabel(float(c0), float(c0 + 0.2), force, "impact", 1 + i % n_j))
    return t, ratios, Labels(tuple(contacts), fs)


def child(minutes: float) -> None:
    """Measure the importable code (one JSON object on stdout)."""
    import importlib

    from impactcli.cli.evaluate import DEFAULT_SCALES, parse_scales

    for pkg in ("impactcli.quality", "impactcli.scoring"):  # today's layout, then older
        try:
            sweep_mod = importlib.import_module(f"{pkg}.sweep")
            verdict_mod = importlib.import_module(f"{pkg}.verdict")
            break
        except ImportError:
            continue
    else:  # pragma: no cover - the oldest layout
        sweep_mod = verdict_mod = importlib.import_module("impactcli.evaluate")
    t, ratios, labels = _run(minutes)
    scales = parse_scales(DEFAULT_SCALES)
    kw = {"warmup_end_s": 5.0, "merge_gap_s": 0.1, "min_duration_s": 0.0}
    t0 = time.perf_counter()
    rows = sweep_mod.sweep_ratios(ratios, t, labels=labels, scales=scales, **kw)
    out: dict[str, Any] = {"in memory (one chunk)": time.perf_counter() - t0}
    if hasattr(sweep_mod, "ThresholdSweep"):
        t0 = time.perf_counter()
        sw = sweep_mod.ThresholdSweep(scales, **kw)
        for a in range(0, len(t), CHUNK_ROWS):
            sw.update(t[a:a + CHUNK_ROWS], {d: r[a:a + CHUNK_ROWS] for d, r in ratios.items()})
        chunked = sw.rows(labels)
        out[f"in chunks of {CHUNK_ROWS:,}"] = time.perf_counter() - t0
        assert chunked == rows, "the chunked sweep differs from the one-chunk sweep"
    zero = verdict_mod.at_zero_false_alarms(rows)
    out.update(samples=len(t), joints=6, scales=len(scales), rows=len(rows),
               max_events=max(r.n_events for r in rows),
               zero={d: None if r is None else [r.scale, r.detected, r.n_contacts]
                     for d, r in zero.items()},
               verdict=verdict_mod.verdict(zero),
               digest=json.dumps([r.to_dict(per_contact=True) for r in rows], sort_keys=True))
    print(json.dumps(out))


def _measure(tree: Path, minutes: float) -> dict[str, Any]:
    p = subprocess.run([sys.executable, str(Path(__file__).resolve()), str(minutes),
                        "--child", str(tree)], capture_output=True, text=True, check=True,
                       cwd=tempfile.gettempdir())
    return dict(json.loads(p.stdout.splitlines()[-1]))


def main() -> None:
    from machine import machine_line
    from release_tree import release_tree

    ap = argparse.ArgumentParser()
    ap.add_argument("minutes", nargs="?", type=float, default=60.0)
    ap.add_argument("--release", default=None, help="also measure this git ref's code")
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        sys.path.insert(0, args.child)
        child(args.minutes)
        return
    codes = [("this", ROOT)]
    with release_tree(args.release) as release:
        if release is not None and args.release is not None:
            codes.append((args.release, release))
        got = [(name, _measure(tree, args.minutes)) for name, tree in codes]
    first = got[0][1]
    print(machine_line())
    print(f"log: {args.minutes:g} min, {first['samples']} samples, {first['joints']} joints, "
          f"{first['scales']} scales, {first['rows']} rows, at most {first['max_events']} "
          "events")
    print("| code | sweep | s |")
    print("|---|---|---|")
    for name, out in got:
        for k, v in out.items():
            if k.startswith("in "):
                print(f"| {name} | {k} | {v:.2f} |")
    if len(got) > 1:
        same = all(o["digest"] == first["digest"] for _, o in got)
        print(f"rows of every code identical: {same}")
    for d, r in first["zero"].items():
        print(f"  {d}: " + ("never" if r is None else f"scale {r[0]:g}, {r[1]}/{r[2]}"))
    print(" ", first["verdict"])


if __name__ == "__main__":
    main()
