"""Adaptive residual evaluation, axis by axis (paper Section III, eq. 24–42, App. A/B).

For axis j, at each sample k: the regressor phi(k) = [r_j(k-1..k-eta) | v_dyn_j(k-1..k-p)
| u_{i,l}(k-1..k-rho_i) for every input type i and axis l] (eq. 31–35, 51–54; nu = eta +
p + n·sum(rho): 34 for 2 joints, 64 for 7 at Table I; past v_dyn are the values this
algorithm computed, samples before the log start are 0); RLS with constant forgetting on
y = r_j(k) (eq. 38–40) and a regulariser that keeps a floor of information about theta
(:mod:`impactcli.detect.rls`; docs/method.md §3); r_tilde = r_j − phi_G^T theta_G
(eq. 26) and v_dyn = phi_v^T theta_v (eq. 33) with theta(k) (``a_posteriori``, the
default, measured in docs/method.md §3) or theta(k-1) (``a_priori``); F1, F2 first-order
low-passes matched by the pole (Fig. 11); RMS over the previous N1 / N2 samples, the
current one excluded (eq. 41); decision r_rms > |v_stat + v_rms| (eq. 42). Settings at the
log's rate: :mod:`impactcli.detect.rates`.

:func:`evaluate_chunk` ``(state, residual (n, J), inputs (m, n, J), fs, v_stat) ->
(result, new_state)`` runs the compiled per-axis kernel of :mod:`impactcli.detect.axes`
on one chunk from an :class:`~impactcli.detect.axes.EvaluatorState`; the chunks' results
joined (:func:`join_chunks`) are bit for bit those of one call on the whole log, and so is
the final state (docs/method.md §3, "Chunks and state"). :func:`inputs_chunk` makes the
threshold's inputs u1, u2 (Table I) chunk by chunk. The plain NumPy reference the tests
compare the kernel against is ``tests/reference/adaptive.py``.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..config import AdaptiveConfig
from ..cores import cores
from ..errors import ImpactWarning
from ..model.causal import Carry
from ..model.iir import butter_lowpass
from .axes import AxisJob, AxisRunner, EvaluatorState
from .rates import Rates, clip_cutoff

#: Frequencies at which |G_hat| is reported [Hz] (plus fs/4 = Nyquist/2, added per log).
GAIN_FREQUENCIES_HZ: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0, 20.0)


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


def _butter(fc_hz: float, sample_rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    b, a = butter_lowpass(2, fc_hz / (0.5 * sample_rate_hz))
    return np.asarray(b), np.asarray(a)


def inputs_chunk(
    chunk: Any, time_s: np.ndarray, sample_rate_hz: float, cfg: AdaptiveConfig | None,
    carry: Carry, where: str = "",
) -> ThresholdInputs:
    """(u1, u2) of one chunk of a log, continued from ``carry`` (:mod:`impactcli.model.causal`).

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
                "inputs come from the causally filtered measured position (no "
                "anticipation of the motion)",
                ImpactWarning, stacklevel=2,
            )
        fc = clip_cutoff(cfg.measured_input_cutoff_hz, sample_rate_hz, "measured-input filter")
        b, a = _butter(fc, sample_rate_hz)
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
        theta_g: (S, J, eta) theta_G as G_hat used it (eq. 26) at the samples whose index
            in the log is a multiple of :data:`impactcli.detect.axes.SNAP_EVERY`, in order
            (the detection floor's blow through G_hat as it stood).
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
    theta_g: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))

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
        """|G_hat(e^{jωTs})| per joint from the final theta_G (docs/method.md §7).

        Returns (freqs (F,), gain (J, F)); default frequencies 1, 2, 5, 10, 20 Hz and fs/4.
        """
        if freqs_hz is None:
            freqs_hz = [f for f in GAIN_FREQUENCIES_HZ if f < 0.5 * self.rates.sample_rate_hz]
            freqs_hz.append(0.25 * self.rates.sample_rate_hz)
        f = np.asarray(freqs_hz, dtype=np.float64)
        return f, g_gain(self.theta[:, : self.eta], f, self.rates.sample_rate_hz)


def g_gain(theta_g: np.ndarray, freqs_hz: np.ndarray, sample_rate_hz: float) -> np.ndarray:
    """|G(e^{jωTs})| with G(z) = 1 − sum_d theta_G[d-1] z^-d (eq. 29, theta_G = −gamma).

    Args: theta_g (J, eta); freqs_hz (F,); sample_rate_hz. Returns (J, F).
    """
    th = np.atleast_2d(theta_g)
    w = 2.0 * np.pi * np.asarray(freqs_hz, dtype=np.float64) / sample_rate_hz
    d = np.arange(1, th.shape[1] + 1)
    zd = np.exp(-1j * np.outer(w, d))  # (F, eta): e^{-jωTs d}
    g = 1.0 - th @ zd.T
    return np.abs(g)


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
    """One thread per core this process may use (:func:`impactcli.cores.cores`: its share
    in a pool worker) from 100k samples (below, a thread's start costs more), else 1."""
    return cores() if n_samples >= 100_000 else 1


def evaluate_chunk(
    state: EvaluatorState, residual_chunk: np.ndarray, inputs_chunk: np.ndarray,
    sample_rate_hz: float, v_stat: Sequence[float] | np.ndarray,
    cfg: AdaptiveConfig | None = None, threads: int = 1,
    progress: Callable[[int, int], None] | None = None,
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
        threads: > 1 runs the axes concurrently, each on a thread of its own (results are
            identical: axes are independent; :func:`default_threads`).
        progress: called with (axes done, axes) after each axis.

    Returns:
        (result, new_state): ``result`` holds the chunk's (n, J) signals; its ``theta``,
        ``n_resets`` and ``n_capped`` are the new state's (totals since the first chunk),
        so :func:`join_chunks` of the results equals one call on the whole log, bit for
        bit (module docstring).
    """
    cfg = state.cfg if cfg is None else cfg
    if cfg != state.cfg:
        raise ValueError("cfg differs from the one the evaluator state was made with")
    if float(sample_rate_hz) != state.rates.sample_rate_hz:
        raise ValueError(f"sample rate {sample_rate_hz} Hz differs from the state's "
                         f"{state.rates.sample_rate_hz} Hz")
    r = np.ascontiguousarray(residual_chunk, dtype=np.float64)
    u = np.ascontiguousarray(inputs_chunk, dtype=np.float64)
    vs = np.ascontiguousarray(v_stat, dtype=np.float64)
    _check(r, u, vs, cfg)
    if r.shape[1] != state.n_joints:
        raise ValueError(f"{r.shape[1]} joints but the state has {state.n_joints}")
    st = state.copy()
    with AxisRunner(st, vs, threads) as runner:
        job = runner.submit(r, u)
        job.wait(progress)
    return result_of(job, st), dataclasses.replace(st, n_samples=runner.n_samples)


def result_of(job: AxisJob, state: EvaluatorState) -> AdaptiveResult:
    """The :class:`AdaptiveResult` of a chunk the axes have done (:mod:`.axes`)."""
    rt, vd, rf, vf, rr, vr, thr, dec, eps = job.out
    return AdaptiveResult(rt, vd, rf, vf, rr, vr, thr, dec, eps, job.theta, job.resets,
                          rates=state.rates, nu=state.nu, eta=state.cfg.eta,
                          n_capped=job.capped, theta_g=job.theta_g)


def join_chunks(results: Sequence[AdaptiveResult]) -> AdaptiveResult:
    """The chunks' results as one: signals concatenated in time; theta and the counters
    from the last chunk (totals)."""
    if not results:
        raise ValueError("no chunks to join")
    last = results[-1]
    rt, vd, rf, vf, rr, vr, thr, dec, eps = (
        np.concatenate([getattr(x, name) for x in results], axis=0) for name in SIGNALS)
    return AdaptiveResult(rt, vd, rf, vf, rr, vr, thr, dec, eps, last.theta, last.n_resets,
                          rates=last.rates, nu=last.nu, eta=last.eta, n_capped=last.n_capped,
                          theta_g=np.concatenate([x.theta_g for x in results], axis=0))


#: The (N, J) signals of an :class:`AdaptiveResult` (concatenated over chunks).
SIGNALS = ("r_tilde", "v_dyn", "r_f", "v_f", "r_rms", "v_rms", "threshold", "decision",
           "prediction_error")


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

