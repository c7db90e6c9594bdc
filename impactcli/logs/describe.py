"""Describing a log for ``impactcli inspect`` (``schemas/inspect.schema.json``) from its
scan (:class:`~impactcli.logs.scan.LogScan`) and its sample times: joints, channels and
their ranges, sources, timing, gaps, repairs — without holding its samples."""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import TOOL_NAME, __version__
from ..clock import GAP_FACTOR as _GAP_FACTOR
from ..clock import gap_steps
from ..sample_channels import CHANNEL_NAMES
from ..types import RobotLog
from .scan import LogScan

#: A step longer than this many periods may be a gap (:mod:`impactcli.clock`, rule (a)).
GAP_FACTOR = _GAP_FACTOR
#: At most this many gaps are listed (all are counted).
MAX_GAPS_LISTED = 20


def _ms(seconds: float) -> str:
    """Milliseconds for the text table; below 1 ns (clock rounding) shown as 0."""
    return "0" if abs(seconds) < 1e-9 else f"{seconds * 1e3:.4g}"


def time_gaps(log: RobotLog) -> tuple[np.ndarray, np.ndarray]:
    """Indices i of the steps t[i] → t[i+1] that are gaps, and their lengths [s]: longer
    than ``GAP_FACTOR`` periods, clearly beyond the log's jitter and not given back by the
    steps around them (:func:`impactcli.clock.gap_steps`)."""
    return gap_steps(log.t_ns, log.sample_clock)


def joints_left_out(scan: LogScan) -> list[dict[str, str]]:
    """The logged joints detection will leave out by their torque, with why, as ``detect``
    says it (``torque flat: …``, ``torque unmeasured: …``): the scan's torque screen
    against the largest peak-to-peak among its joints (:mod:`impactcli.logs.screen`).
    Joints a model or a calibrated config does not cover are left out by ``detect`` too;
    ``inspect`` knows of neither."""
    why = scan.screens["torque"].unusable(scan.torque_ptp, scan.torque_posed)
    return [{"name": j, "reason": f"torque {w}"}
            for j, w in zip(scan.joint_names, why, strict=True) if w is not None]


def _range(lo: float, hi: float) -> list[float] | None:
    return None if np.isnan(lo) else [float(lo), float(hi)]


def describe_log(scan: LogScan, t_ns: np.ndarray) -> dict[str, Any]:
    """JSON-ready description of a log from its scan and its (N,) sample times [ns]:
    joints, channels (and each one's range per joint), sources, timing, gaps, repairs.

    Timing (:mod:`impactcli.clock`): ``sample_rate_hz`` is 1 / the estimated period
    (the mean of the steps that span one period); jitter gives the std, min and max of the
    steps, the largest |dt − period|, the robust std of the steps about the period
    (``robust_std_s``) and the envelope holding 95 % of them (``envelope_s``); a gap is a
    step longer than ``threshold_s`` (1.5 periods, and twice the envelope beyond the
    period) that the steps around it do not give back, listed with its start (s since the
    first sample) and length [s] — the first :data:`MAX_GAPS_LISTED` of them:
    ``gaps.n_listed`` of ``gaps.count`` are listed. ``joints_dropped``: the joints the
    reader left out (no finite position or torque); ``joints_left_out``: those detection
    will leave out by their torque (:func:`joints_left_out`); ``ranges``: per array the log
    has, each joint's smallest and largest value (null where it does not log it);
    ``position_unit``: whether the positions can be radians (``ok``, ``warn`` or
    ``refuse`` — what ``detect`` would refuse, :mod:`impactcli.logs.plausibility`), and
    ``warnings``: what the scan warned of besides the repairs.
    """
    log = scan.log
    dt = np.diff(t_ns).astype(np.float64) * 1e-9
    clock = scan.clock
    period = clock.period_s
    dev = np.abs(dt - period)
    gap_idx = scan.gaps
    listed = gap_idx[:MAX_GAPS_LISTED]
    src = log.source
    present = [s for s in CHANNEL_NAMES if getattr(log, s) is not None]
    used = [f"{j}.{s}" for j in log.joint_names for s in present]
    return {
        "schema_version": "1.0",
        "tool": {"name": TOOL_NAME, "version": __version__},
        "path": src.path,
        "format": src.format,
        "sha256": src.sha256,
        "joints": list(log.joint_names),
        "n_joints": log.n_joints,
        "n_samples": scan.n_samples,
        "t0_ns": scan.t0_ns,
        "duration_s": scan.duration_s,
        "sample_rate_hz": clock.sample_rate_hz,
        "sample_period_s": period,
        "jitter": {
            "dt_std_s": float(np.std(dt)),
            "dt_min_s": float(dt.min()),
            "dt_max_s": float(dt.max()),
            "abs_dev_max_s": float(dev.max()),
            "robust_std_s": clock.jitter_s,
            "envelope_s": clock.envelope_s,
        },
        "gaps": {
            "count": int(gap_idx.size),
            "threshold_s": clock.gap_threshold_s,
            "listed": [
                {"sample": int(i), "t_s": float((t_ns[i] - t_ns[0]).astype(np.float64)
                                                * 1e-9), "length_s": float(dt[i])}
                for i in listed
            ],
            "n_listed": int(listed.size),
        },
        "torque_source": src.torque_source,
        "time_source": src.time_source,
        "signals": present,
        "channels": {"used": used, "ignored": list(src.ignored_channels)},
        "reference": log.has_reference,
        "repairs": list(src.repairs),
        "missing": list(src.notes),
        "joints_dropped": [{"name": n, "reason": r} for n, r in src.joints_dropped],
        "joints_left_out": joints_left_out(scan),
        "ranges": {s: {j: _range(lo[k], hi[k]) for k, j in enumerate(log.joint_names)}
                   for s, (lo, hi) in scan.ranges.items()},
        **({} if scan.position_unit is None else {"position_unit": {
            "verdict": scan.position_unit.kind, "message": scan.position_unit.message,
            "joints": list(scan.position_unit.joints)}}),
        "warnings": list(scan.warnings),
    }


def _unit_row(v: dict[str, Any] | None) -> str:
    """The table's line on the position unit."""
    if v is None:
        return "not checked"
    return {"ok": "rad (plausible)",
            "warn": "rad, suspicious: " + v["message"],
            "refuse": "cannot be radians: " + v["message"]}[v["verdict"]]


def format_table(d: dict[str, Any]) -> str:
    """The human-readable form of :func:`describe_log`'s result (each channel's range on a
    line of its own after the repairs)."""
    j = d["jitter"]
    rows = [
        ("log", d["path"]),
        ("format", d["format"]),
        ("sha256", d["sha256"]),
        ("joints", f"{d['n_joints']}: {', '.join(d['joints'])}"),
        ("samples", str(d["n_samples"])),
        ("t0", f"{d['t0_ns']} ns"),
        ("duration", f"{d['duration_s']:.3f} s"),
        ("sample rate",
         f"{d['sample_rate_hz']:.3f} Hz (period {d['sample_period_s'] * 1e3:.4g} ms)"),
        ("jitter", f"dt std {_ms(j['dt_std_s'])} ms (robust {_ms(j['robust_std_s'])} ms), "
                   f"95 % within ±{_ms(j['envelope_s'])} ms, largest |dt − period| "
                   f"{_ms(j['abs_dev_max_s'])} ms"),
        ("gaps", f"{d['gaps']['count']} (steps > {d['gaps']['threshold_s'] * 1e3:.4g} ms)"),
        ("torque source", d["torque_source"]),
        ("time source", d["time_source"]),
        ("signals", ", ".join(d["signals"])),
        ("reference", "yes" if d["reference"] else "no"),
        ("ignored", ", ".join(d["channels"]["ignored"]) or "none"),
        ("repairs", str(len(d["repairs"])) if d["repairs"] else "none"),
        ("missing", "; ".join(d.get("missing") or []) or "nothing"),
        ("joints dropped", ", ".join(f"{x['name']} ({x['reason']})"
                                     for x in d.get("joints_dropped", [])) or "none"),
        ("joints left out", ", ".join(f"{x['name']} ({x['reason']})"
                                      for x in d.get("joints_left_out", [])) or "none"),
        ("position unit", _unit_row(d.get("position_unit"))),
    ]
    width = max(len(k) for k, _ in rows)
    lines = [f"{k:<{width}}  {v}" for k, v in rows]
    gaps = d["gaps"]
    for g in gaps["listed"]:
        lines.append(f"{'':<{width}}  gap at {g['t_s']:.6f} s: {g['length_s'] * 1e3:.4g} ms")
    if len(gaps["listed"]) < gaps["count"]:
        lines.append(f"{'':<{width}}  {len(gaps['listed'])} of {gaps['count']} gaps listed")
    for r in d["repairs"]:
        lines.append(f"{'':<{width}}  repair: {r}")
    for sig, per in (d.get("ranges") or {}).items():
        text = ", ".join(f"{j} {v[0]:.4g}…{v[1]:.4g}" for j, v in per.items() if v is not None)
        lines.append(f"{'':<{width}}  {sig} range: {text or 'not logged'}")
    return "\n".join(lines)
