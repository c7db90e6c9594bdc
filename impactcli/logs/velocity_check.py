"""Does a log's velocity channel say the motion its positions say? Checked in the scan's
one pass, where both are logged.

A logged velocity v is the positions' derivative; between samples k−1 and k the two
readings are the mean of v and the step Δq/Δt. Where they differ by more than
:data:`MISMATCH_RAD_S` and by more than :data:`MISMATCH_SHARE` of the larger, on some joint,
for :data:`MIN_STEPS` steps in a row and :data:`MIN_S` or more, the two channels do not
describe one motion: one of them is not the arm's there (a recording's end processed
apart, a filter's edge, a channel that froze). A lagging velocity estimate differs by its
lag times the acceleration — a few hundredths of a rad/s on an arm's motion, and for a
step or two at a braking; a real collision changes both channels alike.

Measured: a real KUKA LWR4's log disagrees on all 7 joints over its last 0.11 s (the
positions stop, the velocities go on at 0.36 rad/s, the torques move as if the arm still
moved), where a detector alarms; the real UR logs and every simulated sample log agree
throughout (the ASSIST-like payload log's first 52 ms, a load put on the simulated arm at
its first sample, disagree for less than :data:`MIN_S`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The two readings of a joint's velocity differ by more than this [rad/s] ...
MISMATCH_RAD_S = 0.05
#: ... and by more than this share of the larger of them ...
MISMATCH_SHARE = 0.5
#: ... for this many steps in a row and this long [s]: a lagging estimate disagrees for
#: about its lag (at a braking a step or two; through the simulator's jolt of a load put on
#: at its first sample, a 40 Hz estimate for 52 ms), two readings of two motions go on.
MIN_STEPS = 10
MIN_S = 0.08
#: At most this many stretches are kept (all are counted).
MAX_KEPT = 100
#: The two agree elsewhere when they disagree on at most this share of all steps: else
#: the velocity channel is not these positions' derivative (another quantity, a coarse
#: estimate), and its stretches say nothing of the data.
AGREE_SHARE = 0.05


@dataclass(frozen=True)
class Disagreement:
    """A stretch where the logged velocity and the positions' steps disagree: from the
    sample before its first step to the sample after its last (``t_start_ns``,
    ``t_end_ns``, the log's clock), its ``steps``, the ``joints`` (indices) that disagreed
    and the largest difference [rad/s]."""

    t_start_ns: int
    t_end_ns: int
    steps: int
    joints: tuple[int, ...]
    largest_rad_s: float


class VelocityAgreement:
    """The stretches of :class:`Disagreement`, fed chunk by chunk (state carried across
    chunks: :meth:`add` in order, then :meth:`finish`)."""

    def __init__(self, n_joints: int) -> None:
        self.prev: tuple[int, np.ndarray, np.ndarray] | None = None  # t [ns], q, v
        self.open = False  # a run of disagreeing steps goes on at the last chunk's end
        self.run_t = [0, 0]  # its first and last sample [ns]
        self.run_steps = 0
        self.run_largest = 0.0
        self.run_joints = np.zeros(n_joints, dtype=bool)
        self.found: list[Disagreement] = []  # the first MAX_KEPT
        self.n_found = 0
        self.steps = 0  # steps judged, and those where the two disagreed
        self.bad_steps = 0

    def add(self, t_ns: np.ndarray, q: np.ndarray, v: np.ndarray) -> None:
        """Rows ``t_ns`` (n,) int64, positions ``q`` and velocities ``v`` (n, J) [rad,
        rad/s] (NaN: not logged there, no judgement)."""
        if t_ns.size == 0:
            return
        if self.prev is not None:
            t_ns = np.concatenate(([self.prev[0]], t_ns))
            q = np.concatenate((self.prev[1][None, :], q))
            v = np.concatenate((self.prev[2][None, :], v))
        self.prev = (int(t_ns[-1]), q[-1].copy(), v[-1].copy())
        if t_ns.size < 2:
            return
        dt = np.diff(t_ns).astype(np.float64) * 1e-9
        with np.errstate(invalid="ignore", divide="ignore"):
            step = np.diff(q, axis=0) / dt[:, None]
            mid = 0.5 * (v[1:] + v[:-1])
            gap = np.abs(mid - step)
            bad = (gap > np.maximum(MISMATCH_RAD_S, MISMATCH_SHARE
                                    * np.maximum(np.abs(mid), np.abs(step))))
        bad &= np.isfinite(gap) & (dt[:, None] > 0)
        any_bad = bad.any(axis=1)
        n = int(any_bad.size)
        self.steps += n
        self.bad_steps += int(np.count_nonzero(any_bad))
        if self.open and not any_bad[0]:
            self._close()
        edges = np.diff(np.concatenate(([0], any_bad.astype(np.int8), [0])))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        # only runs long enough, or touching the chunk's ends (they may go on), are kept
        for a, z in zip(starts, ends, strict=True):
            if z - a < MIN_STEPS and a > 0 and z < n:
                continue
            if not self.open:
                self.open, self.run_t[0], self.run_steps = True, int(t_ns[a]), 0
                self.run_largest, self.run_joints[:] = 0.0, False
            self.run_t[1] = int(t_ns[z])
            self.run_steps += int(z - a)
            self.run_largest = max(self.run_largest,
                                   float(np.max(np.where(bad[a:z], gap[a:z], 0.0))))
            self.run_joints |= bad[a:z].any(axis=0)
            if z < n:
                self._close()

    def _close(self) -> None:
        if (self.open and self.run_steps >= MIN_STEPS
                and self.run_t[1] - self.run_t[0] >= MIN_S * 1e9):
            self.n_found += 1
            if len(self.found) < MAX_KEPT:
                self.found.append(Disagreement(
                    self.run_t[0], self.run_t[1], self.run_steps,
                    tuple(int(j) for j in np.flatnonzero(self.run_joints)),
                    self.run_largest))
        self.open = False

    def finish(self) -> list[Disagreement]:
        """The first :data:`MAX_KEPT` stretches found (a run still open at the log's end
        closed there); ``n_found`` counts them all."""
        self._close()
        return self.found


#: At most this many stretches are named in the warning (all are counted).
MAX_NAMED = 3


def disagreement_message(where: str, agreement: VelocityAgreement, keep: list[int],
                         joints: tuple[str, ...], first_ns: int, last_ns: int) -> str | None:
    """The warning naming where the logged velocity and the positions tell two motions
    (on the kept joints; times in s since the log's first sample, ``first_ns``), or None.
    Only for a velocity that is these positions' derivative elsewhere: the caller's test of
    the rate it implies, and disagreeing on at most :data:`AGREE_SHARE` of the steps."""
    found = _named(agreement, keep)
    if not found:
        return None
    uncounted = agreement.n_found - len(agreement.found)  # beyond those kept
    def when(d: Disagreement) -> str:
        a = (d.t_start_ns - first_ns) * 1e-9
        end = ("the log's end" if d.t_end_ns >= last_ns
               else f"{(d.t_end_ns - first_ns) * 1e-9:.3f} s")
        names = [joints[j] for j in d.joints if j in keep]
        on = (f"all {len(names)} joints" if len(names) == len(keep) and len(names) > 1
              else ", ".join(names))
        return f"{a:.3f} s to {end} ({on}, up to {d.largest_rad_s:.2g} rad/s apart)"
    extra = len(found) - MAX_NAMED + uncounted
    more = f" and {extra} more" if extra > 0 else ""
    return (f"{where}: the logged velocity and the positions' steps tell two motions at "
            + "; ".join(when(d) for d in found[:MAX_NAMED]) + more
            + ", where they agree elsewhere: one of them is not the arm's motion there (a "
            "recording's end processed apart, a filter's edge, a frozen channel), so an "
            "incident there may be the data's, not a contact")


def disagreement_stretches(agreement: VelocityAgreement, keep: list[int],
                           joints: tuple[str, ...], first_ns: int
                           ) -> tuple[tuple[float, float, tuple[str, ...]], ...]:
    """The stretches :func:`disagreement_message` is about, as (from [s], to [s], the kept
    joints that disagreed) since the log's first sample (``first_ns``); () when it says
    none. The incidents that overlap one are marked
    (:func:`impactcli.detect.incidents.mark_disagreeing`)."""
    return tuple(((d.t_start_ns - first_ns) * 1e-9, (d.t_end_ns - first_ns) * 1e-9,
                  tuple(joints[j] for j in d.joints if j in keep))
                 for d in _named(agreement, keep))


def _named(agreement: VelocityAgreement, keep: list[int]) -> list[Disagreement]:
    """The stretches on kept joints, where the two agree elsewhere (on all but at most
    :data:`AGREE_SHARE` of the steps); [] else."""
    found = [d for d in agreement.finish() if any(j in keep for j in d.joints)]
    return found if agreement.bad_steps <= AGREE_SHARE * agreement.steps else []
