"""Alias of :mod:`impactcli.outputs.report.samples` under the names the run's wiring
(``impactcli.batch``) imports."""

from __future__ import annotations

from .report.samples import ReportCollector  # alias: removed in M
from .report.samples import Samples as StreamedSamples  # alias: removed in M

__all__ = ["ReportCollector", "StreamedSamples"]
