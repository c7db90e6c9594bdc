"""Render the report in headless Chromium: the first screen answers (layout read from the
rendered page), and the demo renders on screen and in print. Skipped without Chromium.

The same check by hand, with the PNGs kept to look at: ``tests/render_report.sh``.
"""

from __future__ import annotations

import dataclasses
import html
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from impactcli.outputs.report import write_report
from impactcli.types import ContactLabel, Labels, LogSource

from .conftest import REPO
from .fakes import fake_result, with_incidents, write_fake_report

SCRIPT = Path(__file__).resolve().parent / "render_report.sh"
#: The window the first screen is judged in (CSS px).
WINDOW = (1280, 900)
#: Writes each element's page position into the DOM (``--dump-dom`` prints the DOM after
#: the page's scripts ran; the report itself has no script).
PROBE = """<script>(function () {
  const out = {viewport: {w: window.innerWidth, h: window.innerHeight}};
  for (const id of IDS) {
    const el = document.getElementById(id);
    if (!el) { continue; }
    const r = el.getBoundingClientRect();
    out[id] = {top: r.top + window.scrollY, bottom: r.bottom + window.scrollY,
               height: r.height, width: r.width};
  }
  const pre = document.createElement("pre");
  pre.id = "layout-probe";
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
})();</script>"""


def chromium() -> str:
    for c in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(c):
            return c
    pytest.skip("no Chromium on this machine: the report's layout is measured in a headless "
                "browser (install the chromium package to run this test)")


def layout(page: Path, ids: tuple[str, ...], tmp: Path) -> dict[str, Any]:
    """Page positions [CSS px] of the elements ``ids`` of ``page`` rendered in a
    1280 × 900 window, and the viewport (``viewport``: what the window shows)."""
    probed = tmp / f"probe-{page.name}"
    text = page.read_text("utf-8")
    probed.write_text(text.replace("</body>", PROBE.replace("IDS", json.dumps(ids)) + "</body>"),
                      "utf-8")
    res = subprocess.run(
        [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE localhost",
         f"--user-data-dir={tmp / 'profile'}", f"--window-size={WINDOW[0]},{WINDOW[1]}",
         "--dump-dom", probed.as_uri()],
        capture_output=True, text=True, timeout=120, check=False)
    m = re.search(r'<pre id="layout-probe">(.*?)</pre>', res.stdout, re.S)
    assert m, f"no layout from chromium (exit {res.returncode}): {res.stderr[-2000:]}"
    out: dict[str, Any] = json.loads(html.unescape(m.group(1)))
    return out


def assert_first_screen(pos: dict[str, Any], ids: tuple[str, ...]) -> None:
    """Each element starts within the first 900 px and within what the window shows."""
    seen = pos["viewport"]["h"]
    for i in ids:
        assert i in pos, f"#{i} is not in the page"
        assert pos[i]["height"] > 0 and pos[i]["width"] > 0, f"#{i} is not drawn"
        assert pos[i]["top"] < WINDOW[1], f"#{i} starts at {pos[i]['top']:.0f} px"
        assert pos[i]["top"] < seen, f"#{i} starts below the first screen ({seen} px shown)"


def labelled(name: str, sha: str, **kw: Any) -> Any:
    r = with_incidents(fake_result(**kw))
    return dataclasses.replace(r, log=dataclasses.replace(
        r.log, source=LogSource(f"fleet/{name}.csv", sha * 32, "csv")))


@pytest.mark.slow
def test_the_first_screen_answers(tmp_path: Path) -> None:
    """One log, and a fleet of three: the verdict and the incident list (and the fleet
    table) start on the first screen of a 1280 × 900 window."""
    chromium()
    lab = Labels((ContactLabel(3.99, 4.12, 12.0, "impact", 2),
                  ContactLabel(6.95, 7.5, 30.0, "clamp", 1)), 250.0, "fleet/a.labels.json")
    one = tmp_path / "one.html"
    write_fake_report([labelled("arm_a", "a1")], one, labels=[lab])
    ids = ("log1-verdict", "log1-incidents")
    pos = layout(one, ids, tmp_path)
    assert_first_screen(pos, ids)
    assert pos["log1-verdict"]["bottom"] <= pos["log1-incidents"]["top"]
    fleet = tmp_path / "fleet.html"
    write_fake_report([labelled(n, s, joints=j) for n, s, j in
                       (("arm_a", "a1", ("j1", "j2")), ("arm_b", "b2", ("j1", "j2", "j3")),
                        ("arm_c", "c3", ("j1", "j2")))], fleet, labels=[lab, None, None])
    ids = ("fleet-summary", "log1-verdict", "log1-incidents")
    assert_first_screen(layout(fleet, ids, tmp_path), ids)


@pytest.mark.slow
def test_the_first_screen_answers_on_the_sample_logs(tmp_path: Path) -> None:
    """The sample logs of the README's report (three logs, 16 incidents on the first)."""
    chromium()
    import warnings

    from impactcli.config import load_config
    from impactcli.logs.robot_files import read_labels
    from impactcli.outputs.report import render_log
    from impactcli.run.job import run_log as stream_log

    csv = REPO / "sample_logs" / "csv"
    cfg = load_config(REPO / "sample_logs" / "assist_like.config.toml")
    names = ("assist_impacts", "assist_pushes", "assist_clamps")
    rendered = []
    for k, n in enumerate(names):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result, samples = stream_log(str(csv / f"{n}.csv.gz"), robot=None, model=None,
                                         config=cfg, samples="report")
        try:
            rendered.append(render_log(result, read_labels(csv / f"{n}.labels.json"), k,
                                       samples=samples))
        finally:
            samples.close()
    page = tmp_path / "report.html"
    write_report(rendered, page)
    ids = ("fleet-summary", "log1-verdict", "log1-incidents")
    assert_first_screen(layout(page, ids, tmp_path), ids)


@pytest.mark.slow
def test_report_renders_on_screen_and_in_print(tmp_path: Path) -> None:
    chromium()
    res = subprocess.run(["bash", str(SCRIPT), "", str(tmp_path)], capture_output=True, text=True,
                         timeout=180, check=False,
                         env={**os.environ, "PYTHON": sys.executable})  # this test's Python
    assert res.returncode == 0, res.stdout + res.stderr
    shot, pdf = tmp_path / "screen.png", tmp_path / "print.pdf"
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 50_000
    assert pdf.read_bytes()[:5] == b"%PDF-"
    if shutil.which("pdfinfo"):
        # 2 logs, each section on a new page: at least 3 pages
        assert len(list(tmp_path.glob("page-*.png"))) >= 3
