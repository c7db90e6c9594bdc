"""What every part of the report shares: its fixed settings, names, and small formatters.

Formatting only. Numbers are printed with fixed rules (no locale, no time of the run), so
the same inputs give byte-identical HTML and JSON.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import html
import json
import math
from collections.abc import Sequence
from typing import Any, NotRequired, TypedDict

import numpy as np

from ...detect.incidents import PRODUCT_DETECTORS
from ...types import Event

__all__ = ["PRODUCT_DETECTORS"]

#: Version of the report's JSON twin (1.1: verdict, incidents and could_not_see per log; 1.2:
#: lasting loads, incident labels and force checks).
SCHEMA_VERSION = "1.2"
#: Each side of an event or labelled contact excluded from the false-alarm margin [s].
GUARD_S = 0.5
#: Half-width of the time added before and after each incident in its plots [s].
EVENT_WINDOW_S = 1.0
#: At most this many incident figures per log (the rest are listed and stated).
MAX_EVENT_FIGURES = 60
#: Buckets of the min/max envelope of whole-log plots (≈ one per horizontal pixel pair).
WHOLE_LOG_BUCKETS = 700
#: Buckets of the envelope inside an incident window.
EVENT_BUCKETS = 500
#: The y axis of a plot is capped at this multiple of its threshold (peaks drawn at the
#: top edge, their true maximum written in the panel).
CLIP_FACTOR = 4.0
#: A filter gain below this at a frequency <= 10 Hz triggers the "blind to slow contacts"
#: caveat (the G(z) pitfall of the README's method section).
LOW_GAIN = 0.2
#: A model whose RMS torque error exceeds this fraction of the torque RMS (hold-out part
#: when there is one) triggers the "poor fit" caveat.
POOR_FIT = 0.5

DETECTOR_TITLE = {
    "adaptive": "adaptive (eq. 41–42)",
    "static_loading": "static loading",
    "static_baseline": "static baseline",
}
STAT_NAME = {
    "adaptive": ("r̃ rms", "v_stat + v_rms"),
    "static_loading": ("|LP(r)|", "vL"),
    "static_baseline": ("|r|", "v0"),
}
CONTACT_TEXT = {"transient": "transient", "quasi_static": "quasi-static", "unknown": "unknown-kind"}


class LogSection(TypedDict):
    """One log's JSON facts in a report (``schemas/report.schema.json``, ``logs`` items): the
    timeline's fields but ``schema_version`` and ``tool`` (the ``NotRequired`` ones only when
    the timeline has them), then what the report adds. Values are JSON-ready."""

    input: dict[str, Any]
    config: dict[str, Any]
    calibrated: bool
    model: dict[str, Any] | None
    replay: dict[str, Any]
    warmup_end_s: float
    warmup_per_joint_s: dict[str, float]
    thresholds: dict[str, Any]
    filter_gain: dict[str, Any]
    events: list[dict[str, Any]]
    incidents: list[dict[str, Any]]
    lasting_loads: list[dict[str, Any]]
    motion_envelope: NotRequired[Any]
    detection_floor: NotRequired[Any]
    data_defects: NotRequired[Any]
    payload_changes: NotRequired[Any]
    counts: dict[str, Any]
    summary: dict[str, dict[str, int]]
    warnings: list[str]
    stem: str
    timeline_schema_version: str
    origin: dict[str, Any] | None
    incidents_known: bool
    verdict: str
    could_not_see: list[dict[str, Any]]
    false_alarm_margin: dict[str, Any]
    caveats: list[dict[str, Any]]
    labels: dict[str, Any] | None
    quality: dict[str, Any] | None


def incident_score(evaluation: dict[str, Any]) -> dict[str, int] | None:
    """The labelled contacts an evaluation's incidents matched (``as_incidents``) and those
    only payload changes' alarms held (``taken_for_payload``: not counted, missed as
    contacts); None without an incident-level score. Beside the product alarm's hits, which
    count an alarm a payload change took as a hit (a trial's report said "3/4 hit" where 2
    of 4 clamps were incidents)."""
    inc = evaluation.get("incidents") or {}
    if not inc.get("available"):
        return None
    return {"as_incidents": int(inc["matched"]),
            "taken_for_payload": sum(1 for c in inc.get("contacts") or ()
                                     if c.get("payload_change"))}


def incident_score_text(score: dict[str, int] | None, n_contacts: int) -> str:
    """"; as incidents 2/4 (1 taken for a payload change, not counted)", or ""."""
    if score is None:
        return ""
    k = score.get("taken_for_payload", 0)
    return (f"; as incidents {score['as_incidents']}/{n_contacts}"
            + (f" ({k} taken for a payload change, not counted)" if k else ""))


def clean(x: Any) -> Any:
    """JSON-safe copy: numpy scalars → Python, non-finite floats → None, tuples → lists."""
    if isinstance(x, dict):
        return {str(k): clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return clean(x.tolist())
    if hasattr(x, "item") and not isinstance(x, str | bytes):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def to_mapping(obj: Any) -> Any:
    """An evaluation object → plain data (``to_dict()``, dataclass, or as is)."""
    if hasattr(obj, "to_dict"):
        return obj.to_dict()
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.asdict(obj)
    if isinstance(obj, list | tuple):
        return [to_mapping(v) for v in obj]
    return obj


def event_duration_s(e: Event, period_s: float) -> float:
    """Alarm duration: samples i_start..i_end inclusive × the median sample period [s]."""
    return float(e.t_end - e.t_start + period_s)


# --------------------------------------------------------------------------- text


def e(x: Any) -> str:
    """HTML-escaped text (NUL dropped: not valid in HTML, and it marks NUM_TOKEN)."""
    return html.escape(str(x).replace("\x00", ""), quote=True)


def f(v: Any, digits: int = 3) -> str:
    """A number with ``digits`` decimals; yes/no for booleans; — for None."""
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "—" if not math.isfinite(v) else f"{v:.{digits}f}"
    return e(v)


def g(v: Any) -> str:
    """A compact general number."""
    if isinstance(v, bool) or v is None:
        return f(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "—" if not math.isfinite(v) else f"{v:.4g}"
    return e(v)


def approx(v: float) -> str:
    """A force or torque as a reader says it: 37, 4.9, 0.39 (two significant digits,
    whole numbers from 10 on)."""
    a = abs(v)
    if a >= 10:
        return f"{v:.0f}"
    if a >= 1:
        return f"{v:.1f}"
    return f"{v:.2g}"


def share(part_s: float, total_s: float) -> str:
    """``, 7 % of the log`` (empty for an empty log)."""
    return f", {100 * part_s / total_s:.0f} % of the log" if total_s > 0 else ""


def epoch_text(t0_ns: int) -> str:
    """`` (= <UTC time> if it is Unix time)`` for clocks that look like epoch ns, else ""."""
    if not isinstance(t0_ns, int) or t0_ns < 10**17:  # before 1973: not an epoch clock
        return ""
    when = dt.datetime.fromtimestamp(t0_ns // 10**9, tz=dt.UTC)
    ms = (t0_ns // 10**6) % 1000
    return f" (= {when:%Y-%m-%d %H:%M:%S}.{ms:03d} UTC if it is Unix time)"


def utc(iso: str | None) -> dt.datetime | None:
    """An incident's ``t_start_utc`` (ISO 8601) as a datetime, None when absent or bad."""
    if not iso:
        return None
    try:
        return dt.datetime.fromisoformat(iso.replace("Z", "+00:00"))
    except ValueError:
        return None


def ratio_cell(r: float | None, note: str | None = None) -> str:
    """A table cell for a statistic / threshold ratio, coloured by how close to 1."""
    if r is None:
        return '<td class="num muted">—</td>'
    cls = "bad" if r >= 1.0 else ("warn" if r >= 0.8 else "good")
    extra = f' <span class="note">{e(note)}</span>' if note else ""
    return f'<td class="num {cls}">{r:.2f}{extra}</td>'


def kv_table(rows: Sequence[tuple[str, str]]) -> str:
    """A two-column key/value table (values are HTML)."""
    body = "".join(f"<tr><th>{e(k)}</th><td>{v}</td></tr>" for k, v in rows)
    return f'<table class="kv">{body}</table>'


def json_pre(obj: Any, max_str: int = 240) -> str:
    """A JSON value in a ``<pre>``, long strings shortened (the JSON report has them)."""
    def shorten(x: Any) -> Any:
        if isinstance(x, dict):
            return {k: shorten(v) for k, v in x.items()}
        if isinstance(x, list):
            return [shorten(v) for v in x]
        if isinstance(x, str) and len(x) > max_str:
            return x[:80] + f"… ({len(x)} characters, in the JSON report)"
        return x

    return f"<pre>{e(json.dumps(shorten(obj), indent=1, sort_keys=True, ensure_ascii=False))}</pre>"


def compact(v: Any) -> str:
    """A cell's text for any JSON value: numbers compact, containers as short JSON."""
    if isinstance(v, dict | list):
        return e(json.dumps(v, sort_keys=True, ensure_ascii=False))
    return g(v)


def generic_table(rows: Sequence[dict[str, Any]], limit: int = 300) -> str:
    """A table of dicts: one column per key (in first-seen order), values compact."""
    cols = list(dict.fromkeys(k for r in rows for k in r))
    head = "".join(f"<th>{e(c)}</th>" for c in cols)
    body = "".join("<tr>" + "".join(f"<td>{compact(r.get(c))}</td>" for c in cols) + "</tr>"
                   for r in rows[:limit])
    more = (f'<p class="small muted">{len(rows) - limit} more rows in the JSON report.</p>'
            if len(rows) > limit else "")
    return f'<div class="wide"><table><thead><tr>{head}</tr></thead>{body}</table></div>{more}'


class Ids:
    """Deterministic ids for SVG clip paths, unique in the document: one counter per log
    section, prefixed by the log's input index."""

    def __init__(self, prefix: str = "") -> None:
        self.prefix = prefix
        self.n = 0

    def __call__(self) -> str:
        self.n += 1
        return f"clip{self.prefix}{self.n}"
