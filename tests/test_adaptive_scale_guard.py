"""Scale guard: the adaptive evaluator's cost grows with the cube of the joint count; a
replay estimated slower than real time (or above 2 GiB of covariance) is refused before
any work, with one line naming the limit and the option to go on."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from impactcli.cli import main
from impactcli.detect.adaptive import check_scale, replay_cost
from impactcli.errors import ScaleLimitError
from impactcli.logs import write_log
from impactcli.run.one_log import RunSetup

from .conftest import make_log


def test_cost_depends_on_joints_and_rate_never_on_duration() -> None:
    c7, m7 = replay_cost(7, 1000.0)
    c100, _ = replay_cost(100, 1000.0)
    assert c7 < 0.05 and m7 < 1e6  # a 7-joint arm at 1 kHz: far below real time
    assert c100 > 1.0 and c100 / c7 > (100 / 7) ** 2  # grows faster than J²
    assert replay_cost(7, 250.0)[0] == pytest.approx(c7 / 4)
    check_scale(7, 1000.0)
    with pytest.raises(ScaleLimitError, match=r"100 joints at 1000 Hz: .* give --allow-slow"):
        check_scale(100, 1000.0)


def test_detect_refuses_a_huge_arm_before_any_work(tmp_path: Path) -> None:
    joints = tuple(f"j{k}" for k in range(120))
    write_log(make_log(n=1200, joints=joints), tmp_path / "big.csv")
    r = CliRunner().invoke(main, ["detect", str(tmp_path / "big.csv"), "-o", str(tmp_path)])
    assert r.exit_code == 2, r.output
    assert "120 joints at 250 Hz: the adaptive evaluator is estimated at" in r.output
    assert "give --allow-slow to run it anyway" in r.output
    assert not list(tmp_path.glob("*.timeline.json"))


def test_a_replay_reports_its_progress_in_seconds_of_log_over_its_passes() -> None:
    """Identification, replay and the comparison over the spill: each chunk's progress in
    seconds of log, out of three passes over the log."""
    import warnings

    from impactcli.logs.reader import MemoryReader
    from impactcli.run.one_log import RunSetup, detect_log

    seen: list[tuple[float, float]] = []
    log = make_log(n=1500, joints=("a", "b", "c"))
    with warnings.catch_warnings(), MemoryReader(log) as reader:
        warnings.simplefilter("ignore")
        detect_log(reader, RunSetup(chunk_rows=500), progress=lambda d, t: seen.append((d, t)))
    d = log.duration_s
    t_end = [float(log.time_s[k]) for k in (499, 999, 1499)]
    assert seen == [(p * d + t, 3 * d) for p in range(3) for t in t_end]


def _huge_log(tmp_path: Path) -> Path:
    """120 joints at 200 Hz for 4 s (past the 3 s warm-up): small, far above the limit."""
    path = tmp_path / "huge.csv"
    write_log(make_log(n=800, joints=tuple(f"j{k}" for k in range(120)), dt=0.005), path)
    return path


def _refusal(path: Path) -> str:
    with pytest.raises(ScaleLimitError) as err:
        check_scale(120, 200.0, None, str(path))
    msg = str(err.value)
    assert msg.startswith(f"{path}: 120 joints at 200 Hz: the adaptive evaluator is estimated")
    assert msg.endswith("above the limit of 1 s per second of log and 2 GiB: give "
                        "--allow-slow to run it anyway")
    return f"impactcli: error: {msg}\n"


def test_report_refuses_a_huge_arm_and_takes_allow_slow(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    log = _huge_log(tmp_path)
    html, js = tmp_path / "r.html", tmp_path / "r.json"
    r = CliRunner().invoke(main, ["report", str(log), "-o", str(html), "--json", str(js)])
    assert r.exit_code == 2, r.output
    assert r.stderr == _refusal(log)
    assert not html.exists() and not js.exists()
    seen: dict[str, object] = {}

    def stream_log(path: str, **kw: object) -> object:
        seen.update(kw)
        raise ScaleLimitError("stop here")

    monkeypatch.setattr("impactcli.run.job.run_log", stream_log)
    r = CliRunner().invoke(main, ["report", str(log), "-o", str(html), "--allow-slow"])
    assert seen.get("allow_slow") is True, r.output


def test_evaluate_refuses_a_huge_arm_and_takes_allow_slow(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    log = _huge_log(tmp_path)
    labels = tmp_path / "huge.labels.json"
    labels.write_text('{"sample_rate": 200.0, "events": []}')
    r = CliRunner().invoke(main, ["evaluate", str(log), "--json"])
    assert r.exit_code == 2, r.output
    assert r.stderr == _refusal(log)
    assert r.stdout == ""
    seen: dict[str, object] = {}

    def detect_log(reader: object, setup: RunSetup, **kw: object) -> object:  # evaluate's
        seen["allow_slow"] = setup.allow_slow
        raise ScaleLimitError("stop here")

    monkeypatch.setattr("impactcli.run.job.detect_log", detect_log)
    CliRunner().invoke(main, ["evaluate", str(log), "--allow-slow"])
    assert seen["allow_slow"] is True


def test_calibrate_refuses_a_huge_arm_before_identifying(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from impactcli.run import calibration

    def calibrate(*_: object, **__: object) -> object:
        raise AssertionError("the pipeline must not run")

    monkeypatch.setattr(calibration, "calibrate", calibrate)
    log = _huge_log(tmp_path)
    out = tmp_path / "cfg.toml"
    r = CliRunner().invoke(main, ["calibrate", str(log), "-o", str(out)])
    assert r.exit_code == 2, r.output
    assert r.stderr == _refusal(log)
    assert r.stdout == "" and not out.exists()
    # --allow-slow: no refusal from the verb, the pipeline is called
    r = CliRunner().invoke(main, ["calibrate", str(log), "-o", str(out), "--allow-slow"])
    assert r.exit_code == 70 and "the pipeline must not run" in r.stderr
    assert "--allow-slow" in CliRunner().invoke(main, ["calibrate", "--help"]).stdout


def test_calibrate_allow_slow_reaches_the_replay(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """calibrate --allow-slow is not refused later by the replay of each log."""
    from impactcli.run import calibration

    seen: list[object] = []

    def check_replayable(*a: object) -> object:  # each log's, before its replay
        seen.append(a[-1])
        raise ScaleLimitError("stop here")

    import types

    from impactcli import model as model_pkg

    monkeypatch.setattr(calibration, "check_replayable", check_replayable)
    from impactcli.model import selection

    def fake_fit(logs: list, **k: object) -> object:  # no identification of 120 joints here
        return types.SimpleNamespace(joint_names=logs[0].joint_names)

    monkeypatch.setattr(model_pkg, "identify_many", fake_fit)
    monkeypatch.setattr(selection, "select_model", fake_fit)
    log = _huge_log(tmp_path)
    CliRunner().invoke(main, ["calibrate", str(log), "-o", str(tmp_path / "c.toml"),
                              "--allow-slow", "--generator", "inverse_dynamics"])
    assert seen and all(s is True for s in seen)
