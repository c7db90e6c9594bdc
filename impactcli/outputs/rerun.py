"""The Rerun recording of a detection run (formats.md, "Detection timeline": ``--rerun``).

Formatting only: every value comes from a :class:`~impactcli.result.DetectionResult`.
``rerun`` (rerun-sdk 0.41) is imported inside the functions, never at module import.

What the ``.rrd`` holds (entity paths; ``<j>`` is a joint name, escaped for Rerun):

========================================  ===============================================
``/joints/<j>/rms``                       filtered residual RMS r̃_rms (eq. 41) and its
                                          threshold v_stat + v_rms (eq. 42) [N·m]
``/joints/<j>/rms/adaptive``              markers where the adaptive detector fires
``/joints/<j>/loading``                   static-loading statistic and its threshold vL
``/joints/<j>/loading/static_loading``    markers where the static-loading detector fires
``/joints/<j>/residual``                  raw residual r = tau_hat - tau (eq. 7) and the
                                          filtered residual r̃ [N·m]
``/joints/<j>/residual/static_baseline``  markers where the static-baseline detector fires
``/joints/<j>/position``                  measured and reference position [rad]
``/detections/<j>/<lane>``                state lanes: ``warmup`` (warm-up / running) and
                                          one per detector (clear / detected), full rate
``/events``                               one text-log row per event (WARN; INFO when
                                          the event starts in warm-up)
``/incidents``                            the incident track: one row per incident at its
                                          start, a text-log line (link, force, contact
                                          type, detectors, joints; WARN, INFO in warm-up)
                                          and the same as fields ``index`` (1-based),
                                          ``link``, ``force_n``, ``contact``, ``t_end_s``,
                                          ``detectors``, ``joints``, ``in_warmup``
``/incidents/contact``                    a state lane: each incident a span from its start
                                          to its end labelled ``#k link L · F N · type``,
                                          coloured by contact type
``/incidents/force``                      a marker per incident with a force estimate, at
                                          its start, valued at ``force_n`` [N]
``/run/log``                              warm-up end per joint (INFO)
``/run/info``                             a markdown summary of the run (static)
========================================  ===============================================

Two timelines: ``message_log_time`` (a timestamp on the log's own clock, named like the
one Rerun's own MCAP import creates, so both recordings overlay) and
``time_since_start`` (a duration: seconds since the log's first sample, the base of
every time in the timeline JSON). The file ships its default blueprint: on top the
incident lane and the incident forces; one column (or tab, beyond four joints) per joint
with its four plots and its state lanes; below, the event log (every event and incident:
the text-log view lists all rows whatever the time cursor) beside the run summary. Every
plot and lane opens on the whole log — its x axis and its visible time range are
``[0, duration]`` on ``time_since_start`` — not on a window around the time cursor.

Colours: within a plot the statistic, its threshold and its detector's markers differ,
and each detector has one colour everywhere (its markers and its "detected" state):
thresholds are gold, ``adaptive`` red, ``static_loading`` pink, ``static_baseline``
orange; the filtered residual is cyan (not the baseline detector's orange).

Long logs are decimated for display with the documented min/max envelope of
:mod:`impactcli.outputs.decimate` (above 200 000 samples per series), keeping every
event ± 2 s at full rate. The timeline JSON and signals Parquet stay full rate.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .._fs import _umask
from ..result import DetectionResult
from ..types import DETECTORS
from .decimate import DEFAULT_EVENT_WINDOW_S, DEFAULT_MAX_POINTS, select_samples, window_mask

#: Timeline on the log's own clock (a timestamp), as Rerun's MCAP import names it.
LOG_TIMELINE = "message_log_time"
#: Timeline in seconds since the log's first sample (a duration).
ELAPSED_TIMELINE = "time_since_start"
APPLICATION_ID = "impactcli"

#: detector → (plot it is marked on, signal whose value the marker takes)
_MARKED_ON: dict[str, tuple[str, str]] = {
    "adaptive": ("rms", "residual_rms"),
    "static_loading": ("loading", "loading_statistic"),
    "static_baseline": ("residual", "residual"),
}
#: Plot titles, with the colour of each series: the plots carry no legend box (it would
#: cover the end of the log, where a contact may be), the series are named in the title.
_PLOT_TITLES: dict[str, str] = {
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
_MARKER_SHAPE: dict[str, Any] = {  # rr MarkerShape name
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
_CLEAR: RGB = (189, 189, 189)
_NO_CONTACT = "no contact"


def _esc(name: str) -> str:
    import rerun as rr

    return str(rr.escape_entity_path_part(name))


def joint_entity(joint: str) -> str:
    """Root entity path of a joint's plots."""
    return f"/joints/{_esc(joint)}"


def _plots(result: DetectionResult, j: int) -> dict[str, list[tuple[str, np.ndarray]]]:
    """Per plot of joint index ``j``: (series name, (N,) values), in plotting order."""
    sig, log = result.signals, result.log
    name = log.joint_names[j]
    n = log.n_samples

    def col(key: str) -> np.ndarray | None:
        a = sig.get(key)
        if a is None:
            return None
        if np.shape(a)[0] != n:  # a bug upstream, not bad input
            raise ValueError(f"signal {key!r} has {np.shape(a)[0]} samples, the log has {n}")
        return np.asarray(a, dtype=np.float64)[:, j]

    plots: dict[str, list[tuple[str, np.ndarray]]] = {}
    wanted: dict[str, list[tuple[str, np.ndarray | None]]] = {
        "rms": [("residual RMS", col("residual_rms")),
                ("threshold v_stat+v_rms", col("threshold"))],
        "loading": [("loading statistic", col("loading_statistic"))],
        "residual": [("residual r", col("residual")),
                     ("filtered residual", col("filtered_residual"))],
        "position": [("measured", np.asarray(log.position[:, j]))],
    }
    v_l = result.thresholds.get(name, {}).get("vL")
    if v_l is not None:
        wanted["loading"].append(("vL", np.full(n, float(v_l))))
    if log.position_ref is not None:
        # reference first, so the measured line is drawn over it
        wanted["position"].insert(0, ("reference", np.asarray(log.position_ref[:, j])))
    for plot, series in wanted.items():
        kept = [(s, v) for s, v in series if v is not None]
        if kept:
            plots[plot] = kept
    return plots


def _markdown_summary(result: DetectionResult) -> str:
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
    lines += ["", f"{len(result.counted_incidents())} incident(s) after warm-up"
              + (f", {len(incs) - len(result.counted_incidents())} in warm-up" if
                 len(incs) > len(result.counted_incidents()) else "")]
    if incs:
        lines += ["", "| # | start [s] | end [s] | link | force [N] | contact | detectors |",
                  "|---|---|---|---|---|---|---|"]
        for k, inc in enumerate(incs, 1):
            force = f"{inc.force_n:.3g}" if inc.force_n is not None else "–"
            link = str(inc.link) if inc.link is not None else "–"
            lines.append(f"| {k}{' (warm-up)' if inc.in_warmup else ''} | {inc.t_start:.3f} | "
                         f"{inc.t_end:.3f} | {link} | {force} | {inc.contact} | "
                         f"{', '.join(inc.detectors)} |")
    lines += ["", "| joint | v_stat | v0 | vL |", "|---|---|---|---|"]
    for joint in log.joint_names:
        th = result.thresholds.get(joint, {})
        cells = " | ".join(f"{th[k]:.4g}" if k in th else "–" for k in ("v_stat", "v0", "vL"))
        lines.append(f"| {joint} | {cells} |")
    return "\n".join(lines) + "\n"


def _event_text(e: Any) -> str:
    res = ", ".join(f"{j} {r:+.3g} N·m" for j, r in e.peak_residual.items())
    text = (f"{e.detector} on {', '.join(e.joints)}: peak ratio {e.peak_ratio:.2f}"
            f" ({e.t_start:.3f}–{e.t_end:.3f} s); peak residual {res}")
    return text + (" [in warm-up]" if e.in_warmup else "")


def incident_label(k: int, inc: Any) -> str:
    """The span label of incident number ``k`` (1-based, its place in the timeline's
    ``incidents``): ``#k link L · F N · type``."""
    link = f"link {inc.link}" if inc.link is not None else "link ?"
    force = f"{inc.force_n:.3g} N" if inc.force_n is not None else "force ?"
    return f"#{k} {link} · {force} · {inc.contact}" + (" (warm-up)" if inc.in_warmup else "")


def _incident_text(k: int, inc: Any) -> str:
    link = f"link {inc.link}" if inc.link is not None else "link unknown"
    force = (f"~{inc.force_n:.3g} N ({inc.force_method})" if inc.force_n is not None
             else "force unknown (no kinematics)")
    text = (f"incident #{k}: {link}, {force}, {inc.contact} contact; "
            f"{', '.join(inc.detectors)} on {', '.join(inc.joints)} "
            f"({inc.t_start:.3f}–{inc.t_end:.3f} s)")
    return text + (" [in warm-up]" if inc.in_warmup else "")


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
        titles = dict(_PLOT_TITLES)
        if not has_reference:
            titles["position"] = "position: measured (blue; no reference logged)"
        views: list[Any] = [
            rrb.TimeSeriesView(origin=f"{root}/{plot}", name=f"{joint}: {title}",
                               plot_legend=legend, **ranged)
            for plot, title in titles.items()
        ]
        views.append(rrb.StateTimelineView(origin=f"/detections/{_esc(joint)}",
                                           name=f"{joint}: detections", **lane_ranged))
        columns.append(rrb.Vertical(*views, row_shares=[3, 3, 3, 3, 5], name=joint))
    joints_box = rrb.Horizontal(*columns) if len(columns) <= 4 else rrb.Tabs(*columns)
    bottom = rrb.Tabs(
        rrb.TextLogView(
            origin="/", contents=["/incidents", "/events/**", "/run/log/**"],
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


def write_rrd(result: DetectionResult, path: str | os.PathLike[str], *,
              max_points: int = DEFAULT_MAX_POINTS,
              event_window_s: float = DEFAULT_EVENT_WINDOW_S,
              recording_id: str | None = None) -> None:
    """Write ``result`` as a Rerun recording with its default blueprint.

    Bulk-logged with ``send_columns`` (one call per entity), strict (a chunk Rerun would
    drop raises). Written to a temporary sibling and moved into place, so ``path`` is
    never seen half-written.

    Args:
        result: the detection run.
        path: the ``.rrd`` to write (parent folders are created).
        max_points: per-series size above which series are decimated (min/max envelope,
            :func:`impactcli.outputs.decimate.select_samples`).
        event_window_s: full-rate window kept on each side of every event [s].
        recording_id: Rerun recording id (default: a fresh one). Pass the id of another
            recording of the same log to merge both when opened together.
    """
    import rerun as rr

    log = result.log
    t_ns = np.asarray(log.t_ns, dtype=np.int64)
    n = t_ns.shape[0]
    keep = window_mask(t_ns, [(t_ns[e.i_start], t_ns[min(e.i_end, n - 1)]) for e in result.events],
                       round(event_window_s * 1e9))

    def indexes(sel: Any) -> list[Any]:
        ts = t_ns[sel]
        return [
            rr.TimeColumn(LOG_TIMELINE, timestamp=ts.view("datetime64[ns]")),
            rr.TimeColumn(ELAPSED_TIMELINE, duration=(ts - t_ns[0]).view("timedelta64[ns]")),
        ]

    with open_recording(path, result, log.has_reference, recording_id) as rec:
        for j, joint in enumerate(log.joint_names):
            _write_joint(rec, result, j, joint, keep, max_points, indexes)
        _write_events(rec, result, indexes)
        _write_incidents(rec, result, indexes)


@contextlib.contextmanager
def open_recording(path: str | os.PathLike[str], result: DetectionResult, has_reference: bool,
                   recording_id: str | None = None) -> Iterator[Any]:
    """A Rerun recording of ``result`` written to a temporary sibling of ``path`` (with its
    default blueprint, name and run summary) and moved into place when the block succeeds;
    on any error the temporary file is removed and ``path`` is untouched."""
    import rerun as rr

    log = result.log
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    os.close(fd)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    try:
        rec.save(tmp, default_blueprint=default_blueprint(
            log.joint_names, has_reference, duration_s=log.duration_s))
        rec.send_recording_name(Path(log.source.path).name or "impactcli run")
        rec.log("/run/info", rr.TextDocument(_markdown_summary(result), media_type="text/markdown"),
                static=True, strict=True)
        yield rec
        rec.disconnect()
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs are ordinary files
        os.replace(tmp, target)
    except BaseException:
        rec.disconnect()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def lanes_entity(joint: str) -> str:
    """Root entity path of a joint's detection lanes."""
    return f"/detections/{_esc(joint)}"


def style_series(rec: Any, entity: str, names: Sequence[str]) -> None:
    """The static style of a plot's series (names and colours)."""
    import rerun as rr

    rec.log(entity, rr.SeriesLines(names=list(names), colors=[SERIES_COLORS[s] for s in names],
                                   widths=[1.5] * len(names)), static=True, strict=True)


def style_lane(rec: Any, joint: str, det: str) -> None:
    """The static states of a detector's lane (clear / detected in its colour)."""
    import rerun as rr

    rec.log(f"{lanes_entity(joint)}/{det}", rr.StateConfiguration(
        values=["clear", "detected"], colors=[_CLEAR, DETECTOR_COLORS[det]]),
        static=True, strict=True)


def style_markers(rec: Any, entity: str, det: str) -> None:
    """The static style of a detector's markers on its statistic's plot."""
    import rerun as rr

    rec.log(entity, rr.SeriesPoints(names=[f"{det} detection"], markers=[_MARKER_SHAPE[det]],
                                    colors=[DETECTOR_COLORS[det]], marker_sizes=[4.0]),
            static=True, strict=True)


def write_warmup_lane(rec: Any, joint: str, i_w: int, n: int, indexes: Any) -> None:
    """A joint's warm-up lane: "warm-up" from the first sample, "running" from sample
    ``i_w`` (its first after the warm-up; ``n``: none)."""
    import rerun as rr

    lane = f"{lanes_entity(joint)}/warmup"
    rec.log(lane, rr.StateConfiguration(
        values=["warm-up", "running"], colors=[(255, 193, 7), (76, 175, 80)]),
        static=True, strict=True)
    w_idx = np.array([0] if i_w <= 0 else ([0, i_w] if i_w < n else [0]))
    w_states = ["running"] if i_w <= 0 else ["warm-up", "running"][: len(w_idx)]
    rec.send_columns(lane, indexes=indexes(w_idx),
                     columns=rr.StateChange.columns(state=w_states), strict=True)


def _write_joint(rec: Any, result: DetectionResult, j: int, joint: str,
                 keep: np.ndarray, max_points: int, indexes: Any) -> None:
    import rerun as rr

    root = joint_entity(joint)
    log = result.log
    plots = _plots(result, j)
    for plot, series in plots.items():
        entity = f"{root}/{plot}"
        style_series(rec, entity, [s for s, _ in series])
        sel = select_samples([v for _, v in series], keep, max_points)
        matrix = np.column_stack([v[sel] for _, v in series])
        rec.send_columns(entity, indexes=indexes(sel),
                         columns=rr.Scalars.columns(scalars=matrix), strict=True)

    lanes = lanes_entity(joint)
    w_end = result.warmup_per_joint_s.get(joint, result.warmup_end_s)
    write_warmup_lane(rec, joint, int(np.searchsorted(log.time_s, w_end, side="left")),
                      log.n_samples, indexes)

    for det in DETECTORS:
        dec = result.decisions.get(det)
        if dec is None:
            continue
        d = np.asarray(dec, dtype=bool)[:, j]
        # state lane: every transition, full rate
        change = np.concatenate([[0], np.flatnonzero(np.diff(d.astype(np.int8))) + 1])
        style_lane(rec, joint, det)
        rec.send_columns(f"{lanes}/{det}", indexes=indexes(change),
                         columns=rr.StateChange.columns(
                             state=np.where(d[change], "detected", "clear").tolist()), strict=True)
        # markers on the plot of the detector's statistic
        plot, sig_name = _MARKED_ON[det]
        values = result.signals.get(sig_name)
        fired = np.flatnonzero(d)
        if values is None or plot not in plots or fired.size == 0:
            continue
        v = np.asarray(values, dtype=np.float64)[fired, j]
        fired = fired[select_samples(v, keep[fired], max_points)]
        entity = f"{root}/{plot}/{det}"
        style_markers(rec, entity, det)
        rec.send_columns(entity, indexes=indexes(fired),
                         columns=rr.Scalars.columns(
                             scalars=np.asarray(values, dtype=np.float64)[fired, j]), strict=True)


def _write_events(rec: Any, result: DetectionResult, indexes: Any) -> None:
    t = result.log.time_s
    warm = {j: int(np.searchsorted(t, result.warmup_per_joint_s.get(j, result.warmup_end_s),
                                   side="left")) for j in result.log.joint_names}
    _write_events_rows(rec, result, indexes, warm)


def _write_events_rows(rec: Any, result: DetectionResult, indexes: Any,
                       warm_index: dict[str, int]) -> None:
    """The events' text rows and each joint's warm-up end (``warm_index``: joint → its
    first sample after the warm-up, n if none)."""
    import rerun as rr

    log = result.log
    n = log.n_samples
    events = result.events
    if events:
        at = np.array([min(max(e.i_start, 0), n - 1) for e in events], dtype=np.int64)
        levels = [rr.TextLogLevel.INFO if e.in_warmup else rr.TextLogLevel.WARN for e in events]
        rec.send_columns("/events", indexes=indexes(at), columns=rr.TextLog.columns(
            text=[_event_text(e) for e in events], level=levels), strict=True)
    at_w, texts = [], []
    for joint in log.joint_names:
        w_end = result.warmup_per_joint_s.get(joint, result.warmup_end_s)
        i_w = warm_index[joint]
        if i_w < n:
            at_w.append(i_w)
            texts.append(f"warm-up ends for {joint} at {w_end:.3f} s: "
                         "events starting before are not counted")
    if at_w:
        rec.send_columns("/run/log", indexes=indexes(np.array(at_w, dtype=np.int64)),
                         columns=rr.TextLog.columns(text=texts,
                                                    level=[rr.TextLogLevel.INFO] * len(texts)),
                         strict=True)


def _write_incidents(rec: Any, result: DetectionResult, indexes: Any) -> None:
    """The incident track (module docstring): text rows with fields, spans, force markers."""
    import pyarrow as pa
    import rerun as rr

    n = result.log.n_samples
    incs = list(result.incidents)
    labels = [incident_label(k, inc) for k, inc in enumerate(incs, 1)]
    rec.log("/incidents/contact", rr.StateConfiguration(
        values=[_NO_CONTACT, *labels], labels=["", *labels],
        colors=[_CLEAR] + [CONTACT_COLORS.get(i.contact, CONTACT_COLORS["unknown"])
                           for i in incs],
        visible=[False] + [True] * len(incs)), static=True, strict=True)
    rec.log("/incidents/force", rr.SeriesPoints(
        names=["incident force [N]"], markers=["Circle"], colors=[INCIDENT_FORCE_COLOR],
        marker_sizes=[6.0]), static=True, strict=True)
    if not incs:
        rec.send_columns("/incidents/contact", indexes=indexes(np.array([0], dtype=np.int64)),
                         columns=rr.StateChange.columns(state=[_NO_CONTACT]), strict=True)
        return
    at = np.array([min(max(i.i_start, 0), n - 1) for i in incs], dtype=np.int64)
    # one row per incident: its text-log line and its fields, in one chunk
    text = rr.TextLog.columns(
        text=[_incident_text(k, i) for k, i in enumerate(incs, 1)],
        level=[rr.TextLogLevel.INFO if i.in_warmup else rr.TextLogLevel.WARN for i in incs])
    fields = rr.AnyValues.columns(
        index=pa.array(range(1, len(incs) + 1), pa.int64()),
        link=pa.array([i.link for i in incs], pa.int64()),
        force_n=pa.array([i.force_n for i in incs], pa.float64()),
        contact=pa.array([i.contact for i in incs], pa.string()),
        t_end_s=pa.array([float(i.t_end) for i in incs], pa.float64()),
        detectors=pa.array([", ".join(i.detectors) for i in incs], pa.string()),
        joints=pa.array([", ".join(i.joints) for i in incs], pa.string()),
        in_warmup=pa.array([bool(i.in_warmup) for i in incs], pa.bool_()),
    )
    rec.send_columns("/incidents", indexes=indexes(at), columns=[*text, *fields], strict=True)
    # spans: the incident's label from its first sample, "no contact" after its last
    idx: list[int] = [0] if at[0] > 0 else []
    states: list[str] = [_NO_CONTACT] if at[0] > 0 else []
    for k, (inc, lab) in enumerate(zip(incs, labels, strict=True)):
        idx.append(int(at[k]))
        states.append(lab)
        after = min(max(inc.i_end, inc.i_start), n - 1) + 1
        nxt = int(at[k + 1]) if k + 1 < len(incs) else n
        if after < nxt:
            idx.append(after)
            states.append(_NO_CONTACT)
    rec.send_columns("/incidents/contact", indexes=indexes(np.array(idx, dtype=np.int64)),
                     columns=rr.StateChange.columns(state=states), strict=True)
    forced = [k for k, i in enumerate(incs) if i.force_n is not None]
    if forced:
        rec.send_columns("/incidents/force", indexes=indexes(at[forced]),
                         columns=rr.Scalars.columns(scalars=np.array(
                             [incs[k].force_n for k in forced], dtype=np.float64)),
                         strict=True)
