"""Every plot of the report, built on :mod:`impactcli.outputs.svgplot` (inline SVG,
decimated by a min/max envelope so no peak hides): one set of panels around each incident,
the statistic against its threshold over the whole log, and the threshold sweep.

A panel draws one detector's statistic (blue) against its threshold (red, the area above
it shaded: where the detector alarms) on one joint, with the warm-up, the detector's events
on that joint and labelled contacts as bands.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ...detect.force import force_mark
from ...detect.incidents import group_events, link_words
from ...types import DETECTORS, DetectionResult, Labels
from .. import svgplot
from .common import (
    CLIP_FACTOR,
    CONTACT_TEXT,
    DETECTOR_TITLE,
    EVENT_BUCKETS,
    EVENT_WINDOW_S,
    MAX_EVENT_FIGURES,
    PRODUCT_DETECTORS,
    STAT_NAME,
    WHOLE_LOG_BUCKETS,
    Ids,
    approx,
    e,
)
from .samples import Samples, Stretch
from .summary import change_of, load_words

BAND_EVENT = "#f3b6ae"
ALARM_ZONE = "#fdf1ef"
BAND_WARMUP = "#e4e4e4"
BAND_LABEL = "#fde7cf"


def _bands(result: DetectionResult, detector: str, joint: str,
           labels: Labels | None) -> list[svgplot.Band]:
    bands = [svgplot.Band(0.0, result.warmup_end_s, BAND_WARMUP, "warm-up")]
    if labels is not None:
        bands += [svgplot.Band(c.start, c.end, BAND_LABEL, f"labelled {c.kind} {c.peak_force:g} N",
                               outline=svgplot.ORANGE) for c in labels.events]
    bands += [svgplot.Band(ev.t_start, ev.t_end, BAND_EVENT, f"{ev.detector} event")
              for ev in result.events if ev.detector == detector and joint in ev.joints]
    return bands


def panel(result: DetectionResult, detector: str, j: int, *, stat: tuple[np.ndarray, np.ndarray],
          thr: tuple[np.ndarray, np.ndarray], x_range: tuple[float, float], title: str,
          labels: Labels | None, ids: Ids, width: int, height: int) -> str:
    """One detector on one joint: its enveloped statistic ``stat`` and threshold ``thr``
    ((t, y) each) over ``x_range`` [s], as an inline SVG."""
    sname, tname = STAT_NAME[detector]
    chart = svgplot.Chart(
        title=title, x_range=x_range,
        series=(svgplot.Series(sname, stat[0], stat[1], svgplot.BLUE),
                svgplot.Series(tname, thr[0], thr[1], svgplot.RED, width=1.1,
                               fill_above=ALARM_ZONE)),
        bands=_bands(result, detector, result.log.joint_names[j], labels), y_unit="N·m",
        clip_factor=CLIP_FACTOR, clip_reference=tname)
    return svgplot.render_chart(chart, width=width, height=height, chart_id=ids())


def stretch_panel(result: DetectionResult, part: Stretch, detector: str, j: int, *,
                  buckets: int, **kw: Any) -> str:
    """:func:`panel` over the samples of ``part`` (enveloped to ``buckets``)."""
    t = part.t
    stat, thr = part.series[(detector, j)]
    return panel(result, detector, j, stat=svgplot.envelope(t, stat, buckets),
                 thr=svgplot.envelope(t, thr, buckets), x_range=(float(t[0]), float(t[-1])),
                 **kw)


def legend_html(labels: Labels | None) -> str:
    """What the colours of every panel mean."""
    lab = (f'<span class="legend-key" style="background:{BAND_LABEL};border-color:'
           f'{svgplot.ORANGE}"></span>labelled contacts' if labels is not None else "")
    return (
        '<p class="small">Blue: the detector\'s statistic; red: its threshold — the lightly '
        "shaded area above it is where the detector alarms. "
        f'<span class="legend-key" style="background:{BAND_EVENT}"></span>events of that '
        f'detector <span class="legend-key" style="background:{BAND_WARMUP}"></span>warm-up'
        f"{lab}. The y axis is capped at {CLIP_FACTOR:g}× the threshold (the true maximum is "
        "then written in red).</p>")


def _figure(result: DetectionResult, samples: Samples, joints: Sequence[str], t_a: float,
            t_b: float, labels: Labels | None, ids: Ids) -> str:
    part = samples.stretch(t_a, t_b)
    names = result.log.joint_names
    return "".join(
        stretch_panel(result, part, d, names.index(jn), buckets=EVENT_BUCKETS,
                      title=f"{jn} · {DETECTOR_TITLE[d]}", labels=labels, ids=ids, width=520,
                      height=150)
        for jn in joints for d in PRODUCT_DETECTORS)


def _plot_joints(result: DetectionResult, joints: Sequence[str], link: int | None,
                 chain: Sequence[str]) -> list[str]:
    """The joints that fired, and the joint of the isolated link, in the log's order."""
    want = set(joints)
    if link is not None and 0 < link <= len(chain):
        want.add(chain[link - 1])
    return [j for j in result.log.joint_names if j in want]


def incident_figures(result: DetectionResult, incidents: Sequence[dict[str, Any]],
                     labels: Labels | None, ids: Ids, anchor: str,
                     chain: Sequence[str], samples: Samples) -> str:
    """One figure per incident (±EVENT_WINDOW_S around it): both product detectors on each
    joint that fired and on the joint of its link."""
    if not incidents:
        return ""
    p = [f"<h3>Around each incident (±{EVENT_WINDOW_S:g} s)</h3>", legend_html(labels)]
    for inc in incidents[:MAX_EVENT_FIGURES]:
        joints = _plot_joints(result, inc.get("joints") or [], inc.get("link"), chain)
        how = (f"{force_mark(inc)}{approx(inc['force_n'])} N" if inc.get("force_n") is not None
               else "no force estimate")
        kind = CONTACT_TEXT.get(inc.get("contact") or "unknown", inc.get("contact"))
        change = change_of(inc, result.payload_changes or ())
        if change is not None:  # a load, not a contact: as the incident table says it
            how = (f"{change['mass_kg']:+.3g} kg, "
                   f"{load_words(change, since=False, why=False)}")
            kind = "no contact type"
        where = link_words(inc.get("link"), inc.get("link_candidates"))
        evs = ", ".join(f"#{k + 1}" for k in inc.get("events") or [])
        fig = _figure(result, samples, joints, inc["t_start"] - EVENT_WINDOW_S,
                      inc["t_end"] + EVENT_WINDOW_S, labels, ids)
        p.append(
            f'<figure id="{anchor}-inc{inc["label"]}"><figcaption><b>Incident '
            f'{inc["label"]}</b>: {inc["t_start"]:.3f}–{inc["t_end"]:.3f} s, {e(where)}, '
            f'{e(how)}, {e(kind)}'
            + (", in warm-up (not counted)" if inc.get("in_warmup") else
               f", the alarm of payload change P{inc['payload_change']} (not counted)"
               if inc.get("payload_change") else
               ", at a data defect (not counted)" if inc.get("data_defect") else "")
            + f"; events {e(evs)} of the event table.</figcaption>"
            f'<div class="grid2">{fig}</div></figure>')
    if len(incidents) > MAX_EVENT_FIGURES:
        p.append(f'<p class="warn">{len(incidents) - MAX_EVENT_FIGURES} further incident(s) are '
                 f"not plotted (at most {MAX_EVENT_FIGURES} figures per log); they are listed "
                 "above and in the JSON report.</p>")
    return "".join(p)


def alarm_figures(result: DetectionResult, merge_gap_s: float, labels: Labels | None,
                  ids: Ids, samples: Samples) -> str:
    """For a run without incidents: one figure per group of overlapping product alarms."""
    groups = group_events(result.events, merge_gap_s)
    if not groups:
        return ""
    p = [f"<h3>Around each group of alarms (±{EVENT_WINDOW_S:g} s)</h3>", legend_html(labels)]
    for g in groups[:MAX_EVENT_FIGURES]:
        evs = [result.events[k] for k in g]
        joints = [j for j in result.log.joint_names if any(j in ev.joints for ev in evs)]
        t_a, t_b = min(ev.t_start for ev in evs), max(ev.t_end for ev in evs)
        desc = "; ".join(f"#{k + 1} {result.events[k].detector} on "
                         f"{', '.join(result.events[k].joints)}" for k in g)
        fig = _figure(result, samples, joints, t_a - EVENT_WINDOW_S, t_b + EVENT_WINDOW_S,
                      labels, ids)
        p.append(f"<figure><figcaption>Alarms {t_a:.3f}–{t_b:.3f} s: {e(desc)}.</figcaption>"
                 f'<div class="grid2">{fig}</div></figure>')
    if len(groups) > MAX_EVENT_FIGURES:
        p.append(f'<p class="warn">{len(groups) - MAX_EVENT_FIGURES} further group(s) are not '
                 "plotted; they are in the event table.</p>")
    return "".join(p)


def whole_log_figures(result: DetectionResult, labels: Labels | None, ids: Ids,
                      samples: Samples) -> str:
    """Every detector against its threshold over the whole log, per joint."""
    p = ["<h3>Statistic against threshold over the whole log</h3>", legend_html(labels),
         f'<p class="small">Drawn as a min/max envelope of {WHOLE_LOG_BUCKETS} buckets, so no '
         "peak is hidden.</p>"]
    for j, name in enumerate(result.log.joint_names):
        panels = []
        for d in DETECTORS:
            stat, thr, x_range = samples.whole_log(d, j, WHOLE_LOG_BUCKETS)
            panels.append(panel(result, d, j, stat=stat, thr=thr, x_range=x_range,
                                title=f"{name} · {DETECTOR_TITLE[d]}", labels=labels, ids=ids,
                                width=1000, height=150))
        p.append(f"<figure>{''.join(panels)}<figcaption>Joint {e(name)}, whole log."
                 "</figcaption></figure>")
    return "".join(p)


def sweep_plot(rows: Sequence[dict[str, Any]], detectors: Sequence[str]) -> str:
    """The threshold sweep, ROC-style: contacts detected against false alarms per hour, on
    a log(1 + x) axis (no false alarm at the left edge; 1, 10, 100, … decades)."""
    groups: dict[str, tuple[list[float], list[float]]] = {}
    for d in detectors:
        pts = sorted({(float(r["false_alarms_per_hour"]), r["detected"] / r["n_contacts"])
                      for r in rows if r["detector"] == d and r["n_contacts"]
                      and r.get("false_alarms_per_hour") is not None})
        if pts:
            groups[d] = ([a for a, _ in pts], [b for _, b in pts])
    if not groups:
        return ""
    return ("<figure>" + svgplot.render_xy(
        "Threshold sweep", groups, "false alarms per hour (log scale; 0 at the left edge)",
        "fraction of contacts detected", x_scale="log1p")
        + "<figcaption>ROC-style: each point is one threshold scale; up and to the left is "
        "better.</figcaption></figure>")
