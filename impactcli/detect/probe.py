"""The detection floor measured: blows replayed through the evaluator from its own state
(docs/method.md §5b, "The floor measured").

The floor of :mod:`impactcli.detect.floor` is a lower bound for a blow: it holds G_hat
frozen over the blow, while the RLS (eq. 38–40) adapts to the blow as it lasts and passes
it less (measured in tests/test_floor.py: 0.29–0.79 of the frozen gain). So the run also
MEASURES what a blow needs, at up to :data:`PROBES` moments spread over the log (at least
the RLS's memory, 1 / (1 − lambda) samples, apart: closer ones share their state) after the
warm-up's shortest possible length (those that fall before its end, known when the replay
is done, are dropped):

1. **The state.** The replay keeps the evaluator's state as it stood before each probed
   sample k (:meth:`impactcli.detect.axes.AxisRunner.snapshot`: the same bits the log's
   own replay carries there), and the residual r, threshold inputs u and signed
   static-loading low-pass LP(r) of the :func:`probe_window` samples from k.
2. **The blow.** A half-sine of :data:`~impactcli.detect.floor.HALF_SINE_S` with amplitude
   A_j [N·m] is added to each joint's residual from k (every joint at once: the axes are
   independent, eq. 34–35), with the sign alternating from one probe to the next, and the
   window is replayed from the state through the whole evaluator — the RLS adapting, G_hat,
   F1, F2, the RMS windows and the dynamic threshold (eq. 26–42) — against the run's own
   v_stat; for the static-loading detector LP(r) + A_j h, h the low-pass's response to
   the pulse from rest (exact: the filter is linear), against vL. The blow is **caught**
   by a detector on joint j when its decision makes an event within the window as the
   events make them (runs merged across the merge gap, lasting the least duration:
   :func:`_caught`) — within the window only: an alarm the blow's mark on the RLS raises
   later is not counted.
3. **The amplitude.** Per joint, from the frozen-G_hat bound at k, the amplitude is
   doubled until the adaptive detector catches the blow (halved until it misses it, when
   the bound is caught already; up to :data:`MAX_DOUBLINGS` times), then bisected
   :data:`BISECTIONS` times on a log scale between the last amplitude missed and the first
   caught: the smallest amplitude found caught (within 2^(1/2^BISECTIONS) of the
   crossing). The static-loading detector's, on a grid as fine from its own bound. Either
   detector's is the smaller. A joint where a detector's decision is already on in the
   window without a blow is ``in_alarm`` at that probe (a blow joins that alarm: not
   judged); one never caught up to the last step is ``uncaught``; a joint with no finite
   v_stat is judged by the static-loading detector alone.
4. **The figures.** Per joint, over the probes that were judged, the median and the worst
   tenth (the 90th percentile, the probes' own values; an uncaught probe counts above
   every caught one), for either detector and for the adaptive one alone, and per link
   with a link-end Jacobian the force A / |J_i| at the probe's posture
   (:func:`impactcli.detect.force.own_levers`), the same quantiles; a link ending on its
   own joint's axis has no force, and the joint's torque is its floor.

A median is what about half the blows of its size reach at the moments judged, not a size
from which every blow is caught. What this leaves out, and every output says so: the blow
is added to the residual, not to the arm (the residual generator's own filtering of a
contact, an elastic joint and the payload monitor's answer to a blow are not replayed),
the moments where a detector already alarms are not judged (the figures are the quiet
moments'), and a few dozen moments sample the log: the figures carry the count judged.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..cores import cores
from .adaptive import evaluate_chunk
from .axes import EvaluatorState
from .floor import HALF_SINE_S, QUANTILES, pulse_gain
from .force import JacobianFn, own_levers
from .static import causal_lowpass

#: Moments probed per log, at most (fewer when the log after warm-up is short, or when
#: the evaluator's covariances would take more than :data:`MAX_STATE_BYTES` kept).
PROBES = 32
#: The states kept for the probes take at most this many bytes.
MAX_STATE_BYTES = 256 * 1024**2
#: Doublings of the amplitude from the frozen-G_hat bound before a probe is ``uncaught``.
MAX_DOUBLINGS = 14
#: Bisections between the last amplitude missed and the first caught (log scale).
BISECTIONS = 5


def probe_window(sample_rate_hz: float, n1: int, a1: float) -> int:
    """Samples a probe replays from its moment: the blow, the RMS window N1 and F1's decay
    (five time constants) — where the blow can raise r_rms (eq. 41), as
    :func:`~impactcli.detect.floor.pulse_gain` takes it."""
    m = max(1, round(HALF_SINE_S * sample_rate_hz))
    return m + n1 + max(1, round(5.0 / max(1.0 - a1, 1e-12))) + 1


def probe_indices(n_samples: int, hold: int, window: int, count: int = PROBES,
                  spacing: int = 0) -> np.ndarray:
    """(P,) the probed samples: ``count`` spread evenly (each in the middle of its share)
    over [hold, n_samples − window], the samples after ``hold`` (the warm-up's shortest
    possible length) whose window fits in the log — fewer where they would fall less than
    a window, or ``spacing`` samples (the RLS's memory: moments closer share their state),
    apart; none when fewer than ``window`` samples are there."""
    span = n_samples - window - hold
    count = min(count, span // max(window, spacing, 1))  # a window, a spacing apart at least
    if count <= 0:
        return np.zeros(0, dtype=np.int64)
    k = hold + np.floor((np.arange(count) + 0.5) * span / count).astype(np.int64)
    return np.unique(k)


def half_sine(window: int, sample_rate_hz: float) -> np.ndarray:
    """(window,) a unit half-sine of :data:`HALF_SINE_S` from the window's first sample,
    zero after (the floor's reference blow)."""
    m = max(1, round(HALF_SINE_S * sample_rate_hz))
    x = np.zeros(window)
    x[:min(m, window)] = np.sin(np.pi * (np.arange(min(m, window)) + 0.5) / m)
    return x


@dataclass
class Probe:
    """One probed moment: its sample ``k``, the evaluator's state before it (``state``
    waits for the axes and returns it), the (W, J) residual, (m, W, J) inputs and (W, J)
    signed static-loading low-pass LP(r) from it as the replay made them, and the log's
    positions there (None: not recorded)."""

    k: int
    state: Callable[[], EvaluatorState]
    r: list[np.ndarray] = field(default_factory=list)
    u: list[np.ndarray] = field(default_factory=list)
    lp: list[np.ndarray] = field(default_factory=list)
    q: np.ndarray | None = None

    def held(self) -> int:
        return sum(x.shape[0] for x in self.r)


class ProbeRecorder:
    """What the probes need, taken from the replay as it runs (module docstring, step 1):
    :meth:`cuts` where a part must end for a snapshot, :meth:`take` the snapshot at a
    probed sample, :meth:`feed` each part's residual and inputs, :meth:`posture` each
    chunk's positions."""

    def __init__(self, indices: Sequence[int] | np.ndarray, window: int) -> None:
        self.indices = [int(k) for k in indices]
        self._wanted = set(self.indices)
        self.window = int(window)
        self.probes: list[Probe] = []
        self._open: list[Probe] = []

    def cuts(self, k0: int, k1: int) -> list[int]:
        """The probed samples strictly inside [k0, k1): where a part must start."""
        return [k for k in self.indices if k0 < k < k1]

    def wants(self, k: int) -> bool:
        """Whether sample ``k`` is probed (its state is to be taken)."""
        return k in self._wanted

    def take(self, k: int, state: Callable[[], EvaluatorState]) -> None:
        """The snapshot before sample ``k``, when it is probed."""
        if k in self._wanted:
            p = Probe(k, state)
            self.probes.append(p)
            self._open.append(p)

    def feed(self, k0: int, r: np.ndarray, u: np.ndarray, lp: np.ndarray) -> None:
        """A part's (n, J) residual, (m, n, J) inputs and (n, J) signed LP(r), its first
        sample ``k0``."""
        for p in list(self._open):
            held = p.held()
            need = self.window - held
            start = p.k + held - k0  # the part's row of the next sample the probe needs
            if start < 0 or start >= r.shape[0]:
                continue
            take = min(need, r.shape[0] - start)
            p.r.append(np.array(r[start:start + take], dtype=np.float64))
            p.u.append(np.array(u[:, start:start + take], dtype=np.float64))
            p.lp.append(np.array(lp[start:start + take], dtype=np.float64))
            if p.held() >= self.window:
                self._open.remove(p)

    def posture(self, k0: int, q_full: np.ndarray) -> None:
        """The chunk's (n, C) log positions from sample ``k0``: each probe's row."""
        for p in self.probes:
            if p.q is None and k0 <= p.k < k0 + q_full.shape[0]:
                p.q = np.array(q_full[p.k - k0], dtype=np.float64)

    def done(self) -> list[Probe]:
        """The probes whose window is whole."""
        return [p for p in self.probes if p.held() >= self.window]


def _caught(decision: np.ndarray, sample_rate_hz: float,
            events: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """(J,) whether each joint's (W, J) decision holds an event as the events make them
    (:func:`impactcli.detect.events.extract_events`): runs of it merged across gaps of at
    most ``events[0]`` seconds (the merge gap), and one of them lasting at least
    ``events[1]`` seconds (the least duration; 0: any sample). Within the window only: an
    event the window's end cuts short may last longer in the log."""
    merge_gap_s, min_duration_s = events
    if min_duration_s <= 0.0:
        return np.asarray(decision.any(axis=0))
    dt, eps = 1.0 / sample_rate_hz, 1e-9
    out = np.zeros(decision.shape[1], dtype=bool)
    for j in range(decision.shape[1]):
        idx = np.flatnonzero(decision[:, j])
        if idx.size == 0:
            continue
        breaks = np.flatnonzero(np.diff(idx) > 1)
        starts = np.concatenate([[idx[0]], idx[breaks + 1]])
        ends = np.concatenate([idx[breaks], [idx[-1]]])
        a, b = int(starts[0]), int(ends[0])
        for s, e in zip(starts[1:], ends[1:], strict=True):
            if (s - b) * dt <= merge_gap_s + eps:
                b = int(e)
                continue
            out[j] |= (b - a) * dt >= min_duration_s - eps
            a, b = int(s), int(e)
        out[j] |= (b - a) * dt >= min_duration_s - eps
    return out


@dataclass(frozen=True)
class ProbeAnswer:
    """One probe's answer per joint (J,): the smallest amplitude [N·m] found caught by the
    adaptive detector (``adaptive``) and by either product detector (``product``: the
    adaptive one or the static-loading one) — NaN where the joint is in alarm without a
    blow (``*_alarm``) or has no finite threshold, +inf where no amplitude up to the last
    doubling was caught."""

    adaptive: np.ndarray
    product: np.ndarray
    adaptive_alarm: np.ndarray
    product_alarm: np.ndarray


def loading_response(window: int, sample_rate_hz: float, cutoff_hz: float,
                     order: int) -> np.ndarray:
    """(window,) the static-loading low-pass's response to the unit half-sine from rest
    (:func:`half_sine`; the filter is linear, so a blow of amplitude A adds A × this to
    LP(r))."""
    x = np.concatenate([[0.0], half_sine(window, sample_rate_hz)])
    return np.asarray(causal_lowpass(x[:, None], cutoff_hz, sample_rate_hz, order)[1:, 0])


def _static_caught(lp: np.ndarray, h: np.ndarray, v_l: np.ndarray, amps: np.ndarray,
                   sample_rate_hz: float, events: tuple[float, float]) -> np.ndarray:
    """(J,) whether |LP(r) + A_j h| passes vL_j in the window as an event (:func:`_caught`)."""
    return _caught(np.abs(lp + h[:, None] * amps[None, :]) > v_l[None, :], sample_rate_hz,
                   events)


#: The static-loading amplitude's grid: steps of 2^(1 / STATIC_STEPS), as fine as the
#: adaptive one's bisection (2^(1/2^BISECTIONS)), over 2^STATIC_OCTAVES from its bound.
STATIC_STEPS, STATIC_OCTAVES = 32, 20


def _static_amplitude(lp: np.ndarray, h: np.ndarray, v_l: np.ndarray, sample_rate_hz: float,
                      events: tuple[float, float]) -> np.ndarray:
    """(J,) the smallest amplitude on a grid of 2^(1/:data:`STATIC_STEPS`) steps, from the
    bound (vL − max|LP(r)|) / max|h| up, at which the static-loading detector catches the
    blow (:func:`_static_caught`); +inf where none up to 2^:data:`STATIC_OCTAVES` × the
    bound or vL is not finite."""
    top = float(np.max(np.abs(h))) if h.size else 0.0
    J = lp.shape[1]
    out = np.full(J, np.inf)
    if top <= 0:
        return out
    todo = np.isfinite(v_l)
    vl = np.where(todo, v_l, 0.0)
    lo = np.maximum(vl - np.max(np.abs(lp), axis=0), 1e-12 * np.maximum(vl, 1e-12)) / top
    for i in range(STATIC_STEPS * STATIC_OCTAVES + 1):
        if not todo.any():
            break
        a = lo * 2.0 ** (i / STATIC_STEPS)
        got = todo & _static_caught(lp, h, np.where(todo, v_l, np.inf), np.where(todo, a, 0.0),
                                    sample_rate_hz, events)
        out[got] = a[got]
        todo &= ~got
    return out


def probe_amplitudes(probe: Probe, v_stat: np.ndarray, v_l: np.ndarray,
                     sample_rate_hz: float, loading: tuple[float, int],
                     events: tuple[float, float] = (0.0, 0.0),
                     sign: float = 1.0) -> ProbeAnswer:
    """One probe's answer (module docstring, steps 2–3); ``loading`` the static-loading
    low-pass's (cutoff [Hz], order); ``events`` the events' (merge gap, least duration)
    [s]. A joint with no finite v_stat has no adaptive figure and is judged by the
    static-loading detector alone."""
    state = probe.state()
    r = np.concatenate(probe.r)
    u = np.concatenate(probe.u, axis=1)
    lp = np.concatenate(probe.lp)
    vs = np.asarray(v_stat, dtype=np.float64)
    vl = np.asarray(v_l, dtype=np.float64)
    finite = np.where(np.isfinite(vs), vs, 0.0)
    J = r.shape[1]
    pulse = sign * half_sine(r.shape[0], sample_rate_hz)

    def hit(a: np.ndarray) -> np.ndarray:
        res, _ = evaluate_chunk(state, r + pulse[:, None] * a[None, :], u, sample_rate_hz,
                                finite)
        return _caught(res.decision, sample_rate_hz, events)

    base, _ = evaluate_chunk(state, r, u, sample_rate_hz, finite)
    checked = np.isfinite(vs)
    on = _caught(base.decision, sample_rate_hz, events) & checked  # alarming without a blow
    alarm = on | ~checked
    rates = state.rates
    g = pulse_gain(state.theta[:, :state.cfg.eta], sample_rate_hz, rates.a1, rates.n1)
    margin = np.min(np.abs(finite[None, :] + base.v_rms) - base.r_rms, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        lo = np.where(g > 0, np.maximum(margin, 0.0) / g, np.nan)
    lo = np.where(np.isfinite(lo) & (lo > 0), lo, np.maximum(finite, 1e-9))
    hi = np.full(J, np.inf)  # the smallest amplitude caught so far
    missed = np.zeros(J)  # the largest amplitude missed so far (0: none)
    first = hit(np.where(alarm, 0.0, lo))
    hi[~alarm & first] = lo[~alarm & first]
    missed[~alarm & ~first] = lo[~alarm & ~first]
    up, down = ~alarm & ~first, ~alarm & first  # doubling from a miss, halving from a hit
    for _ in range(MAX_DOUBLINGS):
        if not (up.any() or down.any()):
            break
        cur = np.where(up, 2.0 * missed, np.where(down, 0.5 * hi, 0.0))
        got = hit(cur)
        hi = np.where((up | down) & got, cur, hi)
        missed = np.where((up | down) & ~got, cur, missed)
        up &= ~got
        down &= got
    # still caught 2^MAX_DOUBLINGS below the bound: the decision is on for any blow, so the
    # moment is as good as alarming (no size to state)
    on |= down
    alarm |= down
    found = np.isfinite(hi) & (missed > 0)
    for _ in range(BISECTIONS):  # between the last missed and the first caught
        if not found.any():
            break
        mid = np.sqrt(np.where(found, missed, 0.0) * np.where(found, hi, 0.0))
        got = hit(mid)
        hi = np.where(found & got, mid, hi)
        missed = np.where(found & ~got, mid, missed)
    adaptive = np.where(alarm, np.nan, hi)
    h = sign * loading_response(r.shape[0], sample_rate_hz, *loading)
    sl_on = _static_caught(lp, h, np.where(np.isfinite(vl), vl, np.inf), np.zeros(J),
                           sample_rate_hz, events)
    static = _static_amplitude(lp, h, vl, sample_rate_hz, events)
    both = on | sl_on  # a detector alarming without a blow: the blow joins that alarm
    either = np.fmin(np.where(checked, hi, np.inf), static)
    none = ~checked & ~np.isfinite(vl)  # no detector checks the joint
    return ProbeAnswer(adaptive, np.where(both | none, np.nan, either), on, both)


def probed_floor(probes: Sequence[Probe], v_stat: np.ndarray, v_l: np.ndarray,
                 sample_rate_hz: float, loading: tuple[float, int],
                 joints: Sequence[str], events: tuple[float, float] = (0.0, 0.0),
                 chain: Sequence[str] | None = None, index: Sequence[int] | None = None,
                 chain_cols: Sequence[int | None] | None = None,
                 jac: JacobianFn | None = None) -> dict[str, Any] | None:
    """The timeline's ``detection_floor.probed`` (module docstring, step 4) from the
    probes whose window is whole; None without one. ``v_stat``, ``v_l``: (J,) the run's
    adaptive and static-loading thresholds [N·m]; ``loading``: the static-loading
    low-pass's (cutoff [Hz], order); ``events``: the events' (merge gap, least duration) [s];
    ``chain``, ``index``, ``chain_cols``, ``jac`` as for
    :meth:`impactcli.detect.floor.FloorAccumulator.finish` (forces per link)."""
    if not probes:
        return None
    J = len(joints)
    shape = (len(probes), J)
    amps = {"product": np.full(shape, np.nan), "adaptive": np.full(shape, np.nan)}
    alarms = {"product": np.zeros(shape, dtype=bool), "adaptive": np.zeros(shape, dtype=bool)}
    def one(i: int) -> ProbeAnswer:
        return probe_amplitudes(probes[i], v_stat, v_l, sample_rate_hz, loading, events,
                                1.0 if i % 2 == 0 else -1.0)

    # the probes are independent and the kernel releases the GIL: one per core at once
    # (the process's share of the cores in a pool worker: impactcli.cores)
    # (each answer depends on its probe alone, so the figures do not depend on it)
    with ThreadPoolExecutor(max(1, min(cores(), len(probes)))) as pool:
        answers = list(pool.map(one, range(len(probes))))
    for i, ans in enumerate(answers):
        for d, a in amps.items():
            a[i] = getattr(ans, d)
            alarms[d][i] = getattr(ans, f"{d}_alarm")

    def judged(x: np.ndarray, alarm: np.ndarray, unit: str) -> dict[str, Any]:
        x = x[~np.isnan(x)]
        return {**_quantiles(x, unit), "probes": int(x.size), "in_alarm": int(alarm.sum()),
                "uncaught": int(np.isinf(x).sum())}

    per_joint = {name: {**judged(amps["product"][:, j], alarms["product"][:, j], "_nm"),
                        "adaptive": judged(amps["adaptive"][:, j], alarms["adaptive"][:, j],
                                           "_nm")}
                 for j, name in enumerate(joints)}
    out: dict[str, Any] = {"probes": len(probes),
                           "window_s": probes[0].held() / sample_rate_hz,
                           "per_joint": per_joint, "per_link": None}
    qs = [p.q for p in probes]
    if (jac is None or chain is None or index is None or chain_cols is None
            or any(q is None for q in qs)):
        return out
    postures = np.zeros((len(probes), len(chain)))
    for i, q in enumerate(qs):
        assert q is not None
        for c, col_i in enumerate(chain_cols):
            if col_i is not None:
                postures[i, c] = q[col_i]
    levers = own_levers(postures, len(chain), jac)
    links = []
    for j in range(J):
        c = index[j] - 1
        if not np.isfinite(levers[:, c]).any():  # its end on its own joint's axis: no
            none = judged(np.zeros(0), np.zeros(0, dtype=bool), "_n")  # force there turns
            links.append({"link": c + 1, "joint": chain[c], **none,  # it; the joint's
                          "adaptive": dict(none), "no_lever": True,  # torque says it
                          "own_joint": joints[j]})
            continue
        with np.errstate(invalid="ignore"):
            f = {d: a[:, j] / levers[:, c] for d, a in amps.items()}
        links.append({"link": c + 1, "joint": chain[c],
                      **judged(f["product"], alarms["product"][:, j], "_n"),
                      "adaptive": judged(f["adaptive"], alarms["adaptive"][:, j], "_n")})
    out["per_link"] = sorted(links, key=lambda x: x["link"])
    return out


#: The moments judged a quantile needs, at least: a median of fewer than 5 or a worst tenth
#: of fewer than 10 is one moment's answer, not the log's (None, and the line says so).
MIN_JUDGED = {"median": 5, "worst_tenth": 10}


def _quantiles(x: np.ndarray, unit: str) -> dict[str, float | None]:
    """The median and the worst tenth of the probes' values (an observed value each;
    None: fewer judged than :data:`MIN_JUDGED`, or the quantile falls among the
    uncaught)."""
    out: dict[str, float | None] = {}
    for qn, q in QUANTILES.items():
        v = (float(np.quantile(x, q, method="inverted_cdf")) if x.size >= MIN_JUDGED[qn]
             else math.nan)
        out[f"{qn}{unit}"] = v if math.isfinite(v) else None
    return out
