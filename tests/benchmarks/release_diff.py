"""What changed in detection's answers from a release, on the sample logs.

Run: ``python tests/benchmarks/release_diff.py [--release v0.1.0] [--config none|sample]``.

Each bundled sample CSV is replayed by this code and by the release's (a git worktree of
``--release``, imported in a fresh process), without a config (the model identified from
the log, thresholds from its own statistics) or with the sample config of its arm. Printed
per log: the events and incidents of both (the same when their detectors, joints, times,
links, contact types and forces agree), and the largest relative difference of the
events' peak ratios, the incidents' forces and the thresholds.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RELEASE_COMMIT = "504e5ae194b6f66afa8778b2583a1a49010abbe7"   # the tag v0.1.0

_RUN = r"""
import glob, json, sys, warnings
sys.path.insert(0, sys.argv[1])
warnings.simplefilter("ignore")
from impactcli.config import load_config
from impactcli.io import read_log
from impactcli.pipeline import analyze
out = {}
for p in sorted(glob.glob(sys.argv[2] + "/csv/*.csv.gz")):
    name = p.split("/")[-1]
    cfg = None
    if sys.argv[3] == "sample":
        arm = "assist_like" if name.startswith("assist") else "heavy_geared"
        cfg = load_config(sys.argv[2] + f"/{arm}.config.toml")
    r = analyze(read_log(p), config=cfg, read_options={})
    out[name] = {
        "events": [[e.detector, e.t_start, e.t_end, list(e.joints), e.peak_ratio]
                   for e in r.events],
        "incidents": [[i.t_start, i.link, i.force_n, i.contact] for i in r.incidents],
        "thresholds": r.thresholds}
json.dump(out, sys.stdout)
"""


def _answers(code: Path, config: str) -> dict:
    p = subprocess.run([sys.executable, "-c", _RUN, str(code), str(ROOT / "sample_logs"),
                        config], capture_output=True, text=True, check=True,
                       cwd=tempfile.gettempdir())
    return json.loads(p.stdout)


def _rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-300)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--release", default="v0.1.0")
    ap.add_argument("--config", choices=["none", "sample"], default="none")
    args = ap.parse_args()
    ref = args.release
    if ref == "v0.1.0" and subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "-q", "--verify", "refs/tags/v0.1.0"],
            capture_output=True, check=False).returncode:
        ref = RELEASE_COMMIT
    with tempfile.TemporaryDirectory() as tmp:
        wt = Path(tmp) / "release"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(wt), ref],
                       check=True, capture_output=True)
        try:
            old = _answers(wt, args.config)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(wt)],
                           check=False, capture_output=True)
    new = _answers(ROOT, args.config)
    print(f"release {args.release} vs this code, config: {args.config}")
    print("| log | events (release/now) | same | incidents | same | peak ratio | force "
          "| thresholds |")
    print("|---|---|---|---|---|---|---|---|")
    for name, a in old.items():
        b = new[name]
        ev_same = [(e[0], e[1], e[2], e[3]) for e in a["events"]] == \
            [(e[0], e[1], e[2], e[3]) for e in b["events"]]
        inc_same = [(i[0], i[1], i[2], i[3]) for i in a["incidents"]] == \
            [(i[0], i[1], i[2], i[3]) for i in b["incidents"]]
        dr = max([_rel(x[4], y[4])
                  for x, y in zip(a["events"], b["events"], strict=False)] or [0.0])
        df = max([_rel(x[2], y[2]) for x, y in zip(a["incidents"], b["incidents"],
                                                       strict=False)
                  if x[2] and y[2]] or [0.0])
        dt = max(_rel(a["thresholds"][j][k], b["thresholds"][j][k])
                 for j in a["thresholds"] for k in a["thresholds"][j])
        print(f"| {name} | {len(a['events'])}/{len(b['events'])} | {ev_same} | "
              f"{len(a['incidents'])}/{len(b['incidents'])} | {inc_same} | {dr:.1e} | "
              f"{df:.1e} | {dt:.1e} |")


if __name__ == "__main__":
    main()
