"""Per-column reductions of (n, J) sample chunks: each joint's range, whether any or all
of its samples pass a test.

NumPy reduces a C-ordered (n, J) array along axis 0 with an inner loop of J elements,
which is slow when J is a robot's few joints (2–7: 5–25× slower than reducing each column
as one contiguous run). These copy the chunk to (J, n) once and reduce along rows. Min,
max, any and all are exact, so the results equal ``a.min(axis=0)`` and the like bit for
bit; like those, a range of zero rows is an error.
"""

from __future__ import annotations

import numpy as np


def by_column(a: np.ndarray) -> np.ndarray:
    """The (n, J) chunk as a C-contiguous (J, n) array (each column one run)."""
    return np.ascontiguousarray(np.asarray(a).T)


def column_range(a: np.ndarray, *, skip_nan: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(J,) lowest and highest value of each column of (n, J), n ≥ 1. ``skip_nan``: NaN is
    ignored (a column of NaN only gives NaN), as ``np.fmin.reduce``."""
    c = by_column(a)
    if skip_nan:
        return np.fmin.reduce(c, axis=1), np.fmax.reduce(c, axis=1)
    return c.min(axis=1), c.max(axis=1)


def column_any(mask: np.ndarray) -> np.ndarray:
    """(J,) whether any row of each column of the (n, J) boolean ``mask`` is true."""
    return np.asarray(by_column(mask).any(axis=1))


def column_all(mask: np.ndarray) -> np.ndarray:
    """(J,) whether every row of each column of the (n, J) boolean ``mask`` is true."""
    return np.asarray(by_column(mask).all(axis=1))
