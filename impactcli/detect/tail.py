"""Thresholds for a stated false-alarm rate from collision-free logs (peaks over threshold),
and the rate that thresholds set another way (the leave-one-out margin, calibrate's
default) are predicted to give (:func:`rates_for_thresholds`).

``calibrate --false-alarms-per-hour R``: per channel (joint × product detector: adaptive
``r_rms − v_rms`` against v_stat, static_loading ``|LP(r)|`` against vL), the free logs'
statistic is declustered by the incident merge rule (exceedances ≤ merge_gap_s apart are
one cluster), its cluster peaks above a level u are fitted by a Poisson rate × generalized
Pareto tail (:mod:`impactcli.detect.tail_fit`), as in Siffer et al., "Anomaly detection in
streams with extreme value theory", KDD 2017 — here with an upper confidence bound: each
threshold is where the upper ``conf`` bound of its crossing rate is its share of R, and
the shares sum to R (every channel's cluster lies in one incident, so R bounds the
incident rate). Log starts (the first SETTLE_S after warm-up, where the adaptive
statistic still settles) are not a rate: thresholds stay above START_MARGIN × their peak
there. Below the rate the free-motion time supports (:func:`support`) thresholds are widened
along the heaviest allowed tail and the result says so (:meth:`RateCalibration.support_statement`).
The choice of every constant and its validation on simulated free hours: docs/validation.md.

Inputs: per free log, the (N_l, C) statistic *after warm-up* (:func:`stack_detectors`
makes it from detector → (N_l, J)); rates in incidents per hour; statistics in N·m.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .tail_fit import (
    CONF,
    HEAVY_TEST,
    XI_MAX,
    TailFit,
    fit_tail,
    poisson_interval,
    rate_upper,
    sigma_upper,
    threshold_upper,
)
from .thresholds import MAX_MARGIN, MIN_THRESHOLD  # MIN_THRESHOLD: the smallest returned [N·m]

__all__ = [
    "CONF",
    "CONFIG_KEYS",
    "DEFAULT_FALSE_ALARMS_PER_HOUR",
    "DETECTORS",
    "ChannelFits",
    "Clusters",
    "LoloRow",
    "RateCalibration",
    "TailFit",
    "calibrate_rate",
    "calibration_text",
    "capped_detectors",
    "clusters",
    "count_incidents",
    "fit_channel",
    "fit_channels",
    "leave_one_log_out",
    "left_out_above",
    "minutes_needed",
    "minutes_text",
    "per_hour_text",
    "poisson_interval",
    "rate_at",
    "rate_upper",
    "rates_for_thresholds",
    "split_settle",
    "stack_detectors",
    "support",
    "support_statement",
    "threshold_upper",
    "thresholds_for_rate",
]

#: The audit's rate [incidents per hour] (``calibrate --threshold-rule false-alarm-rate``
#: without a rate): 0 held-out false alarms in 77 simulated hours, as at 0.1, with more
#: contacts caught; what ~5 min of free motion supports.
DEFAULT_FALSE_ALARMS_PER_HOUR = 1.0
#: The product's detectors whose thresholds this sets (incidents.PRODUCT_DETECTORS), and
#: the config's threshold each one replaces.
DETECTORS: tuple[str, ...] = ("adaptive", "static_loading")
CONFIG_KEYS: dict[str, str] = {"adaptive": "v_stat", "static_loading": "vL"}
#: events.merge_gap_s's default [s] (config.EventsConfig).
MERGE_GAP_S = 0.1
#: Clusters aimed for above each level u.
N_TARGET = 30
#: Settling window after warm-up [s] and the floor's margin over its peak (module doc).
SETTLE_S = 10.0
START_MARGIN = 1.2
#: How far the fit may extrapolate beyond the free time's zero-count bound (support).
MAX_EXTRAPOLATION = 30.0
_EPS_S = 1e-9


# ---------------------------------------------------------------------------- clusters
class Clusters(NamedTuple):
    """starts, ends (n,): inclusive sample indices; excess (n,): each cluster's largest
    ``x − level`` (over channels too, for (N, C) input) [units of x]."""

    starts: np.ndarray
    ends: np.ndarray
    excess: np.ndarray


def gap_samples(merge_gap_s: float, dt_s: float) -> int:
    """Largest index step between exceeding samples that still merges (t_b − t_a ≤
    merge_gap_s, with events' 1 ns tolerance) at sample period ``dt_s`` [s]."""
    return math.floor((merge_gap_s + _EPS_S) / dt_s + 1e-9)


def clusters(x: np.ndarray, level: float | np.ndarray, dt_s: float,
             merge_gap_s: float = MERGE_GAP_S) -> Clusters:
    """Clusters of ``x > level``: exceeding samples at most ``merge_gap_s`` apart (from one
    burst's last to the next's first, as events.extract_events and incidents.group_events
    merge them) form one cluster.

    x: (N,) one channel, or (N, C) with (C,) ``level``: a sample exceeds when any channel
    does (the incidents of thresholds ``level``). dt_s: sample period [s].
    """
    ex = np.asarray(x, dtype=np.float64) - level
    e1 = ex if ex.ndim == 1 else ex.max(axis=1)
    idx = np.flatnonzero(e1 > 0)
    if idx.size == 0:
        z = np.zeros(0, dtype=np.int64)
        return Clusters(z, z, np.zeros(0))
    brk = np.flatnonzero(np.diff(idx) > gap_samples(merge_gap_s, dt_s))
    starts = np.concatenate([idx[:1], idx[brk + 1]])
    ends = np.concatenate([idx[brk], idx[-1:]])
    # each reduceat segment runs to the next start: the samples past the end are ≤ 0
    return Clusters(starts, ends, np.maximum.reduceat(e1, starts))


def _per_log(dt_s: float | Sequence[float], n: int) -> list[float]:
    if isinstance(dt_s, Sequence | np.ndarray):
        out = [float(d) for d in dt_s]
    else:
        return [float(dt_s)] * n
    if len(out) != n:
        raise ValueError(f"{len(out)} sample periods for {n} logs")
    return out


def _hours(stats: Sequence[np.ndarray], dts: Sequence[float]) -> float:
    return sum(np.shape(s)[0] * d for s, d in zip(stats, dts, strict=True)) / 3600.0


def count_incidents(stats: Sequence[np.ndarray], thresholds: np.ndarray,
                    dt_s: float | Sequence[float], merge_gap_s: float = MERGE_GAP_S) -> int:
    """Incidents (clusters of the union over channels of ``s_c > t_c``) in the logs
    (list of (N_l, C)); without incidents' "pressing" bridge, which only merges more."""
    thr = np.asarray(thresholds, dtype=np.float64)
    return sum(clusters(s, thr, d, merge_gap_s).starts.size
               for s, d in zip(stats, _per_log(dt_s, len(stats)), strict=True))


# ------------------------------------------------------------------------- one channel
def choose_level(xs: Sequence[np.ndarray], dts: Sequence[float], merge_gap_s: float,
                 n_target: int = N_TARGET) -> tuple[float, int]:
    """(u, clusters above u): the highest of 200 upper quantiles of the pooled (N_l,)
    statistics with at least ``n_target`` clusters above it; else the one with the most."""
    qs = np.quantile(np.concatenate(xs), 1.0 - np.geomspace(1e-4, 0.5, 200))
    best_u, best_n = float(qs[0]), -1
    for u in qs:
        n = sum(clusters(x, u, d, merge_gap_s).starts.size
                for x, d in zip(xs, dts, strict=True))
        if n >= n_target:
            return float(u), n
        if n > best_n:
            best_u, best_n = float(u), n
    return best_u, best_n


def fit_channel(stats: Sequence[np.ndarray], c: int, dt_s: float | Sequence[float], *,
                name: str = "", merge_gap_s: float = MERGE_GAP_S, n_target: int = N_TARGET,
                xi_max: float = XI_MAX, heavy_test: float | None = HEAVY_TEST) -> TailFit:
    """The tail of channel ``c`` of the logs' (N_l, C) statistics (clusters pooled over
    logs, never spanning two): :func:`tail_fit.fit_tail` above :func:`choose_level`."""
    dts = _per_log(dt_s, len(stats))
    xs = [np.asarray(s, dtype=np.float64)[:, c] for s in stats]
    if not all(np.all(np.isfinite(x)) for x in xs):
        raise ValueError(f"{name or f'channel {c}'}: statistic not finite")
    u, _ = choose_level(xs, dts, merge_gap_s, n_target)
    peaks = [clusters(x, u, d, merge_gap_s).excess for x, d in zip(xs, dts, strict=True)]
    return fit_tail(np.concatenate(peaks), u, _hours(stats, dts), name=name,
                    max_stat=max(float(np.max(x)) for x in xs), xi_max=xi_max,
                    heavy_test=heavy_test)


def rate_at(fit: TailFit, t: float, conf: float = CONF) -> tuple[float, float]:
    """(predicted, upper ``conf`` bound) of the rate of clusters above threshold t [1/h]."""
    return fit.rate(t), rate_upper(fit, t, conf)


# ----------------------------------------------------------------------------- support
def zero_count_bound(hours: float, conf: float = CONF) -> float:
    """The rate [1/h] that ``hours`` of free motion with no alarm bound by themselves, at
    ``conf``: −ln(1 − conf) / hours (no tail fit)."""
    return -math.log(1.0 - conf) / hours


def support(hours: float, conf: float = CONF) -> float:
    """The lowest rate [1/h] that ``hours`` of free motion support at ``conf``: the
    zero-count bound −ln(1 − conf) / hours, extrapolated at most MAX_EXTRAPOLATION×."""
    return zero_count_bound(hours, conf) / MAX_EXTRAPOLATION


def minutes_needed(rate: float, conf: float = CONF) -> float:
    """Free-motion minutes (after warm-up and settling) that support ``rate`` [1/h]."""
    return 60.0 * -math.log(1.0 - conf) / (MAX_EXTRAPOLATION * rate)


def support_statement(hours: float, rate: float | None, conf: float = CONF) -> str:
    """What ``hours`` of free motion support — the lowest rate they can bound, and the
    zero-count bound it extrapolates from — and what ``rate`` [1/h] would need (None: no
    rate asked)."""
    rs = support(hours, conf)
    per = f"1 per ~{1 / rs:.2g} h" if rs < 1 else f"{per_hour_text(rs)} per hour"
    zero = zero_count_bound(hours, conf)  # what no alarm in them bounds, without a tail fit
    s = (f"{minutes_text(hours * 60)} min of free motion bound a false-alarm rate no lower "
         f"than {per} at {conf * 100:.0f} % confidence (with no alarm in them, "
         f"{per_hour_text(zero)} per hour; the tail fits reach at most "
         f"{MAX_EXTRAPOLATION:g}× below that)")
    if rate is None:
        return s
    if rate < rs:
        return (s + f"; log ≥ {math.ceil(minutes_needed(rate, conf))} min of the robot's "
                f"motions for {rate:g} per hour (until then not promised; each threshold "
                "at least its widened value)")
    return s + f"; {rate:g} per hour is within it"


def extrapolated_note(upper: float, hours: float, conf: float = CONF) -> str | None:
    """The note of a bound ``upper`` [1/h] that only the tail fits give: below what
    ``hours`` of free motion with no alarm bound by themselves (None when it is not)."""
    zero = zero_count_bound(hours, conf)
    if not upper < zero:
        return None
    return (f"the upper bound {per_hour_text(upper)} per hour rests on the tail fits' "
            f"extrapolation: {minutes_text(hours * 60)} min of free motion with no alarm "
            f"bound {per_hour_text(zero)} per hour by themselves")


def minutes_text(minutes: float) -> str:
    """Free-motion minutes as printed: one decimal from 1 min on, else 2 significant
    digits (``0.037``, not ``0.0``)."""
    return f"{minutes:.1f}" if minutes >= 1 else f"{minutes:.2g}"


#: Rates below this [1/h] print as "< 0.001": one false alarm in six weeks of running, far
#: beyond what minutes of free motion show; a tail fit's "2.9e-07" is an extrapolation, and
#: its digits would read as a measurement.
SMALLEST_RATE = 1e-3


def per_hour_text(rate: float) -> str:
    """A rate [1/h] as the terminal and report print it: 2 significant digits, whole
    numbers from 100 on (``200``, not ``2e+02``), ``< 0.001`` below :data:`SMALLEST_RATE`
    (0 as ``0``)."""
    if 0.0 < rate < SMALLEST_RATE:
        return f"< {SMALLEST_RATE:g}"
    return f"{rate:.0f}" if rate >= 100 else f"{rate:.2g}"


def at_most_text(rate: float) -> str:
    """An upper bound [1/h] as printed: ``≤ 2.9``, ``≤ 0.001`` below :data:`SMALLEST_RATE`."""
    return f"≤ {SMALLEST_RATE:g}" if 0.0 < rate < SMALLEST_RATE else f"≤ {per_hour_text(rate)}"


def capped_detectors(calib: Mapping[str, object]) -> list[str]:
    """The detectors of a config's calibration record (its mapping) whose leave-one-out
    margin hit its cap (:data:`~impactcli.detect.thresholds.MAX_MARGIN`) on some joint: the
    calibration logs disagreed, so a log like the most different one may still alarm. Under
    a stated rate the product's detectors (:data:`DETECTORS`) are set by the rate, not the
    margin, and are not listed."""
    margins = calib.get("margins") or {}
    rate = calib.get("false_alarm_rate")
    rated = isinstance(rate, Mapping) and "per_hour" in rate
    return sorted(d for d, m in (margins.items() if isinstance(margins, Mapping) else ())
                  if isinstance(m, Mapping) and max(m.values(), default=0) >= MAX_MARGIN
                  and not (rated and d in DETECTORS))


def left_out_above(rate: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The calibration logs that, left out, false-alarmed above the bound the others' fit
    gave (a rate record's ``leave_one_log_out`` rows: the low end of the observed rate's
    interval, at the record's confidence, above ``upper_per_hour``), each with its worst
    row: ``log``, ``per_hour`` (R), ``observed_per_hour``, ``low`` (that low end),
    ``upper_per_hour`` and ``ratio`` (low / upper), in the rows' order of logs."""
    conf = float(rate.get("confidence", CONF))
    worst: dict[str, dict[str, Any]] = {}
    for r in rate.get("leave_one_log_out") or ():
        hours = float(r["minutes"]) / 60.0
        if hours <= 0.0:
            continue
        low, _ = poisson_interval(int(r["observed"]), hours, conf)
        upper = float(r["upper_per_hour"])
        if upper > 0.0 and low > upper:
            log = str(r["log"])
            if low / upper > worst.get(log, {}).get("ratio", 0.0):
                worst[log] = {"log": log, "per_hour": float(r["per_hour"]),
                              "observed_per_hour": int(r["observed"]) / hours, "low": low,
                              "upper_per_hour": upper, "ratio": low / upper}
    return list(worst.values())


def left_out_text(rate: Mapping[str, Any]) -> str:
    """"but k of the calibration logs, left out, false-alarmed above the others' bound (…)":
    the prediction that did not hold for a log left out (:func:`left_out_above`, the worst
    named), "" when it held for each."""
    above = left_out_above(rate)
    if not above:
        return ""
    w = max(above, key=lambda x: x["ratio"])
    others = [Path(x["log"]).name for x in above if x is not w]
    also = (f"; also {', '.join(others)}" if len(others) <= 3 else
            f"; also {', '.join(others[:3])} and {len(others) - 3} more")
    return (f"but {len(above)} of the calibration logs, left out, false-alarmed above the "
            f"others' bound ({Path(w['log']).name}: {w['observed_per_hour']:.3g}/h against "
            f"{w['upper_per_hour']:.3g}/h, thresholds set on the others for "
            f"{w['per_hour']:g}/h{also if others else ''}): a log unlike the calibration "
            "logs may false-alarm far above the prediction")


def calibration_text(calib: Mapping[str, object], settings_changed: bool = False) -> str:
    """How a calibrated config's thresholds were set and what that promises, in one phrase
    (detect's terminal, the report's header): the rate asked or the margin rule, the rate
    they are predicted to give and its bound, whether the free motion supports it, a
    weak calibration's reason (one log; a capped margin, :func:`capped_detectors`), and,
    with ``settings_changed``, that none of it holds for the config's edited settings."""
    rate = calib.get("false_alarm_rate")
    rate = rate if isinstance(rate, Mapping) else {}
    rule = str(calib.get("margin_rule") or "rule not recorded")
    pct = f" at {100 * float(rate['confidence']):.0f} %" if "confidence" in rate else ""
    bound = (f"predicted {per_hour_text(float(rate['predicted_per_hour']))} false alarm(s) "
             f"per hour, {at_most_text(float(rate['upper_per_hour']))}{pct}, on motion "
             "like the calibration logs'"
             if "predicted_per_hour" in rate and "upper_per_hour" in rate else "")
    # a prediction a log left out contradicted is said after the contradiction, not before
    # it (a trial read "predicted 0.0056 per hour, ≤ 1.5" first, a 4.8e3/h log left out after)
    above = left_out_text(rate)
    lead = f"NOT borne out — {above.removeprefix('but ')}; " if above else ""
    if "per_hour" in rate:
        text = f"set for {float(rate['per_hour']):g} false alarm(s) per hour"
        text += (f": {lead}{bound}" if lead and bound else f" ({bound})" if bound
                 else f": {lead.removesuffix('; ')}" if lead else "")
    else:
        text = f"{rule}, " + lead + (bound or "no false-alarm rate recorded")
    if rate.get("supported") is False or ("per_hour" not in rate and "supported_per_hour"
                                          in rate and float(rate["supported_per_hour"])
                                          > float(rate.get("upper_per_hour", 0.0))):
        text += f", not supported by its free motion ({rate.get('statement', '')})"
    if calib.get("weak"):
        capped = capped_detectors(calib)
        if rule == "fixed-single-log":
            text += "; weak: one calibration log, a fixed 1.5× margin"
        elif capped:
            text += (f"; weak: the leave-one-out margin hit its cap of {MAX_MARGIN:g}× on "
                     f"{', '.join(capped)}")
    if settings_changed:
        text = ("NOT for these settings (edited after calibrate: calibrate again); as "
                f"calibrated: {text}")
    return text


# -------------------------------------------------------------------------- log starts
def split_settle(stats: Sequence[np.ndarray], dt_s: float | Sequence[float],
                 settle_s: float = SETTLE_S) -> tuple[list[np.ndarray], np.ndarray]:
    """Each log's (N_l, C) statistic after warm-up split into what the tail is fitted on
    (from ``settle_s`` on) and its settling window's peak: (list, (L, C) peaks). A log
    shorter than 2 × ``settle_s`` is fitted whole (its peak still counts)."""
    out, peaks = [], []
    for raw, d in zip(stats, _per_log(dt_s, len(stats)), strict=True):
        s = np.asarray(raw, dtype=np.float64)
        k = round(settle_s / d)
        peaks.append(s[:max(k, 1)].max(axis=0))
        out.append(s[k:] if s.shape[0] >= 2 * k else s)
    return out, np.array(peaks)


def stack_detectors(per_detector: Mapping[str, np.ndarray], joints: Sequence[str]
                    ) -> tuple[np.ndarray, tuple[str, ...]]:
    """One log's (N, C) statistic and its C = 2 J channel names ``joint/detector`` from
    detector → (N, J) statistic (adaptive ``r_rms − v_rms``, static_loading ``|LP(r)|``)."""
    x = np.hstack([np.asarray(per_detector[d], dtype=np.float64) for d in DETECTORS])
    return x, tuple(f"{j}/{d}" for d in DETECTORS for j in joints)


# ------------------------------------------------------------------------ all channels
@dataclass(frozen=True, eq=False)
class RateCalibration:
    """Thresholds for ``rate`` incidents per hour over all channels together, or (``rate``
    None) the rate that thresholds set another way are predicted to give.

    Per channel (C,): names ``joint/detector``; thresholds [N·m]; predicted: the
    maximum-likelihood rate at the threshold [1/h]; upper: its upper ``conf`` bound [1/h];
    widened: raised beyond the fit because ``rate`` < rate_supported; floored: held at the
    log-start floor (``rate`` None: below it, so log starts may alarm beyond the
    prediction); fits (ξ, σ, u, ν, n). hours: free-motion time of the fits [h].
    """

    names: tuple[str, ...]
    thresholds: np.ndarray
    predicted: np.ndarray
    upper: np.ndarray
    widened: np.ndarray
    floored: np.ndarray
    fits: tuple[TailFit, ...]
    rate: float | None
    conf: float
    hours: float
    rate_supported: float
    notes: tuple[str, ...] = ()

    @property
    def predicted_total(self) -> float:
        """Predicted incident rate (sum over channels) [1/h]."""
        return float(np.sum(self.predicted))

    @property
    def upper_total(self) -> float:
        """Upper ``conf`` bound of the incident rate (union bound) [1/h]; for thresholds
        set another way (``rate`` None) never below what the free time supports: a
        smaller rate is an extrapolation the data cannot back."""
        total = float(np.sum(self.upper))
        return total if self.rate is not None else max(total, self.rate_supported)

    @property
    def below_support(self) -> bool:
        """The asked rate is below what the free-motion time supports (widening applies)."""
        return self.rate is not None and self.rate < self.rate_supported

    @property
    def any_widened(self) -> bool:
        """Some threshold was raised by the widening (beyond its profile bound)."""
        return bool(np.any(self.widened))

    def support_statement(self) -> str:
        """:func:`support_statement` of this calibration (for the terminal and report)."""
        return support_statement(self.hours, self.rate, self.conf)

    def table(self) -> dict[str, dict[str, float]]:
        """detector → joint → threshold [N·m], the config's ``v_stat``/``vL`` values."""
        out: dict[str, dict[str, float]] = {d: {} for d in DETECTORS}
        for name, t in zip(self.names, self.thresholds, strict=True):
            joint, det = name.rsplit("/", 1)
            out[det][joint] = float(t)
        return out

    def lines(self) -> list[str]:
        """What ``calibrate`` prints: totals, one line per channel, support, notes."""
        asked = "not asked" if self.rate is None else f"asked {self.rate:g}"
        out = [f"false alarms per hour: {asked}; predicted "
               f"{per_hour_text(self.predicted_total)}, upper bound "
               f"{per_hour_text(self.upper_total)} at "
               f"{self.conf * 100:.0f} % confidence, on {minutes_text(self.hours * 60)} min "
               "of free motion"]
        for k, f in enumerate(self.fits):
            floor = " (log-start floor)" if self.rate is not None else " (below log-start floor)"
            tag = " (widened)" if self.widened[k] else floor if self.floored[k] else ""
            out.append(f"  {f.name:28s} threshold {self.thresholds[k]:.4g}{tag}: free max "
                       f"{f.max_stat:.4g}, u {f.u:.4g}, {f.n} clusters ({f.nu:.3g}/h), "
                       f"{f.shape}, σ {f.sigma:.3g}; rate "
                       f"{per_hour_text(self.predicted[k])}/h, bound "
                       f"{per_hour_text(self.upper[k])}/h")
        return [*out, "  " + self.support_statement(), *(f"  note: {n}" for n in self.notes)]


@dataclass(frozen=True, eq=False)
class ChannelFits:
    """Every channel's tail fit and its log-start floor (C,) [N·m] (−inf: none)."""

    fits: tuple[TailFit, ...]
    floor: np.ndarray

    @property
    def hours(self) -> float:
        """Free-motion time the fits rest on [h]."""
        return self.fits[0].hours


def fit_channels(
    stats: Sequence[np.ndarray], dt_s: float | Sequence[float], *,
    names: Sequence[str] | None = None, merge_gap_s: float = MERGE_GAP_S,
    settle_s: float = SETTLE_S, log_start: Sequence[bool] | None = None,
    n_target: int = N_TARGET, heavy_test: float | None = HEAVY_TEST,
) -> ChannelFits:
    """Tail fits of every channel of the free logs, and the log-start floor.

    Args:
        stats: per free log (or stretch), the (N_l, C) statistics after warm-up [N·m].
        dt_s: sample period(s) [s]. names: (C,) ``joint/detector`` (:func:`stack_detectors`).
        settle_s: the window after each log start left out of the fit; the floor is
            START_MARGIN × its peak. log_start: (L,) which entries begin at a warm-up's end
            (default all; a stretch after a cut-out contact does not settle).
        heavy_test: :func:`tail_fit.fit_tail`; None profiles ξ over [0, XI_MAX] always.
    """
    if not stats:
        raise ValueError("need at least one free log")
    dts = _per_log(dt_s, len(stats))
    starts = [True] * len(stats) if log_start is None else [bool(b) for b in log_start]
    fitted, peaks = split_settle(stats, dts, settle_s)
    fitted = [f if st else np.asarray(s, dtype=np.float64)
              for f, s, st in zip(fitted, stats, starts, strict=True)]
    n_ch = np.shape(stats[0])[1]
    names = tuple(names) if names is not None else tuple(f"channel {c}" for c in range(n_ch))
    fits = tuple(fit_channel(fitted, c, dts, name=names[c], merge_gap_s=merge_gap_s,
                             n_target=n_target, heavy_test=heavy_test) for c in range(n_ch))
    floor = (START_MARGIN * peaks[np.array(starts)].max(axis=0) if any(starts)
             else np.full(n_ch, -np.inf))
    return ChannelFits(fits, floor)


def calibrate_rate(
    stats: Sequence[np.ndarray], dt_s: float | Sequence[float],
    rate: float = DEFAULT_FALSE_ALARMS_PER_HOUR, *, conf: float = CONF,
    names: Sequence[str] | None = None, merge_gap_s: float = MERGE_GAP_S,
    settle_s: float = SETTLE_S, log_start: Sequence[bool] | None = None,
    n_target: int = N_TARGET, heavy_test: float | None = HEAVY_TEST, widen: bool = True,
) -> RateCalibration:
    """Thresholds (C,) whose incident rate has upper ``conf`` bound ``rate`` [1/h]:
    :func:`fit_channels` (same arguments) then :func:`thresholds_for_rate`."""
    fits = fit_channels(stats, dt_s, names=names, merge_gap_s=merge_gap_s,
                        settle_s=settle_s, log_start=log_start, n_target=n_target,
                        heavy_test=heavy_test)
    return thresholds_for_rate(fits, rate, conf=conf, widen=widen)


def thresholds_for_rate(channels: ChannelFits, rate: float = DEFAULT_FALSE_ALARMS_PER_HOUR,
                        *, conf: float = CONF, widen: bool = True) -> RateCalibration:
    """Thresholds from fitted channels for ``rate`` [1/h], split equally over channels.

    A channel whose threshold is below its log-start floor is held there with the bound it
    has there; the rest of ``rate`` is shared by the others. With ``widen``, below
    :func:`support` (R_s), each threshold is raised from its bound at the supported rate
    along the heaviest tail allowed, ξ_max, at the scale's upper bound σ⁺:
    t ≥ t(R_s · share) + σ⁺ (f^ξ_max − 1) / ξ_max (σ⁺ ln f at ξ_max = 0), f = R_s / rate.
    """
    if not rate > 0:
        raise ValueError(f"the false-alarm rate must be positive, got {rate}")
    fits, floor = channels.fits, channels.floor
    n_ch, hours = len(fits), channels.hours
    rs = support(hours, conf)
    fac = rs / rate if widen and rate < rs else 1.0
    notes = [f"{f.name}: {f.n} clusters, too few for a shape (exponential, widened as "
             f"ξ = {f.xi_max:g})" for f in fits if f.xi_fixed and f.xi_max > 0]

    def solve(c: int, r: float) -> tuple[float, bool]:
        f = fits[c]
        t = threshold_upper(f, r, conf)
        if fac > 1.0:
            g = math.log(fac) if f.xi_max <= 0 else (fac ** f.xi_max - 1.0) / f.xi_max
            tw = threshold_upper(f, r * fac, conf) + sigma_upper(f, conf) * g
            if tw > t:
                return tw, True
        return t, False

    thr, upper = np.zeros(n_ch), np.zeros(n_ch)
    wid, held = np.zeros(n_ch, dtype=bool), np.zeros(n_ch, dtype=bool)
    while not held.all():
        act = np.flatnonzero(~held)
        budget = max(rate - float(np.sum(upper[held])), 1e-3 * rate)
        for c in act:
            thr[c], wid[c] = solve(int(c), budget / act.size)
        newly = act[floor[act] > thr[act]]
        if newly.size == 0:
            break
        for c in newly:
            notes.append(f"{fits[c].name}: raised from {thr[c]:.4g} to {floor[c]:.4g} by the "
                         "log starts (settling after warm-up); its share of the rate goes "
                         "to the other channels")
            thr[c], wid[c] = floor[c], False
            upper[c] = rate_upper(fits[c], float(thr[c]), conf)
        held[newly] = True
    thr = np.maximum(thr, MIN_THRESHOLD)
    for c in np.flatnonzero(~held):
        upper[c] = rate_upper(fits[c], float(thr[c]), conf) if math.isfinite(thr[c]) else 0.0
    pred = np.array([f.rate(float(t)) for f, t in zip(fits, thr, strict=True)])
    if (note := extrapolated_note(float(np.sum(upper)), hours, conf)) is not None:
        notes.append(note)
    return RateCalibration(tuple(f.name for f in fits), thr, pred, upper, wid, held, fits,
                           float(rate), conf, hours, rs, tuple(notes))


def rates_for_thresholds(channels: ChannelFits, thresholds: np.ndarray, *,
                         conf: float = CONF) -> RateCalibration:
    """The incident rate that thresholds (C,) [N·m] set another way (the leave-one-out
    margin) are predicted to give on motion like the free logs': per channel the fit's
    rate and its upper ``conf`` bound at the threshold (:func:`rate_at`), summed (union
    bound); the total bound is never stated below :func:`support`. A threshold under its
    channel's log-start floor is noted: log starts may alarm beyond the prediction."""
    fits, floor = channels.fits, channels.floor
    thr = np.asarray(thresholds, dtype=np.float64)
    if thr.shape != (len(fits),):
        raise ValueError(f"need {len(fits)} thresholds, got shape {thr.shape}")
    pred, upper = np.zeros(thr.size), np.zeros(thr.size)
    for c, (f, t) in enumerate(zip(fits, thr, strict=True)):
        pred[c], upper[c] = rate_at(f, float(t), conf)
    below = floor > thr
    notes = [f"{fits[c].name}: threshold {thr[c]:.4g} below the log-start peak's floor "
             f"{floor[c]:.4g}: log starts (settling after warm-up) may alarm beyond the "
             "prediction" for c in np.flatnonzero(below)]
    rs = support(channels.hours, conf)
    if float(np.sum(upper)) < rs:
        notes.append(f"the fits' bound {float(np.sum(upper)):.2g} per hour is below what the "
                     f"free motion supports; stated as {rs:.2g}")
    elif (note := extrapolated_note(float(np.sum(upper)), channels.hours, conf)) is not None:
        notes.append(note)
    return RateCalibration(tuple(f.name for f in fits), thr, pred, upper,
                           np.zeros(thr.size, dtype=bool), below, fits, None, conf,
                           channels.hours, rs, tuple(notes))


# ------------------------------------------------------------------- leave-one-log-out
@dataclass(frozen=True)
class LoloRow:
    """One fold: the log left out (index), its hours after warm-up [h], the asked rate,
    incidents seen in it, and the rate its thresholds predict (point, upper) [1/h]."""

    log: int
    hours: float
    rate: float
    observed: int
    predicted: float
    upper: float

    def interval(self, conf: float = CONF) -> tuple[float, float]:
        """Two-sided ``conf`` interval of the observed rate [1/h]."""
        return poisson_interval(self.observed, self.hours, conf)


def leave_one_log_out(stats: Sequence[np.ndarray], dt_s: float | Sequence[float],
                      rates: Sequence[float] = (30.0, 100.0, 300.0), *, conf: float = CONF,
                      merge_gap_s: float = MERGE_GAP_S, settle_s: float = SETTLE_S,
                      n_target: int = N_TARGET, heavy_test: float | None = HEAVY_TEST,
                      log_start: Sequence[bool] | None = None,
                      groups: Sequence[int] | None = None) -> list[LoloRow]:
    """For each free log and rate: :func:`calibrate_rate` on the other logs, incidents
    counted on the whole left-out log after warm-up. Use rates the left-out minutes can
    show (tens to hundreds per hour for 1–2 min logs). A fold above its bound says that
    log's motion is not represented by the others (docs/validation.md).

    ``log_start``: as :func:`fit_channels`. ``groups``: (L,) the log each entry belongs
    to (a log cut by contacts is several entries, left out together); default one log per
    entry. Rows carry the group as ``log``; hours are the group's entries' together.
    """
    dts = _per_log(dt_s, len(stats))
    starts = [True] * len(stats) if log_start is None else [bool(b) for b in log_start]
    grp = list(range(len(stats))) if groups is None else [int(g) for g in groups]
    if len(grp) != len(stats) or len(starts) != len(stats):
        raise ValueError("log_start and groups need one entry per statistic")
    order = sorted(set(grp))
    if len(order) < 2:
        raise ValueError("leave-one-log-out needs at least two free logs")
    rows = []
    for k in order:
        out = [i for i, g in enumerate(grp) if g == k]
        keep = [i for i, g in enumerate(grp) if g != k]
        hours = sum(np.shape(stats[i])[0] * dts[i] for i in out) / 3600.0
        fits = fit_channels([stats[i] for i in keep], [dts[i] for i in keep],
                            merge_gap_s=merge_gap_s, settle_s=settle_s,
                            log_start=[starts[i] for i in keep], n_target=n_target,
                            heavy_test=heavy_test)
        for r in rates:
            cal = thresholds_for_rate(fits, r, conf=conf)
            obs = sum(count_incidents([stats[i]], cal.thresholds, dts[i], merge_gap_s)
                      for i in out)
            rows.append(LoloRow(k, hours, float(r), obs, cal.predicted_total, cal.upper_total))
    return rows
