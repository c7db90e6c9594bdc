"""The CLI answers on the sample logs what it answered before the one-path refactor, byte for
byte: timelines, signals Parquet (sha256), report JSON, calibrated configs, identified models,
``inspect --json``, and the exit code and message of refused inputs.

Each case of tests/golden/make_golden.py (which made the goldens at tag ``base-onepath``, one
fresh process per case) runs here in this process (CliRunner, in the case's working folder),
and its outputs are compared after the same normalisation (absolute paths → ``<SAMPLES>``,
``<ROOT>``, ``<FIXTURES>``, ``<OUT>``).

Default suite: a subset covering every verb and format — the 12 CSV timelines with config,
CSV and MCAP timelines without config, MCAP with config, the three format variants, one
report, both calibrations, two model kinds, inspect, every refused input: 17 s of CPU (50 s
wall on 2 cores at load 9); its cases over ~2 s are marked ``slow`` (``-m "not slow"``: 13 s
of CPU). The whole set (all 48 sample timelines, 24 inspects, 3 reports, 4 models; 59 s of
CPU, 3 min wall at load 8): ``IMPACTCLI_GOLDEN=all pytest tests/test_golden.py``, or in
fresh processes ``python tests/golden/make_golden.py --check``.

When an answer changes on purpose: ``python tests/golden/make_golden.py`` (every golden) or
``--only PREFIX`` (e.g. ``--only detect/csv``), review ``git diff tests/golden``, and commit
the goldens with the change that explains them.
"""

from __future__ import annotations

import os
import traceback
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from impactcli.cli import main

from .golden.make_golden import (
    GOLDEN,
    OUTPUT_DIRS,
    RESULTS,
    SAMPLES,
    Case,
    all_cases,
    build_fixtures,
    differences,
    load_records,
    run_case,
)

FULL = os.environ.get("IMPACTCLI_GOLDEN") == "all"
REGENERATE = ("\nIf this change is intended: python tests/golden/make_golden.py --only "
              "<case id>, then review git diff tests/golden (tests/test_golden.py's docstring).")


def _params() -> Iterator[object]:
    for case in all_cases():
        if case.tier == "all" and not FULL:
            continue
        marks = [pytest.mark.slow] if case.tier != "quick" else []
        yield pytest.param(case, id=case.id, marks=marks)


@pytest.fixture(scope="module")
def fixtures(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("golden_fixtures")
    build_fixtures(d)
    return d


@pytest.fixture(scope="module")
def records() -> dict[str, dict[str, object]]:
    return load_records()


@pytest.mark.parametrize("case", list(_params()))
def test_cli_answers_as_the_golden(case: Case, fixtures: Path,
                                   records: dict[str, dict[str, object]], tmp_path: Path,
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    def invoke(argv: list[str], cwd: Path) -> tuple[int, str, str]:
        monkeypatch.chdir(cwd)
        r = CliRunner().invoke(main, argv, prog_name="impactcli")
        err = r.stderr
        if r.exc_info is not None and not isinstance(r.exception, SystemExit):
            err += "".join(traceback.format_exception(*r.exc_info))
        return r.exit_code, r.stdout, err

    out = tmp_path / "out"
    out.mkdir()
    problems = differences(case, run_case(case, invoke, fixtures, out), records)
    assert not problems, "\n".join(problems) + REGENERATE


def test_goldens_are_complete() -> None:
    """Every case has its record and golden files, and no golden file is left from a case
    that no longer exists."""
    cases = all_cases()
    assert set(load_records()) == {c.id for c in cases}
    wanted = {GOLDEN / dest for c in cases for _, dest in c.texts}
    on_disk = {p for d in OUTPUT_DIRS for p in (GOLDEN / d).rglob("*") if p.is_file()}
    assert on_disk == wanted
    assert RESULTS.is_file()


@pytest.mark.parametrize("name", ["assist_like", "heavy_geared"])
def test_calibrate_golden_is_the_shipped_sample_config(name: str) -> None:
    """docs/validation.md: the sample configs are `calibrate`'s output byte for byte."""
    golden = (GOLDEN / "calibrate" / f"{name}.config.toml").read_bytes()
    assert golden == (SAMPLES / f"{name}.config.toml").read_bytes()
