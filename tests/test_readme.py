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


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    s = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return s.replace(" ", "-")


def _headings(doc: Path) -> list[str]:
    return [m.group(1).strip() for m in
            re.finditer(r"^#+\s+(.*)$", doc.read_text(encoding="utf-8"), re.MULTILINE)]


def test_every_citation_resolves_inside_the_repo() -> None:
    """The code, the docs and the schemas cite docs/ pages, numbered sections of the method
    (``docs/method.md §3``) and quoted sections (``docs/formats.md, "Time"``); each cited
    page, section and Markdown anchor exists in the repository."""
    sources = (sorted((REPO / "impactcli").rglob("*.py")) + sorted((REPO / "docs").glob("*.md"))
               + sorted((REPO / "schemas").glob("*.json")) + [README])
    docs = REPO / "docs"
    bad: list[str] = []
    for src in sources:
        text = re.sub(r"\s+", " ", src.read_text(encoding="utf-8").replace("\\u00a7", "§"))
        where = src.relative_to(REPO)
        # a page: docs/NAME.md anywhere; NAME.md in code and schemas (docs/ name files too)
        bare = r"(?<![\w./-])docs/(\w+)\.md\b" if src.suffix == ".md" else \
            r"(?<![\w./-])(?:docs/)?(\w+)\.md\b"
        for name in re.findall(bare, text):
            if name != "README" and not (docs / f"{name}.md").exists():
                bad.append(f"{where}: {name}.md")
        for name, sec in re.findall(r"(\w+)\.md\)?,? (§\w+)", text):
            if sec != "§N" and (docs / f"{name}.md").exists() and not any(
                    h.split()[0] == sec for h in _headings(docs / f"{name}.md")):
                bad.append(f"{where}: {name}.md {sec}")
        quoted = r"(\w+)\.md\)?,?(?: §\w+,?)? (?:\"([^\"]+)\"|'([^']+)')"
        for name, sec2, sec1 in re.findall(quoted, text):
            sec = sec2 or sec1
            if (not sec.startswith("<") and (docs / f"{name}.md").exists()
                    and sec not in _headings(docs / f"{name}.md")):
                bad.append(f'{where}: {name}.md, "{sec}"')
        for target, anchor in re.findall(r"\]\(([^)#\s]*\.md)#([^)\s]+)\)", text):
            page = (src.parent / target) if src.suffix == ".md" else REPO / target
            if page.exists() and anchor not in {_slug(h) for h in _headings(page)}:
                bad.append(f"{where}: {target}#{anchor}")
    assert not bad, "citations that do not resolve:\n" + "\n".join(bad)


def test_the_timeline_version_the_readme_and_schema_name_is_the_one_written() -> None:
    """README and schema annotation name the version `detect` writes (they had lagged)."""
    import json

    from impactcli.outputs.timeline import SCHEMA_VERSION

    text = README.read_text(encoding="utf-8")
    named = re.search(r"timeline\.schema\.json`, version ([0-9.]+)\)", text)
    assert named is not None and named.group(1) == SCHEMA_VERSION
    schema = json.loads((REPO / "schemas" / "timeline.schema.json").read_text())
    assert schema["schema_version"] == SCHEMA_VERSION
    assert SCHEMA_VERSION in schema["properties"]["schema_version"]["enum"]
