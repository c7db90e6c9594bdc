"""A release the log could not have made (impactcli/detect/payload_change.py): a step that
would take off more than the arm was seen to carry, whose inertia did not show, is a press
along gravity, not a payload change — through the CLI on the robot a trial found it on."""

from __future__ import annotations

import json
from pathlib import Path

from .cli_run import cli


def test_a_clamp_is_not_taken_for_a_release_of_a_load_never_carried(tmp_path: Path) -> None:
    """The heavy geared arm, robot 79 (a trial's), calibrated on its free triangle, p2p,
    multi-sine and fm-triangle logs (seeds 21-24). Its clamps log (seed 33) holds four
    clamps on link 3 (20, 30, 40, 25 N), no load. The fourth read "P1 −2.34 kg … this mass
    cannot be trusted" and "P2 +2.34 kg" at its end, and left the count: 3 incidents for 4
    clamps. A release of 2.34 kg from an arm seen with none, its inertia not seen, is a
    press: the four clamps are four incidents, no payload change, each tried and said so."""
    def sim(name: str, scenario: str, seed: int) -> Path:
        code, _, err = cli("simulate", "--arm", "heavy_geared", "--robot-seed", "79",
                             "--scenario", scenario, "--seed", seed, "-o", tmp_path,
                             "--name", name)
        assert code == 0, err
        return tmp_path / f"{name}.csv.gz"

    free = [sim(f"f{s}", sc, s) for s, sc in ((21, "free_triangle"), (22, "free_p2p"),
                                               (23, "free_multisine"),
                                               (24, "free_fm_triangle"))]
    log = sim("clamps", "clamps", 33)
    code, _, err = cli("calibrate", *free, "--robot", tmp_path / "f21.robot.json", "-o",
                       tmp_path / "c.toml")
    assert code == 0, err
    code, _, err = cli("detect", log, "--config", tmp_path / "c.toml", "-o", tmp_path / "o")
    assert code == 0, err
    tl = json.loads((tmp_path / "o" / "clamps.timeline.json").read_text())
    labels = json.loads((tmp_path / "clamps.labels.json").read_text())["events"]
    assert [(e["kind"], e["link"]) for e in labels] == [("clamp", 3)] * 4
    counted = [i for i in tl["incidents"] if i["number"]]
    assert len(counted) == 4 and not tl.get("payload_changes"), (counted, tl["payload_changes"])
    for e, i in zip(labels, counted, strict=True):
        assert e["start"] <= i["t_start"] <= e["end"] and i["link"] == 3
    last = counted[-1]
    assert "its inertia did not show: a press along gravity" in last["payload_test"]
    assert abs(last["force_n"] - 25.0) < 0.25 * 25.0
