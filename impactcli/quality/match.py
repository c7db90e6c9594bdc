"""What an evaluation matches: the window around a labelled contact, the events it reads,
and the product's alarms — the vocabulary every later stage of :mod:`impactcli.quality`
imports (it imports none of them): the evaluated detectors and constants,
:class:`MatchTolerance`, the event record :class:`ScoredEvent` (from an
:class:`~impactcli.types.Event` or a timeline dict), :func:`product_events`,
:func:`force_known` and the rounding for output.

An event *matches* a labelled contact when it **starts** within ``[start - pre_s, end +
post_s]`` (bounds included, 1 ns tolerance for float sample times). ``pre_s`` (0.02 s)
absorbs clock and filter alignment between the label's source (a load cell, a simulator)
and the log; ``post_s`` (0.25 s) accepts an alarm just after the contact: the adaptive
detector is high-pass by design (docs/method.md §7) and may fire only on a slow push's or
clamp's release. The *product* is the OR of ``adaptive`` and ``static_loading``
(docs/method.md §5): their events merged where they overlap or lie within
``product_merge_gap_s``, so a moment where both fire is one alarm (:func:`product_events`;
its scoring: :mod:`impactcli.quality.evaluation`).

Pure logic: no file I/O, no printing.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import ConfigError, LogFormatError
from ..types import DETECTORS, ContactLabel, Event

SCHEMA_VERSION = "1.0"
#: The product's alarm: adaptive OR static_loading (docs/method.md §5).
PRODUCT = "product"
PRODUCT_PARTS: tuple[str, ...] = ("adaptive", "static_loading")
#: Every row of an evaluation, in display order.
EVALUATED: tuple[str, ...] = (*DETECTORS, PRODUCT)
KINDS: tuple[str, ...] = ("impact", "push", "clamp")
SECONDS_PER_HOUR = 3600.0
#: Tolerance of time comparisons [s]: sample times are float sums of periods (as detect.events).
EPS_S = 1e-9


@dataclass(frozen=True)
class MatchTolerance:
    """When an event matches a contact: it starts within ``[start - pre_s, end + post_s]``.

    Attributes:
        pre_s: how long before the labelled onset an alarm still belongs to the contact [s]
            (clock / filter alignment; default 0.02 s = 5 samples at 4 ms).
        post_s: how long after the labelled end an alarm still belongs to it [s] (a
            high-pass detector may fire on the release; default 0.25 s).
    """

    pre_s: float = 0.02
    post_s: float = 0.25

    def __post_init__(self) -> None:
        for name in ("pre_s", "post_s"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ConfigError(
                    f"match tolerance: {name} must be a finite number >= 0, got {v!r}")

    def window(self, c: ContactLabel) -> tuple[float, float]:
        """The interval of event starts that match contact ``c`` [s]."""
        return (c.start - self.pre_s, c.end + self.post_s)


@dataclass(frozen=True)
class ScoredEvent:
    """The part of an event an evaluation needs (from an :class:`Event` or a timeline dict)."""

    detector: str
    t_start: float
    t_end: float
    in_warmup: bool
    joints: tuple[str, ...] = ()
    peak_ratio: float = float("nan")


def scored_event(e: Event | Mapping[str, Any] | ScoredEvent, warmup_end_s: float,
                 i: int) -> ScoredEvent:
    """The :class:`ScoredEvent` of ``e`` (``i``: its place, for messages); in warm-up when
    flagged so or starting before ``warmup_end_s``. LogFormatError on a bad timeline event."""
    if isinstance(e, ScoredEvent):
        return e
    if isinstance(e, Event):
        det, t0, t1, warm = e.detector, e.t_start, e.t_end, e.in_warmup
        joints, peak = tuple(e.joints), e.peak_ratio
    else:
        try:
            det = str(e["detector"])
            t0, t1 = float(e["t_start"]), float(e["t_end"])
            warm = bool(e.get("in_warmup", False))
            joints = tuple(str(j) for j in e.get("joints", ()))
            peak = float(e.get("peak_ratio", float("nan")))
        except (KeyError, TypeError, ValueError) as err:
            raise LogFormatError(f"events[{i}]: missing or bad field: {err}") from None
    if det not in DETECTORS:
        raise LogFormatError(f"events[{i}]: unknown detector {det!r}")
    return ScoredEvent(det, t0, t1, warm or t0 < warmup_end_s, joints, peak)


def product_events(
    events: Iterable[ScoredEvent], warmup_end_s: float, merge_gap_s: float = 0.0
) -> list[ScoredEvent]:
    """OR of the adaptive and static-loading events: overlapping ones merged into one alarm.

    Two events merge when the next starts at most ``merge_gap_s`` after the current one ends
    (default 0: only overlapping or touching events). A merged event is in warm-up when it
    starts before ``warmup_end_s`` or its first part was flagged so; an alarm after the
    warm-up is never merged into one from the warm-up (it stays counted, as in
    :func:`impactcli.detect.events.split_at_warmup`).
    """
    parts = sorted((e for e in events if e.detector in PRODUCT_PARTS),
                   key=lambda e: (e.t_start, e.t_end))
    out: list[ScoredEvent] = []
    for e in parts:
        warm = e.in_warmup or e.t_start < warmup_end_s
        # a counted alarm never merges into one from the warm-up (it would hide in it)
        if out and e.t_start <= out[-1].t_end + merge_gap_s \
                and not (out[-1].in_warmup and not warm):
            cur = out[-1]
            joints = cur.joints + tuple(j for j in e.joints if j not in cur.joints)
            peak = e.peak_ratio if math.isnan(cur.peak_ratio) else max(cur.peak_ratio, e.peak_ratio)
            out[-1] = ScoredEvent(PRODUCT, cur.t_start, max(cur.t_end, e.t_end), cur.in_warmup,
                          joints, peak)
        else:
            out.append(ScoredEvent(PRODUCT, e.t_start, e.t_end, warm, e.joints, e.peak_ratio))
    return out


#: A label event with this extra field false has no force (labels made from a switch
#: channel, ``impactcli labels``): its ``peak_force`` is not scored.
FORCE_KNOWN_FIELD = "peak_force_known"


def force_known(c: ContactLabel) -> bool:
    """Whether a label's ``peak_force`` is a force (not a switch label's placeholder)."""
    return c.extra.get(FORCE_KNOWN_FIELD, True) is not False


def rounded(x: float | None, nd: int = 9) -> float | None:
    """Round for output (drops float noise like 0.027000000000000003); non-finite → None."""
    if x is None or not math.isfinite(x):
        return None
    return round(float(x), nd)


def median_or_none(xs: Sequence[float]) -> float | None:
    """The median of ``xs``, None when empty."""
    return float(statistics.median(xs)) if xs else None
