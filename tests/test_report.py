"""The safety-audit report (HTML + JSON) built from synthetic results with known events."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from impactcli.detect.force import planar_jacobian, smallest_caught_force
from impactcli.errors import UsageProblem
from impactcli.logs import log_stem
from impactcli.outputs import report, svgplot
from impactcli.outputs.report import GUARD_S, verdict_text
from impactcli.run.report_inputs import auto_labels, pair_labels
from impactcli.schema import load_schema
from impactcli.types import ContactLabel, DetectionResult, Event, Labels, LogSource

from .fakes import build_report, fake_result, margins, render, with_incidents, write_fake_report

EVENTS_CFG = {
    "adaptive": {"forgetting_factor": 0.999},
    "events": {"merge_gap_s": 0.05, "min_duration_s": 0.0},
}


def result_named(path: str, sha: str, **changes: object) -> DetectionResult:
    """fake_result() with its log's provenance replaced (and any result field changed)."""
    r = fake_result()
    log = dataclasses.replace(r.log, source=LogSource(path, sha, "csv"))
    return dataclasses.replace(r, log=log, **changes)  # type: ignore[arg-type]


def validate(doc: dict) -> None:
    jsonschema.Draft202012Validator(load_schema("report")).validate(doc)


def test_html_is_self_contained() -> None:
    html, _ = build_report([fake_result()])
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*(https?:)?//""", html, re.I)
    assert "<script" not in html.lower()
    assert "<link" not in html.lower()
    assert "@import" not in html
    assert all(u.startswith("#") for u in re.findall(r"url\(([^)]*)\)", html))
    assert "http:" not in html and "https:" not in html  # no URL at all
    hrefs = re.findall(r'href="([^"]*)"', html)
    assert hrefs and all(h.startswith("#") for h in hrefs)
    ids = re.findall(r'\bid="([^"]+)"', html)
    assert len(ids) == len(set(ids)), "element ids must be unique"
    for target in hrefs:
        assert target[1:] in ids
    assert "@media print" in html and "break-before: page" in html


def test_html_has_every_event_sha_and_caveats() -> None:
    sha = "5e" * 32
    r = result_named("/data/arm_run3.csv", sha, reference_source="measured")
    html, doc = build_report([r])
    assert sha in html
    assert "arm_run3" in html
    n = len(r.events)
    for k, e in enumerate(r.events, 1):
        row = re.search(rf'<tr[^>]*id="log1-ev{k}">(.*?)</tr>', html)
        assert row, f"event {k} missing from the table"
        assert f"{e.t_start:.3f}" in row.group(1) and e.detector in row.group(1)
        assert ", ".join(e.joints) in row.group(1)
    assert not re.search(rf'id="log1-ev{n + 1}"', html)
    assert "UNCALIBRATED" in html
    assert "MEASURED position" in html
    assert "Warm-up: the first 1.000 s" in html
    codes = {c["code"] for c in doc["logs"][0]["caveats"]}
    assert {"uncalibrated", "reference-missing", "warmup", "model-from-log"} <= codes
    # a run without incidents (made before they existed) says so, shows its events
    # openly and plots each group of alarms
    sec = doc["logs"][0]
    assert sec["incidents_known"] is False and sec["incidents"] == []
    assert "records no incidents" in sec["verdict"]
    assert "no-incidents" in {c["code"] for c in sec["could_not_see"]}
    assert '<details class="events" id="log1-events" open>' in html
    assert html.count("<figcaption>Alarms") == 3


@pytest.mark.parametrize(("rule", "margins", "says"), [
    ("leave-one-out", {"adaptive": {"j1": 1.1}, "static_baseline": {"j1": 3.0}},
     "margin hit its cap of 3× (static_baseline)"),
    ("fixed-single-log", {"adaptive": {"j1": 1.5}}, "a single collision-free log"),
])
def test_weak_calibration_caveat_says_why(rule: str, margins: dict, says: str) -> None:
    cfg = dict(EVENTS_CFG, calibration={"calibrated": True, "margin_rule": rule,
                                        "weak": True, "margins": margins})
    r = result_named("run.csv", "1" * 64, calibrated=True, model_source="config", config=cfg)
    _, doc = build_report([r])
    text = {c["code"]: c["text"] for c in doc["logs"][0]["caveats"]}["weak-calibration"]
    assert text.startswith(f"Weak calibration ({rule}): ") and says in text
    assert ("single" in text) == (rule == "fixed-single-log")


def test_a_long_event_gets_a_caveat() -> None:
    """A 12 s static_loading event (a persistent load) is called out; short ones are not."""
    r = fake_result()
    assert "long-event" not in {c["code"] for c in build_report([r])[1]["logs"][0]["caveats"]}
    long = dataclasses.replace(r.events[0], detector="static_loading", t_start=1.0,
                               t_end=13.0, in_warmup=False)
    _, doc = build_report([dataclasses.replace(r, events=(*r.events, long))])
    text = {c["code"]: c["text"] for c in doc["logs"][0]["caveats"]}["long-event"]
    assert "static_loading, 1.0–13.0 s" in text and "--model-from-log" in text


def test_calibrated_run_has_no_uncalibrated_caveat() -> None:
    cfg = dict(
        EVENTS_CFG,
        calibration={
            "calibrated": True,
            "margin_rule": "leave-one-out",
            "weak": False,
            "logs": [{"path": "free.csv", "sha256": "c" * 64}],
        },
    )
    r = result_named("run.csv", "1" * 64, calibrated=True, model_source="config", config=cfg)
    html, doc = build_report([r])
    codes = {c["code"] for c in doc["logs"][0]["caveats"]}
    assert "uncalibrated" not in codes and "model-from-log" not in codes
    assert "reference-missing" not in codes
    assert "UNCALIBRATED" not in html
    assert "free.csv" in html and "leave-one-out" in html
    assert (
        doc["summary"][0]["calibrated"] is True and doc["summary"][0]["online_equivalent"] is True
    )


def test_json_validates_and_is_byte_identical(tmp_path: Path) -> None:
    labels = Labels((ContactLabel(3.99, 4.12, 12.0, "impact", 2),), 250.0, "a.labels.json")
    runs = []
    for k in range(2):
        r = result_named("a.csv", "a" * 64, config=EVENTS_CFG)
        h, j = tmp_path / f"r{k}.html", tmp_path / f"r{k}.json"
        write_fake_report([r, result_named("b.csv", "b" * 64)], h, j, labels=[labels, None])
        runs.append((h.read_bytes(), j.read_bytes()))
    assert runs[0][1] == runs[1][1]
    assert runs[0][0] == runs[1][0]
    doc = json.loads(runs[0][1])
    validate(doc)
    assert not list(tmp_path.glob("*.part"))


def test_multi_log_summary_table() -> None:
    stems = ["robotA_mon", "robotA_tue", "robotB_mon"]
    results = [result_named(f"/fleet/{s}.csv.gz", f"{k:x}" * 64) for k, s in enumerate(stems)]
    html, doc = build_report(results)
    validate(doc)
    assert [row["stem"] for row in doc["summary"]] == stems
    assert [s["stem"] for s in doc["logs"]] == stems
    for row, r in zip(doc["summary"], results, strict=True):
        assert row["events"]["adaptive"] == {"events": 1, "in_warmup": 1}
        assert row["events"]["static_loading"] == {"events": 1, "in_warmup": 0}
        assert row["duration_s"] == pytest.approx(r.log.duration_s)
        assert row["calibrated"] is False
    summary = html[html.index("<h2>Summary</h2>") : html.index('<section class="log"')]
    for k, s in enumerate(stems, 1):
        assert f'<a href="#log{k}">{s}</a>' in summary
    assert html.count('<section class="log"') == 3
    assert html.index("<h2>Summary</h2>") < html.index('<section class="log" id="log1">')


def test_false_alarm_margin_known_peaks() -> None:
    r = fake_result()
    t = r.log.time_s
    ratios = {d: np.array(v, copy=True) for d, v in r.ratios.items()}
    quiet = (t >= 1.0) & ((t < 3.4) | ((t > 4.7) & (t < 6.4)) | (t > 8.1))
    base = float(np.max(ratios["adaptive"][quiet, 1]))

    def put(ts: float, v: float) -> None:
        ratios["adaptive"][int(np.argmin(np.abs(t - ts))), 1] = v

    put(0.5, 5.0)  # in warm-up: ignored
    put(4.1 + GUARD_S - 0.1, 0.95)  # inside the guard after the 4.0–4.1 s event: ignored
    put(9.0, 0.97)  # a labelled contact (only with labels)
    put(6.0, 0.9)  # collision-free: the margin
    assert base < 0.9
    r = dataclasses.replace(r, ratios=ratios)
    m = margins(r)["per_detector"]["adaptive"]["j2"]
    assert m["max_ratio"] == pytest.approx(0.97) and m["t_s"] == pytest.approx(9.0, abs=0.004)
    lab = Labels((ContactLabel(8.95, 9.1, 5.0, "push", 2),), 250.0)
    full = margins(r, lab)
    m = full["per_detector"]["adaptive"]["j2"]
    assert m["max_ratio"] == pytest.approx(0.9) and m["t_s"] == pytest.approx(6.0, abs=0.004)
    assert m["headroom"] == pytest.approx(1 / 0.9)
    assert full["worst"]["adaptive"] == {
        "max_ratio": pytest.approx(0.9),
        "joint": "j2",
        "t_s": pytest.approx(6.0, abs=0.004),
    }
    # considered time: after warm-up minus the widened events [0.2±, 4.0–4.1, 7.0–7.5] and label
    excluded = (4.1 - 4.0 + 2 * GUARD_S) + (7.5 - 7.0 + 2 * GUARD_S) + (9.1 - 8.95 + 2 * GUARD_S)
    assert full["rule"]["considered_s"] == pytest.approx(
        r.log.duration_s - 1.0 - excluded, abs=0.03
    )


def test_labels_give_the_quality_section() -> None:
    r = result_named("run.csv", "9" * 64, config=EVENTS_CFG)
    lab = Labels(
        (
            ContactLabel(3.99, 4.12, 12.0, "impact", 2),  # adaptive fires at 4.0
            ContactLabel(6.95, 7.5, 30.0, "clamp", 1),  # static_loading at 7.0
            ContactLabel(8.5, 8.6, 3.0, "push", 1),
        ),  # nothing fires: missed
        250.0,
        "run.labels.json",
    )
    html, doc = build_report([r], [lab])
    validate(doc)
    q = doc["logs"][0]["quality"]
    assert q["status"] == "done"
    sc = q["evaluation"]["detectors"]
    assert (sc["adaptive"]["detected"], sc["static_loading"]["detected"]) == (1, 1)
    assert sc["product"]["detected"] == 2 and sc["product"]["n_contacts"] == 3
    assert doc["summary"][0]["quality"] == {
        "detector": "product",
        "detected": 2,
        "n_contacts": 3,
        "false_alarms": 0,
        # this made-up result lists events but no incidents: none matched as an incident
        "as_incidents": 0,
        "taken_for_payload": 0,
    }
    assert q["sweep"] is not None and q["sweep"]["verdict"]
    assert "Detection quality against labels" in html and "run.labels.json" in html
    assert "2/3 hit" in html and "Verdict:" in html
    assert html.count("missed") >= 1
    # the labelled contact is excluded from the margin
    assert "every labelled contact" in doc["logs"][0]["false_alarm_margin"]["rule"]["excludes"]


def test_envelope_keeps_single_sample_peaks() -> None:
    rng = np.random.default_rng(3)
    n = 200_001
    t = np.arange(n) * 1e-3
    y = 0.1 * rng.standard_normal(n)
    y[123_457] = 9.0
    y[7] = -4.0
    y[50_000] = np.nan
    te, ye = svgplot.envelope(t, y, 500)
    assert len(te) <= 1000
    assert np.all(np.diff(te) >= 0)
    assert np.nanmax(ye) == 9.0 and np.nanmin(ye) == -4.0
    assert te[np.argmax(ye)] == t[123_457]
    # every bucket's extremes are kept
    edges = np.linspace(0, n, 501).astype(int)
    k = 250
    seg = y[edges[k] : edges[k + 1]]
    assert np.nanmax(seg) in ye and np.nanmin(seg) in ye
    ts, ys = svgplot.envelope(t[:900], y[:900], 500)  # short: unchanged
    assert ts is not None and len(ys) == 900


def test_clipped_axis_states_the_true_peak() -> None:
    t = np.linspace(0, 1, 101)
    stat = np.full(101, 0.1)
    stat[50] = 40.0
    chart = svgplot.Chart(
        "j1",
        (0.0, 1.0),
        (svgplot.Series("stat", t, stat), svgplot.Series("thr", t, np.full(101, 1.0))),
        clip_factor=4.0,
        clip_reference="thr",
    )
    svg = svgplot.render_chart(chart, chart_id="x1")
    assert "axis capped at 4; max 40" in svg
    assert svg.startswith("<svg") and svg.endswith("</svg>")


def test_one_figure_per_incident_not_per_event() -> None:
    """Events of several detectors in one contact give one incident figure; the events
    stay listed (collapsed) under the incident list."""
    r = with_incidents(fake_result())
    t = r.log.time_s
    extra = Event("static_baseline", float(t[1050]), float(t[1060]), 1050, 1060, ("j2",),
                  1.1, {"j2": 2.0}, False)  # 4.2 s: during the first counted incident
    r = dataclasses.replace(r, events=(*r.events, extra))
    html, doc = build_report([r])
    validate(doc)
    assert len(doc["logs"][0]["events"]) == 4
    # numbered over the counted incidents, as detect prints them; w1 in the warm-up
    assert [i["number"] for i in doc["logs"][0]["incidents"]] == [None, 1, 2]
    assert [i["label"] for i in doc["logs"][0]["incidents"]] == ["w1", "1", "2"]
    assert html.count("<figcaption><b>Incident") == 3
    for n in ("w1", 1, 2):
        assert f'<figure id="log1-inc{n}">' in html and f'href="#log1-inc{n}"' in html
    assert '<details class="events" id="log1-events">' in html  # collapsed
    assert html.index('id="log1-incidents"') < html.index('id="log1-events"') \
        < html.index('id="log1-unseen"') < html.index('id="log1-inc1"') \
        < html.index("<h3>What was analysed</h3>")


def test_log_stem() -> None:
    assert log_stem("/a/b/run1.csv.gz") == "run1"
    assert log_stem("run1.timeline.json") == "run1"
    assert log_stem("x.mcap") == "x" and log_stem("x.npz") == "x" and log_stem("x.CSV") == "x"
    assert log_stem("s3://bucket/day/run2.csv.gz") == "run2" and log_stem("bag/run3/") == "run3"


def test_pair_labels_rule(tmp_path: Path) -> None:
    a, b = tmp_path / "a.csv", tmp_path / "b.timeline.json"
    la, lb = tmp_path / "a.labels.json", tmp_path / "b.labels.json"
    assert pair_labels([a, b], [lb, la]) == [la, lb]  # by stem
    x, y = tmp_path / "x.json", tmp_path / "y.json"
    assert pair_labels([a, b], [x, y]) == [x, y]  # in order
    assert pair_labels([a, b], [lb]) == [None, lb]  # one, by stem
    with pytest.raises(UsageProblem, match="2 input"):
        pair_labels([a, b], [x])
    assert auto_labels(a, a) is None
    la.write_text("{}")
    assert auto_labels(a, a) == la


def test_model_fit_quality_and_unexcited_caveat() -> None:
    fit = {"method": "robust least squares (bisquare)", "n_samples_fit": 2000,
           "n_samples_holdout": 0, "condition_number": 812.5,
           "unexcited_parameters": ["j2.fc", "j2.fv"],
           "joints": {"fit": {"j1": {"rms_nm": 0.0734, "rms_rel_torque_rms": 0.0105,
                                     "torque_rms_nm": 7.03},
                              "j2": {"rms_nm": 0.1833, "rms_rel_torque_rms": 0.0102,
                                     "torque_rms_nm": 17.9}},
                      "holdout": None}}
    model = {"kind": "decoupled", "joint_names": ["j1", "j2"], "fit": fit,
             "parameters": [{"name": "j1.inertia", "value": 0.0148},
                            {"name": "j2.inertia", "value": 0.1307}]}
    r = result_named("run.csv", "7" * 64, model=model)
    html, doc = build_report([r])
    validate(doc)
    start, end = html.index("<h4>Model fit quality</h4>"), html.index("<h4>Model parameters</h4>")
    fit_html = html[start:end]
    assert "0.0734" in fit_html and "0.1833" in fit_html and "812.5" in fit_html
    assert "not validated on held-out data" in fit_html
    assert "j2.fc, j2.fv" in fit_html
    assert "model-unexcited" in {c["code"] for c in doc["logs"][0]["caveats"]}
    params = html[html.index("<h4>Model parameters</h4>"):]
    assert re.search(r"<th>j2</th><td class=\"num\">0.1307</td>", params)


def test_many_event_bands_are_merged_at_pixel_scale() -> None:
    t = np.linspace(0, 3600, 1001)
    starts = np.arange(2000) * 0.5 + 100.0  # 2000 alarms, 0.5 s apart, over 1000 s
    bands = [svgplot.Band(float(a), float(a) + 0.01, "#f00", "alarm") for a in starts]
    bands.append(svgplot.Band(3000.0, 3000.01, "#f00", "alarm"))  # far away: its own band
    chart = svgplot.Chart("long", (0.0, 3600.0), (svgplot.Series("s", t, np.sin(t)),), bands)
    svg = svgplot.render_chart(chart, chart_id="m")
    rects = re.findall(r'<rect x="([\d.]+)" y="\d+" width="([\d.]+)"[^>]*fill="#f00"', svg)
    assert len(rects) == 2
    assert "2000 × alarm" in svg
    _, w = map(float, rects[1])
    assert w >= 3.0  # a 10 ms alarm on an hour-long plot is still visible


def test_run_warnings_shown_verbatim_without_the_path() -> None:
    w = ("run.csv: the log excites the planar model poorly (condition number 1.7e+03 > 1000)",)
    r = result_named("run.csv", "3" * 64, warnings=w)
    html, doc = build_report([r])
    validate(doc)
    box = html[html.index('<div class="caveats">'):html.index("<h3>What was analysed</h3>")]
    assert "Warnings raised during the run" in box
    assert ("<li>the log excites the planar model poorly (condition number 1.7e+03 &gt; 1000)"
            "</li>") in box
    assert doc["logs"][0]["warnings"] == list(w)


def test_poor_model_fit_is_a_caveat() -> None:
    def fit(rel_j1: float) -> dict:
        stats = {"j1": {"rms_nm": rel_j1 * 2.0, "rms_rel_torque_rms": rel_j1, "torque_rms_nm": 2.0},
                 "j2": {"rms_nm": 0.1, "rms_rel_torque_rms": 0.05, "torque_rms_nm": 2.0}}
        return {"kind": "decoupled", "joint_names": ["j1", "j2"],
                "fit": {"joints": {"fit": stats, "holdout": stats}}}

    _, bad = build_report([result_named("a.csv", "4" * 64, model=fit(1.03))])
    cav = [c for c in bad["logs"][0]["caveats"] if c["code"] == "model-poor-fit"]
    assert len(cav) == 1
    assert "j1 (RMS error 103 % of the torque RMS on held-out data)" in cav[0]["text"]
    assert "j2" not in cav[0]["text"]
    _, good = build_report([result_named("a.csv", "4" * 64, model=fit(0.3))])
    assert "model-poor-fit" not in {c["code"] for c in good["logs"][0]["caveats"]}
    # on a controller's channel the model fits only a correction to it: its error against
    # that small target says nothing of the measured torque (a trial read "56 % of the
    # torque RMS" for a 0.036 N·m error), so no caveat for that joint
    logged = {j: {"generator": "logged_external", "reason": "r", "residual": "x"}
              for j in ("j1", "j2")}
    _, ext = build_report([result_named("a.csv", "4" * 64, model=fit(1.03),
                                        generators=logged)])
    assert "model-poor-fit" not in {c["code"] for c in ext["logs"][0]["caveats"]}
    own = {**logged, "j1": {**logged["j1"], "generator": "inverse_dynamics"}}
    _, mixed = build_report([result_named("a.csv", "4" * 64, model=fit(1.03),
                                          generators=own)])
    assert [c for c in mixed["logs"][0]["caveats"] if c["code"] == "model-poor-fit"]


def test_html_tags_are_balanced() -> None:
    from html.parser import HTMLParser

    void = {"meta", "br", "hr", "img", "input", "link", "area", "base", "col", "wbr"}

    class Checker(HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.stack: list[str] = []
            self.errors: list[str] = []

        def handle_starttag(self, tag: str, attrs: list) -> None:
            if tag not in void:
                self.stack.append(tag)

        def handle_startendtag(self, tag: str, attrs: list) -> None:
            pass  # <line .../> in SVG

        def handle_endtag(self, tag: str) -> None:
            if not self.stack or self.stack[-1] != tag:
                self.errors.append(f"</{tag}> closes {self.stack[-1:]}")
            else:
                self.stack.pop()

    lab = Labels((ContactLabel(3.99, 4.12, 12.0, "impact", 2),), 250.0, "l.json")
    html, _ = build_report([result_named("a.csv", "a" * 64, config=EVENTS_CFG), fake_result()],
                           [lab, None], failed=[("b.csv", "b.csv: bad")])
    c = Checker()
    c.feed(html)
    assert not c.errors[:5] and not c.stack


# --------------------------------------------------------------------------- the answer


def inc(t: float, link: int | None, force: float | None, contact: str = "transient", *,
        warm: bool = False, utc: str | None = None,
        peak: dict[str, float] | None = None) -> dict:
    """A timeline incident (only the fields the verdict reads)."""
    return {"t_start": t, "t_end": t + 0.5, "t_start_utc": utc, "link": link, "force_n": force,
            "contact": contact, "in_warmup": warm, "peak_residual": peak or {"j1": 2.0}}


def test_verdict_counts_by_kind_and_link() -> None:
    v = verdict_text([inc(12.0, 2, 25.0), inc(20.0, 1, 60.0, "quasi_static"),
                      inc(30.0, 2, 40.2)])
    assert v == ("3 incidents: 2 transient on link 2, ~25 N and ~40 N; "
                 "1 quasi-static on link 1, ~60 N.")


def test_verdict_when_nothing_counts() -> None:
    assert verdict_text([]) == "No incident after warm-up."
    assert verdict_text([inc(0.2, 1, 0.4, warm=True)]) == \
        "No incident after warm-up (+1 in the warm-up, not counted)."
    old = verdict_text([], known=False, alarms_counted=2)
    assert old.startswith("2 alarms of the product's detectors after warm-up; this run "
                          "records no incidents")


def test_verdict_gives_clock_times_on_an_epoch_clock() -> None:
    v = verdict_text([inc(4.0, 2, 12.0, utc="2026-01-01T00:00:04.000Z"),
                      inc(7.0, 1, 30.0, "quasi_static", utc="2026-01-01T00:00:07.250Z")])
    assert v == ("2 incidents on 2026-01-01 (UTC): 1 transient on link 2, ~12 N (00:00:04); "
                 "1 quasi-static on link 1, ~30 N (00:00:07).")


def test_verdict_many_incidents_and_no_kinematics() -> None:
    many = [inc(10.0 + k, 2, f) for k, f in enumerate([4.9, 37.4, 8.7, 15.1])]
    assert verdict_text(many) == "4 incidents: 4 transient on link 2, ~4.9 to ~37 N."
    nf = [inc(1.0, None, None, "unknown", peak={"j1": -3.14, "j2": 1.0})]
    # "unknown" is an incident running to the log's end: said where the answer is read
    # (a new user read the KUKA log's last-0.3 s incident as a real event)
    assert verdict_text(nf) == ("1 incident: 1 of unknown kind (running to the log's end: "
                                "how long it pressed cannot be seen, nor whether it is a "
                                "contact or the recording's end) on a link the residuals "
                                "cannot say, ~3.1 N·m peak residual.")


def test_verdict_gives_no_measure_where_the_residual_is_the_models_own_torque() -> None:
    """An incident whose force the physics checks left unstated because the residual is
    the model's own torque (beyond_logged) gets no "peak residual" as how hard: a trial's
    verdict read "~86 N·m peak residual" on the real UR log where the model swung 131 N·m
    and the logged torque 1.3 N·m. Other incidents without a force keep theirs."""
    from impactcli.detect.force import BEYOND_LOGGED

    made = {**inc(31.0, 3, None, peak={"j1": -86.0}),
            "force_method": f"{BEYOND_LOGGED} j1 moved 131 N·m within the incident"}
    v = verdict_text([inc(3.2, 5, 155.0, "quasi_static"), made])
    assert v == ("2 incidents: 1 transient on link 3, no force: part of its residual is the "
                 "model's own torque; 1 quasi-static on link 5, ~155 N."), v
    plain = inc(40.0, 3, None, peak={"j1": 3.0})
    many = [made, {**made, "t_start": 32.0}, plain, {**plain, "t_start": 41.0}]
    assert verdict_text(many) == ("4 incidents: 4 transient on link 3, peak residual ~3.0 "
                                  "to ~3.0 N·m (2 where part of the residual is the model's "
                                  "own torque).")
    assert verdict_text(many[:2] * 2) == ("4 incidents: 4 transient on link 3, no force: part "
                                          "of its residual is the model's own torque, in "
                                          "each.")


def test_verdict_says_which_counted_incidents_may_be_no_new_contact() -> None:
    """Incidents the run marked in an earlier one's aftermath, or just after a lasting load
    ended, are still counted; the verdict says how many (a trial read 8 incidents for 4
    pushes, 3 of them so marked only in the timeline). None marked: nothing said."""
    after = {**inc(12.0, 2, 25.0), "aftermath": {"text": "in the aftermath of incident 1"}}
    again = {**inc(20.0, 2, 19.0, "quasi_static"), "resumes_load": {"text": "resumes"}}
    close = {**inc(12.5, 2, 3.0), "close_behind": {"text": "close behind incident 1"}}
    v = verdict_text([inc(10.0, 2, 30.0), after, again, close])
    assert v.endswith(" Counted, though maybe no new contact: 1 began in an earlier "
                      "incident's aftermath, the arm not settled (maybe its ringing) and 1 "
                      "close behind an earlier, stronger one, within the detectors' settling "
                      "time (maybe its ringing) and 1 just after a lasting load ended (maybe "
                      "that load again)."), v
    assert "maybe no new contact" not in verdict_text([inc(10.0, 2, 30.0)])


def test_smallest_caught_force_through_the_jacobian() -> None:
    jac = planar_jacobian([0.4, 0.4])
    q = np.array([0.3, 0.5])
    lever1 = 0.4 * np.cos(0.5) + 0.4  # joint 1's arm for a force normal to link 2 at its end
    rows = smallest_caught_force([0.8, 0.2], q, jac)
    assert rows[0] == {"link": 1, "lever_m": pytest.approx(0.4), "own_force_n": pytest.approx(2.0),
                       "any_force_n": pytest.approx(2.0), "any_joint": 1}
    assert rows[1]["own_force_n"] == pytest.approx(0.5) and rows[1]["any_joint"] == 2
    rows = smallest_caught_force([0.2, 0.8], q, jac)
    assert rows[1]["own_force_n"] == pytest.approx(2.0)
    assert rows[1]["any_force_n"] == pytest.approx(0.2 / lever1) and rows[1]["any_joint"] == 1
    rows = smallest_caught_force([None, 0.8], q, jac)  # joint 1 left out of detection
    assert rows[0]["own_force_n"] is None and rows[0]["any_force_n"] is None


def unseen(doc: dict) -> dict[str, dict]:
    return {c["code"]: c for c in doc["logs"][0]["could_not_see"]}


def test_could_not_see_on_a_planar_arm() -> None:
    r = with_incidents(fake_result())
    _, doc = build_report([r])
    validate(doc)
    items = unseen(doc)
    assert list(items) == ["warmup", "gaps", "joints-left-out", "smallest-force"]
    assert items["warmup"]["text"].startswith(
        "Warm-up: the first 1.000 s (latest over joints, 10 % of the log)")
    assert "1 incident(s) started in it" in items["warmup"]["text"]
    assert items["gaps"]["data"]["n"] == 0 and items["gaps"]["short"] == "no gap"
    assert items["joints-left-out"]["data"]["items"] == []
    # vL = 0.5 N·m on both joints; links of 0.5 m and 0.25 m
    sf = items["smallest-force"]
    after = r.log.time_s >= 1.0
    q2 = float(np.median(np.asarray(r.log.position)[after, 1]))
    via_j1 = 0.5 / abs(0.5 * np.cos(q2) + 0.25)
    links = sf["data"]["links"]
    assert links[0]["own_force_n"] == pytest.approx(1.0)
    assert links[1]["own_force_n"] == pytest.approx(2.0)
    assert links[1]["any_force_n"] == pytest.approx(via_j1) and links[1]["any_joint"] == 1
    assert sf["data"]["posture_rule"] == "median after warm-up"
    assert sf["data"]["posture_rad"]["j2"] == pytest.approx(q2)
    assert "link 1 (j1) ~1.0 N; link 2 (j2) ~2.0 N (joint j1 already alarms at" in sf["text"]
    # what it is: the push the thresholds need with the residual at zero, not a lower bound
    # of what went unseen (a new user read "link 1 ≥ 10 N" as one)
    assert sf["short"] == "static push ~1.0 N on link 1, static push ~2.0 N on link 2"
    # with a measured floor, the fleet table gives it (a new user read the static push,
    # about half the measured floor, as what the run could see)
    from impactcli.outputs.report.unseen import _measured_short

    probed = {"probed": {"per_link": [{"link": 1, "median_n": 29.1},
                                      {"link": 2, "median_n": None},
                                      {"link": 3, "median_n": 13.2}]}}
    assert _measured_short(probed) == "floor measured ~29 N on link 1, ~13 N on link 3"
    assert _measured_short(None) == "" and _measured_short({"probed": {}}) == ""
    assert "need at one posture, with the residual at zero" in sf["text"]
    assert "median posture after warm-up (j1 " in sf["text"]
    assert doc["summary"][0]["could_not_see"] == list(items)


def test_could_not_see_gaps_left_out_joints_and_no_kinematics() -> None:
    r = with_incidents(fake_result(), kinematics=False)
    t_ns = np.asarray(r.log.t_ns).copy()
    t_ns[1500:] += 1_000_000_000  # the clock jumps 1 s after sample 1499
    r = dataclasses.replace(r, log=dataclasses.replace(r.log, t_ns=t_ns),
                            joints_left_out=({"name": "j3", "reason": "not in the model"},))
    _, doc = build_report([r])
    validate(doc)
    items = unseen(doc)
    gaps = items["gaps"]["data"]
    assert gaps["n"] == 1 and gaps["longest_s"] == pytest.approx(1.004)
    assert gaps["items"][0]["t_s"] == pytest.approx(1499 * 0.004)
    assert "Gaps: 1 in the log's clock" in items["gaps"]["text"]
    assert items["joints-left-out"]["data"]["items"] == [{"name": "j3",
                                                          "reason": "not in the model"}]
    assert "j3: not in the model" in items["joints-left-out"]["text"]
    sf = items["smallest-force"]
    assert sf["data"]["links"] == [] and "no kinematics are known" in sf["text"]
    assert sf["short"] == "no force floor: no kinematics"  # a trial read "short": ""

    assert "j1 0.5 N·m, j2 0.5 N·m" in sf["text"]
    assert "Detection floor" not in sf["text"]  # this run states none
    # a run with a floor: the report states it first, as detect prints it
    floor = {"per_joint": {j: {"static_loading": {"median_nm": m, "worst_tenth_nm": m},
                               "adaptive": {"median_nm": None, "worst_tenth_nm": None}}
                           for j, m in (("j1", 0.42), ("j2", 0.21))}, "per_link": None}
    _, doc2 = build_report([dataclasses.replace(r, detection_floor=floor)])
    sf2 = unseen(doc2)["smallest-force"]
    assert sf2["text"].startswith(
        "Detection floor (as detect states it, over the log after warm-up): a contact adding "
        "less than ~0.42 N·m on j1, ~0.21 N·m on j2 would not have been seen at the log's "
        "median moment (at quieter moments a smaller one can be); a lower bound, "
        "not a promise that a larger one was seen. "), sf2["text"]
    assert doc["logs"][0]["verdict"] == (
        "2 incidents: 1 transient on link 2, ~3.0 N·m peak residual; 1 quasi-static on "
        "link 1, ~1.2 N·m peak residual (+1 in the warm-up, not counted).")


def test_an_older_timeline_says_what_it_cannot_tell() -> None:
    origin = {"timeline": "det/run.timeline.json", "timeline_schema_version": "1.0",
              "recorded_by": "impactcli 0.0.9", "recorded_incidents": None}
    rendered = render(with_incidents(fake_result()), origin=origin)
    items = unseen({"logs": [rendered.section]})
    assert "older-timeline" in items
    text = items["older-timeline"]["text"]
    assert "det/run.timeline.json" in text and "impactcli 0.0.9" in text
    assert "records no incidents" in text and "re-running detection" in text
    assert rendered.section["origin"] == origin
    assert "older-timeline" not in unseen({"logs": [render(fake_result()).section]})


def test_the_incident_list_in_html_and_json() -> None:
    r = with_incidents(fake_result(), t0_ns=1_767_225_600_000_000_000)
    html, doc = build_report([r])
    validate(doc)
    sec = doc["logs"][0]
    assert sec["verdict"] == ("2 incidents on 2026-01-01 (UTC): 1 transient on link 2, ~12 N "
                              "(00:00:04); 1 quasi-static on link 1, ~30 N (00:00:07) (+1 in "
                              "the warm-up, not counted).")
    assert f'<p class="verdict" id="log1-verdict">{sec["verdict"]}</p>' in html
    incs = sec["incidents"]
    assert [(i["number"], i["link"], i["force_n"], i["contact"]) for i in incs] == \
        [(None, 1, 0.4, "transient"), (1, 2, 12.0, "transient"), (2, 1, 30.0, "quasi_static")]
    assert incs[1]["peak_ratio"] == 2.0 and incs[1]["peak_ratio_detector"] == "adaptive"
    row = re.search(r'<tr id="log1-row1">(.*?)</tr>', html)
    assert row and "link 2" in row.group(1) and "~12 N" in row.group(1)
    assert "2026-01-01 00:00:04.000 UTC" in row.group(1) and "2.0×" in row.group(1)
    assert re.search(r'<tr class="warmup" id="log1-roww1">.*?warm-up: not counted', html)
    assert "quasi-static" in re.search(r'<tr id="log1-row2">(.*?)</tr>', html).group(1)
    captions = re.findall(r"<figcaption><b>Incident (.*?)</figcaption>", html)
    assert any("quasi-static" in c for c in captions), captions  # as the rows say it
    assert not any("quasi_static" in c for c in captions), captions
    assert any(c.startswith("w1<") and "in warm-up (not counted)" in c for c in captions)
    summ = doc["summary"][0]["incidents"]
    assert summ == {"counted": 2, "in_warmup": 1, "by_contact": {"transient": 1,
                                                                "quasi_static": 1},
                    "max_force_n": 30.0, "known": True, "lasting_loads": 0}
    assert html.index('id="log1-verdict"') < html.index('id="log1-incidents"') \
        < html.index("Caveats — read before the numbers")


def test_links_the_residuals_cannot_tell_apart_are_named_together() -> None:
    """An incident whose evidence leaves links 1 and 2 (``link_candidates``) is "on link 1 or
    2" in the verdict and the table, never "link 1" alone."""
    r = with_incidents(fake_result())
    incs = list(r.incidents)
    incs[2] = dataclasses.replace(incs[2], link_candidates=(1, 2))
    html, doc = build_report([dataclasses.replace(r, incidents=tuple(incs))])
    validate(doc)
    assert "1 quasi-static on link 1 or 2, ~30 N" in doc["logs"][0]["verdict"]
    row = re.search(r'<tr id="log1-row2">(.*?)</tr>', html)
    assert row and "link 1 or 2" in row.group(1), row
    assert "the residuals cannot tell which" in row.group(1)
    assert "link 2 or" not in html and "on link 1," not in doc["logs"][0]["verdict"]


def test_sweep_table_is_short_and_its_plot_logarithmic() -> None:
    r = with_incidents(result_named("run.csv", "9" * 64, config=EVENTS_CFG))
    lab = Labels((ContactLabel(3.99, 4.12, 12.0, "impact", 2),
                  ContactLabel(6.95, 7.5, 30.0, "clamp", 1)), 250.0, "run.labels.json")
    html, doc = build_report([r], [lab])
    validate(doc)
    sweep = html[html.index("<h4>Threshold sweep"):]
    table = sweep[:sweep.index("</table>")]
    assert 3 <= table.count('<tr><th class="num">') <= 8
    assert "this run" in table
    assert f"of {len(doc['logs'][0]['quality']['sweep']['scales'])} scales" in sweep
    assert "false alarms per hour (log scale" in sweep


def test_evaluation_of_incidents_is_rendered_as_it_comes() -> None:
    q = {"labels_path": "l.json", "n_labelled": 2, "notes": [], "sweep": None,
         "evaluation": {"incidents": {
             "summary": [["link right", "2/2"], {"label": "force error (median)", "value": 0.16}],
             "contacts": [{"label": 1, "link_right": True, "force_error": 0.1},
                          {"label": 2, "link_right": False, "per_type": {"a": 1}}]}}}
    text = report.quality.quality_html(q)
    assert "<th>link right</th><td>2/2</td>" in text
    assert "<th>force error (median)</th><td>0.16</td>" in text
    assert "<th>link_right</th>" in text and "<th>per_type</th>" in text
    assert "{&quot;a&quot;: 1}" in text
    assert "Incidents against labels" not in report.quality.quality_html(
        {**q, "evaluation": {"incidents": None}})


def test_a_log_that_is_all_warm_up_is_not_judged() -> None:
    """Nothing after warm-up analysed: the verdict says "not judged", never "no incident"
    (the report's wording for what the detect gate exits 5 on)."""
    assert verdict_text([], analysed_s=0.0).startswith("Not judged: the adaptive detector's "
                                                       "warm-up covers the whole log")
    assert verdict_text([], analysed_s=2.5) == "No incident after warm-up."
    assert verdict_text([]) == "No incident after warm-up."


def test_a_section_holds_every_field_of_its_timeline() -> None:
    """A log's section carries the timeline's fields (all but its schema_version and tool,
    which the report has its own of) and only the fields its typed record declares."""
    from impactcli.outputs.report.common import LogSection
    from impactcli.outputs.timeline import timeline_dict

    for result in (fake_result(), with_incidents(fake_result())):
        tl = timeline_dict(result)
        sec = render(result).section
        assert set(tl) - {"schema_version", "tool"} <= set(sec)
        assert set(sec) <= set(LogSection.__annotations__)
        assert (sec["input"], sec["thresholds"], sec["summary"]) == (
            tl["input"], tl["thresholds"], tl["summary"])


def test_every_code_the_report_writes_is_in_its_schema() -> None:
    """Each caveat and "could not see" code written in the report's modules is one its
    schema's enums allows (a report with an edited config once wrote 'settings-changed',
    which the schema did not know)."""
    src = Path(report.__file__).parent
    schema = load_schema("report")["$defs"]
    for module, enum in (("caveats.py", schema["caveat"]["properties"]["code"]["enum"]),
                         ("unseen.py", next(v["properties"]["code"]["enum"]
                                            for v in schema.values()
                                            if "gaps" in v.get("properties", {}).get(
                                                "code", {}).get("enum", ())))):
        codes = set(re.findall(r'"code": "([a-z-]+)"', (src / module).read_text()))
        assert codes and codes <= set(enum), (module, codes - set(enum))


def test_a_contact_beside_a_payload_change_says_its_ratio_holds_the_loads_step() -> None:
    """The "× threshold" cell is taken over the incident's events: for a contact beside a
    payload change they hold the load's step (a trial read 28× beside a text of 2.3×), and
    the cell says so; another incident's cell does not."""
    import dataclasses

    r = with_incidents(fake_result())
    incs = list(r.incidents)
    incs[1] = dataclasses.replace(incs[1], payload_test=(
        "a contact beside payload change P1, its link, force and contact type the contact's "
        "own, the load's torque taken out: its alarm held the load and, from 4.000 s, a "
        "torque on j2 the load does not explain (2.3× its loading threshold)"))
    html, doc = build_report([dataclasses.replace(r, incidents=tuple(incs))])
    validate(doc)
    beside_row = re.search(r'<tr id="log1-row1">(.*?)</tr>', html)
    other_row = re.search(r'<tr id="log1-row2">(.*?)</tr>', html)
    assert beside_row and "the load&#x27;s step in it" in beside_row.group(1)
    assert other_row and "step in it" not in other_row.group(1)


def test_a_warm_up_force_is_said_to_maybe_be_the_filters_settling() -> None:
    """The warm-up incident (0.4 N at 0.2 s, not counted) keeps its force in the table,
    with a note that it may be the filters settling from the log's start; the counted
    contacts' forces carry no such note (a new user read a 42 N 'transient on link 2' at
    0.000 s as a contact)."""
    html, _ = build_report([with_incidents(fake_result())])
    note = "in the warm-up: it may be the filters settling from the log's start"
    rows = re.findall(r'<tr class="warmup" id="[^"]*-row[^"]*">.*?</tr>', html)
    assert rows and all(note in r for r in rows if "~0.4 N" in r or "≳0.4 N" in r)
    assert any("~0.4 N" in r or "≳0.4 N" in r for r in rows)
    assert html.count(note) == 1


def test_an_alarm_in_a_warm_up_past_its_least_length_is_not_called_the_filters_settling(
        ) -> None:
    """An incident in the warm-up within its least length (the filters starting) keeps the
    note that it may be their settling; one after it (a warm-up that ran on while the
    prediction error settled) is said to be unjudged and maybe a contact."""
    from impactcli.outputs.report.summary import incident_table_html

    def row(label: str, t: float) -> dict[str, object]:
        return {"label": label, "t_start": t, "duration_s": 0.2, "in_warmup": True,
                "force_n": 20.0, "link": 2, "contact_type": "transient",
                "detectors": ["adaptive"], "peak_ratio": 2.0, "peak_ratio_detector": "adaptive",
                "peak_residual": {}}

    html = incident_table_html([row("w1", 0.5), row("w2", 6.1)], "log1", 0, settled_s=3.0)
    first, second = html.split("w2", 1)
    assert "it may be the filters settling" in first and "not judged" not in first
    assert "ran on past its least 3 s" in second and "it may be a contact" in second
    assert "filters settling" not in second


def test_the_alarm_of_a_payload_change_shows_the_mass_not_a_force() -> None:
    """A trial's report listed P2, releasing 1 kg (~9.8 N), as "≳25 N quasi-static" at
    40.020 s while the payload table said 40.016 s: a row that is a payload change's alarm
    now shows the change's mass, weight and onset, and no contact type; a counted incident's
    row keeps its force."""
    from impactcli.outputs.report.summary import incident_table_html

    def row(label: str, **kw: object) -> dict[str, object]:
        return {"label": label, "t_start": 40.02, "duration_s": 3.2, "force_n": 25.0,
                "force_at_least": True, "link": 2, "contact": "quasi_static",
                "detectors": ["adaptive"], "peak_ratio": 13.7,
                "peak_ratio_detector": "static_loading", "peak_residual": {}, **kw}

    changes = [{"t_start": 20.052, "mass_kg": 0.955}, {"t_start": 40.016, "mass_kg": -1.008}]
    html = incident_table_html([row("p2", payload_change=2), row("3", number=3)], "log1", 0,
                               payload_changes=changes)
    p2, counted = html.split('id="log1-row3"', 1)
    assert ("<b>-1.01 kg</b> <span class=\"note\">a load released from 40.016 s (its weight "
            "~9.9 N), not a contact force</span>") in p2
    assert "25 N" not in p2 and "quasi-static" not in p2
    assert "≳25 N" in counted and "quasi-static" in counted
    # a change whose inertia did not show, or whose release took off more than was carried,
    # is taken for a load but not said to be no contact force
    for odd, why in (({"inertia": "unseen"}, "its inertia did not show, so the end of a "
                      "steady press of ~9.9 N down along gravity"),
                     ({"mass_check": "more than carried"}, "it released more than the log "
                      "was seen to carry, so its mass cannot be trusted")):
        html = incident_table_html([row("p2", payload_change=2)], "log1", 0,
                                   payload_changes=[changes[0], {**changes[1], **odd}])
        assert "not a contact force" not in html
        assert f"~9.9 N), not told from a contact: {why}" in html, html
    # without the timeline's payload changes (an older timeline) the row is as before
    assert "≳25 N" in incident_table_html([row("p2", payload_change=2)], "log1", 0)
