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
import pyarrow as pa
import pytest

from impactcli.outputs.rerun_blueprint import ELAPSED_TIMELINE, LOG_TIMELINE
from impactcli.types import DETECTORS, DetectionResult

from .fakes import fake_result
from .fakes import write_fake_rrd as write_rrd
from .helpers import rrd_rows

rr = pytest.importorskip("rerun")


@pytest.fixture(autouse=True)
def strict_rerun() -> Iterator[None]:
    """Dropped chunks fail loudly instead of warning."""
    old = rr.strict_mode()
    rr.set_strict_mode(True)
    yield
    rr.set_strict_mode(old)


def test_rows_tell_recordings_apart(tmp_path: Path) -> None:
    """rrd_rows, what the chunking tests compare: the same run gives the same rows (a NaN
    sample equal to itself), one sample changed by one bit does not."""
    res = fake_result(n=600)
    res.signals["threshold"][100, 0] = np.nan
    for name in ("a", "b"):
        write_rrd(res, tmp_path / f"{name}.rrd", rows=97, max_points=10_000)
    a = rrd_rows(tmp_path / "a.rrd")
    assert a == rrd_rows(tmp_path / "b.rrd")
    res.signals["threshold"][300, 1] = np.nextafter(0.3, 1.0)
    write_rrd(res, tmp_path / "c.rrd", rows=97, max_points=10_000)
    c = rrd_rows(tmp_path / "c.rrd")
    assert a.keys() == c.keys()
    assert [k for k in a if a[k] != c[k]] == ["/joints/j2/rms"]  # statistic and threshold


def read_entities(path: Path) -> dict[str, dict[str, list[Any]]]:
    """Non-static rows per entity: column name → values (chunks concatenated, time-sorted;
    the timelines as integer nanoseconds)."""
    out: dict[str, dict[str, list[Any]]] = {}
    for ch in rr.chunk.RrdReader(path).store().stream():
        if ch.is_static:
            continue
        batch = ch.to_record_batch()
        dst = out.setdefault(ch.entity_path, {})
        for name, col in zip(batch.schema.names, batch.columns, strict=True):
            timeline = pa.types.is_timestamp(col.type) or pa.types.is_duration(col.type)
            values = col.cast(pa.int64()) if timeline else col  # the timelines in ns
            dst.setdefault(name, []).extend(values.to_pylist())
    for cols in out.values():
        order = np.argsort(np.array(cols[ELAPSED_TIMELINE]), kind="stable")
        for name in cols:
            cols[name] = [cols[name][i] for i in order]
    return out


def static_entities(path: Path) -> set[str]:
    return {ch.entity_path for ch in rr.chunk.RrdReader(path).store().stream() if ch.is_static}


def elapsed_ns(cols: dict[str, list[Any]]) -> np.ndarray:
    return np.array(cols[ELAPSED_TIMELINE], dtype=np.int64)


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
        log_clock = np.array(rms[LOG_TIMELINE], dtype=np.int64)
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


def _boundary(u: Any, i: int) -> tuple[str, Any]:
    """(kind, value) of element ``i`` of a TimeRangeBoundary dense union array."""
    code = u.type_codes[i].as_py()
    child = list(u.type.type_codes).index(code)
    return u.type[child].name, u.field(child)[u.offsets[i].as_py()].as_py()


def _ranges(st: Any) -> list[tuple[tuple[str, Any], tuple[str, Any]]]:
    """The (start, end) boundaries of each element of a struct<start, end> array."""
    return [(_boundary(st.field("start"), i), _boundary(st.field("end"), i))
            for i in range(len(st))]


def read_blueprint(path: Path) -> dict[str, dict[str, Any]]:
    """Per view id: class, origin, name, contents, x-axis view range and visible time ranges
    (timeline → (start, end)) as the SDK reads them back from the file's blueprint."""
    reader = rr.chunk.RrdReader(path)
    assert len(reader.blueprints()) == 1
    views: dict[str, dict[str, Any]] = {}
    for ch in reader.store(store=reader.blueprints()[0]).stream():
        parts = ch.entity_path.strip("/").split("/")
        if parts[0] != "view":
            continue
        v = views.setdefault(parts[1], {})
        batch = ch.to_record_batch()
        cols = batch.to_pydict()
        if "ViewBlueprint:class_identifier" in cols:
            v["class"] = cols["ViewBlueprint:class_identifier"][0][0]
            v["origin"] = cols["ViewBlueprint:space_origin"][0][0]
            v["name"] = cols.get("ViewBlueprint:display_name", [[None]])[0][0]
        if "ViewContents:query" in cols:
            v["contents"] = list(cols["ViewContents:query"][0])
        if "TimeAxis:view_range" in cols:
            v["view_range"] = _ranges(batch.column("TimeAxis:view_range").values)[0]
        if "VisibleTimeRanges:ranges" in cols:
            lst = batch.column("VisibleTimeRanges:ranges").values
            rng = _ranges(lst.field("range"))
            v["time_ranges"] = {lst.field("timeline")[i].as_py(): rng[i] for i in range(len(lst))}
    return views


def _time_panel_timeline(path: Path) -> str | None:
    reader = rr.chunk.RrdReader(path)
    for ch in reader.store(store=reader.blueprints()[0]).stream():
        cols = ch.to_record_batch().to_pydict()
        if "TimePanelBlueprint:timeline" in cols:
            return str(cols["TimePanelBlueprint:timeline"][0][0])
    return None


def assert_whole_log_in_view(path: Path, duration_s: float) -> dict[str, dict[str, Any]]:
    """Every plot and lane of the default blueprint opens on [0, duration] on
    time_since_start (absolute bounds: not a window that follows the time cursor)."""
    whole = (("Absolute", 0), ("Absolute", round(duration_s * 1e9)))
    views = read_blueprint(path)
    timed = [v for v in views.values() if v.get("class") in ("TimeSeries", "StateTimeline")]
    assert timed
    for v in timed:
        assert v.get("view_range") == whole, v
        assert v.get("time_ranges") == {ELAPSED_TIMELINE: whole}, v
    assert _time_panel_timeline(path) == ELAPSED_TIMELINE
    return views


def test_default_blueprint_is_in_the_file(written: tuple[DetectionResult, Path]) -> None:
    res, path = written
    reader = rr.chunk.RrdReader(path)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1
    views = assert_whole_log_in_view(path, res.log.duration_s)
    by_class: dict[str, list[str]] = {}
    for v in views.values():
        if "class" in v:
            by_class.setdefault(v["class"], []).append(v["origin"])
    assert sorted(by_class["TimeSeries"]) == sorted(
        ["/incidents/force"] + [f"/joints/{j}/{p}" for j in res.log.joint_names
                                for p in ("rms", "loading", "residual", "position")])
    assert sorted(by_class["StateTimeline"]) == sorted(
        ["/incidents"] + [f"/detections/{j}" for j in res.log.joint_names])
    (log_view,) = [v for v in views.values() if v.get("class") == "TextLog"]
    # the events panel lists every event and every incident (a text-log view shows all
    # rows of its entities whatever the time cursor)
    assert {"/incidents", "/events/**"} <= set(log_view["contents"])
    (lane,) = [v for v in views.values() if v.get("origin") == "/incidents"]
    assert lane["contents"] == ["/incidents/contact"]


def test_plot_colours_tell_statistic_threshold_and_detectors_apart(
        written: tuple[DetectionResult, Path]) -> None:
    res, path = written
    styles: dict[str, dict[str, list[Any]]] = {}
    for ch in rr.chunk.RrdReader(path).store().stream():
        if ch.is_static:
            styles[ch.entity_path] = ch.to_record_batch().to_pydict()
    for joint in res.log.joint_names:
        root = f"/joints/{joint}"
        lane_colors = {}
        for det in DETECTORS:
            cfg = styles[f"/detections/{joint}/{det}"]
            values = list(cfg["StateConfiguration:values"][0])
            lane_colors[det] = cfg["StateConfiguration:colors"][0][values.index("detected")]
        assert len(set(lane_colors.values())) == len(DETECTORS)  # one colour per detector
        for plot, det in (("rms", "adaptive"), ("loading", "static_loading"),
                          ("residual", "static_baseline")):
            series = list(styles[f"{root}/{plot}"]["SeriesLines:colors"][0])
            assert len(set(series)) == len(series), (plot, series)  # statistic vs threshold
            assert lane_colors[det] not in series, (plot, det)
            markers = styles.get(f"{root}/{plot}/{det}")  # only where the detector fired
            if markers is not None:
                assert markers["SeriesPoints:colors"][0][0] == lane_colors[det]
            others = [c for d, c in lane_colors.items() if d != det]
            assert not set(series) & set(others), (plot, "a line has another detector's colour")


def make_incidents(res: DetectionResult) -> tuple[Any, ...]:
    """Incidents on fake_result's events: one in warm-up (no link, no force), the 4.0 s
    adaptive event (link 2, at least 12.5 N, transient), the 7.0 s loading event (link 1,
    quasi-static, no force)."""
    from impactcli.detect.incidents import Incident

    ev = res.events
    def inc(e: Any, link: int | None, force: float | None, contact: str, k: int) -> Incident:
        return Incident(e.t_start, e.t_end, e.i_start, e.i_end, (e.detector,), e.joints, link,
                        force, "test", contact, dict(e.peak_residual), e.in_warmup, None, (k,))
    return (inc(ev[0], None, None, "unknown", 0),
            dataclasses.replace(inc(ev[1], 2, 12.5, "transient", 1), force_at_least=True),
            inc(ev[2], 1, None, "quasi_static", 2))


def test_incident_track_holds_one_entry_per_incident(tmp_path: Path) -> None:
    res = fake_result()
    res = dataclasses.replace(res, incidents=make_incidents(res))
    path = tmp_path / "inc.rrd"
    write_rrd(res, path)
    ent = read_entities(path)
    t0 = res.log.t_ns[0]
    # one row per incident, at its start, carrying link, force and contact type as fields
    rows = ent["/incidents"]
    assert len(rows["TextLog:text"]) == len(res.incidents)
    assert [int(x[0]) for x in rows["index"]] == [1, 2, 3]
    assert [x[0] for x in rows["link"]] == [i.link for i in res.incidents]
    assert [x[0] for x in rows["force_n"]] == [i.force_n for i in res.incidents]
    assert [x[0] for x in rows["force_at_least"]] == [False, True, False]
    assert [x[0] for x in rows["contact"]] == [i.contact for i in res.incidents]
    assert [x[0] for x in rows["in_warmup"]] == [True, False, False]
    np.testing.assert_allclose([x[0] for x in rows["t_end_s"]], [i.t_end for i in res.incidents])
    np.testing.assert_array_equal(elapsed_ns(rows),
                                  [res.log.t_ns[i.i_start] - t0 for i in res.incidents])
    texts = [x[0] for x in rows["TextLog:text"]]
    assert "link 2" in texts[1] and "≳12.5 N" in texts[1] and "transient" in texts[1]
    assert "link unknown" in texts[0] and "force unknown" in texts[0]
    assert [x[0] for x in rows["TextLog:level"]] == ["INFO", "WARN", "WARN"]
    # the annotated spans: each incident labelled from its first to after its last sample
    lane = ent["/incidents/contact"]
    states = [s[0] for s in lane["StateChange:state"]]
    assert states == ["no contact", "#1 link ? · force ? · unknown (warm-up)", "no contact",
                      "#2 link 2 · ≳12.5 N · transient", "no contact",
                      "#3 link 1 · force ? · quasi_static", "no contact"]
    t = elapsed_ns(lane)
    for k, inc in enumerate(res.incidents):
        at = states.index(states[2 * k + 1])
        assert t[at] == res.log.t_ns[inc.i_start] - t0
        assert t[at + 1] == res.log.t_ns[inc.i_end + 1] - t0
    # force markers only where a force is known
    force = ent["/incidents/force"]
    assert scalars(force).ravel().tolist() == [12.5]
    assert elapsed_ns(force).tolist() == [res.log.t_ns[res.incidents[1].i_start] - t0]
    # every incident lies inside the default view
    assert_whole_log_in_view(path, res.log.duration_s)
    assert all(0 <= i.t_start <= i.t_end <= res.log.duration_s for i in res.incidents)
    assert "| 2 | 4.000 |" in next(
        ch.to_record_batch().to_pydict()["TextDocument:text"][0][0]
        for ch in rr.chunk.RrdReader(path).store().stream() if ch.entity_path == "/run/info")


def test_sample_log_view_covers_every_incident(tmp_path: Path) -> None:
    """The shipped ASSIST-like impacts log (72.7 s, 15 impacts), replayed as detect --rerun
    replays it: the default view spans the whole log, and the incident track lists every
    incident of the run."""
    import warnings

    from impactcli.run.job import run_log_from_paths as stream_file

    root = Path(__file__).resolve().parents[1] / "sample_logs"
    log = root / "csv" / "assist_impacts.csv.gz"
    if not log.is_file():
        pytest.skip("sample logs not present")
    path = tmp_path / "impacts.rrd"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res, _ = stream_file(str(log), config_path=str(root / "assist_like.config.toml"),
                             rrd_path=path)
    assert len(res.counted_incidents()) == 15
    assert_whole_log_in_view(path, res.log.duration_s)
    rows = read_entities(path)["/incidents"]
    assert len(rows["TextLog:text"]) == len(res.incidents)
    assert [x[0] for x in rows["link"]] == [i.link for i in res.incidents]
    assert [x[0] for x in rows["contact"]] == [i.contact for i in res.incidents]
    np.testing.assert_allclose([x[0] for x in rows["force_n"]],
                               [i.force_n for i in res.incidents])
    t = elapsed_ns(rows) / 1e9
    assert t.min() >= 0 and t.max() <= res.log.duration_s


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
    broken = dataclasses.replace(res, thresholds={"j1": {"vL": "?"}})  # fails while logging
    path = tmp_path / "out" / "x.rrd"
    with pytest.raises(ValueError, match="format code"):
        write_rrd(broken, path)
    assert not path.exists()
    assert list(path.parent.iterdir()) == []


def test_the_recording_whatever_the_chunks(tmp_path: Path) -> None:
    """Fed in one chunk or in chunks of any size (envelope buckets, event windows, marker
    runs and lane states across chunk boundaries), the writer records the same rows."""
    res = fake_result(n=60_000, dt=0.001)
    res = dataclasses.replace(res, incidents=make_incidents(res))
    opts = {"max_points": 5_000, "event_window_s": 0.5, "recording_id": "same"}
    want = None
    for rows in (60_000, 997, 4096, 1):
        if rows == 1:  # one sample a chunk: on a short log
            res = fake_result(n=600, dt=0.004)
            opts["max_points"] = 100
            want = None
            for r in (600, 1):
                write_rrd(res, tmp_path / f"s{r}.rrd", rows=r, **opts)
                got = rrd_rows(tmp_path / f"s{r}.rrd")
                want = got if want is None else want
                assert got == want
            continue
        write_rrd(res, tmp_path / f"{rows}.rrd", rows=rows, **opts)
        got = rrd_rows(tmp_path / f"{rows}.rrd")
        if want is None:
            want = got
            decimated = [k for k, v in got.items() if k.endswith("/rms")]
            assert decimated and all(len(got[k]) < 60_000 / 3 for k in decimated)
        assert got == want


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


def test_payload_changes_are_rows_at_their_onset_and_classification(tmp_path: Path) -> None:
    res = fake_result()
    change = {"t_start": 2.0, "t_classified": 5.0, "mass_kg": 1.25, "mass_se_kg": 0.01,
              "values": {"m": 1.25}, "explained": 0.97, "mass_after_kg": 1.25,
              "as_log": "heavy.csv", "drift": 0.012, "inertia": "shows"}
    # the alarm of the change (the 7.0 s loading event) is the payload change's, not counted
    warm, one, carried = make_incidents(res)
    incs = (warm, dataclasses.replace(one, number=1), dataclasses.replace(carried,
                                                                          payload_change=1))
    res = dataclasses.replace(res, payload_changes=(change,), incidents=incs)
    path = tmp_path / "payload.rrd"
    write_rrd(res, path)
    ent = read_entities(path)
    rows = ent["/payload_changes"]
    texts = [x[0] for x in rows["TextLog:text"]]
    assert len(texts) == 2 and "+1.25 kg (s.e. ≥ 0.01 kg; 97.0 % of the step a mass, steady " \
        "within 1.2 %, its inertia shows)" in texts[0], texts
    # named as the report names it (p1), not a contact: INFO, "not counted"
    inc_rows = ent["/incidents"]
    assert [x[0] for x in inc_rows["TextLog:level"]] == ["INFO", "WARN", "INFO"]
    said = [x[0] for x in inc_rows["TextLog:text"]]
    assert said[2].startswith("incident #p1: ") and "payload change P1" in said[2]
    assert "None" not in " ".join(said)
    states = [x[0] for x in ent["/incidents/contact"]["StateChange:state"]]
    assert "#p1 link 1 · force ? · quasi_static (payload change P1: not counted)" in states
    assert "classified" in texts[1] and "+1.25 kg" in texts[1]
    np.testing.assert_array_equal(elapsed_ns(rows), [2_000_000_000, 5_000_000_000])
    info = next(ch.to_record_batch().to_pydict()["TextDocument:text"][0][0]
                for ch in rr.chunk.RrdReader(path).store().stream()
                if ch.entity_path == "/run/info")
    assert ("| P1 | 2.000 | +1.25 (s.e. ≥ 0.01) | 97.0 % of the step a mass, steady within "
            "1.2 %, its inertia shows | 5.000 | +1.25 kg beyond the model's load: heavy.csv's "
            "load, as fitted |") in info
    assert "the residual now carries +1.25 kg beyond the model's load: heavy.csv's load" \
        in texts[1]
