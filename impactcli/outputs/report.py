"""The safety-audit report: one self-contained HTML file and its JSON twin.

Formatting only — every number comes from a :class:`~impactcli.result.DetectionResult`
(through :func:`impactcli.outputs.timeline.timeline_dict`, whose fields are reused as they
are) or from :mod:`impactcli.evaluate` when labels are given. The one quantity computed here
is a *reduction* of ``result.ratios`` (a maximum), the false-alarm margin:

    margin_d,j = max { ratio_d(k, j) : t_k >= warmup_end_s, t_k outside every event }

where ``ratio_d = statistic / threshold`` of detector d on joint j (eq. 41–42 for the
adaptive detector; |LP(r)| / vL and |r| / v0 for the static ones) and "outside every event"
excludes each detected event of *any* detector, and each labelled contact when labels are
given, widened by :data:`GUARD_S` on both sides (the RMS windows and filters spread a
contact over a few hundred ms). A margin of 0.6 means the statistic came to 60 % of its
threshold on the collision-free stretches; 1 / margin is the factor by which the threshold
could be lowered before the first false alarm there.

Determinism: no time of the run, no random ids, keys sorted, fixed number formatting; the
same inputs give byte-identical JSON and HTML.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import html
import json
import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from .. import TOOL_NAME, __version__
from .._fs import atomic_write_text, prepare_output
from ..detect.calibrate import (
    MAX_MARGIN,
    UNCALIBRATED_BLOCK_S,
    UNCALIBRATED_MARGIN,
    UNCALIBRATED_QUANTILE,
)
from ..detect.events import LONG_EVENT_S
from ..errors import ImpactError
from ..result import DetectionResult
from ..types import DETECTORS, Event, Labels
from . import svgplot
from .timeline import timeline_dict

SCHEMA_VERSION = "1.0"
#: Each side of an event or labelled contact excluded from the false-alarm margin [s].
GUARD_S = 0.5
#: Half-width of the window plotted around each event [s].
EVENT_WINDOW_S = 1.0
#: Event windows closer than this are drawn in one figure; a figure spans at most
#: :data:`MAX_CLUSTER_S` [s].
MAX_CLUSTER_S = 6.0
#: At most this many event figures per log (the rest are listed in the table and stated).
MAX_EVENT_FIGURES = 60
#: Buckets of the min/max envelope of whole-log plots (≈ one per horizontal pixel pair).
WHOLE_LOG_BUCKETS = 700
#: Buckets of the envelope inside an event window.
EVENT_BUCKETS = 500
#: The y axis of a plot is capped at this multiple of its threshold (peaks drawn at the
#: top edge, their true maximum written in the panel).
CLIP_FACTOR = 4.0
#: Threshold scales of the ROC-style sweep (when :mod:`impactcli.evaluate` provides it).
def _sweep_scales() -> tuple[float, ...]:
    from ..evaluate import DEFAULT_SWEEP_SCALES

    return tuple(DEFAULT_SWEEP_SCALES)


#: the threshold scales of the report's sweep: the same grid as ``impactcli evaluate --sweep``
SWEEP_SCALES: tuple[float, ...] = _sweep_scales()
#: The product's detectors (static_baseline exists to be compared against).
PRODUCT_DETECTORS: tuple[str, ...] = ("adaptive", "static_loading")
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

# --------------------------------------------------------------------------- helpers


def _clean(x: Any) -> Any:
    """JSON-safe copy: numpy scalars → Python, non-finite floats → None, tuples → lists."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if hasattr(x, "item") and not isinstance(x, str | bytes):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def _to_mapping(obj: Any) -> Any:
    """An evaluation object → plain data (``to_dict()``, dataclass, or as is)."""
    if hasattr(obj, "to_dict"):
        return obj.to_dict()
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.asdict(obj)
    if isinstance(obj, list | tuple):
        return [_to_mapping(v) for v in obj]
    return obj


def log_stem(path: str) -> str:
    """The stem ``detect`` names its outputs by (:func:`impactcli.io.log_stem`: the file
    name without its format extension — ``.csv``, ``.csv.gz``, ``.mcap``, ``.npz``, ``.bag``,
    ``.db3`` — or a rosbag2 folder's own name), and a timeline's (``x.timeline.json`` → x)."""
    from ..io import log_stem as io_log_stem

    name = os.path.basename(str(path).rstrip("/\\")) or str(path)
    for ext in (".timeline.json", ".json"):
        if name.lower().endswith(ext):
            return name[: -len(ext)]
    return str(io_log_stem(name))


def event_duration_s(e: Event, period_s: float) -> float:
    """Alarm duration: samples i_start..i_end inclusive × the median sample period [s]."""
    return float(e.t_end - e.t_start + period_s)


def statistic(result: DetectionResult, detector: str, j: int) -> tuple[np.ndarray, np.ndarray]:
    """(statistic, threshold) of ``detector`` on joint index ``j``, each (N,) [N·m].

    adaptive: residual_rms vs threshold (v_stat + v_rms, eq. 42); static_loading:
    loading_statistic vs vL; static_baseline: |residual| vs v0.
    """
    n = result.log.n_samples
    name = result.log.joint_names[j]
    if detector == "adaptive":
        return result.signals["residual_rms"][:, j], result.signals["threshold"][:, j]
    if detector == "static_loading":
        return result.signals["loading_statistic"][:, j], np.full(n, result.thresholds[name]["vL"])
    return np.abs(result.signals["residual"][:, j]), np.full(n, result.thresholds[name]["v0"])


# --------------------------------------------------------------------------- margins


def collision_free_mask(
    result: DetectionResult, labels: Labels | None = None, guard_s: float = GUARD_S
) -> np.ndarray:
    """(N,) bool: samples after warm-up and outside every event / labelled contact ± guard."""
    t = result.log.time_s
    mask = t >= result.warmup_end_s
    spans = [(e.t_start, e.t_end) for e in result.events]
    if labels is not None:
        spans += [(c.start, c.end) for c in labels.events]
    for a, b in spans:
        lo = int(np.searchsorted(t, a - guard_s, side="left"))
        hi = int(np.searchsorted(t, b + guard_s, side="right"))
        mask[lo:hi] = False
    return mask


def false_alarm_margins(
    result: DetectionResult, labels: Labels | None = None, guard_s: float = GUARD_S
) -> dict[str, Any]:
    """Per detector and joint, the largest statistic / threshold ratio on collision-free
    stretches (see the module docstring), its time [s] and the headroom 1 / ratio.

    Returns ``{"rule": {...}, "per_detector": {det: {joint: {...}}}, "worst": {det: {...}}}``;
    ``max_ratio`` is None when no collision-free sample remains.
    """
    t = result.log.time_s
    mask = collision_free_mask(result, labels, guard_s)
    period = result.log.sample_period_s
    considered = float(np.count_nonzero(mask)) * period
    after_warmup = max(result.log.duration_s + period - result.warmup_end_s, 0.0)
    per: dict[str, dict[str, Any]] = {}
    worst: dict[str, Any] = {}
    for d in DETECTORS:
        if d not in result.ratios:
            continue
        ratios = np.asarray(result.ratios[d], dtype=np.float64)
        per[d] = {}
        best: tuple[float, str, float] | None = None
        for j, name in enumerate(result.log.joint_names):
            r = np.where(mask & np.isfinite(ratios[:, j]), ratios[:, j], -np.inf)
            k = int(np.argmax(r)) if r.size else 0
            if r.size == 0 or not np.isfinite(r[k]):
                per[d][name] = {"max_ratio": None, "t_s": None, "headroom": None}
                continue
            m = float(r[k])
            per[d][name] = {
                "max_ratio": m,
                "t_s": float(t[k]),
                "headroom": (1.0 / m) if m > 0 else None,
            }
            if best is None or m > best[0]:
                best = (m, name, float(t[k]))
        worst[d] = (
            {"max_ratio": best[0], "joint": best[1], "t_s": best[2]}
            if best
            else {"max_ratio": None, "joint": None, "t_s": None}
        )
    return {
        "rule": {
            "after_warmup_s": result.warmup_end_s,
            "guard_s": guard_s,
            "excludes": "every detected event of any detector"
            + (" and every labelled contact" if labels is not None else "")
            + f", each widened by {guard_s} s on both sides",
            "considered_s": considered,
            "considered_fraction": considered / after_warmup if after_warmup > 0 else 0.0,
        },
        "per_detector": per,
        "worst": worst,
    }


# --------------------------------------------------------------------------- caveats


def _share(part_s: float, total_s: float) -> str:
    return f", {100 * part_s / total_s:.0f} % of the log" if total_s > 0 else ""


def _epoch_text(t0_ns: int) -> str:
    """`` (= <UTC time> if it is Unix time)`` for clocks that look like epoch ns, else ""."""
    if not isinstance(t0_ns, int) or t0_ns < 10**17:  # before 1973: not an epoch clock
        return ""
    when = dt.datetime.fromtimestamp(t0_ns // 10**9, tz=dt.UTC)
    ms = (t0_ns // 10**6) % 1000
    return f" (= {when:%Y-%m-%d %H:%M:%S}.{ms:03d} UTC if it is Unix time)"


def _poor_fit(result: DetectionResult) -> list[tuple[str, float, str]]:
    """Joints whose model error (hold-out part when there is one, else the fit) exceeds
    :data:`POOR_FIT` of the torque RMS: (joint, ratio, where)."""
    per = ((result.model or {}).get("fit") or {}).get("joints")
    if not isinstance(per, dict):
        return []
    part, where = (per.get("holdout"), " on held-out data") if per.get("holdout") else \
        (per.get("fit"), "")
    out = []
    for j in result.log.joint_names:
        rel = ((part or {}).get(j) or {}).get("rms_rel_torque_rms")
        if isinstance(rel, int | float) and rel > POOR_FIT:
            out.append((j, float(rel), where))
    return out


#: A counted event of adaptive or static_loading at least this long gets a caveat [s].


def caveats(result: DetectionResult, tl: dict[str, Any]) -> list[dict[str, str]]:
    """Plain-language caveats an auditor must read before the numbers (code, text)."""
    out: list[dict[str, str]] = []
    cfg = result.config or {}
    calib = cfg.get("calibration") or {}
    if not result.calibrated:
        out.append(
            {
                "code": "uncalibrated",
                "text": (
                    "UNCALIBRATED: the thresholds were set from this log's own statistics "
                    f"({calib.get('margin_rule') or 'robust rule'}: {UNCALIBRATED_MARGIN:g} × the "
                    f"{UNCALIBRATED_QUANTILE:g}-quantile of its {UNCALIBRATED_BLOCK_S:g} s "
                    "maxima), not calibrated on separate collision-free logs. Only contacts "
                    "standing well above the log's own motion are found, and the events below "
                    "are not what the robot would have detected online; run `impactcli "
                    "calibrate` on collision-free logs and re-run with --config."
                ),
            }
        )
    elif calib.get("weak"):
        rule = calib.get("margin_rule") or "unknown rule"
        margins = calib.get("margins") or {}
        capped = sorted({d for d, m in margins.items() if max(m.values(), default=0) >= MAX_MARGIN})
        if rule == "fixed-single-log":
            why = ("the thresholds come from a single collision-free log with a fixed 1.5× "
                   "margin, not a leave-one-out margin over several logs.")
        else:
            why = ("the collision-free logs disagreed: the leave-one-out margin hit its cap of "
                   f"{MAX_MARGIN:g}× ({', '.join(capped) or 'some detector'}), so a log like "
                   "the most different one may still raise alarms.")
        out.append({"code": "weak-calibration", "text": f"Weak calibration ({rule}): {why}"})
    if result.model_source == "identified-from-log":
        out.append(
            {
                "code": "model-from-log",
                "text": (
                    "The rigid model was identified from this very log (an offline convenience): "
                    "its residual is smaller than a model made from other logs would give."
                ),
            }
        )
    poor = _poor_fit(result)
    if poor:
        out.append({"code": "model-poor-fit", "text": (
            "The rigid model explains the measured torque poorly on "
            + "; ".join(f"{j} (RMS error {100 * r:.0f} % of the torque RMS{where})"
                        for j, r, where in poor)
            + ": its residual carries that model error, so the thresholds there are high "
            "and small contacts can hide below them.")})
    unexcited = ((result.model or {}).get("fit") or {}).get("unexcited_parameters") or []
    if unexcited:
        out.append({"code": "model-unexcited", "text": (
            f"The log used for identification did not excite {len(unexcited)} model "
            f"parameter(s) ({', '.join(map(str, unexcited[:6]))}"
            + (", …" if len(unexcited) > 6 else "") + "); they were fixed at 0, so motions "
            "that excite them raise the residual.")})
    if result.reference_source == "measured":
        out.append(
            {
                "code": "reference-missing",
                "text": (
                    "No controller reference was logged: the adaptive detector's inputs (sign of "
                    "the reference velocity and the reference acceleration, Table I) were taken "
                    "from the causally filtered MEASURED position. A contact changes the measured "
                    "motion too, so the adaptive detector can partly absorb it."
                ),
            }
        )
    n_warm = sum(1 for e in result.events if e.in_warmup)
    out.append(
        {
            "code": "warmup",
            "text": (
                f"Warm-up: the first {result.warmup_end_s:.3f} s (latest over joints"
                f"{_share(result.warmup_end_s, result.log.duration_s)}) are the adaptive "
                "estimator's convergence; a contact in that interval may go undetected. "
                + (
                    f"{n_warm} alarm(s) started in it: listed, not counted."
                    if n_warm
                    else "No alarm started in it."
                )
            ),
        }
    )
    if not result.torque_filtered:
        out.append(
            {
                "code": "torque-unfiltered",
                "text": (
                    "The measured torque was not passed through the estimate's causal filter: the "
                    "residual's high-frequency floor (and the thresholds) are higher than they"
                    " need be."
                ),
            }
        )
    fg = result.filter_gain or {}
    freqs = list(fg.get("frequencies_hz") or [])
    blind = []
    for joint in result.log.joint_names:
        gains = (fg.get("gain") or {}).get(joint) or []
        low = [
            (f, g)
            for f, g in zip(freqs, gains, strict=False)
            if f is not None and g is not None and f <= 10.0 and g < LOW_GAIN
        ]
        if low:
            f, g = low[-1]  # the highest such frequency
            blind.append(f"{joint} {100 * g:.0f} % at {f:g} Hz")
    if blind:
        out.append(
            {
                "code": "filter-blind",
                "text": (
                    "The adaptive filter G(z) passes little of slow signals ("
                    + "; ".join(blind)
                    + "): slowly building contacts vanish from its residual; only the"
                      " static-loading "
                    "detector covers them (README: the method as implemented)."
                ),
            }
        )
    long_ev = [e for e in result.events if not e.in_warmup
               and e.t_end - e.t_start >= LONG_EVENT_S and e.detector != "static_baseline"]
    if long_ev:
        e = max(long_ev, key=lambda x: x.t_end - x.t_start)
        out.append({
            "code": "long-event",
            "text": (
                f"{len(long_ev)} event(s) of the product's detectors last {LONG_EVENT_S:g} s or "
                f"more (the longest: {e.detector}, {e.t_start:.1f}–{e.t_end:.1f} s). A load "
                "that persists is either a real one (a clamp, a held object) or a model that "
                "does not fit this log (an unknown payload, a changed robot): if the robot "
                "changed, re-identify (`detect --config C --model-from-log`) or recalibrate."
            ),
        })
    for rep in tl["input"].get("repairs") or []:
        out.append({"code": "repair", "text": f"Input repaired while reading: {rep}"})
    return out


# --------------------------------------------------------------------------- evaluation


def _evaluate(result: DetectionResult, labels: Labels) -> dict[str, Any]:
    """The detection-quality evaluation and threshold sweep (:mod:`impactcli.evaluate`,
    imported lazily); ``status`` is ``unavailable`` when that module is absent."""
    out: dict[str, Any] = {
        "status": "done",
        "labels_path": labels.path,
        "n_labelled": len(labels.events),
        "evaluation": None,
        "sweep": None,
        "notes": [],
    }
    from .. import evaluate as ev

    evaluation = ev.evaluate_result(result, labels)
    out["evaluation"] = _to_mapping(evaluation)
    try:
        rows = ev.sweep_thresholds(result, labels, SWEEP_SCALES)
    except ImpactError as err:  # e.g. a run whose config lacks the event settings
        out["notes"].append(f"No threshold sweep: {err}")
        return out
    out["sweep"] = {"scales": list(SWEEP_SCALES), **ev.sweep_to_dict(rows)}
    return out


# --------------------------------------------------------------------------- document


def log_section(result: DetectionResult, labels: Labels | None = None) -> dict[str, Any]:
    """The JSON facts of one log: the timeline's fields plus margins, caveats, evaluation."""
    tl = timeline_dict(result)
    period = result.log.sample_period_s
    events = []
    for e, d in zip(result.events, tl["events"], strict=True):
        events.append({**d, "duration_s": event_duration_s(e, period)})
    sec: dict[str, Any] = {k: v for k, v in tl.items() if k not in ("schema_version", "tool")}
    sec["stem"] = log_stem(result.log.source.path)
    sec["events"] = events
    sec["timeline_schema_version"] = tl["schema_version"]
    sec["false_alarm_margin"] = false_alarm_margins(result, labels)
    sec["caveats"] = caveats(result, tl)
    sec["labels"] = (
        None if labels is None else {"path": labels.path, "n_events": len(labels.events)}
    )
    sec["quality"] = None if labels is None else _evaluate(result, labels)
    return _clean(sec)  # type: ignore[no-any-return]


def summary_row(sec: dict[str, Any]) -> dict[str, Any]:
    """One row of the fleet summary from a log section."""
    inp = sec["input"]
    return {
        "stem": sec["stem"],
        "path": inp["path"],
        "sha256": inp["sha256"],
        "duration_s": inp["duration_s"],
        "sample_rate_hz": inp["sample_rate_hz"],
        "n_joints": len(inp["joints"]),
        "calibrated": sec["calibrated"],
        "online_equivalent": sec["replay"]["online_equivalent"],
        "reference_source": sec["replay"]["reference_source"],
        "events": sec["summary"],
        "worst_margin": {d: w["max_ratio"] for d, w in sec["false_alarm_margin"]["worst"].items()},
        "caveats": [c["code"] for c in sec["caveats"]],
        "quality": _quality_summary(sec.get("quality")),
    }


def _quality_summary(q: dict[str, Any] | None) -> dict[str, Any] | None:
    """Headline of the evaluation for the fleet table: the product alarm's score."""
    if not q or not q.get("evaluation"):
        return None
    sc = (q["evaluation"].get("detectors") or {}).get("product")
    if not sc:
        return None
    return {
        "detector": "product",
        "detected": sc["detected"],
        "n_contacts": sc["n_contacts"],
        "false_alarms": sc["false_alarms"],
    }


def report_dict(
    sections: Sequence[dict[str, Any]], failed: Sequence[tuple[str, str]] = ()
) -> dict[str, Any]:
    """The report as a JSON-ready mapping (schemas/report.schema.json).

    Args:
        sections: one :func:`log_section` per log, in report order.
        failed: (input path, one-line error) of inputs that could not be analysed.
    """
    logs = list(sections)
    doc = {
        "schema_version": SCHEMA_VERSION,
        "tool": {"name": TOOL_NAME, "version": __version__},
        "parameters": {
            "guard_s": GUARD_S,
            "event_window_s": EVENT_WINDOW_S,
            "whole_log_buckets": WHOLE_LOG_BUCKETS,
            "max_event_figures": MAX_EVENT_FIGURES,
            "clip_factor": CLIP_FACTOR,
        },
        "summary": [summary_row(s) for s in logs],
        "logs": logs,
        "failed": [{"path": p, "error": e} for p, e in failed],
    }
    return _clean(doc)  # type: ignore[no-any-return]


def report_json(doc: dict[str, Any]) -> str:
    """Deterministic JSON text of a report mapping."""
    return json.dumps(doc, indent=1, sort_keys=True, allow_nan=False, ensure_ascii=False) + "\n"


# --------------------------------------------------------------------------- HTML

CSS = """
@page { size: A4; margin: 12mm 11mm 14mm 11mm; }
* { box-sizing: border-box; }
body { font-family: "DejaVu Sans", "Liberation Sans", Arial, Helvetica, sans-serif;
  color: #111; background: #fff; margin: 0 auto; padding: 18px 22px; max-width: 1180px;
  font-size: 13px; line-height: 1.42; }
h1 { font-size: 22px; margin: 0 0 4px 0; }
h2 { font-size: 18px; margin: 18px 0 6px 0; border-bottom: 2px solid #333; padding-bottom: 2px; }
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
.caveats { border: 2px solid #b9770e; padding: 6px 12px; margin: 8px 0 12px 0; }
.caveats h3 { margin-top: 2px; color: #7e5109; }
.caveats li { margin: 3px 0; }
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
nav ol { margin: 4px 0 8px 0; }
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

BAND_EVENT = "#f3b6ae"
ALARM_ZONE = "#fdf1ef"
BAND_WARMUP = "#e4e4e4"
BAND_LABEL = "#fde7cf"


def _e(x: Any) -> str:
    """HTML-escaped text (NUL dropped: not valid in HTML, and it marks NUM_TOKEN)."""
    return html.escape(str(x).replace("\x00", ""), quote=True)


def _f(v: Any, digits: int = 3) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            return "—"
        return f"{v:.{digits}f}"
    return _e(v)


def _g(v: Any) -> str:
    """A compact general number."""
    if isinstance(v, bool) or v is None:
        return _f(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "—" if not math.isfinite(v) else f"{v:.4g}"
    return _e(v)


def _ratio_cell(r: float | None, note: str | None = None) -> str:
    if r is None:
        return '<td class="num muted">—</td>'
    cls = "bad" if r >= 1.0 else ("warn" if r >= 0.8 else "good")
    extra = f' <span class="note">{_e(note)}</span>' if note else ""
    return f'<td class="num {cls}">{r:.2f}{extra}</td>'


def _kv_table(rows: Sequence[tuple[str, str]]) -> str:
    body = "".join(f"<tr><th>{_e(k)}</th><td>{v}</td></tr>" for k, v in rows)
    return f'<table class="kv">{body}</table>'


def _settings_table(cfg: dict[str, Any]) -> str:
    """Every config value, one row per section: ``key=value`` with nested keys dotted and
    values as compact JSON (the JSON report holds the same mapping)."""
    def flat(d: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
        out: list[tuple[str, Any]] = []
        for k in sorted(d):
            v = d[k]
            if isinstance(v, dict) and v:
                out += flat(v, f"{prefix}{k}.")
            else:
                out.append((f"{prefix}{k}", v))
        return out

    rows = []
    for section in sorted(cfg):
        v = cfg[section]
        if isinstance(v, dict):
            items = flat(v)
            text = "; ".join(
                f"{k}={json.dumps(x, sort_keys=True, ensure_ascii=False)}" for k, x in items)
            rows.append((section, f'<span class="mono small">{_e(text or "{}")}</span>'))
        else:
            rows.append((section, f'<span class="mono small">{_e(json.dumps(v))}</span>'))
    return _kv_table(rows)


def _json_pre(obj: Any, max_str: int = 240) -> str:
    def shorten(x: Any) -> Any:
        if isinstance(x, dict):
            return {k: shorten(v) for k, v in x.items()}
        if isinstance(x, list):
            return [shorten(v) for v in x]
        if isinstance(x, str) and len(x) > max_str:
            return x[:80] + f"… ({len(x)} characters, in the JSON report)"
        return x

    return (
        f"<pre>{_e(json.dumps(shorten(obj), indent=1, sort_keys=True, ensure_ascii=False))}</pre>"
    )


def _generator_cell(replay: dict[str, Any]) -> str:
    """Which residual generator each joint used and why (timeline 2.0), or the one name a
    1.0 timeline records."""
    per = replay.get("generator") or {}
    if not per:
        return _e(replay.get("residual_generator", "—"))
    rows = "".join(
        f"<li><b>{_e(j)}</b>: {_e(g.get('generator'))} — {_e(g.get('reason'))}"
        + (f" (<code>{_e(g['residual'])}</code>)" if g.get("residual") else "") + "</li>"
        for j, g in per.items())
    return f'<ul style="margin:0;padding-left:1.2em">{rows}</ul>'


def _fit_table(fit: dict[str, Any], joints: Sequence[str]) -> str:
    """The model's fit statistics (impactcli.model.identify layout: per joint RMS of the
    torque error on the fitted and the held-back part); any other layout generically."""
    per = fit.get("joints") if isinstance(fit.get("joints"), dict) else None
    if not per or not isinstance(per.get("fit"), dict):
        return _generic_fit_table(fit, joints)
    fitj = per.get("fit") or {}
    hold = per.get("holdout") or {}
    robust = fit.get("robust") or {}
    down = robust.get("downweighted_fraction") or {}
    cols = [("fit RMS error [N·m]", lambda j: (fitj.get(j) or {}).get("rms_nm")),
            ("… / torque RMS", lambda j: (fitj.get(j) or {}).get("rms_rel_torque_rms")),
            ("hold-out RMS error [N·m]", lambda j: (hold.get(j) or {}).get("rms_nm")),
            ("… / torque RMS", lambda j: (hold.get(j) or {}).get("rms_rel_torque_rms")),
            ("torque RMS [N·m]", lambda j: (fitj.get(j) or {}).get("torque_rms_nm")),
            ("down-weighted fraction", down.get)]
    head = "".join(f'<th class="num">{_e(c)}</th>' for c, _ in cols)
    body = "".join(
        f"<tr><th>{_e(j)}</th>" + "".join(f'<td class="num">{_g(fn(j))}</td>' for _, fn in cols)
        + "</tr>" for j in joints)
    unexc = fit.get("unexcited_parameters") or []
    rows = [("method", _e(fit.get("method", "—"))),
            ("samples fitted / held out", f"{_f(fit.get('n_samples_fit'))} / "
                                          f"{_f(fit.get('n_samples_holdout'))}"
             + ("" if hold else ' <span class="warn">(not validated on held-out data)</span>')),
            ("condition number", _g(fit.get("condition_number"))),
            ("unexcited parameters (fixed at 0)",
             _e(", ".join(map(str, unexc))) if unexc else "none")]
    opts = fit.get("options")
    if isinstance(opts, dict) and opts:
        rows.append(("identification options", '<span class="small">' + _e(", ".join(
            f"{k}={v}" for k, v in sorted(opts.items()))) + "</span>"))
    return (f'<div class="wide"><table><thead><tr><th>joint</th>{head}</tr></thead>{body}</table>'
            f"</div>{_kv_table(rows)}")


def _params_table(params: list[dict[str, Any]], joints: Sequence[str]) -> str:
    """Parameters ``<joint>.<name>`` as a joints × names matrix; other names listed after."""
    matrix: dict[str, dict[str, Any]] = {}
    names: list[str] = []
    rest: list[dict[str, Any]] = []
    for q in params:
        joint, _, name = str(q.get("name", "")).partition(".")
        if joint in joints and name:
            matrix.setdefault(joint, {})[name] = q.get("value")
            if name not in names:
                names.append(name)
        else:
            rest.append(q)
    out = ""
    if matrix:
        head = "".join(f'<th class="num">{_e(n)}</th>' for n in names)
        body = "".join(f"<tr><th>{_e(j)}</th>" + "".join(
            f'<td class="num">{_g(matrix.get(j, {}).get(n))}</td>' for n in names) + "</tr>"
            for j in joints if j in matrix)
        out += (f'<div class="wide"><table><thead><tr><th>joint</th>{head}</tr></thead>'
                f"{body}</table></div>")
    if rest:
        out += ('<table><thead><tr><th>parameter</th><th class="num">value</th></tr></thead>'
                + "".join(f"<tr><td><code>{_e(q.get('name'))}</code></td>"
                          f'<td class="num">{_g(q.get("value"))}</td></tr>' for q in rest)
                + "</table>")
    return out + '<p class="small muted">SI units: kg·m², kg·m, N·m·s/rad, N·m.</p>'


def _generic_fit_table(fit: dict[str, Any], joints: Sequence[str]) -> str:
    """The model's fit statistics: per-joint quantities as columns, scalars as rows."""
    if not fit:
        return '<p class="muted">The model records no fit statistics.</p>'
    per_joint: dict[str, dict[str, Any]] = {}
    scalars: list[tuple[str, Any]] = []
    other: dict[str, Any] = {}
    for k, v in fit.items():
        if isinstance(v, dict) and v and set(v) <= set(joints):
            per_joint[k] = v
        elif (
            isinstance(v, list)
            and len(v) == len(joints)
            and all(isinstance(x, int | float) for x in v)
        ):
            per_joint[k] = dict(zip(joints, v, strict=True))
        elif isinstance(v, int | float | str | bool) or v is None:
            scalars.append((k, v))
        elif isinstance(v, list) and len(v) > 12:
            scalars.append((k, f"{len(v)} values (in the JSON report)"))
        else:
            other[k] = v
    out = []
    if per_joint:
        head = "".join(f'<th class="num">{_e(k)}</th>' for k in per_joint)
        body = "".join(
            f"<tr><th>{_e(j)}</th>"
            + "".join(f'<td class="num">{_g(per_joint[k].get(j))}</td>' for k in per_joint)
            + "</tr>"
            for j in joints
        )
        out.append(f"<table><tr><th>joint</th>{head}</tr>{body}</table>")
    if scalars:
        out.append(_kv_table([(k, _g(v)) for k, v in scalars]))
    if other:
        out.append(_json_pre(other))
    return "".join(out)


class _Ids:
    """Deterministic ids for SVG clip paths, unique in the document: one counter per log
    section, prefixed by the log's input index."""

    def __init__(self, prefix: str = "") -> None:
        self.prefix = prefix
        self.n = 0

    def __call__(self) -> str:
        self.n += 1
        return f"clip{self.prefix}{self.n}"


def _bands(
    result: DetectionResult, detector: str, joint: str, labels: Labels | None
) -> list[svgplot.Band]:
    bands = [svgplot.Band(0.0, result.warmup_end_s, BAND_WARMUP, "warm-up")]
    if labels is not None:
        bands += [
            svgplot.Band(
                c.start,
                c.end,
                BAND_LABEL,
                f"labelled {c.kind} {c.peak_force:g} N",
                outline=svgplot.ORANGE,
            )
            for c in labels.events
        ]
    bands += [
        svgplot.Band(e.t_start, e.t_end, BAND_EVENT, f"{e.detector} event")
        for e in result.events
        if e.detector == detector and joint in e.joints
    ]
    return bands


def _panel(
    result: DetectionResult,
    detector: str,
    j: int,
    *,
    lo: int,
    hi: int,
    buckets: int,
    title: str,
    labels: Labels | None,
    ids: _Ids,
    width: int,
    height: int,
) -> str:
    t = result.log.time_s
    stat, thr = statistic(result, detector, j)
    ts, ys = svgplot.envelope(t[lo:hi], stat[lo:hi], buckets)
    tt, yt = svgplot.envelope(t[lo:hi], thr[lo:hi], buckets)
    sname, tname = STAT_NAME[detector]
    chart = svgplot.Chart(
        title=title,
        x_range=(float(t[lo]), float(t[hi - 1])),
        series=(
            svgplot.Series(sname, ts, ys, svgplot.BLUE),
            svgplot.Series(tname, tt, yt, svgplot.RED, width=1.1, fill_above=ALARM_ZONE),
        ),
        bands=_bands(result, detector, result.log.joint_names[j], labels),
        y_unit="N·m",
        clip_factor=CLIP_FACTOR,
        clip_reference=tname,
    )
    return svgplot.render_chart(chart, width=width, height=height, chart_id=ids())


def _clusters(events: Sequence[Event]) -> list[list[int]]:
    """Group events (indices, by start) whose ±EVENT_WINDOW_S windows overlap, each group
    spanning at most MAX_CLUSTER_S."""
    order = sorted(range(len(events)), key=lambda i: (events[i].t_start, events[i].t_end, i))
    groups: list[list[int]] = []
    g_start = g_end = 0.0
    for i in order:
        e = events[i]
        if (
            groups
            and e.t_start - EVENT_WINDOW_S <= g_end + EVENT_WINDOW_S
            and max(g_end, e.t_end) - g_start <= MAX_CLUSTER_S
        ):
            groups[-1].append(i)
            g_end = max(g_end, e.t_end)
        else:
            groups.append([i])
            g_start, g_end = e.t_start, e.t_end
    return groups


def _section_html(
    num: str, result: DetectionResult, sec: dict[str, Any], labels: Labels | None, ids: _Ids
) -> str:
    """One log's section; ``num`` is its number in the report (or :data:`NUM_TOKEN`)."""
    inp = sec["input"]
    joints = list(inp["joints"])
    anchor = f"log{num}"
    p: list[str] = [f'<section class="log" id="{anchor}">', f"<h2>{num}. {_e(sec['stem'])}</h2>"]
    # caveats first
    p.append('<div class="caveats"><h3>Caveats — read before the numbers</h3><ul>')
    p.extend(f"<li>{_e(c['text'])}</li>" for c in sec["caveats"])
    p.append("</ul>")
    if sec.get("warnings"):
        prefix = f"{inp['path']}: "
        p.append('<h4>Warnings raised during the run (verbatim)</h4><ul class="small">')
        p.extend(f"<li>{_e(w[len(prefix):] if w.startswith(prefix) else w)}</li>"
                 for w in sec["warnings"])
        p.append("</ul>")
    p.append("</div>")
    # what was analysed
    p.append("<h3>What was analysed</h3>")
    p.append(
        _kv_table(
            [
                ("file", f"<code>{_e(inp['path'])}</code>"),
                ("sha256", f'<code class="hash">{_e(inp["sha256"])}</code>'),
                ("format", _e(inp.get("format", "—"))),
                ("samples", _f(inp.get("n_samples"))),
                ("duration", f"{inp['duration_s']:.3f} s"),
                ("sample rate", f"{inp['sample_rate_hz']:.2f} Hz (median)"),
                ("joints", _e(", ".join(joints))),
                (
                    "first sample (t0_ns)",
                    f"{inp['t0_ns']} ns on the log's own clock{_epoch_text(inp['t0_ns'])}; "
                    "times below are seconds since this sample",
                ),
                ("torque source", _e(inp["torque_source"])),
                ("time source", _e(inp["time_source"])),
                (
                    "read options",
                    f"<code>{_e(json.dumps(inp.get('read_options') or {}, sort_keys=True))}</code>",
                ),
                ("repairs", _e("; ".join(inp.get("repairs") or []) or "none")),
            ]
        )
    )
    # with what
    model = sec["model"] or {"source": "none", "sha256": None, "model": {}}
    cfg = sec["config"] or {}
    calib = cfg.get("calibration") or {}
    replay = sec["replay"]
    p.append("<h3>With what</h3>")
    calib_logs = calib.get("logs") or []
    p.append(
        _kv_table(
            [
                ("tool", f"{_e(TOOL_NAME)} {_e(__version__)}"),
                (
                    "calibrated thresholds",
                    (
                        '<span class="good">yes</span>'
                        if sec["calibrated"]
                        else '<span class="bad">no — uncalibrated run</span>'
                    ),
                ),
                ("margin rule", _e(calib.get("margin_rule") or "—")),
                (
                    "calibrated on",
                    "<br>".join(
                        f'<code>{_e(lg.get("path"))}</code> <code class="hash'
                        f' small">{_e(lg.get("sha256"))}</code>'
                        for lg in calib_logs
                    )
                    or "—",
                ),
                ("model", f"{_e(model['model'].get('kind', '?'))}, source: {_e(model['source'])}"
                 if model["model"] else "none (every joint read the controller's channels)"),
                ("model sha256", f'<code class="hash">{_e(model["sha256"] or "—")}</code>'),
                (
                    "thresholds belong to model",
                    f'<code class="hash">{_e(calib.get("model_sha256") or "—")}</code>',
                ),
                ("online-equivalent replay", _f(replay["online_equivalent"])),
                (
                    "reference",
                    _e(replay["reference_source"])
                    + (
                        ""
                        if replay["reference_source"] == "reference"
                        else ' <span class="warn">(no logged reference)</span>'
                    ),
                ),
                ("threshold inputs", _e(replay.get("threshold_inputs") or "—")),
                ("torque filtered like the estimate", _f(replay["torque_filtered"])),
                ("residual generator", _generator_cell(replay)),
                ("warm-up end", f"{sec['warmup_end_s']:.3f} s (latest over joints)"),
            ]
        )
    )
    if model["model"]:
        p.append("<h4>Model fit quality</h4>")
        p.append(_fit_table(model["model"].get("fit") or {}, joints))
    params = model["model"].get("parameters")
    if isinstance(params, list) and params:
        p.append("<h4>Model parameters</h4>" + _params_table(params, joints))
    # thresholds & filter gain per joint
    fg = sec.get("filter_gain") or {}
    freqs = list(fg.get("frequencies_hz") or [])
    gains = fg.get("gain") or {}
    head = (
        '<tr><th>joint</th><th class="num">v_stat [N·m]</th><th class="num">v0 [N·m]</th>'
        '<th class="num">vL [N·m]</th><th class="num">warm-up end [s]</th>'
        + "".join(f'<th class="num">|G| at {f:.3g} Hz</th>' for f in freqs)
        + "</tr>"
    )
    rows = []
    for j in joints:
        th = sec["thresholds"].get(j, {})
        g = gains.get(j) or []
        rows.append(
            f"<tr><th>{_e(j)}</th>"
            + "".join(f'<td class="num">{_g(th.get(x))}</td>' for x in ("v_stat", "v0", "vL"))
            + f'<td class="num">{_f((sec.get("warmup_per_joint_s") or {}).get(j))}</td>'
            + "".join(f'<td class="num">{_g(x)}</td>' for x in g)
            + "</tr>"
        )
    p.append("<h4>Thresholds and adaptive filter gain per joint</h4>")
    p.append(f'<div class="wide"><table>{head}{"".join(rows)}</table></div>')
    p.append("<h4>Full detector configuration</h4>")
    p.append(_settings_table({k: v for k, v in cfg.items() if k != "model"}))
    if cfg.get("model") is not None:
        p.append(
            '<p class="small muted">The config also embeds its model (sha256 above); '
            "it is in the JSON report.</p>"
        )
    # result
    p.append("<h3>Result</h3>")
    summ = sec["summary"]
    p.append(
        '<table><tr><th>detector</th><th class="num">events (after warm-up)</th>'
        '<th class="num">in warm-up (not counted)</th></tr>'
        + "".join(
            f'<tr><th>{_e(DETECTOR_TITLE.get(d, d))}</th><td class="num">{summ[d]["events"]}</td>'
            f'<td class="num">{summ[d]["in_warmup"]}</td></tr>'
            for d in DETECTORS
            if d in summ
        )
        + "</table>"
    )
    events = sec["events"]
    if events:
        rows = []
        for n, ev in enumerate(events, 1):
            peaks = ", ".join(f"{_e(j)}: {v:.3g}" for j, v in ev["peak_residual"].items())
            cls = ' class="warmup"' if ev["in_warmup"] else ""
            rows.append(
                f'<tr{cls} id="{anchor}-ev{n}"><td class="num">{n}</td><td'
                f' class="num">{ev["t_start"]:.3f}</td>'
                f'<td class="num">{ev["t_end"]:.3f}</td><td'
                f' class="num">{1000 * ev["duration_s"]:.0f}</td>'
                f"<td>{_e(ev['detector'])}</td><td>{_e(', '.join(ev['joints']))}</td>"
                f'<td class="num">{ev["peak_ratio"]:.2f}</td><td class="num">{peaks}</td>'
                f"<td>{'yes' if ev['in_warmup'] else ''}</td></tr>"
            )
        p.append(
            '<h4>Events</h4><div class="wide"><table><thead><tr><th class="num">#</th><th'
            ' class="num">start [s]</th>'
            '<th class="num">end [s]</th><th class="num">duration [ms]</th><th>detector</th>'
            '<th>joints (first to fire first)</th><th class="num">peak ratio</th>'
            '<th class="num">peak residual [N·m]</th><th>in warm-up</th></tr></thead>'
            + "".join(rows)
            + "</table></div>"
        )
    else:
        p.append("<p><b>No event</b> from any detector.</p>")
    # margins
    fam = sec["false_alarm_margin"]
    rule = fam["rule"]
    dets = [d for d in DETECTORS if d in fam["per_detector"]]
    p.append("<h4>False-alarm margin on collision-free stretches</h4>")
    p.append(
        "<p>Largest statistic / threshold ratio after warm-up "
        f"({rule['after_warmup_s']:.3f} s), excluding {_e(rule['excludes'])}: "
        f"{rule['considered_s']:.1f} s considered ({100 * rule['considered_fraction']:.0f} % of "
        "the time after warm-up). Below 1 the detector stayed silent there; 1 / ratio is the "
        "factor by which its threshold could shrink before the first false alarm. "
        '<span class="good">&lt; 0.8</span> · <span class="warn">0.8–1</span> · '
        '<span class="bad">≥ 1</span>.</p>'
    )
    head = "".join(f'<th class="num">{_e(d)}</th>' for d in dets)
    rows = []
    for j in joints:
        cells = []
        for d in dets:
            m = fam["per_detector"][d].get(j) or {}
            cells.append(_ratio_cell(m.get("max_ratio")))
        times = "; ".join(
            f"{d}: {fam['per_detector'][d][j]['t_s']:.2f}"
            for d in dets
            if (fam["per_detector"][d].get(j) or {}).get("t_s") is not None
        )
        rows.append(f'<tr><th>{_e(j)}</th>{"".join(cells)}<td class="small">{_e(times)}</td></tr>')
    p.append(f"<table><tr><th>joint</th>{head}<th>at time [s]</th></tr>{''.join(rows)}</table>")
    # quality
    q = sec.get("quality")
    if q is not None:
        p.append(_quality_html(q))
    # plots
    p.append("<h3>Statistic against threshold over the whole log</h3>")
    p.append(
        '<p class="small">Blue: the detector\'s statistic; red: its threshold — the lightly '
        'shaded area above it is where the detector alarms. '
        f'<span class="legend-key" style="background:{BAND_EVENT}"></span>events of that detector '
        f'<span class="legend-key" style="background:{BAND_WARMUP}"></span>warm-up'
        + (
            '<span class="legend-key"'
            f' style="background:{BAND_LABEL};border-color:{svgplot.ORANGE}"></span>'
            "labelled contacts"
            if labels is not None
            else ""
        )
        + f". Long logs are drawn as a min/max envelope of {WHOLE_LOG_BUCKETS} buckets, so no "
        f"peak is hidden; the y axis is capped at {CLIP_FACTOR:g}× the threshold (the true "
        "maximum is then written in red).</p>"
    )
    n = result.log.n_samples
    for j, name in enumerate(joints):
        panels = "".join(
            _panel(result, d, j, lo=0, hi=n, buckets=WHOLE_LOG_BUCKETS,
                   title=f"{name} · {DETECTOR_TITLE[d]}", labels=labels, ids=ids,
                   width=1000, height=150)
            for d in DETECTORS
        )
        p.append(f"<figure>{panels}<figcaption>Joint {_e(name)}, whole log.</figcaption></figure>")
    # event figures
    ev_objs = result.events
    if ev_objs:
        p.append(f"<h3>Around every event (±{EVENT_WINDOW_S:g} s)</h3>")
        groups = _clusters(ev_objs)
        t = result.log.time_s
        for gi, g in enumerate(groups):
            if gi >= MAX_EVENT_FIGURES:
                rest = sum(len(x) for x in groups[gi:])
                p.append(
                    f'<p class="warn">{rest} further event(s) in {len(groups) - gi} window(s) '
                    f"are not plotted (at most {MAX_EVENT_FIGURES} figures per log); they are "
                    "listed in the event table and the JSON report.</p>"
                )
                break
            t_a = min(ev_objs[i].t_start for i in g) - EVENT_WINDOW_S
            t_b = max(ev_objs[i].t_end for i in g) + EVENT_WINDOW_S
            lo = int(np.searchsorted(t, t_a, side="left"))
            hi = max(int(np.searchsorted(t, t_b, side="right")), lo + 2)
            hi = min(hi, n)
            lo = min(lo, hi - 2)
            dets_g = [d for d in DETECTORS if any(ev_objs[i].detector == d for i in g)]
            joints_g = [jn for jn in joints if any(jn in ev_objs[i].joints for i in g)]
            nums = [i + 1 for i in g]
            panels = "".join(
                _panel(result, d, joints.index(jn), lo=lo, hi=hi, buckets=EVENT_BUCKETS,
                       title=f"{jn} · {DETECTOR_TITLE[d]}", labels=labels, ids=ids,
                       width=520, height=150)
                for jn in joints_g
                for d in dets_g
            )
            desc = "; ".join(
                f"#{i + 1} {ev_objs[i].detector} {ev_objs[i].t_start:.3f}–{ev_objs[i].t_end:.3f} s "
                f"on {', '.join(ev_objs[i].joints)} (peak ratio {ev_objs[i].peak_ratio:.2f}"
                + (", in warm-up" if ev_objs[i].in_warmup else "")
                + ")"
                for i in g
            )
            p.append(
                f'<figure><div class="grid2">{panels}</div><figcaption>Event'
                f"{'s' if len(nums) > 1 else ''} {desc}.</figcaption></figure>"
            )
    p.append("</section>")
    return "".join(p)


def _ms(v: Any) -> str:
    return "—" if not isinstance(v, int | float) else f"{1000 * v:.0f}"


def _quality_html(q: dict[str, Any]) -> str:
    """The detection-quality section: per-detector scores, per-contact outcomes, the
    threshold sweep (table, ROC-style plot, verdict)."""
    p = [
        "<h3>Detection quality against labels</h3>",
        f"<p>Labels: <code>{_e(q['labels_path'])}</code>, {q['n_labelled']} labelled "
        "contact(s).</p>",
    ]
    p.extend(f'<p class="warn">{_e(n)}</p>' for n in q.get("notes") or [])
    ev = q.get("evaluation")
    if ev:
        nc = ev.get("n_contacts") or {}
        tol = ev.get("tolerance") or {}
        p.append(
            f"<p>{nc.get('counted', 0)} contact(s) counted, {nc.get('in_warmup', 0)} in warm-up "
            f"(not counted), {nc.get('outside_log', 0)} outside the log. Matching rule: "
            f"{_e(tol.get('rule', ''))} (pre_s = {_g(tol.get('pre_s'))} s, post_s = "
            f"{_g(tol.get('post_s'))} s). Collision-free time after warm-up: "
            f"{_g(ev.get('collision_free_s'))} s. <i>product</i> = adaptive OR static_loading, "
            "the product's alarm.</p>"
        )
        dets = list(ev.get("detectors") or {})
        sc = ev["detectors"]

        def frac(s: dict[str, Any]) -> str:
            return f"{s['detected']}/{s['n_contacts']}"

        metrics: list[tuple[str, Any]] = [
            ("counted events", lambda s: str(s["n_events"])),
            ("contacts detected", frac),
            ("false alarms", lambda s: str(s["false_alarms"])),
            ("false alarms per hour", lambda s: _g(s["false_alarms_per_hour"])),
            ("median delay [ms]", lambda s: _ms(s["delay_median_s"])),
            ("max delay [ms]", lambda s: _ms(s["delay_max_s"])),
            ("smallest detected force [N]", lambda s: _g(s["min_detected_force"])),
            ("largest missed force [N]", lambda s: _g(s["max_missed_force"])),
        ]
        head = "".join(f'<th class="num">{_e(d)}</th>' for d in dets)
        body = "".join(
            f"<tr><th>{_e(name)}</th>"
            + "".join(f'<td class="num">{fn(sc[d])}</td>' for d in dets)
            + "</tr>"
            for name, fn in metrics
        )
        p.append(
            f'<div class="wide"><table><tr><th>per detector</th>{head}</tr>{body}</table></div>'
        )
        contacts = ev.get("contacts") or []
        if contacts:
            cdets = list(contacts[0].get("detected") or {})
            rows = []
            for c in contacts[:300]:
                cells = []
                for d in cdets:
                    if c["detected"].get(d):
                        cells.append(f'<td class="num good">hit {_ms(c["delay_s"].get(d))} ms</td>')
                    else:
                        on = " (alarm already on)" if c["alarm_on_at_onset"].get(d) else ""
                        cls = "bad" if c["status"] == "counted" else "muted"
                        cells.append(f'<td class="num {cls}">missed{on}</td>')
                rows.append(
                    f'<tr><td class="num">{c["index"] + 1}</td><td class="num">{c["start"]:.3f}'
                    '</td>'
                    f'<td class="num">{c["end"]:.3f}</td><td>{_e(c["kind"])}</td>'
                    f'<td class="num">{c["link"]}</td><td class="num">{_g(c["peak_force"])}</td>'
                    f"<td>{_e(c['status'])}</td>{''.join(cells)}</tr>"
                )
            more = (
                f'<p class="small muted">{len(contacts) - 300} more contacts in the JSON '
                "report.</p>"
                if len(contacts) > 300
                else ""
            )
            p.append(
                '<h4>Labelled contacts</h4><div class="wide"><table><thead><tr>'
                '<th class="num">#</th>'
                '<th class="num">start [s]</th><th class="num">end [s]</th><th>kind</th>'
                '<th class="num">link</th><th class="num">peak force [N]</th><th>status</th>'
                + "".join(f"<th>{_e(d)}</th>" for d in cdets)
                + "</tr></thead>"
                + "".join(rows)
                + f"</table></div>{more}"
            )
    sw = q.get("sweep")
    if sw:
        p.append(_sweep_html(sw))
    return "".join(p)


def _sweep_html(sw: dict[str, Any]) -> str:
    """The threshold sweep: verdict, a scale × detector table, an ROC-style plot."""
    rows = [r for r in sw.get("rows") or [] if isinstance(r, dict)]
    p = [
        "<h4>Threshold sweep — detectors compared at equal false alarms</h4>",
        "<p>Every threshold multiplied by a scale s (decision: statistic / threshold &gt; s; "
        "s = 1 is this run). Cells: contacts detected / counted, false alarms.</p>",
    ]
    if sw.get("verdict"):
        p.append(f"<p><b>Verdict:</b> {_e(sw['verdict'])}</p>")
    if not rows:
        return "".join(p)
    dets = list(dict.fromkeys(r["detector"] for r in rows))
    scales = sorted({r["scale"] for r in rows})
    zero = sw.get("at_zero_false_alarms") or {}
    cell: dict[tuple[str, float], dict[str, Any]] = {(r["detector"], r["scale"]): r for r in rows}
    body = []
    for s in scales:
        tds = []
        for d in dets:
            r = cell.get((d, s))
            if r is None:
                tds.append('<td class="num muted">—</td>')
                continue
            z = zero.get(d)
            mark = " good" if z is not None and z.get("scale") == s else ""
            tds.append(
                f'<td class="num{mark}">{r["detected"]}/{r["n_contacts"]}, '
                f"{r['false_alarms']} FA</td>"
            )
        body.append(f'<tr><th class="num">{s:g}</th>{"".join(tds)}</tr>')
    p.append(
        '<div class="wide"><table><thead><tr><th class="num">scale s</th>'
        + "".join(f'<th class="num">{_e(d)}</th>' for d in dets)
        + "</tr></thead>"
        + "".join(body)
        + "</table></div>"
    )
    p.append(
        '<p class="small">Green: the smallest scale from which on the detector stays '
        "free of false alarms (its zero-false-alarm point).</p>"
    )
    groups: dict[str, tuple[list[float], list[float]]] = {}
    for d in dets:
        pts = sorted(
            (float(r["false_alarms_per_hour"]), r["detected"] / r["n_contacts"])
            for r in rows
            if r["detector"] == d and r["n_contacts"] and r.get("false_alarms_per_hour") is not None
        )
        if pts:
            groups[d] = ([a for a, _ in pts], [b for _, b in pts])
    if groups:
        p.append(
            "<figure>"
            + svgplot.render_xy(
                "Threshold sweep", groups, "false alarms per hour", "fraction of contacts detected"
            )
            + "<figcaption>ROC-style: each point is one threshold scale.</figcaption></figure>"
        )
    return "".join(p)


def _summary_html(doc: dict[str, Any]) -> str:
    rows = []
    with_q = any(r.get("quality") for r in doc["summary"])
    for k, r in enumerate(doc["summary"]):
        qs = r.get("quality")
        qcell = (
            ""
            if not with_q
            else (
                '<td class="muted">no labels</td>'
                if not qs
                else f'<td class="num">{qs["detected"]}/{qs["n_contacts"]} hit, '
                f"{qs['false_alarms']} FA</td>"
            )
        )
        ev = r["events"]
        evcells = "".join(
            f'<td class="num">{ev[d]["events"]}'
            + (
                f' <span class="muted small">(+{ev[d]["in_warmup"]} w-u)</span>'
                if ev[d]["in_warmup"]
                else ""
            )
            + "</td>"
            for d in DETECTORS
            if d in ev
        )
        wj = doc["logs"][k]["false_alarm_margin"]["worst"]
        worst = "".join(_ratio_cell(r["worst_margin"].get(d), (wj.get(d) or {}).get("joint"))
                        for d in PRODUCT_DETECTORS)
        calib = (
            '<span class="good">yes</span>' if r["calibrated"] else '<span class="bad">no</span>'
        )
        ref = (
            _e(r["reference_source"])
            if r["reference_source"] == "reference"
            else f'<span class="warn">{_e(r["reference_source"])}</span>'
        )
        rows.append(
            f'<tr><td class="num">{k + 1}</td><td><a href="#log{k + 1}">{_e(r["stem"])}</a><br>'
            f'<code class="small" title="{_e(r["sha256"])}">{_e(r["sha256"][:12])}…</code></td>'
            f'<td class="num">{r["duration_s"]:.1f}</td><td'
            f' class="num">{r["sample_rate_hz"]:.0f}</td>'
            f'<td class="num">{r["n_joints"]}</td>{evcells}<td>{calib}</td><td>{ref}'
            f'</td>{worst}{qcell}</tr>'
        )
    dets = [d for d in DETECTORS if d in (doc["summary"][0]["events"] if doc["summary"] else {})]
    head = "".join(f'<th class="num">{_e(d)}</th>' for d in dets)
    whead = "".join(f'<th class="num">{_e(d)}</th>' for d in PRODUCT_DETECTORS)
    return (
        '<table class="summary"><tr><th rowspan="2" class="num">#</th><th rowspan="2">log /'
        ' sha256 (start)</th>'
        '<th rowspan="2" class="num">duration [s]</th><th rowspan="2" class="num">rate [Hz]</th>'
        '<th rowspan="2" class="num">joints</th>'
        f'<th colspan="{len(dets)}">events after warm-up (+ in warm-up)</th>'
        '<th rowspan="2">calibrated</th><th rowspan="2">reference</th>'
        f'<th colspan="{len(PRODUCT_DETECTORS)}">worst false-alarm margin</th>'
        + ('<th rowspan="2">vs labels (product)</th>' if with_q else "")
        + "</tr>"
        f"<tr>{head}{whead}</tr>{''.join(rows)}</table>"
    )


#: Stands for a log's number in a section rendered before the report is assembled (a
#: worker does not know which inputs will fail); NUL never occurs in escaped text.
NUM_TOKEN = "\x00num\x00"


@dataclasses.dataclass(frozen=True)
class RenderedLog:
    """One log, rendered: its JSON facts and its HTML section (numbered by NUM_TOKEN).

    What a report worker returns instead of the whole :class:`DetectionResult` (whose
    per-sample signals dominate memory), so a fleet report holds only these.
    """

    section: dict[str, Any]
    html: str


def render_log(result: DetectionResult, labels: Labels | None = None,
               key: int = 0) -> RenderedLog:
    """Render one log (``key``: its input index, which keeps SVG ids unique)."""
    sec = log_section(result, labels)
    return RenderedLog(sec, _section_html(NUM_TOKEN, result, sec, labels, _Ids(f"{key}-")))


def render_html(doc: dict[str, Any], sections: Sequence[str]) -> str:
    """The self-contained HTML report (inline CSS and SVG only: nothing fetched) from the
    JSON mapping and each log's section (from :func:`render_log`)."""
    n = len(sections)
    toc = "".join(
        f'<li><a href="#log{k + 1}">{_e(s["stem"])}</a></li>' for k, s in enumerate(doc["logs"])
    )
    n_uncal = sum(1 for s in doc["summary"] if not s["calibrated"])
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>impactcli safety-audit report — {n} log{'s' if n != 1 else ''}</title>",
        f"<style>{CSS}</style></head><body>",
        "<header><h1>Impact-detection safety-audit report</h1>",
        f'<p class="muted">{_e(TOOL_NAME)} {_e(__version__)} · report schema {SCHEMA_VERSION} · '
        f"{n} log{'s' if n != 1 else ''}. The report carries no date and no random id: rebuilt "
        "from the same inputs it is byte-identical (the JSON twin holds the same facts).</p>"
        "</header>",
        "<h2>Summary</h2>",
    ]
    if n_uncal:
        parts.append(
            f'<p class="bad">{n_uncal} of {n} log(s) were analysed with UNCALIBRATED '
            "thresholds (see their caveats).</p>"
        )
    parts.append(_summary_html(doc))
    if doc.get("failed"):
        parts.append(
            '<p class="bad">Inputs that could not be analysed (not in this report):</p><ul>'
            + "".join(
                f"<li><code>{_e(f['path'])}</code>: {_e(f['error'])}</li>" for f in doc["failed"]
            )
            + "</ul>"
        )
    parts.append(
        "<h3>How to read this report</h3><p>impactcli replays, offline and causally, the "
        "adaptive impact detector of Makarov et al. (2014): a residual r = τ̂ − τ from a rough "
        "rigid model (eq. 7) is whitened by an RLS-estimated filter G(z) and compared, as an RMS "
        "over a short window, with a threshold v_stat + v_rms that follows the model error "
        "(eq. 41–42). Two static detectors run beside it: <i>static loading</i> (a low-passed "
        "|r| against vL, for slow clamping the adaptive filter is blind to) and <i>static "
        "baseline</i> (|r| against v0, for comparison). An <i>event</i> is a run of samples whose "
        "decision is 1; its <i>peak ratio</i> is statistic / threshold at its worst. Times are "
        "seconds since each log's first sample. Events in the warm-up are listed, never counted. "
        "The <i>false-alarm margin</i> is how close each statistic came to its threshold where no "
        "detector fired (and no contact was labelled): values near 1 mean a detector was close "
        "to a false alarm.</p>"
    )
    parts.append(f"<nav><b>Logs</b><ol>{toc}</ol></nav>")
    parts.extend(html_k.replace(NUM_TOKEN, str(k + 1)) for k, html_k in enumerate(sections))
    parts.append("</body></html>\n")
    return "\n".join(parts)


def assemble_report(
    rendered: Sequence[RenderedLog], failed: Sequence[tuple[str, str]] = ()
) -> tuple[str, dict[str, Any]]:
    """``(html, doc)`` from rendered logs (report order = given order) and failed inputs
    ((input path, one-line error), listed in the summary)."""
    doc = report_dict([r.section for r in rendered], failed)
    return render_html(doc, [r.html for r in rendered]), doc


def build_report(
    results: Sequence[DetectionResult],
    labels: Sequence[Labels | None] | None = None,
    failed: Sequence[tuple[str, str]] = (),
) -> tuple[str, dict[str, Any]]:
    """Build the report: ``(html, doc)`` — the HTML text and the JSON-ready mapping.

    Args:
        results: one :class:`DetectionResult` per log (report order = given order).
        labels: None, or one ``Labels | None`` per result; logs with labels get the
            detection-quality evaluation.
        failed: (input path, one-line error) of inputs that could not be analysed; listed
            in the summary.
    """
    labs = list(labels) if labels is not None else [None] * len(results)
    if len(labs) != len(results):
        raise ValueError(f"{len(labs)} labels for {len(results)} results")
    return assemble_report([render_log(r, lab, k)
                            for k, (r, lab) in enumerate(zip(results, labs, strict=True))],
                           failed)


def write_report(
    results: Sequence[DetectionResult] | Sequence[RenderedLog],
    html_path: str | os.PathLike[str],
    json_path: str | os.PathLike[str] | None = None,
    labels: Sequence[Labels | None] | None = None,
    failed: Sequence[tuple[str, str]] = (),
) -> dict[str, Any]:
    """Write the HTML report (and its JSON twin) atomically; return the JSON mapping.

    ``results`` are detection results (rendered here, with ``labels``) or logs already
    rendered by :func:`render_log` (``labels`` then unused).
    """
    for p in (html_path, json_path):  # both destinations usable before either is written
        if p is not None:
            prepare_output(p)
    if results and all(isinstance(r, RenderedLog) for r in results):
        text, doc = assemble_report(results, failed)  # type: ignore[arg-type]
    else:
        text, doc = build_report(results, labels, failed)  # type: ignore[arg-type]
    atomic_write_text(html_path, text)
    if json_path is not None:
        atomic_write_text(json_path, report_json(doc))
    return doc
