#!/usr/bin/env bash
# Look at a report as a person would: render it with headless Chromium, on screen (PNG) and
# printed (PDF, then PNG pages with pdftoppm when poppler-utils is installed).
#
#   tests/render_report.sh [REPORT.html] [OUTDIR]
#
# Without REPORT.html, a demo report is built from tests/fakes.py (two logs: one with incidents
# on an epoch clock and labels, one run without incidents).
# Writes OUTDIR/screen.png, OUTDIR/print.pdf and OUTDIR/page-N.png (OUTDIR defaults to a new
# temporary folder, printed at the end) — open them and read them. Checks: Chromium renders
# without network access (--host-resolver-rules maps every host to nothing, so a report that
# needed the network would visibly lack its plots), the PDF has at least 1 + (number of logs)
# pages (each log section starts on a new page). Exit 77 (skip) when Chromium is absent.
#
# Debian: apt-get install -y chromium poppler-utils
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(dirname "$here")"
py="${PYTHON:-$repo/.venv/bin/python}"
[ -x "$py" ] || py=python3

chrome=""
for c in chromium chromium-browser google-chrome; do
    if command -v "$c" >/dev/null 2>&1; then chrome="$c"; break; fi
done
if [ -z "$chrome" ]; then
    echo "render_report: chromium not found (apt-get install -y chromium); skipped" >&2
    exit 77
fi

out="${2:-$(mktemp -d)}"
mkdir -p "$out"
report="${1:-}"
if [ -z "$report" ]; then
    report="$out/demo.html"
    (cd "$repo" && "$py" - "$report" <<'EOF'
import dataclasses
import sys

from impactcli.types import ContactLabel, Labels, LogSource
from tests.fakes import fake_result, with_incidents, write_fake_report

cfg = {"adaptive": {"forgetting_factor": 0.999},
       "events": {"merge_gap_s": 0.05, "min_duration_s": 0.0}}
a = with_incidents(fake_result(), t0_ns=1_767_225_600_000_000_000)  # incidents, epoch clock
a = dataclasses.replace(a, config=cfg,
                        log=dataclasses.replace(a.log, source=LogSource("fleet/arm_a.csv", "a1" * 32, "csv")))
b = fake_result(joints=("shoulder", "elbow", "wrist"))  # a run without incidents (older)
b = dataclasses.replace(b, reference_source="measured",
                        log=dataclasses.replace(b.log, source=LogSource("fleet/arm_b.mcap", "b2" * 32, "mcap-ros2")))
labels = Labels((ContactLabel(3.99, 4.12, 12.0, "impact", 2), ContactLabel(6.95, 7.5, 30.0, "clamp", 1),
                 ContactLabel(8.5, 8.6, 3.0, "push", 1)), 250.0, "fleet/arm_a.labels.json")
write_fake_report([a, b], sys.argv[1], sys.argv[1].replace(".html", ".json"), labels=[labels, None])
EOF
    )
fi
n_logs=$(grep -o '<section class="log"' "$report" | wc -l)

flags=(--headless --no-sandbox --disable-gpu --disable-background-networking --no-first-run
       --disable-component-update --disable-sync --hide-scrollbars
       "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE localhost")
"$chrome" "${flags[@]}" --user-data-dir="$(mktemp -d)" --window-size=1280,2400 \
    --screenshot="$out/screen.png" "file://$(realpath "$report")" >/dev/null 2>&1
"$chrome" "${flags[@]}" --user-data-dir="$(mktemp -d)" --no-pdf-header-footer \
    --print-to-pdf="$out/print.pdf" "file://$(realpath "$report")" >/dev/null 2>&1
[ -s "$out/screen.png" ] || { echo "render_report: no screenshot" >&2; exit 1; }
[ -s "$out/print.pdf" ] || { echo "render_report: no PDF" >&2; exit 1; }

if command -v pdfinfo >/dev/null 2>&1; then
    pages=$(pdfinfo "$out/print.pdf" | awk '/^Pages:/ {print $2}')
    if [ "$pages" -lt $((n_logs + 1)) ]; then
        echo "render_report: $pages PDF page(s) for $n_logs log section(s): page breaks missing" >&2
        exit 1
    fi
    pdftoppm -r 70 -png "$out/print.pdf" "$out/page"
    echo "render_report: $n_logs log(s), $pages printed page(s)"
fi
echo "render_report: look at $out/screen.png, $out/print.pdf and $out/page-*.png"
