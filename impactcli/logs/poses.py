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
        first = (-self.n) % self.stride  # the block's first row on the stride
        pick = np.arange(first, n, self.stride)
        prev_q = np.empty((len(pick), q.shape[1]))
        prev_t = np.empty(len(pick), dtype=np.int64)
        inner = pick > 0
        prev_q[inner], prev_t[inner] = q[pick[inner] - 1], t_ns[pick[inner] - 1]
        if len(pick) and pick[0] == 0:  # the block's first row: the step from the last one
            last_t, last_q = self._last if self._last is not None else (int(t_ns[0]), q[0])
            prev_q[0], prev_t[0] = last_q, last_t  # (the log's first row: no speed, NaN)
        self._last = (int(t_ns[-1]), q[-1].copy())
        dt = (t_ns[pick] - prev_t).astype(np.float64) * 1e-9
        with np.errstate(invalid="ignore", divide="ignore"):
            qd = (q[pick] - prev_q) / np.where(dt > 0, dt, np.nan)[:, None]
        self.idx = np.concatenate((self.idx, self.n + pick))
        self.q = np.concatenate((self.q, q[pick]))
        self.tau = np.concatenate((self.tau, tau[pick]))
        self.qd = np.concatenate((self.qd, qd))
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


#: A torque channel varies with the arm's poses when pose features explain at least this
#: share of its variance over the sampled poses (:func:`pose_explained`) ...
EXPLAINED_R2 = 0.5
#: ... judged over at least this many poses.
MIN_EXPLAINED_POSES = 50


def pose_features(q: np.ndarray) -> np.ndarray:
    """(n, 1 + 4J) features a gravity torque is a combination of: 1, sin and cos of each
    joint's angle and of each cumulative sum of them (a chain of parallel axes)."""
    c = np.cumsum(q, axis=1)
    return np.column_stack((np.ones(len(q)), np.sin(q), np.cos(q), np.sin(c), np.cos(c)))


def pose_explained(poses: PoseSample) -> np.ndarray:
    """(J,) whether each joint's torque varies with the arm's poses (module docstring): the
    least squares of it on :func:`pose_features` of every joint's angle explains at least
    :data:`EXPLAINED_R2` of its variance. A still joint still carries gravity torque that
    moves with the others' poses, so its channel is measured however few values it shows;
    a channel stuck near zero with a few values of noise is not."""
    out = np.zeros(poses.n_joints, dtype=bool)
    ok = np.all(np.isfinite(poses.q), axis=1)
    if int(ok.sum()) < MIN_EXPLAINED_POSES:
        return out
    a = pose_features(poses.q[ok])
    if int(ok.sum()) < 5 * a.shape[1]:  # too few poses: noise would fit
        return out
    for j in range(poses.n_joints):
        y = poses.tau[ok, j]
        fin = np.isfinite(y)
        if int(fin.sum()) < MIN_EXPLAINED_POSES:
            continue
        y, aj = y[fin], a[fin]
        var = float(np.sum((y - y.mean()) ** 2))
        if var <= 0.0:
            continue
        coef, *_ = np.linalg.lstsq(aj, y, rcond=None)
        out[j] = 1.0 - float(np.sum((y - aj @ coef) ** 2)) / var >= EXPLAINED_R2
    return out
