"""``impactcli channel-maps [NAME]``: the channel maps the tool ships, and one map's text.

Without NAME: each shipped map's name, format and description, and the folder they are in.
With NAME: the map's text on stdout (``impactcli channel-maps ur_rtde_example > my.yaml``
starts a map of your own), or with ``--path`` the file it is in. A shipped map's name is
what ``--channel-map`` takes.
"""

from __future__ import annotations

import json
from typing import Any

import click

from .options import handle_errors


def shipped_maps() -> list[dict[str, Any]]:
    """Name, format, description and file of every shipped map, sorted by name."""
    import yaml

    from ..logs.channel_map import shipped_map_names, shipped_maps_dir

    out = []
    folder = shipped_maps_dir()
    for name in shipped_map_names():
        path = next(p for p in sorted(folder.iterdir()) if p.stem == name)
        doc = yaml.safe_load(path.read_text("utf-8")) or {}
        out.append({"name": name, "format": str(doc.get("format", "csv")),
                    "description": str(doc.get("description", "")), "path": str(path)})
    return out


@click.command("channel-maps")
@click.argument("name", required=False)
@click.option("--path", "show_path", is_flag=True, help="Print the map's file, not its text.")
@click.option("--json", "as_json", is_flag=True, help="Print the list as one JSON object.")
@handle_errors
def channel_maps_cmd(name: str | None, show_path: bool, as_json: bool) -> None:
    """List the shipped channel maps, or print one (NAME) to copy and edit.

    A channel map reads a log whose columns, topics or arrays are not the canonical ones
    (schemas/channel_map.schema.json); give it with --channel-map NAME|FILE.
    """
    maps = shipped_maps()
    if name is None:
        if show_path:
            raise click.UsageError("--path needs a NAME")
        if as_json:
            click.echo(json.dumps({"channel_maps": maps}, separators=(",", ":")))
            return
        from ..logs.channel_map import shipped_maps_dir

        click.echo(f"Channel maps shipped in {shipped_maps_dir()} (use --channel-map NAME; "
                   "`impactcli channel-maps NAME` prints one):")
        w = max((len(m["name"]) for m in maps), default=4)
        for m in maps:
            click.echo(f"  {m['name']:<{w}}  {m['format']:<8}  {m['description']}")
        return
    found = [m for m in maps if m["name"] == name]
    if not found:
        raise click.BadParameter(
            f"{name!r} is not a shipped channel map (shipped: "
            f"{', '.join(m['name'] for m in maps)})", param_hint="'NAME'")
    from pathlib import Path

    path = Path(found[0]["path"])
    click.echo(str(path) if show_path else path.read_text("utf-8"), nl=show_path)
