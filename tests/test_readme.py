"""The README is the user's page: short, and its four steps work as written."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"


def test_readme_is_at_most_15_kB_and_points_only_inside_the_repo() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.encode()) <= 15_000
    for target in re.findall(r"\]\(([^)#]+)", text):
        if "://" not in target:
            assert (REPO / target).exists(), target
    assert "../shared" not in text and not re.search(r"\bissue \d", text)


def four_steps() -> list[str]:
    """The commands of the 'four steps' block, continuation lines joined."""
    text = README.read_text(encoding="utf-8")
    block = text.split("## Your own robot in four steps", 1)[1].split("```sh", 1)[1]
    block = block.split("```", 1)[0].replace("\\\n", " ")
    return [ln.strip() for ln in block.splitlines() if ln.strip().startswith("impactcli ")]


@pytest.mark.slow
def test_the_four_steps_work_as_written(tmp_path: Path) -> None:
    cmds = four_steps()
    assert [c.split()[1] for c in cmds] == ["inspect", "calibrate", "detect", "report"]
    exe = Path(sys.executable).parent / "impactcli"
    if not exe.exists():
        pytest.skip("the impactcli script is not installed beside this Python")
    bash = shutil.which("bash")
    assert bash is not None
    env = {**os.environ, "PATH": f"{exe.parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    for line in cmds:
        cmd = line.replace("my_robot.toml", str(tmp_path / "my_robot.toml")).replace(
            "out/audit", str(tmp_path / "audit"))
        r = subprocess.run([bash, "-c", cmd], cwd=REPO, env=env, capture_output=True,
                           text=True, timeout=300, check=False)
        assert r.returncode == 0, f"{cmd}\n{r.stdout}\n{r.stderr}"
    assert (tmp_path / "audit" / "report.html").stat().st_size > 10_000
    out = (tmp_path / "audit" / "assist_pushes.timeline.json").read_text()
    assert '"incidents"' in out


def test_docs_point_only_inside_the_repo() -> None:
    """docs/*.md name real data by its public source, never by a folder outside the repo
    (a reader's checkout has no ../shared): every relative link and every quoted ../ path
    stays inside the repository."""
    root = REPO.resolve()
    for doc in sorted((REPO / "docs").glob("*.md")):
        text = doc.read_text(encoding="utf-8")
        assert "../shared" not in text and "shared/real_logs" not in text, doc.name
        targets = re.findall(r"\]\(([^)#]+)", text) + re.findall(r"`(\.\./[^`\s]*)", text)
        for target in targets:
            if "://" not in target:
                resolved = (doc.parent / target).resolve()
                assert resolved.is_relative_to(root), (doc.name, target)
