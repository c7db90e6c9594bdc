"""Contacts of the simulator and the ground-truth labels derived from them.

Three kinds (each enters eq. 1 as tau_ext = J_p(x2)^T F at its point p):

* :class:`Surface` — a horizontal elastomer under the end effector (kind ``impact``):
  unilateral, force ``max(0, k δ + c δ')`` straight up while the tip is below the surface
  (penetration δ > 0), zero otherwise. k is given in N/mm like the paper's elastomers;
  the default damping is c = 0.002 s × k (a "little damping": a 2 ms time constant).
* :class:`Push` — a half-sine force pulse on a link (kind ``push``).
* :class:`Clamp` — a slow linear ramp to a peak, a hold, and a release (kind ``clamp``).

Labels (docs/formats.md, "Ground-truth labels"): per contact source, an event spans the
samples where that source's force magnitude exceeds :data:`LABEL_THRESHOLD_N`; runs
separated by less than :data:`LABEL_MERGE_GAP_S` (bounces) are one event. ``start`` and
``end`` are the first and last such sample [s since the first sample]; ``peak_force`` is
the largest sampled force in the event [N]; ``link`` is 1-based.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..types import ContactLabel, Labels
from .kernel import PULSE, RAMP

#: A contact "exists" at a sample when its force exceeds this [N].
LABEL_THRESHOLD_N = 0.5
#: Above-threshold runs closer than this are one event (bounces on an elastomer) [s].
LABEL_MERGE_GAP_S = 0.1


@dataclass(frozen=True)
class Surface:
    """A horizontal elastomer at height ``height_m`` [m] spanning x in [x_min_m, x_max_m].

    Active for t in [t_on_s, t_off_s) (an experimenter swaps elastomers between impacts).
    stiffness in N/mm; damping in N·s/m (None: 0.002 s × stiffness).
    """

    height_m: float
    stiffness_n_per_mm: float
    x_min_m: float = -math.inf
    x_max_m: float = math.inf
    t_on_s: float = 0.0
    t_off_s: float = math.inf
    damping_ns_per_m: float | None = None

    def row(self) -> list[float]:
        k = self.stiffness_n_per_mm * 1000.0
        c = 0.002 * k if self.damping_ns_per_m is None else self.damping_ns_per_m
        return [self.height_m, self.x_min_m, self.x_max_m, k, c, self.t_on_s, self.t_off_s]


@dataclass(frozen=True)
class Push:
    """A half-sine force pulse: peak [N] at the middle of duration_s [s] starting at t0_s.

    Applied on link ``link`` (1-based) at ``point`` × its length from its joint, in the
    fixed world direction ``direction_deg`` (0 = +x, 90 = up).
    """

    link: int
    t0_s: float
    peak_n: float
    duration_s: float = 0.2
    point: float = 0.8
    direction_deg: float = -90.0

    def row(self) -> list[float]:
        return [self.link - 1, self.point, math.radians(self.direction_deg), self.peak_n,
                self.t0_s, self.duration_s, 0.0, 0.0, PULSE]


@dataclass(frozen=True)
class Clamp:
    """A clamping force: linear rise over rise_s to peak_n, hold hold_s, release release_s."""

    link: int
    t0_s: float
    peak_n: float
    rise_s: float = 3.0
    hold_s: float = 2.0
    release_s: float = 0.1
    point: float = 0.8
    direction_deg: float = -90.0

    def row(self) -> list[float]:
        return [self.link - 1, self.point, math.radians(self.direction_deg), self.peak_n,
                self.t0_s, self.rise_s, self.hold_s, self.release_s, RAMP]


def tables(surfaces: tuple[Surface, ...], pushes: tuple[Push, ...],
           clamps: tuple[Clamp, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's surface table (S, 7) and force table (P, 9); pushes before clamps."""
    s = np.array([x.row() for x in surfaces], dtype=np.float64).reshape(-1, 7)
    rows = [x.row() for x in pushes] + [x.row() for x in clamps]
    f = np.array(rows, dtype=np.float64).reshape(-1, 9)
    return s, f


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Inclusive (first, last) index pairs of the True runs of a boolean vector."""
    d = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


def label_contacts(time_s: np.ndarray, src_force: np.ndarray, *, kinds: list[str],
                   links: list[int], extras: list[dict[str, float]],
                   sample_rate_hz: float) -> Labels:
    """Ground-truth labels from sampled per-source contact forces.

    time_s (N,) [s since the first sample]; src_force (N, S) force magnitude per source
    [N]; kinds, links (1-based) and extras (merged into each event) per source.
    Events are sorted by start time.
    """
    gap = max(1, round(LABEL_MERGE_GAP_S * sample_rate_hz))
    events: list[ContactLabel] = []
    for k in range(src_force.shape[1]):
        f = src_force[:, k]
        runs = _runs(f > LABEL_THRESHOLD_N)
        merged: list[list[int]] = []
        for a, b in runs:
            if merged and a - merged[-1][1] <= gap:
                merged[-1][1] = b
            else:
                merged.append([a, b])
        for a, b in merged:
            events.append(ContactLabel(
                start=float(time_s[a]), end=float(time_s[b]),
                peak_force=float(np.max(f[a:b + 1])), kind=kinds[k], link=links[k],
                extra={"source": k, **extras[k]},
            ))
    events.sort(key=lambda e: (e.start, e.extra["source"]))
    return Labels(events=tuple(events), sample_rate=sample_rate_hz)  # the labels' own name
