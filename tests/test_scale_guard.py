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
from impactcli.io import write_log

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


def test_a_slow_replay_reports_its_progress_per_axis(monkeypatch: pytest.MonkeyPatch) -> None:
    from impactcli import pipeline
    from impactcli.pipeline import analyze

    seen: list[tuple[int, int]] = []
    log = make_log(n=1500, joints=("a", "b", "c"))
    analyze(log, progress=lambda d, t: seen.append((d, t)))
    assert seen == []  # cheap: no progress
    monkeypatch.setattr(pipeline, "PROGRESS_AFTER_S", 0.0)
    analyze(log, progress=lambda d, t: seen.append((d, t)))
    assert seen == [(1, 3), (2, 3), (3, 3)]


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

    monkeypatch.setattr("impactcli.batch.stream_log", stream_log)
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

    def analyze_stream(path: str, **kw: object) -> object:  # the replay evaluate runs
        seen.update(kw)
        raise ScaleLimitError("stop here")

    monkeypatch.setattr("impactcli.stream.analyze_stream", analyze_stream)
    CliRunner().invoke(main, ["evaluate", str(log), "--allow-slow"])
    assert seen["allow_slow"] is True


def test_calibrate_refuses_a_huge_arm_before_identifying(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from impactcli import calibration

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
    from impactcli import calibration

    seen: list[object] = []

    def replay(*_: object, **kw: object) -> object:
        seen.append(kw.get("allow_slow"))
        raise ScaleLimitError("stop here")

    import types

    from impactcli import model as model_pkg

    monkeypatch.setattr(calibration, "replay", replay)
    monkeypatch.setattr(model_pkg, "identify_many",  # no identification of 120 joints here
                        lambda logs, **k: types.SimpleNamespace(joint_names=logs[0].joint_names))
    log = _huge_log(tmp_path)
    CliRunner().invoke(main, ["calibrate", str(log), "-o", str(tmp_path / "c.toml"),
                              "--allow-slow", "--generator", "inverse_dynamics"])
    assert seen and all(s is True for s in seen)
