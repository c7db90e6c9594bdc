"""The identification's filtered regressor rows, from a log read whole or in chunks.

Identification (:mod:`impactcli.model.identification`, docs/method.md §2) smooths positions and
torques without phase lag, differentiates, decimates, and lays out regressor rows at a few
hundred thousand samples at most. All of it is local in time — a zero-phase filter's
output at a sample depends on the samples around it, with a weight that decays as the
filter's slowest pole — so it is computed in fixed windows, each with a margin of samples
on both sides that is filtered and then cut (:class:`Windows`):

1. at the log's rate, windows of :data:`WINDOW` samples with a margin long enough for the
   slowest pole to decay below 1e-20 (:func:`decay_margin`): the filtered positions,
   their central differences and the filtered torques, kept at every ``k1``-th sample;
2. at the decimated rate, windows of :data:`ROW_WINDOW` rows with a margin of
   4 / cut-off: the regressor's columns through the same zero-phase filter, kept at the
   fitted and held-back rows.

The windows are fixed by the sample count, not by how the log arrives, so
:class:`RowsBuilder` fed one whole log or the same log in chunks of any size gives the
same rows bit for bit (one implementation: :func:`impactcli.model.identification.identify` feeds
it the whole log, the streamed detection its chunks) — and holds at most two windows and
the rows it keeps, whatever the log's length (docs/method.md §2, "Identification in
windows").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import structures
from .derivatives import zero_phase_lowpass

#: Samples per window of the filtering at the log's rate.
WINDOW = 65_536
#: Rows per window of the regressor's filtering at the decimated rate.
ROW_WINDOW = 20_000
#: The filter's start-up transient left at the edge of a window's margin, relative.
DECAY = 1e-20
#: Rows the coupled model is fitted on at least, whatever ``coupled_max_mb`` says
#: (:func:`impactcli.model.selection.coupled_too_big` leaves the candidate out where even
#: these exceed it).
COUPLED_MIN_ROWS = 1000


def decay_margin(sample_rate_hz: float, cutoff: float, order: int) -> int:
    """Samples after which the zero-phase Butterworth's slowest pole has decayed below
    :data:`DECAY` (a window's margin on each side)."""
    from scipy import signal  # identification only (1.5 s to import)

    _, p, _ = signal.butter(order, cutoff, fs=sample_rate_hz, output="zpk")
    rho = float(np.max(np.abs(p)))
    return max(8, int(np.ceil(np.log(DECAY) / np.log(rho)))) if rho > 0 else 8


class Windows:
    """Rows ``0..n-1`` of a sequence that arrives in pieces, processed in fixed windows.

    Window ``[s, e)`` (``s`` a multiple of ``window``) is handed to ``fn(a, s, e, *cols)``
    with the columns' rows ``[a, b)``, ``a = max(0, s - margin)``, ``b = min(n, e +
    margin)``, as soon as row ``b - 1`` has arrived; only the rows a later window needs are
    buffered. State in, state out: :meth:`feed` takes the next rows, :meth:`finish` checks
    that all ``n`` came.
    """

    def __init__(self, n: int, window: int, margin: int,
                 fn: Callable[..., None]) -> None:
        self.n, self.window, self.margin, self.fn = n, window, margin, fn
        self.start = 0                      # the buffer's first row in the sequence
        self.arrived = 0                    # rows arrived so far
        self.next = 0                       # the next window's first row
        self.buf: list[np.ndarray] | None = None

    def feed(self, *cols: np.ndarray) -> None:
        """Take the next rows (each column (m, ...)); process every window now complete."""
        m = cols[0].shape[0]
        if m == 0:
            return
        self.buf = list(cols) if self.buf is None else [
            np.concatenate([b, c]) for b, c in zip(self.buf, cols, strict=True)]
        self.arrived += m
        if self.arrived > self.n:
            raise ValueError(f"{self.arrived} rows arrived, {self.n} expected")
        while self.next < self.n:
            e = min(self.n, self.next + self.window)
            b = min(self.n, e + self.margin)
            if self.arrived < b:
                break
            a = max(0, self.next - self.margin)
            assert self.buf is not None
            self.fn(a, self.next, e, *(c[a - self.start:b - self.start] for c in self.buf))
            self.next = e
            drop = max(0, e - self.margin) - self.start
            self.buf = [c[drop:] for c in self.buf]
            self.start += drop

    def finish(self) -> None:
        """Check that every row came and every window was processed."""
        if self.arrived != self.n or self.next < self.n:
            raise ValueError(f"{self.arrived} rows arrived, {self.n} expected")


@dataclass(frozen=True)
class RowsPlan:
    """Where the rows come from, fixed by the sample count before the first sample:
    decimation ``k1`` of the filtered signals (>= 10 samples per cut-off period), the
    fitted and held-back rows (indices in the decimated sequence; every ``k2``-th), the
    held-back part's first row ``split``."""

    n: int
    sample_rate_hz: float
    cutoff: float
    k1: int
    nd: int
    edge: int
    split: int
    use_holdout: bool
    k2: int
    fit_idx: np.ndarray
    hold_idx: np.ndarray

    @classmethod
    def make(cls, n: int, sample_rate_hz: float, cutoff: float, options: Any, kind: str,
             n_joints: int, n_params: int) -> RowsPlan:
        """The plan of :func:`impactcli.model.identification.identify` (its module doc)."""
        k1 = max(1, int(sample_rate_hz // (10.0 * cutoff)))
        nd = len(range(0, n, k1))
        fs_d = sample_rate_hz / k1
        edge = int(np.ceil(fs_d / cutoff))
        n_hold = round(options.holdout_fraction * nd)
        use_holdout = (n_hold > 0 and n_hold / fs_d >= options.min_holdout_s
                       and nd - n_hold > 4 * edge + 20)
        split = nd - n_hold if use_holdout else nd
        fit_idx = np.arange(edge, split - edge)
        hold_idx = np.arange(split + edge, nd - edge) if use_holdout else np.arange(0)
        # a long log: fit on every k2-th filtered sample (the rows are strongly correlated)
        max_rows = options.max_fit_samples
        if kind == "coupled":  # its regressor has J × J(5J+1) numbers per sample
            cap = int(options.coupled_max_mb * 2**20 / (8 * n_joints * n_params))
            max_rows = min(max_rows, max(COUPLED_MIN_ROWS, cap))
        k2 = max(1, int(np.ceil((fit_idx.size + hold_idx.size) / max_rows)))
        return cls(n, sample_rate_hz, cutoff, k1, nd, edge, split, use_holdout, k2, fit_idx[::k2],
                   hold_idx[::k2])


@dataclass(frozen=True)
class Rows:
    """Filtered regressor rows of one log, ready to stack and fit."""

    kind: str
    joints: tuple[str, ...]
    structure: dict[str, Any]
    still: Any
    y_fit: np.ndarray
    tau_fit: np.ndarray
    y_hold: tuple[np.ndarray, np.ndarray] | None
    filter_info: dict[str, Any]
    hold_still_fraction: np.ndarray | None = None
    poses: np.ndarray | None = None
    acc_rms: np.ndarray | None = None
    cv_gap: int = 1


class RowsBuilder:
    """The filtered rows of one log, fed its samples in order, whole or in chunks
    (module docstring).

    Args:
        plan: the :class:`RowsPlan`; kind, joints, structure: the model's layout.
        order: the Butterworth order; filter_regressor: filter the regressor's columns too.
    """

    def __init__(self, plan: RowsPlan, kind: str, joints: tuple[str, ...],
                 structure: dict[str, Any], order: int, filter_regressor: bool) -> None:
        self.plan, self.kind, self.joints, self.structure = plan, kind, joints, structure
        self.order, self.filter_regressor = order, filter_regressor
        self.lo: np.ndarray | None = None           # the raw positions' minima and maxima
        self.hi: np.ndarray | None = None
        self.split_t: float | None = None
        self.sel = (plan.fit_idx, plan.hold_idx)
        self.out: list[dict[str, list[np.ndarray]]] = [
            {k: [] for k in ("y", "tau", "q", "qd", "qdd")} for _ in self.sel]
        self.stage1 = Windows(plan.n, WINDOW, decay_margin(plan.sample_rate_hz, plan.cutoff, order),
                              self._filter)
        margin2 = 4 * plan.edge if filter_regressor else 0
        self.stage2 = Windows(plan.nd, ROW_WINDOW, margin2, self._rows)

    def feed(self, t: np.ndarray, q: np.ndarray, tau: np.ndarray) -> None:
        """The next samples: (m,) times [s], (m, J) raw positions [rad] and torques [N·m]."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape[0] == 0:
            return
        lo, hi = q.min(axis=0), q.max(axis=0)
        self.lo = lo if self.lo is None else np.minimum(self.lo, lo)
        self.hi = hi if self.hi is None else np.maximum(self.hi, hi)
        self.stage1.feed(np.asarray(t, dtype=np.float64), q,
                         np.asarray(tau, dtype=np.float64))

    def ranges(self) -> np.ndarray:
        """(J,) the raw positions' ranges (NaN when a position is)."""
        assert self.lo is not None and self.hi is not None
        return np.asarray(self.hi - self.lo)

    def _filter(self, a: int, s: int, e: int, t: np.ndarray, q: np.ndarray,
                tau: np.ndarray) -> None:
        p = self.plan
        qf = zero_phase_lowpass(q, p.sample_rate_hz, p.cutoff, self.order)
        qd = np.gradient(qf, t, axis=0)
        qdd = np.gradient(qd, t, axis=0)
        tau_f = zero_phase_lowpass(tau, p.sample_rate_hz, p.cutoff, self.order)
        idx = np.arange(s + (-s) % p.k1, e, p.k1) - a
        self.stage2.feed(t[idx], qf[idx], qd[idx], qdd[idx], tau_f[idx])

    def _rows(self, a: int, s: int, e: int, t: np.ndarray, qf: np.ndarray, qd: np.ndarray,
              qdd: np.ndarray, tau_f: np.ndarray) -> None:
        p = self.plan
        if s <= p.split < e:
            self.split_t = float(t[p.split - a])
        wanted = [sel[(sel >= s) & (sel < e)] - a for sel in self.sel]
        if not any(w.size for w in wanted):
            return
        fs_d = p.sample_rate_hz / p.k1
        if self.kind == "coupled":  # filter the shared functions of the motion, then lay out
            f = structures.coupled_features(qf, qd, qdd, self.structure)
            if self.filter_regressor:
                f = zero_phase_lowpass(f, fs_d, p.cutoff, self.order)
            ys = [structures.coupled_assemble(f[w], len(self.joints), self.structure)
                  for w in wanted]
        else:
            y = structures.regressor(self.kind, self.joints, self.structure, qf, qd, qdd)
            if self.filter_regressor:
                shape = y.shape
                y = zero_phase_lowpass(y.reshape(shape[0], -1), fs_d, p.cutoff,
                                       self.order).reshape(shape)
            ys = [y[w] for w in wanted]
        for out, w, yk in zip(self.out, wanted, ys, strict=True):
            for key, v in (("y", yk), ("tau", tau_f[w]), ("q", qf[w]), ("qd", qd[w]),
                           ("qdd", qdd[w])):
                out[key].append(v)

    def finish(self, still: Any, filter_info: dict[str, Any], options: Any,
               still_fraction: Callable[..., np.ndarray],
               poses: Callable[[np.ndarray], np.ndarray]) -> Rows:
        """The rows, once every sample came (``still``: the joints that stay constant)."""
        self.stage1.finish()
        self.stage2.finish()
        p, nj = self.plan, len(self.joints)
        n_par = len(structures.param_names(self.kind, self.joints, self.structure))
        shapes = {"y": (0, nj, n_par), "tau": (0, nj), "q": (0, nj), "qd": (0, nj),
                  "qdd": (0, nj)}
        fit, hold = ({k: np.concatenate(v) if v else np.zeros(shapes[k])
                      for k, v in o.items()} for o in self.out)
        self.out = []   # the pieces, now copied: not twice in memory during the fit
        info = dict(filter_info, holdout={
            "fraction": options.holdout_fraction if p.use_holdout else 0.0,
            "start_s": self.split_t if p.use_holdout else None})
        return Rows(
            self.kind, self.joints, self.structure, still, fit["y"], fit["tau"],
            (hold["y"], hold["tau"]) if p.use_holdout else None, info,
            hold_still_fraction=(still_fraction(hold["q"], hold["qd"], options)
                                 if p.use_holdout and p.hold_idx.size else None),
            poses=poses(fit["q"]), acc_rms=np.sqrt(np.mean(fit["qdd"] ** 2, axis=0)),
            cv_gap=int(np.ceil(p.edge / p.k2)))
