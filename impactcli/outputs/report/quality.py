"""Detection quality against labels (when a log has them): per-detector scores, each
labelled contact's outcome, the incidents' scores when the evaluation carries them
(``evaluation["incidents"]``: ``summary`` rows of label/value and ``contacts`` dicts,
rendered as they come), and the threshold sweep (a short table and an ROC-style plot).

The numbers come from :mod:`impactcli.quality`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ...errors import ImpactError
from ...quality.evaluation import evaluate_result
from ...quality.sweep import DEFAULT_SWEEP_SCALES
from ...quality.verdict import sweep_to_dict
from ...types import DetectionResult, Labels
from .common import e, g, generic_table, kv_table, to_mapping
from .plots import sweep_plot
from .samples import Samples

#: the threshold scales of the report's sweep: the same grid as ``impactcli evaluate --sweep``
SWEEP_SCALES: tuple[float, ...] = tuple(DEFAULT_SWEEP_SCALES)


def evaluate(result: DetectionResult, labels: Labels,
             samples: Samples) -> dict[str, Any]:
    """The detection-quality evaluation and threshold sweep of one log (``samples``: where
    the sweep reads the ratios)."""
    out: dict[str, Any] = {"status": "done", "labels_path": labels.path,
                           "n_labelled": len(labels.events), "evaluation": None,
                           "sweep": None, "notes": []}
    out["evaluation"] = to_mapping(evaluate_result(result, labels))
    try:
        rows = samples.sweep(result, labels, SWEEP_SCALES)
    except ImpactError as err:  # e.g. a run whose config lacks the event settings
        out["notes"].append(f"No threshold sweep: {err}")
        return out
    out["sweep"] = {"scales": list(SWEEP_SCALES), **sweep_to_dict(rows)}
    return out


def _ms(v: Any) -> str:
    return "—" if not isinstance(v, int | float) else f"{1000 * v:.0f}"


def _scores(ev: dict[str, Any]) -> str:
    sc = ev.get("detectors") or {}
    dets = list(sc)

    def frac(s: dict[str, Any]) -> str:
        return f"{s['detected']}/{s['n_contacts']}"

    metrics: list[tuple[str, Any]] = [
        ("counted events", lambda s: str(s["n_events"])),
        ("contacts detected", frac),
        ("false alarms", lambda s: str(s["false_alarms"])),
        ("false alarms per hour", lambda s: g(s["false_alarms_per_hour"])),
        ("median delay [ms]", lambda s: _ms(s["delay_median_s"])),
        ("max delay [ms]", lambda s: _ms(s["delay_max_s"])),
        ("smallest detected force [N]", lambda s: g(s["min_detected_force"])),
        ("largest missed force [N]", lambda s: g(s["max_missed_force"])),
    ]
    head = "".join(f'<th class="num">{e(d)}</th>' for d in dets)
    body = "".join(f"<tr><th>{e(name)}</th>" + "".join(
        f'<td class="num">{fn(sc[d])}</td>' for d in dets) + "</tr>" for name, fn in metrics)
    return f'<div class="wide"><table><tr><th>per detector</th>{head}</tr>{body}</table></div>'


def _contacts(contacts: Sequence[dict[str, Any]]) -> str:
    cdets = list(contacts[0].get("detected") or {})
    rows = []
    for c in contacts[:300]:
        cells = []
        for d in cdets:
            if c["detected"].get(d):
                cells.append(f'<td class="num good">hit {_ms(c["delay_s"].get(d))} ms</td>')
            else:
                on = " (alarm already on)" if (c.get("alarm_on_at_onset") or {}).get(d) else ""
                cls = "bad" if c["status"] == "counted" else "muted"
                cells.append(f'<td class="num {cls}">missed{on}</td>')
        rows.append(
            f'<tr><td class="num">{c["index"] + 1}</td><td class="num">{c["start"]:.3f}</td>'
            f'<td class="num">{c["end"]:.3f}</td><td>{e(c["kind"])}</td>'
            f'<td class="num">{c["link"]}</td><td class="num">{g(c["peak_force"])}</td>'
            f"<td>{e(c['status'])}</td>{''.join(cells)}</tr>")
    more = (f'<p class="small muted">{len(contacts) - 300} more contacts in the JSON report.</p>'
            if len(contacts) > 300 else "")
    return ('<h4>Labelled contacts</h4><div class="wide"><table><thead><tr>'
            '<th class="num">#</th><th class="num">start [s]</th><th class="num">end [s]</th>'
            '<th>kind</th><th class="num">link</th><th class="num">peak force [N]</th>'
            "<th>status</th>" + "".join(f"<th>{e(d)}</th>" for d in cdets)
            + "</tr></thead>" + "".join(rows) + f"</table></div>{more}")


def _incident_scores(inc: Any) -> str:
    """``evaluation["incidents"]`` as it comes: summary rows (label/value), contacts."""
    if not isinstance(inc, dict):
        return ""
    p = ["<h4>Incidents against labels (link, force, contact type)</h4>"]
    summ = inc.get("summary")
    pairs: list[tuple[str, Any]] = []
    if isinstance(summ, dict):
        pairs = list(summ.items())
    elif isinstance(summ, list):
        for r in summ:
            if isinstance(r, dict):
                pairs.append((r.get("label", ""), r.get("value")))
            elif isinstance(r, list | tuple) and len(r) == 2:
                pairs.append((r[0], r[1]))
    if pairs:
        p.append(kv_table([(str(k), g(v)) for k, v in pairs]))
    contacts = [c for c in inc.get("contacts") or [] if isinstance(c, dict)]
    if contacts:
        p.append(generic_table(contacts))
    return "".join(p) if len(p) > 1 else ""


def quality_html(q: dict[str, Any]) -> str:
    """The detection-quality section of one log."""
    p = ["<h3>Detection quality against labels</h3>",
         f"<p>Labels: <code>{e(q['labels_path'])}</code>, {q['n_labelled']} labelled "
         "contact(s).</p>"]
    p.extend(f'<p class="warn">{e(n)}</p>' for n in q.get("notes") or [])
    ev = q.get("evaluation")
    if ev:
        nc = ev.get("n_contacts") or {}
        tol = ev.get("tolerance") or {}
        p.append(
            f"<p>{nc.get('counted', 0)} contact(s) counted, {nc.get('in_warmup', 0)} in warm-up "
            f"(not counted), {nc.get('outside_log', 0)} outside the log. Matching rule: "
            f"{e(tol.get('rule', ''))} (pre_s = {g(tol.get('pre_s'))} s, post_s = "
            f"{g(tol.get('post_s'))} s). Collision-free time after warm-up: "
            f"{g(ev.get('collision_free_s'))} s. <i>product</i> = adaptive OR static_loading, "
            "the product's alarm.</p>")
        if ev.get("detectors"):
            p.append(_scores(ev))
        p.append(_incident_scores(ev.get("incidents")))
        if ev.get("contacts"):
            p.append(_contacts(ev["contacts"]))
    if q.get("sweep"):
        p.append(sweep_html(q["sweep"]))
    return "".join(p)


def _key_scales(rows: Sequence[dict[str, Any]], zero: dict[str, Any]) -> list[float]:
    """The scales worth a row: the ends, this run (nearest 1), each detector's
    zero-false-alarm point."""
    scales = sorted({r["scale"] for r in rows})
    keep = {scales[0], scales[-1], min(scales, key=lambda s: abs(s - 1.0))}
    keep |= {z["scale"] for z in zero.values() if isinstance(z, dict) and z.get("scale") in scales}
    return sorted(keep)


def sweep_html(sw: dict[str, Any]) -> str:
    """The threshold sweep: verdict, a short scale × detector table, an ROC-style plot."""
    rows = [r for r in sw.get("rows") or [] if isinstance(r, dict)]
    p = ["<h4>Threshold sweep — detectors compared at equal false alarms</h4>",
         "<p>Every threshold multiplied by a scale s (decision: statistic / threshold &gt; s; "
         "s ≈ 1 is this run). Cells: contacts detected / counted, false alarms.</p>"]
    if sw.get("verdict"):
        p.append(f"<p><b>Verdict:</b> {e(sw['verdict'])}</p>")
        if sw.get("caveat"):
            p.append(f"<p>{e(sw['caveat'])}</p>")
    if not rows:
        return "".join(p)
    dets = list(dict.fromkeys(r["detector"] for r in rows))
    zero = sw.get("at_zero_false_alarms") or {}
    cell = {(r["detector"], r["scale"]): r for r in rows}
    keys = _key_scales(rows, zero)
    body = []
    for s in keys:
        tds = []
        for d in dets:
            r = cell.get((d, s))
            if r is None:
                tds.append('<td class="num muted">—</td>')
                continue
            z = zero.get(d)
            mark = " good" if isinstance(z, dict) and z.get("scale") == s else ""
            tds.append(f'<td class="num{mark}">{r["detected"]}/{r["n_contacts"]}, '
                       f"{r['false_alarms']} FA</td>")
        what = [d for d in dets if isinstance(zero.get(d), dict) and zero[d].get("scale") == s]
        notes = ["this run"] if s == min(keys, key=lambda x: abs(x - 1.0)) else []
        notes += [f"zero FA from here: {', '.join(what)}"] if what else []
        note = "; ".join(notes)
        body.append(f'<tr><th class="num">{s:g}</th>{"".join(tds)}'
                    f'<td class="small">{e(note)}</td></tr>')
    n_scales = len({r["scale"] for r in rows})
    p.append('<div class="wide"><table><thead><tr><th class="num">scale s</th>'
             + "".join(f'<th class="num">{e(d)}</th>' for d in dets)
             + "<th></th></tr></thead>" + "".join(body) + "</table></div>")
    p.append(f'<p class="small">{len(keys)} of {n_scales} scales: the ends, this run and each '
             "detector's zero-false-alarm point (green: the smallest scale from which on it "
             "stays free of false alarms); every scale is in the JSON report.</p>")
    p.append(sweep_plot(rows, dets))
    return "".join(p)
