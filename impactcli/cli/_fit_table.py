"""alias: removed in M — the fit table is :mod:`impactcli.cli.fit_table` (cli/calibrate.py
still imports it from here)."""

from .fit_table import format_fit_table  # alias: removed in M

__all__ = ["format_fit_table"]
