"""The adaptive evaluator's compiled per-axis kernel and the threads that run it
(paper eq. 34–42 for one axis; :mod:`impactcli.detect.adaptive` is the evaluator).

Axes are independent (eq. 34–35 per axis; only the inputs u are shared), so each runs on
a thread of its own (the kernel releases the GIL). :class:`AxisRunner` takes chunk after
chunk (:meth:`~AxisRunner.submit`) and gives each axis its chunks in order on a
single-thread executor of its own: axis j can work on chunk k + 1 while axis i still works
on chunk k and the caller makes chunk k + 2's residual (:func:`impactcli.run.replay.
Replayer`). Results are the same bits as one chunk at a time on one thread — each
axis runs the same kernel on the same values in the same order; what the axes share is
read only: each submitted chunk carries its own copy of the input lags u(k0−rho_max ..
k0−1) (the runner advances its copy at submission), and each axis snapshots its theta
and counters at the end of its chunk (the chunk's result holds those, not later ones).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numba as nb
import numpy as np

from ..config import AdaptiveConfig
from .floor import GAIN_EVERY
from .rates import Rates, resolve_rates
from .rls import (
    FASTMATH,
    REGULARIZE_EVERY,
    max_diag_of,
    regularization_weight,
    rls_update_inplace,
)

#: The kernel's (n,) outputs per axis, in :data:`impactcli.detect.adaptive.SIGNALS` order.
N_OUTPUTS = 9
DECISION = 7  # the boolean one
#: theta_G is kept at the log's samples whose index is a multiple of this: the detection
#: floor takes the blow's gain through G_hat as it stood there
#: (:data:`impactcli.detect.floor.GAIN_EVERY`).
SNAP_EVERY = GAIN_EVERY

@nb.njit(cache=True, nogil=True, fastmath=FASTMATH)
def _evaluate_axis(
    r: np.ndarray, u: np.ndarray, eta: int, p: int, rho: np.ndarray,
    lam: float, p0: float, max_diag: float, a_post: bool,
    a1: float, a2: float, n1: int, n2: int, v_stat_j: float,
    rt: np.ndarray, vd: np.ndarray, rf: np.ndarray, vf: np.ndarray, rr: np.ndarray,
    vr: np.ndarray, thr: np.ndarray, dec: np.ndarray, eps: np.ndarray,
    th: np.ndarray, P_state: np.ndarray, r_lag: np.ndarray, v_lag: np.ndarray, u_lag: np.ndarray,
    filt: np.ndarray, ring_r: np.ndarray, ring_v: np.ndarray, sums: np.ndarray,
    pos1: int, pos2: int, reg_c: float, theta0: float, pos_reg: int, every: int,
    th_snap: np.ndarray, snap_off: int, snap_every: int,
) -> tuple[int, int]:
    """One axis over one chunk: ``r`` (n,) is its residual, ``u`` (m, n, J) every axis's
    inputs; the outputs are this axis's (n,) rows. The state (``th`` (nu,), ``P_state`` (nu, nu)
    exactly symmetric, ``r_lag`` (eta,), ``v_lag`` (p,), ``filt`` (2,), ``ring_r`` (N1,),
    ``ring_v`` (N2,), ``sums`` (2,)) is read at the start and written back at the end, in
    place; ``u_lag`` (m, rho_max, J) is only read (shared by the axes; the caller advances
    it); ``pos1``, ``pos2`` are the ring positions (samples so far mod N1, N2);
    ``pos_reg`` the regulariser's phase (samples so far mod nu · ``every``): at every
    ``every``-th sample it regularises coordinate pos_reg // every with weight ``reg_c``
    (0: none, plain eq. 39) toward ``theta0`` (:func:`impactcli.detect.rls.rls_update_inplace`).
    ``th_snap`` (n_snap, eta) receives theta_G as G_hat used it (eq. 26) at samples
    ``snap_off``, ``snap_off`` + ``snap_every``, … of the chunk (the detection floor's).

    Axes are independent (eq. 34–35 per axis; only the inputs u are shared), so axes can
    run on separate threads (the kernel releases the GIL). Returns the covariance resets
    and the number of samples at which the wind-up guard scaled P, in this chunk.
    """
    n = r.shape[0]
    J = u.shape[2]
    m = u.shape[0]
    L = u_lag.shape[1]
    nu = th.shape[0]
    # read the state into locals (a private P lets the compiler vectorise eq. 39 without
    # alias checks); written back at the end
    P = P_state.copy()
    resets = 0
    capped = 0
    phi = np.zeros(nu)
    h = np.empty(nu)
    w = np.empty(nu)
    th_old = np.empty(nu)
    pc = np.empty(nu)
    gw = np.empty(nu)
    inv_n1 = 1.0 / n1
    inv_n2 = 1.0 / n2
    prev_r = filt[0]
    prev_v = filt[1]
    sn = 0
    snap_next = snap_off
    sum_r = sums[0]
    sum_v = sums[1]
    for k in range(n):
        # regressor phi(k): past residuals, past v_dyn, and the inputs u_{i,l}(k-1..k-rho_i)
        # of every type i and every axis l (Appendix A); before the chunk from the state
        for d in range(1, eta + 1):
            phi[d - 1] = r[k - d] if k - d >= 0 else r_lag[eta + k - d]
        for d in range(1, p + 1):
            phi[eta + d - 1] = vd[k - d] if k - d >= 0 else v_lag[p + k - d]
        c = eta + p
        for i in range(m):
            for ll in range(J):
                for d in range(1, rho[i] + 1):
                    phi[c] = u[i, k - d, ll] if k - d >= 0 else u_lag[i, L + k - d, ll]
                    c += 1
        if not a_post:
            for i in range(nu):
                th_old[i] = th[i]
        cc = reg_c if pos_reg % every == 0 else 0.0
        e, rs, cp = rls_update_inplace(th, P, phi, r[k], lam, max_diag, p0, h, w,
                                       pos_reg // every, cc, theta0, pc, gw)
        pos_reg += 1
        if pos_reg == nu * every:
            pos_reg = 0
        eps[k] = e
        resets += rs
        capped += cp
        tv = th if a_post else th_old
        g = 0.0
        for i in range(eta):
            g += phi[i] * tv[i]
        v = 0.0
        for i in range(eta, nu):
            v += phi[i] * tv[i]
        x = r[k] - g
        rt[k] = x
        if k == snap_next:
            for i in range(eta):
                th_snap[sn, i] = tv[i]
            sn += 1
            snap_next += snap_every
        vd[k] = v
        # F1 / F2 (from rest)
        prev_r = a1 * prev_r + (1.0 - a1) * x
        prev_v = a2 * prev_v + (1.0 - a2) * v
        rf[k] = prev_r
        vf[k] = prev_v
        # RMS over k-1..k-N (eq. 41): running sums of the last N squares (ring buffers,
        # re-summed exactly at every wrap so rounding cannot accumulate)
        sr = max(sum_r, 0.0)
        sv = max(sum_v, 0.0)
        q = prev_r * prev_r
        sum_r += q - ring_r[pos1]
        ring_r[pos1] = q
        q = prev_v * prev_v
        sum_v += q - ring_v[pos2]
        ring_v[pos2] = q
        a = np.sqrt(sr * inv_n1)
        b = np.sqrt(sv * inv_n2)
        rr[k] = a
        vr[k] = b
        t = abs(v_stat_j + b)
        thr[k] = t
        dec[k] = a > t
        pos1 += 1
        pos2 += 1
        if pos1 == n1:
            pos1 = 0
            sum_r = np.sum(ring_r)
        if pos2 == n2:
            pos2 = 0
            sum_v = np.sum(ring_v)
    # write the state back: P, filters, sums, the last eta residuals / p values of v_dyn
    P_state[:, :] = P
    filt[0] = prev_r
    filt[1] = prev_v
    sums[0] = sum_r
    sums[1] = sum_v
    _shift_in(r_lag, r, n)
    _shift_in(v_lag, vd, n)
    return resets, capped


@nb.njit(cache=True, nogil=True, inline="always")
def _shift_in(lag: np.ndarray, x: np.ndarray, n: int) -> None:
    """lag <- the last len(lag) values of [lag, x[:n]] (oldest first)."""
    L = lag.shape[0]
    if n >= L:
        for d in range(L):
            lag[d] = x[n - L + d]
    else:
        for d in range(L - n):
            lag[d] = lag[d + n]
        for d in range(n):
            lag[L - n + d] = x[d]



# ----------------------------------------------------------------------------- state
@dataclass(frozen=True)
class EvaluatorState:
    """Everything the evaluator carries from sample k0 − 1 to k0 (k0 = ``n_samples``), per
    axis: exactly what the recursion reads back, stored in float64 as the next iteration
    reads it, so any split of a log into chunks gives the same bits (docs/method.md §3,
    "Chunks and state"). Arrays have the axis first;
    :func:`impactcli.detect.adaptive.evaluate_chunk` never modifies a state it is given.

    Attributes:
        theta: (J, nu) theta(k0-1) (eq. 38).
        P: (J, nu, nu) P(k0-1), exactly symmetric (:mod:`impactcli.detect.rls`).
        r_lags: (J, eta) r_j(k0-eta) .. r_j(k0-1), oldest first (phi's first block, eq. 51).
        v_lags: (J, p) v_dyn_j(k0-p) .. v_dyn_j(k0-1), oldest first (pseudo-linear block).
        u_lags: (m, rho_max, J) u_{i,l}(k0-rho_max) .. u_{i,l}(k0-1), oldest first; shared
            by all axes (every axis's inputs enter every regression, eq. 34).
        filters: (J, 2) F1 and F2 outputs r_f(k0-1), v_f(k0-1) (Fig. 11).
        ring_r: (J, N1) r_f² of the last N1 samples (eq. 41), slot ``k % N1``.
        ring_v: (J, N2) v_f² of the last N2 samples, slot ``k % N2``.
        sums: (J, 2) the running sums of ring_r and ring_v as the kernel keeps them.
        n_samples: samples absorbed so far (k0); fixes the ring positions and the
            regulariser's phase (k0 mod nu · REGULARIZE_EVERY).
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


# ----------------------------------------------------------------------------- threads
#: The state's arrays each axis advances on its own thread (axis first).
_PER_AXIS = ("theta", "P", "r_lags", "v_lags", "filters", "ring_r", "ring_v", "sums",
             "n_resets", "n_capped")


@dataclass
class AxisJob:
    """One submitted chunk: its (n, J) outputs (filled by the axes), per axis the state's
    theta and counters at the chunk's end, and theta_G as G_hat used it at the chunk's
    samples whose index in the log is a multiple of :data:`SNAP_EVERY`."""

    n: int
    out: list[np.ndarray]  # N_OUTPUTS arrays (n, J)
    theta: np.ndarray  # (J, nu)
    resets: np.ndarray  # (J,) totals since the first chunk
    capped: np.ndarray  # (J,)
    theta_g: np.ndarray  # (n_snap, J, eta) theta_G at the log's samples k ≡ 0 mod SNAP_EVERY
    futures: list[Future[None]] = dataclasses.field(default_factory=list)

    def wait(self, progress: Callable[[int, int], None] | None = None) -> None:
        """Until every axis has done this chunk (``progress(axes done, J)`` after each;
        axes run at submission have all done)."""
        axes = self.theta.shape[0]
        for i in range(axes):
            if self.futures:
                self.futures[i].result()
            if progress is not None:
                progress(i + 1, axes)


class AxisRunner:
    """The evaluator's axes over consecutive chunks, each axis on a thread of its own when
    ``threads`` > 1 (module docstring); else on the calling thread at submission.

    Advances ``state``'s arrays IN PLACE (``u_lags`` at submission, each axis's own rows
    as it runs, the counters); :attr:`n_samples` counts the samples submitted. Use as a
    context manager (or call :meth:`close`): the threads end there.
    """

    def __init__(self, state: EvaluatorState, v_stat: np.ndarray, threads: int = 1) -> None:
        cfg, rates = state.cfg, state.rates
        self.state = state
        self.v_stat = v_stat
        self.n_samples = state.n_samples
        self._rho = np.asarray(cfg.rho, dtype=np.int64)
        self._max_diag = max_diag_of(state.nu, cfg.p0, cfg.max_trace)
        self._args = (cfg.eta, cfg.p, self._rho, float(cfg.forgetting_factor),
                      float(cfg.p0), self._max_diag, cfg.estimate == "a_posteriori",
                      rates.a1, rates.a2, rates.n1, rates.n2)
        self._every = REGULARIZE_EVERY
        self._reg = (regularization_weight(state.nu, cfg.forgetting_factor,
                                           cfg.regularization), float(cfg.theta0))
        J = state.n_joints
        self._pools = ([ThreadPoolExecutor(1, thread_name_prefix=f"impactcli-axis{j}")
                        for j in range(J)] if threads > 1 and J > 1 else None)

    def submit(self, r: np.ndarray, u: np.ndarray) -> AxisJob:
        """Start the chunk ``r`` (n, J) C-contiguous float64 residual, ``u`` (m, n, J)
        inputs (both left unmodified until the job is done)."""
        st = self.state
        n, J = r.shape
        rates = st.rates
        pos1, pos2 = self.n_samples % rates.n1, self.n_samples % rates.n2
        pos_reg = self.n_samples % (st.nu * self._every)
        u_lag = st.u_lags.copy()
        L = st.u_lags.shape[1]
        if L and n:  # the shared input lags: the last rho_max samples of [u_lags, u]
            st.u_lags[:] = (u[:, n - L:, :] if n >= L
                            else np.concatenate([st.u_lags[:, n:, :], u], axis=1))
        snap_off = (-self.n_samples) % SNAP_EVERY
        n_snap = max(0, -(-(n - snap_off) // SNAP_EVERY))
        self.n_samples += n
        rows = np.ascontiguousarray(r.T)
        eta = st.cfg.eta
        job = AxisJob(n, [np.empty((n, J), dtype=np.bool_ if i == DECISION else np.float64)
                          for i in range(N_OUTPUTS)],
                      np.empty_like(st.theta), np.empty(J, dtype=np.int64),
                      np.empty(J, dtype=np.int64), np.empty((n_snap, J, eta)))

        def axis(j: int) -> None:
            out = [np.empty(n, dtype=x.dtype) for x in job.out]
            snap = np.empty((n_snap, eta))
            rs, cp = _evaluate_axis(  # type: ignore[call-arg]
                rows[j], u, *self._args, float(self.v_stat[j]), *out,  # type: ignore[arg-type]
                st.theta[j], st.P[j], st.r_lags[j], st.v_lags[j], u_lag, st.filters[j],
                st.ring_r[j], st.ring_v[j], st.sums[j], pos1, pos2, *self._reg, pos_reg,
                self._every, snap, snap_off, SNAP_EVERY)
            job.theta_g[:, j, :] = snap
            for x, y in zip(job.out, out, strict=True):
                x[:, j] = y  # on this axis's thread, not the caller's after all axes
            st.n_resets[j] += rs
            st.n_capped[j] += cp
            job.theta[j] = st.theta[j]
            job.resets[j] = st.n_resets[j]
            job.capped[j] = st.n_capped[j]

        if self._pools is None:
            for j in range(J):
                axis(j)
        else:
            job.futures = [pool.submit(axis, j) for j, pool in enumerate(self._pools)]
        return job

    def snapshot(self) -> Callable[[], EvaluatorState]:
        """The state after every chunk submitted so far, without waiting for the axes: a
        copy of each axis's rows is queued on that axis's thread behind its chunks (on the
        calling thread when the axes run there), and the input lags are copied now (the
        runner advanced them at submission). Returns a function that waits for the copies
        and gives the state: the same bits as the state a replay stopped here would carry
        (:mod:`impactcli.detect.probe`)."""
        st = self.state
        snap = dataclasses.replace(st, u_lags=st.u_lags.copy(), n_samples=self.n_samples,
                                   **{k: np.empty_like(getattr(st, k)) for k in _PER_AXIS})

        def axis(j: int) -> None:
            for k in _PER_AXIS:
                getattr(snap, k)[j] = getattr(st, k)[j]

        if self._pools is None:
            for j in range(st.n_joints):
                axis(j)
            return lambda: snap
        futures = [pool.submit(axis, j) for j, pool in enumerate(self._pools)]

        def wait() -> EvaluatorState:
            for f in futures:
                f.result()
            return snap

        return wait

    def close(self) -> None:
        """End the threads (after the jobs submitted)."""
        if self._pools is not None:
            for pool in self._pools:
                pool.shutdown(wait=True, cancel_futures=True)
            self._pools = None

    def __enter__(self) -> AxisRunner:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
