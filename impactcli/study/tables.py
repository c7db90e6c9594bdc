"""The sensitivity study's summary as tables: Table II per variant and threshold setting,
the detection-vs-false-alarm (ROC) table and the verdicts, in plain text
(:func:`format_text`) and Markdown for the README (:func:`format_markdown`).

Formatting only: the numbers are :func:`impactcli.study.aggregate.summarize`'s mapping.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

from .aggregate import fmt
from .spec import PAPER_ADAPTIVE_N, PAPER_STATIC_N, SETTINGS, SOAK_FAMILIES

#: Table II's row labels for our detectors (static_loading is ours, not in the paper).
ROW_LABELS: dict[str, str] = {
    "adaptive": "Proposed method (adaptive)",
    "static_baseline": "Static threshold v0",
    "static_loading": "Static loading vL (ours)",
    "product": "Product (adaptive OR vL)",
}
TABLE_DETECTORS: tuple[str, ...] = ("adaptive", "static_baseline", "static_loading", "product")


def _ms(x: float | None) -> str:
    return "-" if x is None else f"{x * 1e3:.0f}"


def table_rows(variant: dict[str, Any], setting: str) -> list[list[str]]:
    """Table II's rows for one variant and threshold setting (header first)."""
    head = ["Detector", "Scale", "Environment stiffness (N/mm)", "Minimal detected force (N)",
            "Equivalent mass (kg)", "All detected above (N)", "Detected", "Delay med (ms)",
            "Soak FA/h (95 % bound)", "Paper (N)"]
    rows = [head]
    for d in TABLE_DETECTORS:
        cell = variant["settings"][setting][d]
        if not cell.get("reached"):
            rows.append([ROW_LABELS[d], "never", "-", "-", "-", "-", "-", "-", "-",
                         _paper(d, None)])
            continue
        sc = f"{'<=' if cell.get('at_sweep_edge') else ''}{cell['scale']:g}"
        fa = (f"{fmt(cell['soak_false_alarms_per_hour'])} "
              f"(<= {fmt(cell['soak_false_alarms_per_hour_upper95'])})")
        first = True
        for k, c in cell["by_stiffness"].items():
            rows.append([
                ROW_LABELS[d] if first else "", sc if first else "", f"k = {k}",
                fmt(c["min_detected_force_n"], nd=".2f"), fmt(c["equivalent_mass_kg"], nd=".3f"),
                "none missed" if c["all_detected_above_n"] is None and c["detected"]
                else fmt(c["all_detected_above_n"], nd=".2f"),
                f"{c['detected']}/{c['n_contacts']}", _ms(c["delay_median_s"]),
                fa if first else "", _paper(d, float(k))])
            first = False
    return rows


def _paper(det: str, k: float | None) -> str:
    if det == "adaptive" and k is not None:
        for kk, v in PAPER_ADAPTIVE_N.items():
            if abs(kk - k) < 1e-9:
                return f"{v:.2f}"
        return "-"
    if det == "static_baseline":
        return f"> {PAPER_STATIC_N:g}"
    return "-"


def _text_table(rows: Sequence[Sequence[str]]) -> list[str]:
    w = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    out = []
    for n, r in enumerate(rows):
        out.append("  ".join(c.ljust(w[i]) if i < 3 else c.rjust(w[i])
                             for i, c in enumerate(r)).rstrip())
        if n == 0:
            out.append("  ".join("-" * x for x in w))
    return out


def _soak_line(v: dict[str, Any]) -> str:
    fams = sorted({r["family"] for r in v["soak"]["runs"]})
    return (f"soak: {v['soak']['hours_after_warmup']:.2f} h collision-free after warm-up "
            f"({len(v['soak']['runs'])} runs: {', '.join(fams)}); cases: {v['cases']['n_cases']} "
            f"runs, {v['cases']['n_contacts']} counted impacts")


def _roc_rows(v: dict[str, Any], picks: Sequence[float],
              detectors: Sequence[str] = TABLE_DETECTORS) -> list[list[str]]:
    rows = [["Detector", "Scale", "Soak FA", "FA/h (95 % bound)", "Detected",
             "Min detected (N)", "All above (N)", "Delay med (ms)"]]
    for d in detectors:
        pts = v["roc"][d]
        chosen = []
        for p in picks:
            best = min(pts, key=lambda r: abs(math.log(r["scale"] / p)))
            if best not in chosen:
                chosen.append(best)
        first = True
        for r in chosen:
            rows.append([d if first else "", f"{r['scale']:g}", str(r["soak_false_alarms"]),
                         f"{fmt(r['soak_false_alarms_per_hour'])} "
                         f"(<= {fmt(r['soak_false_alarms_per_hour_upper95'])})",
                         f"{r['detected']}/{r['n_contacts']}",
                         fmt(r["min_detected_force_n"], nd=".2f"),
                         fmt(r["all_detected_above_n"], nd=".2f"), _ms(r["delay_median_s"])])
            first = False
    return rows


ROC_PICKS: tuple[float, ...] = (0.25, 0.35, 0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0, 8.0, 16.0)


MD_ROC_PICKS: tuple[float, ...] = (0.5, 0.7, 1.0, 1.4, 2.0, 4.0)


def format_text(summary: dict[str, Any]) -> str:
    """Plain-text report: Table II per variant and setting, the ROC table, the verdicts."""
    lines = []
    for v in summary["variants"]:
        lines.append(f"=== {v['name']}: {v['description']} ===")
        lines.append(_soak_line(v))
        for setting in SETTINGS:
            lines += ["", f"TABLE II (reproduced) — {v['name']}, thresholds {setting}: "
                          + summary["definitions"][setting], *_text_table(table_rows(v, setting))]
        lines += ["", "Detection vs false alarms (threshold scale sweep):",
                  *_text_table(_roc_rows(v, ROC_PICKS)), "", v["verdict"]["text"], ""]
    return "\n".join(lines) + "\n"


def _md(rows: Sequence[Sequence[str]]) -> list[str]:
    out = ["| " + " | ".join(rows[0]) + " |",
           "|" + "|".join("---" if i < 3 else "---:" for i in range(len(rows[0]))) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return out


def format_markdown(summary: dict[str, Any], command: str = "") -> str:
    """Markdown tables to paste in the README (Table II per variant and setting, verdicts)."""
    sp = summary["spec"]
    lines = ["### Table II, reproduced on the simulator", ""]
    if command:
        lines += ["Made with:", "", "```sh", command, "```", ""]
    lines += [
        f"Stiffnesses {', '.join(f'{k:g}' for k in sp['stiffnesses'])} N/mm; "
        f"{len(sp['forces_n'])} amplitudes × {sp['case_seeds']} seeds × "
        f"{sp['impacts_per_case']} impacts per stiffness; soak {len(SOAK_FAMILIES)} families × "
        f"{sp['soak_runs']} × {sp['soak_run_s']:g} s per variant; seed {sp['seed']}. "
        "Minimal detected force = smallest labelled peak force detected; all detected above = "
        "largest peak force missed. Paper (N): Makarov et al. 2014, Table II.", ""]
    for v in summary["variants"]:
        lines += [f"#### {v['name']} — {v['description']}", "", _soak_line(v) + ".", ""]
        for setting in SETTINGS:
            lines += [f"*Thresholds {setting}* — {summary['definitions'][setting]}.", "",
                      *_md(table_rows(v, setting)), ""]
        lines += ["*Detection vs soak false alarms (threshold scale sweep, all stiffnesses)*",
                  "", *_md(_roc_rows(v, MD_ROC_PICKS, ("adaptive", "static_loading"))), "",
                  f"**Verdict.** {v['verdict']['text']}", ""]
    return "\n".join(lines)


def iter_detectors() -> Iterable[str]:
    """The detectors of the tables, in order."""
    return iter(TABLE_DETECTORS)
