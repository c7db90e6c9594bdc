"""Describing a log for ``impactcli inspect`` (``schemas/inspect.schema.json``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import TOOL_NAME, __version__
from ..types import RobotLog
from .channel_map import SIGNALS

#: A step longer than this many median periods is reported as a gap.
GAP_FACTOR = 1.5
#: At most this many gaps are listed (all are counted).
MAX_GAPS_LISTED = 20


def _ms(seconds: float) -> str:
    """Milliseconds for the text table; below 1 ns (clock rounding) shown as 0."""
    return "0" if abs(seconds) < 1e-9 else f"{seconds * 1e3:.4g}"


def time_gaps(log: RobotLog) -> tuple[np.ndarray, np.ndarray]:
    """Indices i of the steps t[i] → t[i+1] longer than ``GAP_FACTOR`` median periods, and
    their lengths [s]."""
    dt = np.diff(log.t_ns).astype(np.float64) * 1e-9
    if dt.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    idx = np.flatnonzero(dt > GAP_FACTOR * float(np.median(dt)))
    return idx, dt[idx]


def describe_log(log: RobotLog) -> dict[str, Any]:
    """JSON-ready description of ``log``: joints, channels, sources, timing, gaps, repairs.

    Timing: ``sample_rate_hz`` is 1 / median period; jitter is the std and max of
    |dt − median| [s]; a gap is a step longer than ``GAP_FACTOR`` median periods, listed
    with its start (s since the first sample) and length [s].
    """
    dt = np.diff(log.t_ns).astype(np.float64) * 1e-9
    med = float(np.median(dt))
    dev = np.abs(dt - med)
    gap_idx = np.flatnonzero(dt > GAP_FACTOR * med)
    ts = log.time_s
    src = log.source
    present = [s for s in SIGNALS if getattr(log, s) is not None]
    used = [f"{j}.{s}" for j in log.joint_names for s in present]
    return {
        "schema_version": "1.0",
        "tool": {"name": TOOL_NAME, "version": __version__},
        "path": src.path,
        "format": src.format,
        "sha256": src.sha256,
        "joints": list(log.joint_names),
        "n_joints": log.n_joints,
        "n_samples": log.n_samples,
        "t0_ns": log.t0_ns,
        "duration_s": log.duration_s,
        "sample_rate_hz": 1.0 / med,
        "sample_period_s": med,
        "jitter": {
            "dt_std_s": float(np.std(dt)),
            "dt_min_s": float(dt.min()),
            "dt_max_s": float(dt.max()),
            "abs_dev_max_s": float(dev.max()),
        },
        "gaps": {
            "count": int(gap_idx.size),
            "threshold_s": GAP_FACTOR * med,
            "listed": [
                {"sample": int(i), "t_s": float(ts[i]), "length_s": float(dt[i])}
                for i in gap_idx[:MAX_GAPS_LISTED]
            ],
        },
        "torque_source": src.torque_source,
        "time_source": src.time_source,
        "signals": present,
        "channels": {"used": used, "ignored": list(src.ignored_channels)},
        "reference": log.has_reference,
        "repairs": list(src.repairs),
    }


def format_table(d: dict[str, Any]) -> str:
    """The human-readable form of :func:`describe_log`'s result."""
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
        ("jitter", f"dt std {_ms(j['dt_std_s'])} ms, largest |dt − period| "
                   f"{_ms(j['abs_dev_max_s'])} ms"),
        ("gaps", f"{d['gaps']['count']} (steps > {d['gaps']['threshold_s'] * 1e3:.4g} ms)"),
        ("torque source", d["torque_source"]),
        ("time source", d["time_source"]),
        ("signals", ", ".join(d["signals"])),
        ("reference", "yes" if d["reference"] else "no"),
        ("ignored", ", ".join(d["channels"]["ignored"]) or "none"),
        ("repairs", str(len(d["repairs"])) if d["repairs"] else "none"),
    ]
    width = max(len(k) for k, _ in rows)
    lines = [f"{k:<{width}}  {v}" for k, v in rows]
    for g in d["gaps"]["listed"]:
        lines.append(f"{'':<{width}}  gap at {g['t_s']:.6f} s: {g['length_s'] * 1e3:.4g} ms")
    for r in d["repairs"]:
        lines.append(f"{'':<{width}}  repair: {r}")
    return "\n".join(lines)
