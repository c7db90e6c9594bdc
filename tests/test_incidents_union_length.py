"""The length of a union of spans (lasting loads' blind time, data defects' blind time, the
labels' contact time in evaluation) against a count of the unit cells the spans cover."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from impactcli.detect.incidents import union_length

ends = st.integers(-20, 40)


@given(spans=st.lists(st.tuples(ends, ends), max_size=8), lo=ends, width=st.integers(0, 60))
def test_union_length_is_the_cells_the_spans_cover(spans: list[tuple[int, int]], lo: int,
                                                   width: int) -> None:
    hi = lo + width
    cells = {c for a, b in spans for c in range(max(a, lo), min(b, hi))}
    assert union_length([(float(a), float(b)) for a, b in spans], lo, hi) == len(cells)
    unclipped = {c for a, b in spans for c in range(a, b)}
    assert union_length(spans) == len(unclipped)
