"""A synthetic run with known events, for testing outputs without a replay: its result
(:func:`fake_result`) and its per-sample data as the chunks a replay hands its writers
(:func:`fake_chunks`), fed through the same writers the CLI uses."""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from impactcli.clock import gap_steps
from impactcli.outputs.report import RenderedLog, assemble_report, render_log, write_report
from impactcli.outputs.report.margins import false_alarm_margins
from impactcli.outputs.report.samples import ReportCollector, Samples
from impactcli.outputs.rerun import RerunWriter
from impactcli.outputs.signals import SignalsWriter
from impactcli.types import (
    DETECTORS,
    SIGNAL_NAMES,
    ContactLabel,
    DetectionResult,
    Event,
    Labels,
    SignalsChunk,
)

from .conftest import make_log

#: Rows per fake chunk: several chunks per fake log, boundaries inside its events.
CHUNK_ROWS = 1000


@dataclass(frozen=True)
class ResultWithSignals(DetectionResult):
    """A detection result holding what its replay handed the writers (tests only): its log
    in memory (a RobotLog in ``log``) and the (N, J) signals, decisions and ratios."""

    signals: dict[str, np.ndarray] = field(default_factory=dict)
    decisions: dict[str, np.ndarray] = field(default_factory=dict)
    ratios: dict[str, np.ndarray] = field(default_factory=dict)


def fake_result(
    n: int = 2500, joints: tuple[str, ...] = ("j1", "j2"), dt: float = 0.004,
) -> ResultWithSignals:
    """10 s, 2 joints; an adaptive event on j2 then j1 at 4.0–4.1 s, a loading event at 7–7.5 s
    on j1, an adaptive event in warm-up at 0.2 s. Signals are smooth, ratios consistent."""
    log = make_log(n=n, joints=joints, dt=dt)
    t = log.time_s
    J = len(joints)
    rng = np.random.default_rng(1)
    sig = {name: 0.05 * rng.standard_normal((n, J)) for name in SIGNAL_NAMES}
    sig["torque"] = np.asarray(log.torque)
    sig["threshold"] = np.full((n, J), 0.3)
    sig["residual_rms"] = np.abs(sig["residual_rms"])
    sig["loading_statistic"] = np.abs(sig["loading_statistic"])
    ev_a = (t >= 4.0) & (t <= 4.1)
    sig["residual_rms"][ev_a, :] = 0.6
    ev_l = (t >= 7.0) & (t <= 7.5)
    sig["loading_statistic"][ev_l, 0] = 1.0
    thresholds = {j: {"v_stat": 0.2, "v0": 1.5, "vL": 0.5} for j in joints}
    ratios = {
        "adaptive": sig["residual_rms"] / sig["threshold"],
        "static_loading": sig["loading_statistic"] / 0.5,
        "static_baseline": np.abs(sig["residual"]) / 1.5,
    }
    decisions = {d: ratios[d] > 1.0 for d in DETECTORS}
    i0, i1 = int(np.argmax(ev_a)), int(len(t) - 1 - np.argmax(ev_a[::-1]))
    l0, l1 = int(np.argmax(ev_l)), int(len(t) - 1 - np.argmax(ev_l[::-1]))
    events = (
        Event("adaptive", float(t[50]), float(t[52]), 50, 52, (joints[0],), 1.4,
              {joints[0]: 0.5}, True),
        Event("adaptive", float(t[i0]), float(t[i1]), i0, i1, (joints[-1], joints[0]), 2.0,
              {joints[-1]: -3.0, joints[0]: 1.0}, False),
        Event("static_loading", float(t[l0]), float(t[l1]), l0, l1, (joints[0],), 2.0,
              {joints[0]: 1.2}, False),
    )
    return ResultWithSignals(
        log=log, model={"kind": "decoupled", "joint_names": list(joints)}, model_sha256="ab" * 32,
        model_source="identified-from-log",
        config={"adaptive": {"forgetting_factor": 0.999}},
        calibrated=False, thresholds=thresholds, reference_source="reference", torque_filtered=True,
        signals=sig, decisions=decisions, ratios=ratios, events=events, warmup_end_s=1.0,
        warmup_per_joint_s=dict.fromkeys(joints, 1.0),
        filter_gain={"frequencies_hz": [1.0, 5.0, 10.0],
                     "gain": {j: [0.1, 0.4, 0.8] for j in joints}},
    )


#: A two-link planar arm (link lengths 0.5 m and 0.25 m) for the report's kinematic facts.
PLANAR_ROBOT = {"joints": [{"name": "j1"}, {"name": "j2"}],
                "kinematics": {"type": "planar", "link_lengths": [0.5, 0.25],
                               "gravity": [0.0, -9.81]}}


def with_incidents(result: DetectionResult, *, kinematics: bool = True,
                   t0_ns: int | None = None) -> DetectionResult:
    """``fake_result()`` with its incidents: the warm-up alarm (0.2 s), a transient contact
    on link 2 (the adaptive event at 4.0 s, ~12 N) and a quasi-static one on link 1 (the
    loading event at 7.0 s, ~30 N). ``kinematics``: the model records a planar robot
    (:data:`PLANAR_ROBOT`), else none (forces None). ``t0_ns``: an epoch clock start."""
    import dataclasses

    from impactcli.detect.incidents import Incident

    log = result.log
    if t0_ns is not None:
        log = dataclasses.replace(log, t_ns=np.asarray(log.t_ns) - log.t_ns[0] + t0_ns)

    def utc(t: float) -> str | None:
        if t0_ns is None:
            return None
        import datetime as dt

        when = dt.datetime.fromtimestamp((t0_ns + round(t * 1e9)) / 1e9, tz=dt.UTC)
        return when.isoformat(timespec="milliseconds").replace("+00:00", "Z")

    ev = result.events
    method = "force at the end of the link (test)" if kinematics else "no kinematics"
    incs = (
        Incident(ev[0].t_start, ev[0].t_end, ev[0].i_start, ev[0].i_end, ("adaptive",),
                 ev[0].joints, 1, 0.4 if kinematics else None, method, "transient",
                 dict(ev[0].peak_residual), True, utc(ev[0].t_start), (0,)),
        Incident(ev[1].t_start, ev[1].t_end, ev[1].i_start, ev[1].i_end, ("adaptive",),
                 ev[1].joints, 2, 12.0 if kinematics else None, method, "transient",
                 dict(ev[1].peak_residual), False, utc(ev[1].t_start), (1,)),
        Incident(ev[2].t_start, ev[2].t_end, ev[2].i_start, ev[2].i_end, ("static_loading",),
                 ev[2].joints, 1, 30.0 if kinematics else None, method, "quasi_static",
                 dict(ev[2].peak_residual), False, utc(ev[2].t_start), (2,)),
    )
    model = dict(result.model or {})
    if kinematics:
        model["robot"] = PLANAR_ROBOT
    return dataclasses.replace(result, log=log, incidents=incs, model=model)


def fake_chunks(result: DetectionResult, rows: int = CHUNK_ROWS) -> Iterator[SignalsChunk]:
    """The fake run's per-sample data in chunks of ``rows`` samples, in time order, as a
    replay hands them to its writers."""
    log = result.log
    n = log.n_samples
    for a in range(0, n, rows):
        b = min(a + rows, n)
        yield SignalsChunk(
            tuple(log.joint_names), log.time_s[a:b], np.asarray(log.t_ns)[a:b],
            {k: v[a:b] for k, v in result.signals.items()},
            {k: v[a:b] for k, v in result.decisions.items()}, np.asarray(log.position)[a:b],
            None if log.position_ref is None else np.asarray(log.position_ref)[a:b],
            {k: v[a:b] for k, v in result.ratios.items()}, start=a)


def collect(result: DetectionResult, rows: int = CHUNK_ROWS, plots: bool = True) -> Samples:
    """The report's :class:`Samples` of the fake run, its chunks fed to a ReportCollector
    (the gaps of its clock as a scan finds them); the caller closes them."""
    log = result.log
    gaps, lengths = gap_steps(np.asarray(log.t_ns))
    col = ReportCollector(log.n_samples, gaps, lengths, plots=plots)
    try:
        for c in fake_chunks(result, rows):
            col(c)
        return col.finish(result)
    except BaseException:
        col.close()
        raise


def render(result: DetectionResult, labels: Labels | None = None, key: int = 0,
           origin: dict[str, Any] | None = None, rows: int = CHUNK_ROWS) -> RenderedLog:
    """:func:`render_log` of the fake run, on its collected samples."""
    samples = collect(result, rows)
    try:
        return render_log(result, labels, key, origin, samples=samples)
    finally:
        samples.close()


def build_report(results: Sequence[DetectionResult],
                 labels: Sequence[Labels | None] | None = None,
                 failed: Sequence[tuple[str, str]] = ()) -> tuple[str, dict[str, Any]]:
    """(html, doc) of a report on fake runs (one labels or None per run)."""
    labs = list(labels) if labels is not None else [None] * len(results)
    return assemble_report([render(r, lab, k) for k, (r, lab) in
                            enumerate(zip(results, labs, strict=True))], failed)


def write_fake_report(results: Sequence[DetectionResult], html_path: str | os.PathLike[str],
                      json_path: str | os.PathLike[str] | None = None,
                      labels: Sequence[Labels | None] | None = None) -> dict[str, Any]:
    """:func:`write_report` of fake runs (one labels or None per run)."""
    labs = list(labels) if labels is not None else [None] * len(results)
    return write_report([render(r, lab, k) for k, (r, lab) in
                         enumerate(zip(results, labs, strict=True))], html_path, json_path)


def margins(result: DetectionResult, labels: Labels | None = None) -> dict[str, Any]:
    """:func:`false_alarm_margins` of the fake run, on its collected samples."""
    samples = collect(result)
    try:
        return false_alarm_margins(result, labels, samples=samples)
    finally:
        samples.close()


def write_fake_rrd(result: DetectionResult, path: str | os.PathLike[str],
                   rows: int = CHUNK_ROWS, **options: Any) -> None:
    """The fake run's Rerun recording: its chunks fed to a :class:`RerunWriter`."""
    with RerunWriter() as w:
        for c in fake_chunks(result, rows):
            w(c)
        w.write(result, path, **options)


def write_fake_signals(result: DetectionResult, path: str | os.PathLike[str],
                       rows: int = CHUNK_ROWS) -> int:
    """The fake run's signals Parquet, written as ``detect --signals`` writes it (one row
    group per chunk of ``rows``); returns the number of row groups."""
    log = result.log
    with SignalsWriter(path, log.t0_ns, log.source.sha256, log.source.path) as w:
        for c in fake_chunks(result, rows):
            w(c)
    return -(-log.n_samples // rows)


def contact(start: float, end: float, force: float = 10.0, kind: str = "impact") -> ContactLabel:
    """A labelled contact on link 2."""
    return ContactLabel(start, end, force, kind, 2)


def labels(*cs: ContactLabel) -> Labels:
    """Labels of the contacts ``cs`` at 250 Hz."""
    return Labels(events=tuple(cs), sample_rate=250.0, path="<test labels>")


def sweep_result(adaptive_delay: float = 0.0):
    """10 s at 4 ms, warm-up 1 s; contacts at 4.0 s (3 N) and 8.0 s (1.5 N).

    adaptive ratio: 0.5 floor, 2.0 at the first contact (from onset + adaptive_delay), a
    1.5 false bump at 6.0 s, 1.2 at the second contact. static_loading: 0.3 floor, 1.4 from
    4.048 s (delay 48 ms), a 1.1 false bump at 2.0 s. static_baseline: 0.2 everywhere.
    """
    base = fake_result()
    t = base.log.time_s
    n, J = len(t), 2

    def box(a: float, b: float) -> np.ndarray:
        return (t >= a - 1e-9) & (t <= b + 1e-9)

    ad = np.full((n, J), 0.5)
    ad[box(4.0 + adaptive_delay, 4.1 + adaptive_delay), 1] = 2.0
    ad[box(6.0, 6.05), 0] = 1.5
    ad[box(8.0, 8.1), 1] = 1.2
    sl = np.full((n, J), 0.3)
    sl[box(4.048, 4.3), 0] = 1.4
    sl[box(2.0, 2.2), 0] = 1.1
    ratios = {"adaptive": ad, "static_loading": sl, "static_baseline": np.full((n, J), 0.2)}
    return replace(
        base, ratios=ratios, decisions={d: r > 1 for d, r in ratios.items()},
        config={"events": {"merge_gap_s": 0.02, "min_duration_s": 0.0}},
    )


#: The contacts :func:`sweep_result`'s ratios are built around.
SWEEP_LABELS = labels(contact(4.0, 4.1, 3.0), contact(8.0, 8.1, 1.5))
