"""The options that say how to read a log, shared by the verbs that read logs
(``--channel-map``, ``--topic``, ``--reference-topic``, ``--time-source``,
``--torque-source``, ``--time-unit``, ``--repair-order``): :func:`log_read_options`, and
:func:`read_options_from` turning them into the readers' keyword arguments. Importing it
imports no model: ``impactcli inspect`` and ``labels`` start fast.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

#: click context ``meta`` key under which --time-unit and --repair-order are kept.
_READ_META = "impactcli.read_options"


def read_options_from(channel_map: str | None, topic: str | None, reference_topic: str | None,
                      time_source: str | None, torque_source: str | None, *,
                      time_unit: str | None = None,
                      repair_order: bool | None = None) -> dict[str, Any]:
    """The read_log keyword arguments given on the command line (None values dropped).

    ``time_unit`` and ``repair_order`` default to the ``--time-unit`` and
    ``--repair-order`` of the running command (:func:`log_read_options` keeps them in the
    click context, so verbs need not take them as parameters); ``repair_order`` is kept
    only when true.
    """
    ctx = click.get_current_context(silent=True)
    given = dict(ctx.meta.get(_READ_META, {})) if ctx is not None else {}
    if time_unit is None:
        time_unit = given.get("time_unit")
    if repair_order is None:
        repair_order = given.get("repair_order")
    opts = {"channel_map": channel_map, "topic": topic, "reference_topic": reference_topic,
            "time_source": time_source, "torque_source": torque_source,
            "time_unit": time_unit, "repair_order": True if repair_order else None}
    return {k: v for k, v in opts.items() if v is not None}


def _keep_read_option(ctx: click.Context, param: click.Parameter, value: Any) -> Any:
    """Keep --time-unit / --repair-order in the context for :func:`read_options_from`."""
    if value is not None and param.name is not None:
        ctx.meta.setdefault(_READ_META, {})[param.name] = value
    return value


def check_channel_map(ctx: click.Context, param: click.Parameter, value: str | None
                      ) -> str | None:
    """``--channel-map``: a file that exists or a shipped map's name, else a usage error
    (exit 2) listing the shipped maps; a file's content is checked when it is read (a bad
    one is a data error, exit 3)."""
    if value is None or "://" in value:
        return value
    from ..errors import ChannelMapError
    from ..io.channel_map import resolve_channel_map_path

    try:
        resolve_channel_map_path(value)
    except ChannelMapError as err:
        raise click.BadParameter(str(err), ctx=ctx, param=param) from None
    return value


def log_read_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The options that say how to read a log (shared by the verbs that read logs).

    ``--time-unit`` and ``--repair-order`` are not passed to the command: they reach
    :func:`read_options_from` through the click context.
    """
    for opt in reversed([
        click.option("--channel-map", metavar="MAP", callback=check_channel_map,
                     help="Channel map (path, or a shipped name) for foreign CSV / .npz logs."),
        click.option("--topic", help="MCAP: the JointState/state topic."),
        click.option("--reference-topic", help="MCAP: the reference topic."),
        click.option("--time-source", type=click.Choice(["log", "publish", "header"]),
                     help="MCAP: which clock stamps samples [default: header, else log]."),
        click.option("--torque-source", type=click.Choice(["current", "torque"]),
                     help="Use logged torque or current × gear ratio × torque constant."),
        click.option("--time-unit", type=click.Choice(["s", "ms", "us", "ns"]),
                     expose_value=False, callback=_keep_read_option,
                     help="CSV / .npz: the unit of the time column [default: s, or the "
                          "channel map's]. A time implying a rate outside 20 Hz – 100 kHz "
                          "is an error."),
        click.option("--repair-order", is_flag=True, default=None, expose_value=False,
                     callback=_keep_read_option,
                     help="Rows out of time order or sharing a stamp: keep the longest "
                          "increasing run of stamps and drop the others, warned [default: "
                          "an error naming the row]."),
    ]):
        func = opt(func)
    return func
