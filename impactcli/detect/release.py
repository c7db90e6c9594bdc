"""An incident whose alarm is the end of a load held before it: a push released.

A hand that pushes an arm for seconds, building up slowly enough that neither product
detector fires at its start, and then lets go at once, leaves a residual that stood off its
level for those seconds and drops back within a few samples. The adaptive detector fires on
the drop (its band-pass, eq. 40, passes a step, not a slow rise), so the incident is dated at
the release and read as a transient blow; the contact began seconds before. On the real UR
arm held still and pushed by hand (``ur-static.csv``, uncalibrated: four pushes fill 40 % of
the log, so its self-set loading thresholds stand at 3× them), two incidents were the
releases of pushes held 4 and 5 s, at 15.9 s and 31.0 s, "transient, ~18 N".

The residual's history tells, after the fact (a note on the answer, as
:mod:`impactcli.detect.aftermath`, not part of the online replay). Its means over blocks of
:data:`BLOCK_S` (:class:`BlockTrace`: J numbers per block, whatever the log's length) give,
per joint of the incident:

- the level after its alarm began, P: the median of :data:`POST_BLOCKS` blocks from
  :data:`SETTLE_BLOCKS` after its start — a release's residual is back by then, while a
  clamp that crossed its threshold at the alarm still holds it there (a trial's heavy-arm
  clamp, alarming 2.3 s into its build-up, was first taken for a release of it);
- the level held before it, H: the median of :data:`PRE_BLOCKS` blocks ending
  :data:`GUARD_BLOCKS` before its start;
- the step H − P must stand out: at least :data:`STEP_SIGMA` × the residual's block noise
  (the robust sd of its block-to-block differences over the log, MAD × 1.4826 / √2 — the
  motion's share of the residual counts as noise) and half the incident's own peak
  residual on that joint (a release's transient is the step itself);
- the hold: walking back from the incident, the blocks stay within :data:`PLATEAU_SHARE`
  of the step around H (:data:`OUT_RUN` blocks in a row outside end it); it began at the
  first of them and lasted :data:`HOLD_MIN_S` or more;
- before the hold the residual stood at P's level again (within half the step): a load that
  came and went — not a level the log started with, and not a model's error that moved;
- no earlier incident or lasting load overlaps the hold (then its start was seen).

An incident that passes on any of its joints is marked ``held_before`` (the hold's start,
per joint the levels held and after, and why): still counted — it is a contact — but dated
and typed by its release. Pure functions; :mod:`impactcli.run.one_log` feeds the trace and
applies the mark once every incident is known.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

#: The residual's history is kept as means over blocks of this length [s].
BLOCK_S = 0.1
#: Blocks over which the held level and the level after are taken.
PRE_BLOCKS = 10
POST_BLOCKS = 10
#: Blocks left out before the incident's start (its onset) and after its end (its
#: settling).
GUARD_BLOCKS = 1
SETTLE_BLOCKS = 3
#: The step must reach this many block-noise sds ...
STEP_SIGMA = 8.0
#: ... and this share of the incident's peak residual on the joint.
STEP_OF_PEAK = 0.5
#: A block belongs to the hold within this share of the step around the held level.
PLATEAU_SHARE = 0.25
#: This many blocks in a row off the held level end the hold (walking back).
OUT_RUN = 3
#: The least hold [s].
HOLD_MIN_S = 1.0


class BlockTrace:
    """Means of a (n, J) signal over consecutive blocks of ``per_block`` samples, fed in
    chunks (:meth:`update`, in order); :meth:`finish` gives the (B, J) means of the whole
    blocks (a last partial block is dropped)."""

    def __init__(self, n_joints: int, per_block: int) -> None:
        self.per_block = max(1, int(per_block))
        self.done: list[np.ndarray] = []
        self.part = np.zeros((0, n_joints))

    def update(self, x: np.ndarray) -> None:
        """Absorb the next (m, J) samples."""
        a = np.concatenate([self.part, np.asarray(x, dtype=np.float64)], axis=0)
        whole = a.shape[0] // self.per_block * self.per_block
        if whole:
            self.done.append(a[:whole].reshape(-1, self.per_block, a.shape[1])
                             .mean(axis=1).astype(np.float32))
        self.part = a[whole:]

    def finish(self) -> np.ndarray:
        """(B, J) block means (float32)."""
        cols = self.part.shape[1]
        return (np.concatenate(self.done, axis=0) if self.done
                else np.zeros((0, cols), dtype=np.float32))


def block_noise(x: np.ndarray) -> np.ndarray:
    """(J,) the robust sd of (B, J) block means' block-to-block differences, per block
    (MAD × 1.4826 / √2; inf with fewer than 3 blocks)."""
    if x.shape[0] < 3:
        return np.full(x.shape[1], np.inf)
    d = np.diff(x.astype(np.float64), axis=0)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(2.0)


def held_level(x: np.ndarray, b0: int, sigma: float, peak: float,
               min_blocks: int) -> tuple[int, float, float] | None:
    """A hold of ``min_blocks`` blocks or more that an incident's alarm at block ``b0``
    ended on one joint's (B,) block means ``x`` (module docstring): (its first block, the
    level held, the level after) or None."""
    n = x.shape[0]
    a, z = b0 - GUARD_BLOCKS - PRE_BLOCKS, b0 + 1 + SETTLE_BLOCKS  # after its alarm began
    if a < 0 or z + POST_BLOCKS // 2 > n:
        return None
    held = float(np.median(x[a:b0 - GUARD_BLOCKS]))
    after = float(np.median(x[z:z + POST_BLOCKS]))
    step = abs(held - after)
    if not (step >= STEP_SIGMA * sigma and step >= STEP_OF_PEAK * abs(peak)):
        return None
    band = PLATEAU_SHARE * step
    first, out, b = b0 - GUARD_BLOCKS - 1, 0, b0 - GUARD_BLOCKS - 1
    while b >= 0:
        if abs(float(x[b]) - held) <= band:
            first, out = b, 0
        else:
            out += 1
            if out >= OUT_RUN:
                break
        b -= 1
    if b < 0 or b0 - first < min_blocks:  # held since the log's start (a level, not a
        return None                         # load that came), or not for long
    before = float(np.median(x[max(0, first - PRE_BLOCKS):first]))
    if abs(before - after) > 0.5 * step:
        return None
    return first, held, after


def mark_held(incidents: Sequence[Any], means: np.ndarray, per_block: int,
              period_s: float, joints: Sequence[str], loads: Sequence[Any] = ()
              ) -> list[Any]:
    """The incidents, each counted one that ended a load held before it marked
    ``held_before`` (module docstring): ``means`` (B, J) the residual's block means
    (:class:`BlockTrace`) of ``per_block`` samples of ``period_s`` [s], ``joints`` its
    columns, ``loads`` the lasting loads (a hold they overlap was seen)."""
    if means.shape[0] == 0:
        return list(incidents)
    sigma = block_noise(means)
    block_s = per_block * period_s
    least = int(np.ceil(HOLD_MIN_S / block_s - 1e-9))
    spans = [(x.t_start, x.t_end) for x in (*incidents, *loads) if not x.in_warmup]
    out = []
    for inc in incidents:
        if inc.number is None or inc.in_warmup:
            out.append(inc)
            continue
        b0 = inc.i_start // per_block
        found: dict[str, dict[str, float]] = {}
        since: float | None = None
        for j in inc.joints:
            k = list(joints).index(j)
            h = held_level(means[:, k], b0, float(sigma[k]),
                           float(inc.peak_residual.get(j, 0.0)), least)
            if h is None:
                continue
            t = h[0] * block_s
            if any(a < inc.t_start - 1e-9 and b > t for a, b in spans):
                continue  # an earlier finding overlaps the hold: its start was seen
            found[j] = {"held_nm": h[1], "after_nm": h[2]}
            since = t if since is None else min(since, t)
        if since is None:
            out.append(inc)
            continue
        out.append(replace(inc, held_before={"t_start": since, "joints": found,
                                             "text": held_text(inc.t_start, since, found)}))
    return out


def held_text(alarm_s: float, since_s: float, found: dict[str, dict[str, float]]) -> str:
    """``ended a load held since 11.868 s: elbow's residual stood at −34.7 N·m for 4.04 s,
    2.66 N·m after it — the contact began then; its alarm is its release, and its time,
    type and force are the release's``."""
    each = ", ".join(f"{j}'s residual stood at {v['held_nm']:.3g} N·m"
                     for j, v in found.items())
    after = ", ".join(f"{v['after_nm']:.3g} N·m" for v in found.values())
    return (f"ended a load held since {since_s:.3f} s: {each} for {alarm_s - since_s:.3g} s, "
            f"{after} after it — the contact began then; its alarm is its release, and its "
            "time, type and force are the release's")
