"""A git worktree of another commit, for the benchmarks' ``--release REF``: its
``impactcli`` is imported by a child process given ``PYTHONPATH`` (and a working folder
outside the repository, so that ``-c`` does not import the repository's code first)."""

from __future__ import annotations

import contextlib
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


@contextlib.contextmanager
def release_tree(ref: str | None) -> Iterator[Path | None]:
    """A detached worktree of ``ref`` for the block (None: no ref, or it does not exist)."""
    if not ref:
        yield None
        return
    tmp = Path(tempfile.mkdtemp(prefix="impactcli-release-"))
    where = tmp / "tree"
    p = subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(where), ref],
                       capture_output=True, text=True, check=False)
    if p.returncode != 0:
        print(f"release {ref!r} not measured: {p.stderr.strip()}")
        yield None
        return
    try:
        yield where
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(where)],
                       capture_output=True, check=False)
