"""``impactcli inspect``: JSON output valid against schemas/inspect.schema.json, numbers right."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.errors import ImpactError, ImpactWarning
from impactcli.logs import inspect_log, write_log
from impactcli.schema import validate
from impactcli.types import RobotLog

from .conftest import make_log


def _gappy_log() -> RobotLog:
    base = make_log(n=300, joints=("a", "b"))
    t = np.arange(300, dtype=np.int64) * 4_000_000
    t[200:] += 40_000_000  # one 44 ms gap after sample 199
    return RobotLog(t_ns=t, joint_names=base.joint_names, position=base.position,
                    torque=base.torque, position_ref=base.position_ref)


def test_inspect_json_validates_and_describes(tmp_path: Path) -> None:
    p = tmp_path / "g.csv"
    write_log(_gappy_log(), p)
    res = CliRunner().invoke(main, ["inspect", str(p), "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    validate(d, "inspect", ImpactError, "inspect output")
    assert d["joints"] == ["a", "b"] and d["format"] == "csv"
    assert d["n_samples"] == 300 and d["reference"] is True
    assert d["duration_s"] == pytest.approx(299 * 0.004 + 0.040)
    assert d["sample_rate_hz"] == pytest.approx(250.0)
    assert d["gaps"]["count"] == 1
    assert d["gaps"]["listed"][0] == {"sample": 199, "t_s": pytest.approx(0.796),
                                      "length_s": pytest.approx(0.044)}
    assert d["jitter"]["dt_max_s"] == pytest.approx(0.044)
    assert d["torque_source"] == "torque" and d["time_source"] == "column"
    assert "a.position_ref" in d["channels"]["used"]
    assert d["repairs"] == [] and d["channels"]["ignored"] == []


def test_inspect_gives_each_channels_range_per_joint(tmp_path: Path) -> None:
    """inspect describes the scan: every array's smallest and largest value per joint,
    as the log's arrays hold them (a controller channel a joint does not log: null), in
    the JSON and on a line of the table; for CSV and MCAP copies alike."""
    log = _gappy_log()
    tm = np.array(log.torque) * 0.5
    tm[:, 1] = np.nan  # joint b does not log torque_model
    log = RobotLog(t_ns=log.t_ns, joint_names=log.joint_names, position=log.position,
                   torque=log.torque, position_ref=log.position_ref, torque_model=tm)
    for name in ("g.csv", "g.mcap"):
        p = tmp_path / name
        write_log(log, p)
        with warnings.catch_warnings():  # the MCAP's empty column is a warned repair
            warnings.simplefilter("ignore", ImpactWarning)
            d = inspect_log(p)
        assert list(d["ranges"]) == ["position", "torque", "position_ref", "torque_model"]
        for sig, per in d["ranges"].items():
            a = getattr(log, sig)
            for k, j in enumerate(log.joint_names):
                if np.isnan(a[:, k]).all():
                    assert per[j] is None
                else:
                    assert per[j] == [float(np.nanmin(a[:, k])), float(np.nanmax(a[:, k]))]
    table = CliRunner().invoke(main, ["inspect", str(tmp_path / "g.csv")]).stdout
    assert f"torque_model range: a {np.min(tm[:, 0]):.4g}…{np.max(tm[:, 0]):.4g}" in table


def test_inspect_imports_no_model() -> None:
    """``impactcli inspect`` starts without importing the model package (its read options
    come from cli/options, not cli/detect)."""
    import subprocess
    import sys

    code = ("import sys, impactcli.cli.inspect, impactcli.cli.labels; "
            "print(any(m.startswith(('impactcli.model', 'impactcli.cli.detect')) "
            "for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


def test_inspect_table_and_repairs_warned_on_stderr(tmp_path: Path) -> None:
    p = tmp_path / "r.csv"
    p.write_text("time,j.position,j.torque,note\n0,0,1,x\n0.01,,1,y\n0.02,0.2,1,z\n")
    res = CliRunner().invoke(main, ["inspect", str(p)])
    assert res.exit_code == 0, res.stderr
    assert "impactcli: warning:" in res.stderr and "interpolated 1" in res.stderr
    assert "joints" in res.stdout and "note" in res.stdout and "repair:" in res.stdout
    with pytest.warns(ImpactWarning):
        d = inspect_log(p)
    assert d["channels"]["ignored"] == ["note"] and len(d["repairs"]) == 1


def test_inspect_mcap_ros2(tmp_path: Path) -> None:
    p = tmp_path / "x.mcap"
    write_log(make_log(n=100), p, mcap_encoding="ros2")
    res = CliRunner().invoke(main, ["inspect", str(p), "--json", "--time-source", "log"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    validate(d, "inspect", ImpactError, "inspect output")
    assert d["format"] == "mcap-ros2" and d["time_source"] == "log" and d["reference"]


@pytest.mark.real_logs
def test_inspect_real_logs_by_short_map_name(real_logs: Path) -> None:
    for log, cmap, joints in (("ur_ext_observer/link4.csv", "ur_ext_observer", 6),
                              ("kuka_lwr4/measurements_1.npz", "kuka_lwr4", 7)):
        res = CliRunner().invoke(main, ["inspect", str(real_logs / log), "--channel-map",
                                        cmap, "--json"])
        assert res.exit_code == 0, res.stderr
        d = json.loads(res.stdout)
        validate(d, "inspect", ImpactError, "inspect output")
        assert d["n_joints"] == joints and d["repairs"] == []


def test_inspect_with_robot_for_currents(tmp_path: Path) -> None:
    p = tmp_path / "c.csv"
    p.write_text("time,a.position,a.current\n0,0,1\n0.01,0,2\n0.02,0,3\n")
    robot = tmp_path / "robot.yaml"
    robot.write_text(
        "joints: [{name: a, gear_ratio: 100, torque_constant: 0.02}]\nkinematics: null\n"
    )
    res = CliRunner().invoke(main, ["inspect", str(p), "--robot", str(robot), "--json"])
    assert res.exit_code == 0, res.stderr
    assert json.loads(res.stdout)["torque_source"] == "current"


def test_inspect_says_how_many_of_the_gaps_it_lists(tmp_path: Path) -> None:
    """45 gaps: 20 are listed, and both the table and the JSON say 20 of 45."""
    base = make_log(n=1000, joints=("a",))
    t = base.t_ns.copy()
    for k in range(45):  # a 40 ms gap after samples 19, 39, ..., 899
        t[20 * (k + 1):] += 40_000_000
    p = tmp_path / "gaps45.csv"
    write_log(RobotLog(t_ns=t, joint_names=base.joint_names, position=base.position,
                       torque=base.torque), p)
    res = CliRunner().invoke(main, ["inspect", str(p)])
    assert res.exit_code == 0, res.stderr
    lines = res.stdout.splitlines()
    assert [ln.split()[:2] for ln in lines if ln.startswith("gaps ")] == [["gaps", "45"]]
    listed = [i for i, ln in enumerate(lines) if ln.strip().startswith("gap at ")]
    assert len(listed) == 20
    assert lines[listed[-1] + 1].strip() == "20 of 45 gaps listed"
    res = CliRunner().invoke(main, ["inspect", str(p), "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    validate(d, "inspect", ImpactError, "inspect output")
    assert d["gaps"]["count"] == 45 and d["gaps"]["n_listed"] == 20
    assert len(d["gaps"]["listed"]) == 20 and d["gaps"]["listed"][0]["sample"] == 19


def test_inspect_lists_every_gap_without_a_count_line_when_all_fit(tmp_path: Path) -> None:
    p = tmp_path / "g.csv"
    write_log(_gappy_log(), p)
    res = CliRunner().invoke(main, ["inspect", str(p)])
    assert res.exit_code == 0, res.stderr
    assert "gaps listed" not in res.stdout
    assert json.loads(CliRunner().invoke(main, ["inspect", str(p), "--json"]).stdout)[
        "gaps"]["n_listed"] == 1


def test_inspect_names_the_joints_detection_leaves_out(tmp_path: Path) -> None:
    """j3's torque is all 0.0: inspect says detection leaves it out, and why, as detect
    says it (the reader keeps it: it is not 'dropped')."""
    log = make_log(n=2500, joints=("j1", "j2", "j3"))
    tau = np.array(log.torque) * np.array([10.0, 5.0, 0.0])
    p = tmp_path / "flat.csv"
    write_log(RobotLog(t_ns=log.t_ns, joint_names=log.joint_names, position=log.position,
                       torque=tau), p)
    why = "torque flat: its torque is constant (0 N·m)"
    res = CliRunner().invoke(main, ["inspect", str(p)])
    assert res.exit_code == 0, res.stderr
    rows = {ln.split("  ")[0]: ln.split("  ", 1)[1].strip() for ln in res.stdout.splitlines()
            if not ln.startswith(" ")}
    assert rows["joints dropped"] == "none"
    assert rows["joints left out"] == f"j3 ({why})"
    res = CliRunner().invoke(main, ["inspect", str(p), "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    validate(d, "inspect", ImpactError, "inspect output")
    assert d["joints_dropped"] == [] and d["joints"] == ["j1", "j2", "j3"]
    assert d["joints_left_out"] == [{"name": "j3", "reason": why}]
    res = CliRunner().invoke(main, ["detect", str(p), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert f"impactcli: warning: {p}: joint 'j3' left out of detection: {why}" in (
        res.stderr.splitlines())
    # a log whose every joint is usable says none
    write_log(_gappy_log(), p.with_name("g.csv"))
    d = json.loads(CliRunner().invoke(main, ["inspect", str(p.with_name("g.csv")),
                                             "--json"]).stdout)
    assert d["joints_left_out"] == []
