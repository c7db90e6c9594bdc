"""Small, dependency-free, deterministic SVG line charts for the audit report.

Formatting only (no detection maths). Every chart is a self-contained ``<svg>`` element
for inline use in HTML5 (no ``xmlns``: the HTML parser supplies the namespace, and the
report then holds no URL at all; no external fonts, CSS or scripts) whose text depends
only on its inputs, so a report built twice from the same data is byte-identical.

Long series are reduced with a **min/max envelope** (:func:`envelope`): the samples are cut
into at most ``n_buckets`` consecutive buckets and each bucket contributes its minimum and
its maximum, in the order they occur. A peak — even a single sample — therefore always
survives decimation; plain subsampling would hide it.
"""

from __future__ import annotations

import hashlib
import html
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Colours (print-safe on white; distinguishable in greyscale by dash pattern too).
BLUE = "#1f5fbf"
RED = "#c0392b"
GREEN = "#1e8449"
GREY = "#555555"
ORANGE = "#d35400"


@dataclass(frozen=True)
class Series:
    """One polyline: ``t`` [s] (M,) and ``y`` (M,), drawn in ``color`` (``dash`` e.g. ``"6 3"``).

    ``fill_above``: a colour shading the area between the line and the top of the panel
    (a threshold's alarm zone), drawn under every line.
    """

    name: str
    t: np.ndarray
    y: np.ndarray
    color: str = BLUE
    dash: str = ""
    width: float = 1.2
    fill_above: str = ""


@dataclass(frozen=True)
class Band:
    """A shaded time interval [t0, t1] [s] (events, warm-up, labelled contacts)."""

    t0: float
    t1: float
    fill: str
    label: str = ""
    outline: str = ""


@dataclass(frozen=True)
class Chart:
    """One panel: series over a time range with shaded bands.

    Attributes:
        title: shown above the panel.
        x_range: (t_min, t_max) [s].
        series: polylines (already decimated by the caller or here, see ``n_buckets``).
        bands: shaded intervals, drawn under the series.
        y_unit: unit shown on the y axis (e.g. ``"N·m"``).
        clip_factor: the y axis is capped at ``clip_factor`` × the largest value of the
            series named in ``clip_reference`` (the threshold); values above are drawn at
            the top edge and the true maximum is written in the corner. ``None``: no cap.
    """

    title: str
    x_range: tuple[float, float]
    series: Sequence[Series]
    bands: Sequence[Band] = field(default_factory=tuple)
    y_unit: str = ""
    clip_factor: float | None = None
    clip_reference: str = ""


def envelope(t: np.ndarray, y: np.ndarray, n_buckets: int) -> tuple[np.ndarray, np.ndarray]:
    """Min/max envelope decimation.

    Args:
        t: (N,) times [s], increasing.  y: (N,) values (NaN allowed: ignored in a bucket).
        n_buckets: the maximum number of buckets; when ``N <= 2 * n_buckets`` the input is
            returned unchanged.

    Returns:
        (t_out, y_out), at most ``2 * n_buckets`` points: for each bucket its minimum and
        maximum sample, in time order. The global maximum and minimum are always kept.
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = t.shape[0]
    if n <= 2 * n_buckets:
        return t, y
    edges = np.linspace(0, n, n_buckets + 1).astype(np.int64)
    starts = edges[:-1]
    yy = np.where(np.isfinite(y), y, np.nan)
    lo_fill = np.where(np.isnan(yy), np.inf, yy)
    hi_fill = np.where(np.isnan(yy), -np.inf, yy)
    mins = np.minimum.reduceat(lo_fill, starts)
    maxs = np.maximum.reduceat(hi_fill, starts)
    # position of min/max inside each bucket: first index equal to the bucket's extreme
    bucket = np.repeat(np.arange(n_buckets), np.diff(edges))
    idx = np.arange(n)
    big = n + 1
    i_min = np.minimum.reduceat(np.where(lo_fill == mins[bucket], idx, big), starts)
    i_max = np.minimum.reduceat(np.where(hi_fill == maxs[bucket], idx, big), starts)
    valid = (i_min < big) & np.isfinite(mins)
    first = np.where(i_min <= i_max, i_min, i_max)[valid]
    second = np.where(i_min <= i_max, i_max, i_min)[valid]
    order = np.stack([first, second], axis=1).ravel()
    return t[order], y[order]


class EnvelopeAccumulator:
    """:func:`envelope` of a series whose ``n`` samples (known beforehand) arrive in
    consecutive chunks: the same points, without holding the series.

    The buckets are fixed by ``n`` alone (``linspace(0, n, n_buckets + 1)``), so each
    chunk's samples fall into known buckets; per bucket the minimum and maximum and where
    they lie are carried from chunk to chunk (fixed-size arrays, one slot per bucket). A
    later equal value never replaces an earlier one, as :func:`envelope` takes the first
    index equal to the bucket's extreme. A series of at most ``2 * n_buckets`` samples is
    kept whole, as :func:`envelope` returns it unchanged.
    """

    def __init__(self, n: int, n_buckets: int) -> None:
        self.n, self.nb, self.k0 = int(n), int(n_buckets), 0
        self.whole = self.n <= 2 * self.nb
        self.parts: list[tuple[np.ndarray, np.ndarray]] = []
        if not self.whole:
            self.edges = np.linspace(0, self.n, self.nb + 1).astype(np.int64)
            self.mn = np.full(self.nb, np.inf)
            self.mx = np.full(self.nb, -np.inf)
            self.i_mn = np.full(self.nb, self.n + 1, dtype=np.int64)
            self.i_mx = np.full(self.nb, self.n + 1, dtype=np.int64)
            self.t_mn = np.zeros(self.nb)
            self.t_mx = np.zeros(self.nb)
            # the sample's own value (a -0.0 the reduction may give as 0.0)
            self.y_mn = np.zeros(self.nb)
            self.y_mx = np.zeros(self.nb)

    def update(self, t: np.ndarray, y: np.ndarray) -> None:
        """Absorb the next chunk: (m,) times [s] and (m,) values."""
        t = np.asarray(t, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        m, k0 = t.shape[0], self.k0
        self.k0 += m
        if m == 0:
            return
        if self.whole:
            self.parts.append((t.copy(), y.copy()))
            return
        b0 = int(np.searchsorted(self.edges, k0, side="right")) - 1
        b1 = int(np.searchsorted(self.edges, k0 + m - 1, side="right")) - 1
        starts = np.maximum(self.edges[b0:b1 + 1], k0) - k0
        yy = np.where(np.isfinite(y), y, np.nan)
        lo_fill = np.where(np.isnan(yy), np.inf, yy)
        hi_fill = np.where(np.isnan(yy), -np.inf, yy)
        mins = np.minimum.reduceat(lo_fill, starts)
        maxs = np.maximum.reduceat(hi_fill, starts)
        bucket = np.repeat(np.arange(starts.size), np.diff(np.append(starts, m)))
        idx = np.arange(m)
        big = m + 1
        i_min = np.minimum.reduceat(np.where(lo_fill == mins[bucket], idx, big), starts)
        i_max = np.minimum.reduceat(np.where(hi_fill == maxs[bucket], idx, big), starts)
        sl = slice(b0, b1 + 1)
        lower = mins < self.mn[sl]   # strictly: the earlier sample wins a tie
        higher = maxs > self.mx[sl]
        self.mn[sl] = np.where(lower, mins, self.mn[sl])
        self.i_mn[sl] = np.where(lower, k0 + i_min, self.i_mn[sl])
        at_mn, at_mx = np.minimum(i_min, m - 1), np.minimum(i_max, m - 1)
        self.t_mn[sl] = np.where(lower, t[at_mn], self.t_mn[sl])
        self.y_mn[sl] = np.where(lower, y[at_mn], self.y_mn[sl])
        self.mx[sl] = np.where(higher, maxs, self.mx[sl])
        self.i_mx[sl] = np.where(higher, k0 + i_max, self.i_mx[sl])
        self.t_mx[sl] = np.where(higher, t[at_mx], self.t_mx[sl])
        self.y_mx[sl] = np.where(higher, y[at_mx], self.y_mx[sl])

    def result(self) -> tuple[np.ndarray, np.ndarray]:
        """(t_out, y_out): what :func:`envelope` gives on the whole series."""
        if self.k0 != self.n:
            raise ValueError(f"envelope: {self.k0} samples given, {self.n} announced")
        if self.whole:
            if not self.parts:
                return np.zeros(0), np.zeros(0)
            return (np.concatenate([p[0] for p in self.parts]),
                    np.concatenate([p[1] for p in self.parts]))
        valid = (self.i_mn <= self.n) & np.isfinite(self.mn)
        min_first = self.i_mn <= self.i_mx
        t1 = np.where(min_first, self.t_mn, self.t_mx)[valid]
        t2 = np.where(min_first, self.t_mx, self.t_mn)[valid]
        y1 = np.where(min_first, self.y_mn, self.y_mx)[valid]
        y2 = np.where(min_first, self.y_mx, self.y_mn)[valid]
        return np.stack([t1, t2], axis=1).ravel(), np.stack([y1, y2], axis=1).ravel()


def nice_ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    """About ``n`` round tick values (1, 2, 5 × 10^k steps) covering [lo, hi]."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo]
    raw = (hi - lo) / max(n, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * mag >= raw)
    first = math.ceil(lo / step - 1e-9) * step
    out = []
    k = 0
    while True:
        v = first + k * step
        if v > hi + 1e-9 * step:
            break
        out.append(0.0 if abs(v) < 1e-12 * step else v)
        k += 1
    return out


def fmt_num(v: float, span: float | None = None) -> str:
    """A short, deterministic label for a tick or a value."""
    if v == 0:
        return "0"
    a = abs(v) if span is None else abs(span)
    if a >= 100 or a == 0:
        return f"{v:.0f}"
    digits = max(0, min(6, 2 - math.floor(math.log10(a))))
    s = f"{v:.{digits}f}"
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return s


def _esc(s: str) -> str:
    return html.escape(s, quote=True)


def _points(xs: np.ndarray, ys: np.ndarray) -> str:
    """An SVG points list "x,y x,y ..." to 0.1 px (Python floats format faster than numpy
    scalars, to the same text)."""
    return " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(xs.tolist(), ys.tolist(), strict=True))


def render_chart(chart: Chart, width: int = 860, height: int = 170, chart_id: str = "") -> str:
    """Render one panel as an inline ``<svg>`` element (string).

    ``chart_id`` names the panel's clip path; give each chart of a document its own
    (deterministic) id. By default it is derived from the title and time range.
    """
    ml, mr, mt, mb = 56, 12, 20, 26
    pw, ph = width - ml - mr, height - mt - mb
    x0, x1 = chart.x_range
    if not x1 > x0:
        x1 = x0 + 1.0
    finite_max = [
        float(np.max(s.y[np.isfinite(s.y)])) for s in chart.series if np.any(np.isfinite(s.y))
    ]
    finite_min = [
        float(np.min(s.y[np.isfinite(s.y)])) for s in chart.series if np.any(np.isfinite(s.y))
    ]
    data_max = max(finite_max, default=1.0)
    y_lo = min(0.0, min(finite_min, default=0.0))
    y_hi = data_max
    clipped = False
    if chart.clip_factor is not None:
        ref = [s for s in chart.series if s.name == chart.clip_reference]
        ref_max = max(
            (float(np.max(s.y[np.isfinite(s.y)])) for s in ref if np.any(np.isfinite(s.y))),
            default=0.0,
        )
        if ref_max > 0 and data_max > chart.clip_factor * ref_max:
            y_hi = chart.clip_factor * ref_max
            clipped = True
        elif ref_max > 0:
            y_hi = max(y_hi, 1.25 * ref_max)  # room above the threshold: its alarm zone shows
    if not y_hi > y_lo:
        y_hi = y_lo + 1.0
    y_hi_axis = y_hi * 1.05 if not clipped else y_hi

    def px(t: np.ndarray | float) -> np.ndarray:
        return ml + (np.asarray(t, dtype=np.float64) - x0) / (x1 - x0) * pw

    def py(v: np.ndarray | float) -> np.ndarray:
        vv = np.clip(np.asarray(v, dtype=np.float64), y_lo, y_hi_axis)
        return mt + ph - (vv - y_lo) / (y_hi_axis - y_lo) * ph

    parts: list[str] = [
        f'<svg viewBox="0 0 {width} {height}" '
        f'class="chart" role="img" aria-label="{_esc(chart.title)}">',
        f"<title>{_esc(chart.title)}</title>",
        f'<rect x="{ml}" y="{mt}" width="{pw}" height="{ph}" fill="#ffffff" stroke="#999999"'
        ' stroke-width="0.8"/>',
    ]
    clip_id = chart_id or "c" + _stable_id(f"{chart.title}|{x0!r}|{x1!r}")
    parts.append(
        f'<clipPath id="{clip_id}"><rect x="{ml}" y="{mt}" width="{pw}" height="{ph}"/></clipPath>'
    )
    parts.append(f'<g clip-path="url(#{clip_id})">')
    for s in chart.series:
        ok = np.isfinite(s.y) & (s.t >= x0 - 1e-12) & (s.t <= x1 + 1e-12)
        if not s.fill_above or not np.any(ok):
            continue
        xs, ys = px(s.t[ok]), py(s.y[ok])
        pts = _points(xs, ys)
        parts.append(f'<polygon fill="{s.fill_above}" stroke="none" '
                     f'points="{xs[0]:.1f},{mt} {pts} {xs[-1]:.1f},{mt}"/>')
    for bx0, w, b, count in _merged_bands(chart.bands, px, ml, ml + pw):
        stroke = f' stroke="{b.outline}" stroke-width="1"' if b.outline else ""
        label = b.label if count == 1 else f"{count} × {b.label}"
        tip = f"<title>{_esc(label)}</title>" if label else ""
        parts.append(
            f'<rect x="{bx0:.1f}" y="{mt}" width="{w:.1f}" height="{ph}"'
            f' fill="{b.fill}" fill-opacity="0.85"{stroke}>{tip}</rect>'
        )
    for s in chart.series:
        ok = np.isfinite(s.y) & (s.t >= x0 - 1e-12) & (s.t <= x1 + 1e-12)
        if not np.any(ok):
            continue
        xs, ys = px(s.t[ok]), py(s.y[ok])
        pts = _points(xs, ys)
        dash = f' stroke-dasharray="{s.dash}"' if s.dash else ""
        parts.append(
            f'<polyline fill="none" stroke="{s.color}" stroke-width="{s.width}"{dash} '
            f'stroke-linejoin="round" points="{pts}"><title>{_esc(s.name)}</title></polyline>'
        )
    parts.append("</g>")
    # axes
    font = 'font-family="DejaVu Sans, Arial, Helvetica, sans-serif" font-size="10" fill="#222222"'
    for v in nice_ticks(y_lo, y_hi_axis, 4):
        yy = float(py(v))
        parts.append(
            f'<line x1="{ml - 3}" y1="{yy:.1f}" x2="{ml + pw}" y2="{yy:.1f}" stroke="#dddddd"'
            ' stroke-width="0.6"/>'
        )
        parts.append(
            f'<text x="{ml - 5}" y="{yy + 3:.1f}" text-anchor="end"'
            f' {font}>{fmt_num(v, y_hi_axis - y_lo)}</text>'
        )
    for v in nice_ticks(x0, x1, 8):
        xx = float(px(v))
        parts.append(
            f'<line x1="{xx:.1f}" y1="{mt + ph}" x2="{xx:.1f}" y2="{mt + ph + 3}"'
            ' stroke="#555555" stroke-width="0.8"/>'
        )
        parts.append(
            f'<text x="{xx:.1f}" y="{mt + ph + 13}" text-anchor="middle"'
            f' {font}>{fmt_num(v, x1 - x0)}</text>'
        )
    parts.append(f'<text x="{ml + pw}" y="{height - 2}" text-anchor="end" {font}>time [s]</text>')
    parts.append(
        f'<text x="{ml}" y="{mt - 6}" {font} font-weight="bold">{_esc(chart.title)}</text>'
    )
    if chart.y_unit:
        parts.append(f'<text x="4" y="{mt - 6}" {font}>{_esc(chart.y_unit)}</text>')
    # legend (right-aligned, top)
    lx = ml + pw
    for s in reversed(chart.series):
        label = _esc(s.name)
        wtxt = 6 * len(s.name) + 26
        lx -= wtxt
        dash = f' stroke-dasharray="{s.dash}"' if s.dash else ""
        parts.append(
            f'<line x1="{lx}" y1="{mt - 9}" x2="{lx + 18}" y2="{mt - 9}" stroke="{s.color}"'
            f' stroke-width="2"{dash}/>'
        )
        parts.append(f'<text x="{lx + 21}" y="{mt - 6}" {font}>{label}</text>')
    if clipped:
        parts.append(
            f'<text x="{ml + 4}" y="{mt + 11}" {font} fill="{RED}">▲ axis capped at '
            f"{fmt_num(y_hi)}; max {fmt_num(data_max)}</text>"
        )
    parts.append("</svg>")
    return "".join(parts)


def _merged_bands(bands: Sequence[Band], px: Any, left: float, right: float,
                  min_px: float = 3.0) -> list[tuple[float, float, Band, int]]:
    """Bands as pixel rectangles (x, width, band, count), at least ``min_px`` wide so a short
    event on a long log stays visible; bands of one style closer than a pixel are merged
    (thousands of alarms stay a few rectangles), in the order the styles first appear."""
    styles: dict[tuple[str, str], list[tuple[float, float, Band]]] = {}
    for b in bands:
        a0, a1 = float(px(b.t0)), float(px(b.t1))
        if a1 < left or a0 > right:
            continue
        a0, a1 = max(a0, left), min(a1, right)
        a1 = max(a1, a0 + min_px)
        styles.setdefault((b.fill, b.outline), []).append((a0, a1, b))
    out: list[tuple[float, float, Band, int]] = []
    for items in styles.values():
        items.sort(key=lambda it: (it[0], it[1]))
        cur0, cur1, first = items[0]
        n = 1
        for a0, a1, b in items[1:]:
            if a0 <= cur1 + 1.0:
                cur1 = max(cur1, a1)
                n += 1
            else:
                out.append((cur0, cur1 - cur0, first, n))
                cur0, cur1, first, n = a0, a1, b, 1
        out.append((cur0, cur1 - cur0, first, n))
    return out


def _stable_id(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:10]


def render_xy(
    title: str,
    groups: Mapping[str, tuple[Sequence[float], Sequence[float]]],
    x_label: str,
    y_label: str,
    *,
    width: int = 640,
    height: int = 300,
    x_scale: str = "linear",
) -> str:
    """A small scatter-and-line chart (e.g. an ROC-style sweep): one polyline per group,
    the legend to the right of the plot area.

    ``x_scale="log1p"`` draws x >= 0 at log10(1 + x): 0 stays at the left edge and the
    decades 1, 10, 100, … get equal room (false-alarm rates spanning 0 to thousands).
    """
    ml, mr, mt, mb = 56, 150, 28, 40
    pw, ph = width - ml - mr, height - mt - mb
    log_x = x_scale == "log1p"

    def tx(v: float) -> float:
        return math.log10(1.0 + max(v, 0.0)) if log_x else v

    xs_all = [tx(float(v)) for x, _ in groups.values() for v in x if math.isfinite(float(v))]
    ys_all = [float(v) for _, y in groups.values() for v in y if math.isfinite(float(v))]
    x0, x1 = min(xs_all, default=0.0), max(xs_all, default=1.0)
    y0, y1 = min(0.0, min(ys_all, default=0.0)), max(ys_all, default=1.0)
    x0 = min(x0, 0.0)
    if x1 <= x0:
        x1 = x0 + 1.0
    if y1 <= y0:
        y1 = y0 + 1.0
    x1 *= 1.05
    y1 *= 1.05

    def px(v: float) -> float:
        return ml + (tx(v) - x0) / (x1 - x0) * pw

    def py(v: float) -> float:
        return mt + ph - (v - y0) / (y1 - y0) * ph

    font = 'font-family="DejaVu Sans, Arial, Helvetica, sans-serif" font-size="10" fill="#222222"'
    parts = [
        f'<svg viewBox="0 0 {width} {height}" class="chart xy" '
        f'role="img" aria-label="{_esc(title)}"><title>{_esc(title)}</title>',
        f'<rect x="{ml}" y="{mt}" width="{pw}" height="{ph}" fill="#ffffff" stroke="#999999"'
        ' stroke-width="0.8"/>',
    ]
    for v in nice_ticks(y0, y1, 5):
        parts.append(
            f'<line x1="{ml}" y1="{py(v):.1f}" x2="{ml + pw}" y2="{py(v):.1f}" stroke="#dddddd"'
            ' stroke-width="0.6"/>'
        )
        parts.append(
            f'<text x="{ml - 5}" y="{py(v) + 3:.1f}" text-anchor="end"'
            f' {font}>{fmt_num(v, y1 - y0)}</text>'
        )
    if log_x:
        x_ticks = [0.0] + [10.0**k for k in range(0, 12) if math.log10(1 + 10.0**k) <= x1]
        x_labels = ["0"] + [f"{v:.0f}" for v in x_ticks[1:]]
    else:
        x_ticks = nice_ticks(x0, x1, 6)
        x_labels = [fmt_num(v, x1 - x0) for v in x_ticks]
    for v, label in zip(x_ticks, x_labels, strict=True):
        parts.append(
            f'<line x1="{px(v):.1f}" y1="{mt}" x2="{px(v):.1f}" y2="{mt + ph}" stroke="#eeeeee"'
            ' stroke-width="0.6"/>'
        )
        parts.append(
            f'<text x="{px(v):.1f}" y="{mt + ph + 13}" text-anchor="middle"'
            f' {font}>{label}</text>'
        )
    parts.append(
        f'<text x="{ml + pw / 2:.1f}" y="{height - 6}" text-anchor="middle"'
        f' {font}>{_esc(x_label)}</text>'
    )
    parts.append(
        f'<text x="{ml}" y="{mt - 8}" {font} font-weight="bold">{_esc(title)} — {_esc(y_label)}'
        '</text>'
    )
    palette = [BLUE, GREEN, GREY, ORANGE, RED]
    dashes = ["", "6 3", "2 2", "8 2 2 2", "4 4"]
    for k, (name, (gx, gy)) in enumerate(groups.items()):
        col, dash = palette[k % len(palette)], dashes[k % len(dashes)]
        pts = [
            (px(float(a)), py(float(b)))
            for a, b in zip(gx, gy, strict=True)
            if math.isfinite(float(a)) and math.isfinite(float(b))
        ]
        if not pts:
            continue
        d = f' stroke-dasharray="{dash}"' if dash else ""
        parts.append(
            f'<polyline fill="none" stroke="{col}" stroke-width="1.6"{d} points="'
            + " ".join(f"{a:.1f},{b:.1f}" for a, b in pts)
            + f'"><title>{_esc(name)}</title></polyline>'
        )
        parts.extend(f'<circle cx="{a:.1f}" cy="{b:.1f}" r="2.4" fill="{col}"/>' for a, b in pts)
        ly = mt + 12 + 14 * k
        lx = ml + pw + 12
        parts.append(
            f'<line x1="{lx}" y1="{ly - 3}" x2="{lx + 18}" y2="{ly - 3}" '
            f'stroke="{col}" stroke-width="2"{d}/>'
        )
        parts.append(f'<text x="{lx + 22}" y="{ly}" {font}>{_esc(name)}</text>')
    parts.append("</svg>")
    return "".join(parts)
