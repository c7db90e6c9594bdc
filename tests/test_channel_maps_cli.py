"""``impactcli channel-maps``: where the shipped maps are, and one map's text to start from."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from click.testing import CliRunner

from impactcli.cli import main
from impactcli.logs.channel_map import load_channel_map, shipped_map_names


def test_the_list_names_every_shipped_map_with_its_format_and_folder() -> None:
    r = CliRunner().invoke(main, ["channel-maps"])
    assert r.exit_code == 0, r.output
    names = shipped_map_names()
    assert "ur_rtde_example" in names and "kuka_lwr4" in names
    for name in names:
        assert f"  {name} " in r.stdout
    assert "use --channel-map NAME" in r.stdout
    doc = json.loads(CliRunner().invoke(main, ["channel-maps", "--json"]).stdout)
    assert [m["name"] for m in doc["channel_maps"]] == names
    assert all(Path(m["path"]).is_file() for m in doc["channel_maps"])


def test_a_printed_map_reads_back_as_the_shipped_one(tmp_path: Path) -> None:
    for name in shipped_map_names():
        r = CliRunner().invoke(main, ["channel-maps", name])
        assert r.exit_code == 0, r.output
        copy = tmp_path / f"{name}.yaml"
        copy.write_text(r.stdout, encoding="utf-8")
        assert dataclasses.replace(load_channel_map(copy), path="") == dataclasses.replace(
            load_channel_map(name), path="")
        path = CliRunner().invoke(main, ["channel-maps", name, "--path"]).stdout.strip()
        assert Path(path).read_text("utf-8") == r.stdout


def test_an_unknown_name_is_a_usage_error_listing_the_maps() -> None:
    r = CliRunner().invoke(main, ["channel-maps", "ur_rdte"])
    assert r.exit_code == 2
    assert "'ur_rdte' is not a shipped channel map (shipped: franka_state_example" in r.stderr
