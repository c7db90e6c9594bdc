"""From per-sample decisions to detection events (docs/formats.md, "Detection timeline").

Rules:
- decisions are ORed over joints; a burst is a maximal run of samples whose OR is 1;
- bursts whose gap (time from the last 1 of one to the first 1 of the next) is at most
  ``merge_gap_s`` are merged (default 0.1 s, config.EventsConfig);
- events whose duration ``t_end − t_start`` is below ``min_duration_s`` are dropped
  (default 0: keep single-sample alarms); both comparisons tolerate 1 ns of rounding;
- ``t_start``/``t_end`` are the first/last sample whose decision is 1 (inclusive);
- ``joints``: the joints that fired in the event, ordered by their first firing sample
  (ties in joint order); ``peak_ratio``: max of ratio over those joints and samples;
  ``peak_residual[joint]``: the signed r of largest |r| within [i_start, i_end];
- ``in_warmup``: t_start < warmup_end_s. An event that starts in the warm-up and still
  fires after it is split (:func:`split_at_warmup`): the part before the warm-up's end
  stays ``in_warmup``; the rest, from its first firing sample at or after the end, is an
  event of its own and is counted — an alarm that never stops must not hide in warm-up.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..types import DETECTORS, Event

#: Tolerance of the time comparisons [s] (sample times are float sums of periods).
_EPS_S = 1e-9

#: An event of the product's detectors this long or longer is said to persist [s]: a real
#: lasting load (a clamp, a held object) or a model that no longer fits the log.
LONG_EVENT_S = 10.0


def chained_text(span_s: float) -> str | None:
    """An incident's caveat when its alarms, each shorter than :data:`LONG_EVENT_S` (else
    it would be a lasting load), chained over ``span_s`` [s] of at least that: contacts in
    it are not told apart (a trial's 17.7 s incident of 28 alarms under a load no
    calibration log carried held a 30 N push); None for a shorter one."""
    if span_s < LONG_EVENT_S:
        return None
    return (f"alarms chained over {span_s:.1f} s (none {LONG_EVENT_S:g} s alone): the contacts "
            "within it are not told apart — a lasting condition (a load no calibration log "
            "carried, a model that no longer fits?)")


def split_at_warmup(
    starts: np.ndarray, ends: np.ndarray, any_d: np.ndarray, time_s: np.ndarray,
    warmup_end_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Split the event that straddles the warm-up's end (see the module doc).

    Args:
        starts, ends: (E,) inclusive sample indices of merged events, in time order.
        any_d: (N,) decisions ORed over joints.  time_s: (N,) [s].  warmup_end_s: [s].
    Returns:
        New (starts, ends) index arrays.
    """
    t = np.asarray(time_s, dtype=np.float64)
    k_w = int(np.searchsorted(t, warmup_end_s - _EPS_S))  # first sample at/after the end
    starts = np.asarray(starts, dtype=np.int64)
    ends = np.asarray(ends, dtype=np.int64)
    cut = np.flatnonzero((starts < k_w) & (ends >= k_w))
    if cut.size == 0:
        return starts, ends
    e = int(cut[0])
    after = k_w + int(np.argmax(any_d[k_w : ends[e] + 1]))
    before = np.flatnonzero(any_d[starts[e] : k_w])
    last_before = int(starts[e] + before[-1])
    new_s = np.concatenate([starts[:e], [starts[e], after], starts[e + 1 :]])
    new_e = np.concatenate([ends[:e], [last_before, ends[e]], ends[e + 1 :]])
    return new_s, new_e


def extract_events(
    detector: str, decision: np.ndarray, ratio: np.ndarray, residual: np.ndarray,
    time_s: np.ndarray, joint_names: Sequence[str], warmup_end_s: float,
    merge_gap_s: float = 0.1, min_duration_s: float = 0.0,
) -> list[Event]:
    """Events of one detector.

    Args:
        detector: ``adaptive``, ``static_loading`` or ``static_baseline``.
        decision: (N, J) bool.  ratio: (N, J) statistic / threshold [-].
        residual: (N, J) residual r [N·m].  time_s: (N,) [s since the first sample].
        joint_names: J names.  warmup_end_s: [s].  merge_gap_s, min_duration_s: [s].
    """
    if detector not in DETECTORS:
        raise ValueError(f"unknown detector {detector!r}; expected one of {DETECTORS}")
    d = np.asarray(decision, dtype=bool)
    if d.ndim != 2 or d.shape[1] != len(joint_names):
        raise ValueError(f"decision must be (N, {len(joint_names)}), got {d.shape}")
    t = np.asarray(time_s, dtype=np.float64)
    any_d = d.any(axis=1)
    idx = np.flatnonzero(any_d)
    if idx.size == 0:
        return []
    # bursts: runs of consecutive indices
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], [idx[-1]]])
    merged: list[list[int]] = [[int(starts[0]), int(ends[0])]]
    for s, e in zip(starts[1:], ends[1:], strict=True):
        if t[s] - t[merged[-1][1]] <= merge_gap_s + _EPS_S:
            merged[-1][1] = int(e)
        else:
            merged.append([int(s), int(e)])
    m = np.asarray(merged, dtype=np.int64)
    s_idx, e_idx = split_at_warmup(m[:, 0], m[:, 1], np.asarray(any_d), t, warmup_end_s)
    events: list[Event] = []
    for i0, i1 in zip(s_idx.tolist(), e_idx.tolist(), strict=True):
        if t[i1] - t[i0] < min_duration_s - _EPS_S:
            continue
        seg = d[i0 : i1 + 1]
        fired = np.flatnonzero(seg.any(axis=0))
        first = [int(np.argmax(seg[:, j])) for j in fired]
        order = [int(j) for _, j in sorted(zip(first, fired, strict=True))]
        rat = np.asarray(ratio)[i0 : i1 + 1][:, order]
        res = np.asarray(residual)[i0 : i1 + 1]
        peak_res = {}
        for j in order:
            k = int(np.argmax(np.abs(res[:, j])))
            peak_res[joint_names[j]] = float(res[k, j])
        events.append(Event(
            detector=detector, t_start=float(t[i0]), t_end=float(t[i1]),
            i_start=i0, i_end=i1, joints=tuple(joint_names[j] for j in order),
            peak_ratio=float(np.max(rat)), peak_residual=peak_res,
            in_warmup=bool(t[i0] < warmup_end_s),
        ))
    return events
