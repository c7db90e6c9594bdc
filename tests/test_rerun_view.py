"""``impactcli view``: checks an .rrd, or detects on a log and writes/opens the recording."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

from impactcli.cli import main
from impactcli.cli import view as view_mod
from impactcli.types import ReadOptions

from .conftest import make_log
from .fakes import fake_result
from .fakes import write_fake_rrd as write_rrd

rr = pytest.importorskip("rerun")


def run(*args: str) -> Result:
    return CliRunner().invoke(main, ["view", *args], catch_exceptions=False)


def explain(r: Result) -> str:
    return f"exit {r.exit_code}\nstdout: {r.stdout}\nstderr: {r.stderr}"


@pytest.fixture(scope="module")
def rrd(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("view") / "run.rrd"
    write_rrd(fake_result(), path)
    return path


@pytest.fixture
def fake_viewer(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """Replace the viewer by a script that records the file it was asked to open."""
    record = tmp_path / "opened.txt"
    script = f"import sys; open({str(record)!r}, 'w').write(sys.argv[1])"
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(view_mod, "viewer_command",
                        lambda path: [sys.executable, "-c", script, str(path)])
    return record


def test_view_checks_and_opens_an_rrd(rrd: Path, fake_viewer: Path) -> None:
    r = run(str(rrd))
    assert r.exit_code == 0, explain(r)
    assert fake_viewer.read_text() == str(rrd)


def test_no_open_only_checks_and_save_copies(rrd: Path, tmp_path: Path) -> None:
    out = tmp_path / "copy" / "kept.rrd"
    r = run(str(rrd), "--no-open", "--save", str(out))
    assert r.exit_code == 0, explain(r)
    assert out.read_bytes() == rrd.read_bytes()
    assert r.stdout.strip() == str(out)
    assert "readable Rerun recording" in r.stderr and "not opened" in r.stderr


@pytest.mark.parametrize("content", [None, b"", b"not a rerun file at all", "truncated"])
def test_missing_or_garbled_rrd_is_one_line_exit_3(tmp_path: Path, rrd: Path,
                                                    content: bytes | str | None) -> None:
    path = tmp_path / "bad.rrd"
    if content == "truncated":
        path.write_bytes(rrd.read_bytes()[:2000])
    elif isinstance(content, bytes):
        path.write_bytes(content)
    r = run(str(path), "--no-open")
    assert r.exit_code == 3, explain(r)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("impactcli: error: ") and str(path) in lines[0]
    assert "Traceback" not in r.stderr


def test_viewer_failure_is_a_clean_error(rrd: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(view_mod, "viewer_command",
                        lambda path: [sys.executable, "-c", "raise SystemExit(7)"])
    r = run(str(rrd))
    assert r.exit_code == 69, explain(r)  # the machine's, not the input's
    assert "status 7" in r.stderr and "--no-open --save PATH" in r.stderr


def test_no_display_is_exit_69_before_any_work(rrd: Path, tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Without a display the viewer cannot open: exit 69 (EX_UNAVAILABLE, not 'bad input'),
    one line saying what works instead, and a log is not replayed first."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    replayed = []
    monkeypatch.setattr("impactcli.run.job.run_log_from_paths", lambda *a, **k: replayed.append(a))
    log = tmp_path / "arm.csv"
    log.write_text("time\n0\n")
    for source in (rrd, log):
        r = run(str(source))
        assert r.exit_code == 69, explain(r)
        assert r.stderr == ("impactcli: error: no display here (DISPLAY and WAYLAND_DISPLAY "
                            "are not set): the Rerun viewer needs one; write the recording "
                            "with --no-open --save PATH and open it where there is a screen "
                            "(rerun PATH)\n")
    assert replayed == []
    assert run(str(rrd), "--no-open").exit_code == 0  # checking needs no display
    # a timeline is no log nor recording: said as bad input whether or not a display is
    # here (a trial got "no display", exit 69, and exit 3 with --no-open)
    tl = tmp_path / "arm.timeline.json"
    tl.write_text("{}")
    for extra in ((), ("--no-open", "--save", str(tmp_path / "x.rrd"))):
        r = run(str(tl), *extra)
        assert r.exit_code == 3 and "a JSON file, not a log nor a Rerun recording" \
            in r.stderr, explain(r)
    assert not (tmp_path / "x.rrd").exists()


def test_log_is_detected_then_written_and_opened(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 fake_viewer: Path) -> None:
    log = tmp_path / "arm.csv"
    log.write_text("time\n0\n")
    seen = {}

    def fake_stream(path: str, *, rrd_path: Path, rrd_options: dict[str, float],
                    **kw: object) -> object:
        """The replay (streamed: tests/test_view_evaluate_stream.py) of a known result."""
        seen["path"], seen["kw"] = Path(path), kw
        result = fake_result()
        write_rrd(result, rrd_path, **rrd_options)  # type: ignore[arg-type]
        return result, None

    monkeypatch.setattr("impactcli.run.job.run_log_from_paths", fake_stream)
    out = tmp_path / "arm.rrd"
    r = run(str(log), "--no-open", "--save", str(out), "--channel-map", "kuka_lwr4")
    assert r.exit_code == 0, explain(r)
    assert seen["path"] == log
    assert seen["kw"]["read_options"] == ReadOptions(channel_map="kuka_lwr4")
    reader = rr.chunk.RrdReader(out)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1
    assert not fake_viewer.exists()
    # without --save: a temporary file, opened, then removed
    r = run(str(log))
    assert r.exit_code == 0, explain(r)
    opened = Path(fake_viewer.read_text())
    assert opened.name == "arm.rrd" and not opened.exists()


def test_log_with_no_open_needs_save(tmp_path: Path) -> None:
    log = tmp_path / "arm.csv"
    log.write_text("time\n0\n")
    r = run(str(log), "--no-open")
    assert r.exit_code == 2, explain(r)


def test_missing_log_is_exit_3(tmp_path: Path) -> None:
    r = run(str(tmp_path / "nope.mcap"), "--no-open", "--save", str(tmp_path / "x.rrd"))
    assert r.exit_code == 3, explain(r)
    assert "nope.mcap" in r.stderr


def test_real_pipeline_on_a_csv(tmp_path: Path) -> None:
    """End to end through the real reader and replay."""
    log = make_log(n=5000, dt=0.002)
    path = tmp_path / "arm.csv"
    cols = {"time": log.time_s}
    for j, name in enumerate(log.joint_names):
        cols[f"{name}.position"] = log.position[:, j]
        cols[f"{name}.torque"] = log.torque[:, j]
        assert log.position_ref is not None
        cols[f"{name}.position_ref"] = log.position_ref[:, j]
    data = np.column_stack(list(cols.values()))
    np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="", fmt="%.9g")
    out = tmp_path / "arm.rrd"
    r = run(str(path), "--no-open", "--save", str(out))  # warnings are printed by the CLI
    assert r.exit_code == 0, explain(r)
    reader = rr.chunk.RrdReader(out)
    paths = {ch.entity_path for ch in reader.store().stream()}
    assert {"/joints/j1/rms", "/joints/j2/position"} <= paths
