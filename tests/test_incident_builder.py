"""A contact beside a payload change placed by itself (impactcli.detect.incident_builder.
beside), against a force whose torques are made through the Jacobian: the link and the
force come back; a part whose posture cannot be known gives nothing."""

from __future__ import annotations

import numpy as np
import pytest

from impactcli.detect.incident_builder import IncidentContext, beside
from impactcli.detect.incidents import Incident, planar_jacobian
from impactcli.detect.payload_change import ContactPart

LENGTHS = (0.4, 0.35)


def _ctx(chain_cols: list[int | None]) -> IncidentContext:
    return IncidentContext(("a", "b"), [1, 2], chain_cols, planar_jacobian(LENGTHS),
                           np.array([0.5, 0.3]), 0.004, 0, 10_000, 0.1,
                           link_lengths=LENGTHS, chain=("a", "b"))


def _incident() -> Incident:
    return Incident(10.0, 10.6, 2500, 2650, ("static_loading",), ("a", "b"), 1, 55.0,
                    "whole alarm", "quasi_static", {"a": 9.0, "b": 4.0}, False)


def _part(force: float, began_before: bool = False) -> ContactPart:
    """A 0.3 s half-sine push of ``force`` N at the end of link 2, normal to it, while the
    arm moves slowly; the torques r = Jᵀ F, their loading ratio as the monitor gives it."""
    n = 75
    t = np.arange(n) * 0.004
    q = np.column_stack([0.3 + 0.1 * t, 0.8 - 0.05 * t])
    jac = planar_jacobian(LENGTHS)
    shape = np.sin(np.pi * t / t[-1])
    r = np.zeros((n, 2))
    for k in range(n):
        j = jac(q[k], 2)
        assert j is not None
        phi = q[k].sum()
        f = force * shape[k] * np.array([-np.sin(phi), np.cos(phi)])  # normal to link 2
        r[k] = j.T @ f
    ratio = np.abs(r) / np.array([0.5, 0.3])
    qd = np.tile([0.1, -0.05], (n, 1))
    return ContactPart(("a", "b"), r, ratio, q, qd, 0.004, began_before)


def test_the_contact_apart_from_the_load_gives_its_own_link_and_force() -> None:
    got = beside(_ctx([0, 1]), _incident(), _part(30.0))
    assert got is not None
    assert got.link == 2 and got.contact == "transient"
    assert got.force_n == pytest.approx(30.0, rel=1e-6)
    assert got.force_method.endswith("(the torque the load leaves)")
    assert got.t_start == 10.0 and got.number is None  # only the figures change
    assert got.peak_residual["b"] == pytest.approx(float(np.max(np.abs(_part(30.0).r[:, 1]))))


def test_a_part_that_holds_only_the_contacts_end_gives_no_force() -> None:
    got = beside(_ctx([0, 1]), _incident(), _part(30.0, began_before=True))
    assert got is not None and got.link == 2 and got.force_n is None
    assert "at least ~30 N at the end of link 2" in got.force_method
    assert got.force_plausible is None


def test_a_chain_joint_logged_but_not_replayed_leaves_the_whole_alarms_figures() -> None:
    ctx = _ctx([0, 1])
    ctx3 = IncidentContext(ctx.joints, ctx.index, [0, 1, 2], ctx.jac, ctx.vl, ctx.dt,
                           ctx.t0_ns, ctx.n_samples, ctx.merge_gap_s,
                           link_lengths=(*LENGTHS, 0.1), chain=("a", "b", "c"))
    assert beside(ctx3, _incident(), _part(30.0)) is None
    other = ContactPart(("a", "x"), *[getattr(_part(30.0), k) for k in
                                      ("r", "ratio", "q", "qd", "dt")])
    assert beside(ctx, _incident(), other) is None
