"""The logged velocity against the positions' steps (impactcli/logs/velocity_check.py):
known truth from exact derivatives, and through `inspect` on a CSV."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from impactcli.logs.velocity_check import MIN_STEPS, VelocityAgreement

from .cli_run import invoke

RATE = 200.0


def arm(seconds: float = 25.0, joints: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """t [ns], positions and their exact velocity: a sine per joint (0.2–0.45 Hz)."""
    t = np.arange(int(seconds * RATE)) / RATE
    w = 2 * np.pi * (0.2 + 0.05 * np.arange(joints))
    q = 0.5 * np.sin(np.outer(t, w))
    return (t * 1e9).astype(np.int64), q, 0.5 * w * np.cos(np.outer(t, w))


def found(t: np.ndarray, q: np.ndarray, v: np.ndarray, cuts: tuple[int, ...] = ()) -> list:
    agree = VelocityAgreement(q.shape[1])
    for a, z in zip((0, *cuts), (*cuts, len(t)), strict=True):
        agree.add(t[a:z], q[a:z], v[a:z])
    return agree.finish()


def test_positions_that_stop_while_the_velocity_goes_on_are_one_stretch_in_any_chunking(
        ) -> None:
    """The real KUKA log's end: the positions ease to a stop over the last 0.11 s while the
    velocities go on. One stretch, on every joint, from where the gap passes the bound to
    the last sample, whatever the chunks; the agreeing rest gives none."""
    t, q, v = arm()
    k0 = len(t) - 22
    q[k0:] = q[k0 - 1]  # frozen: the steps are 0, the velocity is not
    (whole,) = found(t, q, v)
    assert whole.t_end_ns == t[-1] and whole.joints == (0, 1, 2)
    assert whole.t_start_ns == t[k0 - 1] and whole.steps == 22
    assert whole.largest_rad_s == pytest.approx(np.abs(v[k0 - 1:]).max(), rel=0.05)
    for cuts in ((7,), (k0 - 3, k0 + 5), (k0, len(t) - 1), tuple(range(500, len(t), 333))):
        assert found(t, q, v, cuts) == [whole], cuts
    t, q, v = arm()
    assert found(t, q, v) == []


def test_a_lagging_velocity_at_a_braking_and_a_collision_in_both_are_no_stretch() -> None:
    """A velocity estimate 10 ms late disagrees by its lag times the acceleration: at a
    braking from 0.5 rad/s to rest in 20 ms (25 rad/s²), for a step or two; a collision
    stops both channels alike. Neither is a stretch; a glitch of fewer than MIN_STEPS steps
    is none either."""
    t, q, v = arm()
    k = 2000
    stop = np.clip(1.0 - (np.arange(len(t)) - k) / 4.0, 0.0, 1.0)  # 4 samples to rest
    v = v * stop[:, None]
    q = q[0] + np.concatenate((np.zeros((1, 3)), np.cumsum(0.5 * (v[1:] + v[:-1]), axis=0)
                               / RATE))
    assert found(t, q, v) == []  # the collision: both channels stop
    late = np.concatenate((np.repeat(v[:1], 2, axis=0), v[:-2]))  # 10 ms late
    assert found(t, q, late) == []
    glitch = v.copy()
    glitch[3000:3000 + MIN_STEPS - 2] += 1.0
    assert found(t, q, glitch) == []
    # MIN_STEPS steps, but shorter than MIN_S (15 steps at 200 Hz: 75 ms): a lag's
    # disagreement through a jolt; 17 steps (85 ms) are a stretch
    for n, stretch in ((13, False), (15, True)):
        jolt = v.copy()
        jolt[3000:3001 + n] += 1.0  # n + 1 samples off: the n + 2 steps touching them
        got = found(t, q, jolt)
        assert bool(got) == stretch and (not got or got[0].steps == n + 2), (n, got)


def test_inspect_warns_where_the_velocity_and_positions_tell_two_motions(
        tmp_path: Path) -> None:
    """Through the scan: a CSV whose positions freeze over its last 0.11 s while its
    velocities go on is warned of, naming the time, the joints and the gap; the same log
    agreeing throughout is not, nor one whose velocity is not these positions' derivative
    at all (in deg/s: the implied rate is warned of instead)."""
    t, q, v = arm(12.0, 2)

    def write(name: str, q: np.ndarray, v: np.ndarray) -> Path:
        path = tmp_path / name
        cols = ["time"] + [f"j{k}.{s}" for k in (1, 2) for s in ("position", "velocity",
                                                                  "torque")]
        rows = np.column_stack([t * 1e-9] + [x for k in range(2)
                                             for x in (q[:, k], v[:, k],
                                                       np.sin(3 * t * 1e-9 + k))])
        np.savetxt(path, rows, delimiter=",", header=",".join(cols), comments="",
                   fmt="%.9g")
        return path

    frozen = q.copy()
    frozen[-22:] = frozen[-23]
    r = invoke("inspect", str(write("frozen.csv", frozen, v)))
    assert r.exit_code == 0, r.output
    (said,) = [ln for ln in r.stderr.splitlines() if "tell two motions" in ln]
    assert said.startswith("impactcli: warning: ") and "frozen.csv: the logged velocity " \
        "and the positions' steps tell two motions at 11.885 s to the log's end (all 2 " \
        "joints, up to " in said, said
    r = invoke("inspect", str(write("fine.csv", q, v)))
    assert "tell two motions" not in r.stderr, r.stderr
    r = invoke("inspect", str(write("deg.csv", frozen, np.degrees(v))))
    assert "tell two motions" not in r.stderr and "implies a sample rate" in r.stderr


@pytest.mark.real_logs
def test_the_real_kuka_logs_end_and_no_other_real_stretch(real_logs: Path) -> None:
    """The real KUKA LWR4 log: its positions ease to a stop over the last 0.11 s while its
    velocities go on (all 7 joints), where `detect` raises an incident; the real UR logs
    (100 Hz, positions and velocities of the controller) agree throughout."""
    r = invoke("inspect", str(real_logs / "kuka_lwr4" / "measurements_1.npz"),
               "--channel-map", "kuka_lwr4")
    assert r.exit_code == 0, r.output
    (said,) = [ln for ln in r.stderr.splitlines() if "tell two motions" in ln]
    assert "tell two motions at 25.014 s to the log's end (all 7 joints, up to 0.64 rad/s " \
        "apart)" in said, said
    for log in ("link4.csv", "ur-static.csv"):
        r = invoke("inspect", str(real_logs / "ur_ext_observer" / log), "--channel-map",
                   "ur_ext_observer")
        assert r.exit_code == 0 and "tell two motions" not in r.stderr, r.stderr


@pytest.mark.real_logs
def test_the_real_kuka_logs_last_incident_is_marked(real_logs: Path, tmp_path: Path) -> None:
    """detect on the real KUKA log (uncalibrated): its one counted incident, from 24.824 s
    to the log's end, runs into the stretch — marked, still counted, said on its row."""
    import json

    r = invoke("detect", str(real_logs / "kuka_lwr4" / "measurements_1.npz"),
               "--channel-map", "kuka_lwr4", "-o", str(tmp_path))
    assert r.exit_code == 0, r.output
    tl = json.loads((tmp_path / "measurements_1.timeline.json").read_text("utf-8"))
    counted = [i for i in tl["incidents"] if i["number"] is not None]
    assert len(counted) == 1 and counted[0]["velocity_disagrees"]["joints"] == [
        f"a{k}" for k in range(1, 8)]
    assert counted[0]["t_start"] < counted[0]["velocity_disagrees"]["t_start"]
    assert "the logged velocity and positions disagree from 25.014 s" in r.stdout
    # a gate could not judge it (a trial's --fail-on-detect failed the log on it: exit 1)
    r = invoke("detect", str(real_logs / "kuka_lwr4" / "measurements_1.npz"),
               "--channel-map", "kuka_lwr4", "-o", str(tmp_path / "g"), "--fail-on-detect")
    assert r.exit_code == 5 and "--fail-on-detect could not judge 1 incident where the " \
        "log's velocity and positions tell two motions" in r.stderr, r.output


def test_many_stretches_are_all_counted_and_a_few_named() -> None:
    """A channel that disagrees again and again (120 stretches of 20 steps, 100 ms, in
    300 s: 4 % of the steps): MAX_KEPT kept, every one counted, MAX_NAMED named and the rest
    counted in the words. Disagreeing on more than AGREE_SHARE of the steps, the velocity
    is no derivative of these positions: nothing said."""
    from impactcli.logs.velocity_check import MAX_KEPT, MAX_NAMED, disagreement_message

    t, q, v = arm(300.0, 2)
    bad = v.copy()
    for k in range(120):
        bad[100 + 400 * k:100 + 400 * k + 19] += 1.0
    agree = VelocityAgreement(2)
    agree.add(t, q, bad)
    msg = disagreement_message("x.csv", agree, [0, 1], ("a", "b"), int(t[0]), int(t[-1]))
    assert len(agree.found) == MAX_KEPT and agree.n_found == 120
    assert msg is not None and msg.count(" apart)") == MAX_NAMED
    assert f"apart) and {120 - MAX_NAMED} more, where they agree elsewhere" in msg, msg
    agree = VelocityAgreement(2)
    agree.add(t, q, bad + np.where(np.arange(len(t)) % 7 == 0, 1.0, 0.0)[:, None])
    assert agree.bad_steps > 0.05 * agree.steps and disagreement_message(
        "x.csv", agree, [0, 1], ("a", "b"), int(t[0]), int(t[-1])) is None


def test_an_incident_overlapping_a_stretch_is_marked_and_said() -> None:
    """An incident whose span meets a stretch of two motions carries it (still counted);
    one that ends before it, or begins after, does not; the terminal's row and the
    report's verdict say it."""
    from impactcli.cli.detect import _incident_line
    from impactcli.detect.incidents import Incident, mark_disagreeing
    from impactcli.outputs.report.summary import verdict_text

    def inc(a: float, b: float) -> Incident:
        return Incident(a, b, int(a * 200), int(b * 200), ("adaptive",), ("a2",), 2, None,
                        "no kinematics", "transient", {"a2": -6.5}, False, number=1)

    stretch = ((25.014, 25.129, ("a1", "a2")),)
    marked = mark_disagreeing([inc(24.824, 25.129), inc(20.0, 24.9), inc(25.2, 25.3)],
                              stretch)
    assert marked[0].velocity_disagrees == {"t_start": 25.014, "t_end": 25.129,
                                            "joints": ["a1", "a2"]}
    assert [m.velocity_disagrees for m in marked[1:]] == [None, None]
    assert mark_disagreeing([inc(24.824, 25.129)], ()) == [inc(24.824, 25.129)]
    d = marked[0].to_dict()
    assert "the logged velocity and positions disagree from 25.014 s (velocity_disagrees " \
        "in the timeline)" in _incident_line(1, d)  # type: ignore[arg-type]
    assert verdict_text([d]).endswith(" Counted, though maybe no new contact: 1 where the "
                                      "log's velocity and positions tell two motions (maybe "
                                      "the data's).")
