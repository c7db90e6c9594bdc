"""What changed in detection's answers from a release (or any commit), on the sample logs.

Run: ``python tests/benchmarks/release_diff.py [--release REF] [--config none|sample]
[--formats csv mcap] [--jobs N] [--keep DIR]``.

Each sample log (sample_logs/csv, sample_logs/mcap) is detected by REF's CLI (a temporary git
worktree) and by this checkout's, ``detect LOG [--config C] --signals -o OUT``, one fresh
process per log with that tree first on the import path, on the same files (named relative
to sample_logs/, so the Parquet's recorded input path is the same too). ``--config sample``:
each tree uses its own sample config of the log's arm (a regenerated config shows); ``none``:
the model identified from the log and thresholds from its statistics. Printed per log:
whether the timeline JSON (absolute paths normalised) and the signals Parquet are the same
bytes, then the events and incidents of both (the same when their detectors, joints, times,
links, contact types and forces agree) and the largest relative difference of the events'
peak ratios, the incidents' forces and the thresholds. Exit 0 when every log is the same
bytes, 1 otherwise.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "sample_logs"
RELEASE_COMMIT = "504e5ae194b6f66afa8778b2583a1a49010abbe7"   # the tag v0.1.0
SUFFIX = {"csv": ".csv.gz", "mcap": ".mcap"}
ARM_CONFIG = {"assist": "assist_like.config.toml", "heavy": "heavy_geared.config.toml"}

# argv: TREE detect ... ; TREE goes first on the import path, then the CLI runs as installed
_MAIN = ("import sys; sys.path.insert(0, sys.argv.pop(1)); "
         "from impactcli.cli import main; main(prog_name='impactcli')")


def _logs(formats: list[str]) -> list[str]:
    """Sample logs relative to sample_logs/, e.g. ``csv/assist_clamps.csv.gz``."""
    return [f"{fmt}/{p.name}" for fmt in formats
            for p in sorted((SAMPLES / fmt).glob("*" + SUFFIX[fmt]))]


def _normalise(text: str, tree: Path) -> str:
    for path, name in sorted(((str(SAMPLES), "<SAMPLES>"), (str(tree), "<TREE>")),
                             key=lambda x: -len(x[0])):
        text = re.sub(re.escape(path) + r"(?![\w.-])", name, text)
    return text


def _detect(tree: Path, log: str, config: str, out: Path) -> dict[str, Any]:
    """Run ``tree``'s ``detect`` on one log → its normalised timeline, Parquet sha256, exit."""
    stem = Path(log).name.split(".")[0]
    args = ["detect", log, "--signals", "-o", str(out)]
    if config == "sample":
        cfg = tree / "sample_logs" / ARM_CONFIG[stem.split("_")[0]]
        args[2:2] = ["--config", str(cfg if cfg.is_file() else SAMPLES / cfg.name)]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(tree), *filter(None, [os.environ.get("PYTHONPATH")])]))
    p = subprocess.run([sys.executable, "-c", _MAIN, str(tree), *args], cwd=SAMPLES, env=env,
                       capture_output=True, encoding="utf-8", check=False)
    res: dict[str, Any] = {"exit": p.returncode,
                           "error": _normalise((p.stderr.strip().splitlines() or [""])[-1], tree)}
    timeline, parquet = out / f"{stem}.timeline.json", out / f"{stem}.signals.parquet"
    if p.returncode == 0 and timeline.is_file():
        res["text"] = _normalise(timeline.read_text("utf-8"), tree)
        res["timeline"] = json.loads(res["text"])
        res["parquet"] = (hashlib.sha256(parquet.read_bytes()).hexdigest()
                          if parquet.is_file() else None)
    return res


def _answers(tree: Path, logs: list[str], config: str, out: Path, jobs: int
             ) -> dict[str, dict[str, Any]]:
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        done = pool.map(lambda log: _detect(tree, log, config, out / Path(log).parent),
                        logs)
        return dict(zip(logs, done, strict=True))


def _rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-300)


def _first_leaf(a: Any, b: Any, path: str) -> str | None:
    """The first JSON path where ``a`` and ``b`` differ, with both values."""
    if isinstance(a, dict) and isinstance(b, dict):
        keys = sorted(set(a) | set(b))
        return next(filter(None, (_first_leaf(a.get(k), b.get(k), f"{path}.{k}")
                                  for k in keys)), None)
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return next(filter(None, (_first_leaf(u, v, f"{path}[{i}]")
                                  for i, (u, v) in enumerate(zip(a, b, strict=True)))), None)
    return None if a == b else f"{path}: {json.dumps(a)[:70]} → {json.dumps(b)[:70]}"


def _what_differs(a: dict[str, Any], b: dict[str, Any]) -> str:
    """The timeline's top-level fields that differ, and the first difference outside the
    embedded config (the config's own when only it differs)."""
    keys = [k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
    first = next((k for k in keys if k != "config"), keys[0] if keys else "")
    return f"{', '.join(keys)}; first: {_first_leaf(a.get(first), b.get(first), first)}"


def _row(log: str, a: dict[str, Any], b: dict[str, Any]) -> tuple[str, bool, str]:
    """One table row, whether the two answers are the same bytes, what differs."""
    if "timeline" not in a or "timeline" not in b:
        err = " / ".join(f"exit {x['exit']}: {x['error'][:80]}" for x in (a, b))
        return f"| {log} | {err} |", (a["exit"], a["error"]) == (b["exit"], b["error"]), ""
    ta, tb = a["timeline"], b["timeline"]
    same_bytes = a["text"] == b["text"]
    same_parquet = a["parquet"] == b["parquet"]
    ea = [(e["detector"], e["t_start"], e["t_end"], e["joints"]) for e in ta["events"]]
    eb = [(e["detector"], e["t_start"], e["t_end"], e["joints"]) for e in tb["events"]]
    ia = [(i["t_start"], i["link"], i["force_n"], i["contact"]) for i in ta["incidents"]]
    ib = [(i["t_start"], i["link"], i["force_n"], i["contact"]) for i in tb["incidents"]]
    dr = max([_rel(x["peak_ratio"], y["peak_ratio"])
              for x, y in zip(ta["events"], tb["events"], strict=False)] or [0.0])
    df = max([_rel(x[2], y[2]) for x, y in zip(ia, ib, strict=False) if x[2] and y[2]]
             or [0.0])
    dt = max([_rel(ta["thresholds"][j][k], tb["thresholds"][j][k])
              for j in ta["thresholds"] for k in ta["thresholds"][j]
              if isinstance(ta["thresholds"][j][k], float)
              and isinstance(tb["thresholds"].get(j, {}).get(k), float)] or [0.0])
    row = (f"| {log} | {'same' if same_bytes else 'DIFFER'} | "
           f"{'same' if same_parquet else 'DIFFER'} | {len(ea)}/{len(eb)} | {ea == eb} | "
           f"{len(ia)}/{len(ib)} | {ia == ib} | {dr:.1e} | {df:.1e} | {dt:.1e} |")
    return row, same_bytes and same_parquet, "" if same_bytes else _what_differs(ta, tb)


def _describe(ref: str) -> str:
    p = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", ref],
                       capture_output=True, text=True, check=False)
    return p.stdout.strip() or ref


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--release", default="v0.1.0", help="a tag, branch or commit")
    ap.add_argument("--config", choices=["none", "sample"], default="none")
    ap.add_argument("--formats", nargs="+", choices=list(SUFFIX), default=list(SUFFIX))
    ap.add_argument("--jobs", type=int, default=1, help="processes at a time, per tree")
    ap.add_argument("--keep", type=Path, help="keep both trees' outputs in this folder")
    args = ap.parse_args()
    ref = args.release
    if ref == "v0.1.0" and subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "-q", "--verify", "refs/tags/v0.1.0"],
            capture_output=True, check=False).returncode:
        ref = RELEASE_COMMIT
    logs = _logs(args.formats)
    with tempfile.TemporaryDirectory() as tmp:
        out = args.keep.resolve() if args.keep else Path(tmp)
        wt = Path(tmp) / "release"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(wt), ref],
                       check=True, capture_output=True)
        try:
            old = _answers(wt, logs, args.config, out / "release", args.jobs)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(wt)],
                           check=False, capture_output=True)
        new = _answers(ROOT, logs, args.config, out / "now", args.jobs)
    dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--",
                            "impactcli", "schemas", "sample_logs"],
                           capture_output=True, text=True, check=False).stdout.strip()
    print(f"release {args.release} ({_describe(ref)}) vs this checkout ({_describe('HEAD')}"
          f"{', uncommitted changes' if dirty else ''}), config: {args.config}, "
          f"formats: {' '.join(args.formats)}")
    print("| log | timeline bytes | parquet | events (release/now) | same | incidents | same "
          "| peak ratio | force | thresholds |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    same, notes = 0, []
    for log in logs:
        row, ok, what = _row(log, old[log], new[log])
        print(row)
        same += ok
        notes += [f"  {log}: {what}"] if what else []
    print(f"{same} of {len(logs)} logs: the same timeline and Parquet bytes")
    if notes:
        print("timeline fields that differ (release → now):")
        print("\n".join(notes))
    return 0 if same == len(logs) else 1


if __name__ == "__main__":
    sys.exit(main())
