"""Payloads on the controller's residual (impactcli/run/loads.py, ``weighable``): a config
whose residual is the controller's external-torque estimate corrected by the tool's model
(``logged_external``, the default where a log carries ``torque_ext``) weighs the load a log
starts with and tells payload changes from contacts, as the tool's own model does
(docs/models.md, "Payloads"). Through the CLI, against the simulator's truth."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from impactcli.cli import main

REPO = Path(__file__).resolve().parents[1]


def _cli(*args: str) -> Any:
    r = CliRunner().invoke(main, list(args))
    assert r.exit_code == 0, r.output
    return r


def _timeline(out: Path, stem: str) -> dict[str, Any]:
    return json.loads((out / f"{stem}.timeline.json").read_text("utf-8"))


def test_the_sample_payload_log_is_weighed_on_the_controller_residual(tmp_path: Path) -> None:
    """The sample ASSIST-like config (controller channels, planar model) on the sample log
    that carries a 0.5 kg payload its calibration logs did not: the load is weighed on the
    warm-up and carried, and nothing is counted — before, the load was a lasting load and
    an incident, "payloads: not weighed"."""
    log = REPO / "sample_logs" / "csv" / "assist_payload.csv.gz"
    r = _cli("detect", str(log), "--config", str(REPO / "sample_logs" / "assist_like.config.toml"),
             "-o", str(tmp_path))
    tl = _timeline(tmp_path, "assist_payload")
    assert {g["generator"] for g in tl["replay"]["generator"].values()} == {"logged_external"}
    load = tl["input"]["payload"]
    assert load["verdict"] == "used" and abs(load["mass_kg"] - 0.5) < 0.1 * 0.5
    assert tl["counts"]["incidents"]["counted"] == 0
    assert tl["counts"]["lasting_loads"]["counted"] == 0
    assert tl["payload_changes"] == []
    assert "not weighed" not in r.stdout and "not weighed" not in r.stderr


@pytest.fixture(scope="module")
def pick_and_place(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Robot 7 of the ASSIST-like arm with its controller's channels: calibrated by default
    (``logged_external``) on three collision-free logs, then its 45 s pick-and-place (1 kg
    picked at 15 s, released at 30 s, four pushes) detected: the timeline and labels."""
    out = tmp_path_factory.mktemp("controller_pnp")
    for k, sc in enumerate(("free_triangle", "free_p2p", "free_multisine")):
        _cli("simulate", "--scenario", sc, "--robot-seed", "7", "--seed", str(41 + k),
             "-o", str(out), "--name", sc)
    _cli("calibrate", *(str(out / f"{sc}.csv.gz") for sc in ("free_triangle", "free_p2p",
                                                              "free_multisine")),
         "--robot", str(out / "free_triangle.robot.json"), "-o", str(out / "cal.toml"))
    _cli("simulate", "--scenario", "pick_and_place", "--robot-seed", "7", "--seed", "21",
         "--duration", "45", "-o", str(out), "--name", "pnp")
    _cli("detect", str(out / "pnp.csv.gz"), "--config", str(out / "cal.toml"), "-o",
         str(out / "run"))
    return {"tl": _timeline(out / "run", "pnp"),
            "labels": json.loads((out / "pnp.labels.json").read_text("utf-8"))}


def test_a_pick_and_a_release_are_payload_changes_not_contacts(
        pick_and_place: dict[str, Any]) -> None:
    tl, labels = pick_and_place["tl"], pick_and_place["labels"]
    assert {g["generator"] for g in tl["replay"]["generator"].values()} == {"logged_external"}
    truth = labels["payload_changes"]
    found = tl["payload_changes"]
    assert len(found) == len(truth) == 2
    for f, t in zip(found, truth, strict=True):
        assert abs(f["t_start"] - t["t_s"]) < 1.0
        assert abs(f["mass_kg"] - t["mass_kg"]) < 0.25 * abs(t["mass_kg"])
    counted = [i for i in tl["incidents"] if i.get("number") is not None]
    for t in truth:  # neither change counted as a contact
        assert not [i for i in counted if abs(i["t_start"] - t["t_s"]) < 1.0]


def test_contacts_while_carrying_are_still_caught(pick_and_place: dict[str, Any]) -> None:
    tl, labels = pick_and_place["tl"], pick_and_place["labels"]
    picked, released = (c["t_s"] for c in labels["payload_changes"])
    carried = [e for e in labels["events"] if picked < e["start"] < released]
    assert carried  # the scenario pushes while the load is carried
    counted = [i for i in tl["incidents"] if i.get("number") is not None]
    for e in carried:
        assert [i for i in counted if e["start"] - 0.02 <= i["t_start"] <= e["end"] + 0.25], e


def test_no_payload_change_found_says_how_large_one_it_could_have_seen(
        tmp_path: Path) -> None:
    """A run that watched for payload changes and found none says the least load it could
    have seen: a weight at the flange turns joint k by at most |J_k| times itself, so one
    under min_k vL_k / |J_k| reaches no loading threshold (a trial's 1 kg pick and release
    passed in silence under a ~21 N floor). The sample pushes log (no load changes) on the
    sample config. Physics bounds the figure: no larger than the last link's own step
    floor (the elbow alone), no smaller than the least vL over the arm's reach (the longest
    lever any joint has to the flange)."""
    from impactcli.detect.floor import payload_floor
    from impactcli.types import GRAVITY_M_S2

    log = REPO / "sample_logs" / "csv" / "assist_pushes.csv.gz"
    summary = tmp_path / "s.json"
    r = _cli("detect", str(log), "--config", str(REPO / "sample_logs" / "assist_like.config.toml"),
             "-o", str(tmp_path), "--summary", str(summary))
    tl = _timeline(tmp_path, "assist_pushes")
    assert tl["payload_changes"] == []
    floor = tl["detection_floor"]
    step = floor["payload_step"]
    assert step["kg"] == pytest.approx(step["force_n"] / GRAVITY_M_S2)
    last = max(floor["per_link"], key=lambda x: x["link"])
    assert step["force_n"] <= last["static_loading"]["median_n"] * (1 + 1e-9)
    robot = json.loads((REPO / "sample_logs" / "csv" / "assist_pushes.robot.json")
                       .read_text("utf-8"))
    reach = sum(robot["kinematics"]["link_lengths"])
    least_vl = min(v["static_loading"]["median_nm"] for v in floor["per_joint"].values())
    assert step["force_n"] >= least_vl / reach
    kg, link, force = payload_floor(floor)  # type: ignore[misc]
    assert (kg, link, force) == (step["kg"], 2, step["force_n"])
    (line,) = [ln for ln in r.stdout.splitlines() if ln.startswith("payload changes of")]
    assert line == (
        f"payload changes of assist_pushes.csv.gz: none found — a load under ~{kg:.2g} kg "
        "picked or released at the flange (the end of link 2) would not have crossed the "
        f"loading thresholds (its weight, under ~{force:.2g} N, turns no joint to its "
        "threshold at the log's median moment); a lower bound, not a promise that a heavier "
        "one was seen")
    row = json.loads(summary.read_text("utf-8"))["results"][0]
    assert row["payload_floor"] == pytest.approx({"kg": kg, "link": 2, "force_n": force})
    # no payload step (no kinematics, no lever to the flange), or no floor: none
    assert payload_floor({"per_link": floor["per_link"]}) is None and payload_floor(None) is None


def test_calibration_logs_with_different_loads_get_a_payload_each_on_the_channel(
        tmp_path: Path) -> None:
    """Calibrated by default on the controller's channel, free logs of one robot with no
    load and one with 1 kg: the correction model fits a payload per log (held out clearly
    better than one load), the loaded log's +1 kg, so the thresholds are not widened by the
    load; a log that starts with that 1 kg is then carried as that log's load, with no
    lasting load. Before, the channel fitted one load across the logs ("not fitted")."""
    for k, (sc, kg) in enumerate((("free_triangle", 0.0), ("free_p2p", 0.0),
                                  ("free_multisine", 0.0), ("free_multisine", 1.0))):
        _cli("simulate", "--scenario", sc, "--robot-seed", "7", "--seed", str(41 + k),
             "--payload-kg", str(kg), "-o", str(tmp_path), "--name", f"{sc}_{k}")
    logs = [str(tmp_path / f"{sc}_{k}.csv.gz") for k, sc in enumerate(
        ("free_triangle", "free_p2p", "free_multisine", "free_multisine"))]
    r = _cli("calibrate", *logs, "--robot", str(tmp_path / "free_triangle_0.robot.json"),
             "-o", str(tmp_path / "cal.toml"))
    assert ("chosen: a payload per log (clearly better held out)") in r.stdout, r.stdout
    from impactcli.config import load_config
    from impactcli.model import RigidModel, payload

    cfg = load_config(tmp_path / "cal.toml")
    assert set(cfg.residual.generators.values()) == {"logged_external"}
    model = RigidModel.from_dict(cfg.model)
    bb = payload.basis(model.kind, model.joint_names, model.structure)
    assert bb is not None
    loads = {Path(log).name: pi for log, pi in payload.calibration_loads(model, bb[1])}
    m = bb[1].index("m")
    base = min(float(pi[m]) for pi in loads.values())
    assert abs(float(loads["free_multisine_3.csv.gz"][m]) - base - 1.0) < 0.1, loads
    # the motion of the loaded calibration log (a multi-sine): a known load is known on
    # the motion it was carried in — on point-to-point moves, which no loaded log covered,
    # this robot's channel raised 70 static-loading alarms of 1–2.5 N (the tool's own model
    # 45 adaptive ones): calibration must cover the motion with each load
    _cli("simulate", "--scenario", "free_multisine", "--robot-seed", "7", "--seed", "51",
         "--payload-kg", "1", "-o", str(tmp_path), "--name", "carried")
    _cli("detect", str(tmp_path / "carried.csv.gz"), "--config", str(tmp_path / "cal.toml"),
         "-o", str(tmp_path / "run"))
    tl = _timeline(tmp_path / "run", "carried")
    assert tl["input"]["payload"]["verdict"] == "used"
    assert Path(tl["input"]["payload"]["as_log"]).name == "free_multisine_3.csv.gz"
    assert tl["counts"]["lasting_loads"]["counted"] == 0
    assert tl["counts"]["incidents"]["counted"] == 0  # free motion carrying a known load
