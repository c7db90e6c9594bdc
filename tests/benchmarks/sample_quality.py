"""Detection quality on the shipped sample logs, against the done criteria (C1–C6).

    python tests/benchmarks/sample_quality.py               # the committed configs
    python tests/benchmarks/sample_quality.py --calibrate   # recalibrate on the same logs
    python tests/benchmarks/sample_quality.py --truth       # + true impact forces (re-simulated)
    python tests/benchmarks/sample_quality.py --on assist_free_triangle,assist_free_p2p
                                              # calibrate the ASSIST-like config on these
    python tests/benchmarks/sample_quality.py --variants    # other residuals and low-passes
    python tests/benchmarks/sample_quality.py --cross-unit  # + calibrated on other units
    python tests/benchmarks/sample_quality.py --generators  # each residual generator (then exit)

Every contact log in ``sample_logs/csv`` is replayed with the thresholds of its arm's config
(``sample_logs/assist_like.config.toml``, ``sample_logs/heavy_geared.config.toml``, made by
``impactcli calibrate`` on collision-free sample logs — see :data:`CALIBRATION_LOGS`) and
evaluated against its labels with :func:`impactcli.quality.evaluation.evaluate_result` (an event
matches a contact when it starts within [start − 20 ms, end + 250 ms]). Printed: a markdown
table per detector and log (hits, misses, delays, false alarms, smallest detected force),
then one PASS/FAIL line per criterion with what decided it.

The criteria, on the ASSIST-like logs (4 ms sampling; since they carry the controller's
``torque_ext`` and ``torque_model``, the committed config's generator is ``auto`` →
``logged_external``):
- C1 no alarm of the product (adaptive OR static_loading) between contacts after warm-up,
  on every contact log: no counted product event that matches no contact;
- C2 every elastomer impact of ≥ 20 N: a product event within 80 ms of the labelled onset;
- C3 every push of ≥ 20 N: a product event starting while the push lasts (≤ its end);
- C4 every clamping ramp of ≥ 20 N: a static_loading event starting while it lasts;
- C5 ``assist_payload`` (0.5 kg the description does not know) analysed with no model and
  no config (model identified from the log, thresholds by the uncalibrated rule): no
  product alarm after warm-up; reported beside it, the same log with the config's
  thresholds and a model identified from the log (``identify`` then
  ``detect --config --model``) and with the config's own model.
- C6 every contact of ≥ 10 N after warm-up (impact, push or clamp) caught by the product,
  on every ASSIST-like contact log (the controller-channel criterion).

The criteria's functions live in ``tests/sample_criteria.py`` (``tests/test_acceptance.py``
asserts them).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from impactcli.config import DetectorConfig, load_config
from impactcli.quality.evaluation import Evaluation, evaluate_result
from impactcli.quality.match import PRODUCT
from impactcli.run.calibration import calibrate
from impactcli.types import DetectionResult

# the criteria and the sample logs' places, shared with tests/test_acceptance.py
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.sample_criteria import (
    C6_MIN_FORCE_N,
    CALIBRATION_LOGS,
    CONTACT_LOGS,
    IMPACT_DELAY_S,
    PAYLOAD_LOG,
    REPO,
    ROWS,
    calibrate_on,
    clamps_by_static_loading,
    config_path,
    contacts_caught,
    impacts_within,
    labels_of,
    max_ratio_after_warmup,
    ms_text,
    no_alarm_between_contacts,
    payload_no_false_alarm,
    pushes_while_lasting,
    read,
    replay,
    run,
)

#: Residual generators compared by ``--generators`` (``auto`` is what a new config uses),
#: with the controller's channels corrected (default) or plain (``logged_correction``).
GENERATORS: tuple[tuple[str, bool], ...] = (
    ("auto", True), ("logged_external", True), ("logged_external", False),
    ("logged_model", True), ("logged_model", False), ("inverse_dynamics", True),
    ("momentum_observer", True))


def generators() -> None:
    """Per residual generator, calibrated on the committed calibration logs: contacts of
    ≥ 10 N caught by the product and false alarms between contacts, per ASSIST-like log."""
    names = CALIBRATION_LOGS["assist_like"]
    assist = [n for n, a in CONTACT_LOGS.items() if a == "assist_like"]
    print("| generator | " + " | ".join(f"{n}: ≥ {C6_MIN_FORCE_N:g} N caught, all caught, "
                                         "false alarms" for n in assist) + " |")
    print("|---|" + "---|" * len(assist))
    import dataclasses

    for gen, correct in GENERATORS:
        base = DetectorConfig()
        base = dataclasses.replace(base, residual=dataclasses.replace(
            base.residual, logged_correction=correct))
        cfg = calibrate_on(names, base, generator=gen)
        cells = []
        for n in assist:
            ev = run(n, cfg)[1]
            c6 = contacts_caught(n, ev)
            s = ev.scores[PRODUCT]
            cells.append(f"{c6.detail.split(' ')[0]}, {s.detected}/{s.n_contacts}, "
                         f"{s.false_alarms}")
        used = ", ".join(sorted(set(cfg.residual.generators.values())))
        plain = "" if correct or not gen.startswith("logged") else ", plain"
        print(f"| {gen} ({used}{plain}) | " + " | ".join(cells) + " |")


#: Design alternatives to the shipped residual and static-loading filter, each recalibrated
#: on the same free logs (``--variants``): does any of them pass C1 on the clamps log
#: without losing another criterion?
VARIANTS: dict[str, dict[str, dict[str, object]]] = {
    "shipped (generator auto, LP 2 Hz order 1)": {},
    "LP 1 Hz order 1": {"static_loading": {"cutoff_hz": 1.0}},
    "LP 2 Hz order 2": {"static_loading": {"order": 2}},
    "LP 1 Hz order 2": {"static_loading": {"cutoff_hz": 1.0, "order": 2}},
    "momentum observer K = 50/s": {"residual": {"generator": "momentum_observer"}},
}


def variants() -> None:
    """Print the ASSIST-like criteria C1–C4 for each of :data:`VARIANTS`."""
    import dataclasses

    names = CALIBRATION_LOGS["assist_like"]
    assist = [n for n, a in CONTACT_LOGS.items() if a == "assist_like"]
    for label, change in VARIANTS.items():
        base = DetectorConfig()
        for section, fields in change.items():
            base = dataclasses.replace(
                base, **{section: dataclasses.replace(getattr(base, section), **fields)})
        cfg = calibrate_on(names, base)
        evals = {n: run(n, cfg)[1] for n in assist}
        crit = [no_alarm_between_contacts(n, evals[n]) for n in assist]
        crit += [impacts_within("assist_impacts", evals["assist_impacts"]),
                 pushes_while_lasting("assist_pushes", evals["assist_pushes"]),
                 clamps_by_static_loading("assist_clamps", evals["assist_clamps"])]
        print(f"{label}: vL {', '.join(f'{v:.2f}' for v in cfg.thresholds.vL.values())} N·m")
        for c in crit:
            print(f"  {c.line()}")


# ----------------------------------------------------------------------------- the table
def _fn(x: float | None) -> str:
    return "-" if x is None else f"{x:.1f} N"


def _fms(x: float | None) -> str:
    return "-" if x is None else f"{x * 1e3:.0f} ms"


def table(evals: dict[str, Evaluation]) -> str:
    """Markdown table: per log and detector, hits, misses, delays, FAs, forces."""
    head = ("| log | detector | hits | misses | delay median | delay max | false alarms "
            "| smallest detected F | largest missed F |")
    lines = [head, "|" + "---|" * 9]
    for name, ev in evals.items():
        for d in ROWS:
            s = ev.scores[d]
            lines.append(f"| {name} | {d} | {s.detected}/{s.n_contacts} | {s.missed} | "
                         f"{_fms(s.delay_median_s)} | {_fms(s.delay_max_s)} | "
                         f"{s.false_alarms} | {_fn(s.min_detected_force)} | "
                         f"{_fn(s.max_missed_force)} |")
    return "\n".join(lines)


def contact_table(name: str, ev: Evaluation) -> str:
    """Per contact: force, link, duration and each detector's delay [ms]."""
    lines = [f"{name}: contact | kind | link | peak F | duration | "
             + " | ".join(ROWS)]
    for c in ev.contacts:
        lines.append(f"  {c.index:>2} | {c.label.kind} | {c.label.link} | "
                     f"{c.label.peak_force:5.1f} N | "
                     f"{(c.label.end - c.label.start) * 1e3:5.0f} ms | "
                     + " | ".join(ms_text(c.delay_s[d]) for d in ROWS))
    return "\n".join(lines)


def clamp_release_truth(res: DetectionResult, sim: object | None = None,
                        name: str = "assist_clamps",
                        window_s: tuple[float, float] = (0.1, 1.4)) -> str:
    """What the residual gets wrong after each clamp release: per release and joint, over
    ``window_s`` after the labelled end, the correlation between the residual's error (r
    minus the true external torque, sign-aligned) and the transmission deflection θ − q,
    and the largest |LP(error)| / vL. ``sim``: the simulation ``res`` replayed (default:
    ``name`` re-simulated from the sample manifest)."""
    from impactcli.detect.static import causal_lowpass
    from impactcli.sim.core import SimResult, simulate
    from impactcli.sim.sample_logs import MANIFEST

    if sim is None:
        entry = next(m for m in MANIFEST if m.name == name)
        sim = simulate(entry.make(), seed=entry.seed)
    assert isinstance(sim, SimResult)
    t, te = sim.truth["time_s"], sim.truth["tau_ext"]
    r = res.signals["residual"]
    sign = -1.0 if float(np.sum(r * te)) < 0 else 1.0
    err = r - sign * te
    cfg = res.config["static_loading"]
    lp = np.abs(causal_lowpass(err, cfg["cutoff_hz"], res.log.sample_rate_hz, cfg["order"]))
    vl = np.array([res.thresholds[j]["vL"] for j in res.log.joint_names])
    defl = sim.truth["x1"] - sim.truth["x2"]
    out = [f"{name}: re-simulated; after each release ({window_s[0]}–{window_s[1]} s after "
           "the labelled end): corr(residual error, θ − q) and max |LP(error)| / vL per joint"]
    for c in sim.labels.events:
        w = (t > c.end + window_s[0]) & (t < c.end + window_s[1])
        parts = []
        for k, j in enumerate(res.log.joint_names):
            rho = np.corrcoef(defl[w, k], err[w, k])[0, 1]
            parts.append(f"{j} corr {rho:+.2f}, {lp[w, k].max() / vl[k]:.2f}× vL")
        out.append(f"  {c.peak_force:4.0f} N clamp ending {c.end:6.2f} s: " + "; ".join(parts))
    return "\n".join(out)


def cross_unit() -> None:
    """The ASSIST-like logs re-simulated as the sample set was first built — every log on
    its OWN unit of the arm (true parameters drawn from each log's seed, ±20 %) — then
    calibrated and judged like the committed set: thresholds calibrated on other units of
    the same type, the way a fleet might share one config."""
    from dataclasses import replace

    from impactcli.sim.core import simulate
    from impactcli.sim.sample_logs import MANIFEST

    sims = {m.name: simulate(replace(m.make(), robot_seed=None), seed=m.seed)
            for m in MANIFEST if m.arm == "assist_like"}
    names = CALIBRATION_LOGS["assist_like"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cfg = calibrate([sims[n].log for n in names], robot=sims[names[0]].robot)
        assist = [n for n, a in CONTACT_LOGS.items() if a == "assist_like"]
        results = {n: replay(sims[n].log, config=cfg, robot=sims[n].robot) for n in assist}
        evals = {n: evaluate_result(results[n], sims[n].labels) for n in assist}
    print("ASSIST-like logs, each on its own unit; calibrated on " + ", ".join(names)
          + f" (vL {', '.join(f'{v:.2f}' for v in cfg.thresholds.vL.values())} N·m)")
    crit = [no_alarm_between_contacts(n, evals[n]) for n in assist]
    crit += [impacts_within("assist_impacts", evals["assist_impacts"]),
             pushes_while_lasting("assist_pushes", evals["assist_pushes"]),
             clamps_by_static_loading("assist_clamps", evals["assist_clamps"])]
    for c in crit:
        print(f"  {c.line()}")
    print(clamp_release_truth(results["assist_clamps"], sims["assist_clamps"]))


def impact_truth(name: str = "assist_impacts", after_s: float = IMPACT_DELAY_S) -> str:
    """Re-simulate ``name`` (sample manifest, same seed) and give, per impact, the true
    contact force ``after_s`` after the labelled onset and the time to reach 20 N."""
    from impactcli.sim.core import simulate
    from impactcli.sim.sample_logs import MANIFEST

    entry = next(m for m in MANIFEST if m.name == name)
    sim = simulate(entry.make(), seed=entry.seed)
    log = read(name)
    same = bool(np.allclose(sim.log.position, log.position, atol=1e-6))
    t, f = sim.truth["time_s"], sim.truth["contact_force_total"]
    out = [f"{name}: re-simulated (same log as the CSV: {same}); true force "
           f"{after_s * 1e3:.0f} ms after onset"]
    for c in labels_of(name).events:
        k = int(np.searchsorted(t, c.start + after_s - 1e-9))
        win = (t >= c.start - 1e-9) & (t <= c.start + after_s + 1e-9)
        kp = int(np.flatnonzero(win)[np.argmax(f[win])])
        kpk = int(np.flatnonzero((t >= c.start) & (t <= c.end))[0]) + int(
            np.argmax(f[(t >= c.start) & (t <= c.end)]))
        out.append(f"  peak {c.peak_force:5.1f} N at +{(t[kpk] - c.start) * 1e3:4.0f} ms; "
                   f"first {after_s * 1e3:.0f} ms: max {f[kp]:5.1f} N at "
                   f"+{(t[kp] - c.start) * 1e3:3.0f} ms, F(+{after_s * 1e3:.0f} ms) = "
                   f"{f[k]:5.1f} N")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--calibrate", action="store_true",
                    help="recalibrate instead of reading the committed configs")
    ap.add_argument("--on", help="comma-separated ASSIST-like free logs to calibrate on "
                    "(implies --calibrate)")
    ap.add_argument("--truth", action="store_true",
                    help="re-simulate assist_impacts for the true force at onset + 80 ms")
    ap.add_argument("--cross-unit", action="store_true",
                    help="also: the ASSIST-like logs each on its own unit of the arm, "
                    "calibrated across units (how the sample set was first built)")
    ap.add_argument("--generators", action="store_true",
                    help="C6 and false alarms for every residual generator, each "
                    "recalibrated (then exit)")
    ap.add_argument("--variants", action="store_true",
                    help="C1–C4 for alternative residual generators and static-loading "
                    "low-passes, each recalibrated (then exit)")
    args = ap.parse_args(argv)
    t_all = time.perf_counter()
    if args.generators:
        generators()
        print(f"\ntotal {time.perf_counter() - t_all:.1f} s")
        return 0
    if args.variants:
        variants()
        print(f"\ntotal {time.perf_counter() - t_all:.1f} s")
        return 0
    cal = dict(CALIBRATION_LOGS)
    if args.on:
        cal["assist_like"] = tuple(args.on.split(","))
    cfgs: dict[str, DetectorConfig] = {}
    for arm, names in cal.items():
        if args.calibrate or args.on or not config_path(arm).exists():
            cfgs[arm] = calibrate_on(names)
            src = "calibrated now on " + ", ".join(names)
        else:
            cfgs[arm] = load_config(config_path(arm))
            src = f"{config_path(arm).relative_to(REPO)} (calibrated on " + ", ".join(
                Path(lg.path).name for lg in cfgs[arm].calibration.logs) + ")"
        th = cfgs[arm].thresholds
        gens = sorted(set(cfgs[arm].residual.generators.values())) or [
            cfgs[arm].residual.generator]
        print(f"{arm}: {src}; rule {cfgs[arm].calibration.margin_rule}"
              f"{' (weak)' if cfgs[arm].calibration.weak else ''}; generator "
              f"{', '.join(gens)}")
        for j in th.v_stat:
            m = cfgs[arm].calibration.margins
            print(f"  {j}: v_stat {th.v_stat[j]:.3f} (×{m['adaptive'][j]:.2f}), vL {th.vL[j]:.3f} "
                  f"(×{m['static_loading'][j]:.2f}), v0 {th.v0[j]:.3f} "
                  f"(×{m['static_baseline'][j]:.2f}) N·m")
    evals: dict[str, Evaluation] = {}
    results: dict[str, DetectionResult] = {}
    for name, arm in CONTACT_LOGS.items():
        results[name], evals[name] = run(name, cfgs[arm])
    print()
    print(table(evals))
    print()
    for name, ev in evals.items():
        print(contact_table(name, ev))
        gain = results[name].filter_gain
        print(f"  G(z) gain at {gain['frequencies_hz']} Hz (final theta): "
              + "; ".join(f"{j} {[round(g, 2) for g in v]}" for j, v in gain["gain"].items()))
    print()
    assist = [n for n, a in CONTACT_LOGS.items() if a == "assist_like"]
    crit = [no_alarm_between_contacts(n, evals[n]) for n in assist]
    crit.append(impacts_within("assist_impacts", evals["assist_impacts"]))
    crit.append(pushes_while_lasting("assist_pushes", evals["assist_pushes"]))
    crit.append(clamps_by_static_loading("assist_clamps", evals["assist_clamps"]))
    crit += [contacts_caught(n, evals[n]) for n in assist]
    res_u, ev_u = run(PAYLOAD_LOG, None)
    crit.append(payload_no_false_alarm("no model, no config", res_u, ev_u))
    for c in crit:
        print(c.line())
    print("\nalso measured (not criteria):")
    info = [no_alarm_between_contacts("heavy_impacts", evals["heavy_impacts"])]
    res_m, ev_m = run(PAYLOAD_LOG, cfgs["assist_like"], model_from_log=True)
    info.append(payload_no_false_alarm("config thresholds, model identified from the log",
                                       res_m, ev_m))
    res_c, ev_c = run(PAYLOAD_LOG, cfgs["assist_like"])
    info.append(payload_no_false_alarm("config thresholds and the config's model", res_c, ev_c))
    for c in info:
        print(c.line(info=True))
    for lbl, r in (("no config", res_u), ("config + model from log", res_m)):
        print(f"  {PAYLOAD_LOG} ({lbl}): largest statistic/threshold after warm-up "
              + ", ".join(f"{d} {v:.2f}" for d, v in max_ratio_after_warmup(r).items()))
    if args.truth:
        print()
        print(impact_truth())
        print(clamp_release_truth(results["assist_clamps"]))
    if args.cross_unit:
        print()
        cross_unit()
    print(f"\nmachine: {platform.platform()}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} CPUs; python {sys.version.split()[0]}; "
          f"total {time.perf_counter() - t_all:.1f} s")
    return 0 if all(c.passed for c in crit) else 1


if __name__ == "__main__":
    raise SystemExit(main())
