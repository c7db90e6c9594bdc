"""Every verb's --robot says what it takes: a robot description file, a shipped robot's
name (``impactcli robots`` lists them) and, for detect (whose workers fetch it), a URL."""

from __future__ import annotations

import click
import pytest
from click.testing import CliRunner

from impactcli.cli import VERBS, main

#: verb -> (metavar, what the description serves, where it may come from)
EXPECTED = {
    "inspect": ("FILE|NAME", "needed to turn currents into torques", "a file"),
    "identify": ("FILE|NAME", "joints, kinematics: planar or urdf", "a file"),
    "calibrate": ("FILE|NAME", "kinematics for the model, joint order", "a file"),
    "detect": ("FILE|URL|NAME", "joints, gear ratios, kinematics", "a file or an fsspec URL"),
    "report": ("FILE|NAME", "joints, gear ratios, kinematics", "a file"),
    "view": ("FILE|NAME", "joints, gear ratios, kinematics", "a file"),
    "evaluate": ("FILE|NAME", "joints, gear ratios, kinematics", "a file"),
    "labels": ("FILE|NAME", "for a log whose torque comes from currents", "a file"),
}


def _robot_option(verb: str) -> click.Option | None:
    ctx = click.Context(main)
    cmd = main.get_command(ctx, verb)
    assert cmd is not None
    return next((p for p in cmd.params if isinstance(p, click.Option)
                 and "--robot" in p.opts), None)


def test_every_verb_with_robot_is_checked() -> None:
    assert {v for v in VERBS if _robot_option(v) is not None} == set(EXPECTED)


@pytest.mark.parametrize("verb", sorted(EXPECTED))
def test_robot_help_names_file_name_and_the_robots_verb(verb: str) -> None:
    metavar, what, where = EXPECTED[verb]
    res = CliRunner().invoke(main, [verb, "--help"])
    assert res.exit_code == 0, res.output
    text = " ".join(res.stdout.split())
    assert (f"--robot {metavar} Robot description ({what}): {where} (JSON/YAML), or a "
            "shipped robot's name (`impactcli robots` lists them).") in text, text
