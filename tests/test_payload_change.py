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


def test_the_payload_changes_head_says_which_the_gates_cannot_judge() -> None:
    """A trial's heavy arm: both changes said "its inertia not seen (a steady press along
    gravity would look the same)" under a head that said they fail no gate, while
    --fail-on-detect said it could not judge them."""
    from impactcli.cli.detect import payload_changes_head

    mass = {"mass_kg": 2.0, "mass_se_kg": 0.01, "explained": 0.99, "t_start": 20.0,
            "t_classified": 23.0, "values": {"m": 2.0}}
    assert payload_changes_head("a.csv", [mass, mass]) == (
        "payload changes of a.csv (a load picked or released: not incidents, failing no "
        "gate; the residual takes the new load from the classification on):")
    assert payload_changes_head("a.csv", [mass, {**mass, "inertia": "unseen"}]) == (
        "payload changes of a.csv (a load picked or released: not incidents, 1 of them not "
        "told from a steady press, which the gates cannot judge (--fail-on-detect: exit 5; "
        "--fail-on-force N: when its press would pass N); the residual takes the new load "
        "from the classification on):")
