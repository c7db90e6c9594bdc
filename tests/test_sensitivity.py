"""impactcli sensitivity: the Table II study, the soak's bound, zero-false-alarm selection, CLI."""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.quality.match import EVALUATED
from impactcli.schema import load_schema
from impactcli.study.aggregate import poisson_upper_95, summarize, zero_fa_index
from impactcli.study.arms import amplitudes, case_scenario, the_robot
from impactcli.study.spec import PAPER_ADAPTIVE_N, SOAK_FAMILIES, StudySpec
from impactcli.study.tables import TABLE_DETECTORS, format_markdown, format_text, table_rows
from impactcli.study.tasks import (
    CalibOutcome,
    CalibTask,
    CaseOutcome,
    CaseTask,
    ContactRecord,
    SoakOutcome,
    SoakTask,
    run_calibration,
    run_case,
    run_soak,
)

TINY = StudySpec.quick(stiffnesses=(10.12,), forces_n=(8.0,), impacts_per_case=2,
                       soak_run_s=30.0, calib_run_s=30.0, lead_in_s=6.0)


@pytest.fixture(scope="module")
def calib() -> CalibOutcome:
    return run_calibration(CalibTask("assist_like", TINY))


# ---------------------------------------------------------------------------------------
# the 3/T bound and the zero-false-alarm selection


def test_zero_alarms_bound_is_3_over_T() -> None:
    for hours in (0.5, 1.0, 4.0):
        ub = poisson_upper_95(0, hours)
        assert ub is not None
        assert ub == pytest.approx(3.0 / hours, rel=2e-3)  # -ln(0.05) = 2.9957
        assert ub == pytest.approx(-math.log(0.05) / hours, rel=1e-9)


def test_poisson_bound_known_values_and_monotonic() -> None:
    # one event: chi2_0.95(4) / 2 = 4.7439
    assert poisson_upper_95(1, 1.0) == pytest.approx(4.7439, abs=1e-3)
    vals = [poisson_upper_95(n, 2.0) for n in range(6)]
    assert all(b is not None and a is not None and b > a for a, b in itertools.pairwise(vals))
    assert poisson_upper_95(3, 0.0) is None


def test_zero_fa_index_on_hand_built_sweeps() -> None:
    # counts at ascending scales: a lone silent scale below a noisy one is not trusted
    assert zero_fa_index([9, 4, 0, 1, 0, 0]) == 4
    assert zero_fa_index([0, 0, 0]) == 0
    assert zero_fa_index([3, 2, 1]) is None
    assert zero_fa_index([5, 0]) == 1


def _contact(k: float, force: float, delays: dict[str, tuple[float, ...]]) -> ContactRecord:
    return ContactRecord("assist_like", k, 0.2, 4.0, 1, 10.0, force, 0.3, delays,
                         dict.fromkeys(EVALUATED, 1.0))


def test_summarize_matched_scale_and_forces_on_hand_built_data() -> None:
    """Scales 0.5, 1, 2: the soak false-alarms at 0.5 for every detector and at 1 for
    static_loading; so adaptive is matched at 1, static_loading at 2."""
    spec = replace(TINY, scales=(0.5, 1.0, 2.0), stiffnesses=(10.12, 2.12))
    nan = float("nan")
    fa = {"adaptive": (4, 0, 0), "static_loading": (7, 2, 0), "static_baseline": (1, 0, 0),
          "product": (9, 2, 0)}
    soak = SoakOutcome("assist_like", "task", 0, 1, 3603.0, 3.0, 3600.0, fa, 0)
    # contacts: adaptive detects at scale 1 the 6 N and 12 N ones; static_loading at scale 2
    # only the 12 N one, at scale 1 all three
    contacts = (
        _contact(10.12, 3.0, {"adaptive": (0.02, nan, nan), "static_loading": (0.03, 0.03, nan),
                              "static_baseline": (nan,) * 3, "product": (0.02, 0.03, nan)}),
        _contact(10.12, 6.0, {"adaptive": (0.02, 0.02, nan), "static_loading": (0.03, 0.03, nan),
                              "static_baseline": (nan,) * 3, "product": (0.02, 0.02, nan)}),
        _contact(2.12, 12.0, {"adaptive": (0.02, 0.02, 0.03), "static_loading": (0.05, 0.05, 0.06),
                              "static_baseline": (0.01, 0.01, nan), "product": (0.02, 0.02, 0.03)}),
    )
    case = CaseOutcome("assist_like", 10.12, 0.2, 1, contacts, 0, 36.0,
                       dict.fromkeys(EVALUATED, (0, 0, 0)), {})
    calib = CalibOutcome("assist_like", _dummy_config(), ("x",), {}, {})
    s = summarize(spec, [calib], [soak], [case])
    v = s["variants"][0]
    m = v["settings"]["matched"]
    assert m["adaptive"]["scale"] == 1.0 and m["static_loading"]["scale"] == 2.0
    assert m["static_baseline"]["scale"] == 1.0
    assert m["adaptive"]["soak_false_alarms_per_hour_upper95"] == pytest.approx(2.9957, abs=1e-3)
    a = m["adaptive"]["all"]
    assert (a["detected"], a["min_detected_force_n"], a["all_detected_above_n"]) == (2, 6.0, 3.0)
    ld = m["static_loading"]["all"]
    assert (ld["detected"], ld["min_detected_force_n"]) == (1, 12.0)
    assert ld["all_detected_above_n"] == 6.0
    assert m["adaptive"]["by_stiffness"]["10.12"]["min_detected_force_n"] == 6.0
    assert m["adaptive"]["by_stiffness"]["2.12"]["all_detected_above_n"] is None
    c = v["settings"]["calibrated"]
    assert c["static_loading"]["scale"] == 1.0 and c["static_loading"]["soak_false_alarms"] == 2
    assert c["static_loading"]["soak_false_alarms_per_hour"] == pytest.approx(2.0)
    verdict = v["verdict"]
    assert verdict["adaptive_helps"] is True and "YES" in verdict["text"]
    assert verdict["adaptive_only"] == 1 and verdict["static_loading_only"] == 0
    assert verdict["paired_delay_gain_s"] == pytest.approx(0.04)  # 0.06 (scale 2) - 0.02 (scale 1)
    # ROC rows ascend in scale and carry the soak counts
    assert [r["scale"] for r in v["roc"]["adaptive"]] == [0.5, 1.0, 2.0]
    assert [r["soak_false_alarms"] for r in v["roc"]["static_loading"]] == [7, 2, 0]


def _dummy_config():  # type: ignore[no-untyped-def]
    from impactcli.config import DetectorConfig

    return DetectorConfig()


def test_table2_structure_on_hand_built_summary() -> None:
    spec = replace(TINY, scales=(0.5, 1.0, 2.0), stiffnesses=(10.12, 5.93, 2.12))
    fa = dict.fromkeys(EVALUATED, (1, 0, 0))
    soak = SoakOutcome("assist_like", "task", 0, 1, 1800.0, 3.0, 1797.0, fa, 0)
    cases = [CaseOutcome("assist_like", k, 0.2, 1,
                         (_contact(k, 5.0, dict.fromkeys(EVALUATED, (0.02, 0.02, 0.02))),),
                         0, 30.0, dict.fromkeys(EVALUATED, (0, 0, 0)), {})
             for k in spec.stiffnesses]
    s = summarize(spec, [CalibOutcome("assist_like", _dummy_config(), ("x",), {}, {})],
                  [soak], cases)
    v = s["variants"][0]
    rows = table_rows(v, "calibrated")
    assert rows[0][:5] == ["Detector", "Scale", "Environment stiffness (N/mm)",
                           "Minimal detected force (N)", "Equivalent mass (kg)"]
    assert rows[0][-1] == "Paper (N)"
    assert len(rows) == 1 + len(TABLE_DETECTORS) * 3
    adaptive = rows[1:4]
    assert [r[2] for r in adaptive] == ["k = 10.12", "k = 5.93", "k = 2.12"]
    assert [float(r[-1]) for r in adaptive] == [PAPER_ADAPTIVE_N[k] for k in (10.12, 5.93, 2.12)]
    assert adaptive[0][3] == "5.00" and adaptive[0][4] == f"{5.0 / 9.81:.3f}"
    assert all(r[-1] == "> 20" for r in rows[4:7])  # static threshold v0
    txt = format_text(s)
    assert "TABLE II (reproduced)" in txt and "thresholds matched" in txt
    md = format_markdown(s, "impactcli sensitivity --quick")
    assert "impactcli sensitivity --quick" in md
    assert md.count("| Detector | Scale | Environment stiffness") == 2  # calibrated, matched
    assert "Detection vs soak false alarms" in md


# ---------------------------------------------------------------------------------------
# the simulated study itself (tiny)


def test_the_robot_is_one_robot_per_seed() -> None:
    a, b, c = the_robot("assist_like", 0), the_robot("assist_like", 0), the_robot("assist_like", 1)
    assert a == b
    assert a.link_masses != c.link_masses
    nominal = the_robot("assist_like", 0, uncertainty=0.0)
    ratios = [x / y for x, y in zip(a.stiffness, nominal.stiffness, strict=True)]
    assert all(abs(r - 1) <= 0.2 + 1e-12 for r in ratios)


def test_amplitude_sets_impact_speed_and_force() -> None:
    """Larger triangle amplitude (fixed period) → faster impact and larger peak force."""
    from impactcli.sim import simulate

    arm = the_robot("assist_like", 0)
    amps = amplitudes("assist_like", (2.0, 24.0))
    peaks, speeds = [], []
    for a in amps:
        sim = simulate(case_scenario(arm, 10.12, a, TINY), seed=3)
        ev = [e for e in sim.labels.events if e.kind == "impact"]
        assert len(ev) == TINY.impacts_per_case
        peaks.append(max(e.peak_force for e in ev))
        speeds.append(min(e.extra["tip_speed_m_s"] for e in ev))
        # no contact before the elastomer is slid in (after the lead-in)
        assert min(e.start for e in ev) > TINY.lead_in_s
    assert speeds[1] > 2 * speeds[0] and peaks[1] > 2 * peaks[0]


def test_case_and_soak_deterministic(calib: CalibOutcome) -> None:
    amp = amplitudes("assist_like", (8.0,))[0]
    task = CaseTask("assist_like", 10.12, amp, 8.0, 0, TINY, calib.config)
    a, b = run_case(task), run_case(task)
    assert a == b or repr(a) == repr(b)
    assert len(a.contacts) == TINY.impacts_per_case
    other = run_case(replace(task, seed_index=1))
    assert other.seed != a.seed
    assert [c.peak_force for c in other.contacts] != [c.peak_force for c in a.contacts]
    s1 = run_soak(SoakTask("assist_like", "trapezoid", 0, TINY, calib.config))
    s2 = run_soak(SoakTask("assist_like", "trapezoid", 0, TINY, calib.config))
    assert s1 == s2
    # false alarms can only fall as the threshold scale rises... per scale counts exist
    assert all(len(v) == len(TINY.scales) for v in s1.false_alarms.values())
    assert s1.free_s == pytest.approx(TINY.soak_run_s - s1.warmup_end_s, abs=0.01)


def test_calibration_covers_every_family_without_payload(calib: CalibOutcome) -> None:
    assert len(calib.runs) == len(SOAK_FAMILIES)
    assert calib.config.calibration.calibrated
    assert calib.config.calibration.margin_rule == "leave-one-out"
    th = calib.config.thresholds
    assert set(th.v_stat) == {"shoulder", "elbow"} and all(v > 0 for v in th.vL.values())


# ---------------------------------------------------------------------------------------
# CLI


def _run(args: list[str]):  # type: ignore[no-untyped-def]
    return CliRunner().invoke(main, ["sensitivity", *args])


@pytest.mark.parametrize("args", [["--stiffness", "abc"], ["--stiffness", "-1"],
                                  ["--arm", "nope"], ["--soak-minutes", "0"],
                                  ["--jobs", "0"], ["--case-seeds", "0"]])
def test_cli_bad_options_exit_2(args: list[str]) -> None:
    r = _run(args)
    assert r.exit_code == 2, r.output


def test_cli_tiny_run_json_valid(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import jsonschema

    md = tmp_path / "t2.md"
    out = tmp_path / "s.json"
    r = _run(["--quick", "--stiffness", "10.12", "--forces", "8", "--soak-minutes", "0.5",
              "--json", str(out), "--markdown", str(md)])
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    jsonschema.validate(doc, load_schema("sensitivity"))
    v = doc["variants"][0]
    assert v["cases"]["n_contacts"] == 2
    assert v["soak"]["hours_after_warmup"] == pytest.approx(4 * (30 - 3) / 3600, rel=0.2)
    assert "TABLE II (reproduced)" in r.output
    assert "Table II, reproduced" in md.read_text()
    assert np.isfinite(doc["wall_time_s"])


def test_soak_counts_an_alarm_stuck_on_since_warmup() -> None:
    """A detector above its threshold from the start (stuck on) is one false alarm, not
    silence; alarms ending inside the warm-up are not counted; later bursts each count."""
    from impactcli.study.tasks import soak_false_alarms

    t = np.arange(1000) * 0.01  # 10 s, warm-up until 3 s
    quiet = np.full((1000, 2), 0.5)
    stuck = np.full((1000, 2), 2.0)  # above scale 1 everywhere
    bursts = quiet.copy()
    bursts[100:120, 0] = 3.0  # in warm-up only: not counted
    bursts[500:510, 1] = 3.0  # after warm-up
    bursts[800:805, 0] = 1.5  # after warm-up, only above scales < 1.5
    ratios = {"adaptive": bursts, "static_loading": stuck, "static_baseline": quiet}
    fa = soak_false_alarms(ratios, t, 3.0, (0.4, 1.0, 2.5, 5.0), 0.1, 0.0)
    assert fa["static_loading"] == (1, 1, 0, 0)
    assert fa["static_baseline"] == (1, 0, 0, 0)
    assert fa["adaptive"] == (1, 2, 1, 0)  # at 0.4 the whole log is one alarm
    assert fa["product"] == (1, 1, 1, 0)


def test_verdict_no_when_adaptive_adds_nothing() -> None:
    """static_loading catches every impact adaptive catches, earlier: the verdict is NO."""
    spec = replace(TINY, scales=(0.5, 1.0, 2.0), stiffnesses=(10.12,))
    nan = float("nan")
    soak = SoakOutcome("assist_like", "task", 0, 1, 3603.0, 3.0, 3600.0,
                       dict.fromkeys(EVALUATED, (3, 0, 0)), 0)
    contacts = (
        _contact(10.12, 4.0, {"adaptive": (0.02, nan, nan), "static_loading": (0.02, 0.03, 0.04),
                              "static_baseline": (nan,) * 3, "product": (0.02, 0.03, 0.04)}),
        _contact(10.12, 9.0, {"adaptive": (0.02, 0.05, nan), "static_loading": (0.02, 0.03, 0.03),
                              "static_baseline": (nan,) * 3, "product": (0.02, 0.03, 0.03)}),
    )
    case = CaseOutcome("assist_like", 10.12, 0.2, 1, contacts, 0, 36.0,
                       dict.fromkeys(EVALUATED, (0, 0, 0)), {})
    s = summarize(spec, [CalibOutcome("assist_like", _dummy_config(), ("x",), {}, {})],
                  [soak], [case])
    v = s["variants"][0]["verdict"]
    assert v["adaptive_helps"] is False and v["text"].startswith("assist_like: NO")
    assert v["adaptive_only"] == 0 and v["static_loading_only"] == 1
    assert v["paired_delay_gain_s"] == pytest.approx(-0.02)  # 0.03 - 0.05: adaptive later
