"""A batch stopped by a signal or killed (issue "Faults"), through the CLI in a subprocess:
SIGINT exits 130 and SIGTERM 143, serial and ``--jobs 2``, within a bounded time, with no
temporary file left and every output written valid; ``kill -9`` of the main process leaves
no process of its pool behind; a rerun into the same folder gives the timelines of a clean
run byte for byte. Linux only (the process tree is read from /proc)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from impactcli.files import process_running
from impactcli.logs import read_log, write_log
from impactcli.outputs.rerun import verify_rrd
from impactcli.outputs.signals import verify_parquet
from impactcli.outputs.timeline import read_timeline

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(),
                                reason="reads the process tree from /proc (Linux)")

REPO = Path(__file__).resolve().parents[1]
LOG = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"
N_LOGS = 10
#: Bound on a stop: from the signal to the exit [s].
STOP_BOUND_S = 10.0


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """N_LOGS copies of the first 6000 samples (12 s) of a collision-free sample log."""
    d = tmp_path_factory.mktemp("logs")
    first = d / "l00.csv"
    write_log(read_log(LOG).slice(0, 6000), first)
    out = [first]
    for k in range(1, N_LOGS):
        out.append(d / f"l{k:02d}.csv")
        shutil.copy(first, out[-1])
    return out


def _start(logs: list[Path], out: Path, tmpdir: Path, *extra: str) -> subprocess.Popen[str]:
    tmpdir.mkdir(exist_ok=True)
    env = {**os.environ, "TMPDIR": str(tmpdir)}
    return subprocess.Popen(
        [sys.executable, "-m", "impactcli", "detect", *map(str, logs), "--config", str(CONFIG),
         "-o", str(out), *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        start_new_session=True)  # its own process group: a Ctrl-C reaches all of it, only it


def _wait_for_output(proc: subprocess.Popen[str], out: Path, timeout_s: float = 60.0) -> None:
    """Until the batch has written its first timeline (it is under way, not done)."""
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        if out.is_dir() and any(out.glob("*.timeline.json")):
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    raise AssertionError("no output within the timeout")


def _descendants(pid: int) -> set[int]:
    """Every process under ``pid`` now (from /proc)."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found: set[int] = set()
    todo = [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            if c not in found:
                found.add(c)
                todo.append(c)
    return found


def _wait_gone(pids: set[int], timeout_s: float) -> set[int]:
    """The processes of ``pids`` still running after at most ``timeout_s``."""
    t_end = time.monotonic() + timeout_s
    alive = {p for p in pids if process_running(p)}
    while alive and time.monotonic() < t_end:
        time.sleep(0.05)
        alive = {p for p in alive if process_running(p)}
    return alive


@pytest.fixture
def reaper() -> Iterator[list[subprocess.Popen[str]]]:
    """Processes a test started: killed with their group (and anything left under them)
    when the test ends, whatever happened."""
    procs: list[subprocess.Popen[str]] = []
    yield procs
    for p in procs:
        rest = _descendants(p.pid)
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
        p.communicate(timeout=10)  # reaped, its pipes closed
        for pid in rest:
            if process_running(pid):
                os.kill(pid, signal.SIGKILL)


def _check_outputs(out: Path, tmpdir: Path, extras: bool) -> int:
    """No temporary file in ``out`` or TMPDIR; every timeline valid, and with ``extras``
    every log with a timeline has its signals and recording, each whole. Returns the
    number of timelines."""
    assert not [p.name for p in out.iterdir() if p.name.endswith(".part")]
    assert not [p.name for p in tmpdir.iterdir() if p.name.startswith("impactcli-")]
    timelines = sorted(out.glob("*.timeline.json"))
    for t in timelines:
        doc = read_timeline(t)  # parses and validates against its schema
        stem = t.name[: -len(".timeline.json")]
        if extras:
            verify_rrd(out / f"{stem}.rrd")
            verify_parquet(out / f"{stem}.signals.parquet", doc["input"]["n_samples"])
    return len(timelines)


#: serial: with the signals and the recording (their writers stopped mid-way); --jobs 2:
#: the timelines only (a pool's start is the test's cost)
RUNS = {"serial": ["--signals", "--rerun"], "jobs2": ["--jobs", "2"]}


@pytest.mark.parametrize("run", list(RUNS))
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_stops_the_batch_with_the_shell_code(
        logs: list[Path], tmp_path: Path, reaper: list[subprocess.Popen[str]], run: str,
        sig: signal.Signals) -> None:
    out, tmpdir = tmp_path / "out", tmp_path / "tmp"
    summary = tmp_path / "summary.json"
    proc = _start(logs, out, tmpdir, *RUNS[run], "--summary", str(summary))
    reaper.append(proc)
    _wait_for_output(proc, out)
    tree = _descendants(proc.pid)
    t0 = time.monotonic()
    if sig == signal.SIGINT:  # Ctrl-C: the terminal signals the whole foreground group
        os.killpg(proc.pid, sig)
    else:  # a supervisor's SIGTERM: the main process only
        os.kill(proc.pid, sig)
    _, err = proc.communicate(timeout=STOP_BOUND_S * 3)
    assert time.monotonic() - t0 < STOP_BOUND_S
    assert proc.returncode == 128 + sig, err
    assert f"impactcli: stopped by {sig.name}: the outputs already written stay " \
           f"(exit {128 + sig})" in err.splitlines()
    assert "Traceback" not in err
    done = _check_outputs(out, tmpdir, extras=run == "serial")
    assert 1 <= done < N_LOGS  # stopped early: nothing more dispatched after the signal
    assert f"impactcli: {done} of {N_LOGS} logs finished before the stop; run the same " \
           "command again to redo the batch" in err.splitlines()
    assert not _wait_gone(tree, 5.0), "processes of the run left behind"
    # the summary says the batch stopped, of how many (a trial's read "done 4, total 4" of
    # 8, no word of the stop)
    import json

    doc = json.loads(summary.read_text("utf-8"))
    n = doc["logs"]
    assert doc["stopped"] is True and n["total"] == N_LOGS and n["done"] <= done
    assert n["not_run"] == N_LOGS - n["done"] - n["failed"] >= 1 and "gates" not in doc


def test_kill_9_of_a_pool_batch_leaves_no_process(
        logs: list[Path], tmp_path: Path, reaper: list[subprocess.Popen[str]]) -> None:
    out, tmpdir = tmp_path / "out", tmp_path / "tmp"
    proc = _start(logs, out, tmpdir, "--jobs", "2")
    reaper.append(proc)
    _wait_for_output(proc, out)
    tree = _descendants(proc.pid)
    assert len(tree) >= 3  # the fork server, the resource tracker, the workers
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(10)
    assert not _wait_gone(tree, 8.0), "the pool outlived its main process"
    assert len(list(out.glob("*.timeline.json"))) < N_LOGS
    assert not [p.name for p in out.iterdir() if p.name.endswith(".part")]  # workers unwound


def test_a_rerun_after_a_kill_gives_a_clean_runs_timelines(
        logs: list[Path], tmp_path: Path, reaper: list[subprocess.Popen[str]],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Killed mid-batch (kill -9: nothing of it runs, its temporary files stay in its
    TMPDIR), then the same command into the same folder: every log redone, the killed run's
    ``.part`` files gone, nothing of the rerun left in its own TMPDIR, the timelines those
    of a clean run byte for byte."""
    from click.testing import CliRunner

    from impactcli.cli import main

    batch = logs[:4]
    out, tmpdir = tmp_path / "out", tmp_path / "tmp"
    args = ["--signals", "--rerun"]
    proc = _start(batch, out, tmpdir, *args)
    reaper.append(proc)
    _wait_for_output(proc, out)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(10)
    assert len(list(out.glob("*.timeline.json"))) < len(batch)
    # what a writer killed mid-file leaves (planted too: the kill may fall between files)
    stale = out / f".l00.timeline.json.{proc.pid}-0badc0de.part"
    stale.write_text('{"half": ', encoding="utf-8")
    rerun_tmp = tmp_path / "rerun-tmp"  # the killed run's TMPDIR keeps what kill -9 left
    rerun_tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(rerun_tmp))
    r = CliRunner().invoke(main, ["detect", *map(str, batch), "--config", str(CONFIG),
                                  "-o", str(out), *args])
    assert r.exit_code == 0, r.stderr
    assert _check_outputs(out, rerun_tmp, extras=True) == len(batch)
    clean = tmp_path / "clean"
    r = CliRunner().invoke(main, ["detect", *map(str, batch), "--config", str(CONFIG),
                                  "-o", str(clean)])
    assert r.exit_code == 0, r.stderr
    for log in batch:
        name = f"{log.stem}.timeline.json"
        assert (out / name).read_bytes() == (clean / name).read_bytes(), name


def test_a_log_finished_as_the_stop_came_is_counted(tmp_path: Path) -> None:
    """A worker may write a log's timeline just before the stop while its outcome has not
    reached the main process: the stop's count finds it by its timeline, written during
    this run (an older one, from an earlier run into the folder, is not counted)."""
    from impactcli.run.batch import DetectJob, written_since

    jobs = [DetectJob(f"/logs/l{k}.csv", str(tmp_path)) for k in range(4)]
    started = time.time()
    (tmp_path / "l0.timeline.json").write_text("{}")  # its outcome arrived: in done
    (tmp_path / "l1.timeline.json").write_text("{}")  # finished as the stop came
    old = tmp_path / "l2.timeline.json"                # from an earlier run
    old.write_text("{}")
    os.utime(old, (started - 3600, started - 3600))
    assert written_since(jobs, {"/logs/l0.csv"}, started) == ["/logs/l1.csv"]
    assert written_since([DetectJob("/logs/l1.csv", "s3://bucket/out")], set(), started) == []


def test_a_signal_inside_a_c_callback_is_sent_again_not_raised_there(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A stop signal whose handler runs inside llvmlite's object-cache callback (numba
    compiling a kernel) would raise where the exception is printed with its traceback and
    dropped: the handler raises nothing there and sends the signal again DEFER_S later;
    anywhere else it raises Interrupted at once."""
    import threading

    from impactcli.errors import Interrupted
    from impactcli.run import stopping

    code = compile("import sys\nframe = sys._getframe()",
                   "/venv/site-packages/llvmlite/binding/executionengine.py", "exec")
    ns: dict = {}
    exec(code, ns)
    sent = threading.Event()
    calls: list[tuple[int, int]] = []

    def kill(pid: int, sig: int) -> None:
        calls.append((pid, sig))
        sent.set()

    monkeypatch.setattr(stopping.os, "kill", kill)
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        stopping._raise_interrupted(signal.SIGTERM, ns["frame"])  # no raise
        assert signal.getsignal(signal.SIGTERM) == old[signal.SIGTERM]  # still armed
        assert sent.wait(10 * stopping.DEFER_S)
        assert calls == [(os.getpid(), signal.SIGTERM)]
        with pytest.raises(Interrupted):
            stopping._raise_interrupted(signal.SIGTERM, sys._getframe())
        for s, h in old.items():
            signal.signal(s, h)
        # a folder merely named like it is no callback
        other = compile("import sys\nframe = sys._getframe()", "/home/u/llvmlite-notes/run.py",
                        "exec")
        exec(other, ns)
        with pytest.raises(Interrupted):
            stopping._raise_interrupted(signal.SIGTERM, ns["frame"])
        for s, h in old.items():
            signal.signal(s, h)
        # deferred at most MAX_DEFERRALS times in a row: then the stop raises where it is
        monkeypatch.setattr(stopping.threading, "Timer", lambda *a, **k: _NoTimer())
        for _ in range(stopping.MAX_DEFERRALS):
            stopping._raise_interrupted(signal.SIGTERM, ns_frame(ns, code))
        with pytest.raises(Interrupted):
            stopping._raise_interrupted(signal.SIGTERM, ns_frame(ns, code))
    finally:
        for s, h in old.items():
            signal.signal(s, h)


class _NoTimer:
    daemon = False

    def start(self) -> None:
        pass


def ns_frame(ns: dict, code: object) -> object:
    """A fresh frame of ``code`` (run in ``ns``)."""
    exec(code, ns)  # type: ignore[arg-type]
    return ns["frame"]


def test_a_stop_inside_a_whole_block_is_raised_as_the_block_ends() -> None:
    """A stop signal that lands in a file operation that must not be cut in half
    (:func:`impactcli.files.whole`) is held until the block has run to its end, then
    raised; outside such a block it is raised at once."""
    from impactcli.errors import Interrupted
    from impactcli.files import whole
    from impactcli.run.stopping import stop_on_signals

    steps: list[str] = []
    with stop_on_signals(), pytest.raises(Interrupted) as got, whole():
        os.kill(os.getpid(), signal.SIGINT)
        with whole():  # nested: held until the outer block ends
            steps.append("inner")
        steps.append("outer")
    assert steps == ["inner", "outer"] and got.value.signum == signal.SIGINT
    steps.clear()
    with stop_on_signals(), pytest.raises(Interrupted):
        os.kill(os.getpid(), signal.SIGTERM)
        steps.append("after")
    assert steps == []


def test_a_stop_during_a_temporary_folders_removal_or_making_leaves_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The signal lands while the folder is removed (a spill's close) or just after it is
    made (before its removal is registered): the run stops, the folder is gone."""
    from impactcli.errors import Interrupted
    from impactcli.files import temporary_folder
    from impactcli.run.stopping import stop_on_signals
    from impactcli.spill import SpillFolder

    real_rmtree, real_mkdtemp = shutil.rmtree, tempfile.mkdtemp

    def rmtree(path: str, *args: object, **kwargs: object) -> None:
        os.kill(os.getpid(), signal.SIGINT)  # its handler runs before the removal starts
        real_rmtree(path, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(shutil, "rmtree", rmtree)
    folder = SpillFolder("impactcli-spill-")
    assert folder.path is not None
    Path(folder.path, "values").write_bytes(b"\0" * 64)
    with stop_on_signals(), pytest.raises(Interrupted):
        folder.close()
    monkeypatch.setattr(shutil, "rmtree", real_rmtree)
    made: list[str] = []

    def mkdtemp(*args: object, **kwargs: object) -> str:
        made.append(real_mkdtemp(*args, **kwargs))  # type: ignore[call-overload]
        os.kill(os.getpid(), signal.SIGTERM)
        return made[-1]

    monkeypatch.setattr(tempfile, "mkdtemp", mkdtemp)
    entered: list[Path] = []
    with stop_on_signals(), pytest.raises(Interrupted), \
            temporary_folder("impactcli-out-") as tmp:
        entered.append(tmp)
    assert len(made) == 1 and entered == []
    assert list(tmp_path.iterdir()) == []


def test_a_stop_as_an_output_is_checked_leaves_no_part_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The signal lands after the output was written, as its size is checked before the
    move into place: the run stops, no ``.part`` file is left and the target is not
    written."""
    from impactcli import files
    from impactcli.errors import Interrupted
    from impactcli.run.stopping import stop_on_signals

    real = files.check_size

    def check_size(expected: int) -> object:
        os.kill(os.getpid(), signal.SIGINT)
        return real(expected)

    monkeypatch.setattr(files, "check_size", check_size)
    with stop_on_signals(), pytest.raises(Interrupted), \
            files.atomic_output(tmp_path / "out.bin") as f:
        f.write(b"abc")
    assert list(tmp_path.iterdir()) == []


def test_a_stopped_pools_manager_thread_is_gone_when_stop_workers_returns() -> None:
    """CPython's pool manager thread closes the pool's wake-up pipe as it ends, and the
    interpreter's exit writes to that pipe unguarded: stop_workers waits for the thread,
    so a stopped run's exit cannot print "Bad file descriptor"."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    from impactcli.run.stopping import stop_workers

    ex = ProcessPoolExecutor(max_workers=1, mp_context=mp.get_context("fork"))
    ex.submit(time.sleep, 30)
    manager = ex._executor_manager_thread  # type: ignore[attr-defined]
    assert manager is not None and manager.is_alive()
    t0 = time.monotonic()
    stop_workers(ex, grace_s=2.0)
    assert not manager.is_alive()
    assert time.monotonic() - t0 < 5.0


def _task_holding_a_store(folder: str) -> None:
    """A pool task stopped while it holds a spill store no ``try`` closes yet."""
    import tempfile as tf

    from impactcli.errors import Interrupted
    from impactcli.spill import SpillFolder

    tf.tempdir = folder
    store = SpillFolder("impactcli-scan-")
    assert store.path is not None
    raise Interrupted(signal.SIGTERM, "SIGTERM")


def _worker(folder: str) -> None:
    from impactcli.run.stopping import run_in_worker

    run_in_worker(_task_holding_a_store, folder)


def test_a_stopped_worker_removes_the_stores_its_task_held(tmp_path: Path) -> None:
    """A worker stopped by SIGTERM exits with os._exit, which runs no exit hook: a store
    its task made as the stop came, before a ``try`` would close it, is left to its
    finalizer — run before the exit (the task's frames collected), not skipped."""
    import multiprocessing as mp

    p = mp.get_context("fork").Process(target=_worker, args=(str(tmp_path),))
    p.start()
    p.join(30)
    assert p.exitcode == 128 + signal.SIGTERM
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_after_the_run_finished_is_said_and_ignored(tmp_path: Path, sig: int
                                                             ) -> None:
    """A trial's Ctrl-C landed 0.3 s after a finished run's last line, in the interpreter's
    teardown: exit 130 over a finished run, outputs complete, no "stopped" line. The signal
    is sent from the program's last ``atexit`` handler (the teardown, after the verb's exit
    code was decided): the exit code stays the run's — 0 for a clean log, 1 for one with
    contacts under --fail-on-detect — and one line says it was ignored."""
    hook = ("import atexit, os, signal, sys, time\n"
            "def late():\n"
            f"    os.kill(os.getpid(), {int(sig)}); time.sleep(0.2)\n"
            "atexit.register(late)\n"
            "sys.argv[0] = 'impactcli'\n"
            "from impactcli.cli import run\n"
            "run()\n")
    name = signal.Signals(sig).name
    for log, want in ((LOG, 0), (REPO / "sample_logs" / "csv" / "assist_impacts.csv.gz", 1)):
        p = subprocess.run([sys.executable, "-c", hook, "detect", str(log), "--config",
                            str(CONFIG), "-o", str(tmp_path / log.name), "--fail-on-detect"],
                           capture_output=True, text=True, timeout=300, check=False)
        assert p.returncode == want, p.stderr
        assert p.stderr.splitlines()[-1] == (f"impactcli: {name} after the run had finished: "
                                             "ignored — its outputs and exit code stand")
        assert "Traceback" not in p.stderr and "stopped by" not in p.stderr
        stem = log.name.split(".")[0]
        assert read_timeline(tmp_path / log.name / f"{stem}.timeline.json")
