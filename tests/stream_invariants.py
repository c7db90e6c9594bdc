"""The invariants of a streamed reader, shared by the tests of every format: a log's scan
and chunks are ``read_log``'s arrays, clock, gaps, screens and warnings for any chunk size,
and its errors are ``read_log``'s."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from impactcli.errors import ImpactWarning, LogFormatError
from impactcli.logs import read_log
from impactcli.logs.describe import time_gaps
from impactcli.logs.reader import LogScan, iter_chunks, scan_log
from impactcli.logs.screen import unusable_columns
from impactcli.sample_channels import OPTIONAL_CHANNELS

#: Chunk sizes every streamed read is checked at.
CHUNKS = (1, 2, 7, 1000, 65536)


def read_warned(path: Path, **opts: Any) -> tuple[Any, list[str]]:
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        log = read_log(path, **opts)
    return log, [str(x.message) for x in w if issubclass(x.category, ImpactWarning)]


def scan_warned(path: Path, **opts: Any) -> tuple[LogScan, list[str]]:
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        scan = scan_log(path, **opts)
    return scan, [str(x.message) for x in w if issubclass(x.category, ImpactWarning)]


def assert_streams_exactly(path: Path, chunks: tuple[int, ...] = CHUNKS, **opts: Any) -> LogScan:
    """The invariants: the chunks are the same arrays for every chunk size, the scan's
    clock, gaps and screens those of the whole log's arrays, its warnings read_log's."""
    log, warned = read_warned(path, **opts)
    scan, from_scan = scan_warned(path, **opts)
    assert from_scan == warned
    assert scan.log.source == log.source
    assert scan.joint_names == log.joint_names
    assert scan.n_samples == log.n_samples
    assert (scan.t0_ns, scan.t_last_ns) == (log.t0_ns, int(log.t_ns[-1]))
    assert scan.clock == log.sample_clock
    assert scan.sample_rate_hz == log.sample_rate_hz
    idx, lengths = time_gaps(log)
    assert np.array_equal(scan.gaps, idx) and np.array_equal(scan.gap_lengths_s, lengths)
    assert scan.torque_screen == unusable_columns(log.torque)
    ref = float(np.max(np.ptp(log.torque, axis=0)))
    assert scan.torque_ptp == ref
    for ch in ("torque_model", "torque_ext"):
        a = getattr(log, ch)
        assert (ch in scan.screens) == (a is not None)
        if a is not None:
            assert scan.screens[ch].unusable(ref) == unusable_columns(a, ref)
            assert np.array_equal(scan.screens[ch].logged, log.has_channel(ch))
    assert scan.channels == tuple(s for s in OPTIONAL_CHANNELS if getattr(log, s) is not None)
    for size in (*chunks, log.n_samples + 5):
        with warnings.catch_warnings():
            warnings.simplefilter("error", ImpactWarning)  # repairs are warned by the scan
            got = list(iter_chunks(path, scan, size, **opts))
        assert [c.start for c in got] == list(range(0, log.n_samples, size))
        assert all(1 <= c.n_samples <= size for c in got)
        assert np.array_equal(np.concatenate([c.t_ns for c in got]), log.t_ns), size
        for s in ("position", "torque", *OPTIONAL_CHANNELS):
            a = getattr(log, s)
            if a is None:
                assert all(getattr(c, s) is None for c in got)
                continue
            b = np.concatenate([getattr(c, s) for c in got])
            assert b.dtype == np.float64 and np.array_equal(b, a, equal_nan=True), (s, size)
    return scan


def read_error(path: Path, **opts: Any) -> str:
    """read_log's error, which the scan raises (nothing is read before it)."""
    with pytest.raises(LogFormatError) as whole, warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        read_log(path, **opts)
    with pytest.raises(LogFormatError) as scanned, warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        scan_log(path, **opts)
    assert str(scanned.value) == str(whole.value)
    return str(whole.value)
