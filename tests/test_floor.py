"""The detection floor's quantiles per link (impactcli.detect.floor): a link ending on its own
joint's axis takes its floor from the joints before it; a joint alarming for most of the
log (its median none) must not lower the link's worst tenth below its median."""

from __future__ import annotations

import numpy as np

from impactcli.detect.floor import FloorAccumulator


def _jac(q: np.ndarray, i: int) -> np.ndarray:
    """Constant link-end Jacobians: joints a and b turn every link; link 3 ends on joint c's
    axis (no lever)."""
    cols = {1: [[0.0], [0.4]], 2: [[0.0, 0.0], [0.8, 0.4]],
            3: [[0.0, 0.0, 0.0], [0.9, 0.5, 0.0]]}
    return np.array(cols[i])


def test_a_joint_alarming_most_of_the_log_does_not_lower_a_links_worst_tenth() -> None:
    """Known truth: joint a's margin is 1 N·m throughout; joint b alarms 60 % of the time
    (margin 0: its median is none, its worst tenth 0.1 N·m). Link 3 ends on joint c's axis,
    so the joints before it give its floor: over a alone its median is 1 / 0.9 N. With b
    counted at the worst tenth only, that quantile read 0.1 / 0.5 = 0.2 N, below the
    median (a new user's trial on the real UR arm: 3.0 N worst tenth against an 8.9 N
    median). Now b gives link 3 no floor at either quantile."""
    n = 2000
    vl = np.array([2.0, 2.0, 2.0])
    loading = np.empty((n, 3))
    loading[:, 0] = vl[0] - 1.0
    loading[:, 1] = np.where(np.arange(n) % 10 < 6, vl[1], vl[1] - 0.1)
    loading[:, 2] = vl[2] - 0.5
    acc = FloorAccumulator(3, n, 10, vl)
    acc.update(loading, np.zeros((n, 3)), np.ones((n, 3)), np.zeros((n, 3)))
    floor = acc.finish(np.zeros(3, dtype=int), 0, np.ones(3), ("a", "b", "c"),
                       ("a", "b", "c"), [1, 2, 3], [0, 1, 2], _jac)
    b = floor["per_joint"]["b"]["static_loading"]
    assert b["median_nm"] is None and b["in_alarm"] > 0.5
    assert b["worst_tenth_nm"] is not None and b["worst_tenth_nm"] < 0.11
    link3 = floor["per_link"][2]["static_loading"]
    assert link3["median_n"] is not None and link3["worst_tenth_n"] is not None
    assert link3["worst_tenth_n"] >= link3["median_n"]
    assert abs(link3["median_n"] - 1.0 / 0.9) < 0.06 * (1.0 / 0.9)  # bins 5 % below
