"""How a run's Rerun recording looks: entity paths, colours, texts and its default blueprint
(docs/formats.md, "Rerun recording"); what it holds is :mod:`impactcli.outputs.rerun`'s.

Within a plot the statistic, its threshold and its detector's markers differ, and each
detector has one colour everywhere (its markers and its "detected" state). The blueprint
puts the incident lane and forces on top, one column (tabs beyond four joints) per joint
with its four plots and state lanes, the event log and run summary below; every plot and
lane opens on the whole log, ``[0, duration]`` on ``time_since_start``. ``rerun``
(rerun-sdk) is imported inside the functions, never at module import.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .. import __version__
from ..detect.aftermath import ringing_text
from ..detect.force import force_mark
from ..detect.incidents import link_words
from ..detect.payload_words import carrying_text, tested_text

#: Timeline on the log's own clock (a timestamp), as Rerun's MCAP import names it.
LOG_TIMELINE = "message_log_time"
#: Timeline in seconds since the log's first sample (a duration).
ELAPSED_TIMELINE = "time_since_start"
APPLICATION_ID = "impactcli"

#: detector → (plot it is marked on, signal whose value the marker takes)
MARKED_ON: dict[str, tuple[str, str]] = {
    "adaptive": ("rms", "residual_rms"),
    "static_loading": ("loading", "loading_statistic"),
    "static_baseline": ("residual", "residual"),
}
#: Plot titles, with the colour of each series: the plots carry no legend box (it would
#: cover the end of the log, where a contact may be), the series are named in the title.
PLOT_TITLES: dict[str, str] = {
    "rms": "residual RMS (blue) vs threshold (gold), adaptive ✕ (red)",
    "loading": "loading statistic (purple) vs vL (gold), static_loading ◆ (pink)",
    "residual": "residual r (grey), filtered (cyan), static_baseline ▲ (orange)",
    "position": "position: measured (blue), reference (green)",
}
RGB = tuple[int, int, int]
#: One colour per detector, for its markers and its "detected" lane state.
DETECTOR_COLORS: dict[str, RGB] = {
    "adaptive": (214, 39, 40),          # red
    "static_loading": (227, 119, 194),  # pink
    "static_baseline": (255, 127, 14),  # orange
}
#: Thresholds (v_stat + v_rms, vL) in every plot.
THRESHOLD_COLOR: RGB = (255, 193, 7)  # gold
SERIES_COLORS: dict[str, RGB] = {
    "residual RMS": (31, 119, 180),          # blue
    "threshold v_stat+v_rms": THRESHOLD_COLOR,
    "loading statistic": (148, 103, 189),    # purple
    "vL": THRESHOLD_COLOR,
    "residual r": (127, 127, 127),           # grey
    "filtered residual": (23, 190, 207),     # cyan
    "reference": (44, 160, 44),              # green
    "measured": (31, 119, 180),              # blue
}
MARKER_SHAPE: dict[str, Any] = {  # rr MarkerShape name
    "adaptive": "Cross",
    "static_loading": "Diamond",
    "static_baseline": "Up",
}
#: Incident spans by contact type (``/incidents/contact``); the force markers' colour.
CONTACT_COLORS: dict[str, RGB] = {
    "transient": (0, 158, 115),      # bluish green
    "quasi_static": (106, 61, 154),  # deep purple
    "unknown": (150, 150, 150),
}
INCIDENT_FORCE_COLOR: RGB = (0, 158, 115)
CLEAR_COLOR: RGB = (189, 189, 189)
NO_CONTACT = "no contact"



def esc(name: str) -> str:
    """``name`` escaped as one part of a Rerun entity path."""
    import rerun as rr

    return str(rr.escape_entity_path_part(name))


def joint_entity(joint: str) -> str:
    """Root entity path of a joint's plots."""
    return f"/joints/{esc(joint)}"



def markdown_summary(result: Any) -> str:
    """The run summary shown beside the event log (markdown)."""
    log = result.log
    lines = [
        f"# impactcli {__version__}: `{log.source.path}`",
        "",
        f"- {log.n_joints} joints, {log.duration_s:.3f} s at {log.sample_rate_hz:.1f} Hz, "
        f"t0 = {log.t0_ns} ns ({log.source.format}, time source {log.source.time_source})",
        (f"- model: {result.model.get('kind', '?')} ({result.model_source}), "
         f"sha256 {(result.model_sha256 or '')[:12]}…" if result.model is not None
         else "- model: none (the controller's channels)"),
        "- residual generator: " + ", ".join(
            f"{j} {g['generator']}" for j, g in result.generators.items()),
        "- thresholds "
        + ("calibrated" if result.calibrated else "UNCALIBRATED (from the log itself)")
        + f"; reference: {result.reference_source}",
        f"- warm-up ends at {result.warmup_end_s:.3f} s (latest over joints)",
        "",
        "| detector | events | in warm-up |",
        "|---|---|---|",
    ]
    lines += [f"| {d} | {s['events']} | {s['in_warmup']} |" for d, s in result.summary().items()]
    incs = list(result.incidents)
    loads = list(result.lasting_loads)
    lines += ["", f"{len(result.counted_incidents())} incident(s) after warm-up"
              + (f", {len(incs) - len(result.counted_incidents())} in warm-up" if
                 len(incs) > len(result.counted_incidents()) else "")
              + f"; {len(result.counted_lasting_loads())} lasting load(s) after warm-up"]
    names = incident_names(incs)
    if incs:
        lines += ["", "| # | start [s] | end [s] | link | force [N] | contact | detectors |",
                  "|---|---|---|---|---|---|---|"]
        for name, inc in zip(names, incs, strict=True):
            force = (f"{force_mark(inc)}{inc.force_n:.3g}" if inc.force_n is not None
                     else "–")
            link = ("–" if inc.link is None
                    else link_words(inc.link, inc.link_candidates).removeprefix("link "))
            lines.append(f"| {name}{' (warm-up)' if inc.in_warmup else ''} | "
                         f"{inc.t_start:.3f} | {inc.t_end:.3f} | {link} | {force} | "
                         f"{inc.contact} | {', '.join(inc.detectors)} |")
    if loads:
        lines += ["", "Lasting loads (alarms of 10 s or more: an unknown payload, a clamp, or a "
                  "model that no longer fits):", "",
                  "| # | start [s] | end [s] | detector | joints | peak ratio |",
                  "|---|---|---|---|---|---|"]
        for k, x in enumerate(loads, 1):
            lines.append(f"| L{k}{' (warm-up)' if x.in_warmup else ''} | {x.t_start:.3f} | "
                         f"{x.t_end:.3f} | {x.detector} | {', '.join(x.joints)} | "
                         f"{x.peak_ratio:.3g} |")
    changes = list(result.payload_changes or ())
    if changes:
        lines += ["", "Payload changes (a load picked or released: not incidents; the residual "
                  "carries the new load from the classification on):", "",
                  "| # | at [s] | mass [kg] | tests | classified at [s] | then carrying |",
                  "|---|---|---|---|---|---|"]
        for k, c in enumerate(changes, 1):
            lines.append(f"| P{k} | {c['t_start']:.3f} | {c['mass_kg']:+.3g} (s.e. ≥ "
                         f"{c['mass_se_kg']:.2g}) | {tested_text(c)} | "
                         f"{c['t_classified']:.3f} | {carrying_text(c)} |")
    lines += ["", "| joint | v_stat | v0 | vL |", "|---|---|---|---|"]
    for joint in log.joint_names:
        th = result.thresholds.get(joint, {})
        cells = " | ".join(f"{th[k]:.4g}" if k in th else "–" for k in ("v_stat", "v0", "vL"))
        lines.append(f"| {joint} | {cells} |")
    return "\n".join(lines) + "\n"


def event_text(e: Any) -> str:
    """An event's text-log line."""
    res = ", ".join(f"{j} {r:+.3g} N·m" for j, r in e.peak_residual.items())
    text = (f"{e.detector} on {', '.join(e.joints)}: peak ratio {e.peak_ratio:.2f}"
            f" ({e.t_start:.3f}–{e.t_end:.3f} s); peak residual {res}")
    return text + (" [in warm-up]" if e.in_warmup else "")


def incident_names(incs: Sequence[Any]) -> list[str]:
    """Each incident's name, as the terminal and the report give it: its ``number`` (1, 2,
    … over the counted incidents), ``w1``, ``w2``, … in the warm-up, ``d1``, ``d2``, … at a
    data defect, ``pK`` for the alarm of payload change ``PK``; incidents made without numbers
    (before timeline 2.1) keep their place in the list (1, 2, …)."""
    if not any(getattr(i, "number", None) is not None for i in incs):
        return [str(k) for k in range(1, len(incs) + 1)]
    out, warm, marked = [], 0, 0
    for i in incs:
        if i.in_warmup:
            warm += 1
            out.append(f"w{warm}")
        elif getattr(i, "data_defect", None) is not None:
            marked += 1
            out.append(f"d{marked}")
        elif getattr(i, "payload_change", None) is not None:  # the change's own number
            out.append(f"p{i.payload_change}")
        else:
            out.append(str(i.number))
    return out


def incident_label(k: int | str, inc: Any) -> str:
    """The span label of the incident named ``k`` (:func:`incident_names`):
    ``#k link L · F N · type``."""
    link = link_words(inc.link, inc.link_candidates, unknown="link ?")
    force = f"{force_mark(inc)}{inc.force_n:.3g} N" if inc.force_n is not None else "force ?"
    return f"#{k} {link} · {force} · {inc.contact}" + (" (warm-up)" if inc.in_warmup else "") \
        + _defect_note(inc, " ({kind}: not counted)") + _payload_note(
            inc, " (payload change P{p}: not counted)")


def incident_text(k: int | str, inc: Any) -> str:
    """The text-log line of the incident named ``k`` (:func:`incident_names`)."""
    link = link_words(inc.link, inc.link_candidates)
    force = (f"{force_mark(inc)}{inc.force_n:.3g} N ({inc.force_method})"
             if inc.force_n is not None
             else "force unknown (no kinematics)")
    text = (f"incident #{k}: {link}, {force}, {inc.contact} contact; "
            f"{', '.join(inc.detectors)} on {', '.join(inc.joints)} "
            f"({inc.t_start:.3f}–{inc.t_end:.3f} s)")
    return text + (" [in warm-up]" if inc.in_warmup else "") + _defect_note(
        inc, " [at a data defect, a {kind} at {t:.3f} s: not counted]") + _payload_note(
        inc, " [the alarm of payload change P{p}, a load picked or released: not counted]"
    ) + ("" if (ringing := ringing_text(inc)) is None else f" [{ringing}]")


def _payload_note(inc: Any, form: str) -> str:
    """``form`` filled with the payload change the incident is (p), or "" when none."""
    p = getattr(inc, "payload_change", None)
    return "" if p is None else form.format(p=p)


def _defect_note(inc: Any, form: str) -> str:
    """``form`` filled with the incident's data defect (kind, t), or "" when it has none."""
    d = getattr(inc, "data_defect", None)
    return "" if d is None else form.format(kind=d["kind"], t=d["t_start"])


def whole_log_range(duration_s: float) -> tuple[Any, Any]:
    """``(TimeRange, VisibleTimeRange)`` covering ``[0, duration_s]`` on ``time_since_start``:
    the x axis and the data range every plot and lane opens on."""
    import rerun.blueprint as rrb

    start = rrb.TimeRangeBoundary.absolute(seconds=0.0)
    end = rrb.TimeRangeBoundary.absolute(seconds=max(float(duration_s), 0.0))
    return (rrb.TimeRange(start=start, end=end),
            rrb.VisibleTimeRange(ELAPSED_TIMELINE, start=start, end=end))


def default_blueprint(joint_names: Sequence[str], has_reference: bool = True, *,
                      duration_s: float | None = None, has_incidents: bool = True) -> Any:
    """The layout shipped in the file (a ``rerun.blueprint.Blueprint``).

    On top, the incident lane beside the incident forces (``has_incidents``); one column
    per joint (tabs beyond four joints) stacking its RMS-vs-threshold, loading-vs-vL,
    residual and position plots over its detection state lanes (warm-up and one lane per
    detector); below, the event log (events and incidents) beside the run summary. Time
    panel on ``time_since_start``. With ``duration_s`` every plot and lane shows the whole
    log, ``[0, duration_s]`` (x axis and visible time range), whatever the time cursor.
    """
    import rerun.blueprint as rrb

    ranged: dict[str, Any] = {}
    lane_ranged: dict[str, Any] = {}
    if duration_s is not None:
        view_range, visible = whole_log_range(duration_s)
        ranged = {"axis_x": rrb.TimeAxis(view_range=view_range), "time_ranges": visible}
        lane_ranged = {"time_view": rrb.TimeAxis(view_range=view_range),
                       "time_ranges": visible}
    legend = rrb.PlotLegend(visible=False)  # the titles name the series and their colours
    columns = []
    for joint in joint_names:
        root = joint_entity(joint)
        titles = dict(PLOT_TITLES)
        if not has_reference:
            titles["position"] = "position: measured (blue; no reference logged)"
        views: list[Any] = [
            rrb.TimeSeriesView(origin=f"{root}/{plot}", name=f"{joint}: {title}",
                               plot_legend=legend, **ranged)
            for plot, title in titles.items()
        ]
        views.append(rrb.StateTimelineView(origin=f"/detections/{esc(joint)}",
                                           name=f"{joint}: detections", **lane_ranged))
        columns.append(rrb.Vertical(*views, row_shares=[3, 3, 3, 3, 5], name=joint))
    joints_box = rrb.Horizontal(*columns) if len(columns) <= 4 else rrb.Tabs(*columns)
    bottom = rrb.Tabs(
        rrb.TextLogView(
            origin="/", contents=["/incidents", "/payload_changes", "/events/**",
                                  "/run/log/**"],
            name="events and incidents",
            columns=rrb.TextLogColumns(timeline_columns=[ELAPSED_TIMELINE],
                                       text_log_columns=["loglevel", "entitypath", "body"]),
            rows=rrb.TextLogRows(filter_by_log_level=["TRACE", "DEBUG", "INFO", "WARN",
                                                      "ERROR", "CRITICAL"]),
        ),
        rrb.TextDocumentView(origin="/run/info", name="run"),
    )
    rows: list[Any] = [joints_box, bottom]
    shares: list[float] = [10, 4]
    if has_incidents:
        top = rrb.Horizontal(
            rrb.StateTimelineView(origin="/incidents", contents=["/incidents/contact"],
                                  name="incidents (link · force · contact type)",
                                  **lane_ranged),
            rrb.TimeSeriesView(origin="/incidents/force",
                               name="incident force [N] (green dots, at each start)",
                               plot_legend=legend, **ranged),
            column_shares=[3, 1],
        )
        rows.insert(0, top)
        shares.insert(0, 2)
    return rrb.Blueprint(
        rrb.Vertical(*rows, row_shares=shares),
        # "following" puts the cursor at the end (the plots keep their whole-log range)
        rrb.TimePanel(timeline=ELAPSED_TIMELINE, state="collapsed", play_state="following"),
        collapse_panels=True,
    )



def lanes_entity(joint: str) -> str:
    """Root entity path of a joint's detection lanes."""
    return f"/detections/{esc(joint)}"


def style_series(rec: Any, entity: str, names: Sequence[str]) -> None:
    """The static style of a plot's series (names and colours)."""
    import rerun as rr

    rec.log(entity, rr.SeriesLines(names=list(names), colors=[SERIES_COLORS[s] for s in names],
                                   widths=[1.5] * len(names)), static=True, strict=True)


def style_lane(rec: Any, joint: str, det: str) -> None:
    """The static states of a detector's lane (clear / detected in its colour)."""
    import rerun as rr

    rec.log(f"{lanes_entity(joint)}/{det}", rr.StateConfiguration(
        values=["clear", "detected"], colors=[CLEAR_COLOR, DETECTOR_COLORS[det]]),
        static=True, strict=True)


def style_markers(rec: Any, entity: str, det: str) -> None:
    """The static style of a detector's markers on its statistic's plot."""
    import rerun as rr

    rec.log(entity, rr.SeriesPoints(names=[f"{det} detection"], markers=[MARKER_SHAPE[det]],
                                    colors=[DETECTOR_COLORS[det]], marker_sizes=[4.0]),
            static=True, strict=True)
