"""The joint screen of real-log hygiene: :mod:`impactcli.io.stream_screen` (the scan of a
log gathers what it needs chunk by chunk)."""

from __future__ import annotations

# alias: removed in M (detect/screen and io/stream_screen become logs/screen.py)
from ..io.stream_screen import (  # noqa: F401
    FEW_VALUES,
    FLAT_NM,
    SMALL_FRACTION,
    LeftOut,
    unusable_columns,
)
