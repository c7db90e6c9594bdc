"""The quality benchmarks are gates: a target printed FAIL makes the script exit non-zero
(scored rows stubbed here; the benchmark itself runs for about a minute)."""

from __future__ import annotations

import pytest

from .benchmarks import incident_quality as iq


def _row(link: int) -> iq.Row:
    """A detected 20 N impact labelled on link 2 (the last), found on ``link``."""
    return iq.Row("stub", "impact", 2, True, 20.0, True, 1, link, "transient", 22.0)


@pytest.mark.parametrize("found_link, code, err", [
    (2, 0, ""),
    (1, 1, "1 target(s) FAIL\n"),
])
def test_incident_quality_exits_1_when_a_target_fails(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        found_link: int, code: int, err: str) -> None:
    monkeypatch.setattr(iq, "simulated", lambda arm, seed: [_row(found_link)])
    monkeypatch.setattr(iq, "samples", lambda: [_row(2)])
    assert iq.main(["--seeds", "1"]) == code
    out = capsys.readouterr()
    assert out.err == err
    fails = [ln for ln in out.out.splitlines() if ln.startswith("FAIL")]
    assert fails == ([] if code == 0 else ["FAIL  link right ≥ 90 % [fresh]"])
