"""impactcli.columns against NumPy's own axis-0 reductions: bit-identical results on
every layout, NaN and infinity, for few and many columns."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.columns import column_all, column_any, column_range


@pytest.mark.parametrize("n_cols", [1, 2, 7, 40])
@pytest.mark.parametrize("order", ["C", "F", "view"])
def test_same_as_axis_0_reductions(n_cols: int, order: str) -> None:
    rng = np.random.default_rng(n_cols)
    a = rng.normal(0.0, 1e3, (257, n_cols))
    a[rng.random(a.shape) < 0.05] = np.nan
    a[3, 0] = np.inf
    a[:, -1] = np.nan                              # a column never logged
    a = np.asfortranarray(a) if order == "F" else a[::2] if order == "view" else a
    with np.errstate(invalid="ignore"):
        lo, hi = column_range(a, skip_nan=True)
        np.testing.assert_array_equal(lo, np.fmin.reduce(a, axis=0))
        np.testing.assert_array_equal(hi, np.fmax.reduce(a, axis=0))
        lo, hi = column_range(a)
        np.testing.assert_array_equal(lo, a.min(axis=0))   # NaN propagates, as min does
        np.testing.assert_array_equal(hi, a.max(axis=0))
    fin = np.isfinite(a)
    np.testing.assert_array_equal(column_any(fin), fin.any(axis=0))
    np.testing.assert_array_equal(column_all(fin), fin.all(axis=0))
    assert column_any(fin)[-1] == False and np.isnan(column_range(a, skip_nan=True)[0][-1])  # noqa: E712


def test_no_rows_is_an_error_as_in_numpy() -> None:
    with pytest.raises(ValueError):
        column_range(np.zeros((0, 3)))
