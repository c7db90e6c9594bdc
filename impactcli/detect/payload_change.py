"""Payload changes told from contacts, causally, as the replay runs (docs/method.md §5c).

A payload picked or released mid-log is a step in the residual that the static-loading
detector alarms on. Its signature across the poses that follow is that of a mass at the
flange: the torque Y(q, q', q'') B π of :mod:`impactcli.model.payload`, which follows the
Jacobian transpose of gravity as the arm moves. A contact — a blow, a push, a clamp — does
not behave as a mass: it ends, or it holds the arm still, or it pushes another way.

:class:`PayloadMonitor` watches the residual on the replay's calling thread, part by part:

1. **Onset.** The static-loading statistic |LP(r)| (the detector's own filter and
   thresholds vL) rises above vL on some joint, after the warm-up's least length (the load
   at the start is weighed there: :mod:`impactcli.run.loads`). An alarm already on when
   the watch resumes (after a window that was no load) dates from its run's start; an
   alarm ends after a dip below vL longer than the events' merge gap.
2. **Weighing.** When :data:`WINDOW_S` seconds have passed (the classification time, as
   online), the change is weighed (:func:`impactcli.model.payload.weigh`) on the window
   from the onset plus ``settle_s`` (the loading filter and the step's transient) to the
   classification time, through the replay's own causal filters (the inverse-dynamics
   residual is linear in θ).
3. **The test.** A payload change when (a) the window's poses determine the mass and centre
   of mass and the mass is :data:`~impactcli.model.payload.WEIGH_SIGMAS` standard errors
   from zero, (b) the centre of mass lies within the arm's reach, (c) the mass explains
   the step: its torque accounts for at least :data:`EXPLAINED` of the window's residual
   energy, (d) the mass is steady: it drifts by at most :data:`STEADY` of itself across
   the window (:func:`~impactcli.model.payload.drift`; a clamp that builds up does not
   keep a mass), and (e) its inertia does not side with a steady force along gravity
   (:func:`~impactcli.model.payload.inertia`; ``unseen`` where the motion is too slow to
   tell them apart, and every output says so). Otherwise, while the alarm has lasted
   without a break since its onset, the next window is weighed (a push in the first
   window after a pick hides the mass there); once it broke, the alarm stays what the
   detectors make of it — a contact or a lasting load — and the next onset starts afresh.
   A change found at a later onset is dated from the earliest onset that failed since the
   last change, within the windows kept, from which its mass explains the residual
   (:meth:`PayloadMonitor._earlier_onset`): a push that spoiled the pick's first window
   and broke its alarm does not move the change to the load's next onset.
4. **A load it knows.** When the load then carried is one a calibration log carried (its
   mass within :data:`~impactcli.model.payload.WEIGH_SIGMAS` standard errors of the
   step's, and the step to it explains the window as well, from :data:`EXPLAINED` on), it
   is that log's fitted load, known from a whole log rather than a few seconds (above all
   its inertia): the step is taken to it (``as_log``). So is a release back to the
   model's own load.
5. **A contact in the window.** The torque that the mass leaves unexplained, from the
   onset plus ``settle_s`` to the classification (every window weighed, as far as the
   monitor keeps: :data:`KEPT` windows), goes through the static-loading statistic (the detector's
   low-pass against vL): where it passes :data:`BESIDE` × vL, a contact happened beside
   the change (a push while the load was released), and the change's alarm is counted
   from the onset of that excursion (:attr:`PayloadChange.contact`,
   :func:`impactcli.detect.incidents.mark_payload_changes`): the gates judge it. The mass
   is weighed and tested again without the excursion's rows (from ``settle_s`` before it
   to its end) when they fall in the window it was weighed on and half the window is left,
   and taken so when it passes the tests there: a contact in that window biases the mass,
   and the residual would carry the error from then on.
6. **From then on** the residual carries the new load: the torque Y B π of every load
   changed so far is added to the residual from the classification time, whatever the
   chunking (the same sum per row, r + Y B π with π every load changed so far, in whichever
   part the row falls). The monitor then waits for the alarm to end before it looks for the
   next onset.

The inverse-dynamics generator and the controller's channels corrected by the tool's model
(r = Ŷθ − G(target), as linear in a load; :func:`impactcli.run.loads.weighable`) are
corrected so; the momentum observer's state holds the old load, and a channel taken plain
has no model to carry one: the replay says so when such a generator runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..model import payload
from ..model.causal import Carry
from ..model.derivatives import causal_derivatives
from ..model.rigid import RigidModel
from ..model.structures import predict
from .payload_finding import BESIDE, ContactPart, PayloadChange, mass_check
from .static import causal_lowpass

#: Seconds after the onset at which a change is weighed and classified.
WINDOW_S = payload.START_S
#: A mass explains a step when its torque accounts for at least this share of the window's
#: residual energy (the change's confidence).
EXPLAINED = payload.EXPLAINED
#: A change is steady when its mass drifts by at most this share across the window.
STEADY = payload.STEADY
#: A change is dated from an earlier onset that failed its test when, from there to its
#: own onset, the median squared residual the mass leaves is at most this share of the
#: median squared residual (:meth:`PayloadMonitor._earlier_onset`): the mass explains
#: three quarters of the typical sample's residual there.
EARLIER = 0.25
#: The monitor keeps this many windows of the motion and the residual: an onset that
#: failed its first window, then the next onset of the same load weighed on its own first
#: window, fit (:meth:`PayloadMonitor._earlier_onset`).
KEPT = 3
def not_a_load(w: payload.Weighed, explained: float, within_reach: bool) -> str | None:
    """Why a weighed step is not a payload change by the tests (a)–(c) (module docstring),
    in words; None when it passes them."""
    if not w.supported:
        return "the poses after it do not determine a mass (the arm moved too little)"
    if not w.weighed:
        return (f"it weighs no mass clearly ({w.mass_kg:+.2g} ± {w.mass_se_kg:.2g} kg: within "
                "three standard errors of none)")
    if not within_reach:
        return "its centre of mass lies beyond the arm's reach"
    if explained < EXPLAINED:
        return f"a mass explains only {100 * explained:.0f} % of it"
    return None


def mark_tried(findings: Sequence[Any], tried: dict[float, str],
               merge_gap_s: float = 0.1) -> list[Any]:
    """The incidents or lasting loads, each that holds an onset the monitor weighed and
    found no payload change (``tried``: onset → why) given that answer
    (``payload_test``): what the alarm is not, for the reader to rule out."""
    if not tried:
        return list(findings)
    out = []
    for x in findings:
        why = [w for t, w in tried.items()
               if x.t_start - merge_gap_s - 1e-9 <= t <= x.t_end + 1e-9]
        out.append(replace(x, payload_test=f"not a payload change: {why[0]}") if why
                   and getattr(x, "payload_change", None) is None
                   and not getattr(x, "payload_test", None) else x)
    return out


def _typical(left: np.ndarray, d: np.ndarray) -> tuple[float, float]:
    """The typical row's squared residual over ``left`` (n, J) [N·m] with the load's torque
    ``d`` (n, J) taken out, and without: the medians (a contact spoils the mean, not the
    median)."""
    return (float(np.median(np.sum((left - d) ** 2, axis=1))),
            float(np.median(np.sum(left ** 2, axis=1))))


@dataclass(frozen=True)
class Judged:
    """What the tests (a)–(e) of the module docstring found on a window: the weighing, the
    share of the window's residual energy it explains, why it is no payload change (None:
    it is one), and the drift and inertia (tests d, e; unset when (a)–(c) failed)."""

    w: payload.Weighed
    explained: float
    why: str | None
    drift: float = float("inf")
    shows: str = "unseen"


@dataclass
class PayloadMonitor:
    """The monitor's settings and state (module docstring); :meth:`process` each part of
    the residual in order.

    Args:
        model: the replay's model (its kind has kinematics); b, names: the payload basis.
        v_loading: (J,) the static-loading thresholds vL [N·m].
        sample_rate_hz, cutoff_hz: the log's rate and the residual's derivative cut-off.
        loading_cutoff_hz, loading_order: the static-loading low-pass.
        start_s: onsets before this time are not watched (the warm-up's least length).
        settle_s: the window starts this long after the onset.
        reach_m: a centre of mass farther from the last joint is not a load.
        base_kg: the load the replay's model carries beyond the config's model (the load
            the log started with) [kg]: ``mass_after_kg`` counts from the config's.
        known: the loads the calibration logs carried, each (log, π relative to the
            replay's model) (module docstring, step 4).
        start_weighed: the load the log started with was weighed (``base_kg``; False: not,
            and ``base_kg`` is 0) — for :func:`mass_check`'s words.
    """

    model: RigidModel
    b: np.ndarray
    names: tuple[str, ...]
    v_loading: np.ndarray
    sample_rate_hz: float
    cutoff_hz: float
    loading_cutoff_hz: float
    loading_order: int
    start_s: float
    settle_s: float
    reach_m: float
    base_kg: float = 0.0
    known: tuple[tuple[str, np.ndarray], ...] = ()
    start_weighed: bool = True
    merge_gap_s: float = 0.0
    #: the standard error of ``base_kg`` when the stretch weighed it [kg] (0: a calibration
    #: log's fit, or none): the load carried after a change is known to it and the step's
    base_se_kg: float = 0.0
    changes: list[PayloadChange] = field(default_factory=list)
    #: onset [s] → why its alarm, lasting through the first window (it could have been a
    #: load), was not a payload change there (later windows, while it lasts, are retries)
    tried: dict[float, str] = field(default_factory=dict)
    _pi: np.ndarray | None = None
    _carry: Carry = field(default_factory=Carry)
    _buf: dict[str, np.ndarray] = field(default_factory=dict)
    _state: str = "idle"
    _onset: tuple[int, float] | None = None
    _due: int = 0
    _ended: bool = False
    _below: int = 0
    _prev_above: bool = False
    _run_start: tuple[int, float] | None = None
    #: onset [s] → its sample index, for every onset weighed and found no load (ended or
    #: not) since the last change: the step may have begun there (:meth:`_earlier_onset`)
    _failed: dict[float, int] = field(default_factory=dict)
    _carried_se: float = 0.0  # the standard error of the load carried now [kg]
    _last_k: int = -1  # the sample at which the last change was classified
    _kept_from: float | None = None  # the change's load is in all rows kept since [s]

    def __post_init__(self) -> None:
        self._pi = np.zeros(len(self.names))
        self._carried_se = float(self.base_se_kg)

    @property
    def window(self) -> int:
        """Samples from the onset to the classification."""
        return max(1, round(WINDOW_S * self.sample_rate_hz))

    def process(self, k0: int, t: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
        """The part's residual (n, J) [N·m] carrying every load classified so far; ``k0``
        its first sample's index, ``t`` (n,) its times [s], ``q`` (n, J) its positions."""
        if r.shape[0] == 0:
            return np.asarray(r, dtype=np.float64)
        dt = 1.0 / self.sample_rate_hz
        qf, qd, qdd = causal_derivatives(dt, q, self.cutoff_hz, self._carry.scoped("q."), "q")
        r0 = np.asarray(r, dtype=np.float64)
        r = np.array(r0)
        assert self._pi is not None
        if np.any(self._pi):
            r += self._torque(qf, qd, qdd, self._pi)
        n = r.shape[0]
        pos = 0
        while pos < n:
            saved = self._carry.copy()
            lp = np.abs(causal_lowpass(r[pos:], self.loading_cutoff_hz, self.sample_rate_hz,
                                       self.loading_order, self._carry.scoped("lp.")))
            cut = self._scan(k0 + pos, t[pos:], lp)
            if cut is None:
                break
            still = not self._ended
            # a change classified at sample pos + cut: the filter state up to there, then
            # the residual from there carries the new load
            self._carry = saved
            causal_lowpass(r[pos:pos + cut], self.loading_cutoff_hz, self.sample_rate_hz,
                           self.loading_order, self._carry.scoped("lp."))
            self._keep(qf[pos:pos + cut], qd[pos:pos + cut], qdd[pos:pos + cut],
                       r[pos:pos + cut])
            change = self._classify(k0 + pos + cut, float(t[pos + cut]), still)
            pos += cut
            if change is not None:  # the same sum per row as a later part's: r0 + Y B π
                r[pos:] = (r0[pos:] + self._torque(qf[pos:], qd[pos:], qdd[pos:], self._pi)
                           if np.any(self._pi) else r0[pos:])
        self._keep(qf[pos:], qd[pos:], qdd[pos:], r[pos:])
        return r

    def _scan(self, k0: int, t: np.ndarray, lp: np.ndarray) -> int | None:
        """Walk the states over the part's loading statistic from sample ``k0``; the offset
        of a classification time within it, else None (the whole part walked)."""
        above = np.any(lp > self.v_loading[None, :], axis=1)
        n = lp.shape[0]
        # where the alarm's runs begin (the run ongoing at the part's start carried in)
        starts = np.flatnonzero(above & ~np.concatenate([[self._prev_above], above[:-1]]))

        def walked(upto: int) -> int:  # the runs as of sample ``upto`` (exclusive)
            if upto > 0:
                self._prev_above = bool(above[upto - 1])
                s = starts[starts < upto]
                if s.size:
                    self._run_start = (k0 + int(s[-1]), float(t[s[-1]]))
            return upto

        i = 0
        while i < n:
            if self._state == "idle":
                hits = np.flatnonzero(above[i:] & (t[i:] >= self.start_s))
                if not hits.size:
                    walked(n)
                    return None
                i += int(hits[0])
                s = starts[starts <= i]
                run = (k0 + int(s[-1]), float(t[s[-1]])) if s.size else self._run_start
                # an alarm already on when the watch resumed began at its run's start
                # (a step inside the window of an alarm that was no load)
                self._onset = (run if run is not None and run[1] >= self.start_s
                               and run[0] <= k0 + i else (k0 + i, float(t[i])))
                self._due = self._onset[0] + self.window
                self._ended = False
                self._below = 0
                self._state = "pending"
            if self._state == "pending":
                at = self._due - k0
                if not self._ended:  # silent longer than the events' merge gap: it ended
                    self._ended = self._silent(~above[i:min(at, n)])
                if at < n:
                    return walked(max(at, 0))
                walked(n)
                return None
            if self._state == "cooldown":
                below = np.flatnonzero(~above[i:])
                if not below.size:
                    walked(n)
                    return None
                i += int(below[0])
                self._state = "idle"
        walked(n)
        return None

    def _silent(self, below: np.ndarray) -> bool:
        """Whether the alarm fell silent for longer than the events' merge gap within
        ``below`` (the samples under every vL, in order), counting the run it ended the last
        part with: a dip the events would merge over is one alarm, as for the detectors."""
        runs = np.concatenate([[self._below], np.zeros(below.size, dtype=np.int64)])
        for k, b in enumerate(below):  # run lengths, carried in
            runs[k + 1] = runs[k] + 1 if b else 0
        self._below = int(runs[-1])
        return bool(runs.max() > self.merge_gap_s * self.sample_rate_hz)

    def _keep(self, qf: np.ndarray, qd: np.ndarray, qdd: np.ndarray, r: np.ndarray) -> None:
        """Keep the last :data:`KEPT` windows of the filtered motion and the residual."""
        keep = KEPT * self.window + 1
        for key, v in (("qf", qf), ("qd", qd), ("qdd", qdd), ("r", r)):
            old = self._buf.get(key)
            cat = v if old is None else np.concatenate([old, v])
            self._buf[key] = cat[-keep:]

    def _classify(self, k_c: int, t_c: float, still: bool) -> np.ndarray | None:
        """Weigh the change whose onset is pending on the window that ends at sample ``k_c``
        (the buffer ends just before it); the load then carried (π of every change so far)
        when it is a payload change. Else,
        when the alarm is ``still`` on (without a break since its onset), the next window
        is due."""
        assert self._onset is not None and self._pi is not None
        t_a = self._onset[1]
        buf = self._buf
        n = buf["r"].shape[0]
        w0 = max(0, n - self.window + round(self.settle_s * self.sample_rate_hz))
        judged = None
        why: str | None = "too short a window to weigh"
        if n - w0 >= 10:
            y = self.model.regressor(buf["qf"][w0:], buf["qd"][w0:], buf["qdd"][w0:]) @ self.b
            left = -buf["r"][w0:]  # the torque beyond the model's: r = τ̂ − τ
            judged = self._judge(y, left, buf["qf"][w0:])
            why = judged.why or self._a_press(judged)
        if why is not None:
            self._failed = {t: k for t, k in self._failed.items()  # those still kept
                            if k >= k_c - KEPT * self.window}
            self._failed.setdefault(t_a, self._onset[0])
            if still:  # the alarm goes on (could be a load): the first answer, then retries
                self.tried.setdefault(t_a, why)
                self._due = k_c + self.window
                return None
            self._state = "idle"
            return None
        assert judged is not None
        w = judged.w
        earlier = (self._earlier_onset(k_c, w.pi) or self._later_onset(k_c, t_c, w0, w.pi)
                   or self._step_back(k_c, w0, w.pi))
        if earlier is not None:  # the step began at an alarm that failed its test, later
            # in the alarm than its onset (a model error's alarm ran into it), or before
            # the onset by the static-loading low-pass's lag
            self._onset = earlier
            t_a = earlier[1]
        for t in [t for t in self.tried if t >= t_a - 1e-9]:  # those alarms were the load
            del self.tried[t]
        self._failed.clear()
        self._state = "cooldown"
        # the alarm from its onset (after the settle) to the classification, through every
        # window weighed (a contact spoils the first; the mass is weighed on a later one)
        settle = round(self.settle_s * self.sample_rate_hz)
        first = min(n, max(n - w0, k_c - self._onset[0] - settle))
        s0 = n - first
        ys = (y if s0 == w0 else self.model.regressor(
            buf["qf"][s0:], buf["qd"][s0:], buf["qdd"][s0:]) @ self.b)
        clipped = k_c - self._onset[0] - settle > n  # the alarm began before the buffer
        seen, run = self._beside(-buf["r"][s0:] - ys @ w.pi, k_c - first,
                                 t_c - first / self.sample_rate_hz, clipped)
        if run is not None:  # the contact's rows out of the weighing (module docstring, 5)
            keep = np.ones(n - w0, dtype=bool)
            keep[max(s0 + run[0] - settle - w0, 0):max(s0 + run[1] - w0, 0)] = False
            if not keep.all() and keep.sum() >= keep.size // 2:
                again = self._judge(y[keep], left[keep], buf["qf"][w0:][keep],
                                    np.flatnonzero(keep))
                if again.why is None:  # the tests passed without the contact's rows too
                    judged, y, left = again, y[keep], left[keep]
        w = judged.w
        part = None
        if run is not None:  # the contact apart from the load, with the mass as taken
            # already on where the scan began: from the onset, when the buffer holds it
            held = k_c - self._onset[0] <= n
            began_before = run[0] == 0 and not held
            a0 = n - (k_c - self._onset[0]) if run[0] == 0 and held else s0 + run[0]
            z = s0 + run[1]
            yp = self.model.regressor(buf["qf"][a0:z], buf["qd"][a0:z],
                                      buf["qdd"][a0:z]) @ self.b
            rc = buf["r"][a0:z] + yp @ w.pi
            part = ContactPart(tuple(self.model.joint_names), rc, self._loading(-rc),
                               buf["qf"][a0:z], buf["qd"][a0:z], 1.0 / self.sample_rate_hz,
                               began_before)
        se_after = float(np.hypot(self._carried_se, w.mass_se_kg))  # the load then carried
        known = payload.known_load(self.known, self._pi, w.pi, se_after, y, left, self.names)
        self._pi = self._pi + w.pi if known is None else np.array(known[1])
        self._last_k = k_c
        self._carried_se = se_after if known is None else 0.0
        after = self.base_kg + float(self._pi[self.names.index("m")])
        lowest = self._lowest_kg()
        self.changes.append(PayloadChange(
            t_a, t_c, w.mass_kg, w.mass_se_kg,
            {nm: float(v) for nm, v in zip(self.names, w.pi, strict=True)},
            judged.explained, after,
            None if known is None else known[0], judged.drift, judged.shows,
            t_a - self.start_s < 1.5 / self.sample_rate_hz, seen, part,
            max(t_a, t_c - first / self.sample_rate_hz), self.settle_s, self.settle_s,
            mass_check(w.mass_kg, w.mass_se_kg, lowest, after, self.start_weighed),
            carried_since_s=self._kept_from))
        self._kept_from = None
        return self._pi

    def _lowest_kg(self) -> float:
        """The least load the log was seen with so far, beyond the model's: the model's
        own (0), the start's, those after each change (:func:`mass_check`)."""
        return min(0.0, self.base_kg, *(c.mass_after_kg for c in self.changes))

    def _a_press(self, judged: Judged) -> str | None:
        """Why a step that passed the tests is no payload change after all: a release of
        more than the log was seen to carry (:func:`mass_check`, the load it started with
        weighed) whose inertia did not show — a mass cannot be taken off that was not on,
        and a steady press along gravity gives the same torque (a trial's heavy-arm clamp
        of 25 N read "−2.34 kg", then "+2.34 kg" at its end, and left the count). None
        when it may be one."""
        w = judged.w
        if judged.shows == "shows" or not self.start_weighed or self._pi is None:
            return None
        after = self.base_kg + float((self._pi + w.pi)[self.names.index("m")])
        lowest = self._lowest_kg()
        if mass_check(w.mass_kg, w.mass_se_kg, lowest, after, True) is None:
            return None
        return (f"it would release {-w.mass_kg:.3g} kg, more than the log was seen to carry, "
                "and its inertia did not show: a press along gravity (a clamp?), not a load")

    def _judge(self, y: np.ndarray, left: np.ndarray, qf: np.ndarray,
               at: np.ndarray | None = None) -> Judged:
        """The tests (a)–(e) of the module docstring on a window: ``y`` (n, J, m) its payload
        rows, ``left`` (n, J) the torque beyond the model's [N·m], ``qf`` (n, J) its
        filtered positions (the rows at rest, for the inertia test), ``at`` the rows'
        sample positions (default evenly spaced; for a window with rows left out)."""
        w = payload.weigh(y, left, self.names)
        explained = payload.explained(left, y, w.pi)
        why = not_a_load(w, explained, payload.within_reach(self.names, w.pi, self.reach_m))
        if why is not None:
            return Judged(w, explained, why)
        zero = np.zeros_like(qf)
        y0 = self.model.regressor(qf, zero, zero) @ self.b
        shows, _ = payload.inertia(y, y0, left, self.names, w)
        drift = payload.drift(y, left, self.names, w, at)
        if shows != "shows":  # steady as a steady force too: a press's ramp hides in a
            pressed = payload.weigh(y0, left, self.names)  # mass's inertia
            if pressed.weighed:
                drift = max(drift, payload.drift(y0, left, self.names, pressed, at))
        if drift > STEADY:
            why = (f"its mass drifted by {100 * drift:.0f} % across the window (a press "
                   "that builds up or eases off?)")
        elif shows == "contradicts":
            why = "it sides with a steady force, not with a mass's inertia (a press?)"
        return Judged(w, explained, why, drift, shows)

    def _earlier_onset(self, k_c: int, pi: np.ndarray) -> tuple[int, float] | None:
        """The earliest onset weighed before this change's and found no load (``_failed``),
        within the buffer, from which the load ``pi`` was already there: over the samples
        from it to this change's onset, the mass explains the typical sample — the median
        of the squared residual it leaves is at most :data:`EARLIER` of the median of the
        squared residual (a contact in the first window spoils the mean, not the median).
        (sample, time), or None. A step the alarm's first window could not weigh (a push
        0.7 s after a pick) is so dated from the pick, not from a later onset of the same
        load, and the contact in between is found beside it (module docstring, steps 3
        and 5)."""
        assert self._onset is not None
        k_a, n = self._onset[0], self._buf["r"].shape[0]
        for t, k in sorted(self._failed.items()):
            j0, j1 = n - (k_c - k), n - (k_c - k_a)
            if j0 < 0 or j1 - j0 < 10:
                continue
            with_load, without = _typical(*self._rows(j0, j1, pi))
            if with_load <= EARLIER * without:
                return k, t
        return None

    def _rows(self, a: int, z: int, pi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Over the buffer's rows ``a:z``: the torque beyond the model's (n, J) [N·m] and
        the load ``pi``'s torque Y B π there."""
        buf = self._buf
        y = self.model.regressor(buf["qf"][a:z], buf["qd"][a:z], buf["qdd"][a:z]) @ self.b
        return -buf["r"][a:z], y @ pi

    def _later_onset(self, k_c: int, t_c: float, w0: int,
                     pi: np.ndarray) -> tuple[int, float] | None:
        """A change weighed on a later window of its alarm than the first (the alarm
        lasted): where the step of the load ``pi`` began between the alarm's onset (or the
        oldest row kept) and the window weighed, at row ``w0`` of the buffer — the
        least-squares change point of its torque (:func:`impactcli.model.payload.step_onset`)
        — when the rows before it are not the load's: there the mass leaves the typical
        sample a larger residual than none (an alarm of a model error, say a load unlike
        the calibration's, that ran into a release). (sample, time), or None: the alarm's
        onset stands (a push that spoiled the first window after a pick)."""
        assert self._onset is not None
        n = self._buf["r"].shape[0]
        a = max(0, n - (k_c - self._onset[0]))
        if w0 - a < self.window:  # weighed on the alarm's first window
            return None
        left, d = self._rows(a, w0, pi)
        tau = payload.step_onset(left, d)
        if tau < 10 or np.less_equal(*_typical(left[:tau], d[:tau])):
            return None
        back = n - a - tau
        return k_c - back, t_c - back / self.sample_rate_hz

    def _step_back(self, k_c: int, w0: int, pi: np.ndarray) -> tuple[int, float] | None:
        """The step's own start when it lies before the onset: the static-loading
        low-pass crosses vL up to ``settle_s`` after a step the adaptive detector sees at
        once (a 1 kg release on the soft simulated arm: 0.3 s), and a step whose torque
        stays under vL crosses it only when the motion makes it larger (a 0.5 kg release
        on the heavy arm: 4.2 s later). The least-squares change point of the load's torque
        (:func:`impactcli.model.payload.step_onset`) over the rows the monitor keeps before
        the window weighed, at row ``w0`` — not before the watch began nor before the last
        change's classification — when it is before the onset; beyond ``settle_s`` before
        it, only when the mass explains the rows from there to the onset as
        :meth:`_earlier_onset` asks (the median squared residual it leaves at most
        :data:`EARLIER` of the median squared residual) and leaves those before it a larger
        residual than none. (sample, time), or None."""
        assert self._onset is not None
        k_a, t_a = self._onset
        n = self._buf["r"].shape[0]
        j_a = n - (k_c - k_a)  # the onset's row
        back = min(int(np.floor((t_a - self.start_s) * self.sample_rate_hz)),
                   k_a - self._last_k - 1 if self._last_k >= 0 else k_a)
        a = max(0, j_a - back)
        if j_a - a < 2 or w0 <= j_a:
            return None
        left, d = self._rows(a, w0, pi)
        tau = payload.step_onset(left, d)
        if tau >= j_a - a:
            return None
        if tau < 10 and a == 0 and j_a >= self.window:  # the load in every row kept
            with_load, without = _typical(left[:j_a], d[:j_a])  # before the onset: it came
            if with_load <= EARLIER * without:  # then or before (a step under vL); the
                self._kept_from = t_a - j_a / self.sample_rate_hz  # onset stands (its alarm)
                return None
        early = j_a - a - tau
        if early > round(self.settle_s * self.sample_rate_hz):  # beyond the low-pass's lag
            with_load, without = _typical(left[tau:j_a - a], d[tau:j_a - a])
            if (with_load > EARLIER * without or tau < 10
                    or np.less_equal(*_typical(left[:tau], d[:tau]))):
                return None
        return k_a - early, t_a - early / self.sample_rate_hz

    def _beside(self, leftover: np.ndarray, k_first: int, t_first: float,
                clipped: bool = False
                ) -> tuple[dict[str, Any] | None, tuple[int, int] | None]:
        """A contact beside the mass (module docstring, step 5): when the static-loading
        statistic of the window's ``leftover`` (n, J) [N·m], the torque the mass leaves,
        peaks above :data:`BESIDE` × vL — the onset of its run above vL (sample, time), the
        joint and the peak over vL, and the run's rows in ``leftover`` (first, end); None,
        None otherwise. ``k_first``, ``t_first``: the window's first sample and its time;
        ``clipped``: the alarm began before it (the buffer keeps :data:`KEPT` windows), so
        an excursion already on there dates from the alarm's onset."""
        ratio = self._loading(leftover)
        if ratio.size == 0 or not ratio.max() > BESIDE:
            return None, None
        top, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        above = np.any(ratio > 1.0, axis=1)
        below = np.flatnonzero(~above[:top])
        i = int(below[-1]) + 1 if below.size else 0  # the run above vL that holds the peak
        after = np.flatnonzero(~above[top:])
        run = (i, int(top) + (int(after[0]) if after.size else above.size - int(top)))
        seen = {"joint": self.model.joint_names[int(j)], "peak": float(ratio[top, j])}
        if i == 0 and clipped and self._onset is not None:
            return {"i": self._onset[0], "t_s": self._onset[1], **seen}, run
        return {"i": k_first + i, "t_s": t_first + i / self.sample_rate_hz, **seen}, run

    def _loading(self, leftover: np.ndarray) -> np.ndarray:
        """The static-loading statistic |LP(·)| of (n, J) ``leftover`` [N·m] (the
        detector's own low-pass, started afresh) over vL."""
        lp = np.abs(causal_lowpass(leftover, self.loading_cutoff_hz, self.sample_rate_hz,
                                   self.loading_order))
        vl = np.where(self.v_loading > 0, self.v_loading, np.inf)
        return np.asarray(lp / vl[None, :])

    def _torque(self, qf: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                pi: np.ndarray) -> np.ndarray:
        """(n, J) the torque Y B π of the load π on the part's filtered motion [N·m]."""
        if qf.shape[0] == 0:
            return np.zeros_like(qf)
        m = self.model
        return predict(m.kind, m.joint_names, m.structure, qf, qd, qdd, self.b @ pi)
