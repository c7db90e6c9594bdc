"""Which link: each joint's evidence of a contact's torque, against its own noise
(docs/incidents.md, "The rules").

A contact on link i exerts torque on joints 1..i only (r = J_cᵀ F), so the link is the most
distal joint whose residual carries the contact. Two kinds of evidence make a joint
*significant* during an incident, each gated against the leak of an inner contact onto the
outer joints through the arm's dynamic coupling (a small share of the inner joints'):

- **its detectors** (the calibrated thresholds): they fired — |LP(r)| ≥ vL or the adaptive
  decision — or |LP(r)| reached :data:`WEAK_FRACTION` of vL and :data:`COUPLING_FRACTION`
  of the largest ratio among the joints nearer the base;
- **its residual against its own noise at the incident**: the peak deviation of r from its
  level just before the incident, over the incident, is at least :data:`Z_MIN` times the
  joint's residual noise there (:class:`ResidualNoise`: causal exponentially weighted mean
  and standard deviation of r over :data:`NOISE_TAU_S`) and at least :data:`DEV_COUPLING`
  of the largest deviation among the joints nearer the base [N·m]. A threshold is set by
  the worst motion of the calibration; the noise at the incident is that of the motion
  there, so a contact's moment on a joint can stand out of its noise while staying under
  its thresholds (a contact near the joint, a joint whose calibration motion fitted badly).

When the evidence cannot tell two links apart, :func:`decide_link` says which links remain
(``link_candidates``): from the most distal joint whose evidence is sure (its detectors
fired, its statistic reached :data:`SURE_FRACTION` of vL, or a residual :data:`Z_SURE`
times its noise) to the most distal one whose evidence is only
possible (a residual :data:`Z_POSSIBLE` times its noise and :data:`DEV_COUPLING_POSSIBLE` of
the inner deviation, or half the detectors' weak criteria). The values were chosen on
simulated arms (robot seeds 301–302, tests/benchmarks/isolation_quality.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..model.iir import lfilter

#: A joint under its thresholds is significant when |LP(r)| reaches this fraction of its vL
#: *and* COUPLING_FRACTION of the largest ratio among the joints nearer the base.
WEAK_FRACTION = 0.5
COUPLING_FRACTION = 0.25
#: ... and sure evidence (no candidate nearer the base remains) from this fraction of vL
#: on: nearer WEAK_FRACTION a joint's statistic may be the coupling of an inner contact
#: (a trial's heavy arm, a 25 N push on link 2: joint 3 at 0.51 of its vL, link 3 said
#: sure; its pushes on link 3 reached 0.71-0.96 there).
SURE_FRACTION = 0.75
#: Time constant of the residual's running level and noise (:class:`ResidualNoise`) [s].
NOISE_TAU_S = 1.0
#: The noise is at least this fraction of the joint's vL (a still arm's residual noise is
#: its quantisation: no contact evidence is measured against that alone).
NOISE_FLOOR_FRACTION = 0.02
#: A joint's residual deviation is significant at this many times its noise ...
Z_MIN = 3.0
#: ... and this fraction of the largest deviation among the joints nearer the base.
DEV_COUPLING = 0.1
#: A residual deviation this many times the noise is sure evidence (no candidate nearer
#: the base remains).
Z_SURE = 8.0
#: Possible evidence (a candidate link): this many times the noise and this fraction of the
#: inner deviation.
Z_POSSIBLE = 2.5
DEV_COUPLING_POSSIBLE = 0.05


class ResidualNoise:
    """Each joint's causal residual level and noise, sample by sample, chunk after chunk:
    exponentially weighted mean m and mean square of r (time constant :data:`NOISE_TAU_S`),
    the noise sd = sqrt(E[r²] − m²). :meth:`update` gives, per sample, the values *before*
    it (what was known when it came); the noise is infinite (no residual evidence) until
    :data:`NOISE_TAU_S` of samples have been seen.

    Args:
        n_joints: J.  dt: sample period [s].
    """

    def __init__(self, n_joints: int, dt: float) -> None:
        self.a = min(1.0, float(dt) / NOISE_TAU_S)
        self.settle = int(np.ceil(NOISE_TAU_S / float(dt)))
        self.seen = 0
        self.zi: np.ndarray | None = None  # (1, 2J) filter state
        self.last = np.zeros((2, n_joints))  # the last sample's mean and mean square

    def update(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n, J) residual → ((n, J) level, (n, J) noise) before each sample."""
        r = np.asarray(r, dtype=np.float64)
        if r.shape[0] == 0:
            return r.copy(), r.copy()
        x = np.concatenate([r, r * r], axis=1)
        b, a = [self.a], [1.0, self.a - 1.0]
        if self.zi is None:
            self.zi = (1.0 - self.a) * x[:1]  # as if the first sample had always been
            self.last = np.stack([r[0], r[0] * r[0]])
        y, zf = lfilter(np.asarray(b), np.asarray(a), x, self.zi)
        self.zi = zf
        prev = np.concatenate([self.last.reshape(1, -1), y[:-1]], axis=0)
        self.last = y[-1].reshape(2, -1)
        j = r.shape[1]
        mean, sq = prev[:, :j], prev[:, j:]
        sd = np.sqrt(np.maximum(sq - mean * mean, 0.0))
        early = self.seen + np.arange(r.shape[0]) < self.settle
        sd[early] = np.inf
        self.seen += r.shape[0]
        return mean, sd


@dataclass(frozen=True)
class LinkDecision:
    """The link of a contact (1-based, chain order; None: no joint is significant) and the
    links the evidence cannot tell apart (``candidates``, ascending, the link among them;
    empty when ``link`` is None)."""

    link: int | None
    candidates: tuple[int, ...]


def decide_link(
    loading_ratio: np.ndarray, adaptive_fired: np.ndarray, chain_index: Sequence[int],
    residual: np.ndarray | None = None, level: np.ndarray | None = None,
    noise: np.ndarray | None = None, vl: np.ndarray | None = None,
) -> LinkDecision:
    """The link and its candidates from the evidence of each joint (module doc).

    Args:
        loading_ratio: (n, J) |LP(r)| / vL over the incident.
        adaptive_fired: (n, J) the adaptive decision over the incident.
        chain_index: (J,) each detected joint's 1-based position in the robot's chain.
        residual: (n, J) r over the incident [N·m]; level, noise: (J,) the residual's level
            and noise just before it (:class:`ResidualNoise`); vl: (J,) the static-loading
            thresholds (the noise floor). Without them, the detectors' evidence alone.
    """
    peak = np.max(loading_ratio, axis=0)
    fired = (peak >= 1.0) | np.any(adaptive_fired, axis=0)
    n_j = peak.shape[0]
    if residual is not None and level is not None and noise is not None:
        dev = np.max(np.abs(np.asarray(residual) - np.asarray(level)[None, :]), axis=0)
        floor = (NOISE_FLOOR_FRACTION * np.asarray(vl) if vl is not None
                 else np.zeros(n_j))
        z = dev / np.maximum(np.maximum(np.asarray(noise), floor), 1e-12)
    else:
        dev, z = np.zeros(n_j), np.zeros(n_j)
    sig, sure, poss = fired.copy(), fired.copy(), fired.copy()
    inner_ratio = inner_dev = 0.0
    for j in np.argsort(np.asarray(chain_index)):  # base first
        weak = peak[j] >= WEAK_FRACTION and peak[j] >= COUPLING_FRACTION * inner_ratio
        half = (peak[j] >= 0.5 * WEAK_FRACTION
                and peak[j] >= 0.5 * COUPLING_FRACTION * inner_ratio)
        coupled = dev[j] >= DEV_COUPLING * inner_dev
        res_sig = z[j] >= Z_MIN and coupled
        sig[j] = sig[j] or weak or res_sig
        sure[j] = sure[j] or (weak and peak[j] >= SURE_FRACTION) or (z[j] >= Z_SURE
                                                                     and coupled)
        poss[j] = poss[j] or sig[j] or half or (
            z[j] >= Z_POSSIBLE and dev[j] >= DEV_COUPLING_POSSIBLE * inner_dev)
        inner_ratio = max(inner_ratio, float(peak[j]))
        inner_dev = max(inner_dev, float(dev[j]))
    if not sig.any():
        return LinkDecision(None, ())
    pos = np.asarray(chain_index)
    link = int(pos[sig].max())
    lo = min(int(pos[sure].max()) if sure.any() else link, link)
    hi = max(int(pos[poss].max()), link)
    return LinkDecision(link, tuple(range(lo, hi + 1)))
