"""The safety-audit report: one self-contained HTML file and its JSON twin, built around the
answer a safety engineer opens it for — did the arm hit something, when, where, how hard.

Formatting only: every number comes from a :class:`~impactcli.types.DetectionResult`
(through :func:`impactcli.outputs.timeline.timeline_dict`), from the run's chunks as
:mod:`.samples` collects them, from :mod:`impactcli.detect.incidents` or, with labels,
from :mod:`impactcli.quality`. The one quantity reduced here is the false-alarm margin.
Parts, by what the reader sees:

- :mod:`.summary` — the verdict line, the incident list, the fleet summary;
- :mod:`.unseen` — what the audit could not see (warm-up, gaps, joints left out, the
  detection floor and the smallest force caught, what an older timeline cannot tell);
- :mod:`.section` — one log's section, in reading order (answer first);
- :mod:`.plots` — every plot (on :mod:`impactcli.outputs.svgplot`);
- :mod:`.quality` — detection quality against labels, the threshold sweep;
- :mod:`.analysed` — what was analysed and with what;
- :mod:`.caveats`, :mod:`.margins` — the caveats and the false-alarm margin;
- :mod:`.page` — the page (CSS, assembly), the JSON twin, writing both;
- :mod:`.samples` — what the report reads of the samples, collected from the chunks;
- :mod:`.common` — settings and formatters they share.
"""

from __future__ import annotations

from .caveats import caveats
from .common import (
    CLIP_FACTOR,
    DETECTOR_TITLE,
    EVENT_BUCKETS,
    EVENT_WINDOW_S,
    GUARD_S,
    LOW_GAIN,
    MAX_EVENT_FIGURES,
    POOR_FIT,
    PRODUCT_DETECTORS,
    SCHEMA_VERSION,
    STAT_NAME,
    WHOLE_LOG_BUCKETS,
    event_duration_s,
)
from .margins import false_alarm_margins
from .page import (
    CSS,
    NUM_TOKEN,
    RenderedLog,
    assemble_report,
    render_html,
    render_log,
    report_dict,
    report_json,
    summary_row,
    write_report,
)
from .quality import SWEEP_SCALES
from .samples import ReportCollector, Samples
from .section import log_section
from .summary import incident_rows, verdict_text
from .unseen import could_not_see

__all__ = [
    "CLIP_FACTOR",
    "CSS",
    "DETECTOR_TITLE",
    "EVENT_BUCKETS",
    "EVENT_WINDOW_S",
    "GUARD_S",
    "LOW_GAIN",
    "MAX_EVENT_FIGURES",
    "NUM_TOKEN",
    "POOR_FIT",
    "PRODUCT_DETECTORS",
    "SCHEMA_VERSION",
    "STAT_NAME",
    "SWEEP_SCALES",
    "WHOLE_LOG_BUCKETS",
    "RenderedLog",
    "ReportCollector",
    "Samples",
    "assemble_report",
    "caveats",
    "could_not_see",
    "event_duration_s",
    "false_alarm_margins",
    "incident_rows",
    "log_section",
    "render_html",
    "render_log",
    "report_dict",
    "report_json",
    "summary_row",
    "verdict_text",
    "write_report",
]
