"""Render the demo report in headless Chromium (screen and print); skipped without Chromium.

The same check by hand, with the PNGs kept to look at: ``tests/render_report.sh``.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parent / "render_report.sh"


@pytest.mark.slow
def test_report_renders_on_screen_and_in_print(tmp_path: Path) -> None:
    if not any(shutil.which(c) for c in ("chromium", "chromium-browser", "google-chrome")):
        pytest.skip("chromium is not installed (apt-get install -y chromium)")
    res = subprocess.run(["bash", str(SCRIPT), "", str(tmp_path)], capture_output=True, text=True,
                         timeout=180, check=False)
    assert res.returncode == 0, res.stdout + res.stderr
    shot, pdf = tmp_path / "screen.png", tmp_path / "print.pdf"
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 50_000
    assert pdf.read_bytes()[:5] == b"%PDF-"
    if shutil.which("pdfinfo"):
        # 2 logs, each section on a new page: at least 3 pages
        assert len(list(tmp_path.glob("page-*.png"))) >= 3
