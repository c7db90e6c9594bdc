"""Validation of the uncalibrated threshold rule (``detect`` with no config).

    python tests/benchmarks/uncalibrated_rule.py            # all sets, ~5 min on 2 cores
    python tests/benchmarks/uncalibrated_rule.py --quick    # the design set only, ~40 s

With no config, ``detect`` identifies the model from the log and sets each threshold to
``margin × the quantile of the log's block maxima`` of the detector's statistic after
warm-up (:func:`impactcli.detect.thresholds.uncalibrated_thresholds`). This script measures,
for the rule as shipped and for the earlier rule (1.5 × the 0.995-quantile of the samples):

* the margin each collision-free log needs (its statistic's maximum / the rule's level), on
  the product's detectors (adaptive, static_loading);
* collision-free logs with a product alarm after warm-up;
* contact logs with a product alarm between contacts (later than 1.5 s after a contact's
  end: release after-effects are left out) and contacts of ≥ 20 N caught (a product alarm
  from 20 ms before onset to 80 ms after it for impacts, to the contact's end otherwise).

Sets — all simulated with :mod:`impactcli.sim`, two arms (``assist_like``, ``heavy_geared``),
parameters drawn ±20 % by the seed, every log analysed exactly as ``detect LOG`` would:

* ``design`` (seeds 1001–1003): 5 collision-free motion families (triangles, FM triangles,
  point-to-point, multi-sines, multi-sines with an unknown payload) + impacts, pushes,
  clamps. The shipped margin is 1.25 × the worst margin this set needed, rounded.
* ``held-out`` (seeds 2001–2005): the same families, other robots and noise.
* ``long`` (seeds 3001–3002): the collision-free families at 10 min each.
* ``real``: the KUKA LWR4 recording of ``../shared/real_logs`` (no contacts), when present.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import warnings
from collections.abc import Iterable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from impactcli.detect.thresholds import (
    UNCALIBRATED_BLOCK_S,
    UNCALIBRATED_MARGIN,
    UNCALIBRATED_QUANTILE,
)

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))  # after impactcli's import: only ``tests`` comes from here
from tests.reference.thresholds import uncalibrated_thresholds  # noqa: E402

KUKA = REPO.parent / "shared" / "real_logs" / "kuka_lwr4" / "measurements_1.npz"
ARMS = ("assist_like", "heavy_geared")
FREE = {"free_triangle": 60.0, "free_fm_triangle": 60.0, "free_p2p": 90.0,
        "free_multisine": 120.0, "payload": 60.0}
CONTACT = {"impacts": None, "pushes": 60.0, "clamps": 60.0}
SETS: dict[str, tuple[tuple[int, ...], dict[str, float | None]]] = {
    "design": ((1001, 1002, 1003), {**FREE, **CONTACT}),
    "held-out": ((2001, 2002, 2003, 2004, 2005), {**FREE, **CONTACT}),
    "long": ((3001, 3002), dict.fromkeys(FREE, 600.0)),
}
PRODUCT = ("adaptive", "static_loading")
OLD_QUANTILE, OLD_MARGIN = 0.995, 1.5
AFTER_S = 1.5
MIN_FORCE_N = 20.0


def _old_level(s: np.ndarray) -> np.ndarray:
    return np.maximum(np.quantile(s, OLD_QUANTILE, axis=0), 1e-9)


def _summarise(name: str, arm: str, seed: int, t: np.ndarray, fs: float,
               stats: dict[str, np.ndarray], labels: list[tuple]) -> dict:
    """Margins needed and alarms/hits of both rules for one analysed log."""
    between = np.ones(len(t), bool)
    for a, b, *_ in labels:
        between &= ~((t >= a - 0.02) & (t <= b + AFTER_S))
    out: dict = {"name": name, "arm": arm, "seed": seed, "free": not labels and name != "clamps",
                 "need": {}, "alarm": {}, "hits": {}}
    dec = {"new": np.zeros(len(t), bool), "old": np.zeros(len(t), bool)}
    for d in PRODUCT:
        s = np.asarray(stats[d], dtype=np.float64)
        level = uncalibrated_thresholds(s, fs, margin=1.0).thresholds
        out["need"][d] = float(np.max(s[between] / level)) if between.any() else 0.0
        dec["new"] |= (s > UNCALIBRATED_MARGIN * level).any(axis=1)
        dec["old"] |= (s > OLD_MARGIN * _old_level(s)).any(axis=1)
    for rule, x in dec.items():
        out["alarm"][rule] = bool((x & between).any())
        hits = []
        for a, b, force, kind, _link in labels:
            if force < MIN_FORCE_N:
                continue
            end = a + 0.08 if kind == "impact" else b
            w = (t >= a - 0.02) & (t <= end)
            hits.append((kind, bool(x[w].any())))
        out["hits"][rule] = hits
    return out


def _simulated(job: tuple[str, str, int, float | None]) -> dict:
    warnings.simplefilter("ignore")
    from impactcli.sim.core import simulate
    from impactcli.sim.scenarios import scenario

    name, arm, seed, dur = job
    sim = simulate(scenario(name, arm, dur), seed=seed)
    k0, after = _after_warmup(sim.log, sim.robot)
    labels = [(e.start, e.end, e.peak_force, e.kind, e.link) for e in sim.labels.events]
    return _summarise(name, arm, seed, sim.log.time_s[k0:], sim.log.sample_rate_hz,
                      after, labels)


def _after_warmup(log: Any, robot: Any) -> tuple[int, dict[str, np.ndarray]]:
    """The first sample after the warm-up (0 when it covers the log) and each detector's
    threshold-free statistic from there, Table I defaults, model identified from the log."""
    from impactcli.run.collect import stats_in_memory

    st, rp, _ = stats_in_memory(log, robot=robot)
    k0 = rp.warmup.end_index if rp.warmup.end_index < log.n_samples - 10 else 0
    return k0, {d: s[k0:] for d, s in st.stats.items()}


def _real() -> dict:
    warnings.simplefilter("ignore")
    from impactcli.logs import read_log

    log = read_log(KUKA, channel_map="kuka_lwr4")
    k0, after = _after_warmup(log, None)
    return _summarise("kuka_lwr4", "real", 0, log.time_s[k0:], log.sample_rate_hz, after, [])


def _progress(it: Iterable[dict], n: int, label: str) -> list[dict]:
    out = []
    tty = sys.stderr.isatty()
    for i, x in enumerate(it, 1):
        out.append(x)
        if tty or i == n:
            print(f"\r  {label}: {i}/{n} logs", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    return out


def _table(rows_by_set: dict[str, list[dict]]) -> str:
    lines = [
        "| set | logs (collision-free + contact) | worst margin needed, collision-free "
        "(adaptive / static_loading) | collision-free logs alarming: shipped / old | "
        "contact logs alarming between contacts: shipped / old | contacts ≥ 20 N caught: "
        "shipped / old |",
        "|---|---|---|---|---|---|",
    ]
    for set_name, rows in rows_by_set.items():
        free = [r for r in rows if r["free"]]
        cont = [r for r in rows if not r["free"]]
        worst = [max((r["need"][d] for r in free), default=0.0) for d in PRODUCT]
        fa = {k: sum(r["alarm"][k] for r in free) for k in ("new", "old")}
        ca = {k: sum(r["alarm"][k] for r in cont) for k in ("new", "old")}
        hits = {k: [h for r in cont for _, h in r["hits"][k]] for k in ("new", "old")}
        lines.append(
            f"| {set_name} | {len(free)} + {len(cont)} | {worst[0]:.2f} / {worst[1]:.2f} | "
            f"{fa['new']}/{len(free)} / {fa['old']}/{len(free)} | "
            + (f"{ca['new']}/{len(cont)} / {ca['old']}/{len(cont)} | "
               f"{sum(hits['new'])}/{len(hits['new'])} / {sum(hits['old'])}/{len(hits['old'])} |"
               if cont else "— | — |"))
    return "\n".join(lines)


def _by_kind(rows: list[dict]) -> str:
    acc: dict[tuple[str, str], list[int]] = {}
    for r in rows:
        for kind, hit in r["hits"]["new"]:
            c = acc.setdefault((r["arm"], kind), [0, 0])
            c[0] += hit
            c[1] += 1
    return ", ".join(f"{arm} {kind} {h}/{n}" for (arm, kind), (h, n) in sorted(acc.items()))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="the design set only")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    sets = {"design": SETS["design"]} if a.quick else SETS
    rows_by_set: dict[str, list[dict]] = {}
    with ProcessPoolExecutor(a.jobs) as ex:
        for set_name, (seeds, scen) in sets.items():
            jobs = [(n, arm, s, d) for arm in ARMS for s in seeds for n, d in scen.items()]
            rows_by_set[set_name] = _progress(ex.map(_simulated, jobs), len(jobs), set_name)
    if not a.quick and KUKA.is_file():
        rows_by_set["real (KUKA LWR4)"] = [_real()]
    print(f"Uncalibrated rule shipped: {UNCALIBRATED_MARGIN:g} × the "
          f"{UNCALIBRATED_QUANTILE:g}-quantile of {UNCALIBRATED_BLOCK_S:g} s block maxima; "
          f"old: {OLD_MARGIN:g} × the {OLD_QUANTILE:g}-quantile of the samples.\n")
    print(_table(rows_by_set))
    for set_name, rows in rows_by_set.items():
        if any(not r["free"] for r in rows):
            print(f"\n{set_name}, contacts ≥ 20 N caught by the shipped rule: {_by_kind(rows)}")
    worst = {set_name: max(max(r["need"].values()) for r in rows if r["free"])
             for set_name, rows in rows_by_set.items()}
    print("\nworst margin needed by a collision-free log: "
          + ", ".join(f"{k} {v:.2f}" for k, v in worst.items()))
    print(f"\nmachine: {platform.platform()}, {platform.machine()}, {os.cpu_count()} CPUs; "
          f"python {platform.python_version()}; total {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
