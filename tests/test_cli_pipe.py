"""stdout's reader closing early (``impactcli detect ... | head -1``) is not a bug: the CLI
exits quietly with 141 (128 + SIGPIPE, the shell's code for a process a closed pipe ended),
never 70 with a BrokenPipeError traceback, and the outputs already written stay."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import click
from click.testing import CliRunner

from impactcli.cli import EXIT_BROKEN_PIPE, main

REPO = Path(__file__).resolve().parents[1]
LOG = REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz"
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"
CLI = [sys.executable, "-m", "impactcli"]


def test_exit_code_is_the_shells_sigpipe_code():
    assert EXIT_BROKEN_PIPE == 128 + 13


def test_detect_into_a_closed_pipe_exits_141_quietly(tmp_path: Path) -> None:
    """The reader is gone before detect prints its table: exit 141, nothing on stderr, the
    timeline written."""
    r, w = os.pipe()
    os.close(r)
    try:
        proc = subprocess.run([*CLI, "detect", str(LOG), "--config", str(CONFIG),
                               "-o", str(tmp_path / "out")],
                              stdout=w, stderr=subprocess.PIPE, text=True, timeout=300,
                              check=False)
    finally:
        os.close(w)
    assert proc.returncode == 141, proc.stderr
    assert proc.stderr == ""
    assert (tmp_path / "out" / "assist_free_p2p.timeline.json").is_file()


def test_detect_piped_into_a_reader_of_one_line(tmp_path: Path) -> None:
    """``impactcli detect LOG --config C -o DIR | python -c "sys.stdin.readline()"``: never
    a traceback, never 70. Whether the CLI still had lines to write when the reader left is
    a race (it prints its table in a burst), hence 0 or 141; the tests around this one pin
    141 without the race."""
    reader = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.readline()"],
                              stdin=subprocess.PIPE)
    assert reader.stdin is not None
    try:
        proc = subprocess.run([*CLI, "detect", str(LOG), "--config", str(CONFIG),
                               "-o", str(tmp_path / "out")],
                              stdout=reader.stdin, stderr=subprocess.PIPE, text=True,
                              timeout=300, check=False)
    finally:
        reader.stdin.close()
    assert reader.wait(timeout=60) == 0
    assert "Traceback" not in proc.stderr and "BrokenPipeError" not in proc.stderr
    assert proc.returncode in (0, EXIT_BROKEN_PIPE), proc.stderr
    assert (tmp_path / "out" / "assist_free_p2p.timeline.json").is_file()


def test_reader_leaving_after_the_first_line_exits_141(tmp_path: Path, monkeypatch) -> None:
    """Deterministic ``| head -1``: stdout breaks on the second line detect prints (as a
    pipe does once its reader has left). Exit 141, no traceback, the timeline written."""
    real_echo = click.echo
    lines = []

    def echo(message: object = None, file: object = None, nl: bool = True,
             err: bool = False, color: object = None) -> None:
        if not err and file is None:
            lines.append(message)
            if len(lines) > 1:
                raise BrokenPipeError(32, "Broken pipe")
        real_echo(message, file=file, nl=nl, err=err, color=color)  # type: ignore[arg-type]

    monkeypatch.setattr(click, "echo", echo)
    res = CliRunner().invoke(main, ["detect", str(LOG), "--config", str(CONFIG),
                                    "-o", str(tmp_path / "out")])
    assert len(lines) == 2
    assert res.exit_code == EXIT_BROKEN_PIPE, res.output
    assert "Traceback" not in res.stderr and "internal error" not in res.stderr
    assert res.stdout == f"{lines[0]}\n"
    assert (tmp_path / "out" / "assist_free_p2p.timeline.json").is_file()


def test_help_documents_141() -> None:
    res = CliRunner().invoke(main, ["--help"])
    assert "141 stdout's reader closed early (| head), as for SIGPIPE." in " ".join(
        res.stdout.split())


def test_readme_documents_141() -> None:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert "| 141 | stdout's reader closed early" in readme
