"""Warm-up end from the RLS prediction error."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from impactcli.config import WarmupConfig

from .reference.warmup import trailing_rms, warmup_end


def test_trailing_rms_direct() -> None:
    x = np.random.default_rng(0).standard_normal((50, 2))
    got = trailing_rms(x, 5)
    for k in (0, 3, 4, 30, 49):
        w = x[max(0, k - 4) : k + 1]
        np.testing.assert_allclose(got[k], np.sqrt(np.mean(w**2, axis=0)))


def test_warmup_waits_for_min_time_and_settling_with_cap() -> None:
    fs = 250.0
    t = np.arange(int(60 * fs)) / fs
    rng = np.random.default_rng(1)
    noise = 0.1 * rng.standard_normal((t.size, 3))
    e = noise.copy()
    e[:, 0] += 5.0 * np.exp(-t / 0.2)            # settles fast: min_s decides (3 s)
    e[:, 1] += np.where(t < 7.0, 2.0, 0.0)       # settles at 7 s (+ window)
    e[:, 2] += np.where(t < 40.0, 2.0, 0.0)      # settles at 40 s: capped at max_s = 20 s
    w = warmup_end(e, t, WarmupConfig(min_s=3.0, window_s=0.5, tolerance=0.5, max_s=20.0))
    assert w.index[0] == int(3 * fs)
    assert 7.0 <= t[w.index[1]] <= 7.5
    assert w.index[2] == int(20 * fs)
    assert w.end_index == int(20 * fs) and w.end_s == 20.0


def test_the_level_is_the_start_loads_when_the_load_changed() -> None:
    """Known truth: a prediction error that settles by 2 s at 0.5 (under the load the log
    starts with) and drops to 0.2 at 40 s (the load released). Against the whole log's
    later level (0.2) it never comes within 1.5×: the warm-up runs to its 20 s cap; against
    the level before the change (0.5) it ends at its least length, 3 s."""
    fs = 250.0
    t = np.arange(int(60 * fs)) / fs
    rng = np.random.default_rng(7)
    e = rng.normal(size=(t.size, 1)) * np.where(t < 40.0, 0.5, 0.2)[:, None]
    e[t < 2.0] *= 10.0  # the RLS converging
    cfg = WarmupConfig(min_s=3.0, window_s=0.5, tolerance=0.5, max_s=20.0)
    assert warmup_end(e, t, cfg).end_s == pytest.approx(20.0)
    assert warmup_end(e, t, cfg, until_s=40.0).end_s == pytest.approx(3.0)
    assert warmup_end(e, t, cfg, until_s=1.0).end_s == pytest.approx(20.0)  # before k_min


def test_warmup_longer_than_log() -> None:
    t = np.arange(100) / 250.0
    w = warmup_end(np.ones((100, 1)), t, WarmupConfig(min_s=3.0))
    assert w.end_index == 100 and w.end_s == 100 / 250.0


def test_a_contact_in_a_warm_up_past_its_least_length_is_said_and_not_judged(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A new user's case, known truth by the simulator's labels: the heavy arm carrying
    2 kg from the log's first sample (a pick-and-place run cut at 22 s: the release comes
    18 s in), a config fitted with a payload per log. Measured against the whole log's
    later level — the prediction error's after the release, lower — the warm-up ran on to
    11 s and the labelled 20 N push 6 s in fell in it; against the level before the
    release it ends at its least 3 s and the push is counted. A warm-up that does run on
    (here made to, by the whole log's level as before) with alarms in it says so (a
    warning naming them) and a gate could not judge them (exit 5); alarms in the warm-up's
    first 3 s (the filters starting) stay as they were."""
    import warnings
    from dataclasses import replace

    from impactcli.run.calibration import calibrate_run
    from impactcli.run.collect import detect_in_memory
    from impactcli.run.gates import Findings, judge
    from impactcli.sim import scenario, simulate
    from impactcli.types import LogSource

    def run(name: str, seed: int, kg: float) -> tuple[object, object]:
        sc = scenario(name, "heavy_geared", 60.0, robot_seed=7, controller_channels=False,
                      payload_kg=kg)
        res = simulate(sc, seed=seed)
        return res, replace(res.log, source=LogSource(f"{name}{seed}", f"{seed:064x}", "memory"))

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        free, light = run("free_multisine", 1, 0.0)
        cfg = calibrate_run([light, run("free_multisine", 2, 2.0)[1]],
                            robot=free.robot).config  # type: ignore[attr-defined]
        pnp, log = run("pick_and_place", 3, 2.0)
        k = int(22.0 * log.sample_rate_hz)  # type: ignore[attr-defined]
        cut = replace(log.slice(k, log.n_samples),  # type: ignore[attr-defined]
                      source=LogSource("cut.csv", "x", "memory"))
        fixed, _ = detect_in_memory(cut, config=cfg)
        from impactcli.detect.warmup import WarmupTracker

        whole_level = WarmupTracker.finish
        monkeypatch.setattr(WarmupTracker, "finish", lambda self, until_s=None:
                            whole_level(self))  # the level as before: the whole log's
        out, _ = detect_in_memory(cut, config=cfg)
    push = [e for e in pnp.labels.events if 22.0 < e.start < 33.0]  # type: ignore[attr-defined]
    assert [round(p.start - 22.0, 1) for p in push] == [6.0]
    assert fixed.warmup_end_s == pytest.approx(3.0, abs=0.01)  # the level before the release
    assert any(abs(i.t_start - 6.0) < 0.3 for i in fixed.counted_incidents())  # the push
    assert out.warmup_end_s > 9.0  # the warm-up ran on past its least 3 s
    late = [i for i in out.incidents if i.in_warmup and i.t_start >= 3.0]
    assert any(abs(i.t_start - 6.0) < 0.3 for i in late), late  # the push, in the warm-up
    said = [w for w in out.warnings if "alarm(s) in it after 3 s are not counted and not "
            "judged" in w]
    assert len(said) == 1 and f"{late[0].t_start:.3f} s" in said[0], out.warnings
    _, unjudged = judge([Findings.of("cut.csv", out)], fail_on_detect=True,
                        fail_on_force=None)
    line = [u for u in unjudged if "in the warm-up after its least 3 s" in u]
    assert len(line) == 1 and line[0].endswith("alarms in it are not counted; exit 5"), unjudged
    early = [i for i in out.incidents if i.in_warmup and i.t_start < 3.0]
    assert early and not any(f"{i.t_start:.3f} s" in said[0] for i in early)
    # through the CLI: the table's row marks the warm-up, a line under it says why, and
    # the batch summary's row carries it (a new user saw only the warm-up's length there)
    from click.testing import CliRunner

    from impactcli.cli import main
    from impactcli.config import save_config
    from impactcli.logs import write_log

    write_log(replace(cut, source=LogSource("cut.csv.gz", "x", "memory")),
              tmp_path / "cut.csv.gz")
    save_config(cfg, tmp_path / "cfg.toml")  # type: ignore[arg-type]
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "cut.csv.gz"), "--config",
                                  str(tmp_path / "cfg.toml"), "-o", str(tmp_path / "o"),
                                  "--summary", str(tmp_path / "s.json")])
    assert r.exit_code == 0, r.output
    (row,) = [ln for ln in r.stdout.splitlines() if ln.startswith("cut.csv.gz ")]
    assert f"{out.warmup_end_s:.2f}*" in row.split()
    n = len(late)
    assert (f"(*: the warm-up ran on past its least length (3 s) while the evaluator's "
            f"prediction error settled: {n} alarm(s) in it after that are neither counted "
            "nor judged") in r.stdout
    (res,) = json.loads((tmp_path / "s.json").read_text("utf-8"))["results"]
    assert res["late_warmup"] == {"least_s": 3.0, "alarms": n}
