"""``impactcli simulate`` and the sample-log manifest."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.logs import read_log
from impactcli.logs.robot_files import read_labels, read_robot
from impactcli.sim import scenario, simulate
from impactcli.sim.sample_logs import MANIFEST


def _run(args: list[str]):
    res = CliRunner().invoke(main, args)
    return res, f"exit {res.exit_code}\nstdout:\n{res.stdout}\nstderr:\n{res.stderr}"


def test_simulate_writes_log_labels_and_robot(tmp_path):
    res, msg = _run(["simulate", "--scenario", "pushes", "--duration", "10", "--seed", "3",
                     "-o", str(tmp_path), "--format", "csv.gz", "--format", "mcap-json"])
    assert res.exit_code == 0, msg
    expect = simulate(scenario("pushes", "assist_like", 10.0), seed=3)
    for name in ("pushes.csv.gz", "pushes.mcap"):
        log = read_log(tmp_path / name)
        np.testing.assert_allclose(log.position, expect.log.position, atol=1e-12)
        np.testing.assert_allclose(log.torque, expect.log.torque, atol=1e-12)
        np.testing.assert_array_equal(log.t_ns, expect.log.t_ns)
        assert log.joint_names == ("shoulder", "elbow")
    labels = read_labels(tmp_path / "pushes.labels.json")
    assert labels.to_dict()["events"] == expect.labels.to_dict()["events"]
    assert labels.sample_rate == pytest.approx(250.0)
    assert [e.kind for e in labels.events] == ["push"]
    robot = read_robot(tmp_path / "pushes.robot.json")
    assert robot.joint_names == ("shoulder", "elbow")
    assert robot.kinematics["link_lengths"] == [0.4, 0.4]
    assert "pushes.labels.json" in res.stdout


def test_simulate_ros2_heavy(tmp_path):
    res, msg = _run(["simulate", "--arm", "heavy_geared", "--scenario", "free_p2p",
                     "--duration", "1", "-o", str(tmp_path), "--format", "mcap-ros2",
                     "--name", "h"])
    assert res.exit_code == 0, msg
    log = read_log(tmp_path / "h.mcap")
    assert log.n_joints == 3 and log.sample_rate_hz == pytest.approx(500.0)
    assert log.has_reference


def test_simulate_refuses_two_mcap_encodings(tmp_path):
    res, msg = _run(["simulate", "-o", str(tmp_path), "--format", "mcap-json",
                     "--format", "mcap-ros2"])
    assert res.exit_code == 2, msg
    assert "mcap" in res.stderr


def test_simulate_bad_scenario_is_usage_error(tmp_path):
    res, msg = _run(["simulate", "-o", str(tmp_path), "--scenario", "nope"])
    assert res.exit_code == 2, msg


def test_manifest_covers_the_brief():
    names = [e.name for e in MANIFEST]
    assert len(set(names)) == len(names)
    assist_free = {e.scenario for e in MANIFEST if e.arm == "assist_like"
                   and e.scenario.startswith("free_")}
    assert len(assist_free) >= 3
    kinds = {(e.arm, e.scenario) for e in MANIFEST}
    for need in [("assist_like", "impacts"), ("assist_like", "pushes"),
                 ("assist_like", "clamps"), ("assist_like", "payload"),
                 ("heavy_geared", "impacts")]:
        assert need in kinds
    assert any(e.arm == "heavy_geared" and e.scenario.startswith("free_") for e in MANIFEST)
    assert {e.mcap_encoding for e in MANIFEST} == {"json", "ros2"}


def _csv_columns(path) -> list[str]:
    return path.read_text(encoding="utf-8").splitlines()[0].split(",")


@pytest.mark.parametrize("flag", ["--controller-channels", None])
def test_simulate_controller_channels_on_assist_like(tmp_path, flag):
    """assist_like logs the controller's channels by default, as its sample logs do."""
    args = ["simulate", "--arm", "assist_like", "--scenario", "pushes", "--duration", "2",
            "-o", str(tmp_path), "--format", "csv"] + ([flag] if flag else [])
    res, msg = _run(args)
    assert res.exit_code == 0, msg
    cols = _csv_columns(tmp_path / "pushes.csv")
    for joint in ("shoulder", "elbow"):
        assert f"{joint}.torque_model" in cols, cols
        assert f"{joint}.torque_ext" in cols, cols
    log = read_log(tmp_path / "pushes.csv")
    assert log.torque_model is not None and log.torque_ext is not None


def test_simulate_no_controller_channels(tmp_path):
    res, msg = _run(["simulate", "--arm", "assist_like", "--scenario", "pushes",
                     "--duration", "2", "-o", str(tmp_path), "--format", "csv",
                     "--no-controller-channels"])
    assert res.exit_code == 0, msg
    cols = _csv_columns(tmp_path / "pushes.csv")
    assert "shoulder.torque" in cols
    assert not [c for c in cols if c.endswith((".torque_model", ".torque_ext"))], cols


def test_simulate_controller_channels_default_off_on_heavy_geared(tmp_path):
    res, msg = _run(["simulate", "--arm", "heavy_geared", "--scenario", "free_p2p",
                     "--duration", "1", "-o", str(tmp_path / "off"), "--format", "csv"])
    assert res.exit_code == 0, msg
    cols = _csv_columns(tmp_path / "off" / "free_p2p.csv")
    assert not [c for c in cols if c.endswith((".torque_model", ".torque_ext"))], cols
    res, msg = _run(["simulate", "--arm", "heavy_geared", "--scenario", "free_p2p",
                     "--duration", "1", "-o", str(tmp_path / "on"), "--format", "csv",
                     "--controller-channels"])
    assert res.exit_code == 0, msg
    cols = _csv_columns(tmp_path / "on" / "free_p2p.csv")
    for joint in ("j1", "j2", "j3"):
        assert f"{joint}.torque_model" in cols and f"{joint}.torque_ext" in cols, cols


def test_simulate_controller_channels_default_mirrors_the_sample_logs():
    """The default --help states is the sample set's: CONTROLLER_CHANNEL_ARMS."""
    from impactcli.cli.simulate import ARMS
    from impactcli.sim.sample_logs import CONTROLLER_CHANNEL_ARMS

    res, msg = _run(["simulate", "--help"])
    assert res.exit_code == 0, msg
    text = " ".join(res.stdout.split())
    assert "--controller-channels / --no-controller-channels" in text
    on = [a for a in ARMS if a in CONTROLLER_CHANNEL_ARMS]
    off = [a for a in ARMS if a not in CONTROLLER_CHANNEL_ARMS]
    assert on == ["assist_like"] and off == ["heavy_geared"]
    assert "[default: on for assist_like, off for heavy_geared, as in the sample logs]" in text


def test_simulate_into_a_folder_it_cannot_make_is_a_usage_error(tmp_path):
    """A trial's ``-o <file>/x`` gave a traceback and exit 70: now one line naming the
    output, exit 2 (README), before any simulation, and nothing written."""
    blocker = tmp_path / "afile"
    blocker.write_text("x", "utf-8")
    res, msg = _run(["simulate", "--scenario", "free_p2p", "--duration", "1", "-o",
                     str(blocker / "x")])
    assert res.exit_code == 2, msg
    assert res.stderr.strip().splitlines() == [
        f"impactcli: error: cannot write {blocker / 'x' / 'free_p2p.csv.gz'}: a part of its "
        "folder path is a file, not a folder"], msg
    assert "Traceback" not in res.output and sorted(tmp_path.iterdir()) == [blocker]


def test_simulate_says_the_load_it_carried(tmp_path):
    """A trial could not score the start load: the summary line names it and the changes,
    as the scenario sets them."""
    res, msg = _run(["simulate", "--scenario", "pick_and_place", "--duration", "12",
                     "--payload-kg", "0.5", "-o", str(tmp_path)])
    assert res.exit_code == 0, msg
    sc = scenario("pick_and_place", "assist_like", 12.0, payload_kg=0.5)
    (pick, kg), (place, after) = sc.payload_changes
    assert res.stdout.splitlines()[0].endswith(
        f", carrying 0.5 kg at the flange from the start; the load set to {kg:g} kg at "
        f"{pick:.3f} s, {after:g} kg at {place:.3f} s"), res.stdout
    res, msg = _run(["simulate", "--scenario", "pushes", "--duration", "5", "-o",
                     str(tmp_path / "p")])
    assert res.exit_code == 0, msg
    assert "carrying" not in res.stdout and "the load set" not in res.stdout
