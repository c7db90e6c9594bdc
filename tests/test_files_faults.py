"""An output that cannot be written (issue "Faults"): a full disk — injected as ENOSPC at
the one seam every writer goes through (:func:`impactcli.files.sync_output`), and on a real
small tmpfs where this machine lets a test mount one — is exit 2 naming the output and the
reason, whichever writer meets it; nothing truncated is ever moved under its final name; a
batch line names its log; a name with a newline stays one line."""

from __future__ import annotations

import errno
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from impactcli import files
from impactcli.files import part_path, process_running, remove_stale_parts
from impactcli.logs import read_log, write_log

from .cli_run import cli

REPO = Path(__file__).resolve().parents[1]
LOG = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"
ENOSPC = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


@pytest.fixture(scope="module")
def small_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The first 3000 samples (6 s) of a collision-free sample log, as CSV."""
    path = tmp_path_factory.mktemp("logs") / "x.csv"
    write_log(read_log(LOG).slice(0, 3000), path)
    return path


def _full_disk_for(monkeypatch: pytest.MonkeyPatch, *suffixes: str) -> list[str]:
    """Make the disk "full" for outputs whose name ends with one of ``suffixes``: the
    flush of their temporary file fails with ENOSPC. Returns the targets hit."""
    real = files.sync_output
    hit: list[str] = []

    def sync(tmp: str | os.PathLike[str]) -> None:
        name = Path(tmp).name
        if any(f"{s}." in name for s in suffixes):
            hit.append(name)
            raise ENOSPC
        real(tmp)

    monkeypatch.setattr(files, "sync_output", sync)
    return hit


@pytest.mark.parametrize(("flags", "full", "named"), [
    (["--signals"], [".signals.parquet"], "x.signals.parquet"),
    (["--rerun"], [".rrd"], "x.rrd"),
    (["--signals", "--rerun"], [".signals.parquet", ".rrd"], "x.rrd"),  # the .rrd is first
    ([], [".timeline.json"], "x.timeline.json"),
])
def test_a_full_disk_is_exit_2_naming_the_output_and_leaves_nothing(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, small_log: Path, flags: list[str],
        full: list[str], named: str) -> None:
    hit = _full_disk_for(monkeypatch, *full)
    out = tmp_path / "out"
    code, _, err = cli("detect", str(small_log), "--config", str(CONFIG), *flags,
                       "-o", str(out))
    assert hit, "the writer never reached the seam"
    assert code == 2
    assert err.splitlines() == [
        f"impactcli: error: cannot write {out / named}: No space left on device"]
    # nothing under a final name of what failed, and no temporary file anywhere
    left = sorted(p.name for p in out.iterdir())
    assert not [n for n in left if n.endswith(".part")]
    assert not [n for n in left if any(n.endswith(s) for s in full)]
    assert "x.timeline.json" not in left  # the run failed: no timeline claims it


def test_a_full_disk_under_the_report_is_exit_2_naming_it(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, small_log: Path) -> None:
    _full_disk_for(monkeypatch, ".html")
    out = tmp_path / "rep"
    code, _, err = cli("report", str(small_log), "--config", str(CONFIG),
                       "-o", str(out / "r.html"), "--json", str(out / "r.json"))
    assert code == 2
    assert err.splitlines()[-1] == (
        f"impactcli: error: cannot write {out / 'r.html'}: No space left on device")
    assert not (out / "r.html").exists()
    assert not list(out.glob(".*.part"))


def _truncating(monkeypatch: pytest.MonkeyPatch, suffix: str, cut: int) -> None:
    """A writer that loses the tail of its file without any error (what a sink that died
    quietly leaves): ``cut`` bytes gone from outputs ending with ``suffix``."""
    real = files.sync_output

    def sync(tmp: str | os.PathLike[str]) -> None:
        if f"{suffix}." in Path(tmp).name:
            size = Path(tmp).stat().st_size
            os.truncate(tmp, size - cut)
        real(tmp)

    monkeypatch.setattr(files, "sync_output", sync)


@pytest.mark.parametrize(("flags", "suffix", "why"), [
    (["--rerun"], ".rrd", "no RRD footer: the recording is truncated"),
    (["--signals"], ".signals.parquet", "bytes on disk of"),
    ([], ".timeline.json", "bytes on disk of"),
])
def test_a_truncated_output_is_never_moved_into_place(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, small_log: Path, flags: list[str],
        suffix: str, why: str) -> None:
    _truncating(monkeypatch, suffix, cut=7)
    out = tmp_path / "out"
    code, _, err = cli("detect", str(small_log), "--config", str(CONFIG), *flags,
                       "-o", str(out))
    assert code == 2
    [line] = err.splitlines()
    assert line.startswith(f"impactcli: error: cannot write {out}/x{suffix}: ")
    assert why in line
    assert not [p for p in out.iterdir() if p.name.endswith((suffix, ".part"))]


def test_verify_rrd_tells_a_whole_recording_from_a_cut_one(tmp_path: Path) -> None:
    from impactcli.outputs.rerun import verify_rrd

    from .fakes import fake_result, write_fake_rrd

    whole = tmp_path / "whole.rrd"
    write_fake_rrd(fake_result(), whole)
    verify_rrd(whole)  # the writer's own output passes
    data = whole.read_bytes()
    for cut in (1, 32, len(data) // 2):
        p = tmp_path / f"cut{cut}.rrd"
        p.write_bytes(data[:-cut])
        with pytest.raises(ValueError, match="truncated"):
            verify_rrd(p)


def test_verify_parquet_tells_a_whole_signals_file_from_a_cut_one(tmp_path: Path) -> None:
    from impactcli.outputs.signals import verify_parquet

    from .fakes import fake_result, write_fake_signals

    res = fake_result()
    whole = tmp_path / "whole.signals.parquet"
    write_fake_signals(res, whole)
    verify_parquet(whole, res.log.n_samples)
    with pytest.raises(ValueError, match="rows read back"):
        verify_parquet(whole, res.log.n_samples + 1)
    data = whole.read_bytes()
    for cut in (1, 100, len(data) // 2):
        p = tmp_path / f"cut{cut}.parquet"
        p.write_bytes(data[:-cut])
        with pytest.raises(ValueError, match="truncated"):
            verify_parquet(p, res.log.n_samples)


def test_an_oserror_without_a_file_name_does_not_blame_the_log(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, small_log: Path) -> None:
    """ENOSPC met by any code of the job (here: the timeline's writer) is the output's
    fault, exit 2; another I/O error without a file name is not said to be "on" the log."""
    from impactcli.outputs import timeline

    def no_space(*a: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(timeline, "atomic_write_text", no_space)
    out = tmp_path / "out"
    code, _, err = cli("detect", str(small_log), "--config", str(CONFIG), "-o", str(out))
    assert code == 2
    assert err.splitlines() == [f"impactcli: error: {small_log}: cannot write its outputs "
                                f"in {out}: No space left on device"]

    def einval(*a: object) -> None:  # not transient: not retried
        raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))

    monkeypatch.setattr(timeline, "atomic_write_text", einval)
    code, _, err = cli("detect", str(small_log), "--config", str(CONFIG), "-o", str(out))
    assert code == 3
    assert err.splitlines() == [f"impactcli: error: {small_log}: I/O error: Invalid argument"]


def test_a_full_disk_in_a_batch_names_each_log(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, small_log: Path) -> None:
    _full_disk_for(monkeypatch, ".rrd")
    second = tmp_path / "y.csv"
    shutil.copy(small_log, second)
    out = tmp_path / "out"
    code, _, err = cli("detect", str(small_log), str(second), "--config", str(CONFIG),
                       "--rerun", "-o", str(out))
    assert code == 2
    assert [ln for ln in err.splitlines() if ln.startswith("impactcli: error: ")] == [
        f"impactcli: error: {log}: cannot write {out / log.stem}.rrd: No space left on device"
        for log in (small_log, second)]


def test_a_full_tmpdir_in_a_batch_names_each_log(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, small_log: Path) -> None:
    from impactcli.spill import ColumnFiles

    def full(*a: object, **k: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    # every write of the temporary store fails: the scan's cache gives itself up (the file
    # is read again), the replay's first spill stops the log with exit 2
    monkeypatch.setattr(ColumnFiles, "_write", staticmethod(full))
    second = tmp_path / "y.csv"
    shutil.copy(small_log, second)
    code, _, err = cli("detect", str(small_log), str(second), "--config", str(CONFIG),
                       "--rerun", "-o", str(tmp_path / "out"))
    assert code == 2  # every log failed: the failure's own code
    lines = [ln for ln in err.splitlines() if ln.startswith("impactcli: error: ")]
    assert len(lines) == 2
    for log, line in zip((small_log, second), lines, strict=True):
        assert line.startswith(f"impactcli: error: {log}: temporary folder ")
        assert "No space left on device" in line


def test_a_newline_in_a_name_stays_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "a\nb.csv"
    bad.write_text("not,a\nlog\n", encoding="utf-8")
    code, _, err = cli("detect", str(bad), "-o", str(tmp_path / "out"))
    assert code == 3
    [line] = err.splitlines()
    assert f"{tmp_path}/a\\nb.csv: " in line


def test_stale_parts_of_dead_writers_are_removed_and_live_ones_kept(tmp_path: Path) -> None:
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead_pid = int(dead.stdout)
    assert not process_running(dead_pid)
    target = tmp_path / "x.timeline.json"
    mine = part_path(target)  # this process writes it: kept
    killed = tmp_path / f".x.rrd.{dead_pid}-0123abcd.part"
    killed.write_bytes(b"half")
    old_legacy = tmp_path / ".x.signals.parquet.k3j4h5g6.part"  # an older version's name
    old_legacy.write_bytes(b"half")
    os.utime(old_legacy, (0, 0))
    new_legacy = tmp_path / ".y.rrd.a1b2c3d4.part"
    new_legacy.write_bytes(b"half")
    assert sorted(remove_stale_parts(tmp_path)) == sorted([killed, old_legacy])
    assert mine.exists() and new_legacy.exists()


def test_temporary_folders_of_killed_runs_are_removed_and_said(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A trial's ``kill -9`` left ~60 MB in /tmp/impactcli-{scan,rrd,warmup,islands}-*,
    which no rerun removed. The folders now carry their process's id; a run's first step
    removes those whose process is gone, and older versions' (no id) after an hour, and
    says so; a running process's stay, and so does anything else in TMPDIR."""
    import tempfile

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead_pid = int(dead.stdout)
    assert not process_running(dead_pid)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    killed = [tmp / f"impactcli-{w}-{dead_pid}-{r}" for w, r in (("scan", "j0wnakl6"),
                                                                ("rrd", "a_b1c2d3"))]
    for k, d in enumerate(killed):
        (d / "sub").mkdir(parents=True)
        (d / "sub" / "x.bin").write_bytes(b"\0" * (1000 * (k + 1)))
    old = tmp / "impactcli-warmup-u0_acegt"  # an older version's, two hours old
    old.mkdir()
    (old / "y").write_bytes(b"\0" * 500)
    os.utime(old, (0, 0))
    keep = [tmp / f"impactcli-scan-{os.getpid()}-abcdefgh",  # this (running) process's
            tmp / "impactcli-islands-k3j4h5g6",            # an older version's, just made
            tmp / f"impactcli-scan-{dead_pid}-abc",         # not a name of ours
            tmp / "impactcli-release-notes-20240101",       # nor this (hyphens, no pid)
            tmp / "other-tool-xyz"]
    for d in keep:
        d.mkdir()
    os.utime(keep[-2], (0, 0))  # old enough to go, were it ours
    code, _, err = cli("inspect", str(LOG))
    assert code == 0, err
    said = [ln for ln in err.splitlines() if "temporary folder" in ln]
    assert said == [f"impactcli: removed 3 temporary folder(s) (0.0035 MB) that runs since "
                    f"killed had left in {tmp}"], err
    assert not any(d.exists() for d in [*killed, old])
    assert all(d.exists() for d in keep)
    assert files.remove_stale_temp(tmp) == (0, 0)
    # every prefix the tool makes a temporary folder with is told as a killed run's
    said_prefixes = set()
    for src in (Path(files.__file__).parent).rglob("*.py"):
        said_prefixes |= set(re.findall(r'(?:ColumnFiles|temporary_folder)\("(impactcli-[^"]*)"',
                                        src.read_text(encoding="utf-8")))
    assert {"impactcli-report-q-", "impactcli-scan-", "impactcli-url-"} <= said_prefixes
    made_dead = [tmp / f"{pre}{dead_pid}-a1b2c3d4" for pre in sorted(said_prefixes)]
    for d in made_dead:
        d.mkdir()
    assert files.remove_stale_temp(tmp)[0] == len(made_dead)
    assert not any(d.exists() for d in made_dead) and all(d.exists() for d in keep)
    # this process's folders carry its id
    with files.temporary_folder("impactcli-url-") as made:
        assert made.name.startswith(f"impactcli-url-{os.getpid()}-") and made.parent == tmp


needs_root_mount = pytest.mark.skipif(
    not sys.platform.startswith("linux") or os.geteuid() != 0 or shutil.which("mount") is None,
    reason="mounting a tmpfs needs root on Linux (the injected-ENOSPC tests cover the rest)")


@pytest.fixture
def tiny_disk(tmp_path: Path) -> object:
    """A 512 KiB tmpfs (root only); skipped where it cannot be mounted."""
    mnt = tmp_path / "tiny"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=512k", "tmpfs", str(mnt)],
                       capture_output=True, text=True, check=False)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


@needs_root_mount
@pytest.mark.parametrize("flag", ["--rerun", "--signals"])
def test_a_real_full_disk_fails_fast_with_exit_2(tiny_disk: Path, flag: str) -> None:
    """The whole 40 s sample log (a 2.9 MB recording, 1 MB of signals) into 512 KiB: exit
    2 within the timeout (never a hang), one line naming the output, nothing left."""
    out = tiny_disk / "out"
    proc = subprocess.run([sys.executable, "-m", "impactcli", "detect", str(LOG), "--config",
                           str(CONFIG), flag, "-o", str(out)],
                          capture_output=True, text=True, timeout=60, check=False)
    name = "assist_free_p2p.rrd" if flag == "--rerun" else "assist_free_p2p.signals.parquet"
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.splitlines() == [
        f"impactcli: error: cannot write {out / name}: No space left on device"
        + (" (the Rerun SDK's file writer stopped)" if flag == "--rerun" else "")]
    assert list(out.iterdir()) == []


def test_a_sink_that_never_finishes_is_given_up_on(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, small_log: Path) -> None:
    """The fallback for an SDK that blocks on a failed file sink: the flush waited for at
    most SINK_TIMEOUT_S, then exit 2 naming the recording, and nothing left."""
    import threading
    import time

    import rerun as rr

    from impactcli.outputs import rerun as writer

    release = threading.Event()
    real_flush = rr.RecordingStream.flush

    def hung_flush(self: rr.RecordingStream, *a: object, **k: object) -> None:
        release.wait(30)  # a sink that does not answer (released at the end of the test)
        real_flush(self)

    monkeypatch.setattr(rr.RecordingStream, "flush", hung_flush)
    monkeypatch.setattr(writer, "SINK_TIMEOUT_S", 0.5)
    out = tmp_path / "out"
    t0 = time.monotonic()
    try:
        code, _, err = cli("detect", str(small_log), "--config", str(CONFIG), "--rerun",
                           "-o", str(out))
    finally:
        release.set()
    assert time.monotonic() - t0 < 15
    assert code == 2
    assert err.splitlines() == [
        f"impactcli: error: cannot write {out / 'x.rrd'}: the Rerun SDK did not "
        "finish its file within 0.5 s (a full or failed disk?); given up"]
    assert not [p for p in out.iterdir() if p.name.endswith((".rrd", ".part"))]


def test_a_newline_in_a_log_name_stays_one_line_in_the_table(
        tmp_path: Path, small_log: Path) -> None:
    odd = tmp_path / "odd\nname.csv"
    shutil.copy(small_log, odd)
    code, out, _ = cli("detect", str(odd), "--config", str(CONFIG), "-o", str(tmp_path / "o"))
    assert code == 0
    rows = [ln for ln in out.splitlines() if ln.startswith("odd")]
    assert len(rows) == 1 and rows[0].startswith("odd\\nname.csv ")
