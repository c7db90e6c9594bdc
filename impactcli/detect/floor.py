"""The detection floor: the smallest contact a run could have seen (docs/method.md §5b,
"The detection floor").

Per joint j and sample k after j's warm-up, the torque a contact must ADD to the residual
for a product detector to cross its threshold there, for two reference contacts:

* a **step** (a lasting push) for the static-loading detector: the low-passed residual
  settles at LP(r) + tau, so it crosses vL once |tau| >= vL − |LP(r)(k)| (the favourable
  sign; 0 where it already alarms: there a contact joins the alarm that is on, and when a
  quantile falls on such samples the floor states no figure but the share of them,
  ``in_alarm`` — a joint in a lasting load for most of the log sees no new contact);
* a **half-sine of 100 ms** (a blow) for the adaptive detector: the statistic r_rms
  (eq. 41 of G_hat r through F1) responds to a unit half-sine with a peak ``g_j(k)``
  (:func:`pulse_gain`, with G_hat as it stood at sample k, eq. 29: the evaluator keeps
  theta_G at every :data:`GAIN_EVERY`-th sample, :func:`gain_per_sample`), and RMS is
  subadditive, so the statistic cannot cross the dynamic threshold (eq. 42) unless
  A >= (threshold(k) − r_rms(k)) / g_j(k). G_hat whitens the residual: while the arm
  moves it passes a slow blow less than at rest (measured once, on a new user's probe: a
  median gain of 0.52 on the shoulder where the log's last, resting G_hat gave 0.94; the
  floor taken with that one was half as large). The RLS adapts to a blow while it lasts
  and passes it less still, which this bound leaves out (tests/test_floor.py).

Both are lower bounds under their assumptions (linear filters, the contact's torque on
this joint alone, G_hat frozen over the blow — the RLS adapting to it only passes it
less): a smaller contact of that shape was not seen; a larger one is not promised.
The floor varies along the log (the residual's level, the dynamic threshold): the
run states its median and its worst tenth (the 90th percentile), from log-spaced
histograms (bounded memory; each quantile is its bin's LOWER edge, within 5 % below the
true one — "below ~X not seen" stays true). With a link-end Jacobian, the floor of
joint i becomes a force at the end of link i (the direction that turns joint i most:
force = tau / |J_i|, :func:`impactcli.detect.force.own_levers`) over up to
:data:`MAX_POSTURES` postures spread along the log: the median force with the median
torque, and the worst tenth over postures with the worst-tenth torque.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..types import GRAVITY_M_S2
from .force import MIN_LEVER_M, JacobianFn, link_jacobians, own_levers

#: The adaptive detector's reference contact: a half-sine of this duration [s].
HALF_SINE_S = 0.1
#: Histogram bins per decade of torque, and its range [N·m] (below: the "0" bin).
BINS_PER_DECADE = 50
LOG10_LO, LOG10_HI = -9, 9
_EDGES = 10.0 ** (np.arange(LOG10_LO * BINS_PER_DECADE, LOG10_HI * BINS_PER_DECADE + 1)
                  / BINS_PER_DECADE)
#: After the warm-up's longest possible end, every SAMPLE_EVERY-th sample goes into the
#: histograms (the quantiles of a log's floor do not need every sample; the cost stays a
#: small share of the replay's).
SAMPLE_EVERY = 4
#: The blow's gain through G_hat is taken with G_hat as it stood at every GAIN_EVERY-th
#: sample of the log (the evaluator keeps theta_G there; the samples between take the last
#: one: G_hat forgets over 1 / (1 − lambda) = 1000 samples by default).
GAIN_EVERY = 16
#: Postures kept along the log for the link forces.
MAX_POSTURES = 256
#: The quantiles stated: the median and the worst tenth.
QUANTILES = {"median": 0.5, "worst_tenth": 0.9}
DETECTORS = ("static_loading", "adaptive")
REFERENCE_CONTACTS = {
    "static_loading": "a step (a lasting push), through the low-pass of the loading detector",
    "adaptive": f"a half-sine of {HALF_SINE_S * 1000:g} ms (a blow), through G_hat, F1 and "
                "the RMS window of the adaptive detector",
}


def pulse_gain(theta_g: np.ndarray, sample_rate_hz: float, a1: float, n1: int,
               duration_s: float = HALF_SINE_S) -> np.ndarray:
    """(...) the peak of r_rms (eq. 41: RMS over the N1 samples before k of F1's output)
    for a unit half-sine of ``duration_s`` added to the residual, through
    G(z) = 1 − sum_d theta_G[d−1] z^−d (eq. 29; ``theta_g`` (..., eta), one G per leading
    index) and F1 (pole a1).

    G and F1 are linear and time-invariant, so F1(G x) = c · b(k) with c = (1, −theta_G)
    and b(k) = F1(x) and its delays by 1..eta at k; the window's sum of squares is then the
    quadratic form c W_k cᵀ, W_k = sum over the window of b bᵀ (precomputed once): one
    matrix product per block of G's."""
    th = np.asarray(theta_g, dtype=np.float64)
    lead, eta = th.shape[:-1], th.shape[-1]
    m = max(1, round(duration_s * sample_rate_hz))
    n = m + n1 + max(1, round(5.0 / max(1.0 - a1, 1e-12))) + 1  # the pulse, the window, F1's decay
    x = np.zeros(n)
    x[:m] = np.sin(np.pi * (np.arange(m) + 0.5) / m)
    y0 = np.empty(n)
    prev = 0.0
    for k in range(n):
        prev = a1 * prev + (1.0 - a1) * x[k]
        y0[k] = prev
    e = eta + 1
    basis = np.zeros((e, n))  # F1(x) and its delays by 1..eta samples
    basis[0] = y0
    for d in range(1, eta + 1):
        basis[d, d:] = y0[:-d]
    iu, ju = np.triu_indices(e)
    prod = basis[iu] * basis[ju]  # (pairs, n): b_i b_j at each sample
    cum = np.concatenate((np.zeros((len(iu), 1)), np.cumsum(prod, axis=1)), axis=1)
    win = cum[:, n1:n] - cum[:, : n - n1]  # W_k's entries, the window k−N1 .. k−1
    twice = np.where(iu == ju, 1.0, 2.0)
    flat = th.reshape(-1, eta)
    out = np.empty(flat.shape[0])
    for a in range(0, flat.shape[0], _GAIN_BLOCK):  # bounded memory: a block of G's at once
        c = np.concatenate((np.ones((min(_GAIN_BLOCK, flat.shape[0] - a), 1)),
                            -flat[a:a + _GAIN_BLOCK]), axis=1)
        peak = ((c[:, iu] * c[:, ju] * twice) @ win).max(axis=1, initial=0.0)
        out[a:a + _GAIN_BLOCK] = np.sqrt(np.maximum(peak, 0.0) / n1)
    return out.reshape(lead)


#: G_hat's taken at once by :func:`pulse_gain` (its memory: this × the response's length).
_GAIN_BLOCK = 2048


def gain_per_sample(theta_g: np.ndarray, n: int, k0: int, sample_rate_hz: float, a1: float,
                    n1: int, before: np.ndarray | None = None) -> np.ndarray:
    """(n, J) each sample's :func:`pulse_gain` of a chunk of n samples from the log's
    sample ``k0``, with G_hat as it stood at the last sample at or before it whose index is
    a multiple of :data:`GAIN_EVERY` (``theta_g`` (S, J, eta): the evaluator's
    snapshots there, :attr:`impactcli.detect.adaptive.AdaptiveResult.theta_g`); the
    samples before the chunk's first snapshot take ``before`` (J,) (the previous chunk's
    last gain; None: the first snapshot's). float32: the floor's bins are 5 % wide, and
    the replay spills it with every sample when it has no thresholds yet."""
    th = np.asarray(theta_g, dtype=np.float64)
    if th.shape[0] == 0:
        if before is None:
            raise ValueError("a chunk without a snapshot of G_hat and no gain before it")
        return np.broadcast_to(np.asarray(before, dtype=np.float32), (n, before.shape[0]))
    g = pulse_gain(th, sample_rate_hz, a1, n1).astype(np.float32)  # (S, J)
    off = (-k0) % GAIN_EVERY
    idx = (np.arange(n) - off) // GAIN_EVERY
    out = g[np.clip(idx, 0, g.shape[0] - 1)]
    if before is not None and off:
        out[:off] = before
    return np.asarray(out)


def _bins(x: np.ndarray) -> np.ndarray:
    """The histogram bin of each margin x ≥ 0: k ≥ 1 holds [_EDGES[k−1], _EDGES[k]) (from
    the edges' log spacing), 0 below 10^LOG10_LO (an alarm's 0 included)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.floor((np.log10(x) - LOG10_LO) * BINS_PER_DECADE) + 1.0
    return np.clip(np.nan_to_num(k, nan=0.0, neginf=0.0, posinf=_EDGES.size),
                   0, _EDGES.size).astype(np.intp)


def _quantile(counts: np.ndarray, q: float) -> float | None:
    """The lower edge of the bin holding the q-quantile (None without samples)."""
    total = int(counts.sum())
    if total == 0:
        return None
    k = int(np.searchsorted(np.cumsum(counts), q * total))
    return 0.0 if k == 0 else float(_EDGES[k - 1])


class FloorAccumulator:
    """The floor's margins, fed chunk by chunk in order (the streamed replay): histograms
    of the samples after ``hold`` samples, the first ``hold`` kept (the warm-up is known
    only at the end; it ends by ``warmup.max_s``), and postures every ``stride`` samples.

    Args:
        n_joints: J.  n_samples: the log's length.  hold: samples kept before the
            histograms (≥ the latest a warm-up may end).
        v_l: (J,) the static-loading thresholds [N·m].
    """

    def __init__(self, n_joints: int, n_samples: int, hold: int, v_l: np.ndarray) -> None:
        self.J = n_joints
        self.hold = max(0, min(hold, n_samples))
        self.v_l = np.asarray(v_l, dtype=np.float64)
        nb = _EDGES.size + 1
        self.counts = {d: np.zeros((n_joints, nb), dtype=np.int64) for d in DETECTORS}
        self.head = {d: np.zeros((self.hold, n_joints)) for d in DETECTORS}
        self.stride = max(1, n_samples // MAX_POSTURES)
        self.post_k: list[int] = []
        self.post_q: list[np.ndarray] = []
        self.gain_k: list[int] = []
        self.gain_g: list[np.ndarray] = []
        self.k = 0

    def update(self, loading: np.ndarray, r_rms: np.ndarray, threshold: np.ndarray,
               q_full: np.ndarray | None, gain: np.ndarray) -> None:
        """Feed one chunk: (n, J) |LP(r)|, r_rms, the adaptive threshold and each sample's
        :func:`pulse_gain` (:func:`gain_per_sample`); ``q_full`` (n, C) the log's
        positions (for the postures), or None."""
        n = loading.shape[0]
        if n == 0:
            return
        gain = np.broadcast_to(np.asarray(gain, dtype=np.float64), loading.shape)
        with np.errstate(invalid="ignore", divide="ignore"):
            margins = {"static_loading": np.maximum(self.v_l[None, :] - np.abs(loading), 0.0),
                       "adaptive": np.where(gain > 0, np.maximum(threshold - r_rms, 0.0)
                                            / gain, np.inf)}
        k0, k1 = self.k, self.k + n
        nb = _EDGES.size + 1
        offset = nb * np.arange(self.J)
        for d, m in margins.items():
            if k0 < self.hold:
                take = min(k1, self.hold) - k0
                self.head[d][k0:k0 + take] = m[:take]
            # after the held samples: every SAMPLE_EVERY-th sample of the log
            first = max(self.hold, k0)
            first += (-first) % SAMPLE_EVERY
            rows = m[first - k0::SAMPLE_EVERY]
            if rows.size:
                # +inf (a blow G_hat does not pass: no size is seen) counts in the top bin
                fin = ~np.isnan(rows)
                flat = (_bins(np.where(fin, rows, 0.0)) + offset[None, :])[fin]
                self.counts[d] += np.bincount(flat, minlength=nb * self.J).reshape(self.J, nb)
        if q_full is not None:
            first = (-k0) % self.stride
            for i in range(first, n, self.stride):
                self.post_k.append(k0 + i)
                self.post_q.append(np.array(q_full[i], dtype=np.float64))
        first = (-k0) % self.stride  # the gains there, for the median stated
        for i in range(first, n, self.stride):
            self.gain_k.append(k0 + i)
            self.gain_g.append(np.array(gain[i], dtype=np.float64))
        self.k = k1

    def finish(self, warmup_index: Sequence[int] | np.ndarray, warmup_end: int,
               joints: Sequence[str], chain: Sequence[str] | None = None,
               index: Sequence[int] | None = None,
               chain_cols: Sequence[int | None] | None = None,
               jac: JacobianFn | None = None) -> dict[str, Any]:
        """The floor (module docstring) as the timeline's ``detection_floor`` mapping.

        Args:
            warmup_index: (J,) each joint's first sample after warm-up.  warmup_end: the
                latest (postures before it are dropped).
            joints: the detected joints.  chain, index, chain_cols, jac: the robot's chain,
                each joint's 1-based link number in it, each chain joint's column in the
                log's positions (None: held at 0) and the link-end Jacobian (None: no forces).
        """
        counts = {d: c.copy() for d, c in self.counts.items()}
        for d in DETECTORS:
            for j in range(self.J):
                m = self.head[d][int(warmup_index[j]):self.k, j][::SAMPLE_EVERY]
                m = m[~np.isnan(m)]
                counts[d][j] += np.bincount(_bins(m), minlength=counts[d].shape[1])
        per_joint: dict[str, Any] = {}
        torque = {d: {qn: np.full(self.J, np.nan) for qn in QUANTILES} for d in DETECTORS}
        for j, name in enumerate(joints):
            row: dict[str, Any] = {}
            for d in DETECTORS:
                vals: dict[str, Any] = {}
                total = int(counts[d][j].sum())
                alarming = int(counts[d][j][0]) / total if total else 0.0
                for qn, q in QUANTILES.items():
                    v = _quantile(counts[d][j], q)
                    # 0: the detector already alarms there, so a contact joins that alarm
                    # and is not seen as one of its own: no floor, the share said instead
                    # none above the top bin: no size of contact was seen there
                    vals[f"{qn}_nm"] = (None if v is None or v == 0.0 or v >= _EDGES[-1]
                                        else v)
                    if vals[f"{qn}_nm"] is not None:
                        torque[d][qn][j] = vals[f"{qn}_nm"]
                    elif v == 0.0:
                        vals["in_alarm"] = alarming
                row[d] = vals
            per_joint[name] = row
        out: dict[str, Any] = {
            "reference_contacts": dict(REFERENCE_CONTACTS),
            "half_sine_s": HALF_SINE_S,
            "pulse_gain": self._median_gain(warmup_index, joints),
            "per_joint": per_joint,
            "per_link": None,
        }
        keep = [i for i, k in enumerate(self.post_k) if k >= warmup_end]
        if jac is None or chain is None or index is None or chain_cols is None or not keep:
            return out
        links: list[dict[str, Any]] = []
        postures = np.zeros((len(keep), len(chain)))
        for p, i in enumerate(keep):
            for c, col in enumerate(chain_cols):
                if col is not None:
                    postures[p, c] = self.post_q[i][col]
        levers = own_levers(postures, len(chain), jac)  # once, for every detector and quantile
        link_joint = {index[j] - 1: j for j in range(self.J)}
        # a link that ends on its own joint's axis: the joints before it see a force there
        # (|tau_k| <= |J_k| |F|: below min_k threshold_k / |J_k| no joint's is reached)
        axial = {c: _inner_levers(postures, c, jac) for c in link_joint
                 if np.isnan(levers[:, c]).all() and jac(postures[0], c + 1) is not None}
        for d in DETECTORS:
            for qn in QUANTILES:
                forces = np.full((len(postures), len(chain)), np.nan)
                for j in range(self.J):
                    # a joint whose median is none (alarming for most of the log: a contact
                    # there joins its alarm) gives no link its floor at either quantile, so
                    # that the worst tenth never falls below the median
                    v = torque[d][qn][j] if math.isfinite(torque[d]["median"][j]) else math.nan
                    if math.isfinite(v):  # the force that reaches joint j's own threshold
                        forces[:, index[j] - 1] = float(v) / levers[:, index[j] - 1]
                for c, arms in axial.items():
                    for j in range(self.J):
                        v, k = torque[d][qn][j], index[j] - 1
                        if not math.isfinite(torque[d]["median"][j]):
                            continue  # as above
                        if k < c and math.isfinite(v):
                            with np.errstate(divide="ignore", invalid="ignore"):
                                f = np.where(arms[:, k] >= MIN_LEVER_M, float(v) / arms[:, k],
                                             np.nan)
                            forces[:, c] = np.fmin(forces[:, c], f)
                over = 0.5 if qn == "median" else 0.9
                for c in range(len(chain)):
                    col = forces[:, c][np.isfinite(forces[:, c])]
                    while len(links) <= c:
                        links.append({"link": len(links) + 1, "joint": chain[len(links)]})
                    links[c].setdefault(d, {})[f"{qn}_n"] = (
                        float(np.quantile(col, over)) if col.size else None)
        for c in axial:
            links[c]["no_lever"] = True
            links[c]["own_joint"] = joints[link_joint[c]]  # its name in per_joint
        out["per_link"] = links
        out["postures"] = len(postures)
        if (step := _weight_step(postures, len(chain) - 1, jac, index,
                                 torque["static_loading"]["median"])) is not None:
            out["payload_step"] = step
        return out


    def _median_gain(self, warmup_index: Sequence[int] | np.ndarray,
                     joints: Sequence[str]) -> dict[str, float | None]:
        """Each joint's median :func:`pulse_gain` over the log after its warm-up (at the
        samples the postures are kept at; None where none is)."""
        out: dict[str, float | None] = {}
        for j, name in enumerate(joints):
            g = [x[j] for k, x in zip(self.gain_k, self.gain_g, strict=True)
                 if k >= int(warmup_index[j]) and np.isfinite(x[j])]
            out[name] = float(np.median(g)) if g else None
        return out


def _weight_step(postures: np.ndarray, c: int, jac: JacobianFn, index: Sequence[int],
                 median_nm: np.ndarray) -> dict[str, Any] | None:
    """The least weight at the end of the chain's last link (0-based ``c``: the flange)
    whose step reaches some joint's static-loading threshold at the log's median moment:
    per posture min over the joints k up to it of vL_k / |J_k| (|tau_k| <= |J_k| |F|, any
    direction, gravity's too), the median over postures; as ``{"force_n", "kg"}``
    (kg = force / g). None where no joint has a lever there."""
    arms = _inner_levers(postures, c, jac)
    best = np.full(len(postures), np.nan)
    for j, v in enumerate(np.asarray(median_nm, dtype=np.float64)):
        k = int(index[j]) - 1
        if k <= c and math.isfinite(float(v)):
            with np.errstate(divide="ignore", invalid="ignore"):
                f = np.where(arms[:, k] >= MIN_LEVER_M, float(v) / arms[:, k], np.nan)
            best = np.fmin(best, f)
    col = best[np.isfinite(best)]
    if not col.size:
        return None
    force = float(np.median(col))
    return {"force_n": force, "kg": force / GRAVITY_M_S2}


def _inner_levers(postures: np.ndarray, c: int, jac: JacobianFn) -> np.ndarray:
    """(P, c + 1) each joint k <= c's lever |J_k| to the end of link c + 1 (0-based c) at
    each posture."""
    jacs = np.stack([np.asarray(j) for j in link_jacobians(postures, c + 1, jac)])
    return np.asarray(np.linalg.norm(jacs, axis=1))


#: A link's floor also gives the static-loading detector's own (a push held until its
#: low-pass settles) when it is more than this many times the smallest: the adaptive
#: detector's blow figure says nothing of a push it filters out (a trial read "~4.6 N·m"
#: beside a 38 N·m push held 6 s and missed on a real UR arm, whose push figure was 98).
PUSH_APART = 2.0
#: What a floor's sentence says it is.
LOWER_BOUND = "a lower bound, not a promise that a larger one was seen"
#: Links or joints a floor's sentence names at most (the largest floors).
MAX_LISTED = 6
#: Where the floors in N act (the module docstring: a force at the link's end in the
#: direction that turns its joint most), said beside them: a trial read "~14 N on link 1"
#: as any 14 N contact, and a 25 N push there went unseen.
FORCE_AT = ("N: a force at the link's end, normal to it; one nearer its joint or aslant "
            "needs more")


def floor_line(floor: dict[str, Any] | None) -> str | None:
    """The run's floor in one phrase for the terminal and the verdict, e.g. ``a contact
    below ~45 N on link 2 (~60 N in the worst tenth of the log) would not have been seen at
    the log's median moment (at quieter moments a smaller one can be)`` — a new user read
    "would not have been seen" beside 5 N pushes caught under a ~10 N floor
    — per link with forces, else per joint with torques; the smallest over the two
    reference contacts; at most :data:`MAX_LISTED` (the largest); None without a floor."""
    if not floor:
        return None
    per_joint = floor.get("per_joint", {})
    if floor.get("per_link"):
        items = [(f"link {row['link']}", row) for row in floor["per_link"]]
        key, unit, head = "_n", "N", "a contact below"
    else:
        items = list(per_joint.items())
        key, unit, head = "_nm", "N·m", "a contact adding less than"
    parts: list[tuple[float, str]] = []
    axial: list[str] = []  # links ending on their joint's axis, no joint before: torques
    inner: list[str] = []  # links ending on their joint's axis: seen by the joints before
    for where, row in items:
        m = _smallest(row, "median" + key)
        w = _smallest(row, "worst_tenth" + key)
        if m is not None:
            push = (row.get("static_loading") or {}).get("median" + key)
            said = ([f"~{_approx(w)} {unit} in the worst tenth"] if w is not None
                    and w > 1.05 * m else []) + (
                [f"held as a push: ~{_approx(push)} {unit}"] if push is not None
                and push > PUSH_APART * m else [])
            parts.append((m, f"~{_approx(m)} {unit} on {where}"
                          + (f" ({'; '.join(said)})" if said else "")))
            if row.get("no_lever"):
                inner.append(str(row["link"]))
        elif row.get("no_lever") and isinstance(per_joint.get(row.get("own_joint")), dict):
            t = _smallest(per_joint[row["own_joint"]], "median_nm")
            if t is not None:
                axial.append(f"~{_approx(t)} N·m on {row['own_joint']}")
    # joints with no median from either detector, one of them already alarming there
    alarming = [f"{name} ({100 * a:.3g} %)" for name, row in per_joint.items()
                if _smallest(row, "median_nm") is None
                and (a := max((row[d].get("in_alarm", 0.0) for d in DETECTORS
                               if isinstance(row.get(d), dict)), default=0.0)) >= 0.5]
    if not parts and not axial and not alarming:
        return None
    shown = _largest(parts)
    if axial:  # always said: these floors are no force at all
        shown.append(f"{'and ' if shown else ''}a torque below {', '.join(axial)} "
                     + ("(its link ends on the joint's axis: no force there turns it)"
                        if len(axial) == 1 else
                        "(their links end on the joints' axes: no force there turns them)"))
    note = ""
    if inner:
        note = (f" (links {', '.join(inner)} end on their own joints' axes"
                if len(inner) > 1 else f" (link {inner[0]} ends on its own joint's axis")
        note += ": the force there is what the joints before see)"
    busy = ("" if not alarming else
            f"{', '.join(alarming)} had a detector already alarming for most of the log after "
            "warm-up: a contact there joins that alarm, so no floor is stated for them")
    if not shown:
        return busy
    at = f" ({FORCE_AT})" if unit == "N" and parts else ""
    return (f"{head} {', '.join(shown)}{at} would not have been seen at the log's median "
            f"moment (at quieter moments a smaller one can be){note}; {LOWER_BOUND}"
            + (f"; {busy}" if busy else ""))


def probed_line(floor: dict[str, Any] | None) -> str | None:
    """The measured floor (``floor["probed"]``, :mod:`impactcli.detect.probe`) in one
    phrase, e.g. ``a 100 ms blow was caught at half the moments judged from ~5.5 N on link
    1 (at nine in ten from ~7.3 N; 31 of 32 judged) … — 32 moments probed after warm-up,
    …`` — per link with forces (a link ending on its joint's axis by that joint's torque),
    else per joint with torques; at most :data:`MAX_LISTED` (the largest); None without
    it. A median is what about half the blows of its size reach, not a size from which all
    are caught, and the moments where a detector already alarmed are not judged: both
    are said."""
    probed = (floor or {}).get("probed")
    if not probed:
        return None
    total = int(probed["probes"])
    per_joint = probed.get("per_joint", {})
    links = probed.get("per_link")
    items: list[tuple[str, dict[str, Any], str]] = []
    for row in links or ():
        if row.get("no_lever") and isinstance(per_joint.get(row.get("own_joint")), dict):
            items.append((f"{row['own_joint']} (link {row['link']} ends on its axis)",
                          per_joint[row["own_joint"]], "_nm"))
        elif not row.get("no_lever"):
            items.append((f"link {row['link']}", row, "_n"))
    if not links:
        items = [(name, row, "_nm") for name, row in per_joint.items()]
    parts: list[tuple[float, str]] = []
    busy: list[str] = []
    for where, row, key in items:
        unit = "N" if key == "_n" else "N·m"
        m, w = row.get("median" + key), row.get("worst_tenth" + key)
        judged = int(row.get("probes", 0))
        of = "" if judged == total else f"; {judged} of {total} judged"
        if m is not None:
            nine = (f"at nine in ten from ~{_approx(w)} {unit}" if w is not None else
                    "too few judged for nine in ten" if judged < 10 else
                    f"not caught at {row.get('uncaught', 0)} of {judged} however large")
            parts.append((m, f"~{_approx(m)} {unit} on {where} ({nine}{of})"))
        elif 0 < judged < 5 and row.get("uncaught", 0) * 2 < judged:
            busy.append(f"on {where}, only {judged} of {total} moments judged (a detector "
                        "already alarming at the rest): too few for a figure" if judged < total
                        else f"on {where}, only {_moments(judged)} judged: too few for a "
                        "figure")
        elif judged and row.get("uncaught", 0) * 2 >= judged:
            busy.append(f"on {where}, no blow however large was caught at "
                        f"{row['uncaught']} of {judged} moments judged")
        elif row.get("in_alarm"):
            busy.append(f"on {where}, a detector was already alarming at "
                        f"{row['in_alarm']} of {total} moments (none judged)")
    if not parts and not busy:
        return None
    tails = {b.split(", ", 1)[1] for b in busy}
    if not parts and len(busy) > 1 and len(tails) == 1:  # the same on each: said once
        tail = tails.pop()
        hint = (" (the moments probed lie at least the adaptive filter's memory apart: a "
                "longer log gives more)" if tail.endswith("judged: too few for a figure")
                and "alarming" not in tail else "")
        busy = [f"on every {'link' if links else 'joint'}, {tail}{hint}"]
    shown = _largest(parts)
    at = f" ({FORCE_AT})" if any(key == "_n" for _, _, key in items) else ""
    ms = 1000 * float((floor or {}).get("half_sine_s", HALF_SINE_S))
    said = ([f"a {ms:g} ms blow was caught at half the moments judged from "
             + ", ".join(shown) + at] if shown else []) + busy
    return ("; ".join(said) + f" — {_moments(total)} probed after warm-up, each replayed "
            f"with a {ms:g} ms blow added to the residual through both detectors from "
            "their own state, and judged within its window; one where a detector was "
            "already alarming is not judged (a blow there joins that alarm); "
            "detection_floor.probed in the timeline")


def payload_floor(floor: dict[str, Any] | None) -> tuple[float, int, float] | None:
    """The least load (kg) a payload change needs to be seen at all at the log's median
    moment, with the link it is at and its weight (N): a load picked or released at the
    flange starts a payload change only when its step crosses a loading threshold vL, and
    its weight turns each joint k no more than |J_k| times itself (the floor's
    ``payload_step``: per posture the least vL_k / |J_k| over the joints up to the flange,
    the median over postures). A lower bound like the floor itself — not a promise that a
    heavier one is seen. None without kinematics or a lever to the flange."""
    step = (floor or {}).get("payload_step")
    rows = (floor or {}).get("per_link") or []
    if not step or not rows:
        return None
    return float(step["kg"]), max(int(r["link"]) for r in rows), float(step["force_n"])


def floor_words(floor: dict[str, Any] | None) -> str | None:
    """The floor as the report says it: :func:`floor_line`, then the measured one
    (:func:`probed_line`) after "measured:"."""
    parts = [x for x in (floor_line(floor), probed_line(floor)) if x]
    return "; measured: ".join(parts) if parts else None


def _moments(n: int) -> str:
    """``1 moment``, ``3 moments``."""
    return f"{n} moment{'' if n == 1 else 's'}"


def _largest(parts: list[tuple[float, str]]) -> list[str]:
    """The phrases of ``parts`` (figure, phrase) in order, at most :data:`MAX_LISTED` — the
    largest figures: the least sensitive places, where contacts go unseen — and how many
    others the timeline holds."""
    if len(parts) <= MAX_LISTED:
        return [p for _, p in parts]
    top = sorted(range(len(parts)), key=lambda i: -parts[i][0])[:MAX_LISTED]
    return ([parts[i][1] for i in sorted(top)]
            + [f"and less on the {len(parts) - MAX_LISTED} others (in the timeline)"])


def _smallest(row: dict[str, Any], key: str) -> float | None:
    vals = [row[d][key] for d in DETECTORS if isinstance(row.get(d), dict)
            and row[d].get(key) is not None]
    return min(vals) if vals else None


def _approx(x: float) -> str:
    return f"{x:.2g}" if x < 100 else f"{x:.0f}"
