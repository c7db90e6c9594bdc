"""The calibration's motion envelope: the motion a threshold's stated rate was measured on.

A false-alarm rate fitted on free logs (:mod:`impactcli.detect.tail`) holds for motion like
theirs: on held-out simulated hours every false alarm outside the calibration's motion
families touched a sample whose reference velocity or acceleration lay outside the ranges
the calibration logs covered (docs/validation.md, "Thresholds for a false-alarm rate").
``calibrate`` records those ranges per joint (:class:`MotionEnvelope`, in the config's
calibration record); ``detect`` checks each chunk against them (:class:`EnvelopeCheck`)
and says which share of the log lay outside, and which incidents touch it.

The motion of a joint is its reference position where the log has one (else its measured
position), through a causal 2nd-order Butterworth low-pass at ``CUTOFF_HZ`` and backward
differences — the path of the adaptive detector's threshold inputs without a reference
(:func:`impactcli.detect.adaptive.inputs_chunk`), so calibrate and detect compute the same
quantity from the same log, chunk by chunk, bit for bit whatever the split
(:mod:`impactcli.model.causal`). Velocity [rad/s], acceleration [rad/s²], position [rad].

Slow motion lies inside those ranges and is not like the calibration's for all that: the
model's friction turns over with the velocity below a few hundredths of a rad/s (its smooth
sign, docs/method.md §2), and a drive's stiction lies there too. A slow reversal keeps a
joint there for seconds where the calibration's motion crossed it in a fraction of one,
and there the ranges alone call the motion inside: a heavy-geared arm's slow free runs gave
303 false alarms per hour against a stated bound of 162 with 0 % of their time outside the
ranges (docs/validation.md, "Slow motion"). So each joint also carries a clock
(:attr:`Motion.slow_s`): the time it has spent moving slower than :data:`SLOW_RAD_S` since
it last moved faster — time at rest (below :data:`HELD_RAD_S`) neither adds to it nor ends
it. ``calibrate`` records each joint's longest such time after warm-up
(:attr:`MotionEnvelope.slow_dwell_s`); ``detect`` counts a sample outside while a clock is
beyond it. Only for motion of the reference position: a measured position's noise at rest,
through the low-pass, sits in the slow band (the simulated elbow held still in
``assist_impacts``: 28 % of its samples between 1 and 20 mrad/s), so without a reference in
the calibration logs or the log no slow stretch is recorded or checked, and the envelope's
ranges are all there is.

Where the log has a reference, the arm's *measured* motion is traced beside it (the same
low-pass and differences of the measured position): ``calibrate`` records the ranges of its
velocity and acceleration too (:data:`MEASURED`), and ``detect`` keeps the stretches where
the measured motion left them while the joint's reference motion stayed inside its own
(:attr:`EnvelopeShare.measured`). They are not part of the share outside — a contact itself
throws the measured motion out of the calibration's ranges, by construction — but they say
when the arm had not settled after an incident: a 30 N push sets a compliant arm ringing
for seconds under a calm reference, and each velocity reversal of the ringing turns the
model's friction where the calibration's motion never did
(:mod:`impactcli.detect.aftermath`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..columns import column_range
from ..model.causal import Carry
from ..model.derivatives import MAX_CUTOFF_FRACTION
from ..model.iir import butter_lowpass
from .aftermath import MeasuredStretch, PeakRuns
from .aftermath import runs as _runs

__all__ = ["CHECKED", "CUTOFF_HZ", "HELD_RAD_S", "LEAD_S", "MEASURED", "QUANTITIES",
           "SLOW_RAD_S",
           "EnvelopeAccumulator", "EnvelopeCheck", "EnvelopeShare", "Motion",
           "MotionEnvelope", "MotionTrace", "outside_share_text", "posture_text", "slow_text"]

#: Low-pass of the position before each difference [Hz] (the adaptive inputs' measured path).
CUTOFF_HZ = 10.0
#: The quantities recorded per joint, and those a sample is checked on (position is recorded
#: for the reader: no measurement yet shows that posture alone makes false alarms).
QUANTITIES: tuple[str, ...] = ("velocity", "acceleration", "position")
CHECKED: tuple[str, ...] = ("velocity", "acceleration")
#: The measured motion's quantities, recorded and checked where the motion is the
#: reference's (module docstring): kept apart from the share outside.
MEASURED: tuple[str, ...] = ("measured_velocity", "measured_acceleration")
#: An incident touches the outside when a sample from LEAD_S before its start to its end
#: is outside (the residual's filters lag the motion that causes it) [s] — its end pushed
#: on by the motion trace's own lag (:attr:`MotionTrace.lag_s`): the trace dates an
#: outside moment later than the residual feels it (a trial's heavy arm: its reference
#: reversed at 4.334 s, the residual alarmed 4.352–4.364 s, the trace was outside from
#: 4.372 s, and 12 false alarms were said to touch no outside motion).
LEAD_S = 0.2
#: Outside stretches closer than this merge into one (as alarms merge) [s] (the share
#: counts only the samples outside).
MERGE_S = 0.1
#: The measured motion leaves its calibrated range when it passes it by more than this
#: share of the range's width (:data:`MEASURED`): a range is the extreme of a few minutes of
#: free motion, and the same motion passes its own extremes by rounding (a repeat of a
#: calibration log's motion, by 1e-8 rad/s²) — each such sample would be a stretch; the
#: free stretches of the simulated pick-and-place passed theirs by up to 13 % of the width,
#: a push's ringing by 20–130 % (docs/incidents.md, "A contact's aftermath").
MEASURED_MARGIN = 0.1
#: A pose is outside the calibration's when a joint's position lies beyond its recorded
#: range by more than this [rad] (~3°: a rigid model's fit does not turn over that).
POSTURE_MARGIN_RAD = 0.05
#: A joint moves slowly below this speed [rad/s]: twice the model's Coulomb velocity scale
#: (``coulomb_slope_rad_s``, 0.01 rad/s: its smooth sign tanh(q'/v_s) is below 96 % of the
#: full friction there, so the friction the model predicts turns with the velocity). A
#: model with another scale gets twice its own (:func:`slow_speed`).
SLOW_RAD_S = 0.02
#: ... and is at rest below this one [rad/s] (a reference held still reads 0). Time at rest
#: is not slow motion: the simulated arms' held joints raise no false alarm (the sample
#: impact logs hold a joint all along), and a real drive's stiction at rest is not measured
#: here.
HELD_RAD_S = 1e-3


@dataclass(frozen=True)
class Motion:
    """One chunk's motion, (n, J) each: velocity, acceleration, position, the slow
    clock [s] (module docstring; zeros when not traced), and the measured motion's velocity
    and acceleration where the motion is the reference's (else None)."""

    velocity: np.ndarray
    acceleration: np.ndarray
    position: np.ndarray
    slow_s: np.ndarray | None = None
    measured_velocity: np.ndarray | None = None
    measured_acceleration: np.ndarray | None = None

    @property
    def slow(self) -> np.ndarray:
        """(n, J) :attr:`slow_s`, zeros when absent."""
        return (np.zeros_like(self.velocity) if self.slow_s is None
                else np.asarray(self.slow_s))

    def get(self, quantity: str) -> np.ndarray:
        """The (n, J) array of ``quantity`` (one of :data:`QUANTITIES`, or of
        :data:`MEASURED` when traced)."""
        return np.asarray(getattr(self, quantity))

    @classmethod
    def joined(cls, chunks: Sequence[Motion]) -> Motion:
        """The motion of consecutive ``chunks`` (one or more) as one."""
        def cat(k: str) -> np.ndarray | None:
            xs = [getattr(m, k) for m in chunks]
            return None if any(x is None for x in xs) else np.concatenate(xs)

        return cls(np.concatenate([m.velocity for m in chunks]),
                   np.concatenate([m.acceleration for m in chunks]),
                   np.concatenate([m.position for m in chunks]),
                   np.concatenate([m.slow for m in chunks]),
                   cat("measured_velocity"), cat("measured_acceleration"))

    def has(self, quantity: str) -> bool:
        """Whether ``quantity`` was traced."""
        return getattr(self, quantity) is not None


class MotionTrace:
    """The motion of a log chunk after chunk (module docstring): :meth:`update` in order.

    Args:
        sample_rate_hz: the log's rate [Hz] (the low-pass is clipped below
            0.4 × it, silently: the clip is the same at calibrate and detect).
        cutoff_hz: the low-pass [Hz].
    """

    def __init__(self, sample_rate_hz: float, cutoff_hz: float = CUTOFF_HZ,
                 slow_rad_s: float = SLOW_RAD_S, held_rad_s: float = HELD_RAD_S) -> None:
        self.slow_rad_s, self.held_rad_s = float(slow_rad_s), float(held_rad_s)
        fc = min(float(cutoff_hz), MAX_CUTOFF_FRACTION * float(sample_rate_hz))
        b, a = butter_lowpass(2, fc / (0.5 * float(sample_rate_hz)))
        self.b, self.a = np.asarray(b), np.asarray(a)
        self.period_s = 1.0 / float(sample_rate_hz)
        self.carry = Carry()
        self.source: str | None = None
        # the velocity and the acceleration go through the low-pass twice (its DC group
        # delay √2 / (2π fc) each) and two backward differences (half a period each)
        self.lag_s = 2.0 * math.sqrt(2.0) / (2.0 * math.pi * fc) + self.period_s

    def update(self, time_s: np.ndarray, position: np.ndarray,
               position_ref: np.ndarray | None = None) -> Motion:
        """The motion of (n,) ``time_s`` [s since the log's first sample] and (n, J)
        positions [rad]: of ``position_ref`` when given, else of ``position``, and with a
        reference the measured motion's velocity and acceleration beside it. The source is
        fixed by the first chunk (a log has a reference or not)."""
        if self.source is None:
            self.source = "position_ref" if position_ref is not None else "position"
        q = np.asarray(position_ref if self.source == "position_ref" and
                       position_ref is not None else position, dtype=np.float64)
        dt = self.carry.steps_s("t", np.asarray(time_s, dtype=np.float64))
        qf = self.carry.lfilter("q", self.b, self.a, q, "steady")
        v = self.carry.lfilter("v", self.b, self.a,
                               self.carry.backward_difference("qf", qf, dt), "steady")
        acc = self.carry.backward_difference("vf", v, dt)
        mv = ma = None
        if self.source == "position_ref":
            mq = self.carry.lfilter("mq", self.b, self.a,
                                    np.asarray(position, dtype=np.float64), "steady")
            mv = self.carry.lfilter("mv", self.b, self.a,
                                    self.carry.backward_difference("mqf", mq, dt), "steady")
            ma = self.carry.backward_difference("mvf", mv, dt)
        return Motion(v, acc, qf, self._slow_clock(v, dt), mv, ma)

    def _slow_clock(self, v: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """(n, J) time [s] each joint has spent with held ≤ |v| < slow since |v| last
        reached slow (:data:`HELD_RAD_S`, :data:`SLOW_RAD_S` by default; a step longer
        than two sample periods, a gap, adds two), carried across chunks: the same sums in
        the same order whatever the split."""
        speed = np.abs(v)
        if speed.shape[0] == 0:
            return speed.copy()
        step = np.nan_to_num(np.minimum(dt, 2.0 * self.period_s), nan=0.0)
        inc = np.where((speed >= self.held_rad_s) & (speed < self.slow_rad_s),
                       step[:, None], 0.0)
        zero = np.zeros(speed.shape[1:])
        total0 = self.carry.state.get("slow_total", zero)
        base0 = self.carry.state.get("slow_base", zero)
        total = np.cumsum(np.vstack([total0[None], inc]), axis=0)[1:]
        marks = np.where(speed >= self.slow_rad_s, total, -np.inf)
        base = np.maximum.accumulate(np.vstack([base0[None], marks]), axis=0)[1:]
        self.carry.state["slow_total"], self.carry.state["slow_base"] = total[-1], base[-1]
        return np.asarray(total - base)


def _range(lo_hi: Sequence[float]) -> tuple[float, float]:
    lo, hi = (float(x) for x in lo_hi)
    return lo, hi


@dataclass(frozen=True)
class MotionEnvelope:
    """Per joint, the [min, max] of each quantity over the calibration's free motion.

    Attributes:
        joints: joint → quantity → (min, max) (:data:`QUANTITIES`, and :data:`MEASURED`
            where the calibration logs had a reference; units in the module doc).
        source: ``position_ref`` (the logs' reference) or ``position`` (measured).
        samples: samples the ranges were taken over (after warm-up, contacts cut out).
        cutoff_hz: the low-pass the motion went through [Hz].
        slow_dwell_s: joint → the longest time [s] the joint moved slowly at a stretch
            after warm-up (the slow clock's maximum, module docstring); empty in configs
            written before it was recorded (then slow motion is not checked).
        slow_rad_s, held_rad_s: the speeds the slow clock was read with [rad/s].
    """

    joints: dict[str, dict[str, tuple[float, float]]]
    source: str
    samples: int
    cutoff_hz: float = CUTOFF_HZ
    slow_dwell_s: dict[str, float] = field(default_factory=dict)
    slow_rad_s: float = SLOW_RAD_S
    held_rad_s: float = HELD_RAD_S

    def to_dict(self) -> dict[str, Any]:
        """The config's ``calibration.motion_envelope`` table (no null: TOML)."""
        slow = {} if not self.slow_dwell_s else {
            "slow_rad_s": float(self.slow_rad_s), "held_rad_s": float(self.held_rad_s),
            "slow_dwell_s": {j: float(v) for j, v in self.slow_dwell_s.items()}}
        return {"source": self.source, "samples": int(self.samples),
                "cutoff_hz": float(self.cutoff_hz), **slow,
                "joints": {j: {k: [float(lo), float(hi)] for k, (lo, hi) in q.items()}
                           for j, q in self.joints.items()}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MotionEnvelope:
        """The envelope a config records (:meth:`to_dict`'s mapping)."""
        return cls({str(j): {str(k): _range(v) for k, v in q.items()}
                    for j, q in dict(d["joints"]).items()},
                   str(d["source"]), int(d["samples"]), float(d.get("cutoff_hz", CUTOFF_HZ)),
                   {str(j): float(v) for j, v in dict(d.get("slow_dwell_s", {})).items()},
                   float(d.get("slow_rad_s", SLOW_RAD_S)),
                   float(d.get("held_rad_s", HELD_RAD_S)))

    def lines(self) -> list[str]:
        """One line per joint, as ``calibrate`` prints it."""
        unit = {"velocity": "rad/s", "acceleration": "rad/s²", "position": "rad",
                "measured_velocity": "rad/s", "measured_acceleration": "rad/s²"}
        out = []
        for j, q in self.joints.items():
            slow = (f"; slower than {self.slow_rad_s:g} rad/s for at most "
                    f"{self.slow_dwell_s[j]:.3g} s at a stretch"
                    if j in self.slow_dwell_s else "")
            out.append(f"  {j:16s} " + "; ".join(
                f"{k.replace('_', ' ')} {lo:.3g} … {hi:.3g} {unit.get(k, '')}"
                for k, (lo, hi) in q.items())
                + slow)
        return out


def slow_speed(model: Any | None) -> float:
    """The speed below which a joint moves slowly for ``model`` (a
    :class:`~impactcli.model.rigid.RigidModel`, or None) [rad/s]: twice its Coulomb velocity
    scale ``coulomb_slope_rad_s``; :data:`SLOW_RAD_S` for a model without one, or none."""
    vs = (getattr(model, "structure", None) or {}).get("coulomb_slope_rad_s")
    return 2.0 * float(vs) if vs else SLOW_RAD_S


class EnvelopeAccumulator:
    """The envelope of the motions :meth:`add` is given (only their ``keep`` samples).

    Args:
        joints: the J joints, in the motions' column order.
        source: what the motion was made of (:attr:`MotionTrace.source`).
        slow_rad_s: the speed the motions' slow clocks were read with [rad/s].
    """

    def __init__(self, joints: Sequence[str], source: str = "position",
                 cutoff_hz: float = CUTOFF_HZ, slow_rad_s: float = SLOW_RAD_S) -> None:
        self.joints = tuple(joints)
        self.source, self.cutoff_hz = source, float(cutoff_hz)
        self.slow_rad_s = float(slow_rad_s)
        self.lo: dict[str, np.ndarray] = {}
        self.hi: dict[str, np.ndarray] = {}
        self.dwell: np.ndarray | None = None
        self.samples = 0
        self.untraced = False  # a motion without the measured quantities was added

    def add(self, motion: Motion, keep: np.ndarray | None = None,
            from_index: int | None = None) -> None:
        """Absorb a log's motion (n, J): its ranges over the samples where ``keep`` (n,)
        is True (of the measured motion too, when every log given traced it), its slow
        clock's maximum from sample ``from_index`` on (the warm-up's end,
        whatever ``keep`` cut out: ``detect`` reads the clock on every sample after
        warm-up; default: the first kept sample)."""
        clock = motion.slow
        if from_index is None:
            kept = np.flatnonzero(keep) if keep is not None else np.arange(clock.shape[0])
            from_index = int(kept[0]) if kept.size else clock.shape[0]
        if clock.shape[0] > from_index:
            most = clock[from_index:].max(axis=0)
            self.dwell = most if self.dwell is None else np.maximum(self.dwell, most)
        for k in QUANTITIES + MEASURED:
            if not motion.has(k):
                continue
            x = motion.get(k)
            if keep is not None:
                x = x[np.asarray(keep, dtype=bool)]
            if x.shape[0] == 0:
                continue
            lo, hi = column_range(x)
            self.lo[k] = lo if k not in self.lo else np.minimum(self.lo[k], lo)
            self.hi[k] = hi if k not in self.hi else np.maximum(self.hi[k], hi)
        n = motion.velocity.shape[0] if keep is None else int(np.count_nonzero(keep))
        self.samples += n
        if not all(motion.has(k) for k in MEASURED):
            self.untraced = True

    def finish(self) -> MotionEnvelope | None:
        """The envelope; None when no sample was kept."""
        if not self.samples or not self.lo:
            return None
        dwell = {} if self.dwell is None or self.source != "position_ref" else {
            j: float(self.dwell[c]) for c, j in enumerate(self.joints)}
        traced = [k for k in QUANTITIES + MEASURED if k in self.lo
                  and not (self.untraced and k in MEASURED)]
        return MotionEnvelope({j: {k: (float(self.lo[k][c]), float(self.hi[k][c]))
                                   for k in traced}
                               for c, j in enumerate(self.joints)},
                              self.source, self.samples, self.cutoff_hz, dwell,
                              self.slow_rad_s)


@dataclass(frozen=True)
class EnvelopeShare:
    """What :meth:`EnvelopeCheck.finish` found, from sample ``start`` on.

    Attributes:
        samples: samples checked; outside: of them, outside the envelope.
        per_joint: joint → share of the checked samples outside on that joint.
        stretches: (K, 2) [s] first and last time of each outside stretch after ``start``
            (runs merged over MERGE_S), in order. unchecked: the log's joints the envelope
            does not have.
        source: the motion's source in this log; note: a mismatch with the calibration's.
        posture: joint → share of the checked samples whose position lay outside the
            calibration logs' position range by more than :data:`POSTURE_MARGIN_RAD` (not
            part of ``outside``: no measurement here shows posture alone making false alarms,
            but a rigid model identified on some poses is only known there, so the stated
            rate is not either), joints with none left out.
        slow: joint → share of the checked samples outside because the joint had moved
            slowly for longer than the calibration's longest stretch (part of ``outside``),
            joints with none left out; slow_dwell_s: that longest stretch [s], per joint of
            ``slow``; ranges: joint → share outside its velocity or acceleration range
            (joints with none left out; in the mapping only beside ``slow``, where
            ``per_joint`` mixes the two); slow_rad_s: the speed below which a joint moved
            slowly [rad/s] (the envelope's; in the mapping only beside ``slow``).
        lag_s: how much later the motion trace dates the motion than it happened
            (:attr:`MotionTrace.lag_s`; :meth:`touches`).
        measured: the stretches where the measured motion left the calibration's measured
            ranges (:class:`MeasuredStretch`, over the whole log, runs merged over
            MERGE_S), in order; None when it was not checked (no reference in the log or
            in the calibration logs, or a config written before it was recorded).
    """

    samples: int
    outside: int
    per_joint: dict[str, float]
    stretches: np.ndarray
    unchecked: tuple[str, ...] = ()
    source: str = "position"
    note: str = ""
    posture: dict[str, float] = field(default_factory=dict)
    slow: dict[str, float] = field(default_factory=dict)
    slow_dwell_s: dict[str, float] = field(default_factory=dict)
    ranges: dict[str, float] = field(default_factory=dict)
    slow_rad_s: float = SLOW_RAD_S
    measured: tuple[MeasuredStretch, ...] | None = None
    lag_s: float = 0.0

    @property
    def share(self) -> float:
        """Share of the checked samples outside (0 when none was checked)."""
        return self.outside / self.samples if self.samples else 0.0

    def touches(self, t_start: float, t_end: float, lead_s: float = LEAD_S) -> bool:
        """Whether an incident from ``t_start`` to ``t_end`` [s] touches an outside
        stretch (from ``lead_s`` before its start to ``lag_s``, the motion trace's lag,
        after its end: :data:`LEAD_S`)."""
        s = self.stretches
        if s.shape[0] == 0:
            return False
        return bool(np.any((s[:, 0] <= t_end + self.lag_s)
                           & (s[:, 1] >= t_start - lead_s)))

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready mapping (for a timeline's 2.x optional field)."""
        return {"samples": self.samples, "outside": self.outside, "share": self.share,
                "per_joint": dict(self.per_joint), "source": self.source,
                "stretches_s": self.stretches.tolist(), "unchecked": list(self.unchecked),
                **({"note": self.note} if self.note else {}),
                **({"posture_outside": dict(self.posture)} if self.posture else {}),
                **({"slow_outside": dict(self.slow), "slow_dwell_s": dict(self.slow_dwell_s),
                    "ranges_outside": dict(self.ranges), "slow_rad_s": self.slow_rad_s}
                   if self.slow else {}),
                **({} if self.measured is None
                   else {"measured_stretches": [m.to_dict() for m in self.measured]})}


class _Runs:
    """Runs of outside samples as [a, b) index ranges of the log (with their first and last
    times), joined across chunk boundaries."""

    def __init__(self) -> None:
        self.ab: list[list[int]] = []
        self.t: list[list[float]] = []

    def add(self, k0: int, t: np.ndarray, mask: np.ndarray) -> None:
        for a, b in zip(*_runs(mask), strict=True):
            ga, gb = k0 + int(a), k0 + int(b) + 1
            if self.ab and self.ab[-1][1] == ga:
                self.ab[-1][1], self.t[-1][1] = gb, float(t[b])
            else:
                self.ab.append([ga, gb])
                self.t.append([float(t[a]), float(t[b])])

    def count_from(self, start: int) -> int:
        return sum(b - max(a, start) for a, b in self.ab if b > start)


class EnvelopeCheck:
    """Each chunk's samples against a recorded envelope (detect's side).

    One :meth:`update` per chunk, in order (a :class:`~impactcli.types.SignalsChunk`, or
    :meth:`update_arrays`), returns the chunk's (n,) outside mask; :meth:`finish` once,
    with the warm-up's end, gives the :class:`EnvelopeShare`. A sample is outside when, on
    any joint the envelope has, a quantity of :data:`CHECKED` leaves [lo − m, hi + m] with
    m = ``margin`` × (hi − lo), or its slow clock exceeds the envelope's longest slow
    stretch × (1 + ``margin``) (where the envelope records one). Holds only the runs of
    outside samples, not the samples.
    """

    def __init__(self, envelope: MotionEnvelope, sample_rate_hz: float,
                 joints: Sequence[str], *, margin: float = 0.0,
                 loads: Sequence[dict[str, Any]] = ()) -> None:
        self.envelope = envelope
        # per calibration log with its own load, that log's envelope checked beside
        # (:mod:`impactcli.detect.load_motion`): (its config entry, its check)
        self.loads = [(e, EnvelopeCheck(MotionEnvelope.from_dict(e["envelope"]),
                                        sample_rate_hz, joints, margin=margin))
                      for e in loads]
        self.joints = tuple(joints)
        self.cols = [c for c, j in enumerate(self.joints) if j in envelope.joints]
        self.names = [self.joints[c] for c in self.cols]
        self.unchecked = tuple(j for j in self.joints if j not in envelope.joints)
        self.trace = MotionTrace(sample_rate_hz, envelope.cutoff_hz, envelope.slow_rad_s,
                                 envelope.held_rad_s)
        self.dwell = np.array([envelope.slow_dwell_s.get(j, np.inf) for j in self.names]
                              ) * (1.0 + margin)
        self.bounds: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for k in CHECKED:
            lo = np.array([envelope.joints[j][k][0] for j in self.names])
            hi = np.array([envelope.joints[j][k][1] for j in self.names])
            m = margin * (hi - lo)
            self.bounds[k] = (lo - m, hi + m)
        # the position range per joint where the envelope records one (older configs: none)
        self.pose_cols = [c for c, j in zip(self.cols, self.names, strict=True)
                          if "position" in envelope.joints[j]]
        self.pose_bounds = (
            np.array([envelope.joints[self.joints[c]]["position"][0] for c in self.pose_cols])
            - POSTURE_MARGIN_RAD,
            np.array([envelope.joints[self.joints[c]]["position"][1] for c in self.pose_cols])
            + POSTURE_MARGIN_RAD)
        # the measured motion's ranges, on the joints the envelope records them for
        self.m_cols = [c for c, j in zip(self.cols, self.names, strict=True)
                       if all(k in envelope.joints[j] for k in MEASURED)]
        self.m_bounds = [(np.array([envelope.joints[self.joints[c]][k][0]
                                    for c in self.m_cols]),
                          np.array([envelope.joints[self.joints[c]][k][1]
                                    for c in self.m_cols])) for k in MEASURED]
        self.m_at = [self.cols.index(c) for c in self.m_cols]  # their place in cols
        self.measured = PeakRuns(MERGE_S)
        self.n = 0
        self.any = _Runs()
        self.each = [_Runs() for _ in self.cols]
        self.pose_each = [_Runs() for _ in self.pose_cols]
        self.slow_each = [_Runs() for _ in self.cols]
        self.range_each = [_Runs() for _ in self.cols]

    def update_arrays(self, time_s: np.ndarray, position: np.ndarray,
                      position_ref: np.ndarray | None = None, start: int | None = None
                      ) -> np.ndarray:
        """The chunk of samples ``start`` … (default: right after the last) as arrays."""
        k0 = self.n if start is None else int(start)
        t = np.asarray(time_s, dtype=np.float64)
        for _, check in self.loads:
            check.update_arrays(t, position, position_ref, k0)
        mot = self.trace.update(t, position, position_ref)
        n = t.shape[0]
        out_j = np.zeros((n, len(self.cols)), dtype=bool)
        for k, (lo, hi) in self.bounds.items():
            x = mot.get(k)[:, self.cols]
            out_j |= (x < lo) | (x > hi)
        slow = ((mot.slow[:, self.cols] > self.dwell) if self.trace.source == "position_ref"
                else np.zeros_like(out_j))  # a measured position's noise at rest reads slow
        for c, runs in enumerate(self.range_each):
            runs.add(k0, t, out_j[:, c])
        if self.m_cols and all(mot.has(k) for k in MEASURED):
            self._measured(k0, t, mot, out_j[:, self.m_at])
        out_j |= slow
        mask: np.ndarray = (np.asarray(out_j.any(axis=1)) if self.cols
                            else np.zeros(n, dtype=bool))
        self.any.add(k0, t, mask)
        for c, runs in enumerate(self.each):
            runs.add(k0, t, out_j[:, c])
        for c, runs in enumerate(self.slow_each):
            runs.add(k0, t, slow[:, c])
        if self.pose_cols:
            x = mot.position[:, self.pose_cols]
            away = (x < self.pose_bounds[0]) | (x > self.pose_bounds[1])
            for c, runs in enumerate(self.pose_each):
                runs.add(k0, t, away[:, c])
        self.n = k0 + n
        return mask

    def _measured(self, k0: int, t: np.ndarray, mot: Motion, commanded: np.ndarray
                  ) -> None:
        """The chunk's samples against the measured ranges: how far out each lies beyond
        :data:`MEASURED_MARGIN`, as a share of its range's width (0 inside, and where the
        joint's reference motion itself left its ranges, ``commanded`` (n, M): a motion
        commanded beyond the calibration's is the envelope's finding, not an arm that did
        not settle), its farthest joint and quantity."""
        n, m = t.shape[0], len(self.m_cols)
        score = np.zeros((n, len(MEASURED) * m))
        value = np.zeros_like(score)
        for q, (k, (lo, hi)) in enumerate(zip(MEASURED, self.m_bounds, strict=True)):
            x = mot.get(k)[:, self.m_cols]
            width = np.where(hi > lo, hi - lo, 1.0)
            score[:, q * m:(q + 1) * m] = np.where(commanded, 0.0, np.maximum(
                np.maximum(x - hi, lo - x) / width - MEASURED_MARGIN, 0.0))
            value[:, q * m:(q + 1) * m] = x
        score = np.nan_to_num(score, nan=0.0)  # a NaN sample hides no other joint's
        far = np.argmax(score, axis=1) if n else np.zeros(0, dtype=np.int64)
        rows = np.arange(n)
        self.measured.add(k0, t, score[rows, far], far % m, far // m, value[rows, far])

    def finish(self, start: int = 0) -> EnvelopeShare:
        """The share outside from sample ``start`` on (the warm-up's end index; samples
        before it are not counted, as alarms there are not)."""
        start = max(0, min(int(start), self.n))
        checked = self.n - start
        stretches: list[list[float]] = []
        for (_, b), tt in zip(self.any.ab, self.any.t, strict=True):
            if b <= start:
                continue
            if stretches and tt[0] - stretches[-1][1] <= MERGE_S + 1e-9:
                stretches[-1][1] = tt[1]
            else:
                stretches.append(list(tt))
        src = self.trace.source or "position"
        note = ""
        if src != self.envelope.source:
            note = (f"the calibration's motion is of its logs' {self.envelope.source}, "
                    f"this log's of its {src}: ranges compared across sources")
        if self.envelope.slow_dwell_s and src != "position_ref":
            note += (("; " if note else "") + "slow stretches not checked: this log has no "
                     "reference position (a measured position's noise at rest reads as slow "
                     "motion)")
        bare = [self.joints[c] for c in self.cols if c not in self.m_cols]
        if self.m_cols and bare and src == "position_ref":  # some joints' measured ranges
            note += (("; " if note else "") + "measured motion not checked on "
                     f"{', '.join(bare)} (the config records no measured ranges for it): "
                     "an incident in a contact's aftermath there is not marked")
        posture = {self.joints[c]: r.count_from(start) / checked
                   for c, r in zip(self.pose_cols, self.pose_each, strict=True)
                   if checked and r.count_from(start)}
        slow = {j: r.count_from(start) / checked
                for j, r in zip(self.names, self.slow_each, strict=True)
                if checked and r.count_from(start)}
        ranges = {j: r.count_from(start) / checked
                  for j, r in zip(self.names, self.range_each, strict=True)
                  if checked and r.count_from(start)}
        return EnvelopeShare(
            checked, self.any.count_from(start),
            {j: (r.count_from(start) / checked if checked else 0.0)
             for j, r in zip(self.names, self.each, strict=True)},
            np.array(stretches, dtype=np.float64).reshape(-1, 2), self.unchecked, src, note,
            posture, slow, {j: self.envelope.slow_dwell_s[j] for j in slow}, ranges,
            self.envelope.slow_rad_s, self._stretches() if self.m_cols and
            src == "position_ref" else None, self.trace.lag_s)

    def _stretches(self) -> tuple[MeasuredStretch, ...]:
        out = []
        for t0, t1, _, c, q, v in self.measured.runs:
            lo, hi = self.m_bounds[q][0][c], self.m_bounds[q][1][c]
            out.append(MeasuredStretch(t0, t1, self.joints[self.m_cols[c]], MEASURED[q],
                                       v, float(lo), float(hi)))
        return tuple(out)


def posture_text(posture: Mapping[str, float]) -> str:
    """One phrase on the poses outside the calibration's position range
    (:attr:`EnvelopeShare.posture`, or a timeline's ``posture_outside``), "" when none."""
    if not posture:
        return ""
    parts = ", ".join(f"{j} ({100 * v:.3g} %)" for j, v in
                      sorted(posture.items(), key=lambda kv: -kv[1]))
    return (f"its posture left the calibration logs' position range on {parts} of the log "
            "after warm-up: the model was identified and the thresholds' false-alarm rate "
            "measured on other poses, where a rigid model's error is not known")


def outside_share_text(share: EnvelopeShare | Mapping[str, Any]) -> str:
    """One sentence for a report or terminal: of an :class:`EnvelopeShare` or of its
    mapping (a timeline's ``motion_envelope``)."""
    d = share.to_dict() if isinstance(share, EnvelopeShare) else share
    if not d.get("samples"):
        return "motion envelope: nothing checked"
    per_joint: Mapping[str, float] = d.get("per_joint") or {}
    slow: Mapping[str, float] = d.get("slow_outside") or {}
    worst = max(per_joint.items(), key=lambda kv: kv[1], default=("", 0.0))
    ranges: Mapping[str, float] = (d.get("ranges_outside") or {}) if slow else per_joint
    beyond = "velocity or acceleration beyond the ranges calibrated on"
    if slow and ranges:  # say which joint left which, the two shares apart
        beyond += ": " + ", ".join(f"{j} {100 * v:.3g} %" for j, v in
                                   sorted(ranges.items(), key=lambda kv: -kv[1]))
    why = "; ".join(([] if slow and not any(ranges.values()) else [beyond])
                    + ([slow_text(slow, d.get("slow_dwell_s") or {},
                                  float(d.get("slow_rad_s") or SLOW_RAD_S))] if slow else []))
    txt = (f"{100.0 * float(d['share']):.3g} % of the log after warm-up moved outside the "
           f"calibration's motion envelope ({why})")
    if worst[0] and worst[1] > 0:
        txt += f"; most on {worst[0]} ({100 * worst[1]:.3g} %)"
    if d.get("note"):
        txt += f"; {d['note']}"
    return txt


def slow_text(slow: Mapping[str, float], dwell_s: Mapping[str, float],
              slow_rad_s: float = SLOW_RAD_S) -> str:
    """One phrase on the slow stretches longer than the calibration's
    (:attr:`EnvelopeShare.slow`, or a timeline's ``slow_outside`` and ``slow_dwell_s``),
    read below ``slow_rad_s`` [rad/s]."""
    parts = ", ".join(f"{j} {100 * v:.3g} % (calibrated: ≤ "
                      f"{dwell_s.get(j, float('nan')):.2g} s)"
                      for j, v in sorted(slow.items(), key=lambda kv: -kv[1]))
    return (f"slower than {slow_rad_s:g} rad/s for longer at a stretch than in the "
            f"calibration logs, where the model's friction turns with the velocity: {parts}")
