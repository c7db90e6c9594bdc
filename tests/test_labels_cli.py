"""``impactcli labels``: labels from a switch or force channel of a log, then ``evaluate``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from impactcli.errors import LabelsError
from impactcli.logs import write_log
from impactcli.logs.channel_labels import stretches
from impactcli.schema import validate

from .cli_run import invoke
from .conftest import make_log

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
#: (first, last) sample of each contact in the test log (4 ms samples): 2.0–2.2 s,
#: 4.0–4.5 s, 6.0–6.004 s (two samples), 6.04–6.1 s (a bounce 36 ms later), 8.0–8.3 s
STRETCHES = [(500, 550), (1000, 1125), (1500, 1501), (1510, 1525), (2000, 2075)]
PEAKS = [12.0, 20.0, 3.0, 4.0, 35.0]


def info(r: Any) -> str:
    return f"exit {r.exit_code}\nstdout:\n{r.stdout}\nstderr:\n{r.stderr}"


def add_columns(csv: Path, out: Path, t: np.ndarray,
                stretch: list[tuple[int, int]], peaks: list[float]) -> None:
    """The canonical CSV ``csv`` with a ``bumper`` switch (0/1) and a ``load_cell`` force
    [N] (a half-sine of the given peak over each stretch, 0.2 N noise-free baseline)."""
    import pandas as pd

    df = pd.read_csv(csv)
    assert np.allclose(df["time"].to_numpy(), t)
    sw = np.zeros(len(t))
    force = np.full(len(t), 0.2)
    for (a, b), p in zip(stretch, peaks, strict=True):
        sw[a : b + 1] = 1.0
        k = np.arange(b - a + 1)
        shape = np.sin(np.pi * (k + 1) / (b - a + 2))  # > 0 on every sample of the stretch
        force[a : b + 1] = 1.0 + (p - 1.0) * shape / shape.max()
    df["bumper"] = sw
    df["load_cell"] = force
    df.to_csv(out, index=False)


@pytest.fixture
def switch_log(tmp_path: Path) -> tuple[Path, np.ndarray]:
    log = make_log(n=2500)
    plain = tmp_path / "plain.csv"
    write_log(log, plain)
    out = tmp_path / "arm.csv"
    add_columns(plain, out, log.time_s, STRETCHES, PEAKS)
    return out, log.time_s


def test_switch_and_force_columns_give_the_contacts(switch_log, tmp_path):
    log, t = switch_log
    ins = invoke("inspect", str(log), "--json")
    assert ins.exit_code == 0, info(ins)
    assert {"bumper", "load_cell"} <= set(json.loads(ins.stdout)["channels"]["ignored"])
    out = tmp_path / "sw.labels.json"
    r = invoke("labels", str(log), "--from-channel", "bumper", "--above", "0.5", "--link", "2",
               "-o", str(out))
    assert r.exit_code == 0, info(r)
    assert "5 contact(s) where bumper > 0.5" in r.stdout and "a switch" in r.stdout
    doc = json.loads(out.read_text())
    validate(doc, "labels", LabelsError, str(out))
    assert doc["sample_rate"] == pytest.approx(250.0)
    assert [(e["start"], e["end"]) for e in doc["events"]] == [
        (pytest.approx(t[a]), pytest.approx(t[b])) for a, b in STRETCHES]
    assert all(e["kind"] == "push" and e["link"] == 2 for e in doc["events"])
    # a switch knows when, not how hard
    assert all(e["peak_force"] == 0.0 and e["peak_force_known"] is False
               and e["peak_value"] == 1.0 for e in doc["events"])
    assert doc["source"]["channel_kind"] == "switch" and doc["source"]["channel"] == "bumper"

    out_f = tmp_path / "f.labels.json"
    r = invoke("labels", str(log), "--from-channel", "load_cell", "--above", "0.5",
               "--link", "1", "--kind", "impact", "-o", str(out_f))
    assert r.exit_code == 0, info(r)
    fdoc = json.loads(out_f.read_text())
    validate(fdoc, "labels", LabelsError, str(out_f))
    assert fdoc["source"]["channel_kind"] == "force"
    assert [(e["start"], e["end"]) for e in fdoc["events"]] == [
        (pytest.approx(t[a]), pytest.approx(t[b])) for a, b in STRETCHES]
    assert [e["peak_force"] for e in fdoc["events"]] == pytest.approx(PEAKS)
    assert all("peak_force_known" not in e and e["kind"] == "impact" and e["link"] == 1
               for e in fdoc["events"])
    # the bounce at 6.04 s merges into the contact at 6.0 s (6.0–6.1 s), then contacts
    # shorter than 0.15 s are dropped
    out_m = tmp_path / "m.labels.json"
    r = invoke("labels", str(log), "--from-channel", "load_cell", "--above", "0.5",
               "--link", "1", "--merge-gap", "0.05", "--min-duration", "0.15", "-o", str(out_m))
    assert r.exit_code == 0, info(r)
    mdoc = json.loads(out_m.read_text())
    assert [(e["start"], e["end"]) for e in mdoc["events"]] == [
        (pytest.approx(t[a]), pytest.approx(t[b]))
        for a, b in [(500, 550), (1000, 1125), (2000, 2075)]]
    assert mdoc["source"]["merge_gap_s"] == 0.05
    r = invoke("labels", str(log), "--from-channel", "load_cell", "--above", "0.5",
               "--link", "1", "--merge-gap", "0.05", "-o", str(out_m))
    merged = json.loads(out_m.read_text())["events"]
    assert [(e["start"], e["end"]) for e in merged][2] == (pytest.approx(t[1500]),
                                                           pytest.approx(t[1525]))
    assert merged[2]["peak_force"] == pytest.approx(4.0)
    # --channel-kind force on the switch: its peak is taken as a force
    r = invoke("labels", str(log), "--from-channel", "bumper", "--above", "0.5", "--link", "2",
               "--channel-kind", "force", "-o", str(out))
    assert json.loads(out.read_text())["events"][0]["peak_force"] == 1.0


def test_evaluate_runs_on_the_labels(switch_log, tmp_path):
    log, _ = switch_log
    out = tmp_path / "f.labels.json"
    r = invoke("labels", str(log), "--from-channel", "load_cell", "--above", "0.5",
               "--link", "2", "-o", str(out))
    assert r.exit_code == 0, info(r)
    ev = invoke("evaluate", str(log), "--labels", str(out), "--json")
    assert ev.exit_code == 0, info(ev)
    doc = json.loads(ev.stdout)
    validate(doc, "evaluation", LabelsError, "evaluate --json")
    assert sum(doc["n_contacts"].values()) == len(STRETCHES)
    assert doc["incidents"]["available"] is True
    assert [c["link_label"] for c in doc["incidents"]["contacts"]] == [2] * len(STRETCHES)
    assert [c["force_label_n"] for c in doc["incidents"]["contacts"]] == pytest.approx(PEAKS)


def test_sample_log_labels_from_a_force_column_score_the_answer(tmp_path):
    """The shipped pushes log with a load-cell column made from its labels: labels made from
    it score link, force and contact type like the shipped labels do."""
    log = SAMPLES / "csv" / "assist_pushes.csv.gz"
    if not log.is_file():
        pytest.skip("sample logs not present")
    from impactcli.logs import read_log
    from impactcli.logs.robot_files import read_labels

    t = read_log(log).time_s
    truth = read_labels(SAMPLES / "csv" / "assist_pushes.labels.json").events
    idx = [(int(np.searchsorted(t, c.start - 1e-9)), int(np.searchsorted(t, c.end + 1e-9)) - 1)
           for c in truth]
    import gzip

    plain = tmp_path / "plain.csv"
    plain.write_bytes(gzip.decompress(log.read_bytes()))
    csv = tmp_path / "pushes.csv"
    add_columns(plain, csv, t, idx, [c.peak_force for c in truth])
    lab = tmp_path / "pushes.labels.json"
    links = {c.link for c in truth}
    assert links == {1, 2}
    # one label file per link (a load cell per link)
    docs = []
    for link in sorted(links):
        mine = [k for k, c in enumerate(truth) if c.link == link]
        one = tmp_path / f"link{link}.csv"
        add_columns(plain, one, t, [idx[k] for k in mine], [truth[k].peak_force for k in mine])
        out = tmp_path / f"link{link}.labels.json"
        r = invoke("labels", str(one), "--from-channel", "load_cell", "--above", "0.5",
                   "--link", str(link), "-o", str(out))
        assert r.exit_code == 0, info(r)
        docs.append(json.loads(out.read_text()))
    events = sorted((e for d in docs for e in d["events"]), key=lambda e: e["start"])
    lab.write_text(json.dumps({"sample_rate": docs[0]["sample_rate"], "events": events}))
    assert [(e["start"], e["end"], e["link"]) for e in events] == [
        (pytest.approx(c.start, abs=1e-9), pytest.approx(c.end, abs=1e-9), c.link)
        for c in truth]
    ev = invoke("evaluate", str(csv), "--labels", str(lab), "--json",
                "--config", str(SAMPLES / "assist_like.config.toml"))
    assert ev.exit_code == 0, info(ev)
    inc = json.loads(ev.stdout)["incidents"]
    assert inc["matched"] == len(truth)
    assert inc["link_accuracy"] == 1.0 and inc["contact_accuracy"] == 1.0
    assert 0 < inc["force_rel_error_median"] < 0.5


def test_a_message_field_and_a_joint_channel(tmp_path):
    """In an MCAP, a JointState field by joint name or index, and <joint>.<signal>, give the
    same contacts as the CSV's torque column."""
    log = make_log(n=2500, seed=2)
    csv, mcap = tmp_path / "arm.csv", tmp_path / "arm.mcap"
    write_log(log, csv)
    write_log(log, mcap, mcap_encoding="ros2")
    outs = {}
    for src, channel in ((csv, "j1.torque"), (mcap, "/joint_states/effort[j1]"),
                         (mcap, "/joint_states/effort[0]"), (mcap, "j1.torque")):
        out = tmp_path / f"{len(outs)}.json"
        r = invoke("labels", str(src), "--from-channel", channel, "--above", "2.0",
                   "--link", "1", "-o", str(out))
        assert r.exit_code == 0, info(r)
        outs[(src.suffix, channel)] = [(e["start"], e["end"], e["peak_force"])
                                       for e in json.loads(out.read_text())["events"]]
    want = outs[(".csv", "j1.torque")]
    assert len(want) >= 3
    for got in outs.values():
        np.testing.assert_allclose(np.array(got), np.array(want), rtol=1e-6)


def test_a_column_of_a_mapped_headerless_csv(tmp_path):
    log = make_log(n=1000)
    t = log.time_s
    sw = ((t > 1.0) & (t < 1.5)).astype(float)
    rows = np.column_stack([t * 1000, log.position[:, 0], log.torque[:, 0], sw])
    csv = tmp_path / "dump.csv"
    csv.write_text("\n".join(",".join(f"{v:.9g}" for v in r) for r in rows) + "\n")
    cmap = tmp_path / "map.json"
    cmap.write_text(json.dumps({
        "schema_version": "1.0", "name": "dump", "format": "csv",
        "csv": {"header": False}, "time": {"column": 0, "unit": "ms"},
        "joints": [{"name": "j1", "position": {"column": 1}, "torque": {"column": 2}}]}))
    out = tmp_path / "l.json"
    r = invoke("labels", str(csv), "--channel-map", str(cmap), "--from-channel", "3",
               "--above", "0.5", "--link", "1", "-o", str(out))
    assert r.exit_code == 0, info(r)
    (e,) = json.loads(out.read_text())["events"]
    on = np.flatnonzero(sw)
    assert (e["start"], e["end"]) == (pytest.approx(t[on[0]]), pytest.approx(t[on[-1]]))
    bad = invoke("labels", str(csv), "--channel-map", str(cmap), "--from-channel", "7",
                 "--above", "0.5", "--link", "1", "-o", str(out))
    assert bad.exit_code == 3, info(bad)
    assert "columns 0–3 (no header)" in bad.stderr and "j1.position" in bad.stderr


def test_a_channel_that_does_not_exist_is_one_line_exit_3(switch_log, tmp_path):
    log, _ = switch_log
    out = tmp_path / "nope.json"
    r = invoke("labels", str(log), "--from-channel", "gripper", "--above", "1", "--link", "1",
               "-o", str(out))
    assert r.exit_code == 3, info(r)
    assert r.stdout == ""
    (line,) = r.stderr.strip().splitlines()
    assert line.startswith(f"impactcli: error: {log}: no channel 'gripper'")
    assert "bumper" in line and "load_cell" in line and "time" in line
    assert not out.exists()
    mcap = tmp_path / "arm.mcap"
    write_log(make_log(), mcap, mcap_encoding="ros2")
    for channel, what in (("gripper", "/joint_states"), ("/gripper/force", "names no topic"),
                          ("/joint_states/force[0]", "does not exist")):
        r = invoke("labels", str(mcap), "--from-channel", channel, "--above", "1",
                   "--link", "1", "-o", str(out))
        assert r.exit_code == 3, info(r)
        assert len(r.stderr.strip().splitlines()) == 1 and what in r.stderr, info(r)
        assert str(mcap) in r.stderr


def test_usage_errors_exit_2(switch_log, tmp_path):
    log, _ = switch_log
    out = str(tmp_path / "l.json")
    base = ["labels", str(log), "--from-channel", "bumper", "-o", out]
    no_link = invoke(*base, "--above", "0.5")  # --link is required, and said what it is
    assert no_link.exit_code == 2
    assert no_link.stderr.splitlines()[-1] == (
        "Error: Missing option '--link'. --link N is the link the contacts are on: 1-based, "
        "counted from the base along the robot's chain (1: the link the first joint moves); "
        "a label names the link touched, and evaluate scores the incidents' link against it")
    assert invoke(*base, "--above", "0.5", "--link", "0").exit_code == 2
    assert invoke(*base, "--above", "nan", "--link", "1").exit_code == 2
    assert invoke(*base, "--link", "1").exit_code == 2
    assert invoke(*base, "--above", "0.5", "--link", "1", "--kind", "slap").exit_code == 2
    missing = invoke("labels", str(tmp_path / "none.csv"), "--from-channel", "x", "--above", "1",
                     "--link", "1", "-o", out)
    assert missing.exit_code == 3 and "not found" in missing.stderr


def test_no_stretch_warns_and_writes_empty_labels(switch_log, tmp_path):
    log, _ = switch_log
    out = tmp_path / "none.json"
    r = invoke("labels", str(log), "--from-channel", "load_cell", "--above", "100",
               "--link", "1", "-o", str(out))
    assert r.exit_code == 0, info(r)
    assert "never above 100" in r.stderr
    assert json.loads(out.read_text())["events"] == []


def test_stretches_rules():
    t = np.arange(10) * 0.1
    v = np.array([0, 1, 1, 0, 1, 0, 0, np.nan, 1, 1])
    assert stretches(t, v, 0.5) == [(1, 2), (4, 4), (8, 9)]
    assert stretches(t, v, 0.5, merge_gap_s=0.2) == [(1, 4), (8, 9)]
    assert stretches(t, v, 0.5, merge_gap_s=0.4) == [(1, 9)]
    assert stretches(t, v, 0.5, min_duration_s=0.1) == [(1, 2), (8, 9)]
    assert stretches(t, np.zeros(10), 0.5) == []


def test_readme_and_help_give_the_real_syntax():
    """README's command table names every required option (--link N was missing)."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text("utf-8")
    assert "`impactcli labels LOG --from-channel NAME --above X --link N -o labels.json`" in readme
    text = " ".join(invoke("labels", "--help").stdout.split())
    assert ("--link N The link the contacts are on: 1-based, counted from the base along the "
            "robot's chain (1: the link the first joint moves); a label names the link touched, "
            "and evaluate scores the incidents' link against it. [x>=1; required]") in text
