"""The page: the JSON twin (:func:`report_dict`), the HTML document (CSS, header, fleet
summary, the log sections, how to read it) and writing both.

A fleet report (several logs) opens with one row per log — its verdict, what could not be
seen — then each log's section on its own printed page. Determinism: no time of the run,
no random ids, keys sorted, fixed number formatting; the same inputs give byte-identical
JSON and HTML.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Sequence
from typing import Any

from ... import TOOL_NAME, __version__
from ...files import atomic_write_text, prepare_output
from ...types import DetectionResult, Labels
from .common import (
    CLIP_FACTOR,
    EVENT_WINDOW_S,
    GUARD_S,
    MAX_EVENT_FIGURES,
    SCHEMA_VERSION,
    WHOLE_LOG_BUCKETS,
    Ids,
    LogSection,
    clean,
    e,
    incident_score,
)
from .samples import Samples
from .section import log_section, section_html
from .summary import fleet_details_html, fleet_table_html, incident_counts

CSS = """
@page { size: A4; margin: 12mm 11mm 14mm 11mm; }
* { box-sizing: border-box; }
body { font-family: "DejaVu Sans", "Liberation Sans", Arial, Helvetica, sans-serif;
  color: #111; background: #fff; margin: 0 auto; padding: 14px 22px; max-width: 1180px;
  font-size: 13px; line-height: 1.42; }
h1 { font-size: 20px; margin: 0 0 2px 0; }
h2 { font-size: 18px; margin: 14px 0 4px 0; border-bottom: 2px solid #333; padding-bottom: 2px; }
h3 { font-size: 14.5px; margin: 16px 0 5px 0; }
h4 { font-size: 13px; margin: 10px 0 4px 0; }
p { margin: 4px 0 8px 0; }
table { border-collapse: collapse; margin: 4px 0 10px 0; font-size: 12px; }
th, td { border: 1px solid #b8b8b8; padding: 2px 6px; vertical-align: top; text-align: left; }
th { background: #ececec; font-weight: 600; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
table.kv th { width: 190px; }
code, .mono { font-family: "DejaVu Sans Mono", "Liberation Mono", Consolas, monospace;
  font-size: 11.5px; }
.hash { word-break: break-all; }
pre { white-space: pre-wrap; word-break: break-word; font-size: 10.5px; line-height: 1.3;
  border: 1px solid #ccc; background: #fafafa; padding: 6px 8px; margin: 4px 0 10px 0; }
p.meta { color: #444; font-size: 12px; margin: 0 0 6px 0; }
p.verdict { font-size: 16px; font-weight: 600; margin: 6px 0 8px 0; padding: 6px 10px;
  border-left: 5px solid #1f5fbf; background: #f2f5fb; }
td.verdict-cell { font-weight: 600; }
table.incidents { width: 100%; margin-bottom: 2px; }
table.incidents td { padding: 2px 6px; }
ul.tight { margin: 0 0 4px 0; padding-left: 1.4em; }
details { margin: 6px 0 8px 0; }
details > summary { cursor: pointer; color: #1f4f99; font-weight: 600; }
.unseen { border: 2px solid #7f8c8d; padding: 4px 12px; margin: 8px 0 10px 0; }
.unseen h3 { margin-top: 2px; color: #34495e; }
.unseen li, .caveats li { margin: 3px 0; }
.caveats { border: 2px solid #b9770e; padding: 4px 12px; margin: 8px 0 12px 0; }
.caveats h3 { margin-top: 2px; color: #7e5109; }
.bad { color: #a93226; font-weight: 600; }
.warn { color: #9a5b00; font-weight: 600; }
.good { color: #1e6b38; font-weight: 600; }
.muted { color: #555; }
.note { color: #555; font-weight: normal; font-size: 11px; }
.small { font-size: 11px; }
tr.warmup td { color: #666; font-style: italic; }
figure { margin: 6px 0 10px 0; break-inside: avoid; page-break-inside: avoid; }
figcaption { font-size: 11.5px; color: #333; margin-top: 2px; }
svg.chart { width: 100%; height: auto; display: block; }
svg.xy { max-width: 640px; }
.grid2 { display: grid; grid-template-columns: 1fr 1fr; gap: 4px 14px; }
.legend-key { display: inline-block; width: 18px; height: 10px; vertical-align: middle;
  border: 1px solid #888; margin: 0 3px 0 8px; }
table.summary { width: 100%; }
table.summary td, table.summary th { padding: 2px 4px; }
section.log { break-before: page; page-break-before: always; }
section.appendix { break-before: page; page-break-before: always; }
.wide { overflow-x: auto; }
@media print {
  body { max-width: none; padding: 0; font-size: 10.5px; }
  table { font-size: 9.5px; }
  pre { font-size: 8.5px; }
  a { color: inherit; text-decoration: none; }
  h2, h3, h4 { break-after: avoid; page-break-after: avoid; }
  tr { break-inside: avoid; page-break-inside: avoid; }
  .wide { overflow: visible; }
}
"""

#: Stands for a log's number in a section rendered before the report is assembled (a
#: worker does not know which inputs will fail); NUL never occurs in escaped text.
NUM_TOKEN = "\x00num\x00"


def _quality_summary(q: dict[str, Any] | None) -> dict[str, Any] | None:
    """Headline of the evaluation for the fleet table: the product alarm's score."""
    if not q or not q.get("evaluation"):
        return None
    sc = (q["evaluation"].get("detectors") or {}).get("product")
    if not sc:
        return None
    return {"detector": "product", "detected": sc["detected"], "n_contacts": sc["n_contacts"],
            "false_alarms": sc["false_alarms"],
            **(incident_score(q["evaluation"]) or {})}


def summary_row(sec: LogSection) -> dict[str, Any]:
    """One row of the fleet summary from a log section."""
    inp = sec["input"]
    return {
        "stem": sec["stem"], "path": inp["path"], "sha256": inp["sha256"],
        "duration_s": inp["duration_s"], "sample_rate_hz": inp["sample_rate_hz"],
        "n_joints": len(inp["joints"]), "calibrated": sec["calibrated"],
        "online_equivalent": sec["replay"]["online_equivalent"],
        "reference_source": sec["replay"]["reference_source"],
        "verdict": sec["verdict"],
        "incidents": {**incident_counts(sec["incidents"], sec.get("lasting_loads") or []),
                      "known": sec["incidents_known"]},
        "could_not_see": [c["code"] for c in sec["could_not_see"]],
        "events": sec["summary"],
        "worst_margin": {d: w["max_ratio"] for d, w in sec["false_alarm_margin"]["worst"].items()},
        "caveats": [c["code"] for c in sec["caveats"]],
        "quality": _quality_summary(sec.get("quality")),
    }


def report_dict(sections: Sequence[LogSection],
                failed: Sequence[tuple[str, str]] = ()) -> dict[str, Any]:
    """The report as a JSON-ready mapping (schemas/report.schema.json).

    Args:
        sections: one :func:`~.section.log_section` per log, in report order.
        failed: (input path, one-line error) of inputs that could not be analysed.
    """
    logs = list(sections)
    doc = {
        "schema_version": SCHEMA_VERSION,
        "tool": {"name": TOOL_NAME, "version": __version__},
        "parameters": {"guard_s": GUARD_S, "event_window_s": EVENT_WINDOW_S,
                       "whole_log_buckets": WHOLE_LOG_BUCKETS,
                       "max_event_figures": MAX_EVENT_FIGURES, "clip_factor": CLIP_FACTOR},
        "summary": [summary_row(s) for s in logs],
        "logs": logs,
        "failed": [{"path": p, "error": err} for p, err in failed],
    }
    return clean(doc)  # type: ignore[no-any-return]


def report_json(doc: dict[str, Any]) -> str:
    """Deterministic JSON text of a report mapping."""
    return json.dumps(doc, indent=1, sort_keys=True, allow_nan=False, ensure_ascii=False) + "\n"


HOW_TO_READ = (
    "<h3>How to read this report</h3><p>Each log's section opens with its answer: a verdict "
    "line and the <i>incidents</i> — one per physical contact as the product sees it, made "
    "of the alarms of its two detectors that overlap or follow each other closely. For each: "
    "when it started (seconds since the log's first sample, and the clock time when the log's "
    "clock is Unix time), where (the link, numbered from the base along the robot's chain: "
    "the most distal joint whose detectors fired or whose residual stands out of its own "
    "noise; the links the residuals cannot tell apart are named), how hard (the force at the "
    "end of that link from the residual torques through the Jacobian, when the kinematics "
    "are known, marked when it is beyond what the arm can exert; else the peak residual "
    "torques), what kind (transient — a collision the body can recoil "
    "from — or quasi-static — clamping, pressing while still — in the sense of ISO/TS 15066), "
    "which detectors fired and how far above their thresholds. The counted incidents are "
    "numbered 1, 2, … as <code>detect</code> prints them; those in the warm-up (w1, w2, …) "
    "are listed, never counted, and an incident never spans the warm-up's end. A "
    "<i>lasting load</i> — an alarm of 10 s or more: an unknown payload, a clamp, or a model "
    "that no longer fits — is a finding of its own, counted beside the incidents. Then what "
    "the audit could not see, the caveats, plots around "
    "each incident, and what was analysed with what.</p><p>impactcli replays, offline and "
    "causally, the adaptive impact detector of Makarov et al. (2014): a residual r = τ̂ − τ "
    "from a rough rigid model (eq. 7) is whitened by an RLS-estimated filter G(z) and "
    "compared, as an RMS over a short window, with a threshold v_stat + v_rms that follows "
    "the model error (eq. 41–42). Two static detectors run beside it: <i>static loading</i> "
    "(a low-passed |r| against vL, for slow clamping the adaptive filter is blind to; part "
    "of the product) and <i>static baseline</i> (|r| against v0, for comparison only). An "
    "<i>event</i> is a run of samples whose decision is 1; its <i>peak ratio</i> is "
    "statistic / threshold at its worst. The <i>false-alarm margin</i> is how close each "
    "statistic came to its threshold where no detector fired (and no contact was labelled): "
    "values near 1 mean a detector was close to a false alarm.</p>")


def render_html(doc: dict[str, Any], sections: Sequence[str]) -> str:
    """The self-contained HTML report (inline CSS and SVG only: nothing fetched) from the
    JSON mapping and each log's section (from :func:`render_log`)."""
    n = len(sections)
    logs = f"{n} log{'s' if n != 1 else ''}"
    n_uncal = sum(1 for s in doc["summary"] if not s["calibrated"])
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>impactcli safety-audit report — {logs}</title>",
        f"<style>{CSS}</style></head><body>",
        "<header><h1>Impact-detection safety-audit report</h1>",
        f'<p class="meta">{e(TOOL_NAME)} {e(__version__)} · report schema {SCHEMA_VERSION} · '
        f"{logs} · no date, no random id: the same inputs rebuild it byte for byte (the JSON "
        'twin holds the same facts) · <a href="#how-to-read">how to read it</a></p></header>',
    ]
    if n > 1 or doc.get("failed"):
        parts.append("<h2>Summary</h2>")
        if n_uncal:
            parts.append(f'<p class="bad">{n_uncal} of {n} log(s) were analysed with '
                         "UNCALIBRATED thresholds (see their caveats).</p>")
        parts.append(fleet_table_html(doc))
        if doc.get("failed"):
            parts.append(
                '<p class="bad">Inputs that could not be analysed (not in this report):</p><ul>'
                + "".join(f"<li><code>{e(x['path'])}</code>: {e(x['error'])}</li>"
                          for x in doc["failed"]) + "</ul>")
        parts.append(fleet_details_html(doc))
    parts.extend(html_k.replace(NUM_TOKEN, str(k + 1)) for k, html_k in enumerate(sections))
    parts.append(f'<section class="appendix" id="how-to-read">{HOW_TO_READ}</section>')
    parts.append("</body></html>\n")
    return "\n".join(parts)


@dataclasses.dataclass(frozen=True)
class RenderedLog:
    """One log, rendered: its JSON facts and its HTML section (numbered by NUM_TOKEN).

    What a report worker returns instead of its run and samples, so a fleet report holds
    only these.
    """

    section: LogSection
    html: str


def render_log(result: DetectionResult, labels: Labels | None = None, key: int = 0,
               origin: dict[str, Any] | None = None, *, samples: Samples) -> RenderedLog:
    """Render one log (``key``: its input index, which keeps SVG ids unique; ``origin``:
    the timeline it was re-run from, see :func:`~.section.log_section`; ``samples``: what
    its run's chunks left for the report, :mod:`.samples`)."""
    sec = log_section(result, labels, origin, samples)
    return RenderedLog(sec, section_html(NUM_TOKEN, result, sec, labels, Ids(f"{key}-"),
                                         samples))


def assemble_report(rendered: Sequence[RenderedLog],
                    failed: Sequence[tuple[str, str]] = ()) -> tuple[str, dict[str, Any]]:
    """``(html, doc)`` from rendered logs (report order = given order) and failed inputs
    ((input path, one-line error), listed in the summary)."""
    doc = report_dict([r.section for r in rendered], failed)
    return render_html(doc, [r.html for r in rendered]), doc


def write_report(rendered: Sequence[RenderedLog], html_path: str | os.PathLike[str],
                 json_path: str | os.PathLike[str] | None = None,
                 failed: Sequence[tuple[str, str]] = ()) -> dict[str, Any]:
    """Write the HTML report of logs rendered by :func:`render_log` (and its JSON twin)
    atomically; return the JSON mapping."""
    for p in (html_path, json_path):  # both destinations usable before either is written
        if p is not None:
            prepare_output(p)
    text, doc = assemble_report(rendered, failed)
    atomic_write_text(html_path, text)
    if json_path is not None:
        atomic_write_text(json_path, report_json(doc))
    return doc
