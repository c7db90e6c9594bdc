"""The incident-quality targets gate (tests/incident_criteria.py, which
tests/benchmarks/incident_quality.py prints): contacts found on the wrong link, of the wrong
type or with a wrong force FAIL their target, and a FAIL makes the benchmark's exit code 1."""

from __future__ import annotations

import pytest

from .incident_criteria import Row, report, verdict


def _row(link: int, contact: str = "transient", force_n: float = 22.0) -> Row:
    """A detected 20 N impact labelled on link 2 (the last), found on ``link``."""
    return Row("stub", "impact", 2, True, 20.0, True, 1, link, contact, force_n)


def _failed(rows: list[Row]) -> list[str]:
    return [name for name, ok in report(rows, "stub") if not ok]


def test_right_answers_pass_every_target(capsys: pytest.CaptureFixture[str]) -> None:
    assert _failed([_row(2)] * 4) == []
    capsys.readouterr()


@pytest.mark.parametrize("rows, target", [
    ([_row(1)] * 4, "link right ≥ 90 %"),
    ([_row(2, "quasi_static")] * 4, "type right ≥ 90 %"),
    ([_row(2, force_n=40.0)] * 4, "median force error ≤ 30 %"),
    ([_row(2, force_n=None)] * 4, "median force error ≤ 30 %"),  # type: ignore[arg-type]
])
def test_a_wrong_answer_fails_its_target(rows: list[Row], target: str,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    assert target in _failed(rows)
    capsys.readouterr()


def test_a_failed_target_gives_exit_1(capsys: pytest.CaptureFixture[str]) -> None:
    assert verdict({"fresh": [("a", True)], "samples": [("b", True)]}) == 0
    assert capsys.readouterr().err == ""
    assert verdict({"fresh": [("a", True), ("link right ≥ 90 %", False)]}) == 1
    out = capsys.readouterr()
    assert out.err == "1 target(s) FAIL\n"
    assert [ln for ln in out.out.splitlines() if ln.startswith("FAIL")] == [
        "FAIL  link right ≥ 90 % [fresh]"]
