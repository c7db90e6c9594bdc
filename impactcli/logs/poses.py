"""A bounded sample of a log's poses, taken in the scan's one pass: positions, torques
and each joint's speed at evenly strided samples (at most :data:`MAX_POSES`, whatever the
log's length). What needs the whole log's poses but not every sample — the torque scale
against a description's gravity (:mod:`impactcli.model.gravity`), the torque a joint must
hold — reads it instead of the log."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: At most this many poses are kept (every ``stride``-th sample; the stride doubles).
MAX_POSES = 4096


@dataclass
class PoseSample:
    """Feed :meth:`add` each block of samples in order; ``q``, ``tau`` and ``qd`` (signed
    speed from the position's step before each sample [rad/s]) hold every ``stride``-th."""

    n_joints: int
    stride: int = 1
    n: int = 0
    idx: np.ndarray = field(init=False)
    q: np.ndarray = field(init=False)
    tau: np.ndarray = field(init=False)
    qd: np.ndarray = field(init=False)
    _last: tuple[int, np.ndarray] | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        j = self.n_joints
        self.idx = np.zeros(0, dtype=np.int64)
        self.q = self.tau = self.qd = np.zeros((0, j))

    def add(self, t_ns: np.ndarray, q: np.ndarray, tau: np.ndarray) -> None:
        """The next (n,) times [ns], (n, J) positions [rad] and torques [N·m]."""
        n = len(t_ns)
        if not n:
            return
        if self._last is None:
            tq, qq = np.concatenate((t_ns[:1], t_ns)), np.concatenate((q[:1], q))
        else:
            tq = np.concatenate(([self._last[0]], t_ns))
            qq = np.concatenate((self._last[1][None, :], q))
        self._last = (int(t_ns[-1]), q[-1].copy())
        dt = np.diff(tq).astype(np.float64) * 1e-9
        with np.errstate(invalid="ignore", divide="ignore"):
            qd = np.diff(qq, axis=0) / np.where(dt > 0, dt, np.nan)[:, None]
        rows = np.arange(self.n, self.n + n)
        pick = rows % self.stride == 0
        self.idx = np.concatenate((self.idx, rows[pick]))
        self.q = np.concatenate((self.q, q[pick]))
        self.tau = np.concatenate((self.tau, tau[pick]))
        self.qd = np.concatenate((self.qd, qd[pick]))
        self.n += n
        while len(self.idx) > MAX_POSES:
            self.stride *= 2
            keep = self.idx % self.stride == 0
            self.idx, self.q = self.idx[keep], self.q[keep]
            self.tau, self.qd = self.tau[keep], self.qd[keep]

    def select(self, columns: list[int]) -> PoseSample:
        """The sample of the joints ``columns`` only."""
        out = PoseSample(len(columns), self.stride, self.n)
        out.idx = self.idx
        out.q, out.tau, out.qd = self.q[:, columns], self.tau[:, columns], self.qd[:, columns]
        return out
