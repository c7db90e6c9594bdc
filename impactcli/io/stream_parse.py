"""A CSV's text parsed range by range on threads, in order (:func:`parsed_batches`).

Why: the scan of a streamed CSV (:mod:`impactcli.io.stream`) runs on one core; half of its
time is pyarrow's parse (about 1 s of CPU per 10 minutes of a 7-joint 1 kHz log), the
rest Python and NumPy work on the batches (time conversion, repairs, statistics). pyarrow's
streaming reader parses the next batch only when asked, on the calling thread, and on
another thread it competes for the GIL at every batch. Here the file's text is cut at line
ends into ranges of about ``block_size`` bytes, each parsed whole by ``read_csv`` on a
worker thread (one call without the GIL per range), up to :data:`IN_FLIGHT` ranges ahead
of the consumer: the parse of the next ranges runs while the scan works on the current one.

Exact: every range is parsed with the same parse and convert options (the first with the
layout's skipped lines and header, the others with its column names and no header), so the
batches hold the rows pyarrow's streaming reader gives, in order, cut elsewhere (the scan
does not depend on where batches end: ``tests/test_io_stream.py`` reads with 4 KiB
blocks). Lines end at ``\\n``, ``\\r\\n`` or ``\\r`` as pyarrow reads them (a cut between
``\\r`` and ``\\n`` leaves an empty line, which pyarrow skips), and values never hold a line
break (``newlines_in_values`` is off, as for the streaming reader). Compressed files are
read through pyarrow's input stream, decompressed as ``open_csv`` does.

Memory: :data:`IN_FLIGHT` ranges of text and their tables.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

#: Ranges parsed ahead of the consumer (and at most this many tables in memory).
IN_FLIGHT = 4
#: Worker threads parsing ranges.
THREADS = 2

_BREAK = re.compile(rb"\r\n|\r|\n")


def parsed_batches(lay: Any, names: list[str], convert_options: Any, block_size: int,
                   each: Callable[[Any], Any] | None = None) -> Iterator[Any]:
    """The pyarrow record batches of the CSV ``lay`` (a :class:`~impactcli.io.csv.CsvLayout`;
    ``names``: pyarrow's column names of the file), in order, parsed on threads (module
    docstring) — or ``each(batch)`` of them, computed on the same threads (the batch's
    conversion: it must read nothing but the batch). Raises what pyarrow raises
    (``ArrowInvalid``, ``OSError``), and what ``each`` raises."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from .csv import csv_read_options

    first_opts, parse_opts = csv_read_options(lay, block_size)
    head_lines = lay.skip + (1 if lay.header else 0) + 1  # up to the first data line

    def parse(text: bytes, first: bool) -> Any:
        size = max(len(text), 1)
        ropts = (pacsv.ReadOptions(skip_rows=first_opts.skip_rows,
                                   autogenerate_column_names=first_opts
                                   .autogenerate_column_names,
                                   block_size=size, use_threads=False) if first else
                 pacsv.ReadOptions(column_names=names, block_size=size, use_threads=False))
        table = pacsv.read_csv(pa.py_buffer(text), read_options=ropts,
                               parse_options=parse_opts, convert_options=convert_options)
        batches = table.combine_chunks().to_batches()
        return batches if each is None else [each(b) for b in batches]

    pending: deque[Future[Any]] = deque()
    with pa.input_stream(str(lay.path)) as src, ThreadPoolExecutor(THREADS) as pool:
        try:
            rest = b""
            first = True
            eof = False
            while not eof:
                data = src.read(block_size)
                eof = not data
                buf = rest + data
                if eof:
                    text, rest = buf, b""
                else:
                    cut = max(buf.rfind(b"\n"), buf.rfind(b"\r")) + 1
                    if cut == 0 or (first and len(_BREAK.findall(buf, 0, cut)) < head_lines):
                        rest = buf  # no whole line yet (or not past the header): read on
                        continue
                    text, rest = buf[:cut], buf[cut:]
                if text or first:
                    pending.append(pool.submit(parse, text, first))
                    first = False
                while pending and (len(pending) >= IN_FLIGHT or eof):
                    yield from pending.popleft().result()
        finally:
            for f in pending:
                f.cancel()
