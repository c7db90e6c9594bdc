"""Weighing a load on a stretch (impactcli/model/payload.py: ``weigh``, ``weigh_trimmed``,
``step_onset``) and dating a change inside a lasting alarm (the monitor's
``_later_onset``), against known truth on a planar arm."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from impactcli.detect.payload_change import PayloadMonitor
from impactcli.model import payload, structures
from impactcli.model.causal import Carry
from impactcli.model.derivatives import causal_derivatives
from impactcli.model.rigid import RigidModel

JOINTS = ("a", "b")
STRUCTURE = {"coulomb_slope_rad_s": 0.01, "offset": True, "motor_inertia": True,
             "link_lengths": [0.4, 0.35], "gravity": [0.0, -9.81]}
FS = 250.0


def _rows(seconds: float, swing: float = 0.8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, the payload's rows Y B through the replay's causal derivatives)."""
    t = np.arange(int(seconds * FS)) / FS
    q = np.column_stack([swing * np.sin(1.3 * t), 1.1 * np.sin(0.9 * t + 1)])
    qf, qd, qdd = causal_derivatives(1.0 / FS, q, 15.0, Carry(), "q")
    b, _ = payload.basis("planar", JOINTS, STRUCTURE)
    return t, q, structures.regressor("planar", JOINTS, STRUCTURE, qf, qd, qdd) @ b


def _point(m: float, c: tuple[float, float]) -> np.ndarray:
    return np.array([m, m * c[0], m * c[1], m * (c[0] ** 2 + c[1] ** 2)])


NAMES = payload.basis("planar", JOINTS, STRUCTURE)[1]


def _scaled_cost(y: np.ndarray, r: np.ndarray, moments: np.ndarray) -> float:
    m = moments[0]
    pi = _point(m, (moments[1] / m, moments[2] / m))
    scale = np.sqrt(np.mean(r**2, axis=0))
    return float(np.sum(((r - y @ pi) / scale) ** 2))


def test_weigh_is_the_point_mass_least_squares() -> None:
    """Known truth: on a point mass's torque the weighing returns it (to 1e-6); with a
    misfit no point mass holds (a constant torque on one joint), what it returns is the
    least squares of the point-mass model — no small step of the moments lowers the cost —
    where solving the moments and their inertia in turn stopped elsewhere."""
    _, _, y = _rows(3.0)
    truth = _point(1.2, (0.35, 0.02))
    w = payload.weigh(y, y @ truth, NAMES)
    np.testing.assert_allclose(w.pi, truth, rtol=1e-6, atol=1e-9)
    r = y @ truth + np.array([0.6, 0.0])[None, :] \
        + np.random.default_rng(3).normal(0, 0.02, (y.shape[0], 2))
    w = payload.weigh(y, r, NAMES)
    at = w.pi[:3]
    best = _scaled_cost(y, r, at)
    for k in range(3):
        for sign in (-1.0, 1.0):
            step = np.zeros(3)
            step[k] = sign * 1e-3 * max(abs(at[k]), 0.1)
            assert _scaled_cost(y, r, at + step) >= best - 1e-9 * best


def test_a_start_transient_is_left_out_of_the_weighing() -> None:
    """Known truth: a 1.2 kg point mass, the first 0.2 s of the stretch ringing at 8 Hz up
    to 40 N·m (an arm settling under its load, a filter starting). Weighed on every row
    the centre of mass moves; the trimmed weighing leaves the ringing rows out and finds
    the load within 2 %, keeping every row after them."""
    t, _, y = _rows(3.0)
    truth = _point(1.2, (0.35, 0.02))
    rng = np.random.default_rng(1)
    r = y @ truth + rng.normal(0, 0.05, (t.size, 2))
    ring = t < 0.2
    r[ring] += 40.0 * np.exp(-t[ring] / 0.1)[:, None] * np.column_stack(
        [np.sin(2 * np.pi * 8 * t[ring]), -0.5 * np.sin(2 * np.pi * 8 * t[ring])])
    com = truth[1:3] / truth[0]
    plain = payload.weigh(y, r, NAMES)
    w, keep = payload.weigh_trimmed(y, r, NAMES)
    err_plain = np.linalg.norm(plain.pi[1:3] / plain.pi[0] - com)
    err_trim = np.linalg.norm(w.pi[1:3] / w.pi[0] - com)
    assert err_plain > 3 * err_trim
    assert abs(w.mass_kg - 1.2) < 0.02 * 1.2 and err_trim < 0.01
    assert keep[t >= 0.25].all() and not keep[ring].all()


def test_a_step_in_the_stretch_is_not_trimmed_away() -> None:
    """A load picked 1.2 s into a 3 s stretch is no start transient: the rows the load
    leaves out reach past the stretch's first quarter, or what is kept drifts, so every
    row is kept and the load's tests judge them."""
    t, _, y = _rows(3.0)
    r = np.where((t >= 1.2)[:, None], y @ _point(1.2, (0.35, 0.02)), 0.0)
    w, keep = payload.weigh_trimmed(y, r, NAMES)
    assert keep.all()
    np.testing.assert_array_equal(w.pi, payload.weigh(y, r, NAMES).pi)


@pytest.mark.parametrize("misfit", [0.0, 0.3])
def test_the_step_onset_is_the_change_point_of_its_signature(misfit: float) -> None:
    """Known truth: the load's torque from row 400 of 750, with noise and, before it, a
    model error along the load's own torque at ``misfit`` of it (below half: it does not
    move the change point); a stretch without a step gives its end."""
    _, _, y = _rows(3.0)
    d = y @ _point(-1.5, (0.35, 0.02))
    rng = np.random.default_rng(2)
    left = rng.normal(0, 0.05, d.shape)
    left[400:] += d[400:]
    left[:400] += misfit * d[:400]
    assert abs(payload.step_onset(left, d) - 400) <= 3
    assert payload.step_onset(rng.normal(0, 0.05, d.shape), d) >= d.shape[0] - 5


def _release_run(kg: float, error_nm: float = 0.0, lag_vl: float | None = None
                 ) -> tuple[Callable[[], PayloadMonitor], np.ndarray]:
    """A 30 s planar run releasing ``kg`` (negative) at 18 s, with ``error_nm`` on the first
    joint's residual from 8 s (a model error no mass explains); vL 0.1 N·m, or
    ``lag_vl`` × the step's mean torque over its first 0.2 s. A function that runs the
    monitor over it in parts of 1000 samples, and vL."""
    t, q, y = _rows(30.0, swing=1.5)
    names_p = structures.planar_names(JOINTS, STRUCTURE)
    model = RigidModel("planar", JOINTS, tuple(names_p), np.zeros(len(names_p)), STRUCTURE)
    b, names = payload.basis("planar", JOINTS, STRUCTURE)
    d = y @ _point(kg, (0.35, 0.02))
    r = np.random.default_rng(0).normal(0, 0.01, (t.size, 2))
    r[t >= 18.0] -= d[t >= 18.0]  # r = τ̂ − τ
    r[t >= 8.0, 0] += error_nm
    k = int(18.0 * FS)
    v_l = (np.array([0.1, 0.1]) if lag_vl is None
           else lag_vl * np.abs(d[k:k + 50]).mean(axis=0))

    def run() -> PayloadMonitor:
        mon = PayloadMonitor(model, b, names, v_l, FS, 15.0, 2.0, 1, 3.0, 0.56, 1.5,
                             merge_gap_s=0.1)
        for k0 in range(0, t.size, 1000):
            mon.process(k0, t[k0:k0 + 1000], q[k0:k0 + 1000], r[k0:k0 + 1000])
        return mon

    return run, v_l


def test_a_release_inside_a_lasting_alarm_is_dated_at_its_step(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Known truth: a model error no mass explains (0.5 N·m on the first joint) keeps the
    static-loading alarm on from 8 s; a 1.5 kg release at 18 s runs into it. The monitor
    weighs the alarm's windows in turn and the one after the release passes: the change
    is dated at its step (18.0 s), not at the alarm's onset (8 s, as before
    ``_later_onset``), and the onset at 8 s stays one that was no load."""
    run, _ = _release_run(-1.5, error_nm=0.5)
    mon = run()
    (change,) = mon.changes
    assert abs(change.t_start - 18.0) < 0.05 and change.t_classified > 20.0
    assert abs(change.mass_kg + 1.5) < 0.25 * 1.5
    assert min(mon.tried) < 8.1  # the model error's alarm: tried, no load
    monkeypatch.setattr(PayloadMonitor, "_later_onset", lambda *a, **k: None)
    assert run().changes[0].t_start < 8.1  # what the change was dated at before


@pytest.mark.parametrize(("lag_vl", "crossed"), [(0.9, 18.15), (1.6, 18.8)])
def test_a_change_is_dated_at_its_step_not_where_the_loading_crossed_vl(
        monkeypatch: pytest.MonkeyPatch, lag_vl: float, crossed: float) -> None:
    """Known truth: a 1 kg release at 18 s whose torque there is 1.1× vL (the low-pass
    crosses vL 0.17 s after the step) or 0.6× vL (it crosses only when the motion makes
    the torque larger, at 18.83 s). The change is dated at its step, 18.0 s — where the
    mass explains the rows from there on and not those before — so an incident the
    adaptive detector starts at the step falls within the change. A new user's releases
    had been dated 0.3 s and 4.2 s late, and their steps counted as 29 N and 17 N
    contacts."""
    run, _ = _release_run(-1.0, lag_vl=lag_vl)

    def dated() -> float:
        (change,) = run().changes
        assert abs(change.mass_kg + 1.0) < 0.01
        return change.t_start

    assert abs(dated() - 18.0) < 0.01
    monkeypatch.setattr(PayloadMonitor, "_step_back", lambda *a, **k: None)
    assert dated() > crossed  # where the loading statistic crossed vL, as before


def test_a_load_in_all_the_motion_kept_before_its_alarm_is_not_dated_at_the_alarm() -> None:
    """Known truth: 1 kg picked at 5 s by the planar arm hanging down (its torque there
    ~0.9 N·m), then raised from 10 s; with vL 2 N·m the static-loading alarm comes only at
    ~13.3 s, when the raised arm makes the load's torque pass it — 8 s after the pick,
    beyond the 9 s the monitor keeps around its 3 s window. The change is not said to be a
    step there: the load is in every row kept before the onset (``carried_since_s``, at or
    after the pick), and the words say so (a trial's pick at 20 s was printed as "+1.04 kg"
    at a 30 N push's alarm at 35.1 s). With vL 1 N·m the alarm is the pick's own: dated at
    5.0 s, and no such words."""
    from impactcli.detect.payload_words import change_text

    t = np.arange(int(30 * FS)) / FS
    q = np.column_stack([-np.pi / 2 + 0.1 * np.sin(1.3 * t)
                         + np.clip((t - 10.0) / 18.0, 0, 1) * 1.4, 0.6 * np.sin(0.9 * t + 1)])
    qf, qd, qdd = causal_derivatives(1.0 / FS, q, 15.0, Carry(), "q")
    b, names = payload.basis("planar", JOINTS, STRUCTURE)
    d = structures.regressor("planar", JOINTS, STRUCTURE, qf, qd, qdd) @ b @ _point(
        1.0, (0.35, 0.02))
    names_p = structures.planar_names(JOINTS, STRUCTURE)
    model = RigidModel("planar", JOINTS, tuple(names_p), np.zeros(len(names_p)), STRUCTURE)
    r = np.random.default_rng(0).normal(0, 0.01, (t.size, 2))
    r[t >= 5.0] -= d[t >= 5.0]  # r = τ̂ − τ

    def change(vl: float) -> dict:
        mon = PayloadMonitor(model, b, names, np.array([vl, vl]), FS, 15.0, 2.0, 1, 3.0,
                             0.56, 1.5, merge_gap_s=0.1)
        for k0 in range(0, t.size, 1000):
            mon.process(k0, t[k0:k0 + 1000], q[k0:k0 + 1000], r[k0:k0 + 1000])
        (c,) = mon.changes
        assert abs(c.mass_kg - 1.0) < 0.01
        return c.to_dict()

    late = change(2.0)
    assert late["t_start"] > 13.0 and 5.0 <= late["carried_since_s"] <= late["t_start"] - 6.0
    assert (f"NOT a step at this time: the load is in all the motion kept before it, from "
            f"{late['carried_since_s']:.3f} s, so it was picked or released then or before") \
        in change_text(late)
    own = change(1.0)
    assert abs(own["t_start"] - 5.0) < 0.01 and "carried_since_s" not in own
    assert "NOT a step" not in change_text(own)


def test_a_load_beyond_the_described_last_link_is_said() -> None:
    """A trial's robot file with its last link 0.25 m (the arm's: 0.4 m) fitted its 1 kg
    at mx 0.4 kg·m — a centre of mass 0.15 m beyond the described flange — and nothing
    said so. Known truth: a point mass m at c along the last link has mx = m·c."""
    from types import SimpleNamespace

    from impactcli.model.payload_table import describe

    def model(length: float, logs: list[tuple[str, float, float]]) -> SimpleNamespace:
        rec = {"relative_to": "a.csv", "parameters": ["m", "mx", "my", "J"],
               "logs": [{"log": n, "values": {"m": m, "mx": m * c, "my": 0.0, "J": m * c * c},
                         "se": {"m": 0.0005, "mx": 0.0005, "my": 0.0005, "J": 0.001}}
                        for n, m, c in logs]}
        return SimpleNamespace(kind="planar", structure={"link_lengths": [0.4, length]},
                               fit={"payloads": rec})

    logs = [("a.csv", 0.0, 0.0), ("b.csv", 1.0, 0.4), ("c.csv", 0.0015, -0.036)]
    said = [ln for ln in describe(model(0.25, logs)) if "centre of mass" in ln]
    assert said == ["  b.csv: its load's centre of mass lies 0.4 m along the last link, where "
                    "the robot description ends that link at 0.25 m: a long tool — or a "
                    "wrong link length in the description (forces and the loads' effects "
                    "scale with it)"]
    # the right length, or a tool within a quarter of it beyond the flange: nothing said;
    # a 1.5 g "load" (three of its standard errors) has no centre of mass to judge
    assert not [ln for ln in describe(model(0.4, logs)) if "centre of mass" in ln]
    assert not [ln for ln in describe(model(0.34, logs)) if "centre of mass" in ln]
    behind = [("a.csv", 0.0, 0.0), ("b.csv", 1.0, -0.1)]
    assert [ln.split(":")[0] for ln in describe(model(0.4, behind))
            if "centre of mass" in ln] == ["  b.csv"]
