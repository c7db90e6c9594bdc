"""What a threshold sweep says, and the sweep as JSON and text.

:func:`at_zero_false_alarms` takes, per detector, the smallest swept scale from which on the
log stays free of false alarms; :func:`compare_at_zero` pairs adaptive and static_loading
there contact by contact, and :func:`verdict` says in one sentence whether the adaptive
detector helps (it detects a smaller contact than static_loading's smallest, or fires
earlier on the contacts both detect — medians over different contacts are not compared).
The scales are chosen on the very log they are scored on: an in-sample, best-case
comparison of the detectors at matched rates, not a calibration (that is
``impactcli calibrate`` on collision-free logs).

:func:`sweep_to_dict` (JSON) and :func:`format_sweep` (text) hold the rows of
:mod:`impactcli.quality.sweep`, these points and the verdict. Pure logic: no file I/O, no
printing.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ..detect.tail import zero_count_bound
from .match import EPS_S, PRODUCT_PARTS, median_or_none, rounded
from .sweep import SweepRow
from .text import fmt_ms, fmt_n, text_table


def at_zero_false_alarms(rows: Sequence[SweepRow]) -> dict[str, SweepRow | None]:
    """Per detector, the sweep row at the smallest scale from which on it stays silent.

    That is the smallest swept scale s such that this scale and every larger swept scale
    give zero false alarms (a lone silent scale below a noisy one is not trusted: event
    merging can make the count non-monotonic). None when even the largest scale
    false-alarms. Its ``min_detected_force`` is the minimal detected force at zero false
    alarms.
    """
    out: dict[str, SweepRow | None] = {}
    for d in dict.fromkeys(r.detector for r in rows):
        best: SweepRow | None = None
        for r in sorted((r for r in rows if r.detector == d), key=lambda r: -r.scale):
            if r.false_alarms:
                break
            best = r
        out[d] = best
    return out


def _at_edge(zero: Mapping[str, SweepRow | None], smallest_scale: float | None) -> list[str]:
    """Compared detectors already silent at the smallest swept scale (their zero-false-alarm
    point lies below the sweep)."""
    if smallest_scale is None:
        return []
    return [d for d in PRODUCT_PARTS
            if (r := zero.get(d)) is not None and r.scale <= smallest_scale + EPS_S]


@dataclass(frozen=True)
class Comparison:
    """Adaptive vs static_loading, each at its own zero-false-alarm threshold scale.

    Attributes:
        adaptive, static_loading: their sweep rows at that point.
        adaptive_only, loading_only, both: counted contacts detected by only one / by both.
        paired_delay_gain_s: median over contacts detected by both of (static_loading delay
            − adaptive delay) [s]: positive when adaptive fires earlier; None if none shared.
    """

    adaptive: SweepRow
    static_loading: SweepRow
    adaptive_only: int
    loading_only: int
    both: int
    paired_delay_gain_s: float | None

    @property
    def smaller_force(self) -> bool:
        """Adaptive detects a smaller contact than static_loading's smallest detected one."""
        a, s = self.adaptive.min_detected_force, self.static_loading.min_detected_force
        return a is not None and (s is None or a < s)

    @property
    def earlier(self) -> bool:
        """On the contacts both detect, adaptive fires earlier (median of paired delays)."""
        return self.paired_delay_gain_s is not None and self.paired_delay_gain_s > EPS_S


def compare_at_zero(zero: Mapping[str, SweepRow | None]) -> Comparison | None:
    """The :class:`Comparison` of adaptive and static_loading at zero false alarms, or None
    when either never reached zero false alarms in the sweep."""
    a, s = zero.get("adaptive"), zero.get("static_loading")
    if a is None or s is None:
        return None
    da, ds = a.contact_delays_s, s.contact_delays_s
    if len(da) != len(ds):
        raise ValueError("sweep rows of different label sets cannot be compared")
    pairs = [(x, y) for x, y in zip(da, ds, strict=True) if x is not None and y is not None]
    return Comparison(
        adaptive=a, static_loading=s,
        adaptive_only=sum(1 for x, y in zip(da, ds, strict=True) if x is not None and y is None),
        loading_only=sum(1 for x, y in zip(da, ds, strict=True) if x is None and y is not None),
        both=len(pairs),
        paired_delay_gain_s=median_or_none([y - x for x, y in pairs]),
    )


def adaptive_helps(zero: Mapping[str, SweepRow | None], *,
                   smallest_scale: float | None = None) -> bool | None:
    """Whether adaptive beats static_loading at matched (zero) false alarms, or None if unknown.

    Each detector is taken at its own zero-false-alarm scale (:func:`at_zero_false_alarms`).
    Helps when adaptive detects a smaller contact than any static_loading detects (smaller
    minimal detected force — that contact is one static_loading misses), or when, on the
    contacts both detect, it fires earlier (median of the paired delay differences: median
    delays over different sets of contacts are not compared). Unknown (None): either
    detector never reaches zero false alarms in the sweep, or is already silent at
    ``smallest_scale`` (the smallest swept scale: its true zero-false-alarm point lies
    lower, so the two are not compared at matched rates), or there is no counted contact.
    """
    cmp = compare_at_zero(zero)
    if cmp is None or cmp.adaptive.n_contacts == 0 or _at_edge(zero, smallest_scale):
        return None
    return cmp.smaller_force or cmp.earlier


def _row_text(r: SweepRow) -> str:
    txt = f"{r.detected}/{r.n_contacts} contacts at threshold scale {r.scale:g}"
    if r.detected:
        txt += (f", down to {r.min_detected_force:.3g} N with a median delay of "
                f"{fmt_ms(r.delay_median_s)}")
    return txt


def _pair_text(cmp: Comparison) -> str:
    parts = [f"{cmp.adaptive_only} contact(s) only adaptive detects, {cmp.loading_only} only "
             f"static_loading detects, {cmp.both} both"]
    if cmp.paired_delay_gain_s is not None:
        g = cmp.paired_delay_gain_s
        parts.append(f"on those adaptive fires {fmt_ms(abs(g))} "
                     f"{'earlier' if g >= 0 else 'later'} (median)")
    return ", ".join(parts)


def verdict(zero: Mapping[str, SweepRow | None], *, smallest_scale: float | None = None) -> str:
    """One plain sentence: does the adaptive detector help on this robot and log?

    Compares adaptive with static_loading at their zero-false-alarm points
    (:func:`at_zero_false_alarms`); criteria in :func:`adaptive_helps`.
    """
    a, s = zero.get("adaptive"), zero.get("static_loading")
    missing = [d for d, r in (("adaptive", a), ("static_loading", s)) if r is None]
    if missing:
        return (f"Undetermined: {' and '.join(missing)} never reached zero false alarms "
                "within the swept threshold scales; sweep larger scales.")
    cmp = compare_at_zero(zero)
    assert a is not None and s is not None and cmp is not None
    if a.n_contacts == 0:
        return "Undetermined: the labels hold no contact after warm-up to compare detectors on."
    both = (f"adaptive detected {_row_text(a)}; static_loading detected {_row_text(s)}; "
            f"{_pair_text(cmp)}.")
    edge = _at_edge(zero, smallest_scale)
    if edge:
        return (f"Undetermined: {' and '.join(edge)} had no false alarm even at the smallest "
                f"swept scale ({smallest_scale:g}), so the detectors are not compared at "
                f"matched rates; sweep smaller scales ({both[:-1]}).")
    if cmp.smaller_force or cmp.earlier:
        why = " and ".join(w for w, ok in (("detects smaller contacts", cmp.smaller_force),
                                          ("fires earlier on shared contacts", cmp.earlier))
                           if ok)
        return f"The adaptive detector helps here at zero false alarms ({why}): {both}"
    return ("The adaptive detector does not help here at zero false alarms (no smaller "
            f"contact detected, not earlier on shared contacts): {both}")


def zero_bound_text(rows: Sequence[SweepRow]) -> str:
    """What "zero false alarms" rests on: the log's collision-free time and the rate it
    bounds at 90 % (:func:`impactcli.detect.tail.zero_count_bound`, as calibrate's; a
    trial took a sweep's "0 FA" scale from 50 s of one log and found it false-alarmed 4042
    times per hour on free motion); "" when not known."""
    free = next((r.collision_free_s for r in rows if r.collision_free_s), None)
    if not free:
        return ""
    return (f"Zero false alarms here is over this log's {free:.3g} s of collision-free time: "
            f"a rate up to {zero_count_bound(free / 3600.0):.3g} per hour at 90 % "
            "confidence — not thresholds for an audit (calibrate on collision-free logs; "
            "evaluate a scale on them too).")


def sweep_to_dict(rows: Sequence[SweepRow]) -> dict[str, Any]:
    """The sweep, its zero-false-alarm points and the verdict, JSON-ready (deterministic)."""
    zero = at_zero_false_alarms(rows)
    lo = min((r.scale for r in rows), default=None)
    free = next((r.collision_free_s for r in rows if r.collision_free_s), None)
    return {
        "rows": [r.to_dict() for r in rows],
        "at_zero_false_alarms": {
            d: (r.to_dict(per_contact=True) if r is not None else None)
            for d, r in zero.items()},
        "adaptive_helps": adaptive_helps(zero, smallest_scale=lo),
        "verdict": verdict(zero, smallest_scale=lo),
        **({} if free is None else {
            "collision_free_s": rounded(free),
            "zero_bound_per_hour": rounded(zero_count_bound(free / 3600.0), 6),
            "caveat": zero_bound_text(rows)}),
    }


def format_sweep(rows: Sequence[SweepRow]) -> str:
    """A plain-text table of the sweep's zero-false-alarm points and the verdict."""
    zero = at_zero_false_alarms(rows)
    scales = sorted({r.scale for r in rows})
    lo = scales[0] if scales else None
    table: list[tuple[str, ...]] = [("detector", "scale @ 0 FA", "detected", "min detected F",
                                     "delay med")]
    for d, r in zero.items():
        if r is None:
            table.append((d, f"never (> {scales[-1]:g})", "-", "-", "-"))
        else:
            at_lo = lo is not None and r.scale <= lo + EPS_S
            table.append((d, f"<= {r.scale:g}" if at_lo else f"{r.scale:g}",
                          f"{r.detected}/{r.n_contacts}",
                          fmt_n(r.min_detected_force), fmt_ms(r.delay_median_s)))
    rng = f"{scales[0]:g}–{scales[-1]:g}, {len(scales)} scales" if scales else "no scales"
    caveat = zero_bound_text(rows)
    return "\n".join([f"Threshold sweep ({rng}), at zero false alarms:", *text_table(table), "",
                      verdict(zero, smallest_scale=lo), *([caveat] if caveat else [])]) + "\n"
