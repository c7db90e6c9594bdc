"""A contact's aftermath through the CLI, against the simulator's truth: the compliant
simulated arm (assist_like) rings for seconds after a 30 N push under a calm reference, and
the static-loading detector fires on the ringing's velocity reversals. Those alarms are no
labelled contact; each must say that it started while the arm had not settled after the
push's incident — and the pushes' own incidents must not."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.detect.incidents import settle_s
from impactcli.schema import validate


def _pick_and_place_run(d: Path, robot_seed: int, free: list[tuple[str, str, dict, int]],
                        pp_seed: int, *detect_extra: str) -> dict[str, Any]:
    """The free logs ``free`` ((name, scenario, overrides, seed) of the robot
    ``robot_seed``) calibrated; the 60 s pick-and-place (seed ``pp_seed``) detected with
    that config: the timeline, labels and output."""
    from impactcli.logs import write_log
    from impactcli.logs.robot_files import write_labels, write_robot
    from impactcli.sim import scenario, simulate

    for name, scen, kw, seed in free:
        write_log(simulate(scenario(scen, "assist_like", 60.0, robot_seed=robot_seed, **kw),
                           seed=seed).log, d / f"{name}.csv.gz")
    res = simulate(scenario("pick_and_place", "assist_like", 60.0, robot_seed=robot_seed),
                   seed=pp_seed)
    write_log(res.log, d / "pp.csv.gz")
    write_labels(res.labels, d / "pp.labels.json")
    write_robot(res.robot, d / "robot.json")
    run = CliRunner()
    r = run.invoke(main, ["calibrate", *(str(d / f"{n}.csv.gz") for n, *_ in free),
                          "--robot", str(d / "robot.json"), "-o", str(d / "cal.toml")])
    assert r.exit_code == 0, r.output
    r = run.invoke(main, ["detect", str(d / "pp.csv.gz"), "--config", str(d / "cal.toml"),
                          *detect_extra, "-o", str(d / "out")])
    assert r.exit_code == 0, r.output
    tl = json.loads((d / "out" / "pp.timeline.json").read_text())
    validate(tl, "timeline", AssertionError, "timeline")
    return {"dir": d, "timeline": tl, "labels": res.labels, "stdout": r.stdout}


@pytest.fixture(scope="module")
def rung(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """Two free logs (one carrying the pick-and-place's 1 kg), calibrated; the 60 s
    pick-and-place with its four pushes detected; the timeline, labels and output."""
    d = tmp_path_factory.mktemp("rung")
    return _pick_and_place_run(d, 23, [("free_a", "free_multisine", {}, 1),
                                       ("free_b", "free_multisine", {"payload_kg": 1.0}, 2)],
                               3, "--robot", str(d / "robot.json"))


def test_alarms_in_a_pushs_ringing_say_so_and_the_pushes_do_not(rung: dict[str, Any]
                                                                 ) -> None:
    tl, labels = rung["timeline"], rung["labels"]
    counted = [i for i in tl["incidents"] if i["number"] is not None]
    # the incident that answers each push: the first starting in its window
    answer = {}
    for c in labels.events:
        first = next(i for i in counted if c.start - 0.1 <= i["t_start"] <= c.end + 0.2)
        answer[first["number"]] = c
        assert "aftermath" not in first, first  # a push is no push's aftermath
    strong = [n for n, c in answer.items() if c.peak_force > 25.0]
    ringing = [i for i in counted if i["number"] not in answer
               and not any(c.start - 0.1 <= i["t_start"] <= c.end + 0.2
                           for c in labels.events)]
    assert len(ringing) >= 3  # the case: 2–5 N "contacts" after the 30 N pushes
    for i in ringing:
        m = i.get("aftermath")
        assert m is not None, i
        assert m["incident"] in strong  # of a 30 N push's incident, none of a 20 N one's
        cause = next(x for x in counted if x["number"] == m["incident"])
        assert cause["t_end"] < i["t_start"] <= m["until_s"] + 0.6
        assert i["t_start"] - cause["t_start"] < 3.0  # seconds, not the rest of the log
        lo, hi = m["measured"]["calibrated"]
        assert not lo <= m["measured"]["value"] <= hi  # the measured motion was out
        assert m["text"].startswith(f"in the aftermath of incident {m['incident']} at ")
        assert i["force_n"] < 8.0  # small beside the push (24–26 N): the ringing's size
    # the terminal's row says it, and where to read the rest
    rows = [ln for ln in rung["stdout"].splitlines()
            if "(aftermath in the timeline)" in ln]
    assert len(rows) == len([i for i in counted if "aftermath" in i])
    # the reference stayed calm: the envelope alone flagged not all of them
    assert any(not i["outside_envelope"] for i in ringing)
    # the config recorded the measured ranges, the timeline the stretches
    cal = (rung["dir"] / "cal.toml").read_text()
    assert "measured_acceleration = [" in cal and "measured_velocity = [" in cal
    assert tl["motion_envelope"]["measured_stretches"]


def test_evaluate_says_which_unmatched_incidents_are_an_aftermath(rung: dict[str, Any]
                                                                 ) -> None:
    d = rung["dir"]
    args = ["evaluate", str(d / "out" / "pp.timeline.json"), "--labels",
            str(d / "pp.labels.json")]
    r = CliRunner().invoke(main, [*args, "--json"])
    assert r.exit_code == 0, r.output
    ev = json.loads(r.stdout)["incidents"]
    after = ev["unmatched_in_aftermath"]
    assert after and set(after) <= set(ev["unmatched_incidents"])
    tl = rung["timeline"]["incidents"]
    assert all("aftermath" in tl[k] or "close_behind" in tl[k] for k in after)
    # still counted: every unmatched incident is in the count, the aftermath said apart
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    assert (f"({len(ev['unmatched_incidents'])} matching no labelled contact, {len(after)} "
            "of them maybe an earlier incident's ringing (in its aftermath or close behind "
            "it))") in r.stdout


@pytest.fixture(scope="module")
def close(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A trial's robot (seed 53), calibrated on free point-to-point moves and a multi-sine
    carrying 1 kg — measured motion wide enough that a push's ringing stays inside it — and
    its pick-and-place (seed 94: pushes of 30, 20, 30, 20 N, the third while carrying)."""
    return _pick_and_place_run(tmp_path_factory.mktemp("close"), 53,
                               [("p2p", "free_p2p", {}, 61),
                                ("loaded", "free_multisine", {"payload_kg": 1.0}, 11)], 94)


def test_a_ringing_the_measured_motion_did_not_tell_is_close_behind_its_push(
        close: dict[str, Any]) -> None:
    """Against the simulator's truth: every alarm marked close behind matches no labelled
    contact and follows, within the settling time, a chain headed by a push's incident; no
    push's own incident is marked; the 30 N push made while carrying rang as a marked chain
    of alarms no stronger than it."""
    tl, labels = close["timeline"], close["labels"]
    counted = {i["number"]: i for i in tl["incidents"] if i["number"] is not None}
    pushes = {}
    for c in labels.events:
        first = next(i for i in counted.values() if c.start - 0.1 <= i["t_start"] <= c.end + 0.2)
        pushes[first["number"]] = c
        assert "close_behind" not in first and "aftermath" not in first, first
    marked = [i for i in counted.values() if "close_behind" in i]
    cfg = tomllib.loads((close["dir"] / "cal.toml").read_text())
    settle = settle_s(cfg["static_loading"]["cutoff_hz"], cfg["adaptive"]["n2_s"])
    for i in marked:
        m = i["close_behind"]
        assert not any(c.start - 0.1 <= i["t_start"] <= c.end + 0.2 for c in labels.events)
        before = counted[m["after"]]
        assert 0 < i["t_start"] - before["t_end"] == pytest.approx(m["gap_s"])
        assert m["gap_s"] <= settle + 1e-9 and m["settle_s"] == pytest.approx(settle)
        assert i["force_n"] <= counted[m["incident"]]["force_n"] == m["force_n"]
    carried = next(n for n, c in pushes.items() if 34.0 < c.start < 36.0)
    chain = [i for i in marked if i["close_behind"]["incident"] == carried]
    assert len(chain) >= 2, [(i["t_start"], i.get("close_behind")) for i in marked]
    assert all(i["t_start"] - counted[carried]["t_start"] < 5.0 for i in chain)
    rows = [ln for ln in close["stdout"].splitlines() if "(close_behind in the timeline)" in ln]
    assert len(rows) == len(marked)
    assert any(f"close behind incident {carried} (" in r and "maybe its ringing" in r
               for r in rows), rows
