"""The incident-quality targets (one incident per contact, link, contact type, force),
shared by ``tests/benchmarks/incident_quality.py`` (whose docstring states them) and the
test that the targets gate, ``tests/test_incident_criteria.py``: a contact scored against
the incident found for it (:func:`score`), the targets over the scored contacts
(:func:`report`) and the exit code they give (:func:`verdict`)."""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from impactcli.types import DetectionResult, Labels

KIND = {"impact": "transient", "push": "transient", "clamp": "quasi_static"}
MIN_FORCE_N = 10.0
MATCH = (0.02, 0.25)  # an incident starting within [start - 0.02, end + 0.25] s


@dataclass
class Row:
    """One scored contact."""

    source: str
    kind: str
    label_link: int
    last_link: bool
    peak_n: float
    detected: bool
    n_incidents: int = 0
    link: int | None = None
    contact: str = ""
    force_n: float | None = None
    force_at_least: bool = False


def score(source: str, res: DetectionResult, labels: Labels) -> list[Row]:
    """One row per labelled contact ≥ MIN_FORCE_N after warm-up."""
    n_links = len(res.log.joint_names) + len(res.joints_left_out)
    rows = []
    for lab in labels.events:
        if lab.peak_force < MIN_FORCE_N or lab.start < res.warmup_end_s:
            continue
        inc = [i for i in res.counted_incidents()
               if lab.start - MATCH[0] <= i.t_start <= lab.end + MATCH[1]]
        row = Row(source, lab.kind, lab.link, lab.link == n_links, lab.peak_force, bool(inc),
                  len(inc))
        if inc:
            row.link, row.contact, row.force_n = inc[0].link, inc[0].contact, inc[0].force_n
            row.force_at_least = bool(inc[0].force_at_least)
        rows.append(row)
    return rows


def pct(a: int, b: int) -> str:
    return f"{a}/{b} ({100 * a / b:.0f} %)" if b else "—"


def report(rows: list[Row], title: str) -> list[tuple[str, bool]]:
    """Print the scores of ``rows``; return (criterion, passed)."""
    det = [r for r in rows if r.detected]
    one = [r for r in det if r.n_incidents == 1]
    link_ok = [r for r in det if r.link == r.label_link]
    inner = [r for r in det if not r.last_link]
    inner_ok = [r for r in inner if r.link == r.label_link]
    type_ok = [r for r in det if r.contact == KIND[r.kind]]
    errs = [abs(r.force_n - r.peak_n) / r.peak_n for r in det if r.force_n is not None]
    med = float(np.median(errs)) if errs else float("nan")
    print(f"\n### {title}\n")
    print(f"- contacts ≥ {MIN_FORCE_N:g} N after warm-up: {len(rows)}, detected {len(det)}")
    print(f"- detected contacts in exactly one incident: {pct(len(one), len(det))}")
    print(f"- link right: {pct(len(link_ok), len(det))}; not on the last link: "
          f"{pct(len(inner_ok), len(inner))}")
    by_type = {}
    for t in ("transient", "quasi_static"):
        of = [r for r in det if KIND[r.kind] == t]
        ok = [r for r in of if r.contact == t]
        by_type[t] = (len(ok), len(of))
    print(f"- contact type right: {pct(len(type_ok), len(det))}; "
          + "; ".join(f"{t} {pct(*v)}" for t, v in by_type.items()))
    ratio = [r.force_n / r.peak_n for r in det if r.force_n]
    print(f"- force: median relative error {100 * med:.0f} % over {len(errs)} estimates"
          + (f" (estimate / truth: median {np.median(ratio):.2f})" if errs else ""))
    print("\n| link | detected | link right | force median error | transient right | "
          "quasi-static right |\n|---|---|---|---|---|---|")
    for link in sorted({r.label_link for r in det}):
        of = [r for r in det if r.label_link == link]
        e = [abs(r.force_n - r.peak_n) / r.peak_n for r in of if r.force_n is not None]
        cells = []
        for t in ("transient", "quasi_static"):
            o = [r for r in of if KIND[r.kind] == t]
            cells.append(pct(sum(r.contact == t for r in o), len(o)))
        err = f"{100 * float(np.median(e)):.0f} %" if e else "—"
        print(f"| {link} | {len(of)} | {pct(sum(r.link == link for r in of), len(of))} | "
              f"{err} | " + " | ".join(cells) + " |")
    print("\n| source, kind | forces | marked ≳ | estimate / truth: median (range) | "
          "above the truth |\n|---|---|---|---|---|")
    for key in sorted({(r.source.split(" robot ")[0].replace("sample ", ""), r.kind)
                       for r in det if r.force_n}):
        of = [r for r in det if r.force_n and r.kind == key[1]
              and r.source.split(" robot ")[0].replace("sample ", "") == key[0]]
        q = np.array([r.force_n / r.peak_n for r in of if r.force_n])
        print(f"| {key[0]}, {key[1]} | {len(of)} | {sum(r.force_at_least for r in of)} | "
              f"{np.median(q):.2f} ({q.min():.2f}–{q.max():.2f}) | "
              f"{pct(int(np.sum(q > 1.0)), len(q))} |")

    def frac(a: list[Row], b: list[Row]) -> float:
        return len(a) / len(b) if b else 1.0

    return [
        ("one incident per detected contact", len(one) == len(det)),
        ("link right ≥ 90 %", frac(link_ok, det) >= 0.9),
        ("link right ≥ 75 % off the last link", frac(inner_ok, inner) >= 0.75),
        ("type right ≥ 90 %", frac(type_ok, det) >= 0.9),
        ("type right ≥ 75 % per type", all(v[1] == 0 or v[0] / v[1] >= 0.75
                                          for v in by_type.values())),
        ("median force error ≤ 30 %", bool(errs) and med <= 0.30),
    ]


def verdict(groups: dict[str, list[tuple[str, bool]]]) -> int:
    """Print ``PASS``/``FAIL  <target> [<group>]`` per target, and on stderr how many
    FAILed; the benchmark's exit code: 1 when any target FAILs, else 0."""
    failed = 0
    for label, crit in groups.items():
        for name, ok in crit:
            print(f"{'PASS' if ok else 'FAIL'}  {name} [{label}]")
            failed += not ok
    if failed:
        print(f"{failed} target(s) FAIL", file=sys.stderr)
    return 1 if failed else 0
