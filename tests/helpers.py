"""Helpers the tests share: a sample log's threshold-free pass, a log that goes bad midway,
and a Rerun recording's rows (heavy imports inside the functions)."""

from __future__ import annotations

import gzip
import warnings
from pathlib import Path
from typing import Any

import pytest

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def assist_impacts_pass() -> tuple[Any, Any, Any, Any]:
    """sample_logs' assist_impacts through the replay's threshold-free pass with its arm's
    config: (the log, its joints as the plan keeps them; the config; the pass's statistics;
    the adaptive evaluator's inputs). Skips when the CSV copies are absent."""
    from impactcli.config import load_config
    from impactcli.errors import ImpactWarning
    from impactcli.logs import read_log
    from impactcli.logs.robot_files import read_robot
    from impactcli.run.collect import stats_in_memory

    from .reference.adaptive import threshold_inputs

    csv = SAMPLES / "csv"
    if not (csv / "assist_impacts.csv.gz").exists():  # pragma: no cover - trimmed checkout
        pytest.skip("sample_logs/csv is absent")
    robot = read_robot(csv / "assist_impacts.robot.json")
    cfg = load_config(SAMPLES / "assist_like.config.toml")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        log = read_log(csv / "assist_impacts.csv.gz", robot=robot)
        st, _, plan = stats_in_memory(log, config=cfg, robot=robot)
        log = log.select(plan.joints)
        inputs = threshold_inputs(log, cfg.adaptive)
    return log, cfg, st, inputs


def bad_midway_csv(folder: Path, row: int = 15000) -> Path:
    """A copy of sample_logs' assist_impacts whose row ``row`` holds a cell that is not a
    number (a log that goes bad far into the file)."""
    with gzip.open(SAMPLES / "csv" / "assist_impacts.csv.gz", "rt") as f:
        lines = f.read().splitlines(keepends=True)
    cells = lines[row].split(",")
    cells[2] = "oops"
    lines[row] = ",".join(cells)
    bad = folder / "bad.csv"
    bad.write_text("".join(lines))
    return bad


def csv_with_gap(src: Path, dst: Path, drop: slice) -> int:
    """The CSV ``src`` (gzip) written to ``dst`` without the rows of ``drop`` (a time gap);
    returns the gap's first row."""
    with gzip.open(src, "rt") as f:
        lines = f.read().splitlines(keepends=True)
    body = lines[1:]
    del body[drop]
    dst.write_text(lines[0] + "".join(body))
    return int(drop.start)


def rrd_rows(path: Path, *, everything: bool = False) -> dict[str, list[tuple[str, ...]]]:
    """Every entity's rows in a Rerun recording (static ones apart, named ``static …``),
    each row the repr of its values, sorted: what a recording holds, whatever its chunks.
    The blueprint's and the recording's properties (its start time) are left out unless
    ``everything``."""
    import rerun as rr

    out: dict[str, list[tuple[str, ...]]] = {}
    for ch in rr.chunk.RrdReader(path).store().stream():
        cols = ch.to_record_batch().to_pydict()
        names = sorted(k for k in cols if "rowid" not in k.lower().replace("_", ""))
        rows = out.setdefault(("static " if ch.is_static else "") + ch.entity_path, [])
        for i in range(len(cols[names[0]]) if names else 0):
            rows.append(tuple(repr(cols[k][i]) for k in names))
    return {k: sorted(v) for k, v in out.items()
            if everything or not (k.startswith("static /__properties") or "blueprint" in k)}
