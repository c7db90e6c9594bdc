"""Every verb that takes a log reads ROS bags: a rosbag2 folder (split in two files), a
rosbag2 ``.db3`` and a ROS 1 ``.bag`` — outputs and labels named after the log's stem (a
folder's own name); a plain folder given as a log is a data error (exit 3, one line)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import Result

from impactcli.logs import log_sha256, log_stem
from impactcli.logs.write import write_rosbag1, write_rosbag2
from impactcli.types import RobotLog

from .cli_run import invoke
from .conftest import make_log

RATE = 250.0
T0_NS = 1_700_000_000 * 10**9  # an epoch clock, as a recorder's header stamps
#: one labelled contact on joint j2 (link 2), after detection's 3 s warm-up
CONTACT = (6.0, 6.1)
LABELS = {"sample_rate": RATE,
          "events": [{"start": CONTACT[0], "end": CONTACT[1], "peak_force": 10.0,
                      "kind": "impact", "link": 2}]}
KINDS = ("folder", "db3", "bag")


def bag_log(seed: int, contact: bool) -> RobotLog:
    """9 s at 250 Hz (two joints, references), with a torque bump on j2 over CONTACT."""
    log = make_log(n=int(9 * RATE), dt=1 / RATE, seed=seed)
    tau = log.torque.copy()
    if contact:
        t = np.arange(log.n_samples) / RATE
        tau[(t >= CONTACT[0]) & (t <= CONTACT[1]), 1] += 3.0
    return RobotLog(t_ns=log.t_ns + T0_NS, joint_names=log.joint_names, position=log.position,
                    torque=tau, position_ref=log.position_ref, velocity_ref=log.velocity_ref,
                    acceleration_ref=log.acceleration_ref)


def write_bag(log: RobotLog, folder: Path, name: str, kind: str) -> Path:
    """``folder/name`` as a rosbag2 folder split in 2 files, ``name.db3`` or ``name.bag``."""
    if kind == "folder":
        p = folder / name
        write_rosbag2(log, p, split=2)
    elif kind == "db3":
        p = folder / f"{name}.db3"
        write_rosbag2(log, p)
    else:
        p = folder / f"{name}.bag"
        write_rosbag1(log, p)
    return p


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Path]]:
    """Per kind: ``log`` (a contact, labels beside it as ``<stem>.labels.json``) and
    ``free1``, ``free2`` (collision-free, for calibrate); and ``plain``: a folder that is
    not a rosbag2."""
    root = tmp_path_factory.mktemp("bags")
    out: dict[str, dict[str, Path]] = {}
    for kind in KINDS:
        d = root / kind
        d.mkdir()
        log = write_bag(bag_log(0, True), d, f"run_{kind}", kind)
        (d / f"run_{kind}.labels.json").write_text(json.dumps(LABELS), "utf-8")
        out[kind] = {"log": log,
                     "free1": write_bag(bag_log(1, False), d, f"free1_{kind}", kind),
                     "free2": write_bag(bag_log(2, False), d, f"free2_{kind}", kind)}
    plain = root / "plain" / "not_a_bag"
    plain.mkdir(parents=True)
    (plain / "run.db3-wal").write_bytes(b"")  # files inside, no log and no metadata.yaml
    out["plain"] = {"log": plain}
    return out


def ok(r: Result) -> Result:
    assert r.exit_code == 0, (r.exit_code, r.output, r.stderr)
    return r


def test_the_bags_are_what_the_tests_think(bags: dict[str, dict[str, Path]]) -> None:
    folder = bags["folder"]["log"]
    assert folder.is_dir() and len(list(folder.glob("*.db3"))) == 2
    assert log_stem(folder) == "run_folder" and log_stem(bags["db3"]["log"]) == "run_db3"
    assert log_stem(bags["bag"]["log"]) == "run_bag"


@pytest.mark.parametrize("kind", KINDS)
def test_inspect_a_bag(bags: dict[str, dict[str, Path]], kind: str) -> None:
    p = bags[kind]["log"]
    d = json.loads(ok(invoke("inspect", p, "--json")).stdout)
    assert d["format"] == ("rosbag1" if kind == "bag" else "rosbag2")
    assert d["joints"] == ["j1", "j2"]
    text = ok(invoke("inspect", p)).stdout
    assert "rosbag" in text


@pytest.mark.parametrize("kind", KINDS)
def test_identify_a_bag(bags: dict[str, dict[str, Path]], kind: str, tmp_path: Path) -> None:
    out = tmp_path / "model.json"
    r = ok(invoke("identify", bags[kind]["log"], "-o", out))
    assert out.is_file() and f"wrote {out}" in r.stdout


@pytest.mark.parametrize("kind", KINDS)
def test_calibrate_on_two_bags(bags: dict[str, dict[str, Path]], kind: str,
                               tmp_path: Path) -> None:
    out = tmp_path / "config.toml"
    r = ok(invoke("calibrate", bags[kind]["free1"], bags[kind]["free2"], "-o", out))
    assert out.is_file() and "calibrated on 2 log(s)" in r.stdout
    text = out.read_text("utf-8")
    for key in ("free1", "free2"):  # the logs it was calibrated on, by sha256
        assert log_sha256(bags[kind][key]) in text


@pytest.mark.parametrize("kind", KINDS)
def test_detect_evaluate_report_view_on_a_bag(bags: dict[str, dict[str, Path]], kind: str,
                                              tmp_path: Path) -> None:
    log = bags[kind]["log"]
    stem = f"run_{kind}"
    out = tmp_path / "out"
    ok(invoke("detect", log, "-o", out, "--signals"))
    tl = out / f"{stem}.timeline.json"
    assert sorted(p.name for p in out.iterdir()) == [f"{stem}.signals.parquet", tl.name]
    doc = json.loads(tl.read_text("utf-8"))
    assert doc["input"]["path"] == str(log) and doc["input"]["sha256"] == log_sha256(log)

    # evaluate: the log (labels beside it) and the timeline (labels beside its log)
    labels = str(log.with_name(f"{stem}.labels.json"))
    for src in (log, tl):
        ev = json.loads(ok(invoke("evaluate", src, "--json")).stdout)
        assert ev["input"] == str(src) and ev["labels"] == labels
        assert ev["n_contacts"]["counted"] == 1
    ok(invoke("evaluate", tl, "--sweep", "--scales", "0.5,1,2"))

    # report: the log and the timeline (re-run from the folder/file it records)
    for src, name in ((log, "log"), (tl, "tl")):
        html, js = tmp_path / f"{name}.html", tmp_path / f"{name}.json"
        ok(invoke("report", src, "-o", html, "--json", js))
        rep = json.loads(js.read_text("utf-8"))
        (sec,) = rep["logs"]
        assert sec["stem"] == stem
        assert sec["labels"]["path"] == labels
        assert html.is_file()

    # view: detect on the log and keep the recording
    rrd = tmp_path / f"{stem}.rrd"
    r = ok(invoke("view", log, "--no-open", "--save", rrd))
    assert rrd.is_file() and str(rrd) in r.stdout


def test_a_timeline_finds_its_moved_folder_and_labels(bags: dict[str, dict[str, Path]],
                                                      tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """A folder recorded by a relative path is found beside the timeline from any working
    folder, with its labels; a folder name with dots keeps them in its stem."""
    work = tmp_path / "work"
    work.mkdir()
    name = "rosbag2_2026.01.01-10.00.00"
    shutil.copytree(bags["folder"]["log"], work / name)
    (work / f"{name}.labels.json").write_text(json.dumps(LABELS), "utf-8")
    monkeypatch.chdir(work)
    ok(invoke("detect", f"{name}/", "-o", "."))  # a trailing slash names the same folder
    tl = work / f"{name}.timeline.json"
    assert json.loads(tl.read_text("utf-8"))["input"]["sha256"] == log_sha256(work / name)
    monkeypatch.chdir(tmp_path)  # "rosbag2_…" no longer resolves from here
    ev = json.loads(ok(invoke("evaluate", tl, "--json")).stdout)
    assert ev["labels"] == str(work / f"{name}.labels.json") and ev["n_contacts"]["counted"] == 1
    js = tmp_path / "r.json"
    ok(invoke("report", tl, "-o", tmp_path / "r.html", "--json", js))
    (sec,) = json.loads(js.read_text("utf-8"))["logs"]
    assert sec["stem"] == name and sec["labels"]["path"] == str(work / f"{name}.labels.json")


def test_a_folder_recorded_by_a_timeline_must_still_be_a_bag(bags: dict[str, dict[str, Path]],
                                                             tmp_path: Path) -> None:
    """A re-run looks for a file or a rosbag2 folder: a plain folder of the recorded name is
    not taken for the log."""
    log = tmp_path / "run"
    shutil.copytree(bags["folder"]["log"], log)
    out = tmp_path / "out"
    ok(invoke("detect", log, "-o", out))
    tl = out / "run.timeline.json"
    (log / "metadata.yaml").unlink()
    r = invoke("report", tl, "-o", tmp_path / "r.html")
    assert r.exit_code == 3
    assert f"the log it records, {log}, is not found" in r.stderr


def _plain_args(verb: str, d: Path, tmp: Path, bags: dict[str, dict[str, Path]]) -> list[object]:
    return {
        "inspect": ["inspect", d],
        "inspect-json": ["inspect", d, "--json"],
        "identify": ["identify", d, "-o", tmp / "model.json"],
        "calibrate": ["calibrate", d, "-o", tmp / "config.toml"],
        "calibrate-second": ["calibrate", bags["db3"]["free1"], d, "-o", tmp / "config.toml"],
        "detect": ["detect", d, "-o", tmp / "out"],
        "evaluate": ["evaluate", d],  # before looking for labels beside it
        "evaluate-labels": ["evaluate", d, "--labels",
                            bags["db3"]["log"].with_name("run_db3.labels.json")],
        "report": ["report", d, "-o", tmp / "r.html"],
        "view": ["view", d, "--no-open", "--save", tmp / "x.rrd"],
        "labels": ["labels", d, "--from-channel", "x", "--above", "1", "--link", "1",
                   "-o", tmp / "l.json"],
    }[verb]


@pytest.mark.parametrize("verb", ["inspect", "inspect-json", "identify", "calibrate",
                                  "calibrate-second", "detect", "evaluate", "evaluate-labels",
                                  "report", "view", "labels"])
def test_a_plain_folder_is_a_data_error_in_every_verb(bags: dict[str, dict[str, Path]],
                                                      verb: str, tmp_path: Path) -> None:
    d = bags["plain"]["log"]
    r = invoke(*_plain_args(verb, d, tmp_path, bags))
    assert r.exit_code == 3, (r.output, r.stderr)
    # a folder that is not a bag stands for the logs in it (tests/test_paths_folders.py)
    assert r.stderr == (f"impactcli: error: {d}: a folder without any log (looked for "
                        ".csv.gz, .csv, .mcap, .npz, .bag, .db3 files or rosbag2 folders "
                        "(with metadata.yaml), directly inside it)\n")
    assert r.stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # nothing written
