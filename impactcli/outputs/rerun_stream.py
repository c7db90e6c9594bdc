"""Alias of :mod:`impactcli.outputs.rerun` under the names the run's wiring
(``impactcli.batch``) and its tests import."""

from __future__ import annotations

from .column_spill import ColumnSpill as SpillWriter  # alias: removed in M
from .decimate import EnvelopeStream  # alias: removed in M
from .rerun import spill_columns  # alias: removed in M
from .rerun import write_recording as write_rrd_from_spill  # alias: removed in M

__all__ = ["EnvelopeStream", "SpillWriter", "spill_columns", "write_rrd_from_spill"]
