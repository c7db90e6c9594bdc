"""Thresholds for a false-alarm rate (impactcli.detect.tail, tail_fit) against known truth:
the product's merge rule, known GPD parameters, Poisson × exponential cluster processes
whose crossing rate at any threshold is known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from impactcli.config import EventsConfig
from impactcli.detect import tail
from impactcli.detect import tail_fit as tf
from impactcli.detect.events import extract_events
from impactcli.detect.incidents import PRODUCT_DETECTORS, group_events
from impactcli.detect.tail import calibration_text, capped_detectors
from impactcli.detect.thresholds import MAX_MARGIN, MIN_THRESHOLD


# ----------------------------------------------------------------------- the merge rule
def product_incidents(dec_a: np.ndarray, dec_l: np.ndarray, t: np.ndarray
                      ) -> list[tuple[int, int]]:
    """(first, last) sample of each incident the product forms from two detectors'
    (N, J) decisions (no warm-up, no "pressing" bridge)."""
    names = [f"j{k}" for k in range(dec_a.shape[1])]
    z = np.zeros(dec_a.shape)
    evs = [e for det, d in (("adaptive", dec_a), ("static_loading", dec_l)) if d.any()
           for e in extract_events(det, d, z, z, t, names, -1.0, 0.1)]
    evs.sort(key=lambda e: (e.t_start, e.t_end))
    return [(min(evs[k].i_start for k in g), max(evs[k].i_end for k in g))
            for g in group_events(evs, 0.1)]


def test_constants_are_the_products() -> None:
    assert tail.DETECTORS == PRODUCT_DETECTORS
    assert EventsConfig().merge_gap_s == tail.MERGE_GAP_S
    assert tail.MIN_THRESHOLD == MIN_THRESHOLD


def test_clusters_merge_gaps_up_to_merge_gap_s_only() -> None:
    x = np.zeros(100)
    # dt 10 ms: 5 → 15 is 0.10 s (merges), 15 → 26 is 0.11 s (does not), 26–28 a run
    x[[5, 15, 26, 27, 28, 60]] = [1.0, 3.0, 0.5, 2.0, 0.5, 0.2]
    c = tail.clusters(x, 0.1, 0.01)
    assert c.starts.tolist() == [5, 26, 60]
    assert c.ends.tolist() == [15, 28, 60]
    np.testing.assert_allclose(c.excess, [2.9, 1.9, 0.1])
    assert tail.clusters(x, 5.0, 0.01).starts.size == 0
    # (N, C): a sample exceeds when any channel exceeds its own level; excess is the
    # largest over channels. Union: 5 15 | 26 27 28 | 40 | 52 60 (gaps 10, 11, 12, 12, 8)
    y = np.zeros(100)
    y[[40, 52]] = [7.0, 1.0]
    cc = tail.clusters(np.stack([x, y], axis=1), np.array([0.1, 0.5]), 0.01)
    assert cc.starts.tolist() == [5, 26, 40, 52]
    assert cc.ends.tolist() == [15, 28, 40, 60]
    np.testing.assert_allclose(cc.excess, [2.9, 1.9, 6.5, 0.5])


@pytest.mark.parametrize("seed", range(6))
def test_clusters_are_the_products_incidents(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n, j, dt = 3000, 3, 0.004
    t = np.arange(n) * dt
    # sparse bursts of random lengths on random joints of both detectors
    stat = np.full((n, 2 * j), -1.0)
    for _ in range(60):
        a = int(rng.integers(0, n - 40))
        stat[a:a + int(rng.integers(1, 30)), int(rng.integers(0, 2 * j))] = rng.uniform(0.1, 2)
    thr = np.zeros(2 * j)
    want = product_incidents(stat[:, :j] > 0, stat[:, j:] > 0, t)
    got = tail.clusters(stat, thr, dt)
    assert list(zip(got.starts.tolist(), got.ends.tolist(), strict=True)) == want
    assert tail.count_incidents([stat[:1500], stat[1500:]], thr, dt) >= len(want)


# ------------------------------------------------------------------------------ the fit
@pytest.mark.parametrize(("xi", "sigma"), [(0.0, 2.0), (0.25, 1.5), (0.45, 0.3)])
def test_fit_recovers_known_gpd(xi: float, sigma: float) -> None:
    rng = np.random.default_rng(3)
    u = rng.uniform(size=4000)
    y = sigma * (-np.log(u) if xi == 0 else (u ** (-xi) - 1) / xi)
    xh, sh, _ = tf.fit_gpd(y)
    assert xh == pytest.approx(xi, abs=0.05)
    assert sh == pytest.approx(sigma, rel=0.06)
    f = tf.fit_tail(y, 1.0, 2.0)
    assert (f.shape == "exponential") == (xi == 0)     # the test rejects ξ = 0 when ξ > 0
    assert f.nu == pytest.approx(2000.0)


def gpd(rng: np.random.Generator, n: int, xi: float, sigma: float = 1.0) -> np.ndarray:
    u = rng.uniform(size=n)
    return sigma * (-np.log(u) if xi == 0 else (u ** (-xi) - 1) / xi)


def true_rate(nu: float, t: float, xi: float, sigma: float = 1.0) -> float:
    return float(nu * tf.gpd_survival(t, xi, sigma))


@pytest.mark.parametrize(("xi", "heavy_test", "rate"), [(0.0, tf.HEAVY_TEST, 1.0),
                                                         (0.3, None, 3.0)])
def test_upper_bound_covers_the_true_rate(xi: float, heavy_test: float | None,
                                          rate: float) -> None:
    """10 min of clusters at 300/h (50 peaks), thresholds 100–300× beyond: the bound holds
    in ≥ 85 % of seeds (aimed: 90 %), the point estimate in about half, and the bound is
    not vacuous (the true rate at it is within 20× of the asked one)."""
    nu, hours, covered, point, ratio = 300.0, 10 / 60, 0, 0, []
    for seed in range(40):
        rng = np.random.default_rng(seed)
        f = tf.fit_tail(gpd(rng, int(rng.poisson(nu * hours)), xi), 0.0, hours,
                        heavy_test=heavy_test)
        lam = true_rate(nu, tf.threshold_upper(f, rate), xi)
        covered += lam <= rate
        point += true_rate(nu, tf.return_excess(f.nu / rate, f.xi, f.sigma), xi) <= rate
        ratio.append(lam / rate)
        # rate_upper inverts threshold_upper
        pred, up = tail.rate_at(f, tf.threshold_upper(f, rate))
        assert pred < up == pytest.approx(rate, rel=1e-3)
    assert covered >= 34
    assert 8 <= point <= 32
    assert np.median(ratio) > 0.05


# --------------------------------------------------------------------- synthetic logs
SLOT_S = 0.5   # one cluster at most per slot: a Bernoulli ≈ Poisson process of clusters


def free_log(rng: np.random.Generator, minutes: float, nu: tuple[float, ...],
             sigma: tuple[float, ...], dt: float = 0.01, u0: float = 1.0) -> np.ndarray:
    """(N, C) statistic: Gaussian background (sd 0.1) and, per channel, clusters at rate
    nu [1/h] whose peaks are u0 + Exp(sigma), each a 3-sample bump (0.8 × peak beside)."""
    n = round(minutes * 60 / dt)
    x = 0.1 * rng.standard_normal((n, len(nu)))
    k = round(SLOT_S / dt)
    for c, (r, s) in enumerate(zip(nu, sigma, strict=True)):
        slots = np.flatnonzero(rng.uniform(size=n // k) < r * SLOT_S / 3600)
        i = slots * k + k // 2
        p = u0 + rng.exponential(s, slots.size)
        x[i, c] = p
        x[i - 1, c] = x[i + 1, c] = 0.8 * p
    return x


def held_out(rng: np.random.Generator, hours: float, nu: tuple[float, ...],
             sigma: tuple[float, ...], u0: float = 1.0) -> np.ndarray:
    """The same cluster process over a long time, one sample per slot (dt = SLOT_S)."""
    n = round(hours * 3600 / SLOT_S)
    x = np.zeros((n, len(nu)))
    for c, (r, s) in enumerate(zip(nu, sigma, strict=True)):
        hit = rng.uniform(size=n) < r * SLOT_S / 3600
        x[hit, c] = u0 + rng.exponential(s, int(hit.sum()))
    return x


def test_thresholds_for_a_rate_hold_over_long_synthetic_time() -> None:
    """Two channels, 4 free logs of 5 min; R = 3 per hour; 300 h held out."""
    rng = np.random.default_rng(7)
    nu, sigma = (360.0, 240.0), (0.5, 2.0)
    logs = [free_log(rng, 5.0, nu, sigma) for _ in range(4)]
    cal = tail.calibrate_rate(logs, 0.01, 3.0, names=("a/adaptive", "a/static_loading"))
    assert cal.hours == pytest.approx(4 * (5 * 60 - tail.SETTLE_S) / 3600)
    assert cal.upper_total == pytest.approx(3.0, rel=1e-3)
    assert not cal.any_widened and cal.rate >= cal.rate_supported
    for f, r, s in zip(cal.fits, nu, sigma, strict=True):
        assert f.shape == "exponential" and f.u >= 1.0
        assert f.sigma == pytest.approx(s, rel=0.35)
        assert f.nu * math.exp((f.u - 1.0) / s) == pytest.approx(r, rel=0.5)   # ν at u0
    truth = sum(r * math.exp(-(t - 1.0) / s)
                for r, s, t in zip(nu, sigma, cal.thresholds, strict=True))
    assert truth <= 3.0                                  # honest: the true rate is bounded
    hours = 300.0
    seen = sum(tail.count_incidents([held_out(rng, 50.0, nu, sigma)], cal.thresholds,
                                    SLOT_S) for _ in range(6))
    lo, hi = tf.poisson_interval(seen, hours, 0.99)
    assert lo <= truth <= hi                             # the counting sees the process
    assert lo <= 3.0                                     # the observed rate is within R
    assert seen / hours == pytest.approx(cal.predicted_total, rel=0.7)   # not vacuous
    # the baseline rule (max × a small margin) is not: it raises far more than R
    base = 1.05 * np.max([lg.max(axis=0) for lg in logs], axis=0)
    assert tail.count_incidents([held_out(rng, 50.0, nu, sigma)], base, SLOT_S) / 50 > 3.0


def test_rate_stated_for_thresholds_set_another_way() -> None:
    """The margin rule's thresholds (max × 1.05 over 4 free logs of 5 min): the rate the
    fits state for them bounds the true rate and what 300 held-out hours show; given the
    rate rule's own thresholds, it states the rate rule's rates."""
    rng = np.random.default_rng(13)
    nu, sigma = (360.0, 240.0), (0.5, 2.0)
    logs = [free_log(rng, 5.0, nu, sigma) for _ in range(4)]
    names = ("a/adaptive", "a/static_loading")
    chans = tail.fit_channels(logs, 0.01, names=names)
    base = 1.05 * np.max([lg.max(axis=0) for lg in logs], axis=0)
    st = tail.rates_for_thresholds(chans, base)
    assert st.rate is None and not st.below_support and not st.any_widened
    truth = sum(r * math.exp(-(t - 1.0) / s) for r, s, t in zip(nu, sigma, base, strict=True))
    assert st.predicted_total < st.upper_total and truth <= st.upper_total
    seen = sum(tail.count_incidents([held_out(rng, 50.0, nu, sigma)], base, SLOT_S)
               for _ in range(6))
    lo, _ = tf.poisson_interval(seen, 300.0, 0.9)
    assert lo <= st.upper_total and seen > 0            # honest, and not vacuous
    assert st.lines()[0].startswith("false alarms per hour: not asked; predicted ")
    ask = tail.thresholds_for_rate(chans, 3.0)
    again = tail.rates_for_thresholds(chans, ask.thresholds)
    np.testing.assert_allclose(again.predicted, ask.predicted, rtol=1e-9)
    np.testing.assert_allclose(again.upper, ask.upper, rtol=1e-6)
    with pytest.raises(ValueError, match="need 2 thresholds"):
        tail.rates_for_thresholds(chans, base[:1])


def test_stated_bound_is_never_below_what_the_free_time_supports() -> None:
    rng = np.random.default_rng(17)
    logs = [free_log(rng, 2.0, (360.0,), (0.5,)) for _ in range(2)]
    chans = tail.fit_channels(logs, 0.01)
    st = tail.rates_for_thresholds(chans, np.array([1e3]))   # far above every peak
    assert float(np.sum(st.upper)) < st.rate_supported
    assert st.upper_total == st.rate_supported
    assert any("below what the free motion supports" in n for n in st.notes)
    low = tail.rates_for_thresholds(chans, np.array([0.0]))  # under the log-start floor
    assert low.floored.tolist() == [True] and any("log-start" in n for n in low.notes)


def test_log_start_floor_holds_a_channel_and_shares_its_rate() -> None:
    rng = np.random.default_rng(11)
    logs = [free_log(rng, 4.0, (360.0, 360.0), (0.5, 0.5)) for _ in range(3)]
    logs[1][200:300, 0] += 40.0                        # a start transient at 2–3 s
    cal = tail.calibrate_rate(logs, 0.01, 2.0)
    assert cal.floored.tolist() == [True, False]
    assert cal.thresholds[0] == pytest.approx(tail.START_MARGIN * logs[1][:1000, 0].max())
    assert cal.upper[0] < 1e-3 and cal.upper_total == pytest.approx(2.0, rel=1e-3)
    # the same stretch not at a log start (after a cut-out): no floor from it; it is a
    # cluster of the fit then, which a tail of ξ ≤ 0.5 does not follow to 41
    no_start = tail.calibrate_rate(logs, 0.01, 2.0, log_start=[True, False, True])
    assert no_start.floored.tolist() == [False, False]
    assert no_start.thresholds[0] < 41.0 < cal.thresholds[0]
    assert any("log starts" in n for n in cal.notes)


# ----------------------------------------------------------------------------- support
def test_support_statement_for_a_known_duration() -> None:
    h = 2.5 / 60
    # −ln(0.1) / (2.5/60 h) / 30 = 1.842 per hour; 0.1 per hour needs 60·2.3026/3 = 46.05 min
    assert tail.support(h) == pytest.approx(1.8421, rel=1e-4)
    assert tail.minutes_needed(0.1) == pytest.approx(46.05, rel=1e-3)
    assert tail.support_statement(h, 0.1) == (
        "2.5 min of free motion bound a false-alarm rate no lower than 1.8 per hour at "
        "90 % confidence (with no alarm in them, 55 per hour; the tail fits reach at most "
        "30× below that); log ≥ 47 min of the robot's motions for 0.1 per hour (until then "
        "not promised; each threshold at least its widened value)")  # −ln(0.1)·60/2.5 = 55
    assert tail.support_statement(1.0, 0.1) == (
        "60.0 min of free motion bound a false-alarm rate no lower than 1 per ~13 h at "
        "90 % confidence (with no alarm in them, 2.3 per hour; the tail fits reach at most "
        "30× below that); 0.1 per hour is within it")


def test_widening_below_support_only() -> None:
    """A channel with too few clusters for a shape (6 in 2 min) is widened along ξ = 0.5
    below the supported rate, and not above it."""
    rng = np.random.default_rng(5)
    f = tf.fit_tail(rng.exponential(1.0, 6), 0.0, 2 / 60)
    assert f.xi_fixed and f.xi_max == tf.XI_MAX
    chans = tail.ChannelFits((f,), np.array([-np.inf]))
    rs = tail.support(f.hours)                          # 2.3 / (2/60) / 30 = 2.3 per hour
    above = tail.thresholds_for_rate(chans, 1.2 * rs)
    below = tail.thresholds_for_rate(chans, rs / 10)
    plain = tail.thresholds_for_rate(chans, rs / 10, widen=False)
    assert not above.any_widened and not above.below_support and below.below_support
    assert above.thresholds[0] == pytest.approx(tf.threshold_upper(f, 1.2 * rs))
    assert below.widened.tolist() == [True]
    assert below.thresholds[0] > plain.thresholds[0]
    step = tf.sigma_upper(f) * (10 ** 0.5 - 1) / 0.5
    assert below.thresholds[0] == pytest.approx(tf.threshold_upper(f, rs) + step)
    assert below.upper_total < below.rate               # wider than the fit asks for
    assert "log ≥ 20 min" in below.support_statement()   # 10 × the 2 min
    assert any("too few" in n for n in below.notes)


# ------------------------------------------------------------------------------ output
def test_table_gives_the_configs_thresholds_per_detector_and_joint() -> None:
    rng = np.random.default_rng(2)
    per = [tail.stack_detectors({"adaptive": x[:, :2], "static_loading": x[:, 2:]},
                                ("shoulder", "elbow"))
           for x in (free_log(rng, 3.0, (400.0,) * 4, (0.3, 0.3, 1.0, 1.0)) for _ in range(2))]
    cal = tail.calibrate_rate([x for x, _ in per], 0.01, names=per[0][1])
    assert cal.rate == tail.DEFAULT_FALSE_ALARMS_PER_HOUR
    tab = cal.table()
    assert tab == {"adaptive": {"shoulder": cal.thresholds[0], "elbow": cal.thresholds[1]},
                   "static_loading": {"shoulder": cal.thresholds[2],
                                      "elbow": cal.thresholds[3]}}
    assert tab["static_loading"]["elbow"] > tab["adaptive"]["elbow"]   # σ 1.0 vs 0.3
    text = "\n".join(cal.lines())
    assert "elbow/static_loading" in text and "min of free motion bound a false-alarm rate" in text


# ----------------------------------------------------------------- leave-one-log-out
def test_leave_one_log_out_rows_and_a_log_unlike_the_others() -> None:
    rng = np.random.default_rng(9)
    nu, sigma = (600.0,), (0.5,)
    logs = [free_log(rng, 3.0, nu, sigma) for _ in range(3)]
    odd = free_log(rng, 3.0, nu, (2.0,))                # another "motion": a wider tail
    rows = tail.leave_one_log_out([*logs, odd], 0.01, rates=(100.0, 300.0))
    assert [(r.log, r.rate) for r in rows] == [(k, r) for k in range(4) for r in (100, 300)]
    for r in rows:
        assert r.hours == pytest.approx(3 / 60)
        assert 0 < r.predicted < r.upper <= r.rate * (1 + 1e-3)   # < R: log-start floor
        keep = [lg for k, lg in enumerate([*logs, odd]) if k != r.log]
        thr = tail.calibrate_rate(keep, 0.01, r.rate).thresholds
        assert r.observed == tail.count_incidents([[*logs, odd][r.log]], thr, 0.01)
    for r in rows:   # alike logs: within their bound; the odd log: far above it
        lo = r.interval(0.9)[0]
        assert (lo > r.upper) == (r.log == 3)


def test_rates_and_minutes_as_printed() -> None:
    assert [tail.per_hour_text(x) for x in (197.6, 100.0, 62.4, 3.42, 0.047, 0.00123,
                                            9.9e-4, 1.7e-13, 0.0)] == [
        "198", "100", "62", "3.4", "0.047", "0.0012", "< 0.001", "< 0.001", "0"]
    assert [tail.at_most_text(x) for x in (2.94, 5e-5)] == ["≤ 2.9", "≤ 0.001"]
    assert [tail.minutes_text(x) for x in (60.0, 1.35, 1.0, 0.15, 0.0366)] == [
        "60.0", "1.4", "1.0", "0.15", "0.037"]
    assert tail.support_statement(0.0366 / 60, None).startswith(
        "0.037 min of free motion bound a false-alarm rate no lower than 126 per hour")


def test_calibration_text_says_what_each_kind_of_threshold_promises() -> None:
    rated = {"per_hour": 1.0, "confidence": 0.9, "predicted_per_hour": 0.42,
             "upper_per_hour": 1.0, "supported": True, "statement": "60 min ..."}
    assert calibration_text({"margin_rule": "leave-one-out", "false_alarm_rate": rated}) == (
        "set for 1 false alarm(s) per hour (predicted 0.42 false alarm(s) per hour, ≤ 1 at "
        "90 %, on motion like the calibration logs')")
    short = {**rated, "supported": False, "statement": "1.4 min supports at best 3.4"}
    assert calibration_text({"false_alarm_rate": short}).endswith(
        "), not supported by its free motion (1.4 min supports at best 3.4)")
    loo = {"confidence": 0.95, "predicted_per_hour": 161.4, "upper_per_hour": 409.4,
           "supported_per_hour": 3.4, "statement": "s"}
    assert calibration_text({"margin_rule": "leave-one-out", "false_alarm_rate": loo}) == (
        "leave-one-out, predicted 161 false alarm(s) per hour, ≤ 409 at 95 %, on motion like "
        "the calibration logs'")
    # a bound below what the free minutes support is the tail fit's extrapolation alone
    tiny = {**loo, "predicted_per_hour": 0.01, "upper_per_hour": 0.1}
    assert calibration_text({"margin_rule": "leave-one-out", "false_alarm_rate": tiny}
                            ).endswith("not supported by its free motion (s)")
    assert calibration_text({"margin_rule": "leave-one-out"}) == (
        "leave-one-out, no false-alarm rate recorded")
    # weak: one log, or a margin at its cap; under a rate the product's detectors are not
    # set by the margin, so only the others' caps count
    capped = {"adaptive": {"a": MAX_MARGIN}, "static_baseline": {"a": 1.0, "b": MAX_MARGIN}}
    assert calibration_text({"margin_rule": "fixed-single-log", "weak": True}).endswith(
        "; weak: one calibration log, a fixed 1.5× margin")
    assert calibration_text({"margin_rule": "leave-one-out", "weak": True, "margins": capped}
                            ).endswith("cap of 3× on adaptive, static_baseline")
    assert capped_detectors({"margins": capped, "false_alarm_rate": rated}) == [
        "static_baseline"]
    assert capped_detectors({"margins": {"adaptive": {"a": 2.99}}}) == []


def test_a_bound_only_the_tail_fits_give_is_said_to_be_one() -> None:
    """Known truth: 3 min of free motion with no alarm bound −ln(0.1) / 0.05 h = 46 per
    hour at 90 %; an upper bound of 7.4 per hour rests on the tail fits (noted, with both
    figures), one of 50 does not (no note)."""
    import math

    from impactcli.detect.tail import extrapolated_note

    zero = -math.log(0.1) / 0.05
    assert zero == pytest.approx(46.05, abs=0.01)
    note = extrapolated_note(7.4, 0.05, 0.9)
    assert note == ("the upper bound 7.4 per hour rests on the tail fits' extrapolation: "
                    "3.0 min of free motion with no alarm bound 46 per hour by themselves")
    assert extrapolated_note(50.0, 0.05, 0.9) is None
