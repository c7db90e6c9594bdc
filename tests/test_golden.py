"""The CLI answers on the sample logs what it answered before the one-path refactor:
timelines, signals Parquet, report JSON and HTML, calibrated configs, identified models,
``inspect --json``, and the exit code and message of refused inputs. On the machine that made
the goldens, byte for byte; on another CPU, where NumPy's and OpenBLAS's SIMD kernels round
differently, every integer, string and shape the same and every float within a stated
tolerance (make_golden.py: ``RTOL``; ``IMPACTCLI_GOLDEN_EXACT=1`` asks for the bytes).

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

import json
import os
import traceback
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from impactcli.cli import main

from .golden import make_golden
from .golden.make_golden import (
    GOLDEN,
    OUTPUT_DIRS,
    RESULTS,
    SAMPLES,
    Case,
    agree,
    all_cases,
    build_fixtures,
    differences,
    load_records,
    run_case,
    signals_summary,
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


def test_agreement_is_beyond_a_floats_last_bits_only(monkeypatch: pytest.MonkeyPatch) -> None:
    """What another CPU may change in an answer: a float within RTOL (model selection's
    cross-validation figures within RTOL_LOOSE) and an identified model's sha256; never an
    integer, a string, a key or a float beyond it, and nothing at all with
    IMPACTCLI_GOLDEN_EXACT=1."""
    monkeypatch.setattr(make_golden, "EXACT", False)
    sha, sha2 = "a" * 64, "b" * 64
    base = {"i_end": 3374, "force_n": 18.777419742862428, "model_sha256": sha,
            "fit": {"selection": {"rms_nm": 0.06038938}, "rms_nm": 0.06038938},
            "detectors": ["adaptive"]}

    def with_(**kw: object) -> str:
        return json.dumps({**base, **kw})

    old = json.dumps(base)
    assert agree("t.json", old, with_(force_n=18.77741974286243, model_sha256=sha2))
    assert agree("t.json", old, with_(fit={"selection": {"rms_nm": 0.06038072},
                                           "rms_nm": 0.06038938}))
    for bad in (with_(i_end=3375), with_(force_n=18.7775),
                with_(fit={"selection": {"rms_nm": 0.0605}, "rms_nm": 0.06038938}),
                with_(fit={"selection": {"rms_nm": 0.06038938}, "rms_nm": 0.06038072}),
                with_(detectors=["static_loading"]), with_(model_sha256="other"),
                with_(extra=1)):
        assert not agree("t.json", old, bad), bad
    assert agree("c.toml", "x = 0.1\nn = 3\n", "x = 0.10000000001\nn = 3\n")
    assert not agree("c.toml", "x = 0.1\nn = 3\n", "x = 0.1\nn = 4\n")
    assert agree("-", "link 2 ~4.8712345 N", "link 2 ~4.87123450001 N")
    assert not agree("-", "link 2 ~4.87 N", "link 2 ~4.88 N")
    assert not agree("-", "link 2 ~4.87 N", "link 3 ~4.87 N")
    assert not agree("-", "n 3", "n 3.0") and not agree("t.json", '{"x": 3}', '{"x": 3.0}')
    for a, b in (("Infinity", "3.0"), ("Infinity", "-Infinity"), ("NaN", "1.0")):
        assert not agree("t.json", f'{{"x": {a}}}', f'{{"x": {b}}}'), (a, b)
    assert agree("t.json", '{"x": NaN}', '{"x": NaN}')
    # a report's HTML: its skeleton's sha256 must be the same, its bytes' need not
    rec = {"exit_code": 0, "sha256": {"r.html": sha}, "content": {"r.html": sha}}
    assert make_golden._record_agrees(rec, {**rec, "sha256": {"r.html": sha2}})
    assert not make_golden._record_agrees(rec, {**rec, "content": {"r.html": sha2}})
    monkeypatch.setattr(make_golden, "EXACT", True)
    assert not agree("t.json", old, with_(force_n=18.77741974286243))
    assert agree("t.json", old, old)


def test_a_signals_summary_sees_a_flipped_decision_not_a_last_bit(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two Parquets of signals agree when each residual sample moved by its last bit, and
    differ when one decision sample flipped, the decisions moved by 5 samples, or one
    residual sample moved by 0.01 of its standard deviation (Σ|x| by 6e-6 of itself: a
    column's summary is six numbers, so its grain is a sum's RTOL; the timeline's goldens
    hold the answers drawn from it). A column's min and max agree to RTOL of the larger of
    their magnitudes."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    monkeypatch.setattr(make_golden, "EXACT", False)
    rng = np.random.default_rng(3)
    r = rng.normal(size=2000)
    d = (np.abs(r) > 2).astype(np.uint8)

    def summary(res: np.ndarray, dec: np.ndarray) -> dict[str, object]:
        path = tmp_path / "s.parquet"
        pq.write_table(pa.table({"j.residual": res, "j.adaptive": dec}), path)
        return signals_summary(path.read_bytes())

    want = summary(r, d)
    rec = {"exit_code": 0, "sha256": {"s": "x"}, "content": {"s": want}}
    flipped = d.copy()
    flipped[7] ^= 1
    moved = r.copy()
    moved[11] += 1e-2
    for res, dec, same in ((np.nextafter(r, np.inf), d, True), (r, flipped, False),
                           (r, np.roll(d, 5), False), (moved, d, False)):
        got = {"exit_code": 0, "sha256": {"s": "y"}, "content": {"s": summary(res, dec)}}
        assert make_golden._record_agrees(rec, got) is same
    # a statistic at rest: its min near 0 holds the precision of a column that reaches
    # thousands (another machine moved a 2.7e-6 min by 2e-6 of itself), not its own
    stat = np.abs(r) * 1000.0
    stat[5] = 2.698916367005396e-06
    base = {"exit_code": 0, "sha256": {"s": "x"}, "content": {"s": summary(stat, d)}}
    for at_rest, same in ((2.6989220112795743e-06, True), (0.5, False)):
        other = stat.copy()
        other[5] = at_rest
        got = {"exit_code": 0, "sha256": {"s": "y"}, "content": {"s": summary(other, d)}}
        assert make_golden._record_agrees(base, got) is same
