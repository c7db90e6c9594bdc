"""A load released (impactcli/detect/release.py): the residual's block means, the hold an
incident's alarm ended, known truth on built block sequences, and through the CLI the real
UR arm pushed by hand (skipped without the real logs)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from impactcli.detect.incidents import Incident
from impactcli.detect.release import (
    BlockTrace,
    block_noise,
    held_level,
    mark_held,
)

from .cli_run import cli


def test_block_means_are_the_same_whatever_the_chunks() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(1003, 2))
    whole = BlockTrace(2, 10)
    whole.update(x)
    parts = BlockTrace(2, 10)
    for a in range(0, 1003, 77):
        parts.update(x[a:a + 77])
    assert whole.finish().shape == (100, 2)
    np.testing.assert_allclose(parts.finish(), whole.finish(), rtol=0, atol=1e-6)
    np.testing.assert_allclose(whole.finish()[3], x[30:40].mean(axis=0), atol=1e-6)


def _held(level: float = 10.0, start: int = 50, end: int = 90, before: float = 0.0,
          after: float = 0.0, noise: float = 0.2, n: int = 140, seed: int = 1) -> np.ndarray:
    """Block means: ``before`` until block ``start``, ``level`` until ``end`` (the alarm),
    ``after`` from then on, with white noise of sd ``noise``."""
    x = np.full(n, before, dtype=float)
    x[start:end] = level
    x[end:] = after
    return x + np.random.default_rng(seed).normal(0.0, noise, n)


def test_a_hold_released_is_found_with_its_start_and_levels() -> None:
    x = _held()
    sigma = float(block_noise(x[:, None])[0])
    assert 0.15 < sigma < 0.3  # the white noise's sd, from the block-to-block differences
    got = held_level(x, 90, sigma, peak=8.0, min_blocks=10)
    assert got is not None
    first, held, after = got
    assert first == 50 and abs(held - 10.0) < 0.2 and abs(after) < 0.2


@pytest.mark.parametrize("case, kw, peak", [
    ("a step within the noise", {"level": 1.0}, 0.5),
    ("a step small beside the incident's own peak", {}, 25.0),
    ("held since the log's start", {"start": 0}, 8.0),
    ("a level that moved (before 0, after 6)", {"after": 6.0}, 8.0),
    ("held shorter than the least hold", {"start": 84}, 8.0),
])
def test_what_is_not_a_load_released(case: str, kw: dict, peak: float) -> None:
    x = _held(**kw)
    sigma = float(block_noise(x[:, None])[0])
    assert held_level(x, 90, sigma, peak=peak, min_blocks=10) is None, case


def _inc(number: int | None, t0: float, k0: int, warm: bool = False) -> Incident:
    return Incident(t_start=t0, t_end=t0 + 0.05, i_start=k0, i_end=k0 + 5,
                    detectors=("adaptive",), joints=("j2",), link=2, force_n=None,
                    force_method="", contact="transient", peak_residual={"j2": 8.0},
                    in_warmup=warm, number=number)


def test_mark_held_marks_a_release_and_not_a_hold_whose_start_an_incident_caught() -> None:
    """Blocks of 10 samples at 100 Hz (0.1 s): j2 holds 10 N·m from 5.0 s to 9.0 s. The
    incident at the release (9.0 s) is marked from 5.0 s; with an incident at 5.0 s (the
    push's start caught) it is not; nor is a warm-up one."""
    means = np.column_stack([np.zeros(140), _held()])
    rel = _inc(2, 9.0, 900)
    (out,) = mark_held([rel], means, 10, 0.01, ("j1", "j2"))
    assert out.held_before["t_start"] == pytest.approx(5.0)
    assert out.held_before["joints"]["j2"]["held_nm"] == pytest.approx(10.0, abs=0.2)
    assert out.held_before["text"].startswith(
        "ended a load held since 5.000 s: j2's residual stood at ")
    seen = mark_held([_inc(1, 5.0, 500), rel], means, 10, 0.01, ("j1", "j2"))
    assert [x.held_before for x in seen] == [None, None]
    (warm,) = mark_held([_inc(None, 9.0, 900, warm=True)], means, 10, 0.01, ("j1", "j2"))
    assert warm.held_before is None


def test_the_real_arm_pushed_by_hand_its_releases_dated_from_the_pushes(
        real_logs: Path, tmp_path: Path) -> None:
    """ur-static.csv (uncalibrated, as a UR10e): its incidents 2 and 3 are alarms at the
    releases of pushes the log's own currents show beginning at about 11.5 s and 25.3 s
    (elbow −9 → +5 A·K between 11.23 and 11.76 s; shoulder_lift −39 → −67 between 25.08
    and 25.62 s); the first, at 3.22 s, began with its push and is not marked."""
    import json

    robot = tmp_path / "ur10e.robot.json"
    robot.write_text(json.dumps({"kinematics": {"type": "urdf", "robot": "ur10e"},
                                 "joint_map": {j: f"{j}_joint" for j in (
                                     "shoulder_pan", "shoulder_lift", "elbow", "wrist_1",
                                     "wrist_2", "wrist_3")}}), encoding="utf-8")
    code, out, err = cli("detect", real_logs / "ur_ext_observer" / "ur-static.csv",
                         "--channel-map", "ur_ext_observer", "--robot", robot, "-o",
                         tmp_path / "o")
    assert code == 0, err
    tl = json.loads((tmp_path / "o" / "ur-static.timeline.json").read_text())
    held = {i["number"]: i.get("held_before") for i in tl["incidents"] if i["number"]}
    assert held[1] is None
    assert 11.2 <= held[2]["t_start"] <= 12.2 and 25.0 <= held[3]["t_start"] <= 26.0, held
    assert held[2]["joints"]["elbow"]["held_nm"] < -25.0 < 25.0 < \
        held[3]["joints"]["elbow"]["held_nm"]
    assert "ended a load held since 11.9" in out and "(held_before in the timeline)" in out


def test_an_alarm_while_the_load_still_holds_is_no_release() -> None:
    """A clamp that builds up and crosses its threshold at block 70 of a hold from 50 to
    90: the residual stays held after the alarm began, so it is not the hold's release (a
    trial's heavy-arm clamp, alarming 2.3 s into its build-up, was first marked so)."""
    x = _held()
    sigma = float(block_noise(x[:, None])[0])
    assert held_level(x, 70, sigma, peak=8.0, min_blocks=10) is None
    assert held_level(x, 90, sigma, peak=8.0, min_blocks=10) is not None
