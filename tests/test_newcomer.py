"""A newcomer's first hour: what inspect says about a log it cannot convert yet, an unknown
channel map's name and a glob that matches nothing — one clear line and the documented
exit code in every verb."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.logs import write_log

from .conftest import make_log

SAMPLE = str(Path(__file__).resolve().parents[1] / "sample_logs" / "csv"
             / "assist_pushes.csv.gz")


def current_only_csv(tmp: Path) -> Path:
    log = make_log(n=2500)
    log = dataclasses.replace(log, current=np.asarray(log.torque) / 2.0)
    write_log(log, tmp / "full.csv")
    lines = (tmp / "full.csv").read_text().splitlines()
    head = lines[0].split(",")
    keep = [k for k, c in enumerate(head) if not c.endswith(".torque")]
    out = tmp / "currents.csv"
    out.write_text("\n".join(",".join(row.split(",")[k] for k in keep) for row in lines) + "\n")
    return out


def test_inspect_describes_a_log_it_cannot_convert_yet(tmp_path: Path) -> None:
    path = current_only_csv(tmp_path)
    r = CliRunner().invoke(main, ["inspect", str(path)])
    assert r.exit_code == 0, r.output
    assert ("current of j1, j2 not converted to torque: needs a robot description (--robot) "
            "with gear_ratio and torque_constant") in r.output
    assert "joints          2: j1, j2" in r.output or "2: j1, j2" in r.output
    r = CliRunner().invoke(main, ["detect", str(path), "-o", str(tmp_path / "o")])
    assert r.exit_code == 3
    assert "joint 'j1' has only current; converting it to torque needs a robot" in r.output


@pytest.mark.parametrize("verb,extra", [
    ("inspect", []), ("identify", ["-o", "OUT.json"]), ("detect", ["-o", "OUT"]),
    ("calibrate", ["-o", "OUT.toml"]), ("evaluate", []), ("report", ["-o", "OUT.html"]),
    ("view", ["--no-open"]),
    ("labels", ["--from-channel", "x", "--above", "1", "--link", "1", "-o", "OUT.json"]),
])
def test_unknown_channel_map_name_is_a_usage_error_in_every_verb(
        verb: str, extra: list[str], tmp_path: Path) -> None:
    args = [verb, SAMPLE, "--channel-map", "no_such_map",
            *[a.replace("OUT", str(tmp_path / "out")) for a in extra]]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, r.output
    assert "no_such_map: channel map not found (neither a file nor a shipped map; shipped: " \
        in r.output


@pytest.mark.parametrize("verb,pattern,extra", [
    ("inspect", "*.csv", []), ("inspect", "*.csv", ["--json"]),
    ("identify", "*.csv", ["-o", "OUT/m.json"]), ("calibrate", "*.csv", ["-o", "OUT/c.toml"]),
    ("detect", "*.csv", ["-o", "OUT"]), ("report", "*.csv", ["-o", "OUT/r.html"]),
    ("report", "*.timeline.json", ["-o", "OUT/r.html"]),
    ("evaluate", "*.csv", []), ("evaluate", "*.timeline.json", []),
    ("view", "*.csv", ["--no-open", "--save", "OUT/x.rrd"]), ("view", "*.rrd", ["--no-open"]),
    ("labels", "*.csv", ["--from-channel", "x", "--above", "1", "--link", "1",
                         "-o", "OUT/l.json"]),
])
def test_a_glob_that_matches_nothing_says_so_in_every_verb(
        verb: str, pattern: str, extra: list[str], tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    glob = str(tmp_path / "runs" / pattern)
    r = CliRunner().invoke(main, [verb, glob, *[a.replace("OUT", str(out)) for a in extra]])
    assert r.exit_code == 3, (r.stdout, r.stderr)
    assert r.stderr == f"impactcli: error: {glob}: the pattern matches no file\n"
    assert not list(out.iterdir())  # nothing written


def test_report_and_evaluate_find_the_log_from_any_folder(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    repo = Path(SAMPLE).parents[2]
    monkeypatch.chdir(repo)  # detect with a relative path, as a user in the repo would
    r = CliRunner().invoke(main, ["detect", "sample_logs/csv/assist_pushes.csv.gz", "--config",
                                  "sample_logs/assist_like.config.toml", "-o", str(tmp_path)])
    assert r.exit_code == 0, r.output
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    tl = str(tmp_path / "assist_pushes.timeline.json")
    r = CliRunner().invoke(main, ["evaluate", tl])
    assert r.exit_code == 0, r.output  # the labels found beside the log, via abs_path
    assert "Contacts: 9 counted" in r.output
    r = CliRunner().invoke(main, ["report", tl, "-o", str(tmp_path / "r.html")])
    assert r.exit_code == 0, r.output


def test_identify_takes_the_topic_of_a_multi_arm_mcap(tmp_path: Path) -> None:
    from impactcli.logs.messages.ros2_cdr import JOINT_STATE

    from .message_logs import jointstates, write_mcap

    log = make_log(n=2500, joints=("j1", "j2"))
    rows = jointstates(log.t_ns + 10**18, list(log.joint_names), np.asarray(log.position),
                       np.asarray(log.torque))
    p = tmp_path / "two_arms.mcap"
    write_mcap(p, [("/left/joint_states", JOINT_STATE, "ros2msg", "cdr", rows),
                   ("/right/joint_states", JOINT_STATE, "ros2msg", "cdr", rows)])
    r = CliRunner().invoke(main, ["identify", str(p), "-o", str(tmp_path / "m.json")])
    assert r.exit_code == 3
    assert "/left/joint_states" in r.output and "/right/joint_states" in r.output
    r = CliRunner().invoke(main, ["identify", str(p), "--topic", "/right/joint_states",
                                  "-o", str(tmp_path / "m.json")])
    assert r.exit_code == 0, r.output
