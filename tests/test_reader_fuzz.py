"""Property-based tests of the readers: a valid CSV or MCAP log, mutated (truncated, bytes
flipped, columns swapped or dropped, rows shuffled, extreme or broken cells), gives one
clean error — an ImpactError, through the command line exit 3 and one ``impactcli: error:``
line — or a warned repair; never a traceback, never exit 1 (a CI gate's "collision") or 70.

Seeded (``derandomize=True``) with a small budget in the default run (a few seconds); set
``IMPACTCLI_FUZZ_EXAMPLES`` for a longer search.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from impactcli.cli import main
from impactcli.errors import ImpactError, ImpactWarning
from impactcli.logs import read_log, write_log
from impactcli.types import LogSource, RobotLog

EXAMPLES = int(os.environ.get("IMPACTCLI_FUZZ_EXAMPLES", "0")) or None
SETTINGS = {"derandomize": True, "deadline": None, "database": None,
            "suppress_health_check": [HealthCheck.function_scoped_fixture,
                                      HealthCheck.too_slow]}
REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "sample_logs" / "assist_like.config.toml"


def _log(n: int = 400) -> RobotLog:
    """A small 250 Hz two-joint log with the sample config's joint names."""
    t = np.arange(n, dtype=np.int64) * 4_000_000
    k = np.arange(n)
    q = np.column_stack([np.sin(k / 60), 0.5 * np.cos(k / 45)])
    tau = np.column_stack([3 + np.cos(k / 60), -1 + 0.2 * np.sin(k / 45)])
    return RobotLog(t_ns=t, joint_names=("shoulder", "elbow"), position=q, torque=tau,
                    torque_ext=0.01 * np.column_stack([np.sin(k / 7), np.cos(k / 9)]),
                    source=LogSource("<fuzz>", "0" * 64, "memory"))


def _check_cli(path: Path, *args: str) -> None:
    """The CLI on ``path``: exit 0 or 3; an error is one ``impactcli: error:`` line; no
    traceback; never 1 or 70."""
    r = CliRunner().invoke(main, [*args[:1], str(path), *args[1:]])
    note = f"exit {r.exit_code}\n{r.stderr[-3000:]}"
    assert r.exit_code in (0, 3), note
    assert "Traceback" not in r.stderr, note
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("impactcli: error:")]
    lines = r.stderr.splitlines()
    assert all(ln.startswith("impactcli: ") for ln in lines), note
    assert len(errors) == (1 if r.exit_code == 3 else 0), note


def _check_read(path: Path) -> None:
    """read_log returns a log or raises an ImpactError (never anything else)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            log = read_log(path)
        except ImpactError:
            return
    assert np.all(np.diff(log.t_ns) > 0)
    assert np.all(np.isfinite(log.position)) and np.all(np.isfinite(log.torque))
    assert np.all(np.abs(log.torque) <= 1e12)


# ---------------------------------------------------------------------------- mutations
CELLS = st.sampled_from(["1e300", "-1e308", "inf", "-inf", "nan", "", "abc", "1e12", "3e12",
                         "0x1F", "1,5", "--1", "1e-320", "9" * 40, '"2"', "NaN", "null"])


@st.composite
def csv_mutation(draw: st.DrawFn, text: str) -> bytes:
    lines = text.splitlines(keepends=True)
    kind = draw(st.sampled_from(["truncate", "flip", "swap_columns", "drop_column",
                                 "cells", "shuffle_rows", "swap_header", "repeat_stamp"]))
    header = lines[0].rstrip("\n").split(",")
    rows = [ln.rstrip("\n").split(",") for ln in lines[1:]]
    if kind == "truncate":
        data = text.encode()
        return data[:draw(st.integers(0, len(data)))]
    if kind == "flip":
        data = bytearray(text.encode())
        for _ in range(draw(st.integers(1, 8))):
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        return bytes(data)
    if kind in ("swap_columns", "swap_header"):
        a = draw(st.integers(0, len(header) - 1))
        b = draw(st.integers(0, len(header) - 1))
        for r in [header, *rows] if kind == "swap_columns" else [header]:
            r[a], r[b] = r[b], r[a]
    elif kind == "drop_column":
        c = draw(st.integers(0, len(header) - 1))
        header, rows = header[:c] + header[c + 1:], [r[:c] + r[c + 1:] for r in rows]
    elif kind == "cells":
        for _ in range(draw(st.integers(1, 6))):
            r = draw(st.integers(0, len(rows) - 1))
            c = draw(st.integers(0, len(header) - 1))
            rows[r][c] = draw(CELLS)
    elif kind == "repeat_stamp":
        r = draw(st.integers(1, len(rows) - 1))
        rows[r][0] = rows[r - 1][0]
    else:  # shuffle_rows: a block of rows written out of order
        a = draw(st.integers(0, len(rows) - 2))
        b = draw(st.integers(a + 1, min(len(rows), a + 40)))
        block = rows[a:b]
        draw(st.randoms(use_true_random=False)).shuffle(block)
        rows[a:b] = block
    return "".join(",".join(r) + "\n" for r in [header, *rows]).encode()


@pytest.fixture(scope="module")
def csv_text(tmp_path_factory: pytest.TempPathFactory) -> str:
    path = tmp_path_factory.mktemp("fuzz") / "base.csv"
    write_log(_log(), path)
    return path.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def mcap_bytes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    out = {}
    for enc in ("json", "ros2"):
        path = tmp_path_factory.mktemp("fuzz") / f"base_{enc}.mcap"
        write_log(_log(200), path, mcap_encoding=enc)
        out[enc] = path.read_bytes()
    return out


@settings(max_examples=EXAMPLES or 40, **SETTINGS)  # type: ignore[arg-type]
@given(data=st.data())
def test_mutated_csv_is_one_clean_error_or_a_warned_repair(
        tmp_path: Path, csv_text: str, data: st.DataObject) -> None:
    blob = data.draw(csv_mutation(csv_text))
    path = tmp_path / "m.csv"
    path.write_bytes(blob)
    _check_read(path)
    _check_cli(path, "inspect")


@settings(max_examples=EXAMPLES or 30, **SETTINGS)  # type: ignore[arg-type]
@given(enc=st.sampled_from(["json", "ros2"]), cut=st.floats(0, 1),
       flips=st.lists(st.tuples(st.floats(0, 1), st.integers(0, 255)), max_size=6))
def test_mutated_mcap_is_one_clean_error_or_a_warned_repair(
        tmp_path: Path, mcap_bytes: dict[str, bytes], enc: str, cut: float,
        flips: list[tuple[float, int]]) -> None:
    data = bytearray(mcap_bytes[enc])
    for where, value in flips:
        data[min(int(where * len(data)), len(data) - 1)] = value
    if cut < 0.5:  # half the examples truncated
        data = data[:int(cut * 2 * len(data))]
    path = tmp_path / "m.mcap"
    path.write_bytes(bytes(data))
    _check_read(path)
    _check_cli(path, "inspect")


@pytest.fixture(scope="module")
def free_text(tmp_path_factory: pytest.TempPathFactory) -> str:
    """12 s of a collision-free sample log (canonical CSV): detect exits 0 on it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ImpactWarning)
        log = read_log(REPO / "sample_logs" / "csv" / "assist_free_p2p.csv.gz")
    path = tmp_path_factory.mktemp("fuzz") / "free.csv"
    write_log(log.slice(0, 3000), path)
    return path.read_text(encoding="utf-8")


@settings(max_examples=EXAMPLES or 8, **SETTINGS)  # type: ignore[arg-type]
@given(cells=st.lists(st.tuples(st.integers(0, 2999), st.integers(1, 18), CELLS),
                      min_size=1, max_size=3))
def test_extreme_cells_through_detect_are_exit_0_or_3(
        tmp_path: Path, free_text: str, cells: list[tuple[int, int, str]]) -> None:
    """The whole pipeline on a free log with broken cells: exit 0 (repaired) or 3 — never
    1 (incidents are not asked for: only a crash could give it) nor 70."""
    lines = free_text.splitlines()
    rows = [ln.split(",") for ln in lines[1:]]
    for r, c, v in cells:
        rows[r][c % len(rows[r])] = v
    path = tmp_path / "cells.csv"
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n",
                    encoding="utf-8")
    _check_cli(path, "detect", "--config", str(CONFIG), "-o", str(tmp_path / "out"))


# ------------------------------------------------- corrupt MCAP files, through every verb
MAGIC = b"\x89MCAP0\r\n"
SAMPLE_MCAP = REPO / "sample_logs" / "mcap" / "assist_free_p2p.mcap"
SAMPLE_LABELS = REPO / "sample_logs" / "mcap" / "assist_free_p2p.labels.json"


def _rec(op: int, body: bytes) -> bytes:
    """An MCAP record: opcode, length, body."""
    import struct

    return bytes([op]) + struct.pack("<Q", len(body)) + body


def _corrupt_mcaps(folder: Path) -> list[Path]:
    """MCAP files a disk, a crash or a bad copy could leave: the magic bytes and random
    garbage; records whose fields do not fit them (these exited 70: struct.error,
    UnicodeDecodeError); a chunk claiming 32 TiB; a real file cut before its first complete
    message."""
    import struct

    def text(b: bytes) -> bytes:
        return struct.pack("<I", len(b)) + b

    header = _rec(1, text(b"") + text(b""))
    rng = np.random.default_rng(21)
    files = {f"garbage{k}.mcap": MAGIC + rng.bytes(size)
             for k, size in enumerate((0, 9, 1000, 300_000))}
    files.update({
        "schema_name_not_utf8.mcap": MAGIC + header + _rec(
            3, struct.pack("<H", 1) + text(b"\xff\xfe") + text(b"ros2msg") + b"\0" * 4),
        "schema_cut.mcap": MAGIC + header + _rec(3, b"\x01"),
        "channel_cut.mcap": MAGIC + header + _rec(4, b"\x01"),
        "schema_name_2GiB.mcap": MAGIC + header + _rec(3, struct.pack("<HI", 1, 2**31) + b"ab"),
        "chunk_record_cut.mcap": MAGIC + header + _rec(
            6, struct.pack("<QQQI", 0, 0, 12, 0) + text(b"") + struct.pack("<Q", 12)
            + _rec(3, b"\x01\x02\x03")),
        "chunk_32TiB.mcap": MAGIC + header + _rec(
            6, struct.pack("<QQQI", 0, 0, 2**45, 0) + text(b"zstd") + struct.pack("<Q", 4)
            + b"abcd"),
    })
    real = SAMPLE_MCAP.read_bytes()
    files.update({f"cut{frac}.mcap": real[:int(frac * len(real))] for frac in (0.001, 0.02)})
    out = []
    for name, blob in files.items():
        (folder / name).write_bytes(blob)
        out.append(folder / name)
    return out


VERBS: dict[str, list[str]] = {
    "inspect": [], "identify": ["-o", "{out}/m.json"], "calibrate": ["-o", "{out}/c.toml"],
    "detect": ["-o", "{out}/d"], "report": ["-o", "{out}/r.html"],
    "labels": ["--from-channel", "/joint_states/effort[0]", "--above", "1", "--link", "1",
               "-o", "{out}/l.json"],
    "evaluate": ["--labels", str(SAMPLE_LABELS)],
    "view": ["--no-open", "--save", "{out}/v.rrd"],
}


@pytest.mark.parametrize("verb", sorted(VERBS))
def test_a_corrupt_mcap_is_one_line_and_exit_3_in_every_verb(tmp_path: Path,
                                                            verb: str) -> None:
    """An MCAP with valid magic bytes and garbage after them made detect exit 70
    (MemoryError); damaged records made every verb exit 70 (struct.error): now exit 3 and
    one line naming the file, and nothing written."""
    out = tmp_path / "out"
    out.mkdir()
    for path in _corrupt_mcaps(tmp_path):
        args = [a.format(out=out) for a in VERBS[verb]]
        r = CliRunner().invoke(main, [verb, str(path), *args])
        note = f"{verb} {path.name}: exit {r.exit_code}\n{r.stderr[-2000:]}"
        assert r.exit_code == 3, note
        assert "Traceback" not in r.stderr, note
        errors = [ln for ln in r.stderr.splitlines() if ln.startswith("impactcli: error:")]
        assert len(errors) == 1 and errors[0].startswith(f"impactcli: error: {path}: "), note
        assert list(out.rglob("*")) == [] or verb == "detect", note
    if verb == "detect":
        assert not list(out.rglob("*.json")), "a timeline written for a corrupt MCAP"


def test_a_real_mcap_cut_after_some_messages_is_read_with_a_warning(tmp_path: Path) -> None:
    """docs/formats.md, "MCAP": a valid start whose records end early, holding complete
    messages, yields what was recorded, warned."""
    real = SAMPLE_MCAP.read_bytes()
    path = tmp_path / "cut.mcap"
    path.write_bytes(real[:len(real) // 2])
    r = CliRunner().invoke(main, ["inspect", str(path), "--json"])
    assert r.exit_code == 0, r.stderr
    assert any("truncated" in ln for ln in r.stderr.splitlines()), r.stderr
    full = CliRunner().invoke(main, ["inspect", str(SAMPLE_MCAP), "--json"])
    import json

    assert 0 < json.loads(r.stdout)["n_samples"] < json.loads(full.stdout)["n_samples"]
