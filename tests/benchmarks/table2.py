"""Reproduce the README's Table II (``impactcli sensitivity``) and time it.

    python tests/benchmarks/table2.py [--quick] [--jobs N] [--markdown PATH] [--json PATH]

Runs the same study as ``impactcli sensitivity --jobs N`` (default: every variant of
:data:`impactcli.study.spec.VARIANTS`, 15-min soak runs), prints the text tables, then a
small table with the machine (platform, CPU count), the simulated soak hours, the number
of impacts and the wall time.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

from impactcli.cli.sensitivity import task_runner
from impactcli.study.runner import run_study
from impactcli.study.spec import VARIANTS, StudySpec
from impactcli.study.tables import format_markdown, format_text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the tests' small study")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--markdown", type=Path, default=None)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    variants = tuple(VARIANTS)
    spec = StudySpec.quick() if args.quick else StudySpec(variants=variants)
    t0 = time.monotonic()
    summary = run_study(spec, runner=task_runner(args.jobs))
    wall = time.monotonic() - t0
    summary["wall_time_s"] = round(wall, 1)
    cmd = ("impactcli sensitivity --jobs " + str(args.jobs)
           + "".join(f" --arm {v}" for v in spec.variants) + (" --quick" if args.quick else ""))
    summary["command"] = cmd
    sys.stdout.write(format_text(summary))
    if args.markdown:
        args.markdown.write_text(format_markdown(summary, cmd), encoding="utf-8")
    if args.json:
        args.json.write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    impacts = sum(v["cases"]["n_contacts"] for v in summary["variants"])
    soak_h = sum(v["soak"]["hours_after_warmup"] for v in summary["variants"])
    rows = [("machine", "cpus", "jobs", "variants", "impacts", "soak h", "wall s"),
            (platform.platform(), str(os.cpu_count()), str(args.jobs),
             str(len(spec.variants)), str(impacts), f"{soak_h:.2f}", f"{wall:.0f}")]
    w = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for r in rows:
        print("  ".join(c.ljust(x) for c, x in zip(r, w, strict=True)))


if __name__ == "__main__":
    main()
