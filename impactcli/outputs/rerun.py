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
``/run/log``                              warm-up end per joint (INFO)
``/run/info``                             a markdown summary of the run (static)
========================================  ===============================================

Two timelines: ``message_log_time`` (a timestamp on the log's own clock, named like the
one Rerun's own MCAP import creates, so both recordings overlay) and
``time_since_start`` (a duration: seconds since the log's first sample, the base of
every time in the timeline JSON). The file ships its default blueprint: one column (or
tab, beyond four joints) per joint with its four plots and its state lanes; the event log.

Long logs are decimated for display with the documented min/max envelope of
:mod:`impactcli.outputs.decimate` (above 200 000 samples per series), keeping every
event ± 2 s at full rate. The timeline JSON and signals Parquet stay full rate.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Sequence
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
_PLOT_TITLES: dict[str, str] = {
    "rms": "RMS vs threshold",
    "loading": "loading vs vL",
    "residual": "residual",
    "position": "position",
}
_RED = (214, 39, 40)
_SERIES_COLORS: dict[str, tuple[int, int, int]] = {
    "residual RMS": (31, 119, 180),
    "threshold v_stat+v_rms": _RED,
    "loading statistic": (148, 103, 189),
    "vL": _RED,
    "residual r": (127, 127, 127),
    "filtered residual": (255, 127, 14),
    "reference": (44, 160, 44),
    "measured": (31, 119, 180),
}
_MARKER_STYLE: dict[str, tuple[Any, tuple[int, int, int]]] = {  # (rr MarkerShape name, RGB)
    "adaptive": ("Cross", _RED),
    "static_loading": ("Diamond", (227, 119, 194)),
    "static_baseline": ("Up", (255, 127, 14)),
}


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


def default_blueprint(joint_names: Sequence[str], has_reference: bool = True) -> Any:
    """The layout shipped in the file (a ``rerun.blueprint.Blueprint``).

    One column per joint (tabs beyond four joints) stacking its RMS-vs-threshold,
    loading-vs-vL, residual and position plots over its detection state lanes (warm-up and
    one lane per detector); below, the event log beside the run summary. Time panel on
    ``time_since_start``.
    """
    import rerun.blueprint as rrb

    legend = rrb.PlotLegend(corner="RightTop")
    columns = []
    for joint in joint_names:
        root = joint_entity(joint)
        titles = dict(_PLOT_TITLES)
        if not has_reference:
            titles["position"] = "position (measured; no reference logged)"
        views: list[Any] = [
            rrb.TimeSeriesView(origin=f"{root}/{plot}", name=f"{joint}: {title}",
                               plot_legend=legend)
            for plot, title in titles.items()
        ]
        views.append(rrb.StateTimelineView(origin=f"/detections/{_esc(joint)}",
                                           name=f"{joint}: detections"))
        columns.append(rrb.Vertical(*views, row_shares=[3, 3, 3, 3, 5], name=joint))
    joints_box = rrb.Horizontal(*columns) if len(columns) <= 4 else rrb.Tabs(*columns)
    bottom = rrb.Tabs(
        rrb.TextLogView(
            origin="/", contents=["/events/**", "/run/log/**"], name="events",
            columns=rrb.TextLogColumns(timeline_columns=[ELAPSED_TIMELINE],
                                       text_log_columns=["loglevel", "body"]),
            rows=rrb.TextLogRows(filter_by_log_level=["DEBUG", "INFO", "WARN", "ERROR"]),
        ),
        rrb.TextDocumentView(origin="/run/info", name="run"),
    )
    return rrb.Blueprint(
        rrb.Vertical(joints_box, bottom, row_shares=[4, 1]),
        # "following" puts the cursor at the end: every event is listed at once
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

    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    os.close(fd)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    try:
        rec.save(tmp, default_blueprint=default_blueprint(log.joint_names, log.has_reference))
        rec.send_recording_name(Path(log.source.path).name or "impactcli run")
        rec.log("/run/info", rr.TextDocument(_markdown_summary(result), media_type="text/markdown"),
                static=True, strict=True)
        for j, joint in enumerate(log.joint_names):
            _write_joint(rec, result, j, joint, keep, max_points, indexes)
        _write_events(rec, result, indexes)
        rec.disconnect()
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs are ordinary files
        os.replace(tmp, target)
    except BaseException:
        rec.disconnect()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _write_joint(rec: Any, result: DetectionResult, j: int, joint: str,
                 keep: np.ndarray, max_points: int, indexes: Any) -> None:
    import rerun as rr

    root = joint_entity(joint)
    log = result.log
    plots = _plots(result, j)
    for plot, series in plots.items():
        entity = f"{root}/{plot}"
        colors = [_SERIES_COLORS[name] for name, _ in series]
        rec.log(entity, rr.SeriesLines(names=[s for s, _ in series], colors=colors,
                                       widths=[1.5] * len(series)), static=True, strict=True)
        sel = select_samples([v for _, v in series], keep, max_points)
        matrix = np.column_stack([v[sel] for _, v in series])
        rec.send_columns(entity, indexes=indexes(sel),
                         columns=rr.Scalars.columns(scalars=matrix), strict=True)

    lanes = f"/detections/{_esc(joint)}"
    # warm-up lane: "warm-up" from the first sample, "running" from the joint's warm-up end
    w_end = result.warmup_per_joint_s.get(joint, result.warmup_end_s)
    i_w = int(np.searchsorted(log.time_s, w_end, side="left"))
    rec.log(f"{lanes}/warmup", rr.StateConfiguration(
        values=["warm-up", "running"], colors=[(255, 193, 7), (76, 175, 80)]),
        static=True, strict=True)
    w_idx = np.array([0] if i_w <= 0 else ([0, i_w] if i_w < log.n_samples else [0]))
    w_states = ["running"] if i_w <= 0 else ["warm-up", "running"][: len(w_idx)]
    rec.send_columns(f"{lanes}/warmup", indexes=indexes(w_idx),
                     columns=rr.StateChange.columns(state=w_states), strict=True)

    for det in DETECTORS:
        dec = result.decisions.get(det)
        if dec is None:
            continue
        d = np.asarray(dec, dtype=bool)[:, j]
        # state lane: every transition, full rate
        change = np.concatenate([[0], np.flatnonzero(np.diff(d.astype(np.int8))) + 1])
        rec.log(f"{lanes}/{det}", rr.StateConfiguration(
            values=["clear", "detected"], colors=[(189, 189, 189), _RED]), static=True, strict=True)
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
        marker, color = _MARKER_STYLE[det]
        entity = f"{root}/{plot}/{det}"
        rec.log(entity, rr.SeriesPoints(names=[f"{det} detection"], markers=[marker],
                                        colors=[color], marker_sizes=[4.0]),
                static=True, strict=True)
        rec.send_columns(entity, indexes=indexes(fired),
                         columns=rr.Scalars.columns(
                             scalars=np.asarray(values, dtype=np.float64)[fired, j]), strict=True)


def _write_events(rec: Any, result: DetectionResult, indexes: Any) -> None:
    import rerun as rr

    log = result.log
    n = log.n_samples
    events = result.events
    if events:
        at = np.array([min(max(e.i_start, 0), n - 1) for e in events], dtype=np.int64)
        levels = [rr.TextLogLevel.INFO if e.in_warmup else rr.TextLogLevel.WARN for e in events]
        rec.send_columns("/events", indexes=indexes(at), columns=rr.TextLog.columns(
            text=[_event_text(e) for e in events], level=levels), strict=True)
    t = log.time_s
    at_w, texts = [], []
    for joint in log.joint_names:
        w_end = result.warmup_per_joint_s.get(joint, result.warmup_end_s)
        i_w = int(np.searchsorted(t, w_end, side="left"))
        if i_w < n:
            at_w.append(i_w)
            texts.append(f"warm-up ends for {joint} at {w_end:.3f} s: "
                         "events starting before are not counted")
    if at_w:
        rec.send_columns("/run/log", indexes=indexes(np.array(at_w, dtype=np.int64)),
                         columns=rr.TextLog.columns(text=texts,
                                                    level=[rr.TextLogLevel.INFO] * len(texts)),
                         strict=True)
