"""The Rerun recording: read the .rrd back and check series, lanes, events and blueprint."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from impactcli.outputs.rerun import ELAPSED_TIMELINE, LOG_TIMELINE, write_rrd
from impactcli.result import DetectionResult
from impactcli.types import DETECTORS

from .fakes import fake_result

rr = pytest.importorskip("rerun")


@pytest.fixture(autouse=True)
def strict_rerun() -> Iterator[None]:
    """Dropped chunks fail loudly instead of warning."""
    old = rr.strict_mode()
    rr.set_strict_mode(True)
    yield
    rr.set_strict_mode(old)


def read_entities(path: Path) -> dict[str, dict[str, list[Any]]]:
    """Non-static rows per entity: column name → values (chunks concatenated, time-sorted)."""
    out: dict[str, dict[str, list[Any]]] = {}
    for ch in rr.chunk.RrdReader(path).store().stream():
        if ch.is_static:
            continue
        cols = ch.to_record_batch().to_pydict()
        dst = out.setdefault(ch.entity_path, {})
        for name, values in cols.items():
            dst.setdefault(name, []).extend(values)
    for cols in out.values():
        order = np.argsort(np.array([int(v.value) for v in cols[ELAPSED_TIMELINE]]), kind="stable")
        for name in cols:
            cols[name] = [cols[name][i] for i in order]
    return out


def static_entities(path: Path) -> set[str]:
    return {ch.entity_path for ch in rr.chunk.RrdReader(path).store().stream() if ch.is_static}


def elapsed_ns(cols: dict[str, list[Any]]) -> np.ndarray:
    return np.array([int(v.value) for v in cols[ELAPSED_TIMELINE]], dtype=np.int64)


def scalars(cols: dict[str, list[Any]]) -> np.ndarray:
    return np.array(cols["Scalars:scalars"], dtype=np.float64)


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> tuple[DetectionResult, Path]:
    res = fake_result()
    path = tmp_path_factory.mktemp("rrd") / "run.rrd"
    old = rr.strict_mode()
    rr.set_strict_mode(True)
    write_rrd(res, path)
    rr.set_strict_mode(old)
    return res, path


def test_series_are_full_length_on_both_timelines(written: tuple[DetectionResult, Path]) -> None:
    res, path = written
    mask = os.umask(0)
    os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask  # an ordinary file, not mkstemp's 0600
    ent = read_entities(path)
    t_ns = res.log.t_ns
    n = res.log.n_samples
    for j, joint in enumerate(res.log.joint_names):
        rms = ent[f"/joints/{joint}/rms"]
        np.testing.assert_array_equal(elapsed_ns(rms), t_ns - t_ns[0])
        log_clock = np.array([int(v.value) for v in rms[LOG_TIMELINE]], dtype=np.int64)
        np.testing.assert_array_equal(log_clock, t_ns)
        m = scalars(rms)
        assert m.shape == (n, 2)
        np.testing.assert_allclose(m[:, 0], res.signals["residual_rms"][:, j])
        np.testing.assert_allclose(m[:, 1], res.signals["threshold"][:, j])
        load = scalars(ent[f"/joints/{joint}/loading"])
        np.testing.assert_allclose(load[:, 0], res.signals["loading_statistic"][:, j])
        np.testing.assert_allclose(load[:, 1], res.thresholds[joint]["vL"])
        resid = scalars(ent[f"/joints/{joint}/residual"])
        np.testing.assert_allclose(resid[:, 0], res.signals["residual"][:, j])
        pos = scalars(ent[f"/joints/{joint}/position"])
        assert res.log.position_ref is not None
        np.testing.assert_allclose(pos[:, 0], res.log.position_ref[:, j])
        np.testing.assert_allclose(pos[:, 1], res.log.position[:, j])
    styled = static_entities(path)
    assert {f"/joints/{j}/{p}" for j in res.log.joint_names
            for p in ("rms", "loading", "residual", "position")} <= styled


def test_detections_as_markers_and_state_lanes(written: tuple[DetectionResult, Path]) -> None:
    res, path = written
    ent = read_entities(path)
    t_ns = res.log.t_ns
    plot_of = {"adaptive": "rms", "static_loading": "loading", "static_baseline": "residual"}
    n_markers = 0
    for j, joint in enumerate(res.log.joint_names):
        for det in DETECTORS:
            d = res.decisions[det][:, j]
            lane = ent[f"/detections/{joint}/{det}"]
            states = [s[0] for s in lane["StateChange:state"]]
            # replaying the transitions gives back the decision at every sample
            at = np.searchsorted(elapsed_ns(lane), t_ns - t_ns[0], side="right") - 1
            np.testing.assert_array_equal(np.array(states)[at] == "detected", d)
            markers = ent.get(f"/joints/{joint}/{plot_of[det]}/{det}")
            if not d.any():
                assert markers is None
                continue
            np.testing.assert_array_equal(elapsed_ns(markers), (t_ns - t_ns[0])[d])
            n_markers += int(d.sum())
        warm = ent[f"/detections/{joint}/warmup"]
        assert [s[0] for s in warm["StateChange:state"]] == ["warm-up", "running"]
        assert elapsed_ns(warm)[1] == pytest.approx(res.warmup_per_joint_s[joint] * 1e9, abs=4e6)
    assert n_markers > 0


def test_one_text_log_row_per_event(written: tuple[DetectionResult, Path]) -> None:
    res, path = written
    ev = read_entities(path)["/events"]
    assert len(ev["TextLog:text"]) == len(res.events)
    for e, text, level, t in zip(res.events, ev["TextLog:text"], ev["TextLog:level"],
                                 elapsed_ns(ev), strict=True):
        assert level == ["INFO" if e.in_warmup else "WARN"]
        assert e.detector in text[0]
        assert all(joint in text[0] for joint in e.joints)
        assert f"{e.peak_ratio:.2f}" in text[0]
        assert t == res.log.t_ns[e.i_start] - res.log.t_ns[0]


def test_default_blueprint_is_in_the_file(written: tuple[DetectionResult, Path]) -> None:
    res, path = written
    reader = rr.chunk.RrdReader(path)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1
    views: list[tuple[str, str]] = []
    timeline = None
    for ch in reader.store(store=reader.blueprints()[0]).stream():
        cols = ch.to_record_batch().to_pydict()
        if "ViewBlueprint:class_identifier" in cols:
            views.append((cols["ViewBlueprint:class_identifier"][0][0],
                          cols["ViewBlueprint:space_origin"][0][0]))
        if "TimePanelBlueprint:timeline" in cols:
            timeline = cols["TimePanelBlueprint:timeline"][0][0]
    assert timeline == ELAPSED_TIMELINE
    series = sorted(o for k, o in views if k == "TimeSeries")
    assert series == sorted(f"/joints/{j}/{p}" for j in res.log.joint_names
                            for p in ("rms", "loading", "residual", "position"))
    assert sorted(o for k, o in views if k == "StateTimeline") == sorted(
        f"/detections/{j}" for j in res.log.joint_names)
    assert any(k == "TextLog" for k, _ in views)


def test_rerun_cli_verifies_the_file(written: tuple[DetectionResult, Path]) -> None:
    _, path = written
    proc = subprocess.run([sys.executable, "-m", "rerun_cli", "rrd", "verify", str(path)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "without error" in proc.stdout + proc.stderr


def test_long_logs_are_decimated_keeping_peaks_and_event_windows(tmp_path: Path) -> None:
    res = fake_result(n=60_000, dt=0.001)  # 60 s at 1 kHz; events at 0.05, 4.0–4.1, 7.0–7.5 s
    spike_i = 40_000
    res.signals["residual"][spike_i, 1] = 25.0  # a one-sample spike far from any event
    path = tmp_path / "long.rrd"
    write_rrd(res, path, max_points=5_000, event_window_s=2.0)
    ent = read_entities(path)
    t_rel = res.log.t_ns - res.log.t_ns[0]
    in_window = np.zeros(res.log.n_samples, dtype=bool)
    for e in res.events:
        in_window |= (t_rel >= t_rel[e.i_start] - 2e9) & (t_rel <= t_rel[e.i_end] + 2e9)
    for j, joint in enumerate(res.log.joint_names):
        for plot, names in (("rms", ("residual_rms", "threshold")),
                            ("residual", ("residual", "filtered_residual"))):
            cols = ent[f"/joints/{joint}/{plot}"]
            t = elapsed_ns(cols)
            assert len(t) < res.log.n_samples / 3
            assert np.isin(t_rel[in_window], t).all(), "event windows must be full rate"
            m = scalars(cols)
            for k, name in enumerate(names):
                full = res.signals[name][:, j]
                assert m[:, k].max() == full.max() and m[:, k].min() == full.min()
    assert t_rel[spike_i] in elapsed_ns(ent["/joints/j2/residual"])


def test_no_half_written_file_on_failure(tmp_path: Path) -> None:
    res = fake_result()
    bad = dict(res.signals)
    bad["residual"] = bad["residual"][:10]  # wrong length: fails while logging
    broken = dataclasses.replace(res, signals=bad)
    path = tmp_path / "out" / "x.rrd"
    with pytest.raises(ValueError, match="'residual' has 10 samples"):
        write_rrd(broken, path)
    assert not path.exists()
    assert list(path.parent.iterdir()) == []


def test_module_import_does_not_import_rerun() -> None:
    code = ("import sys, impactcli.outputs.rerun, impactcli.cli.view; "
            "sys.exit(1 if 'rerun' in sys.modules else 0)")
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_no_reference_and_no_events(tmp_path: Path) -> None:
    res = fake_result()
    log = dataclasses.replace(res.log, position_ref=None, velocity_ref=None,
                              acceleration_ref=None)
    quiet = {d: np.zeros_like(v) for d, v in res.decisions.items()}
    res = dataclasses.replace(res, log=log, events=(), decisions=quiet)
    path = tmp_path / "quiet.rrd"
    write_rrd(res, path)
    ent = read_entities(path)
    assert "/events" not in ent
    assert not any(p.endswith(("/adaptive", "/static_loading", "/static_baseline"))
                   for p in ent if p.startswith("/joints/"))
    for j, joint in enumerate(res.log.joint_names):
        pos = scalars(ent[f"/joints/{joint}/position"])
        assert pos.shape == (res.log.n_samples, 1)
        np.testing.assert_allclose(pos[:, 0], res.log.position[:, j])
        lane = ent[f"/detections/{joint}/adaptive"]["StateChange:state"]
        assert [s[0] for s in lane] == ["clear"]
