"""A folder that is not a rosbag2 bag stands for the logs in it: every
log of it for the verbs that take many (``detect``, ``report``), its one log for the verbs
that read one; several logs for those are a usage error (exit 2) listing them, a folder
without a log a data error (exit 3) naming what was looked for."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from impactcli.logs.paths import LOG_SUFFIXES
from impactcli.logs.urls import expand_inputs

from .cli_run import cli

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "sample_logs"
CONFIG = SAMPLES / "assist_like.config.toml"
P2P = SAMPLES / "csv" / "assist_free_p2p.csv.gz"
MCAP = SAMPLES / "mcap" / "assist_free_triangle.mcap"
LOOKED_FOR = (f"{', '.join(LOG_SUFFIXES)} files or rosbag2 folders (with metadata.yaml), "
              "directly inside it")


def _errors(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ln.startswith("impactcli: error:")]


@pytest.fixture
def two_logs(tmp_path: Path) -> Path:
    """A folder of two logs (a CSV and an MCAP), a note, a labels file and a hidden file."""
    d = tmp_path / "runs"
    d.mkdir()
    shutil.copy(P2P, d / "b_p2p.csv.gz")
    shutil.copy(MCAP, d / "a_triangle.mcap")
    (d / "notes.txt").write_text("arm 3, day 2\n")
    (d / ".b_p2p.csv.gz.swp").write_bytes(b"\x00")
    shutil.copy(SAMPLES / "csv" / "assist_free_p2p.labels.json", d / "b_p2p.labels.json")
    (d / "sub").mkdir()
    shutil.copy(P2P, d / "sub" / "deeper.csv.gz")  # not recursive
    return d


def test_the_logs_of_a_folder_sorted_and_not_recursive(two_logs: Path) -> None:
    assert expand_inputs([str(two_logs)]) == [str(two_logs / "a_triangle.mcap"),
                                             str(two_logs / "b_p2p.csv.gz")]
    url = f"file://{two_logs}"
    assert expand_inputs([url]) == [f"file://{two_logs / 'a_triangle.mcap'}",
                                    f"file://{two_logs / 'b_p2p.csv.gz'}"]
    # a glob of folders: the logs of each
    assert expand_inputs([str(two_logs.parent / "run*")]) == expand_inputs([str(two_logs)])


def test_detect_and_report_read_every_log_of_a_folder(two_logs: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    code, stdout, err = cli("detect", two_logs, "--config", CONFIG, "-o", out)
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["a_triangle.timeline.json",
                                                     "b_p2p.timeline.json"]
    assert "batch: 2 done, 0 failed of 2 logs" in stdout
    code, _, err = cli("report", two_logs, "--config", CONFIG, "-o", tmp_path / "r.html",
                       "--json", tmp_path / "r.json")
    assert code == 0, err
    rep = json.loads((tmp_path / "r.json").read_text())
    assert [Path(x["input"]["path"]).name for x in rep["logs"]] == ["a_triangle.mcap",
                                                                     "b_p2p.csv.gz"]


def test_a_verb_reading_one_log_reads_a_folders_one_log(tmp_path: Path) -> None:
    d = tmp_path / "one"
    d.mkdir()
    shutil.copy(P2P, d / "run.csv.gz")
    (d / "README.md").write_text("free motion\n")
    code, out, err = cli("inspect", d, "--json")
    assert code == 0, err
    assert json.loads(out)["path"] == str(d / "run.csv.gz")
    code, out, err = cli("labels", d, "--from-channel", "shoulder.torque_ext", "--above", "5",
                         "--link", "1", "-o", tmp_path / "l.json")
    assert code == 0, err
    assert json.loads((tmp_path / "l.json").read_text())["source"]["log"] == str(
        d / "run.csv.gz")
    code, _, err = cli("identify", d, "-o", tmp_path / "m.json")
    assert code == 0, err


def test_a_folder_of_several_logs_for_a_verb_reading_one_is_a_usage_error(
        tmp_path: Path) -> None:
    d = tmp_path / "many"
    d.mkdir()
    for k in range(12):
        shutil.copy(P2P, d / f"r{k:02d}.csv.gz")
    names = ", ".join(f"r{k:02d}.csv.gz" for k in range(10))
    want = (f"impactcli: error: {d}: a folder of 12 logs ({names}, … and 2 more), and this "
            "verb reads one: name the log (detect and report read every log of a folder)")
    for verb in (["inspect"], ["identify", "-o", tmp_path / "m.json"],
                 ["labels", "--from-channel", "x", "--above", "1", "--link", "1", "-o",
                  tmp_path / "l.json"]):
        code, _, err = cli(verb[0], d, *verb[1:])
        assert code == 2, (verb, err)
        assert _errors(err) == [want], verb
    two = tmp_path / "two"
    two.mkdir()
    shutil.copy(P2P, two / "a.csv.gz")
    shutil.copy(MCAP, two / "b.mcap")
    code, _, err = cli("inspect", two)
    assert code == 2
    assert _errors(err) == [f"impactcli: error: {two}: a folder of 2 logs (a.csv.gz, b.mcap), "
                            "and this verb reads one: name the log (detect and report read "
                            "every log of a folder)"]


@pytest.mark.parametrize("content", ["empty", "no_log"])
def test_a_folder_without_a_log_is_a_data_error_naming_what_was_looked_for(
        tmp_path: Path, content: str) -> None:
    d = tmp_path / content
    d.mkdir()
    if content == "no_log":
        (d / "notes.txt").write_text("x\n")
        (d / "arm.robot.json").write_text("{}\n")
    want = f"impactcli: error: {d}: a folder without any log (looked for {LOOKED_FOR})"
    for verb in (["inspect"], ["detect", "-o", tmp_path / "o"]):
        code, _, err = cli(verb[0], d, *verb[1:])
        assert code == 3, (verb, err)
        assert _errors(err) == [want], verb


def test_a_rosbag2_folder_inside_a_folder_is_one_of_its_logs(tmp_path: Path) -> None:
    from impactcli.logs import read_log
    from impactcli.logs.write import write_rosbag2

    d = tmp_path / "day"
    d.mkdir()
    write_rosbag2(read_log(P2P), d / "bag")  # a rosbag2 folder
    assert (d / "bag" / "metadata.yaml").is_file()
    code, out, err = cli("inspect", d, "--json")
    assert code == 0, err
    assert json.loads(out)["format"] == "rosbag2"
    assert expand_inputs([str(d)]) == [str(d / "bag")]
