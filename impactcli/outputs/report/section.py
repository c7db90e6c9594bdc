"""One log's section: its JSON facts (:func:`log_section`) and its HTML (:func:`section_html`).

The HTML answers first and explains after:

1. the verdict line and the incident list (when, where, how hard, what kind, which
   detectors, how far above threshold); the events per detector, collapsed, below;
2. what the audit could not see (:mod:`.unseen`), then the caveats;
3. the plots around each incident;
4. detection quality against labels (when given), the whole-log plots, the false-alarm
   margin;
5. what was analysed and with what (:mod:`.analysed`).
"""

from __future__ import annotations

from typing import Any

from ...config import settings_changed
from ...detect.floor import floor_words
from ...detect.incidents import baseline_alone, baseline_alone_text
from ...detect.tail import calibration_text
from ...detect.warmup import least_s
from ...logs.paths import log_stem
from ...types import DETECTORS, DetectionResult, Labels
from ..timeline import timeline_dict
from .analysed import analysed_html, with_what_html
from .caveats import caveats
from .common import (
    DETECTOR_TITLE,
    MAX_EVENT_FIGURES,
    Ids,
    LogSection,
    clean,
    e,
    event_duration_s,
    incident_score,
    incident_score_text,
    ratio_cell,
)
from .margins import false_alarm_margins
from .plots import alarm_figures, incident_figures, whole_log_figures
from .quality import evaluate, quality_html
from .samples import Samples
from .summary import (
    counts_as_contact,
    incident_rows,
    incident_table_html,
    incidents_known,
    lasting_table_html,
    payload_table_html,
    truncated_text,
    uncalibrated_none,
    verdict_text,
)
from .unseen import chain_of, could_not_see, could_not_see_html


def log_section(result: DetectionResult, labels: Labels | None,
                origin: dict[str, Any] | None, samples: Samples) -> LogSection:
    """The JSON facts of one log: the timeline's fields, plus the verdict, the incidents
    (with their peak ratio), what could not be seen, margins, caveats and evaluation.

    ``origin``: where the result came from when it is not the log itself (a re-run
    timeline: ``{"timeline", "timeline_schema_version", "recorded_by"}``); ``samples``:
    where the per-sample facts are read (:mod:`.samples`).
    """
    tl = timeline_dict(result)
    period = result.log.sample_period_s
    events = [{**d, "duration_s": event_duration_s(ev, period)}
              for ev, d in zip(result.events, tl["events"], strict=True)]
    known = incidents_known(len(result.incidents), events)
    incidents = incident_rows(tl, period)
    counted_alarms = sum(1 for ev in events if ev["detector"] in ("adaptive", "static_loading")
                         and not ev["in_warmup"])
    verdict = verdict_text(incidents, known=known, alarms_counted=counted_alarms,
                           lasting_loads=tl["lasting_loads"],
                           analysed_s=max(result.log.duration_s + period
                                          - result.warmup_end_s, 0.0),
                           floor=floor_words(result.detection_floor),
                           unchecked=[x for x in tl["input"]["joints_left_out"]
                                      if "travel_rad" in x],
                           payload_changes=tl.get("payload_changes") or (),
                           start_load=tl["input"].get("payload"))
    if alone := baseline_alone_text(baseline_alone(events, tl["incidents"],
                                                   tl["lasting_loads"])):
        verdict += f" {alone[0].upper()}{alone[1:]}."
    if result.log.source.truncated:
        verdict += " " + truncated_text(result.log.duration_s)
    if not result.calibrated and not any(counts_as_contact(i) for i in incidents):
        verdict += " " + uncalibrated_none(result)
    sec: LogSection = {
        "input": tl["input"], "config": tl["config"], "calibrated": tl["calibrated"],
        "model": tl["model"], "replay": tl["replay"], "warmup_end_s": tl["warmup_end_s"],
        "warmup_per_joint_s": tl["warmup_per_joint_s"], "thresholds": tl["thresholds"],
        "filter_gain": tl["filter_gain"], "events": events, "incidents": incidents,
        "lasting_loads": tl["lasting_loads"], "counts": tl["counts"],
        "summary": tl["summary"], "warnings": tl["warnings"],
        "stem": log_stem(result.log.source.path),
        "timeline_schema_version": tl["schema_version"],
        "origin": dict(origin) if origin else None,
        "incidents_known": known, "verdict": verdict,
        "could_not_see": could_not_see(result, incidents, known=known, origin=origin,
                                       samples=samples),
        "false_alarm_margin": false_alarm_margins(result, labels, samples=samples),
        "caveats": caveats(result, tl),
        "labels": (None if labels is None
                   else {"path": labels.path, "n_events": len(labels.events)}),
        "quality": None if labels is None else evaluate(result, labels, samples),
    }
    if "motion_envelope" in tl:
        sec["motion_envelope"] = tl["motion_envelope"]
    if "detection_floor" in tl:
        sec["detection_floor"] = tl["detection_floor"]
    if "data_defects" in tl:
        sec["data_defects"] = tl["data_defects"]
    if "payload_changes" in tl:
        sec["payload_changes"] = tl["payload_changes"]
    return clean(sec)  # type: ignore[no-any-return]


def _meta(sec: LogSection, anchor: str) -> str:
    inp = sec["input"]
    model = (sec.get("model") or {}).get("model") or {}
    calib = (sec.get("config") or {}).get("calibration") or {}
    rule = calibration_text(calib, settings_changed(sec.get("config") or {}))
    cal = (f'calibrated ({e(rule)})' if sec["calibrated"]
           else '<span class="bad">UNCALIBRATED</span>')
    ev = ((sec.get("quality") or {}).get("evaluation") or {})
    prod = (ev.get("detectors") or {}).get("product")
    labels = (f' · <a href="#{anchor}-quality">vs labels</a> (product): {prod["detected"]}/'
              f'{prod["n_contacts"]} hit, {prod["false_alarms"]} false-alarm events (alarm '
              "events matching no contact; the incidents below group them)"
              + e(incident_score_text(incident_score(ev), prod["n_contacts"]))
              if prod else "")
    return (f'<p class="meta"><code>{e(inp["path"])}</code> · {inp["duration_s"]:.1f} s at '
            f'{inp["sample_rate_hz"]:.0f} Hz · {len(inp["joints"])} joints · {cal} · model '
            f'{e(model.get("kind", "none"))}{labels} · <a href="#{anchor}-analysed">what was '
            "analysed</a></p>")


def _caveats_html(sec: LogSection) -> str:
    """The caveats (the warm-up one is under "could not see") and the run's warnings."""
    items = [c for c in sec["caveats"] if c["code"] != "warmup"]
    warnings = sec.get("warnings") or []
    if not items and not warnings:
        return ""
    p = ['<div class="caveats"><h3>Caveats — read before the numbers</h3><ul>']
    p.extend(f"<li>{e(c['text'])}</li>" for c in items)
    p.append("</ul>")
    if warnings:
        prefix = f"{sec['input']['path']}: "
        p.append('<h4>Warnings raised during the run (verbatim)</h4><ul class="small">')
        p.extend(f"<li>{e(w[len(prefix):] if w.startswith(prefix) else w)}</li>"
                 for w in warnings)
        p.append("</ul>")
    p.append("</div>")
    return "".join(p)


def _events_html(sec: LogSection, anchor: str, open_: bool) -> str:
    """Events per detector: counts and the full table, in a ``<details>``."""
    summ = sec["summary"]
    events = sec["events"]
    counts = ", ".join(f"{summ[d]['events']} {d}" for d in DETECTORS if d in summ)
    head = (f"<summary>Events per detector: {len(events)} in all ({counts} after warm-up)"
            "</summary>")
    table = ('<table><tr><th>detector</th><th class="num">events (after warm-up)</th>'
             '<th class="num">in warm-up (not counted)</th></tr>'
             + "".join(f'<tr><th>{e(DETECTOR_TITLE.get(d, d))}</th><td class="num">'
                       f'{summ[d]["events"]}</td><td class="num">{summ[d]["in_warmup"]}</td></tr>'
                       for d in DETECTORS if d in summ) + "</table>")
    rows = []
    for n, ev in enumerate(events, 1):
        peaks = ", ".join(f"{e(j)}: {v:.3g}" for j, v in ev["peak_residual"].items())
        cls = ' class="warmup"' if ev["in_warmup"] else ""
        rows.append(
            f'<tr{cls} id="{anchor}-ev{n}"><td class="num">{n}</td>'
            f'<td class="num">{ev["t_start"]:.3f}</td><td class="num">{ev["t_end"]:.3f}</td>'
            f'<td class="num">{1000 * ev["duration_s"]:.0f}</td><td>{e(ev["detector"])}</td>'
            f"<td>{e(', '.join(ev['joints']))}</td>"
            f'<td class="num">{ev["peak_ratio"]:.2f}</td><td class="num">{peaks}</td>'
            f"<td>{'yes' if ev['in_warmup'] else ''}</td></tr>")
    body = ("<p><b>No event</b> from any detector.</p>" if not rows else
            '<div class="wide"><table><thead><tr><th class="num">#</th>'
            '<th class="num">start [s]</th><th class="num">end [s]</th>'
            '<th class="num">duration [ms]</th><th>detector</th>'
            '<th>joints (first to fire first)</th><th class="num">peak ratio</th>'
            '<th class="num">peak residual [N·m]</th><th>in warm-up</th></tr></thead>'
            + "".join(rows) + "</table></div>")
    return (f'<details class="events" id="{anchor}-events"{" open" if open_ else ""}>{head}'
            f"{table}{body}</details>")


def _margins_html(sec: LogSection) -> str:
    fam = sec["false_alarm_margin"]
    rule = fam["rule"]
    dets = [d for d in DETECTORS if d in fam["per_detector"]]
    head = "".join(f'<th class="num">{e(d)}</th>' for d in dets)
    rows = []
    for j in sec["input"]["joints"]:
        cells = "".join(ratio_cell((fam["per_detector"][d].get(j) or {}).get("max_ratio"))
                        for d in dets)
        times = "; ".join(f"{d}: {fam['per_detector'][d][j]['t_s']:.2f}" for d in dets
                          if (fam["per_detector"][d].get(j) or {}).get("t_s") is not None)
        rows.append(f'<tr><th>{e(j)}</th>{cells}<td class="small">{e(times)}</td></tr>')
    return (
        "<h3>False-alarm margin on collision-free stretches</h3>"
        "<p>Largest statistic / threshold ratio after warm-up "
        f"({rule['after_warmup_s']:.3f} s), excluding {e(rule['excludes'])}: "
        f"{rule['considered_s']:.1f} s considered ({100 * rule['considered_fraction']:.0f} % of "
        "the time after warm-up). Below 1 the detector stayed silent there; 1 / ratio is the "
        "factor by which its threshold could shrink before the first false alarm. "
        '<span class="good">&lt; 0.8</span> · <span class="warn">0.8–1</span> · '
        '<span class="bad">≥ 1</span>.</p>'
        f"<table><tr><th>joint</th>{head}<th>at time [s]</th></tr>{''.join(rows)}</table>")


def section_html(num: str, result: DetectionResult, sec: LogSection,
                 labels: Labels | None, ids: Ids, samples: Samples) -> str:
    """One log's section; ``num`` is its number in the report (or ``NUM_TOKEN``);
    ``samples`` as in :func:`log_section`."""
    anchor = f"log{num}"
    known = sec["incidents_known"]
    incidents = sec["incidents"]
    chain, _ = chain_of(result)
    p = [f'<section class="log" id="{anchor}">', f"<h2>{num}. {e(sec['stem'])}</h2>",
         _meta(sec, anchor),
         f'<p class="verdict" id="{anchor}-verdict">{e(sec["verdict"])}</p>']
    if not sec["calibrated"]:
        p.append('<p class="bad small">Thresholds UNCALIBRATED (set from this log itself): '
                 "see the caveats below before relying on this answer.</p>")
    if incidents:
        p.append(incident_table_html(incidents, anchor, MAX_EVENT_FIGURES,
                                     least_s(result.config),
                                     sec.get("payload_changes") or []))
    p.append(payload_table_html(sec.get("payload_changes") or [], anchor))
    p.append(lasting_table_html(sec.get("lasting_loads") or [], anchor))
    p.append(_events_html(sec, anchor, open_=not known))
    p.append(could_not_see_html(sec["could_not_see"], anchor))
    p.append(_caveats_html(sec))
    if known:
        p.append(incident_figures(result, incidents, labels, ids, anchor, chain, samples))
    else:
        gap = float(((sec.get("config") or {}).get("events") or {}).get("merge_gap_s") or 0.0)
        p.append(alarm_figures(result, gap, labels, ids, samples))
    if (quality := sec["quality"]) is not None:
        p.append(f'<div id="{anchor}-quality">{quality_html(quality)}</div>')
    p.append(whole_log_figures(result, labels, ids, samples))
    p.append(_margins_html(sec))
    p.append(f'<div id="{anchor}-analysed">{analysed_html(sec)}</div>')
    p.append(with_what_html(sec))
    p.append("</section>")
    return "".join(p)
