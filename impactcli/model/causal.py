"""Causal filters whose state is carried from one chunk of a log to the next.

Every causal stage of the replay — the derivative filter G of the residual, the torque's
filter, the momentum observer, the threshold inputs' differences and filters, the
static-loading low-pass — is a composition of linear recursive filters (``scipy.signal.
lfilter``, direct form II transposed), backward differences and per-sample arithmetic.
A :class:`Carry` holds, under a name per filter or difference, exactly what such a stage
carries from sample k0 − 1 to k0: the filter's delay line ``zf`` (as ``lfilter`` returns
it) or the previous sample. The stage functions take an optional ``carry``; the whole-log
call is the same code with a fresh carry (docs/architecture.md, "Streaming"). Start
conditions: ``steady`` (steady state on the first sample, ``lfilter_zi`` × x(0)), ``rest``
(zero state); a backward difference is 0 at the log's first sample.

For any split of a log into consecutive chunks, the outputs concatenated are bit for bit
those of one call on the whole log: ``lfilter`` performs the same operations per sample
whatever the chunk, and a difference subtracts the same two stored float64 values. A
stage mutates the carry it is given; :meth:`Carry.copy` gives an independent one.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from . import iir

Start = Literal["steady", "rest"]


class Carry:
    """Named state of causal filters and differences (module docstring).

    Attributes:
        state: name → array (an ``lfilter`` delay line ``(order, ...)`` or a previous
            sample ``(...)``); absent before the first sample.
    """

    def __init__(self, state: dict[str, np.ndarray] | None = None) -> None:
        self.state: dict[str, np.ndarray] = dict(state or {})

    def copy(self) -> Carry:
        """An independent copy (arrays copied)."""
        return Carry({k: v.copy() for k, v in self.state.items()})

    def scoped(self, prefix: str) -> Carry:
        """A view of this carry whose names are prefixed with ``prefix`` (the same stage
        run twice, e.g. two residual generators, keeps two states in one carry)."""
        return _Scoped(self, prefix)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Carry) or self.state.keys() != other.state.keys():
            return False
        return all(np.array_equal(v, other.state[k]) for k, v in self.state.items())

    __hash__ = None  # type: ignore[assignment]

    def lfilter(self, name: str, b: np.ndarray, a: np.ndarray, x: np.ndarray,
                start: Start = "steady") -> np.ndarray:
        """``lfilter(b, a, x, axis=0)`` continued from the state under ``name``.

        Args:
            name: the filter's name in this carry (unique per filter and signal).
            b, a: the filter's coefficients.
            x: (n, ...) the chunk (n ≥ 0).
            start: how the filter starts at the log's first sample (module docstring).
        Returns:
            (n, ...) the filtered chunk.
        """
        x = np.asarray(x, dtype=np.float64)
        if x.shape[0] == 0:
            return x.copy()
        zi = self.state.get(name)
        if zi is None:
            order = max(len(a), len(b)) - 1
            shape = (order, *x.shape[1:])
            if start == "steady":
                z0 = iir.lfilter_zi(b, a)
                zi = z0.reshape((order,) + (1,) * (x.ndim - 1)) * x[:1]
            else:
                zi = np.zeros(shape)
        y, zf = iir.lfilter(b, a, x, zi)
        self.state[name] = np.asarray(zf)
        return np.asarray(y)

    def previous(self, name: str, x: np.ndarray) -> np.ndarray | None:
        """The sample before each of the chunk's: (n, ...) ``x`` shifted by one, the first
        row the previous chunk's last sample — or None at the log's first sample (then
        the row is ``x[0]`` and the caller treats k = 0 itself). Stores the chunk's last."""
        x = np.asarray(x, dtype=np.float64)
        if x.shape[0] == 0:
            return x.copy() if name in self.state else None
        last = self.state.get(name)
        prev = np.empty_like(x)
        prev[1:] = x[:-1]
        prev[0] = x[0] if last is None else last
        self.state[name] = x[-1].copy()
        return None if last is None else prev

    def backward_difference(self, name: str, x: np.ndarray, dt: np.ndarray | float
                            ) -> np.ndarray:
        """(x(k) − x(k−1)) / dt(k) with the previous chunk's last sample; 0 at the log's
        first sample. ``dt``: scalar or (n,) step to each sample [s]."""
        x = np.asarray(x, dtype=np.float64)
        first = name not in self.state
        prev = self.previous(name, x)
        d = np.zeros_like(x)
        if x.shape[0] == 0:
            return d
        dt_a = np.asarray(dt, dtype=np.float64)
        if dt_a.ndim:
            dt_a = dt_a.reshape((-1,) + (1,) * (x.ndim - 1))
        if first:
            d[1:] = (x[1:] - x[:-1]) / (dt_a[1:] if dt_a.ndim else dt_a)
        else:
            assert prev is not None
            d[:] = (x - prev) / dt_a
        return d

    def steps_s(self, name: str, t_s: np.ndarray) -> np.ndarray:
        """(n,) t(k) − t(k−1) [s] with the previous chunk's last time (NaN at the log's
        first sample, where no step exists). ``t_s``: seconds since the log's first sample."""
        t = np.asarray(t_s, dtype=np.float64)
        prev = self.previous(name, t)
        out = np.full_like(t, np.nan)
        if t.shape[0] == 0:
            return out
        if prev is None:
            out[1:] = np.diff(t)
        else:
            out[:] = t - prev
        return out


class _Scoped(Carry):
    """:meth:`Carry.scoped`: names prefixed, state shared with the parent carry."""

    def __init__(self, parent: Carry, prefix: str) -> None:
        super().__init__()
        self._parent, self._prefix = parent, prefix
        self.state = _PrefixedDict(parent.state, prefix)  # type: ignore[assignment]


class _PrefixedDict(dict):  # type: ignore[type-arg]
    """The parent's dict seen through a name prefix (get / set / contains)."""

    def __init__(self, base: dict[str, np.ndarray], prefix: str) -> None:
        super().__init__()
        self._base, self._prefix = base, prefix

    def get(self, key: str, default: object = None) -> object:  # type: ignore[override]
        return self._base.get(self._prefix + key, default)

    def __getitem__(self, key: str) -> np.ndarray:
        return self._base[self._prefix + key]

    def __setitem__(self, key: str, value: np.ndarray) -> None:
        self._base[self._prefix + key] = value

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and (self._prefix + key) in self._base
