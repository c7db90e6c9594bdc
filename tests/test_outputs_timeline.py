"""Timeline JSON and signals Parquet from a synthetic result with known events."""

from __future__ import annotations

import json

import numpy as np

from impactcli.outputs.signals import read_signals, signal_groups, signals_schema
from impactcli.outputs.timeline import timeline_json, write_timeline
from impactcli.schema import load_schema

from .fakes import fake_result, write_fake_signals


def test_timeline_validates_and_counts(tmp_path) -> None:
    import jsonschema

    res = fake_result()
    p = tmp_path / "x.timeline.json"
    write_timeline(res, p)
    doc = json.loads(p.read_text())
    jsonschema.validate(doc, load_schema("timeline"))
    assert doc["summary"]["adaptive"] == {"events": 1, "in_warmup": 1}
    assert doc["summary"]["static_loading"] == {"events": 1, "in_warmup": 0}
    ev = next(e for e in doc["events"] if e["detector"] == "adaptive" and not e["in_warmup"])
    assert ev["joints"] == ["j2", "j1"]
    assert abs(ev["t_start"] - 4.0) < 0.004 and abs(ev["t_end"] - 4.1) < 0.004
    assert doc["input"]["t0_ns"] == 0 and doc["calibrated"] is False
    assert doc["replay"]["online_equivalent"] is False
    assert not list(tmp_path.glob("*.part"))


def test_timeline_is_deterministic() -> None:
    assert timeline_json(fake_result()) == timeline_json(fake_result())


def test_signals_roundtrip(tmp_path) -> None:
    """Written chunk by chunk (one row group each), read back whole or group by group."""
    res = fake_result()
    p = tmp_path / "x.signals.parquet"
    assert write_fake_signals(res, p, rows=1000) == 3
    names, meta, n_groups = signals_schema(p)
    assert n_groups == 3 and names[0] == "time"
    groups = list(signal_groups(p, ["time", "j1.residual"]))
    assert [len(g["time"]) for g in groups] == [1000, 1000, 500]
    assert set(groups[0]) == {"time", "j1.residual"}
    np.testing.assert_array_equal(np.concatenate([g["j1.residual"] for g in groups]),
                                  res.signals["residual"][:, 0])
    cols, meta2 = read_signals(p)
    assert meta2 == meta
    np.testing.assert_array_equal(cols["time"], res.log.time_s)
    np.testing.assert_array_equal(cols["j2.residual_rms"], res.signals["residual_rms"][:, 1])
    np.testing.assert_array_equal(cols["j1.static_loading"], res.decisions["static_loading"][:, 0])
    assert meta["impactcli.t0_ns"] == "0"
    expected = {"time"} | {f"{j}.{s}" for j in ("j1", "j2") for s in (
        "torque", "residual", "filtered_residual", "dynamic_threshold", "residual_rms", "threshold",
        "loading_statistic", "adaptive", "static_loading", "static_baseline")}
    assert set(cols) == expected
