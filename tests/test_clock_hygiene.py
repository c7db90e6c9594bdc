"""Time hygiene: one sample-rate estimator and gap rule (impactcli.clock), rows out of
time order (--repair-order), time units (--time-unit, the 20 Hz – 100 kHz check), the
calibration rate, and labels that start before the log."""

from __future__ import annotations

import dataclasses
import gzip
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

from impactcli.clock import check_calibrated_rate, gap_steps, sample_clock
from impactcli.errors import ConfigError, ImpactWarning, LogFormatError
from impactcli.logs import read_log, write_log
from impactcli.logs.repair import longest_increasing

from .cli_run import cli

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "sample_logs" / "csv"
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"
MS = 1_000_000


def _errors(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ln.startswith("impactcli: error:")]


def _sample(name: str = "assist_free_p2p") -> object:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        return read_log(SAMPLES / f"{name}.csv.gz")


def _old_gaps(t: np.ndarray) -> int:
    """What the median-step rule said before: steps > 1.5 median steps."""
    dt = np.diff(t)
    return int(np.sum(dt > 1.5 * np.median(dt)))


# ----------------------------------------------------------------- the estimator itself
def test_clean_grid_is_exact() -> None:
    k = np.arange(5000)
    for period_ns in (4 * MS, MS, 10 * MS):
        c = sample_clock(k * period_ns)
        assert c.period_s == period_ns * 1e-9 and c.jitter_s == 0.0
        assert c.gap_threshold_s == pytest.approx(1.5 * period_ns * 1e-9)
    # stamps rounded to the ns: the mean of the steps, not one of the two step lengths
    c = sample_clock(np.round(k * 1e9 / 300).astype(np.int64))
    assert c.sample_rate_hz == pytest.approx(300.0, rel=1e-9)


def test_jitter_dropped_samples_and_late_stamps_do_not_move_the_rate() -> None:
    rng = np.random.default_rng(1)
    n = 20_000
    grid = np.arange(n) * MS  # 1 kHz
    # host-clock jitter: the median step moved, the estimate does not
    jit = np.sort(grid + rng.normal(0, 0.12 * MS, n).astype(np.int64))
    assert sample_clock(jit).sample_rate_hz == pytest.approx(1000.0, rel=2e-3)
    assert gap_steps(jit)[0].size == 0
    assert _old_gaps(jit) > 0
    # 6 % of the samples dropped (2 ms steps) with the jitter: the median step is 1.5 % off
    drop = rng.random(n) < 0.06
    t = jit[~drop]
    assert 1e9 / np.median(np.diff(t)) == pytest.approx(985, abs=10)
    assert sample_clock(t).sample_rate_hz == pytest.approx(1000.0, rel=2e-3)
    # a late sample delivered with the next one (8 - 0.02 ms, then 0.02 ms) is jitter
    t = grid.copy()
    late = np.flatnonzero(rng.random(n) < 0.06)
    late = late[late < n - 1]
    t[late] = t[late + 1] - 20_000
    c = sample_clock(t)
    assert c.sample_rate_hz == 1000.0 and gap_steps(t, c)[0].size == 0
    assert _old_gaps(t) > 1000  # each was a "gap" before
    # ... also when rare (the step is not given back: rule (c))
    t = grid.copy()
    t[[100, 5000, 9000]] = t[[101, 5001, 9001]] - 20_000
    assert gap_steps(t)[0].size == 0 and _old_gaps(t) == 3


def test_steps_that_alternate_or_run_long_give_the_mean_spacing() -> None:
    """0.9/1.1 ms alternating: the median step is either (909 or 1111 Hz); the samples
    come at 1 kHz. A logger at 10 ms that is 12 ms late a fifth of the time (a real UR
    log's pattern) samples at 1 / mean spacing."""
    k = np.arange(10_000)
    t = np.cumsum(np.where(k % 2 == 0, 900_000, 1_100_000))
    assert sample_clock(t).sample_rate_hz == pytest.approx(1000.0, rel=1e-4)
    steps = np.where(np.random.default_rng(2).random(5000) < 0.2, 12 * MS, 10 * MS)
    t = np.concatenate(([0], np.cumsum(steps)))
    assert sample_clock(t).period_s == pytest.approx(steps.mean() * 1e-9, rel=1e-12)
    assert gap_steps(t)[0].size == 0


def test_gaps_are_long_steps_beyond_the_jitter() -> None:
    k = np.arange(10_000)
    grid = k * MS
    # a 50 ms hole is a gap; so is one dropped sample in an otherwise clean log
    t = np.concatenate([grid[:4000], grid[4000:] + 50 * MS])
    idx, lengths = gap_steps(t)
    assert idx.tolist() == [3999] and lengths.tolist() == pytest.approx([0.051])
    t = np.delete(grid, [2000, 7000])
    assert gap_steps(t)[0].tolist() == [1999, 6998]
    # a logger that drops 6 % of its samples: dropping is its timing (beyond 5 % of the
    # steps), not a gap each time; the 50 ms hole still is one
    rng = np.random.default_rng(3)
    t = grid[~(rng.random(k.size) < 0.06)]
    t = np.concatenate([t[:3000], t[3000:] + 50 * MS])
    c = sample_clock(t)
    assert c.sample_rate_hz == 1000.0 and c.gap_threshold_s == pytest.approx(0.003)
    idx, _ = gap_steps(t, c)
    assert 2999 in idx.tolist() and all(np.diff(t)[idx] >= 3 * MS)
    assert _old_gaps(t) > 300


def test_repeated_stamps_are_merged() -> None:
    t = np.array([0, 4, 4, 8, 12, 12, 16]) * MS
    c = sample_clock(t)
    assert c.n_repeated == 2 and c.period_s == 0.004
    assert np.isnan(sample_clock(np.array([5, 5])).period_s)


# ------------------------------------------- a host-stamped log, through inspect and detect
def _host_stamped(tmp_path: Path) -> tuple[Path, np.ndarray]:
    """assist_impacts (250 Hz, labelled impacts) as a host-side logger writes it: 6 % of
    the samples stamped late, with the next one (an 8 ms step, then 20 µs), and 6 % of the
    rows written twice."""
    log = _sample("assist_impacts")
    t = log.t_ns.copy()
    rng = np.random.default_rng(11)
    late = np.flatnonzero(rng.random(t.size) < 0.06)
    late = late[(late > 0) & (late < t.size - 1)]
    t[late] = log.t_ns[late + 1] - 20_000
    stamped = dataclasses.replace(log, t_ns=t)
    path = tmp_path / "host.csv"
    write_log(stamped, path)
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    twice = set((np.flatnonzero(rng.random(len(lines)) < 0.06)).tolist()) - {0}
    path.write_text("".join(ln + ln if i in twice else ln for i, ln in enumerate(lines)),
                    encoding="utf-8")
    return path, t


def test_host_stamped_log_reads_at_its_rate_without_gaps(tmp_path: Path) -> None:
    path, t = _host_stamped(tmp_path)
    assert _old_gaps(t) > 900  # what inspect and detect said before
    code, out, err = cli("inspect", str(path), "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["sample_rate_hz"] == 250.0 and d["sample_period_s"] == 0.004
    assert d["gaps"]["count"] == 0 and d["gaps"]["listed"] == []
    assert d["gaps"]["threshold_s"] == pytest.approx(3 * 0.004, rel=1e-2)
    assert any("exact duplicate sample(s)" in r for r in d["repairs"])
    code, out, err = cli("detect", str(path), "--config", str(CONFIG), "-o",
                         str(tmp_path / "out"))
    assert code == 0, err
    assert "time gap" not in err
    tl = json.loads((tmp_path / "out" / "host.timeline.json").read_text())
    assert tl["input"]["sample_rate_hz"] == 250.0
    assert tl["incidents"] and not any("gap" in w for w in tl["warnings"])


# ----------------------------------------------------------------- rows out of time order
def _grid_csv(tmp_path: Path, name: str = "order.csv") -> tuple[Path, list[str]]:
    log = _sample()
    path = tmp_path / name
    write_log(log, path)
    return path, path.read_text(encoding="utf-8").splitlines(keepends=True)


def test_rows_out_of_order_are_an_error_naming_the_row_and_the_option(tmp_path: Path) -> None:
    path, lines = _grid_csv(tmp_path)
    # line numbers are 1-based with the header on line 1: data row r is line r + 1
    lines[101], lines[102] = lines[102], lines[101]
    path.write_text("".join(lines), encoding="utf-8")
    code, _, err = cli("detect", str(path), "-o", str(tmp_path / "out"))
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {path}: column 'time', row 102 (line 103): time is decreasing "
        "(404000000 ns then 400000000 ns); it must be strictly increasing: rows written out "
        "of order are repaired by --repair-order (keeps the longest increasing run of "
        "stamps, drops the other rows, warned)"]
    with pytest.raises(LogFormatError, match="--repair-order"):
        read_log(path)


def test_repair_order_keeps_the_longest_increasing_run(tmp_path: Path) -> None:
    path, lines = _grid_csv(tmp_path)
    lines[101], lines[102] = lines[102], lines[101]  # two rows swapped
    moved = lines.pop(501)  # row 500 (t = 2.000 s) written ten rows late
    lines.insert(511, moved)
    path.write_text("".join(lines), encoding="utf-8")
    n = len(lines) - 1
    want = (f"{path}: dropped 2 row(s) (2 out of time order; first at row 101 (line 102)), "
            f"keeping the longest increasing run of stamps ({n - 2} rows; --repair-order)")
    with pytest.warns(ImpactWarning) as rec:
        log = read_log(path, repair_order=True)
    assert want in [str(w.message) for w in rec]
    assert log.n_samples == n - 2 and log.source.repairs == (want,)
    assert np.all(np.diff(log.t_ns) > 0) and 2_000_000_000 not in log.t_ns
    # the same through the command line; the option is recorded in the timeline
    code, _, err = cli("detect", str(path), "--repair-order", "--config", str(CONFIG),
                       "-o", str(tmp_path / "out"))
    assert code == 0, err
    assert f"impactcli: warning: {want}" in err.splitlines()
    tl = json.loads((tmp_path / "out" / "order.timeline.json").read_text())
    assert tl["input"]["read_options"] == {"repair_order": True}


def test_a_repeated_stamp_with_other_values(tmp_path: Path) -> None:
    path, lines = _grid_csv(tmp_path)
    stamp = lines[200].split(",", 1)[0]
    lines[201] = stamp + "," + lines[201].split(",", 1)[1]  # row 200 stamped like row 199
    path.write_text("".join(lines), encoding="utf-8")
    code, _, err = cli("detect", str(path), "-o", str(tmp_path / "out"))
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {path}: column 'time', row 201 (line 202): time is repeated "
        "(796000000 ns, as on row 200 (line 201)) with other values; it must be strictly "
        "increasing: --repair-order keeps the last row of each stamp and drops rows out of "
        "time order (warned)"]
    with pytest.warns(ImpactWarning, match=r"dropped 1 row\(s\) \(1 with a repeated stamp; "
                                           r"first at row 200 \(line 201\)\)"):
        log = read_log(path, repair_order=True)
    later = [float(x) for x in lines[201].split(",")[1:]]
    i = int(np.flatnonzero(log.t_ns == 796_000_000)[0])
    assert log.position[i, 0] == later[0]  # the last row written for that stamp


def test_longest_increasing_matches_brute_force() -> None:
    rng = np.random.default_rng(5)
    for _ in range(200):
        t = rng.integers(0, 12, rng.integers(1, 14))
        keep = longest_increasing(t)
        assert np.all(np.diff(t[keep]) > 0)
        best = [1] * t.size  # O(N^2) longest strictly increasing subsequence
        for i in range(t.size):
            for j in range(i):
                if t[j] < t[i]:
                    best[i] = max(best[i], best[j] + 1)
        assert keep.size == max(best)
    big = np.arange(300_000)
    big[1000:1010] = big[1000:1010][::-1]
    assert longest_increasing(big).size == 300_000 - 9


# ------------------------------------------------------------------------------ time units
def _time_csv(tmp_path: Path, name: str, values: list[str], n: int | None = None) -> Path:
    """The sample log with its time column replaced by ``values``."""
    path, lines = _grid_csv(tmp_path, name)
    rows = lines[1:] if n is None else lines[1:n + 1]
    body = [v + "," + ln.split(",", 1)[1] for v, ln in zip(values, rows, strict=True)]
    path.write_text(lines[0] + "".join(body), encoding="utf-8")
    return path


def test_time_in_ms_is_an_error_naming_the_rate_and_the_option(tmp_path: Path) -> None:
    k = np.arange(10_001)
    path = _time_csv(tmp_path, "ms.csv", [f"{4 * i}" for i in k])
    code, _, err = cli("inspect", str(path))
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {path}: column 'time': the implied sample rate is 0.25 Hz, "
        "outside 20 Hz – 100 kHz; read in s, it looks like ms (250 Hz): give the time unit "
        "with --time-unit s|ms|us|ns (or 'unit' under 'time' in a channel map)"]
    code, _, err = cli("detect", str(path), "--time-unit", "ms", "--config", str(CONFIG),
                       "-o", str(tmp_path / "out"))
    assert code == 0, err
    tl = json.loads((tmp_path / "out" / "ms.timeline.json").read_text())
    assert tl["input"]["sample_rate_hz"] == 250.0 and tl["input"]["duration_s"] == 40.0
    assert tl["input"]["read_options"] == {"time_unit": "ms"}
    assert read_log(path, time_unit="ms").t_ns[-1] == 40 * 10**9


def test_time_in_ns_read_as_seconds(tmp_path: Path) -> None:
    """Short: the rate says ns; long: the time overflows the ns clock first (it used to
    wrap round to a negative duration)."""
    short = _time_csv(tmp_path, "ns.csv", [str(4_000_000 * i) for i in range(1000)], n=1000)
    code, _, err = cli("inspect", str(short))
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {short}: column 'time': the implied sample rate is 2.5e-07 Hz, "
        "outside 20 Hz – 100 kHz; read in s, it looks like ns (250 Hz): give the time unit "
        "with --time-unit s|ms|us|ns (or 'unit' under 'time' in a channel map)"]
    assert read_log(short, time_unit="ns").sample_rate_hz == 250.0
    long = _time_csv(tmp_path, "nslong.csv", [str(4_000_000 * i) for i in range(10_001)])
    code, _, err = cli("detect", str(long), "-o", str(tmp_path / "out"))
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {long}: column 'time', row 2307 (line 2308): time 9.224e+09 s is "
        "beyond the clock's range (±292 years in ns); read in s, it looks like ns (250 Hz): "
        "give the time unit with --time-unit s|ms|us|ns (or 'unit' under 'time' in a "
        "channel map)"]


def test_a_rate_above_100_khz_and_time_unit_misuse(tmp_path: Path) -> None:
    path = _time_csv(tmp_path, "us.csv", [f"{4e-6 * i:.9f}" for i in range(3000)], n=3000)
    code, _, err = cli("inspect", str(path))
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {path}: column 'time': the implied sample rate is 250 kHz, "
        "outside 20 Hz – 100 kHz; read in s: give the time unit with --time-unit s|ms|us|ns "
        "(or 'unit' under 'time' in a channel map)"]
    ms = _time_csv(tmp_path, "ms.csv", [str(4 * i) for i in range(3000)], n=3000)
    code, _, err = cli("detect", str(ms), "--time-unit", "us", "-o", str(tmp_path / "o"))
    assert code == 3
    assert _errors(err) == [
        f"impactcli: error: {ms}: column 'time': the implied sample rate is 250 kHz, outside "
        "20 Hz – 100 kHz; read in us, it looks like ms (250 Hz): give the time unit with "
        "--time-unit s|ms|us|ns (or 'unit' under 'time' in a channel map)"]
    ns = tmp_path / "tns.csv"
    ns.write_text("time_ns,j.position,j.torque\n0,1,2\n4000000,1,2\n8000000,1,3\n")
    # the user's unit wins over the name, warned; read in ms, the rate check refuses it
    with pytest.warns(ImpactWarning, match="--time-unit ms given: column 'time_ns' is read "
                                           "in ms, not in ns as its name says"), \
            pytest.raises(LogFormatError, match=r"the sample rate is 0\.00025 Hz"):
        read_log(ns, time_unit="ms")
    mcap = tmp_path / "x.mcap"
    write_log(_sample(), mcap)
    code, _, err = cli("detect", str(mcap), "--time-unit", "ms", "-o", str(tmp_path / "o"))
    assert code == 3
    assert _errors(err) == [f"impactcli: error: {mcap}: --time-unit applies to CSV and .npz "
                            "logs only (MCAP and bag stamps are ns)"]


def test_a_channel_maps_unit_and_time_unit_over_it(tmp_path: Path) -> None:
    path = tmp_path / "dump.csv"
    k = np.arange(400)
    path.write_text("".join(f"{4 * i},{np.sin(i / 50):.6f},{np.cos(i / 40):.6f}\n" for i in k))
    cmap = tmp_path / "map.yaml"
    cmap.write_text('schema_version: "1.0"\nname: dump\nformat: csv\n'
                    "csv: {header: false}\ntime: {column: 0, unit: ms}\n"
                    "joints:\n  - {name: j, position: 1, torque: 2}\n")
    assert read_log(path, channel_map=cmap).sample_rate_hz == 250.0
    with pytest.raises(LogFormatError) as e:
        read_log(path, channel_map=cmap, time_unit="us")  # --time-unit replaces the map's
    assert str(e.value) == (
        f"{path}: column 0: the implied sample rate is 250 kHz, outside 20 Hz – 100 kHz; "
        "read in us, it looks like ms (250 Hz): give the time unit with --time-unit "
        "s|ms|us|ns (or 'unit' under 'time' in a channel map)")


# --------------------------------------------------------------- the calibration's rate
def test_calibrate_records_the_rate_and_detect_refuses_another(tmp_path: Path) -> None:
    """Thresholds belong to the rate they were calibrated at: a log at another rate is a
    data error naming both rates and what to do, in detect and report alike."""
    cfg = tmp_path / "cal.yaml"
    code, _, err = cli("calibrate", str(SAMPLES / "assist_free_p2p.csv.gz"), "--generator",
                       "logged_external", "-o", str(cfg))
    assert code == 0, err
    doc = yaml.safe_load(cfg.read_text())
    assert doc["calibration"]["sample_rate_hz"] == 250.0
    lines = gzip.decompress((SAMPLES / "assist_free_multisine.csv.gz").read_bytes()).decode()
    # a free log decimated to 125 Hz
    path = tmp_path / "slow.csv"
    rows = lines.splitlines(keepends=True)
    path.write_text(rows[0] + "".join(rows[1::2]), encoding="utf-8")
    expected = (f"impactcli: error: {path}: sampled at 125 Hz, but its config ({cfg}) was "
                "calibrated at 250 Hz (tolerance ±10%): its thresholds belong to that rate; "
                "calibrate on logs at 125 Hz, or run without --config (uncalibrated)\n")
    code, out, err = cli("detect", str(path), "--config", str(cfg), "-o", str(tmp_path / "o"))
    assert (code, err) == (3, expected), out
    assert not (tmp_path / "o" / "slow.timeline.json").exists()
    code, _, err = cli("report", str(path), "--config", str(cfg), "-o",
                       str(tmp_path / "r.html"))
    assert code == 3 and "calibrated at 250 Hz" in err, err
    code, _, err = cli("detect", str(SAMPLES / "assist_free_multisine.csv.gz"), "--config",
                       str(cfg), "-o", str(tmp_path / "o2"))
    assert code == 0 and "calibrated at" not in err


def test_check_calibrated_rate_tolerance() -> None:
    check_calibrated_rate(96.3, 100.0, "x")  # the same logger, a little late
    check_calibrated_rate(500.0, None, "x")  # an older config records no rate
    with pytest.raises(ConfigError, match="sampled at 500 Hz, but config was calibrated "
                                          "at 1000 Hz"):
        check_calibrated_rate(500.0, 1000.0, "x")
    with pytest.raises(ConfigError, match="sampled at 30 Hz, but config was calibrated at "
                                          "990 Hz"):
        check_calibrated_rate(30.0, 990.0, "x.bag")  # a ROS 1 bag against a 1 kHz config


# ----------------------------------------------------------- labels against the log's time
def test_labels_before_the_log_are_warned_about(tmp_path: Path) -> None:
    code, _, err = cli("detect", str(SAMPLES / "assist_impacts.csv.gz"), "--config",
                       str(CONFIG), "-o", str(tmp_path / "out"))
    assert code == 0, err
    labels = json.loads((SAMPLES / "assist_impacts.labels.json").read_text())
    labels["events"] = [dict(labels["events"][0], start=-3.5, end=-2.0), *labels["events"]]
    lab = tmp_path / "shifted.labels.json"
    lab.write_text(json.dumps(labels))
    code, _, err = cli("evaluate", str(tmp_path / "out" / "assist_impacts.timeline.json"),
                       "--labels", str(lab))
    assert code == 0, err
    assert (f"impactcli: warning: {lab}: 1 contact(s) start before the log's first sample, "
            "first at -3.5 s: in its warm-up, not counted (labels of another log?)"
            ) in err.splitlines()
