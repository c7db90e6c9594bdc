"""Adaptive residual evaluation, axis by axis (paper Section III, eq. 24–42, App. A/B).

For axis j, at each sample k (all axes in one pass):

1. Regressor (eq. 31–35, 51–54; App. B for n = 2):
   ``phi(k) = [ r_j(k-1..k-eta) | v_dyn_j(k-1..k-p) | u_{i,l}(k-1..k-rho_i) for i = 1..m,
   l = 1..n ]`` — every axis's inputs enter every axis's regression; ``nu = eta + p +
   n·sum(rho)`` (34 for 2 joints, 64 for 7 at Table I). Past v_dyn are the values this
   algorithm computed earlier (pseudo-linear regression). Samples before the log start
   are 0.
2. RLS with constant forgetting (eq. 38–40) on ``y = r_j(k)``: :mod:`impactcli.detect.rls`
   (P symmetric by storage; wind-up guard: each diagonal element of P capped at
   max_trace / nu, which leaves the replay bit for bit plain eq. 39's where the capped
   regressor entries are 0, e.g. a still joint's inputs).
3. ``r_tilde(k) = r_j(k) - phi_G(k)^T theta_G`` (= G_hat(z) r_j, eq. 26, 29–31) and
   ``v_dyn(k) = phi_v(k)^T theta_v`` (eq. 33, 46) with theta = theta(k) (``a_posteriori``)
   or theta(k-1) (``a_priori``).
4. F1, F2 (Fig. 11): first-order low-pass, unit DC gain, discretised by matching the pole
   (exponential / impulse-invariant): ``y(k) = a y(k-1) + (1 - a) x(k)``,
   ``a = exp(-2π f_c Ts)`` — i.e. ``scipy.signal.lfilter([1 - a], [1, -a], x)`` from rest.
   (method.md §8: Tustin vs exponential did not matter.)
5. RMS over the previous N samples, the current one excluded (eq. 41):
   ``r_rms(k) = sqrt(sum_{i=1..N1} r_f(k-i)^2 / N1)``, samples before the start = 0;
   v_rms likewise over N2.
6. Decision (eq. 42): ``d(k) = r_rms(k) > |v_stat + v_rms(k)|``; ``threshold`` is
   ``|v_stat + v_rms|``.

a priori vs a posteriori (method.md §3) — measured
--------------------------------------------------
Default: ``a_posteriori``. Measurement (``tests/test_detect_adaptive.py::
test_a_posteriori_default_is_measured`` reproduces it): a 2-joint synthetic residual (40 s
at 4 ms, state-dependent model error driven by triangle-like references, white noise) with
three added 0.5 N·m, 80 ms contact pulses. With each option's v_stat set to 1.2 × its own
collision-free maximum of r_rms − v_rms (after 5 s), the peak of r_rms / threshold during
each pulse was 0.94, 1.13, 0.93 (mean 1.001) a priori and 1.00, 1.20, 1.05 (mean 1.080)
a posteriori — about 8 % more margin over the threshold, no false alarm with either (the
default wind-up guard does not act in these 40 s: plain eq. 39; with every diagonal
element of P capped at p0, max_trace = nu·p0, the means were 1.006 and 1.028); the fitted
G was the same near-differentiator (|G| = 0.04 at 1 Hz, 1.58 at 62.5 Hz) in both. This
agrees with the simulation study quoted in method.md §3. ``a_priori`` stays available (the
conservative reading: the update that sees a collision cannot absorb it).

Sample rate (method.md §5b): orders are in samples; N1, N2 are durations converted at the
log's rate (at least 1 sample); w1, w2 are clipped below 0.4 × fs with an ImpactWarning.

Two implementations of the same equations: :func:`evaluate_chunk` / :func:`evaluate`
(the compiled per-axis kernel of :mod:`impactcli.detect.axes`) and
:func:`evaluate_reference` (plain NumPy, obviously correct); tests compare them to 1e-9.

Chunks and state (architecture.md, "Streaming")
-----------------------------------------------
:func:`evaluate_chunk` ``(state, residual (n, J), inputs (m, n, J), fs, v_stat, cfg) ->
(result, new_state)`` runs the compiled per-axis kernel (:mod:`impactcli.detect.axes`)
on one chunk; the kernel reads the state at the start and writes it back at the end (the state
passed in is left as it was). :func:`evaluate`, the whole-log API, is ``evaluate_chunk``
on the whole log as one chunk from :meth:`EvaluatorState.initial`: one implementation.
:class:`EvaluatorState` holds exactly what the recursion carries from sample k0 − 1 to
k0 (k0 = ``n_samples``, the samples absorbed so far), per axis j:

- theta(k0−1) and P(k0−1) of eq. 38–39 (P as the RLS kernel keeps it: the lower
  triangle; initially theta0 and p0 I, Table I), and the reset / wind-up-guard counters;
- the regressor's past values (eq. 31–35, 51–54): r_j(k0−eta..k0−1), v_dyn_j(k0−p..k0−1)
  (the pseudo-linear block: values this algorithm computed) and u_{i,l}(k0−rho_max..k0−1)
  of every input type i and axis l — one copy shared by the axes, since every axis's
  inputs enter every regression (eq. 34); initially 0 (samples before the start are 0);
- the outputs r_f(k0−1), v_f(k0−1) of F1 and F2 (step 4; initially 0: from rest);
- eq. 41's windows: ring buffers of the last N1 values r_f² and N2 values v_f² and their
  running sums; the ring positions are k0 mod N1 and k0 mod N2;
- the settings it was made for (``cfg``, ``rates``): a chunk with others is refused.

Guarantee, for any split of a log into consecutive chunks (any sizes, 1 sample included;
boundaries inside the regression's start-up, inside a contact, while the wind-up guard
acts): the chunks' outputs concatenated (:func:`join_chunks`) are bit for bit those of the
whole-log call, and so is the final state. The kernel performs the same floating-point
operations in the same order whatever the boundaries: every value carried across a
boundary is stored in float64 exactly as the next iteration reads it (nothing is
recomputed at a boundary), and the RMS running sums are updated sample by sample and
re-summed from their ring at every wrap, at the samples k ≡ 0 (mod N) of the whole log,
not of the chunk — so their rounding depends on k alone and cannot drift with the
chunking. ``tests/test_evaluator_chunks.py`` checks ``np.array_equal`` of every output and
every state array for chunks of 1, 7, 1000, 4096 samples and the whole log, and for
boundaries after samples 1–5, mid-contact and at random places, on sample_logs'
assist_impacts (guard acting: a still elbow) and synthetic logs (a standstill and
contact pulses; a priori, plain eq. 39, other windows, axes on threads). Cost per chunk:
a copy of the state (J·nu² for P), the axes' Python dispatch (tests/benchmarks/bench_rls.py).
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..causal import Carry
from ..config import AdaptiveConfig
from ..errors import ImpactWarning
from ..iir import butter_lowpass
from ..types import RobotLog
from .axes import AxisJob, AxisRunner
from .rls import max_diag_of

#: Frequencies at which |G_hat| is reported [Hz] (plus fs/4 = Nyquist/2, added per log).
GAIN_FREQUENCIES_HZ: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0, 20.0)


@dataclass(frozen=True)
class Rates:
    """Table I's settings converted at a sample rate (method.md §5b).

    Attributes:
        fs_hz: sample rate [Hz].  n1, n2: RMS windows [samples].
        w1_hz, w2_hz: F1/F2 cut-offs after clipping [Hz].
        a1, a2: F1/F2 poles exp(-2π w Ts).
    """

    fs_hz: float
    n1: int
    n2: int
    w1_hz: float
    w2_hz: float
    a1: float
    a2: float


def clip_cutoff(f_hz: float, fs_hz: float, what: str) -> float:
    """Clip a cut-off below 0.4·fs with an ImpactWarning (method.md §5b)."""
    lim = 0.4 * fs_hz
    if f_hz > lim:
        warnings.warn(
            f"{what} cut-off {f_hz:g} Hz is above 0.4 × the sample rate {fs_hz:g} Hz; "
            f"clipped to {lim:g} Hz", ImpactWarning, stacklevel=3,
        )
        return lim
    return float(f_hz)


def lowpass_pole(f_hz: float, fs_hz: float) -> float:
    """Pole a = exp(-2π f Ts) of the unit-DC-gain first-order low-pass."""
    return float(np.exp(-2.0 * np.pi * f_hz / fs_hz))


def resolve_rates(cfg: AdaptiveConfig, fs_hz: float) -> Rates:
    """Convert durations and cut-offs of ``cfg`` at ``fs_hz`` (method.md §5b)."""
    n1 = max(1, round(cfg.n1_s * fs_hz))
    n2 = max(1, round(cfg.n2_s * fs_hz))
    w1 = clip_cutoff(cfg.w1_hz, fs_hz, "F1 (w1)")
    w2 = clip_cutoff(cfg.w2_hz, fs_hz, "F2 (w2)")
    return Rates(float(fs_hz), n1, n2, w1, w2, lowpass_pole(w1, fs_hz), lowpass_pole(w2, fs_hz))


# ----------------------------------------------------------------------------- inputs
@dataclass(frozen=True)
class ThresholdInputs:
    """Inputs u_i of the dynamic threshold (Table I).

    Attributes:
        u: (m, N, J) with u[0] = tanh(slope · x1_ref') [-] and u[1] = x1_ref'' [rad/s²].
        source: ``velocity_ref`` (logged reference derivatives), ``position_ref`` (causal
            finite differences of the logged reference position) or ``measured`` (causally
            filtered measured position; no reference logged).
        detail: how u was made, in words (recorded in the timeline: two logs of one run
            with and without an acceleration reference give slightly different inputs).
    """

    u: np.ndarray
    source: str
    detail: str = ""


def _butter(fc_hz: float, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    b, a = butter_lowpass(2, fc_hz / (0.5 * fs_hz))
    return np.asarray(b), np.asarray(a)


def threshold_inputs(log: RobotLog, cfg: AdaptiveConfig | None = None) -> ThresholdInputs:
    """Build (u1, u2) from a log (paper Sec. IV: inputs from the reference trajectory):
    :func:`inputs_chunk` on the whole log."""
    return inputs_chunk(log, log.time_s, log.sample_rate_hz, cfg, Carry(), log.source.path)


def inputs_chunk(
    chunk: Any, time_s: np.ndarray, sample_rate_hz: float, cfg: AdaptiveConfig | None,
    carry: Carry, where: str = "",
) -> ThresholdInputs:
    """(u1, u2) of one chunk of a log, continued from ``carry`` (:mod:`impactcli.causal`).

    Order of preference: logged ``velocity_ref`` (and ``acceleration_ref``, else its causal
    backward difference); else causal backward differences of ``position_ref``; else the
    measured position through a causal 2nd-order Butterworth at
    ``cfg.measured_input_cutoff_hz`` (clipped below 0.4 fs) before each backward
    difference — with an ImpactWarning (at the log's first chunk), since the paper's
    anticipation is lost.

    Args:
        chunk: a :class:`~impactcli.types.RobotLog` or a chunk of one (its ``position``,
            ``position_ref``, ``velocity_ref``, ``acceleration_ref``: (n, J) or None).
        time_s: (n,) the chunk's times [s since the log's first sample].
        sample_rate_hz: the whole log's rate [Hz].
        cfg: settings; carry: state after the previous chunk (updated); where: for messages.

    Returns ThresholdInputs with u of shape (2, n, J).
    """
    cfg = cfg or AdaptiveConfig()
    t = np.asarray(time_s, dtype=np.float64)
    dt = carry.steps_s("t", t)
    if chunk.velocity_ref is not None:
        v = np.asarray(chunk.velocity_ref)
        if chunk.acceleration_ref is not None:
            acc = np.asarray(chunk.acceleration_ref)
            detail = "velocity_ref and acceleration_ref as logged"
        else:
            acc = carry.backward_difference("v_ref", v, dt)
            detail = ("velocity_ref as logged; acceleration by causal backward difference "
                      "(no acceleration_ref logged)")
        source = "velocity_ref"
    elif chunk.position_ref is not None:
        v = carry.backward_difference("q_ref", np.asarray(chunk.position_ref), dt)
        acc = carry.backward_difference("v", v, dt)
        source = "position_ref"
        detail = "position_ref; velocity and acceleration by causal backward differences"
    else:
        if "q_meas" not in carry.state:
            warnings.warn(
                f"{where}: no reference trajectory logged; the dynamic threshold's "
                "inputs come from the causally filtered measured position",
                ImpactWarning, stacklevel=2,
            )
        fs = sample_rate_hz
        fc = clip_cutoff(cfg.measured_input_cutoff_hz, fs, "measured-input filter")
        b, a = _butter(fc, fs)
        qf = carry.lfilter("q_meas", b, a, np.asarray(chunk.position), "steady")
        v = carry.lfilter("v_meas", b, a, carry.backward_difference("qf", qf, dt), "steady")
        acc = carry.backward_difference("v", v, dt)
        source = "measured"
        detail = (f"measured position, causal {fc:g} Hz low-pass, backward differences "
                  "(no reference logged)")
    u = np.stack([np.tanh(cfg.tanh_slope * v), acc]).astype(np.float64)
    return ThresholdInputs(np.ascontiguousarray(u), source, detail)


# ----------------------------------------------------------------------------- result
@dataclass(frozen=True)
class AdaptiveResult:
    """Output of the adaptive evaluator. Arrays (N, J) unless stated; torques in N·m.

    Attributes:
        r_tilde: G_hat(z) r (eq. 26).  v_dyn: dynamic threshold (eq. 33).
        r_f, v_f: after F1 / F2.  r_rms, v_rms: eq. 41 over N1 / N2.
        threshold: |v_stat + v_rms|.  decision: bool, eq. 42.
        prediction_error: a priori RLS error eps0 (eq. 40).
        theta: (J, nu) final estimates.  n_resets: (J,) RLS covariance resets.
        rates: the converted settings.  nu: number of parameters per axis.
        eta: degree of G (theta[:, :eta] is theta_G).
        n_capped: (J,) samples at which the RLS wind-up guard scaled P
            (:mod:`impactcli.detect.rls`).
    """

    r_tilde: np.ndarray
    v_dyn: np.ndarray
    r_f: np.ndarray
    v_f: np.ndarray
    r_rms: np.ndarray
    v_rms: np.ndarray
    threshold: np.ndarray
    decision: np.ndarray
    prediction_error: np.ndarray
    theta: np.ndarray
    n_resets: np.ndarray
    rates: Rates
    nu: int
    eta: int
    n_capped: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def statistic(self) -> np.ndarray:
        """(N, J) r_rms − v_rms: what v_stat must exceed (calibration)."""
        return self.r_rms - self.v_rms

    @property
    def ratio(self) -> np.ndarray:
        """(N, J) r_rms / threshold (decision ⇔ ratio > 1)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.threshold > 0, self.r_rms / self.threshold, np.inf)

    def g_gain(self, freqs_hz: Sequence[float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """|G_hat(e^{jωTs})| per joint from the final theta_G (method.md §7).

        Returns (freqs (F,), gain (J, F)); default frequencies 1, 2, 5, 10, 20 Hz and fs/4.
        """
        if freqs_hz is None:
            freqs_hz = [f for f in GAIN_FREQUENCIES_HZ if f < 0.5 * self.rates.fs_hz]
            freqs_hz.append(0.25 * self.rates.fs_hz)
        f = np.asarray(freqs_hz, dtype=np.float64)
        return f, g_gain(self.theta[:, : self.eta], f, self.rates.fs_hz)


def g_gain(theta_g: np.ndarray, freqs_hz: np.ndarray, fs_hz: float) -> np.ndarray:
    """|G(e^{jωTs})| with G(z) = 1 − sum_d theta_G[d-1] z^-d (eq. 29, theta_G = −gamma).

    Args: theta_g (J, eta); freqs_hz (F,); fs_hz. Returns (J, F).
    """
    th = np.atleast_2d(theta_g)
    w = 2.0 * np.pi * np.asarray(freqs_hz, dtype=np.float64) / fs_hz
    d = np.arange(1, th.shape[1] + 1)
    zd = np.exp(-1j * np.outer(w, d))  # (F, eta): e^{-jωTs d}
    g = 1.0 - th @ zd.T
    return np.abs(g)


# ----------------------------------------------------------------------------- state
@dataclass(frozen=True)
class EvaluatorState:
    """Everything the evaluator carries from one sample to the next (module docstring,
    "Chunks and state"). Arrays have the axis first; ``evaluate_chunk`` never modifies a
    state it is given (it returns a new one).

    Attributes:
        theta: (J, nu) theta(k0-1) (eq. 38).
        P: (J, nu, nu) P(k0-1), LOWER triangle authoritative (:mod:`impactcli.detect.rls`).
        r_lags: (J, eta) r_j(k0-eta) .. r_j(k0-1), oldest first (phi's first block, eq. 51).
        v_lags: (J, p) v_dyn_j(k0-p) .. v_dyn_j(k0-1), oldest first (pseudo-linear block).
        u_lags: (m, rho_max, J) u_{i,l}(k0-rho_max) .. u_{i,l}(k0-1), oldest first; shared
            by all axes (every axis's inputs enter every regression, eq. 34).
        filters: (J, 2) F1 and F2 outputs r_f(k0-1), v_f(k0-1) (Fig. 11).
        ring_r: (J, N1) r_f² of the last N1 samples (eq. 41), slot ``k % N1``.
        ring_v: (J, N2) v_f² of the last N2 samples, slot ``k % N2``.
        sums: (J, 2) the running sums of ring_r and ring_v as the kernel keeps them.
        n_samples: samples absorbed so far (k0); fixes the ring positions.
        n_resets, n_capped: (J,) covariance resets and wind-up-guard steps so far.
        cfg, rates: the settings the state was made for (a chunk must use the same).
    """

    theta: np.ndarray
    P: np.ndarray
    r_lags: np.ndarray
    v_lags: np.ndarray
    u_lags: np.ndarray
    filters: np.ndarray
    ring_r: np.ndarray
    ring_v: np.ndarray
    sums: np.ndarray
    n_samples: int
    n_resets: np.ndarray
    n_capped: np.ndarray
    cfg: AdaptiveConfig
    rates: Rates

    @property
    def n_joints(self) -> int:
        return int(self.theta.shape[0])

    @property
    def nu(self) -> int:
        return int(self.theta.shape[1])

    @classmethod
    def initial(cls, n_joints: int, cfg: AdaptiveConfig | None = None,
                sample_rate_hz: float = 250.0) -> EvaluatorState:
        """The state before the first sample: theta = theta0, P = p0 I (Table I), every
        past value 0 (samples before the log start are 0), filters at rest, empty windows."""
        cfg = cfg or AdaptiveConfig()
        J = int(n_joints)
        nu = cfg.n_params(J)
        rates = resolve_rates(cfg, sample_rate_hz)
        P = np.zeros((J, nu, nu))
        idx = np.arange(nu)
        P[:, idx, idx] = cfg.p0
        return cls(
            theta=np.full((J, nu), float(cfg.theta0)), P=P,
            r_lags=np.zeros((J, cfg.eta)), v_lags=np.zeros((J, cfg.p)),
            u_lags=np.zeros((len(cfg.rho), max(cfg.rho, default=0), J)),
            filters=np.zeros((J, 2)), ring_r=np.zeros((J, rates.n1)),
            ring_v=np.zeros((J, rates.n2)), sums=np.zeros((J, 2)), n_samples=0,
            n_resets=np.zeros(J, dtype=np.int64), n_capped=np.zeros(J, dtype=np.int64),
            cfg=cfg, rates=rates,
        )

    def copy(self) -> EvaluatorState:
        """A deep copy (the arrays are copied; cfg and rates are immutable)."""
        return dataclasses.replace(self, **{
            f.name: getattr(self, f.name).copy() for f in dataclasses.fields(self)
            if isinstance(getattr(self, f.name), np.ndarray)})


# ----------------------------------------------------------------------------- kernels
def _check(r: np.ndarray, u: np.ndarray, v_stat: np.ndarray, cfg: AdaptiveConfig) -> None:
    if r.ndim != 2:
        raise ValueError(f"residual must be (N, J), got shape {r.shape}")
    if u.ndim != 3 or u.shape[1:] != r.shape:
        raise ValueError(f"inputs must be (m, N, J) = (m, {r.shape}), got {u.shape}")
    if u.shape[0] != len(cfg.rho):
        raise ValueError(f"{u.shape[0]} input types but rho has {len(cfg.rho)} orders")
    if v_stat.shape != (r.shape[1],):
        raise ValueError(f"v_stat must be ({r.shape[1]},), got {v_stat.shape}")


def default_threads(n_samples: int) -> int:
    """One thread per core from 100k samples (below, a thread's start costs more), else 1."""
    return (os.cpu_count() or 1) if n_samples >= 100_000 else 1


def evaluate_chunk(
    state: EvaluatorState, residual_chunk: np.ndarray, inputs_chunk: np.ndarray,
    sample_rate_hz: float, v_stat: Sequence[float] | np.ndarray,
    cfg: AdaptiveConfig | None = None, threads: int = 1,
    progress: Callable[[int, int], None] | None = None, *, _consume: bool = False,
) -> tuple[AdaptiveResult, EvaluatorState]:
    """Run the adaptive evaluator (compiled) on one chunk, continuing from ``state``.

    Args:
        state: the state after the previous chunk (:meth:`EvaluatorState.initial` before
            the first); not modified.
        residual_chunk: (n, J) residual of the chunk [N·m] (n may be 0).
        inputs_chunk: (m, n, J) threshold inputs of the chunk.
        sample_rate_hz: fs [Hz]; must be the state's.
        v_stat: (J,) static thresholds [N·m] (eq. 42).
        cfg: settings; None → the state's; otherwise must equal the state's.
        threads, progress: as :func:`evaluate`.

    Returns:
        (result, new_state): ``result`` holds the chunk's (n, J) signals; its ``theta``,
        ``n_resets`` and ``n_capped`` are the new state's (totals since the first chunk),
        so :func:`join_chunks` of the results equals :func:`evaluate` on the whole log,
        bit for bit (module docstring).
    """
    cfg = state.cfg if cfg is None else cfg
    if cfg != state.cfg:
        raise ValueError("cfg differs from the one the evaluator state was made with")
    if float(sample_rate_hz) != state.rates.fs_hz:
        raise ValueError(f"sample rate {sample_rate_hz} Hz differs from the state's "
                         f"{state.rates.fs_hz} Hz")
    r = np.ascontiguousarray(residual_chunk, dtype=np.float64)
    u = np.ascontiguousarray(inputs_chunk, dtype=np.float64)
    vs = np.ascontiguousarray(v_stat, dtype=np.float64)
    _check(r, u, vs, cfg)
    if r.shape[1] != state.n_joints:
        raise ValueError(f"{r.shape[1]} joints but the state has {state.n_joints}")
    st = state if _consume else state.copy()
    with AxisRunner(st, vs, threads) as runner:
        job = runner.submit(r, u)
        job.wait(progress)
    return result_of(job, st), dataclasses.replace(st, n_samples=runner.n_samples)


def result_of(job: AxisJob, state: EvaluatorState) -> AdaptiveResult:
    """The :class:`AdaptiveResult` of a chunk the axes have done (:mod:`.axes`)."""
    rt, vd, rf, vf, rr, vr, thr, dec, eps = job.out
    return AdaptiveResult(rt, vd, rf, vf, rr, vr, thr, dec, eps, job.theta, job.resets,
                          rates=state.rates, nu=state.nu, eta=state.cfg.eta,
                          n_capped=job.capped)


def join_chunks(results: Sequence[AdaptiveResult]) -> AdaptiveResult:
    """The chunks' results as one: signals concatenated in time; theta and the counters
    from the last chunk (totals)."""
    if not results:
        raise ValueError("no chunks to join")
    last = results[-1]
    rt, vd, rf, vf, rr, vr, thr, dec, eps = (
        np.concatenate([getattr(x, name) for x in results], axis=0) for name in SIGNALS)
    return AdaptiveResult(rt, vd, rf, vf, rr, vr, thr, dec, eps, last.theta, last.n_resets,
                          rates=last.rates, nu=last.nu, eta=last.eta, n_capped=last.n_capped)


#: The (N, J) signals of an :class:`AdaptiveResult` (concatenated over chunks).
SIGNALS = ("r_tilde", "v_dyn", "r_f", "v_f", "r_rms", "v_rms", "threshold", "decision",
           "prediction_error")


def evaluate(
    residual: np.ndarray, inputs: np.ndarray, sample_rate_hz: float,
    v_stat: Sequence[float] | np.ndarray, cfg: AdaptiveConfig | None = None,
    threads: int | None = None, progress: Callable[[int, int], None] | None = None,
) -> AdaptiveResult:
    """Run the adaptive evaluator (compiled) on all axes: :func:`evaluate_chunk` on the
    whole log as one chunk from :meth:`EvaluatorState.initial`.

    Args:
        residual: (N, J) residual r = tau_hat − tau [N·m].
        inputs: (m, N, J) threshold inputs (see :func:`threshold_inputs`).
        sample_rate_hz: fs [Hz].
        v_stat: (J,) static thresholds [N·m] (eq. 42).
        cfg: settings (Table I defaults).
        threads: > 1 runs the axes concurrently, each on a thread of its own (results are
            identical: axes are independent); None → :func:`default_threads`.
        progress: called with (axes done, axes) after each axis (every axis costs the same).
    """
    cfg = cfg or AdaptiveConfig()
    if threads is None:
        threads = default_threads(np.shape(residual)[0])
    r = np.asarray(residual)
    if r.ndim != 2:
        raise ValueError(f"residual must be (N, J), got shape {r.shape}")
    state = EvaluatorState.initial(r.shape[1], cfg, sample_rate_hz)
    res, _ = evaluate_chunk(state, r, inputs, sample_rate_hz, v_stat, cfg, threads, progress,
                            _consume=True)
    return res


def evaluate_reference(
    residual: np.ndarray, inputs: np.ndarray, sample_rate_hz: float,
    v_stat: Sequence[float] | np.ndarray, cfg: AdaptiveConfig | None = None,
) -> AdaptiveResult:
    """Plain NumPy implementation of the same equations (slow; for tests)."""
    cfg = cfg or AdaptiveConfig()
    r = np.asarray(residual, dtype=np.float64)
    u = np.asarray(inputs, dtype=np.float64)
    vs = np.asarray(v_stat, dtype=np.float64)
    _check(r, u, vs, cfg)
    rates = resolve_rates(cfg, sample_rate_hz)
    n, J = r.shape
    eta, p, rho = cfg.eta, cfg.p, cfg.rho
    nu = cfg.n_params(J)
    lam = cfg.forgetting_factor
    cap = max_diag_of(nu, cfg.p0, cfg.max_trace)

    def past(x: np.ndarray, k: int, order: int) -> np.ndarray:
        """[x(k-1), ..., x(k-order)], zero before the start."""
        return np.array([x[k - d] if k - d >= 0 else 0.0 for d in range(1, order + 1)])

    res = {name: np.zeros((n, J)) for name in
           ("rt", "vd", "rf", "vf", "rr", "vr", "thr", "eps")}
    dec = np.zeros((n, J), dtype=bool)
    thetas = np.zeros((J, nu))
    capped = np.zeros(J, dtype=np.int64)
    for j in range(J):
        theta = np.full(nu, cfg.theta0)
        P = cfg.p0 * np.eye(nu)
        for k in range(n):
            parts = [past(r[:, j], k, eta), past(res["vd"][:, j], k, p)]
            for i in range(len(rho)):
                for ll in range(J):
                    parts.append(past(u[i, :, ll], k, rho[i]))
            phi = np.concatenate(parts)
            eps0 = r[k, j] - theta @ phi                                  # eq. 40
            s = phi @ P @ phi
            h = P @ phi
            gain = h / (lam + s)
            theta_new = theta + gain * eps0                               # eq. 38
            P = (P - np.outer(h, h) / (lam + s)) / lam                    # eq. 39
            over = np.diag(P) > cap                                       # wind-up guard
            if over.any():
                w = np.where(over, np.sqrt(cap / np.where(over, np.diag(P), 1.0)), 1.0)
                P = P * np.outer(w, w)                                    # W P W
                capped[j] += 1
            tv = theta_new if cfg.estimate == "a_posteriori" else theta
            theta = theta_new
            res["eps"][k, j] = eps0
            res["rt"][k, j] = r[k, j] - phi[:eta] @ tv[:eta]
            res["vd"][k, j] = phi[eta:] @ tv[eta:]
        thetas[j] = theta
    from scipy import signal  # the reference only (tests)

    res["rf"] = signal.lfilter([1 - rates.a1], [1, -rates.a1], res["rt"], axis=0)
    res["vf"] = signal.lfilter([1 - rates.a2], [1, -rates.a2], res["vd"], axis=0)
    for name, src, nn in (("rr", "rf", rates.n1), ("vr", "vf", rates.n2)):
        padded = np.vstack([np.zeros((nn, J)), res[src]])
        for k in range(n):
            window = padded[k : k + nn]        # samples k-nn .. k-1
            res[name][k] = np.sqrt(np.sum(window**2, axis=0) / nn)
    res["thr"] = np.abs(vs + res["vr"])
    dec = res["rr"] > res["thr"]
    return AdaptiveResult(
        res["rt"], res["vd"], res["rf"], res["vf"], res["rr"], res["vr"], res["thr"], dec,
        res["eps"], thetas, np.zeros(J, dtype=np.int64), rates=rates, nu=nu, eta=eta,
        n_capped=capped,
    )


# ----------------------------------------------------------------------------- scale guard
#: Measured speed of the compiled evaluator at nu = 64 [axis-samples/s] on the project's
#: 2-core machine, one thread (``tests/benchmarks/bench_rls.py``: 0.93–0.98 M); the cost
#: per axis-sample grows as nu² (the covariance update).
AXIS_SAMPLES_PER_S_AT_NU64 = 0.9e6
#: Refuse (unless told) a replay estimated to run slower than the log's own time ...
MAX_COST_PER_LOG_SECOND = 1.0
#: ... or whose covariances need more memory than this [bytes].
MAX_COVARIANCE_BYTES = 2 * 1024**3


def replay_cost(n_joints: int, sample_rate_hz: float, cfg: AdaptiveConfig | None = None
                ) -> tuple[float, float]:
    """(seconds of compute per second of log, bytes of covariance) of the adaptive
    evaluator for ``n_joints`` axes: J axes, each an RLS with nu = eta + p + J·Σrho
    parameters (eq. 34–35), costing ∝ nu² per sample. Depends on the joint count and the
    rate, never on the log's duration."""
    cfg = cfg or AdaptiveConfig()
    nu = cfg.n_params(n_joints)
    per_sample = n_joints * (nu / 64.0) ** 2 / AXIS_SAMPLES_PER_S_AT_NU64
    return per_sample * sample_rate_hz, float(n_joints * nu * nu * 8)


def check_scale(n_joints: int, sample_rate_hz: float, cfg: AdaptiveConfig | None = None,
                where: str = "log") -> None:
    """Raise :class:`~impactcli.errors.ScaleLimitError` (exit 2) when the replay is
    estimated to run slower than real time or to need more than 2 GiB of covariance."""
    from ..errors import ScaleLimitError

    cost, mem = replay_cost(n_joints, sample_rate_hz, cfg)
    if cost > MAX_COST_PER_LOG_SECOND or mem > MAX_COVARIANCE_BYTES:
        raise ScaleLimitError(
            f"{where}: {n_joints} joints at {sample_rate_hz:.4g} Hz: the adaptive evaluator is "
            f"estimated at {cost:.3g} s of compute per second of log and "
            f"{mem / 1024**3:.3g} GiB of covariance (its cost grows with the cube of the joint "
            f"count), above the limit of {MAX_COST_PER_LOG_SECOND:g} s per second of log and "
            f"{MAX_COVARIANCE_BYTES / 1024**3:g} GiB: give --allow-slow to run it anyway")

