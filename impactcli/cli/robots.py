"""``impactcli robots``: the robots the tool ships (the ``robots`` extra), each with the URDF
it uses and its arm joints — the names ``--robot NAME`` and a robot description's
``{"type": "urdf", "robot": NAME}`` take."""

from __future__ import annotations

import json
from typing import Any

import click

from .options import handle_errors


@click.command("robots")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
@handle_errors
def robots_cmd(as_json: bool) -> None:
    """List the robots --robot NAME takes: name, URDF, arm joints in chain order.

    Most come with the robots extra (pip install 'impactcli[robots]'); the arms built from
    their manufacturer's published table need only Pinocchio. Only those whose URDF is
    installed and loads are listed. Meshes are never needed.
    """
    from ..errors import EXIT_USAGE, one_line
    from ..logs import published_arms
    from ..logs import robot_catalogue as robots

    try:
        ok, bad = robots.available()
    except robots.RobotsExtraMissing as err:
        click.echo(f"impactcli: error: {one_line(err)}", err=True)
        click.get_current_context().exit(EXIT_USAGE)
        return
    doc: dict[str, Any] = {
        "package": robots.DIST, "version": robots.data_version(),
        "robots": [{"name": e.name, "urdf": None if e.built else e.urdf,
                    "source": (published_arms.SOURCE if e.built
                               else f"{robots.DIST} {robots.data_version()}"),
                    "title": e.title, "joints": list(j)}
                   for e, j in ok],
    }
    if bad:
        doc["not_loaded"] = [{"name": n, "reason": why} for n, why in bad]
    if as_json:
        click.echo(json.dumps(doc, separators=(",", ":")))
        return
    click.echo("Robots --robot NAME takes (URDF, or where a built arm's numbers come from; "
               "arm joints):")
    wn = max(len(e.name) for e, _ in ok) if ok else 4
    wu = max(len(e.urdf) for e, _ in ok) if ok else 4
    for e, joints in ok:
        click.echo(f"  {e.name:<{wn}}  {e.urdf:<{wu}}  {', '.join(joints)}")
    by_reason: dict[str, list[str]] = {}
    for name, why in bad:  # one line per reason: a missing extra is said once
        by_reason.setdefault(why, []).append(name)
    for why, names in by_reason.items():
        click.echo(f"impactcli: warning: {', '.join(names)} not listed: {why}", err=True)
