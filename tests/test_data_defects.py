"""Data defects are not contacts (issue "The answer states its own limits", item 2): a
time gap, a position jump no motion explains (a recording splice), a whole-turn step and
rows that cannot be consecutive, each planted in a collision-free sample log and run
through the CLI; and the finder itself (impactcli.logs.defects) against planted truth,
whatever the blocks the log arrives in."""

from __future__ import annotations

import dataclasses
import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from impactcli.cli import main
from impactcli.logs import read_log, write_log
from impactcli.logs.defects import JUMP_RAD, DefectScan, unwrap_positions
from impactcli.types import RobotLog

REPO = Path(__file__).resolve().parents[1]
FREE = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"
ROBOT = REPO / "sample_logs" / "csv" / "assist_free_p2p.robot.json"


@pytest.fixture(scope="module")
def free() -> RobotLog:
    """The first 20 s of a collision-free sample log (0 incidents with the sample config)."""
    log = read_log(FREE)
    return log.slice(0, round(20.0 * log.sample_rate_hz))


def _with(log: RobotLog, **arrays: np.ndarray) -> RobotLog:
    return dataclasses.replace(log, **arrays)


def _gap(log: RobotLog, at_s: float, samples: int) -> RobotLog:
    """``samples`` rows removed from ``at_s`` on (the times of the rest kept)."""
    i = round(at_s * log.sample_rate_hz)
    keep = np.r_[0:i, i + samples:log.n_samples]
    return dataclasses.replace(log, t_ns=log.t_ns[keep], **{
        s: getattr(log, s)[keep] for s in ("position", "torque", "velocity", "current",
                                           "position_ref", "velocity_ref",
                                           "acceleration_ref", "torque_model", "torque_ext")
        if getattr(log, s) is not None})


def _step(log: RobotLog, at_s: float, by: np.ndarray) -> RobotLog:
    """Every position from ``at_s`` on shifted by ``by`` (J,) [rad]: a splice (the logged
    velocity and the controller's channels go on unchanged)."""
    i = round(at_s * log.sample_rate_hz)
    q = log.position.copy()
    q[i:] += by
    return _with(log, position=q)


def _detect(log: RobotLog, tmp_path: Path, *extra: str) -> tuple[int, str, str, dict]:
    src = tmp_path / "log.csv"
    write_log(log, src)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["detect", str(src), "--config", str(CONFIG), "--robot",
                                  str(ROBOT), "-o", str(out), *extra])
    tl = out / "log.timeline.json"
    doc = json.loads(tl.read_text(encoding="utf-8")) if tl.exists() else {}
    return r.exit_code, r.stdout, r.stderr, doc


def test_the_clean_log_has_no_incident_and_no_defect(free: RobotLog, tmp_path: Path) -> None:
    code, _, err, doc = _detect(free, tmp_path, "--fail-on-detect")
    assert code == 0, err
    assert doc["counts"]["incidents"] == {"counted": 0, "in_warmup": 0}
    assert "data_defects" not in doc and not doc["incidents"]


def test_a_gap_is_a_data_defect_not_a_contact(free: RobotLog, tmp_path: Path) -> None:
    log = _gap(free, 12.0, 50)  # 200 ms missing: the residual jumps at the gap
    code, out, err, doc = _detect(log, tmp_path)
    assert code == 0, err
    assert doc["counts"]["incidents"]["counted"] == 0
    marked = [i for i in doc["incidents"] if "data_defect" in i]
    assert marked and marked == doc["incidents"]
    assert doc["counts"]["incidents"]["data_defect"] == len(marked)
    d = marked[0]["data_defect"]
    assert d["kind"] == "gap" and d["t_start"] == pytest.approx(11.996, abs=1e-6)
    assert doc["data_defects"]["gaps"] == 1 and doc["data_defects"]["jumps"] == 0
    gap = doc["data_defects"]["listed"][0]
    assert gap["size"] == pytest.approx(0.204, abs=1e-6)
    assert "not counted, at a data defect of log.csv: 1 incident at" in out
    assert "marked data_defect in the timeline and not counted as contacts" in err
    # asked to judge: the only incidents are at a defect, so it could not (exit 5)
    code, _, err, _ = _detect(log, tmp_path, "--fail-on-detect")
    assert code == 5
    assert "--fail-on-detect could not judge 1 incident at data defects" in err
    code, _, err, _ = _detect(log, tmp_path, "--fail-on-force", "1")
    assert code == 5
    assert "--fail-on-force 1 N could not judge 1 incident at data defects (the first at " \
           "12.200 s, a gap, ≳" in err
    code, _, err, _ = _detect(log, tmp_path, "--fail-on-force", "100000")  # below any limit
    assert code == 0, err


def test_a_splice_is_named_and_its_incident_marked(free: RobotLog, tmp_path: Path) -> None:
    log = _step(free, 12.0, np.array([0.03, -0.02]))  # every joint, one sample, v = as is
    code, _, err, doc = _detect(log, tmp_path)
    assert code == 0, err
    jumps = [d for d in doc["data_defects"]["listed"] if d["kind"] == "jump"]
    assert len(jumps) == 1 and jumps[0]["t_end"] == pytest.approx(12.0, abs=1e-9)
    assert jumps[0]["joints"] == list(log.joint_names)
    assert jumps[0]["size"] == pytest.approx(0.03, rel=0.1)
    assert "the positions jump at 1 sample(s) further than the samples around them move " \
           "(the first from 11.996 to 12.000 s" in err
    assert doc["counts"]["incidents"]["counted"] == 0
    assert all(i["data_defect"]["kind"] == "jump" for i in doc["incidents"])


def test_a_whole_turn_is_unwrapped_and_said(free: RobotLog, tmp_path: Path) -> None:
    turn = np.array([0.0, -2.0 * np.pi])
    code, _, err, doc = _detect(_step(free, 12.0, turn), tmp_path)
    assert code == 0, err
    assert "joint(s) elbow step by a whole turn (1 step(s), the first on elbow at sample " \
           "3000, 12.000 s): unwrapped, as an angle logged modulo 2π" in err
    assert doc["counts"]["incidents"] == {"counted": 0, "in_warmup": 0}
    assert not doc["incidents"] and "data_defects" not in doc


def test_a_reference_that_wraps_is_unwrapped_too(free: RobotLog, tmp_path: Path) -> None:
    """The elbow's position and its reference both logged modulo a turn from 12 s on:
    both unwrapped and said; the run is the clean one's (no incident, the envelope calm)."""
    i = round(12.0 * free.sample_rate_hz)
    q, r = free.position.copy(), free.position_ref.copy()
    q[i:, 1] -= 2 * np.pi
    r[i + 3:, 1] -= 2 * np.pi  # the reference turns a few samples apart
    code, _, err, doc = _detect(_with(free, position=q, position_ref=r), tmp_path)
    assert code == 0, err
    assert "the reference of joint(s) elbow step by a whole turn (1 step(s)" in err
    assert "joint(s) elbow step by a whole turn (1 step(s), the first on elbow at sample " \
           "3000" in err
    assert doc["counts"]["incidents"] == {"counted": 0, "in_warmup": 0}
    assert "outside the calibration's motion envelope" not in err


def test_rows_that_cannot_be_consecutive_are_refused(free: RobotLog, tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    perm = rng.permutation(free.n_samples)  # the rows' contents shuffled, the times kept
    log = _with(free, position=free.position[perm], torque=free.torque[perm])
    src = tmp_path / "shuffled.csv"
    write_log(log, src)
    r = CliRunner().invoke(main, ["detect", str(src), "--config", str(CONFIG), "-o",
                                  str(tmp_path / "out")])
    assert r.exit_code == 3
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith(f"impactcli: error: {src}: rows that cannot be consecutive: ")
    assert "Traceback" not in r.stderr and not (tmp_path / "out").exists()


@settings(max_examples=6, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(["gap", "jump", "wrap"]),
       at_s=st.floats(6.0, 18.0),
       size=st.floats(0.0, 1.0),
       joint=st.integers(0, 1))
@example(kind="jump", at_s=6.0, size=1.0, joint=1)  # an adaptive alarm 2.2 s after the splice
def test_planted_defects_never_make_an_unmarked_contact(
        free: RobotLog, tmp_path: Path, kind: str, at_s: float, size: float,
        joint: int) -> None:
    """A gap of 2–100 samples, a jump of 0.02–0.2 rad on one joint or all, or a turn of
    ±1–3 on one joint, anywhere after the warm-up of a collision-free log: no counted
    incident, and every incident marked with its defect."""
    if kind == "gap":
        log = _gap(free, at_s, 2 + int(size * 98))
    elif kind == "jump":
        by = np.full(2, 0.02 + 0.18 * size) * (1 if joint else -1)
        by[joint] *= 0.5
        log = _step(free, at_s, by)
    else:
        turns = np.zeros(2)
        turns[joint] = [-3, -1, 1, 2][int(size * 3.999)]
        log = _step(free, at_s, 2.0 * np.pi * turns)
    code, _, err, doc = _detect(log, tmp_path)
    assert code == 0, err
    assert doc["counts"]["incidents"]["counted"] == 0, doc["incidents"]
    assert all(i.get("data_defect", {}).get("kind") == kind for i in doc["incidents"])


# ------------------------------------------------------------------ the finder itself


def _walk(n: int, j: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=np.int64) * 4_000_000  # 250 Hz
    k = np.arange(n)[:, None]
    q = 0.8 * np.sin(2 * np.pi * 0.3 * k * 0.004 * (1 + np.arange(j))) \
        + np.cumsum(rng.normal(0.0, 1e-5, (n, j)), axis=0)
    return t, q


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**16), jump_at=st.integers(5, 1990),
       jump=st.floats(3 * JUMP_RAD, 0.5), wrap_at=st.integers(5, 1990),
       turns=st.sampled_from([-2, -1, 1, 3]),
       cuts=st.lists(st.integers(1, 1999), max_size=6))
def test_the_finder_finds_what_was_planted_in_any_blocks(
        seed: int, jump_at: int, jump: float, wrap_at: int, turns: int,
        cuts: list[int]) -> None:
    n, j = 2000, 3
    t, q = _walk(n, j, seed)
    raw = q.copy()
    raw[jump_at:, 0] += jump
    raw[wrap_at:, 2] += 2 * np.pi * turns
    found = DefectScan(j)
    bounds = [0, *sorted(set(cuts)), n]
    out = np.concatenate([found.add(t[a:b], raw[a:b]) for a, b in itertools.pairwise(bounds)
                          if b > a])
    found.finish()
    assert [(x.i, x.joint) for x in found.jumps] == [(jump_at, 0)]
    assert found.jumps[0].size == pytest.approx(jump, abs=0.01)
    assert [(w.i, w.joint, w.turns) for w in found.wraps] == [(wrap_at, 2, turns)]
    expect = raw.copy()
    expect[wrap_at:, 2] -= 2 * np.pi * turns
    assert np.array_equal(out, expect)  # unwrapped exactly, the jump left as logged
    # a later pass removes the same turns from any chunk
    for a in (0, wrap_at - 1, wrap_at, 1500):
        chunk = unwrap_positions(raw[a:a + 300], a, found.wraps, [0, 1, 2])
        assert np.array_equal(chunk, expect[a:a + 300])
    assert not found.shuffled


def test_noise_is_not_a_jump_and_shuffled_rows_are_told() -> None:
    """Positions with 0.006 rad of noise (a log in degrees read as radians) make no jump;
    a splice of 0.2 rad on them still does; the same rows shuffled cannot be consecutive."""
    t, q = _walk(4000, 2, 7)
    rng = np.random.default_rng(1)
    noisy = q + 0.006 * rng.standard_normal(q.shape)
    noisy[2500:, 1] += 0.2
    found = DefectScan(2)
    found.add(t, noisy)
    found.finish()
    assert [(x.i, x.joint) for x in found.jumps] == [(2500, 1)] and not found.shuffled
    mixed = DefectScan(2)
    mixed.add(t, q[rng.permutation(len(q))])
    mixed.finish()
    assert mixed.shuffled
    assert "j0" in mixed.describe(("j0", "j1"))


def test_a_noisy_joint_does_not_crowd_out_anothers_splice() -> None:
    """60,000 samples of a joint whose position is 0.02 rad of noise (its candidates fill
    any shared list) beside a clean joint spliced by 0.5 rad at sample 50,000."""
    n = 60_000
    t = np.arange(n, dtype=np.int64) * 1_000_000
    q = np.zeros((n, 2))
    q[:, 0] = 0.02 * np.random.default_rng(2).standard_normal(n)
    q[:, 1] = 0.5 * np.sin(np.arange(n) * 1e-4)
    q[50_000:, 1] += 0.5
    found = DefectScan(2)
    for a in range(0, n, 4096):
        found.add(t[a:a + 4096], q[a:a + 4096])
    found.finish()
    assert [(x.i, x.joint) for x in found.jumps] == [(50_000, 1)]


def test_the_finder_leaves_a_smooth_fast_motion_alone() -> None:
    """A joint at up to 3 rad/s, sampled at 125 Hz (0.024 rad a step), braking at 200
    rad/s² in one step: no jump (the step stays within its neighbours' and the
    acceleration bound)."""
    dt = 0.008
    v = np.r_[np.full(300, 3.0), np.full(300, 3.0 - 200 * dt), np.zeros(300)]
    q = np.cumsum(v * dt)[:, None]
    t = (np.arange(len(q)) * dt * 1e9).astype(np.int64)
    found = DefectScan(1)
    found.add(t, q)
    found.finish()
    assert found.jumps == [] and found.wraps == [] and found.steps == len(q) - 3  # not the ends


def test_one_dropped_sample_is_no_defect(tmp_path: Path) -> None:
    """A single sample missing just before an impact (a step of two periods, as a network
    drops one): a gap warned of, not a data defect; the impact stays counted."""
    log = read_log(REPO / "sample_logs" / "csv" / "assist_impacts.csv.gz")
    _, _, _, clean = _detect(log, tmp_path / "clean")
    code, _, err, doc = _detect(_gap(log, 11.9, 1), tmp_path / "gap")
    assert code == 0, err
    assert "1 time gap(s) longer than 1.5 sample periods" in err
    assert "data_defects" not in doc
    assert doc["counts"]["incidents"] == clean["counts"]["incidents"]


def test_contacts_away_from_a_defect_are_counted_as_before(tmp_path: Path) -> None:
    """Impacts stay incidents, numbered 1, 2, … without a hole, when a gap lies between two
    of them; only what starts at the gap is marked."""
    log = read_log(REPO / "sample_logs" / "csv" / "assist_impacts.csv.gz")
    _, _, err, clean = _detect(log, tmp_path / "clean")
    assert "data_defects" not in clean, err
    code, _, err, doc = _detect(_gap(log, 14.5, 25), tmp_path / "gap")  # 100 ms at 14.5 s
    assert code == 0, err
    counted = [i for i in doc["incidents"] if not i["in_warmup"] and "data_defect" not in i]
    assert [i["number"] for i in counted] == list(range(1, len(counted) + 1))
    assert all(i["number"] is None for i in doc["incidents"] if "data_defect" in i)
    at_gap = [i for i in doc["incidents"] if "data_defect" in i]
    assert all(14.49 <= i["t_start"] <= 14.5 + doc["data_defects"]["settle_s"] for i in at_gap)
    # every contact of the clean run is there, at the same time (within a sample)
    before = [i["t_start"] for i in clean["incidents"] if not i["in_warmup"]]
    assert len(counted) == len(before)
    assert np.allclose([i["t_start"] for i in counted], before, atol=0.0041)


def test_the_adaptive_detectors_memory_of_a_defect() -> None:
    """An incident the adaptive detector raised alone is marked while the evaluator still
    remembers the defect (three time constants of its forgetting); one the static
    detector shares, only within the settling time; neither after."""
    import dataclasses

    from impactcli.detect.incidents import (
        DataDefect,
        Incident,
        adaptive_memory_s,
        mark_defects,
    )

    memory = adaptive_memory_s(0.999, 250.0)
    assert memory == pytest.approx(12.0) and adaptive_memory_s(1.0, 250.0) == 0.0
    jump = DataDefect("jump", 5.996, 6.0, 0.2, ("elbow",))
    base = Incident(0.0, 0.1, 0, 25, ("adaptive",), ("elbow",), 2, None, "none", "transient",
                    {"elbow": 1.0}, False)
    incs = [dataclasses.replace(base, t_start=t, t_end=t + 0.1, detectors=d)
            for t, d in ((8.2, ("adaptive",)), (8.2, ("static_loading", "adaptive")),
                         (6.3, ("static_loading",)), (18.5, ("adaptive",)))]
    marked = [i.data_defect is not None for i in mark_defects(incs, [jump], 0.56, memory)]
    assert marked == [True, False, True, False]
    # a defect the warm-up ran past, ending where the prediction error had settled, is
    # not remembered beyond the settling time (a new user's trial: a jump at 0.012 s took
    # a labelled push at 8.08 s out of the count); one after that end is
    early = DataDefect("jump", 0.012, 0.016, 0.011, ("elbow",))
    push = dataclasses.replace(base, t_start=8.08, t_end=8.2)
    assert mark_defects([push], [early], 0.56, memory)[0].data_defect is not None
    assert mark_defects([push], [early], 0.56, memory, settled_s=3.0)[0].data_defect is None
    assert mark_defects(incs, [jump], 0.56, memory, settled_s=3.0)[0].data_defect is not None


def test_the_time_a_defect_blinds_is_said_and_exact(free: RobotLog, tmp_path: Path) -> None:
    """A trial's splice: the labelled 5 N push 8 ms after it was "not counted, at a data
    defect", while the floor lines did not say that the time after a defect is blind. The
    splice at 12.000 s (one step, from 11.996 s) blinds the detectors for the settling time
    after it — for the adaptive detector alone its evaluator's memory, 12 s at λ = 0.999
    and 250 Hz, cut at the log's end; the timeline, the terminal and the report say so."""
    log = _step(free, 12.0, np.array([0.03, -0.02]))
    code, out, err, doc = _detect(log, tmp_path)
    assert code == 0, err
    dd = doc["data_defects"]
    settle, end = dd["settle_s"], doc["input"]["duration_s"]
    assert dd["adaptive_settle_s"] == pytest.approx(3.0 / (1.0 - 0.999) / 250.0)
    assert dd["blind_s"] == pytest.approx(12.0 + settle - 11.996, abs=1e-9)
    assert dd["adaptive_blind_s"] == pytest.approx(min(12.0 + 12.0, end) - 11.996, abs=1e-9)
    (line,) = [ln for ln in out.splitlines() if ln.startswith("blind at data defects of")]
    assert line == (
        f"blind at data defects of log.csv: an alarm starting within {settle:.2g} s after "
        f"its defect is taken for the defect's and not counted, so a contact starting "
        f"there is missed: {dd['blind_s']:.3g} s of the log after warm-up "
        f"({dd['adaptive_blind_s']:.3g} s for a contact only the adaptive detector sees: its "
        "evaluator remembers a defect 12 s); the detection floor does not hold there"), line
    r = CliRunner().invoke(main, ["report", str(tmp_path / "out" / "log.timeline.json"), "-o",
                                  str(tmp_path / "r.html"), "--json", str(tmp_path / "r.json")])
    assert r.exit_code == 0, r.output
    rep = json.loads((tmp_path / "r.json").read_text())
    (item,) = [u for u in rep["logs"][0]["could_not_see"] if u["code"] == "data-defects"]
    assert item["data"]["blind_s"] == dd["blind_s"]
    assert "a contact starting there is missed" in item["text"]
    # a clean log says none of it
    code, out, _, doc = _detect(free, tmp_path / "clean")
    assert "data_defects" not in doc and "blind at data defects" not in out


def test_a_blind_time_for_the_adaptive_detector_alone_is_said() -> None:
    """A defect whose settling time ends in warm-up but whose evaluator memory runs past
    it blinds the adaptive detector alone: said in the report, with the plural right."""
    from types import SimpleNamespace

    from impactcli.detect.incidents import defect_blind_words
    from impactcli.outputs.report.unseen import _defects

    dd = {"gaps": 1, "jumps": 1, "settle_s": 0.56, "blind_s": 0.0,
          "adaptive_settle_s": 12.0, "adaptive_blind_s": 4.5}
    assert defect_blind_words(dd) == (
        "an alarm starting within 0.56 s after one of its 2 defects is taken for the "
        "defect's and not counted, so a contact starting there is missed: 0 s of the log "
        "after warm-up (4.5 s for a contact only the adaptive detector sees: its evaluator "
        "remembers a defect 12 s); the detection floor does not hold there")
    (item,) = _defects(SimpleNamespace(data_defects=dd))  # type: ignore[arg-type]
    assert item["short"] == "4.5 s at data defects" and item["data"]["adaptive_blind_s"] == 4.5
    assert _defects(SimpleNamespace(data_defects={**dd, "adaptive_blind_s": 0.0})) == []  # type: ignore[arg-type]


@given(spans=st.lists(st.tuples(st.floats(0.0, 20.0), st.floats(0.0, 1.0),
                                st.floats(0.0, 3.0)), min_size=1, max_size=6),
       t0=st.floats(0.0, 5.0))
def test_defect_blind_time_is_the_union_of_the_windows(
        spans: list[tuple[float, float, float]], t0: float) -> None:
    """Against the windows drawn on a fine grid: [start, end + after] per defect, their
    union within [t0, t1]."""
    from impactcli.detect.incidents import DataDefect, defect_blind_s

    t1 = 20.0
    defects = [DataDefect("gap", a, a + d, d, ()) for a, d, _ in spans]
    got = defect_blind_s(defects, [x for *_, x in spans], t0, t1)
    grid = np.linspace(t0, t1, 200_001)
    inside = np.zeros(grid.size, dtype=bool)
    for a, d, x in spans:
        inside |= (grid >= a) & (grid <= a + d + x)
    assert got == pytest.approx(inside.mean() * (t1 - t0), abs=2e-4 * 6 + 1e-9)
