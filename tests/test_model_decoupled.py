"""The decoupled model's torque without its block-diagonal regressor
(impactcli.model.structures.decoupled_predict): the same bits as the row sums of the
full regressor (rowdot), which the chunked replay's guarantee rests on."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.model import structures as st


@pytest.mark.parametrize("offset", [True, False])
@pytest.mark.parametrize("nj", [1, 2, 7])
def test_decoupled_predict_is_rowdot_of_the_regressor(nj: int, offset: bool) -> None:
    rng = np.random.default_rng(nj + 10 * offset)
    structure = {"coulomb_slope_rad_s": 0.01, "offset": offset}
    joints = tuple(f"j{k}" for k in range(nj))
    n = 5000
    q = rng.uniform(-np.pi, np.pi, (n, nj))
    qd = rng.normal(0, 1, (n, nj)) * (rng.uniform(size=(n, nj)) > 0.1)  # some still
    qdd = rng.normal(0, 3, (n, nj))
    p = len(st.decoupled_names(joints, structure)) // nj
    for theta in (rng.normal(size=nj * p),
                  np.where(rng.uniform(size=nj * p) > 0.5, 0.0, rng.normal(size=nj * p)),
                  -np.abs(rng.normal(size=nj * p)) * (np.arange(nj * p) % p == 0),
                  np.zeros(nj * p), -np.zeros(nj * p)):
        y = st.decoupled_regressor(q, qd, qdd, structure)
        want = st.rowdot(y.reshape(n * nj, -1), theta).reshape(n, nj)
        got = st.predict("decoupled", joints, structure, q, qd, qdd, theta)
        assert np.array_equal(got, want)
        assert np.array_equal(np.signbit(got), np.signbit(want))  # signed zeros too
