"""The answer states its own limits: what the tool could not ground is said, not implied.
Here: link numbers made without a robot description (the log's column order), and the
detection floor (the smallest contact a run could have seen)."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from impactcli.cli import main

REPO = Path(__file__).resolve().parents[1]
IMPACTS = REPO / "sample_logs" / "csv" / "assist_impacts.csv.gz"
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"
NOTE = "are numbered in the log's column order"


def _without_robot(tmp_path: Path) -> Path:
    """The sample config with its model's robot description cut out (every
    ``[model.robot…]`` table): the incidents' links can only follow the columns."""
    lines = CONFIG.read_text(encoding="utf-8").splitlines(keepends=True)
    out, skip = [], False
    for line in lines:
        if line.startswith("["):
            skip = line.startswith("[model.robot")
        if not skip:
            out.append(line)
    path = tmp_path / "norobot.config.toml"
    path.write_text("".join(out), encoding="utf-8")
    return path


def test_links_by_column_order_are_said_in_the_terminal_summary_and_report(
        tmp_path: Path) -> None:
    cfg = _without_robot(tmp_path)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(IMPACTS), "--config", str(cfg), "-o", str(out),
                                  "--summary", str(tmp_path / "s.json")])
    assert r.exit_code == 0, r.stderr
    assert f"links {NOTE} (joint k's link is k)" in r.stdout
    summary = json.loads((tmp_path / "s.json").read_text(encoding="utf-8"))
    assert summary["results"][0]["links"] == "column_order"
    assert summary["results"][0]["incidents"] > 0
    rep = tmp_path / "r.json"
    r = CliRunner().invoke(main, ["report", str(IMPACTS), "--config", str(cfg),
                                  "-o", str(tmp_path / "r.html"), "--json", str(rep)])
    assert r.exit_code == 0, r.stderr
    caveats = json.loads(rep.read_text(encoding="utf-8"))["logs"][0]["caveats"]
    assert any(c["code"] == "links-column-order" for c in caveats)
    # with the description: the chain is the robot's, and nothing is said
    r = CliRunner().invoke(main, ["detect", str(IMPACTS), "--config", str(CONFIG), "-o",
                                  str(out), "--summary", str(tmp_path / "s2.json")])
    assert r.exit_code == 0 and NOTE not in r.stdout
    summary = json.loads((tmp_path / "s2.json").read_text(encoding="utf-8"))
    assert summary["results"][0]["links"] == "robot"


# ------------------------------------------------------------------ the detection floor
def test_pulse_gain_against_closed_forms() -> None:
    """Without G_hat (theta_G = 0) and F1 (a1 = 0), r_rms over one sample peaks at the
    half-sine's peak (1), and over a window as long as the pulse at its RMS (1/sqrt 2); a
    differencing G_hat (theta_G = [1, 0]) passes a slow pulse far less."""
    import numpy as np

    from impactcli.detect.floor import pulse_gain

    fs = 1000.0
    # 100 samples at mid-sample phases: the largest is cos(pi / 200)
    assert pulse_gain(np.zeros((1, 2)), fs, 0.0, 1)[0] == pytest.approx(np.cos(np.pi / 200))
    assert pulse_gain(np.zeros((1, 2)), fs, 0.0, 100)[0] == pytest.approx(2 ** -0.5, rel=1e-3)
    diff = pulse_gain(np.array([[1.0, 0.0]]), fs, 0.0, 1)[0]
    assert diff == pytest.approx(np.sin(np.pi / 100), rel=0.05)  # |x(k) − x(k−1)| at most


def test_floor_accumulator_knows_its_margins_and_skips_the_warm_up() -> None:
    """Known margins: loading 0.3 under vL 1.0 (a step needs 0.7), the adaptive threshold
    0.5 over r_rms 0.1 with a pulse gain of 0.8 (a blow needs 0.5); the warm-up's samples
    (huge margins) are left out; each quantile is a lower bound within one bin (12 %)."""
    import numpy as np

    from impactcli.detect.floor import FloorAccumulator

    n, J = 5000, 2
    acc = FloorAccumulator(J, n, hold=2000, v_l=np.array([1.0, 1.0]))
    loading = np.full((n, J), 0.3)
    r_rms = np.full((n, J), 0.1)
    thr = np.full((n, J), 0.5)
    loading[:700] = -50.0  # |LP(r)| over vL: margin 0 in the warm-up ...
    thr[:700] = 1e6        # ... and a huge adaptive one
    for a in range(0, n, 333):  # chunks of any size
        acc.update(loading[a:a + 333], r_rms[a:a + 333], thr[a:a + 333], None,
                   np.array([0.8, 0.8]))
    floor = acc.finish([700, 700], 700, ("a", "b"))
    for j in ("a", "b"):
        st, ad = floor["per_joint"][j]["static_loading"], floor["per_joint"][j]["adaptive"]
        for v, true in ((st["median_nm"], 0.7), (st["worst_tenth_nm"], 0.7),
                        (ad["median_nm"], 0.5), (ad["worst_tenth_nm"], 0.5)):
            assert true / 1.13 <= v <= true
    assert floor["per_link"] is None


def test_a_joint_already_alarming_states_no_floor_but_the_share() -> None:
    """Joint b's loading statistic is over vL for the whole log (a lasting load) and its
    adaptive one for 70 %: a contact there joins an alarm already on, so its floor is no
    "~0 N" but the share in alarm; its link's force floor comes from joint a alone, and the
    terminal's sentence names b. Joint a, loading over vL 40 % of the time, keeps a median
    (and its in_alarm share is said only where a quantile falls in the alarm)."""
    import numpy as np

    from impactcli.detect.floor import FloorAccumulator, floor_line

    def jac(q: np.ndarray, i: int) -> np.ndarray:
        return np.array([[0.0], [0.5]]) if i == 1 else np.array([[0.0, 0.3], [0.8, 0.0]])

    n, J = 4000, 2
    acc = FloorAccumulator(J, n, hold=500, v_l=np.array([1.0, 1.0]))
    loading = np.zeros((n, J))
    loading[:, 1] = 5.0
    loading[: int(0.4 * n), 0] = 5.0
    r_rms, thr = np.zeros((n, J)), np.full((n, J), 1.0)
    r_rms[: int(0.7 * n), 1] = 2.0
    acc.update(loading, r_rms, thr, np.zeros((n, J)), np.ones(J))
    floor = acc.finish([0, 0], 0, ("a", "b"), ("a", "b"), [1, 2], [0, 1], jac)
    b = floor["per_joint"]["b"]
    assert b["static_loading"] == {"median_nm": None, "worst_tenth_nm": None,
                                   "in_alarm": 1.0}
    assert b["adaptive"]["median_nm"] is None and b["adaptive"]["worst_tenth_nm"] > 0
    assert abs(b["adaptive"]["in_alarm"] - 0.7) < 0.01
    a = floor["per_joint"]["a"]
    assert a["static_loading"]["median_nm"] > 0.9 and "in_alarm" not in a["static_loading"]
    assert a["static_loading"]["worst_tenth_nm"] > 0.9
    link2 = floor["per_link"][1]
    assert link2["static_loading"]["median_n"] is None  # b's own: none; a reaches not link 2's
    line = floor_line(floor)
    assert line is not None and "~0 N" not in line, line
    assert "b (100 %) had a detector already alarming for most of the log" in line, line


def test_a_link_ending_on_its_joints_axis_has_no_force_floor_of_its_own() -> None:
    """Link 2 ends on joint 2's axis (as a UR's wrist links do): its lever is a rounding
    error (1e-17 m), and a floor of torque / lever would read 1e17 N. Its floor is what
    joint 1 sees at its end (torque 1 / lever 0.8 m); link 1 (lever 0.5 m) keeps its own.
    A link ending on its joint's axis with no joint before it has its torque stated."""
    import numpy as np

    from impactcli.detect.floor import FloorAccumulator, floor_line

    def jac(q: np.ndarray, i: int) -> np.ndarray:
        c = np.array([[0.0], [0.5]]) if i == 1 else np.array([[0.0, 1e-17], [0.8, 0.0]])
        return c

    n, J = 3000, 2
    acc = FloorAccumulator(J, n, hold=500, v_l=np.array([1.0, 2.0]))
    q = np.zeros((n, J))
    acc.update(np.zeros((n, J)), np.zeros((n, J)), np.full((n, J), 1e6), q, np.zeros(J))
    floor = acc.finish([500, 500], 500, ("a", "b"), ("a", "b"), [1, 2], [0, 1], jac)
    link1, link2 = floor["per_link"]
    assert 1.0 / 0.5 / 1.13 <= link1["static_loading"]["median_n"] <= 1.0 / 0.5
    assert "no_lever" not in link1
    assert link2["no_lever"] is True and link2["own_joint"] == "b"
    assert 1.0 / 0.8 / 1.13 <= link2["static_loading"]["median_n"] <= 1.0 / 0.8
    line = floor_line(floor)
    assert line is not None and "~2 N on link 1" in line and "N on link 2" in line, line
    assert line.endswith("(link 2 ends on its own joint's axis: the force there is what "
                         "the joints before see); a lower bound, not a promise that a "
                         "larger one was seen"), line

    def axial(q: np.ndarray, i: int) -> np.ndarray:  # link 1 itself ends on joint 1's axis
        return np.array([[1e-17], [0.0]]) if i == 1 else np.array([[0.0, 0.0], [0.7, 0.3]])

    floor = acc.finish([500, 500], 500, ("a", "b"), ("a", "b"), [1, 2], [0, 1], axial)
    assert floor["per_link"][0]["no_lever"] is True
    assert floor["per_link"][0]["static_loading"]["median_n"] is None
    line = floor_line(floor)
    assert line is not None and "a torque below ~1 N·m on a (its link ends on the " \
        "joint's axis" in line, line


def test_the_run_states_its_floor_and_the_link_forces_follow_the_link_lengths(
        tmp_path: Path) -> None:
    """A calibrated run on a free log states its floor (terminal, timeline, summary,
    report verdict); per joint it lies between 0 and the threshold, and on the planar
    sample arm each link's force is its joint's torque over the link's length (|J_i| of
    the link's own joint), whatever the posture."""
    free = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(free), "--config", str(CONFIG), "-o", str(out),
                                  "--summary", str(tmp_path / "s.json")])
    assert r.exit_code == 0, r.stderr
    assert "detection floor of assist_free_p2p.csv.gz: a contact below ~" in r.stdout
    assert "would not have been seen" in r.stdout
    # a lower bound, and a median (a new user read a 1.3 N incident against a 4.2 N
    # floor; another read "below ~4.8 N not seen" as "above it seen" and missed 20 N blows)
    assert "would not have been seen at the log's median moment (at quieter moments a "\
        "smaller one can be); a lower bound, not a promise that a larger one was "\
        "seen — the median over the log after warm-up" in r.stdout
    tl = json.loads((out / "assist_free_p2p.timeline.json").read_text(encoding="utf-8"))
    floor = tl["detection_floor"]
    lengths = (0.4, 0.4)  # the sample arm's link lengths (its robot description)
    for j, row in floor["per_joint"].items():
        vl = tl["thresholds"][j]["vL"]
        st = row["static_loading"]
        assert 0 <= st["median_nm"] <= st["worst_tenth_nm"] <= vl
        assert row["adaptive"]["median_nm"] > 0
        link = next(x for x in floor["per_link"] if x["joint"] == j)
        assert link["static_loading"]["median_n"] == pytest.approx(
            st["median_nm"] / lengths[link["link"] - 1], rel=1e-9)
    summary = json.loads((tmp_path / "s.json").read_text(encoding="utf-8"))
    assert summary["results"][0]["detection_floor"].startswith("a contact below ~")
    rep = tmp_path / "r.json"
    r = CliRunner().invoke(main, ["report", str(free), "--config", str(CONFIG),
                                  "-o", str(tmp_path / "r.html"), "--json", str(rep)])
    assert r.exit_code == 0, r.stderr
    verdict = json.loads(rep.read_text(encoding="utf-8"))["logs"][0]["verdict"]
    assert verdict.startswith("No incident after warm-up; a contact below ~")


# ------------------------------------------------------------------ data defects
def test_recordings_one_after_another_are_refused_naming_them(tmp_path: Path) -> None:
    """Three recordings concatenated (the time starts again at 0 twice) are not one log:
    exit 3 naming the rows where each starts, with or without --repair-order (which does
    not merge recordings into one interleaved log)."""
    from impactcli.logs import read_log, write_log

    one = tmp_path / "one.csv"
    write_log(read_log(REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz").slice(0, 2000),
              one)
    lines = one.read_text(encoding="utf-8").splitlines(keepends=True)
    path = tmp_path / "three.csv"
    path.write_text(lines[0] + "".join(lines[1:]) * 3, encoding="utf-8")
    for extra in ([], ["--repair-order"]):
        r = CliRunner().invoke(main, ["detect", str(path), "-o", str(tmp_path / "o"), *extra])
        assert r.exit_code == 3, r.output
        err = [ln for ln in r.stderr.splitlines() if ln.startswith("impactcli: error:")]
        assert len(err) == 1, r.stderr
        assert "time starts again 2 time(s), at row 2001 (line 2002), row 4001 (line 4002)" \
            in err[0], err[0]
        assert "the file holds 3 recordings one after another" in err[0]


# ------------------------------------------------------------------ cost before work
def _many_joints_csv(path: Path, joints: int, rows: int) -> Path:
    import numpy as np

    t = np.arange(rows) / 500.0
    rng = np.random.default_rng(0)
    cols = {"time": t}
    for j in range(joints):
        q = 0.5 * np.sin(2 * np.pi * (0.2 + 0.01 * j) * t + j)
        cols[f"j{j}.position"] = q
        cols[f"j{j}.torque"] = 2.0 * np.cos(q) + 0.1 * rng.standard_normal(rows)
    text = ",".join(cols) + "\n" + "\n".join(
        ",".join(f"{cols[k][i]:.6f}" for k in cols) for i in range(rows)) + "\n"
    path.write_text(text, encoding="utf-8")
    return path


def test_sixty_joints_identify_in_bounded_memory(tmp_path: Path) -> None:
    """A 60-joint log: the coupled model's regressor (J × J(5J+1) numbers a row) would need
    gigabytes, so the model choice falls back to the decoupled model, warned — under a
    2 GiB address-space limit, in a subprocess (it used to allocate 17 GB)."""
    import subprocess
    import sys

    log = _many_joints_csv(tmp_path / "j60.csv", 60, 800)  # its coupled regressor: 6.5 GiB
    code = ("import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30)); "
            "from impactcli.cli import main; sys.argv = sys.argv[1:]; main()")
    p = subprocess.run([sys.executable, "-c", code, "impactcli", "identify", str(log),
                        "-o", str(tmp_path / "m.json")], capture_output=True, text=True,
                       timeout=600, check=False)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "the coupled candidate was not tried — 60 joints make its regressor about" \
        in p.stderr
    model = json.loads((tmp_path / "m.json").read_text(encoding="utf-8"))
    assert model["kind"] == "decoupled"


def test_the_coupled_candidate_is_kept_where_it_fits() -> None:
    from impactcli.model import IdentifyOptions
    from impactcli.model.selection import coupled_too_big

    assert coupled_too_big(7, 10**6, IdentifyOptions(), "x") is None
    msg = coupled_too_big(20, 10**6, IdentifyOptions(), "x")
    assert msg is not None and "20 joints" in msg and "coupled_max_mb = 256 MB" in msg


# ------------------------------------------------------------------ rate and time
def test_a_wrong_rate_is_named_with_the_rate_the_logged_velocity_implies() -> None:
    """A 250 Hz log carrying its joints' velocity, read with --rate 1000: warned with the
    rate the velocity implies (its |v| over the positions' steps); read right: silent."""
    free = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
    r = CliRunner().invoke(main, ["inspect", str(free), "--rate", "1000"])
    assert r.exit_code == 0, r.stderr
    assert ("the logged velocity implies a sample rate of about 250 Hz (its |v| over the "
            "positions' steps, 2 moving joint(s)), the log's clock 1e+03 Hz: check --rate"
            in " ".join(r.stderr.split()))
    r = CliRunner().invoke(main, ["inspect", str(free)])
    assert r.exit_code == 0 and "velocity implies" not in r.stderr


# ------------------------------------------------------------------ unchecked joints
def test_a_joint_that_moves_but_is_not_checked_is_named(tmp_path: Path) -> None:
    """A third joint the config does not know, moving 1.2 rad: left out of detection, and
    said so — the terminal's warning, the timeline (travel_rad, motion_envelope.unchecked)
    and the report's verdict ("Not checked, though they moved"); a still one is not named."""
    import numpy as np

    from impactcli.logs import read_log, write_log

    log = read_log(IMPACTS).slice(0, 5000)
    n = log.n_samples
    t = np.asarray(log.time_s)
    path = tmp_path / "three.csv"
    write_log(log, path)
    lines = path.read_text(encoding="utf-8").splitlines()
    wrist = 0.6 * np.sin(2 * np.pi * 0.1 * t)
    still = np.full(n, 0.2)
    rows = [lines[0] + ",wrist.position,wrist.torque,still.position,still.torque"]
    rows += [f"{ln},{wrist[i]:.6f},{0.1 * np.cos(wrist[i]):.6f},{still[i]:.6f},0.05"
             for i, ln in enumerate(lines[1:])]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(path), "--config", str(CONFIG), "-o", str(out)])
    assert r.exit_code == 0, r.stderr
    text = " ".join(r.stderr.split())
    assert "joint(s) moved but were not checked" in text and "wrist (travels 1.2 rad;" in text
    assert "still (travels" not in text
    tl = json.loads((out / "three.timeline.json").read_text(encoding="utf-8"))
    left = {x["name"]: x for x in tl["input"]["joints_left_out"]}
    assert left["wrist"]["travel_rad"] == pytest.approx(1.2, rel=0.01)
    assert "travel_rad" not in left["still"]
    assert "wrist" in tl["motion_envelope"]["unchecked"]
    rep = tmp_path / "r.json"
    r = CliRunner().invoke(main, ["report", str(path), "--config", str(CONFIG),
                                  "-o", str(tmp_path / "r.html"), "--json", str(rep)])
    assert r.exit_code == 0, r.stderr
    verdict = json.loads(rep.read_text(encoding="utf-8"))["logs"][0]["verdict"]
    assert "Not checked, though they moved: wrist (1.2 rad;" in verdict


def _wrist_log(tmp_path: Path, noise: bool) -> tuple[Path, Path]:
    """The heavy arm's free log with its wrist (j3) held still: its torque is either the
    gravity the description predicts there (moving with the other joints' poses), scaled to
    a light wrist and quantised to 0.02 N·m — a few dozen values, under 1 % of the
    shoulder's range — or three values of noise around zero (a channel not measured)."""
    import dataclasses

    import numpy as np

    from impactcli.logs import read_log, write_log
    from impactcli.logs.robot_files import read_robot
    from impactcli.model.gravity import nominal_gravity

    csv = REPO / "sample_logs" / "csv"
    log = read_log(csv / "heavy_free_p2p.csv.gz")
    robot = read_robot(csv / "heavy_free_p2p.robot.json")
    q = log.position.copy()
    q[:, 2] = 0.3
    tau = log.torque.copy()
    if noise:
        tau[:, 2] = np.random.default_rng(0).choice([-0.02, 0.0, 0.02], log.n_samples)
    else:
        g = nominal_gravity(robot, log.joint_names, q)
        assert g is not None
        tau[:, 2] = np.round(0.3 * g[:, 2] / 0.02) * 0.02
        assert 3 < len(np.unique(tau[:, 2])) < 64
        assert np.ptp(tau[:, 2]) < 0.01 * np.ptp(tau[:, 0])
    path = tmp_path / ("noise.csv" if noise else "wrist.csv")
    write_log(dataclasses.replace(log, position=q, torque=tau, velocity=None,
                                  position_ref=None, velocity_ref=None,
                                  acceleration_ref=None), path)
    return path, csv / "heavy_free_p2p.robot.json"


@pytest.mark.parametrize("noise", [False, True], ids=["gravity", "noise"])
def test_a_still_joints_torque_is_judged_by_its_own_signal(tmp_path: Path,
                                                          noise: bool) -> None:
    """Few values and a small range beside the shoulder's: measured when they move with the
    arm's poses (kept), not when they are noise (left out as unmeasured)."""
    path, _ = _wrist_log(tmp_path, noise)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(path), "-o", str(out)])
    assert r.exit_code == 0, r.stderr
    doc = json.loads((out / f"{path.stem}.timeline.json").read_text(encoding="utf-8"))
    left = {x["name"]: x["reason"] for x in doc["input"]["joints_left_out"]}
    if noise:
        assert left["j3"].startswith("torque unmeasured: 3 distinct values")
    else:
        assert "j3" not in left and "j3" in doc["thresholds"]


def test_calibration_keeps_a_joint_measured_in_one_of_its_logs(tmp_path: Path) -> None:
    """Two calibration logs: the wrist's torque is noise-like in one (it stands still and
    its channel shows three values) and measured in the other: kept, said per log."""
    still, robot = _wrist_log(tmp_path, noise=True)
    moving = REPO / "sample_logs" / "csv" / "heavy_free_multisine.csv.gz"
    cfg = tmp_path / "c.toml"
    r = CliRunner().invoke(main, ["calibrate", str(still), str(moving), "--robot", str(robot),
                                  "-o", str(cfg)])
    assert r.exit_code == 0, r.stderr
    assert (f"{still}: joint 'j3': its torque unmeasured: 3 distinct values"
            in r.stderr) and "but it is measured in another calibration log: kept" in r.stderr
    import tomllib

    doc = tomllib.loads(cfg.read_text(encoding="utf-8"))
    assert "j3" in doc["thresholds"]["v_stat"]
    assert not [x for x in doc["calibration"].get("joints_left_out", []) if x["name"] == "j3"]


def test_an_explicit_coupled_model_too_wide_is_refused_before_work(tmp_path: Path) -> None:
    """``--kind coupled`` on 60 joints: refused (exit 2) naming the memory and the way out,
    under a 3 GiB address-space limit (it used to die of a MemoryError, exit 70)."""
    import subprocess
    import sys

    log = _many_joints_csv(tmp_path / "j60.csv", 60, 400)
    code = ("import resource, sys; resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30)); "
            "from impactcli.cli import main; sys.argv = sys.argv[1:]; main()")
    p = subprocess.run([sys.executable, "-c", code, "impactcli", "identify", str(log),
                        "--kind", "coupled", "-o", str(tmp_path / "m.json")],
                       capture_output=True, text=True, timeout=600, check=False)
    assert p.returncode == 2, p.stderr[-2000:]
    assert p.stderr.strip().splitlines()[-1] == (
        f"impactcli: error: {log}: a coupled model of 60 joints needs a regressor of about "
        "8.07 GiB at the 1000 rows it needs (J × J(5J+1) numbers a row), above "
        "coupled_max_mb = 256 MB: use --kind decoupled (a model per joint)")
    assert not (tmp_path / "m.json").exists()


def test_rate_given_over_a_time_column_is_checked_against_it(tmp_path: Path) -> None:
    """--rate wins over a time column, which is then only compared: a column rounded to
    10 ms at 250 Hz agrees on average (silent), one at half the rate is named with the rate
    it implies; --time-column names the time column by name it overrides."""
    import numpy as np

    free = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
    lines = gzip.decompress(free.read_bytes()).decode("utf-8").splitlines()[:3001]
    head, rows = lines[0], [ln.split(",", 1) for ln in lines[1:]]
    t = np.arange(len(rows)) / 250.0

    def write(name: str, times: np.ndarray, header: str = head) -> Path:
        path = tmp_path / name
        path.write_text(header + "\n" + "\n".join(f"{x:.6f},{r[1]}" for x, r in
                                                  zip(times, rows, strict=True)) + "\n",
                        encoding="utf-8")
        return path

    def warned(*args: str) -> list[str]:
        r = CliRunner().invoke(main, ["inspect", *args])
        assert r.exit_code == 0, r.stderr
        return [ln for ln in r.stderr.splitlines() if "check the rate" in ln]

    assert warned(str(write("rounded.csv", np.round(t, 2))), "--rate", "250") == []
    slow = write("slow.csv", 2 * t)
    assert warned(str(slow), "--rate", "250") == [
        f"impactcli: warning: {slow}: --rate 250: the time column 'time' (not used) steps by "
        "0.008 s on average over its first 2000 rows (125 Hz, read in s), not the 1/250 s "
        "--rate gives: check the rate (or the column's unit)"]
    both = tmp_path / "both.csv"
    both.write_text(head.replace("time,", "time,stamp_s,", 1) + "\n" + "\n".join(
        f"{2 * x:.6f},{x:.6f},{r[1]}" for x, r in zip(t, rows, strict=True)) + "\n",
        encoding="utf-8")
    r = CliRunner().invoke(main, ["inspect", str(both), "--time-column", "stamp_s"])
    assert r.exit_code == 0, r.stderr
    assert (f"impactcli: warning: {both}: --time-column 'stamp_s' given: the column 'time', a "
            "time column by its name, is not read as the log's clock") in r.stderr.splitlines()


def test_identification_cost_is_checked_before_work() -> None:
    """The estimate of identifying the model from the log: far under real time for the arms
    of the field (7 joints at 1 kHz: ~0.02 s per s for a URDF), refused (exit 2) for a URDF
    chain of 50 joints at 1 kHz; the estimate follows the measured rows of IDENTIFY_COST."""
    from impactcli.errors import ScaleLimitError
    from impactcli.model.identification import identification_cost
    from impactcli.run.plan import check_identification

    assert identification_cost("urdf", 7, 1000.0) == pytest.approx(19.6 / 800, rel=0.1)
    assert identification_cost("decoupled", 7, 1000.0) == pytest.approx(5.4 / 800, rel=0.1)
    check_identification("x", "urdf", 7, 1000.0)
    check_identification("x", "decoupled", 200, 1000.0)
    with pytest.raises(ScaleLimitError) as err:
        check_identification("x", "urdf", 50, 1000.0)
    assert "identifying a urdf model from the log is estimated at 1.25 s" in str(err.value)


def test_rate_given_over_a_maps_time_is_checked_against_it(tmp_path: Path) -> None:
    """A channel map's time (a mapped CSV's column, an archive's array) under --rate: not
    the clock, compared with it — named with the rate it implies when they disagree."""
    import numpy as np

    n = 3000
    t_ms, q = np.arange(n) * 8.0, 0.3 * np.sin(np.arange(n) * 0.004)
    csv = tmp_path / "mapped.csv"
    csv.write_text("t,pa,ta\n" + "".join(f"{a:g},{b:.6f},{np.cos(b):.6f}\n"
                                         for a, b in zip(t_ms, q, strict=True)),
                   encoding="utf-8")
    cmap = tmp_path / "m.json"
    cmap.write_text(json.dumps({"format": "csv", "time": {"column": "t", "unit": "ms"},
                                "joints": [{"name": "a", "position": "pa", "torque": "ta"}]}),
                    encoding="utf-8")
    npz = tmp_path / "m.npz"
    import numpy

    numpy.savez(npz, times=t_ms / 1000.0, positions=q[:, None], torques=np.cos(q)[:, None])
    nmap = tmp_path / "n.json"
    nmap.write_text(json.dumps({"format": "npz", "time": {"key": "times", "unit": "s"},
                                "joints": [{"name": "a",
                                            "position": {"key": "positions", "index": 0},
                                            "torque": {"key": "torques", "index": 0}}]}),
                    encoding="utf-8")
    for log, m, what, unit, kind in ((csv, cmap, "column 't'", "ms", "column"),
                                     (npz, nmap, "array 'times'", "s", "array")):
        for rate, said in (("250", True), ("125", False)):
            r = CliRunner().invoke(main, ["inspect", str(log), "--channel-map", str(m),
                                          "--rate", rate])
            assert r.exit_code == 0, r.stderr
            line = (f"impactcli: warning: {log}: --rate 250: the time {what} (not used) steps "
                    f"by 0.008 s on average over its first 2000 rows (125 Hz, read in {unit}), "
                    f"not the 1/250 s --rate gives: check the rate (or the {kind}'s unit)")
            assert (line in r.stderr.splitlines()) is said, r.stderr


def test_a_floor_far_below_the_push_a_link_needs_says_the_push_too() -> None:
    """Known truth, one link: a 100 ms blow needs 49 N (adaptive), a push held until the
    loading low-pass settles 225 N (static_loading): "~49 N" alone read as the floor of a
    push on the real UR arm, where a 38 N·m push held 6 s went unseen. The push's figure is
    said when it is more than twice the smallest; 1.5 times is not."""
    from impactcli.detect.floor import floor_line

    def floor(push: float) -> dict:
        return {"per_joint": {}, "per_link": [{
            "link": 2, "joint": "b",
            "adaptive": {"median_n": 49.0, "worst_tenth_n": 56.0},
            "static_loading": {"median_n": push, "worst_tenth_n": push}}]}

    line = floor_line(floor(225.0))
    assert line is not None and line.startswith(
        "a contact below ~49 N on link 2 (~56 N in the worst tenth; held as a push: ~225 N) "
        "(N: a force at the link's end, normal to it; one nearer its joint or aslant needs "
        "more) would not have been seen"), line
    line = floor_line(floor(73.5))
    assert line is not None and "held as a push" not in line, line
