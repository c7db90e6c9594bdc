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


def _cells(col: Any) -> list[Any]:
    """Each row of an Arrow array as a value that tells any two rows apart: integers for
    fixed-width numbers (a float's bits, so that NaN equals NaN), tuples of those for
    lists, Python values otherwise; None for a null."""
    import numpy as np
    import pyarrow as pa

    t = col.type
    if pa.types.is_list(t) or pa.types.is_large_list(t):
        inner = _cells(col.values)
        offs = col.offsets.to_numpy().tolist()
        nulls = col.is_null().to_numpy(zero_copy_only=False).tolist()
        return [None if nulls[i] else tuple(inner[offs[i]:offs[i + 1]])
                for i in range(len(col))]
    if pa.types.is_timestamp(t) or pa.types.is_duration(t):
        col = col.cast(pa.int64())
        t = col.type
    if col.null_count == 0 and (pa.types.is_integer(t) or pa.types.is_floating(t)):
        v = col.to_numpy()
        if v.dtype.kind == "f":
            v = v.view(np.int64 if v.itemsize == 8 else np.int32)
        return v.tolist()
    return col.to_pylist()


def rrd_rows(path: Path, *, everything: bool = False) -> dict[str, list[tuple[Any, ...]]]:
    """Every entity's rows in a Rerun recording (static ones apart, named ``static …``),
    each row its values in column order (:func:`_cells`: floats by their bits), sorted:
    what a recording holds, whatever its chunks. The blueprint's and the recording's
    properties (its start time) are left out unless ``everything``."""
    import rerun as rr

    out: dict[str, list[tuple[Any, ...]]] = {}
    for ch in rr.chunk.RrdReader(path).store().stream():
        batch = ch.to_record_batch()
        names = sorted(k for k in batch.schema.names
                       if "rowid" not in k.lower().replace("_", ""))
        rows = out.setdefault(("static " if ch.is_static else "") + ch.entity_path, [])
        cols = [_cells(batch.column(k)) for k in names]
        rows.extend(zip(*cols, strict=True) if cols else [])
    return {k: _sorted(v) for k, v in out.items()
            if everything or not (k.startswith("static /__properties") or "blueprint" in k)}


def _sorted(rows: list[tuple[Any, ...]]) -> list[tuple[Any, ...]]:
    try:
        return sorted(rows)
    except TypeError:  # a null beside a value in one column
        return sorted(rows, key=repr)


def motion_residual(pos: Any, fs: float, rng: Any) -> tuple[Any, Any]:
    """(r, u) of a synthetic arm moving along ``pos`` (n, J) [rad] at ``fs`` [Hz]: the
    evaluator's inputs u = (tanh(50 q'), q'') by backward differences, and a residual of
    Coulomb-like and inertial model error, white noise (``rng``) and an offset."""
    import numpy as np

    v = np.zeros_like(pos)
    v[1:] = np.diff(pos, axis=0) * fs
    acc = np.zeros_like(v)
    acc[1:] = np.diff(v, axis=0) * fs
    u = np.stack([np.tanh(50 * v), acc])
    r = 0.3 * np.tanh(50 * v) + 0.002 * acc + 0.03 * rng.standard_normal(pos.shape) + 0.2
    return r, u
