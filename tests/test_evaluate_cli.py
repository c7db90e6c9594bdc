"""``impactcli evaluate``: a timeline JSON and labels built in the test; exit codes and --json."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner

import impactcli.cli.evaluate as cli_eval
from impactcli.cli import main
from impactcli.errors import LabelsError
from impactcli.outputs.timeline import write_timeline
from impactcli.quality.sweep import DEFAULT_SWEEP_SCALES, ratios_from_signals, sweep_ratios
from impactcli.run import evaluate_run
from impactcli.schema import validate
from impactcli.types import ReadOptions

from .fakes import SWEEP_LABELS, fake_result, sweep_result, write_fake_signals

H = 3600.0


def timeline_doc() -> dict[str, Any]:
    """60 s at 250 Hz, warm-up 5 s; events: adaptive in warm-up (1.0 s), adaptive on the
    impact (10.01 s), baseline on the impact (10.05 s), loading on the push's release
    (20.6 s), an adaptive false alarm (40.0 s)."""
    def e(det: str, t0: float, warm: bool = False) -> dict[str, Any]:
        return {"t_start": t0, "t_end": t0 + 0.04, "detector": det, "joints": ["j2"],
                "peak_ratio": 1.7, "peak_residual": {"j2": -0.8}, "in_warmup": warm}

    return {
        "schema_version": "1.0",
        "tool": {"name": "impactcli", "version": "0.0.0"},
        "input": {"path": "arm.csv", "sha256": "0" * 64, "joints": ["j1", "j2"],
                  "duration_s": 60.0, "sample_rate_hz": 250.0, "t0_ns": 0,
                  "torque_source": "torque", "time_source": "column"},
        "config": {"events": {"merge_gap_s": 0.1, "min_duration_s": 0.0}},
        "calibrated": True,
        "model": {"source": "given", "sha256": "ab" * 32, "model": {}},
        "replay": {"online_equivalent": True, "reference_source": "reference",
                   "torque_filtered": True},
        "warmup_end_s": 5.0,
        "thresholds": {j: {"v_stat": 0.2, "v0": 1.5, "vL": 0.5} for j in ("j1", "j2")},
        "events": [e("adaptive", 1.0, True), e("adaptive", 10.01), e("static_baseline", 10.05),
                   e("static_loading", 20.6), e("adaptive", 40.0)],
        "summary": {},
    }


LABELS = {
    "sample_rate": 250.0,
    "events": [
        {"start": 2.0, "end": 2.1, "peak_force": 3.0, "kind": "impact", "link": 1},   # warm-up
        {"start": 10.0, "end": 10.1, "peak_force": 4.0, "kind": "impact", "link": 2},
        {"start": 20.0, "end": 20.5, "peak_force": 12.0, "kind": "push", "link": 2},
        {"start": 30.0, "end": 31.0, "peak_force": 25.0, "kind": "clamp", "link": 1},
    ],
}


def write(tmp_path: Path, name: str, doc: Any) -> Path:
    p = tmp_path / name
    with p.open("w") as f:
        json.dump(doc, f)
    return p


def invoke(*args: str) -> Any:
    result = CliRunner().invoke(main, ["evaluate", *args], catch_exceptions=False)
    return result


def info(r: Any) -> str:
    return f"exit {r.exit_code}\nstdout:\n{r.stdout}\nstderr:\n{r.stderr}"


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    tl = write(tmp_path, "arm.timeline.json", timeline_doc())
    return tl, write(tmp_path, "labels.json", LABELS)


def test_text_table(files):
    tl, lab = files
    r = invoke(str(tl), "--labels", str(lab))
    assert r.exit_code == 0, info(r)
    out = r.stdout
    assert "3 counted, 1 in warm-up" in out
    row = next(line for line in out.splitlines() if line.startswith("adaptive "))
    assert "1/3" in row and "10 ms" in row
    assert "in warm-up (not counted as misses)" in out


def test_json_has_the_known_numbers_and_is_deterministic(files):
    tl, lab = files
    r = invoke(str(tl), "--labels", str(lab), "--json")
    assert r.exit_code == 0, info(r)
    doc = json.loads(r.stdout)
    validate(doc, "evaluation", LabelsError, "evaluate --json")
    free = 55.0 - (0.37 + 0.77 + 1.27)
    assert doc["collision_free_s"] == pytest.approx(free)
    a = doc["detectors"]["adaptive"]
    assert (a["detected"], a["n_contacts"], a["false_alarms"]) == (1, 3, 1)
    assert a["n_events_in_warmup"] == 1
    assert a["false_alarms_per_hour"] == pytest.approx(H / free, rel=1e-6)
    assert a["delay_median_s"] == pytest.approx(0.01)
    assert a["min_detected_force"] == 4.0 and a["max_missed_force"] == 25.0
    sl = doc["detectors"]["static_loading"]
    assert (sl["detected"], sl["false_alarms"], sl["delay_median_s"]) == (1, 0, pytest.approx(0.6))
    p = doc["detectors"]["product"]
    assert (p["detected"], p["false_alarms"], p["max_missed_force"]) == (2, 1, 25.0)
    assert doc["detectors"]["static_baseline"]["by_kind"]["impact"]["detected"] == 1
    assert doc["n_contacts"] == {"counted": 3, "in_warmup": 1, "outside_log": 0}
    assert doc["input"] == str(tl)
    again = invoke(str(tl), "--labels", str(lab), "--json")
    assert again.stdout == r.stdout
    wider = json.loads(invoke(str(tl), "--labels", str(lab), "--json", "--post", "0.7").stdout)
    assert wider["detectors"]["adaptive"]["detected"] == 1  # the loading event is not adaptive's
    assert wider["tolerance"]["post_s"] == 0.7


def timeline_2_doc() -> dict[str, Any]:
    """timeline_doc as a 2.0 timeline with incidents: the warm-up alarm; the impact
    (events 1, 2: link 2, 5 N, transient); the push's release (event 3: link 1, no force,
    quasi-static); the false alarm (event 4)."""
    doc = timeline_doc()
    doc["schema_version"] = "2.0"

    def inc(t0: float, link: int | None, force: float | None, contact: str,
            events: list[int], warm: bool = False) -> dict[str, Any]:
        return {"t_start": t0, "t_end": t0 + 0.04, "t_start_utc": None,
                "detectors": ["adaptive"], "joints": ["j2"], "link": link, "force_n": force,
                "force_method": "test", "contact": contact, "peak_residual": {"j2": -0.8},
                "in_warmup": warm, "events": events}

    doc["incidents"] = [inc(1.0, 2, 1.0, "transient", [0], True),
                        inc(10.01, 2, 5.0, "transient", [1, 2]),
                        inc(20.6, 1, None, "quasi_static", [3]),
                        inc(40.0, None, None, "unknown", [4])]
    return doc


def test_incidents_of_a_2_0_timeline_are_scored(files, tmp_path):
    _, lab = files
    tl = write(tmp_path, "arm2.timeline.json", timeline_2_doc())
    r = invoke(str(tl), "--labels", str(lab), "--json")
    assert r.exit_code == 0, info(r)
    doc = json.loads(r.stdout)
    validate(doc, "evaluation", LabelsError, "evaluate --json")
    ie = doc["incidents"]
    assert ie["available"] is True
    assert (ie["n_contacts"], ie["matched"], ie["n_incidents"], ie["unmatched_incidents"]) == (
        3, 2, 3, [3])
    rows = {c["label_index"]: c for c in ie["contacts"]}
    assert rows[1]["incident_index"] == 1 and rows[1]["link_right"] is True
    assert rows[1]["force_rel_error"] == pytest.approx(0.25)  # 5 N for a 4 N impact
    assert rows[2]["incident_index"] == 2 and rows[2]["link_right"] is False
    assert rows[2]["contact_right"] is False  # a push is transient
    assert rows[3]["incident_index"] is None  # the clamp was missed
    assert ie["link_accuracy"] == 0.5 and ie["contact_accuracy"] == 0.5
    assert ie["one_incident_per_contact"]["holds"] is True
    text = invoke(str(tl), "--labels", str(lab))
    assert text.exit_code == 0, info(text)
    assert "link right                                      1/2 (50%)" in text.stdout


def test_a_1_0_timeline_says_it_has_no_incidents(files):
    tl, lab = files
    r = invoke(str(tl), "--labels", str(lab))
    assert r.exit_code == 0, info(r)
    assert "is a 1.0 timeline: it has no incidents" in r.stdout
    doc = json.loads(invoke(str(tl), "--labels", str(lab), "--json").stdout)
    assert doc["incidents"]["available"] is False
    assert "1.0 timeline" in doc["incidents"]["summary"][0][1]


@pytest.mark.parametrize("labels_doc, what", [
    ({"sample_rate": 250.0, "events": [{"start": 1.0, "end": 2.0, "kind": "impact", "link": 1}]},
     "peak_force"),
    ({"sample_rate": 250.0, "events": [{"start": 1.0, "end": 2.0, "peak_force": 3,
                                        "kind": "slap", "link": 1}]}, "slap"),
    ({"events": []}, "sample_rate"),
    ({"sample_rate": 250.0, "events": [{"start": 2.0, "end": 1.0, "peak_force": 3,
                                        "kind": "push", "link": 1}]}, "ends before"),
    # a link the 2-joint arm does not have (a trial's link 7 was scored "7 / 2 WRONG")
    ({"sample_rate": 250.0, "events": [{"start": 1.0, "end": 2.0, "peak_force": 3,
                                        "kind": "push", "link": 7}]},
     "event 0 (from 0) is on link 7, but"),
])
def test_bad_labels_exit_3_one_line(files, tmp_path, labels_doc, what):
    tl, _ = files
    bad = write(tmp_path, "bad.json", labels_doc)
    r = invoke(str(tl), "--labels", str(bad))
    assert r.exit_code == 3, info(r)
    assert r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("impactcli: error:"), info(r)
    assert str(bad) in lines[0] and what in lines[0]


def test_unreadable_or_missing_labels_exit_3(files, tmp_path):
    tl, _ = files
    garbled = tmp_path / "garbled.json"
    garbled.write_text("{not json")
    for p in (garbled, tmp_path / "absent.json"):
        r = invoke(str(tl), "--labels", str(p))
        assert r.exit_code == 3, info(r)
        assert len(r.stderr.strip().splitlines()) == 1


def test_bad_timeline_exit_3(tmp_path):
    lab = write(tmp_path, "labels.json", LABELS)
    doc = timeline_doc()
    doc["events"][1]["detector"] = "magic"
    tl = write(tmp_path, "bad.timeline.json", doc)
    r = invoke(str(tl), "--labels", str(lab))
    assert r.exit_code == 3, info(r)
    assert "events/1/detector" in r.stderr and str(tl) in r.stderr
    del doc["warmup_end_s"]
    r = invoke(str(write(tmp_path, "b2.timeline.json", doc)), "--labels", str(lab))
    assert r.exit_code == 3 and "warmup_end_s" in r.stderr, info(r)


def test_a_missing_input_is_named_before_labels_are_looked_for(tmp_path):
    for name, what in (("gone.csv", "log"), ("gone.timeline.json", "timeline")):
        r = invoke(str(tmp_path / name))
        assert r.exit_code == 3, info(r)
        assert r.stderr.strip() == f"impactcli: error: {tmp_path / name}: {what} file not found"


def test_usage_errors_exit_2(files):
    tl, lab = files
    r = invoke(str(tl), "--labels", str(lab), "--sweep")  # no signals beside the timeline
    assert r.exit_code == 2 and "signals.parquet" in r.stderr, info(r)
    r = invoke(str(tl), "--labels", str(lab), "--sweep", "--scales", "3:1:0.1")
    assert r.exit_code == 2 and "--scales" in r.stderr, info(r)
    r = invoke(str(tl), "--labels", str(lab), "--model", str(lab))
    assert r.exit_code == 2, info(r)
    r = invoke(str(tl))  # no arm.labels.json beside arm.timeline.json
    assert r.exit_code == 2 and "--labels" in r.stderr, info(r)


def test_labels_found_beside_the_input(files):
    tl, lab = files
    (tl.parent / "arm.labels.json").write_text(lab.read_text())
    r = invoke(str(tl), "--json")
    assert r.exit_code == 0, info(r)
    assert json.loads(r.stdout)["labels"] == str(tl.parent / "arm.labels.json")


def test_parse_scales():
    geo = cli_eval.parse_scales(cli_eval.DEFAULT_SCALES)
    assert geo == DEFAULT_SWEEP_SCALES
    assert geo[0] == 0.2 and 4.7 < geo[-1] <= 5.0 and len(geo) == 66
    ratios = np.array(geo[1:]) / np.array(geo[:-1])
    assert np.allclose(ratios, 1.05, atol=1e-3)
    assert cli_eval.parse_scales("0.5:1:0.25") == (0.5, 0.75, 1.0)
    assert cli_eval.parse_scales("2, 1,2") == (1.0, 2.0)
    for bad in ("3:1:0.1", "0:1:x2", "1:2:x1", "1:2", "a,b", "-1,2", ""):
        with pytest.raises(ValueError):
            cli_eval.parse_scales(bad)


def test_labels_of_another_rate_warn(files, tmp_path):
    tl, _ = files
    lab = write(tmp_path, "l100.json", dict(LABELS, sample_rate=100.0))
    r = invoke(str(tl), "--labels", str(lab), "--json")
    assert r.exit_code == 0, info(r)
    assert "impactcli: warning:" in r.stderr and "100 Hz" in r.stderr
    json.loads(r.stdout)


def test_sweep_from_a_log(tmp_path, monkeypatch):
    """The LOG branch with the replay replaced by a known result and its samples (the
    streamed replay: tests/test_view_evaluate_stream.py)."""
    import dataclasses
    import types

    from impactcli.outputs.report.samples import ReportCollector

    seen: dict[str, Any] = {}

    def fake_replay_log(path: Path, **kw: Any) -> Any:
        seen.update(kw, path=path)
        known = sweep_result()
        joints = known.log.joint_names
        # thresholds of 1: the spilled statistics are the known ratios themselves
        result = dataclasses.replace(known, thresholds={
            j: {"v_stat": 1.0, "vL": 1.0, "v0": 1.0} for j in joints})
        if not kw["sweep"]:
            return result, None
        r = known.ratios
        col = ReportCollector(known.log.n_samples, plots=False)
        col(types.SimpleNamespace(
            joints=joints, time_s=known.log.time_s, position=np.zeros_like(r["adaptive"]),
            signals={"residual_rms": r["adaptive"], "threshold": np.ones_like(r["adaptive"]),
                     "loading_statistic": r["static_loading"],
                     "residual": r["static_baseline"]}))
        return result, col.finish(result)

    monkeypatch.setattr(evaluate_run, "replay_log", fake_replay_log)
    log = tmp_path / "arm.csv"
    log.write_text("time\n0\n")
    lab = write(tmp_path, "labels.json", SWEEP_LABELS.to_dict())
    r = invoke(str(log), "--labels", str(lab), "--json", "--sweep", "--scales", "1,1.3,1.6,2.5",
               "--channel-map", "ur_ext_observer")
    assert r.exit_code == 0, info(r)
    assert seen["read_options"] == ReadOptions(channel_map="ur_ext_observer")
    assert seen["path"] == log
    doc = json.loads(r.stdout)
    validate(doc, "evaluation", LabelsError, "evaluate --json --sweep")
    zero = doc["sweep"]["at_zero_false_alarms"]
    assert zero["adaptive"]["scale"] == 1.6 and zero["static_loading"]["scale"] == 1.3
    assert doc["sweep"]["adaptive_helps"] is True
    assert doc["sweep"]["verdict"].startswith("The adaptive detector helps")
    text = invoke(str(log), "--labels", str(lab), "--sweep", "--scales", "1:2.5:0.3")
    assert text.exit_code == 0, info(text)
    assert "at zero false alarms" in text.stdout and "adaptive detector" in text.stdout


def test_sweep_from_a_timeline_with_its_signals(tmp_path):
    res = sweep_result()
    # make the stored signals agree with the test's ratios: threshold 1, rms = ratio, etc.
    sig = dict(res.signals)
    sig["threshold"] = np.ones_like(res.ratios["adaptive"])
    sig["residual_rms"] = res.ratios["adaptive"]
    sig["loading_statistic"] = res.ratios["static_loading"] * 0.5   # vL = 0.5
    sig["residual"] = res.ratios["static_baseline"] * 1.5           # v0 = 1.5
    res = dataclasses.replace(res, signals=sig, events=())
    tl = tmp_path / "arm.timeline.json"
    write_timeline(res, tl)
    write_fake_signals(res, tmp_path / "arm.signals.parquet", rows=1012)  # a group at warm-up
    lab = write(tmp_path, "labels.json", SWEEP_LABELS.to_dict())
    r = invoke(str(tl), "--labels", str(lab), "--json", "--sweep", "--scales", "1,1.3,1.6,2.5")
    assert r.exit_code == 0, info(r)
    doc = json.loads(r.stdout)
    zero = doc["sweep"]["at_zero_false_alarms"]
    assert zero["adaptive"]["scale"] == 1.6 and zero["static_loading"]["scale"] == 1.3
    assert zero["adaptive"]["min_detected_force"] == 3.0
    # "zero false alarms" rests on this log's collision-free time: the rate it bounds at
    # 90 % is ln(10) / hours (a trial took a 0-FA scale from 50 s of one log; it gave
    # 4042 per hour on free motion)
    free = doc["collision_free_s"]
    assert 0 < free < 9.0 and doc["sweep"]["collision_free_s"] == pytest.approx(free)
    assert doc["sweep"]["zero_bound_per_hour"] == pytest.approx(math.log(10) * 3600 / free)
    assert doc["sweep"]["caveat"].startswith(
        f"Zero false alarms here is over this log's {free:.3g} s of collision-free time")
    r = invoke(str(tl), "--labels", str(lab), "--sweep", "--scales", "1,1.3,1.6,2.5")
    assert r.exit_code == 0 and "not thresholds for an audit" in r.stdout, info(r)


def test_timeline_sweep_reads_its_signals_one_row_group_at_a_time(tmp_path, monkeypatch):
    """evaluate TIMELINE --sweep on a long run's signals (400,000 samples, 20 row groups):
    the file is read one row group at a time, never whole, the memory the sweep allocates
    stays far below what the whole log's ratios take, and the rows are the in-memory
    sweep's of the whole run."""
    import tracemalloc

    import pyarrow.parquet as pq

    res = dataclasses.replace(fake_result(n=400_000, dt=0.004),
                              config={"events": {"merge_gap_s": 0.02, "min_duration_s": 0.0}})
    tl, sig = tmp_path / "arm.timeline.json", tmp_path / "arm.signals.parquet"
    write_timeline(res, tl)
    assert write_fake_signals(res, sig, rows=20_000) == pq.ParquetFile(sig).num_row_groups == 20
    lab = write(tmp_path, "labels.json", SWEEP_LABELS.to_dict())
    groups: list[int] = []
    real = pq.ParquetFile.read_row_group

    def read_row_group(self: Any, i: int, *a: Any, **k: Any) -> Any:
        t = real(self, i, *a, **k)
        groups.append(t.num_rows)
        return t

    def whole(*a: Any, **k: Any) -> Any:
        raise AssertionError("the signals file was read whole")

    monkeypatch.setattr(pq.ParquetFile, "read_row_group", read_row_group)
    monkeypatch.setattr(pq.ParquetFile, "read", whole)
    monkeypatch.setattr(pq, "read_table", whole)
    args = (str(tl), "--labels", str(lab), "--json", "--sweep", "--scales", "1,1.3")
    assert invoke(*args).exit_code == 0  # once untraced: the modules it imports are loaded
    groups.clear()
    tracemalloc.start()
    try:
        r = invoke(*args)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert r.exit_code == 0, info(r)
    assert groups == [20_000] * 20
    whole_ratios = 3 * res.log.n_samples * 2 * 8  # bytes of the (N, J) ratios, 3 detectors
    assert peak < whole_ratios / 3, f"peak {peak / 1e6:.1f} MB"
    monkeypatch.undo()
    cols = {f"{j}.{name}": res.signals[name][:, k] for k, j in enumerate(res.log.joint_names)
            for name in ("residual_rms", "threshold", "loading_statistic", "residual")}
    want = sweep_ratios(ratios_from_signals(cols, res.log.joint_names, res.thresholds),
                        res.log.time_s, labels=SWEEP_LABELS, scales=(1, 1.3),
                        warmup_end_s=res.warmup_end_s, merge_gap_s=0.02, min_duration_s=0.0)
    from impactcli.quality.verdict import sweep_to_dict

    assert json.loads(r.stdout)["sweep"] == json.loads(json.dumps(sweep_to_dict(want)))


def test_end_to_end_log_and_timeline_agree(tmp_path):
    """Simulated impacts → LOG evaluated (detection inside) and LOG → detect --signals →
    TIMELINE evaluated: the same evaluation and the same sweep."""
    from impactcli.logs import write_log
    from impactcli.logs.robot_files import write_labels, write_robot
    from impactcli.sim.core import simulate
    from impactcli.sim.scenarios import scenario

    sim = simulate(scenario("impacts", duration_s=30.0), seed=1)
    log, lab, rob = tmp_path / "imp.csv", tmp_path / "imp.labels.json", tmp_path / "imp.robot.json"
    write_log(sim.log, log)
    write_labels(sim.labels, lab)
    write_robot(sim.robot, rob)
    args = ["--labels", str(lab), "--json", "--sweep", "--scales", "0.2:3:x1.1"]
    r = invoke(str(log), "--robot", str(rob), *args)
    assert r.exit_code == 0, info(r)
    assert "uncalibrated" in r.stderr
    from_log = json.loads(r.stdout)
    validate(from_log, "evaluation", LabelsError, "evaluate --json --sweep")
    assert from_log["n_contacts"]["counted"] == len(sim.labels.events) == 5
    # the uncalibrated run (3 × its own 1 s maxima level) is insensitive by design; the
    # sweep still finds impacts at zero false alarms, so the two evaluations agree on content
    assert from_log["sweep"]["at_zero_false_alarms"]["product"]["detected"] >= 1
    assert from_log["sweep"]["verdict"]
    det = CliRunner().invoke(main, ["detect", str(log), "--robot", str(rob), "-o",
                                    str(tmp_path / "out"), "--signals"])
    assert det.exit_code == 0, info(det)
    r2 = invoke(str(tmp_path / "out" / "imp.timeline.json"), *args)
    assert r2.exit_code == 0, info(r2)
    from_tl = json.loads(r2.stdout)
    from_log.pop("input")
    from_tl.pop("input")
    assert from_tl == from_log
    # both score the run's incidents (the log's from the run, the timeline's from its JSON)
    assert from_log["incidents"]["available"] is True
    assert from_log["incidents"]["n_contacts"] == 5


def test_a_lower_bound_force_is_scored_and_shown_as_one(pushes: dict[str, Any]) -> None:
    """The sample pushes (their forces all lower bounds: the arm near stretched) through
    detect, then evaluate: each matched contact's force carries ``force_at_least`` in the
    JSON and '≳' in the text table, where a contact without it would read plain."""
    tl = pushes["timeline"]
    labels = str(pushes["labels_path"])
    r = CliRunner().invoke(main, ["evaluate", str(tl), "--labels", labels, "--json"])
    assert r.exit_code == 0, r.output
    contacts = json.loads(r.stdout)["incidents"]["contacts"]
    forced = [c for c in contacts if c["force_n"] is not None]
    assert forced and all(c.get("force_at_least") is True for c in forced)
    assert all("force_at_least" not in c for c in contacts if c["force_n"] is None)
    text = CliRunner().invoke(main, ["evaluate", str(tl), "--labels", labels]).stdout
    assert f"/ ≳{forced[0]['force_n']:.3g} N" in text, text


@pytest.fixture(scope="module")
def pushes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The sample pushes log through detect (its timeline) and its labels."""
    d = tmp_path_factory.mktemp("pushes")
    repo = Path(__file__).resolve().parents[1]
    log = repo / "sample_logs" / "csv" / "assist_pushes.csv.gz"
    r = CliRunner().invoke(main, ["detect", str(log), "--config",
                                  str(repo / "sample_logs" / "assist_like.config.toml"),
                                  "-o", str(d)])
    assert r.exit_code == 0, r.output
    labels_path = Path(str(log).replace(".csv.gz", ".labels.json"))
    return {"dir": d, "timeline": d / "assist_pushes.timeline.json",
            "labels": json.loads(labels_path.read_text()), "labels_path": labels_path}


@pytest.mark.parametrize(("factor", "unit"), [(1000.0, "kN"), (9.80665, "kgf"),
                                              (4.4482216, "lbf"), (0.001, "mN"),
                                              (40.0, None), (1.0, "")])
def test_labels_forces_in_another_unit_are_said_against_physics(
        pushes: dict[str, Any], factor: float, unit: str | None) -> None:
    """A trial's labels in kN (peak forces ÷ 1000) were scored silently ("min detected F
    0.005 N", "force error 73749 %"). The incidents' forces (a contact set's median within
    0.79–1.44× the truth on simulated arms) against labels divided by a unit's factor: the
    warning names the unit (no unit within 2×: another log's labels?); the labels in N: no
    warning."""
    doc = json.loads(json.dumps(pushes["labels"]))
    for ev in doc["events"]:
        ev["peak_force"] = ev["peak_force"] / factor
    lab = write(pushes["dir"], f"labels_{factor:g}.json", doc)
    r = CliRunner().invoke(main, ["evaluate", str(pushes["timeline"]), "--labels", str(lab)])
    assert r.exit_code == 0, info(r)
    said = [ln for ln in r.stderr.splitlines() if "the incidents' forces are a median" in ln]
    if unit == "":
        assert said == [], r.stderr
        return
    assert len(said) == 1, r.stderr
    assert said[0].startswith(f"impactcli: warning: {lab}: the incidents' forces are a median ")
    assert ("where on simulated arms a contact set's median lay within 0.79–1.44× the "
            "truth: " in said[0])
    if unit is None:
        assert said[0].endswith("labels of another log? The force errors below compare "
                                "across that factor")
    else:
        assert f"peak_force written in {unit} rather than N (×{factor:g})?" in said[0]
    # forces the physics checks did not trust (a log whose torque scale is off) say nothing
    # of the labels' unit: no warning
    tl = json.loads(pushes["timeline"].read_text())
    for inc in tl["incidents"]:
        inc["force_plausible"] = False
    off = write(pushes["dir"], f"off_scale_{factor:g}.timeline.json", tl)
    r = CliRunner().invoke(main, ["evaluate", str(off), "--labels", str(lab)])
    assert r.exit_code == 0, info(r)
    assert "the incidents' forces are a median" not in r.stderr, r.stderr
