"""The plain-text table of an :class:`~impactcli.quality.evaluation.Evaluation`
(``impactcli evaluate`` prints it): one row per detector, then per contact kind, the
contacts in warm-up, and the incidents against the labels (:func:`format_incident_evaluation`).

Formatting only: the numbers come from :mod:`impactcli.quality.evaluation` and
:mod:`impactcli.quality.incident_scores`. Its small formatters (ms, N, the aligned table) are
reused by the sweep's text (:mod:`impactcli.quality.verdict`).
"""

from __future__ import annotations

from collections.abc import Sequence

from ..detect.force import AT_LEAST
from .evaluation import Evaluation
from .incident_scores import IncidentEvaluation


def fmt_ms(x: float | None) -> str:
    """A duration in s as whole milliseconds (``-`` for None)."""
    return "-" if x is None else f"{x * 1e3:.0f} ms"


def fmt_n(x: float | None) -> str:
    """A force in N, 3 significant digits (``-`` for None)."""
    return "-" if x is None else f"{x:.3g} N"


def _fmt_rate(x: float | None) -> str:
    return "-" if x is None else f"{x:.3g}"


def format_evaluation(ev: Evaluation) -> str:
    """A plain-text table of an :class:`Evaluation` (one row per detector, then per kind)."""
    n_counted = len(ev.contacts_with_status("counted"))
    n_warm = len(ev.contacts_with_status("in_warmup"))
    n_out = len(ev.contacts_with_status("outside_log"))
    lines = [
        f"Contacts: {n_counted} counted"
        + (f", {n_warm} in warm-up (reported, not counted)" if n_warm else "")
        + (f", {n_out} after the log's end (not counted)" if n_out else ""),
        f"Log {ev.duration_s:.3f} s, warm-up until {ev.warmup_end_s:.3f} s, "
        f"collision-free time {ev.collision_free_s:.3f} s",
        f"Match: an event starting within [contact start - {ev.tolerance.pre_s:g} s, "
        f"contact end + {ev.tolerance.post_s:g} s]; product = adaptive OR static_loading",
        "(the product's alarms are its parts' merged where they overlap or follow within "
        f"{ev.product_merge_gap_s:g} s: one long alarm holds many of a part's, so the "
        "product can count fewer false alarms than one of its parts)",
        "",
    ]
    head = ("detector", "detected", "false alarms", "FA/h", "delay med", "delay max",
            "min detected F", "max missed F", "warm-up ev.")
    rows = [head]
    for d, s in ev.scores.items():
        rows.append((
            d, f"{s.detected}/{s.n_contacts}", str(s.false_alarms),
            _fmt_rate(s.false_alarms_per_hour),
            fmt_ms(s.delay_median_s), fmt_ms(s.delay_max_s), fmt_n(s.min_detected_force),
            fmt_n(s.max_missed_force), str(s.n_events_in_warmup),
        ))
    lines += text_table(rows)
    picked = {d: len(s.payload_change_events) for d, s in ev.scores.items()
              if s.payload_change_events}
    if picked:
        lines.append("not false alarms: the alarms of payload changes (a load picked or "
                     "released) — " + ", ".join(f"{d} {n}" for d, n in picked.items()))
    kind_rows: list[tuple[str, ...]] = [("detector", "kind", "detected", "delay med",
                                         "min detected F", "max missed F")]
    for d, s in ev.scores.items():
        for k in s.by_kind:
            kind_rows.append((d, k.kind, f"{k.detected}/{k.n_contacts}", fmt_ms(k.delay_median_s),
                              fmt_n(k.min_detected_force), fmt_n(k.max_missed_force)))
    if len(kind_rows) > 1:
        lines += ["", "By contact kind:", *text_table(kind_rows)]
    warm = ev.contacts_with_status("in_warmup")
    if warm:
        lines += ["", "Contacts in warm-up (not counted as misses):"]
        for c in warm:
            by = [d for d, v in c.detected.items() if v]
            lines.append(f"  #{c.index} {c.label.kind} at {c.label.start:.3f} s, "
                         f"{c.label.peak_force:.3g} N: alarm by {', '.join(by) if by else 'none'}")
    lines += ["", *format_incident_evaluation(ev.incidents)]
    if ev.payload_changes is not None:
        from .payload_scores import payload_text

        lines += ["", payload_text(ev.payload_changes)]
    return "\n".join(lines) + "\n"


def format_incident_evaluation(ie: IncidentEvaluation) -> list[str]:
    """Text lines: the incidents' scores (:meth:`IncidentEvaluation.summary`) and, per
    labelled contact, the incident that answers it."""
    if not ie.available:
        return [f"Incidents: {ie.note}"]
    rows = ie.summary()
    width = max(len(a) for a, _ in rows)
    lines = ["Incidents (the answer: link, force, contact type) against the labels:"]
    lines += [f"  {a.ljust(width)}  {b}" for a, b in rows]
    if not ie.contacts:
        return lines
    table: list[tuple[str, ...]] = [("label", "kind", "incident at", "link: label / found",
                                     "force: label / found", "error", "type: expected / found")]
    for c in ie.contacts:
        def mark(ok: bool | None) -> str:
            return "" if ok is None else (" ok" if ok else " WRONG")
        f_lab = "switch" if c.force_label_n is None else f"{c.force_label_n:.3g} N"
        f_inc = ("-" if c.force_n is None
                 else f"{AT_LEAST if c.force_at_least else ''}{c.force_n:.3g} N")
        table.append((
            f"#{c.label_index}" + ("" if c.status == "counted" else f" ({c.status})"),
            c.kind,
            (f"{c.incident_t_start:.3f} s" if c.incident_t_start is not None
             else "a payload change" if c.payload_change
             else "in an earlier one" if c.status == "counted" and c.n_incidents >= 1
             else "none"),
            f"{c.link_label} / " + ("-" if c.link is None else " or ".join(
                str(k) for k in c.link_candidates) if len(c.link_candidates) > 1
                else str(c.link)) + (" among" if c.among else mark(c.link_right)),
            f"{f_lab} / {f_inc}",
            "-" if c.force_rel_error is None else f"{100 * c.force_rel_error:+.0f}%",
            f"{c.expected_contact} / {c.contact or '-'}{mark(c.contact_right)}",
        ))
    lines += ["", "Per labelled contact (label # from 0, as in the labels' events):",
              *text_table(table)]
    return lines


def text_table(rows: Sequence[Sequence[str]]) -> list[str]:
    """Lines of an aligned table (first row the header, underlined; first column left)."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    out = []
    for n, r in enumerate(rows):
        out.append("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in
                             enumerate(zip(r, widths, strict=True))).rstrip())
        if n == 0:
            out.append("  ".join("-" * w for w in widths))
    return out
