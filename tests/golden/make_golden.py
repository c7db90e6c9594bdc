"""Golden outputs of the CLI on the sample logs: what each verb answers today, to compare
later code against (tests/test_golden.py): byte for byte on the machine that made them, and
beyond a float's last bits on any other (:func:`agree`; ``IMPACTCLI_GOLDEN_EXACT=1`` asks for
the bytes).

Made at the commit before the one-path refactor (tag ``base-onepath``), each case a fresh
``impactcli`` process: ``detect --signals`` of the 12 sample logs, CSV and MCAP, with the arm's
config and without (timeline JSON; the signals Parquet's sha256 and :func:`signals_summary`),
``report --json`` (report JSON; the HTML's sha256 and :func:`skeleton_sha256`),
``calibrate`` as docs/validation.md gives it (config TOML, one JSON), ``identify`` (model
JSON, each kind needing no URDF), ``inspect --json`` of every sample log and of format
variants built here (';' CSV, ISO-time CSV, .npz through a channel map), and the exit code +
stderr/stdout of inputs refused today.

Normalisation (so goldens compare across checkouts and machines): logs are named relative to
a fixed working directory (sample_logs/, the repo root for ``calibrate``, or the fixtures'
folder), which also keeps the Parquet's ``impactcli.input_path`` metadata checkout-independent;
in text outputs the absolute paths of sample_logs/, the repo, the fixtures' and the output
folder become ``<SAMPLES>``, ``<ROOT>``, ``<FIXTURES>``, ``<OUT>``. Fixtures are written with no
time stamps (plain CSV, .npz members dated 1980-01-01). The tool version stays in.

Run: ``python tests/golden/make_golden.py`` (rewrite every golden; ~10 min on 2 busy cores),
``--only PREFIX`` (cases whose id starts with it), ``--check`` (compare, exit 1 on a difference).
"""

from __future__ import annotations

import argparse
import difflib
import gzip
import hashlib
import io
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
import zipfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

GOLDEN = Path(__file__).resolve().parent
ROOT = GOLDEN.parents[1]
SAMPLES = ROOT / "sample_logs"
RESULTS = GOLDEN / "results.json"
OUTPUT_DIRS = ("detect", "report", "calibrate", "identify", "inspect")

STEMS = ("assist_clamps", "assist_free_fm_triangle", "assist_free_multisine", "assist_free_p2p",
         "assist_free_triangle", "assist_impacts", "assist_payload", "assist_pushes",
         "heavy_free_multisine", "heavy_free_p2p", "heavy_free_triangle", "heavy_impacts")
SUFFIX = {"csv": ".csv.gz", "mcap": ".mcap"}
CONFIG = {"assist": "assist_like.config.toml", "heavy": "heavy_geared.config.toml"}
VARIANT_SOURCE = "csv/assist_free_p2p.csv.gz"   # 40 s at 250 Hz, 2 joints, every channel
NPZ_SIGNALS = ("position", "velocity", "torque", "position_ref", "velocity_ref",
               "acceleration_ref", "torque_model", "torque_ext")

# (argv, cwd) -> (exit code, stdout, stderr)
Invoke = Callable[[list[str], Path], tuple[int, str, str]]


@dataclass(frozen=True)
class Case:
    """One CLI run. ``argv`` may hold ``{out}`` (the run's output folder); ``cwd`` is
    ``samples``, ``root`` or ``fixtures``. ``texts`` maps an output (a file in ``{out}``, or
    ``-`` for stdout) to its golden file under tests/golden/; ``digests`` are files in
    ``{out}`` whose sha256 is kept (text files after normalisation, others as bytes).
    ``error``: keep stdout and stderr. ``tier``: ``quick`` and ``slow`` run in the default
    test suite (``slow`` marked so), ``all`` only with IMPACTCLI_GOLDEN=all."""

    id: str
    argv: tuple[str, ...]
    cwd: str = "samples"
    texts: tuple[tuple[str, str], ...] = ()
    digests: tuple[str, ...] = ()
    error: bool = False
    tier: str = "all"


@dataclass
class Outcome:
    """A case's normalised answers: golden texts by path, and its record in results.json."""

    texts: dict[str, str] = field(default_factory=dict)
    record: dict[str, object] = field(default_factory=dict)


def _arm(stem: str) -> str:
    return stem.split("_", 1)[0]


# The default test subset: every verb and format, the CSV timelines with config all of them;
# its cases of more than ~2 s (on a busy machine) are marked slow.
_QUICK = {"detect/csv/config/" + s for s in STEMS} | {
    "detect/csv/none/heavy_impacts", "detect/mcap/config/assist_free_p2p",
    "detect/variants/semicolon", "identify/csv/assist_free_multisine.planar",
    "inspect/csv/assist_free_p2p", "inspect/mcap/assist_free_p2p", "inspect/mcap/heavy_impacts",
    "inspect/variants/semicolon", "inspect/variants/iso_time", "inspect/variants/npz_map"}
_SLOW = {"detect/csv/none/assist_impacts", "detect/mcap/config/assist_pushes",
         "detect/mcap/config/heavy_impacts", "detect/mcap/none/heavy_free_multisine",
         "report/csv_config_assist_pushes", "calibrate/assist_like.toml",
         "calibrate/heavy_geared.toml", "identify/csv/heavy_free_p2p.coupled"}


def _tier(case_id: str) -> str:
    if case_id.startswith("errors/") or case_id in _QUICK:
        return "quick"
    return "slow" if case_id in _SLOW else "all"


def _detect_cases() -> Iterable[Case]:
    for fmt, suffix in SUFFIX.items():
        for mode in ("config", "none"):
            for stem in STEMS:
                cfg = ("--config", CONFIG[_arm(stem)]) if mode == "config" else ()
                cid = f"detect/{fmt}/{mode}/{stem}"
                yield Case(cid, ("detect", f"{fmt}/{stem}{suffix}", *cfg, "--signals",
                                 "-o", "{out}"),
                           texts=((f"{stem}.timeline.json", f"{cid}.timeline.json"),),
                           digests=(f"{stem}.signals.parquet",))
    cfg = str(SAMPLES / CONFIG["assist"])
    for name, log, extra in (("semicolon", "semicolon.csv", ()), ("iso_time", "iso_time.csv", ()),
                             ("npz_map", "p2p.npz", ("--channel-map", "p2p.map.json"))):
        stem = log.split(".")[0]
        cid = f"detect/variants/{name}"
        yield Case(cid, ("detect", log, *extra, "--config", cfg, "--signals", "-o", "{out}"),
                   cwd="fixtures", texts=((f"{stem}.timeline.json", f"{cid}.timeline.json"),),
                   digests=(f"{stem}.signals.parquet",))


def _other_cases() -> Iterable[Case]:
    report = ("-o", "{out}/report.html", "--json", "{out}/report.json")
    for name, logs in (("csv_config_assist_pushes",
                        ("csv/assist_pushes.csv.gz", "--config", CONFIG["assist"])),
                       ("csv_config_assist_clamps_impacts",
                        ("csv/assist_clamps.csv.gz", "csv/assist_impacts.csv.gz",
                         "--config", CONFIG["assist"])),
                       ("mcap_none_heavy_impacts", ("mcap/heavy_impacts.mcap",))):
        yield Case(f"report/{name}", ("report", *logs, *report),
                   texts=(("report.json", f"report/{name}.report.json"),),
                   digests=("report.html",))
    # docs/validation.md's command for assist_like.config.toml; the heavy arm's alike
    # (calibrate's default: the leave-one-out rule, with the rate its thresholds give)
    for arm, cfg in (("assist", "assist_like"), ("heavy", "heavy_geared")):
        logs = tuple(f"sample_logs/csv/{arm}_free_{m}.csv.gz"
                     for m in ("triangle", "p2p", "multisine"))
        robot = f"sample_logs/csv/{arm}_free_triangle.robot.json"
        for ext in ("toml", "json") if arm == "assist" else ("toml",):
            out = f"{cfg}.config.{ext}"
            yield Case(f"calibrate/{cfg}.{ext}",
                       ("calibrate", *logs, "--robot", robot, "-o", f"{{out}}/{out}"),
                       cwd="root", texts=((out, f"calibrate/{out}"),))
    for fmt, stem, kind, robot in (("csv", "assist_free_multisine", "planar", True),
                                   ("csv", "heavy_free_p2p", "coupled", False),
                                   ("csv", "heavy_free_p2p", "decoupled", False),
                                   ("mcap", "assist_free_p2p", "decoupled", False)):
        cid = f"identify/{fmt}/{stem}.{kind}"
        rob = ("--robot", f"{fmt}/{stem}.robot.json") if robot else ()
        yield Case(cid, ("identify", f"{fmt}/{stem}{SUFFIX[fmt]}", *rob, "--kind", kind,
                         "-o", "{out}/model.json"),
                   texts=(("model.json", f"{cid}.model.json"),))
    for fmt, suffix in SUFFIX.items():
        for stem in STEMS:
            cid = f"inspect/{fmt}/{stem}"
            yield Case(cid, ("inspect", f"{fmt}/{stem}{suffix}", "--json"),
                       texts=(("-", f"{cid}.json"),))
    for name, args in (("semicolon", ("semicolon.csv",)), ("iso_time", ("iso_time.csv",)),
                       ("npz_map", ("p2p.npz", "--channel-map", "p2p.map.json"))):
        cid = f"inspect/variants/{name}"
        yield Case(cid, ("inspect", *args, "--json"), cwd="fixtures",
                   texts=(("-", f"{cid}.json"),))


def _error_cases() -> Iterable[Case]:
    both = {"missing_file": ("nope.csv",), "non_numeric_cell": ("bad_cell.csv",),
            "ragged_line": ("ragged.csv",), "one_row": ("one_row.csv",),
            "empty_csv": ("empty.csv",), "truncated_mcap": ("truncated.mcap",),
            "not_mcap": ("not_mcap.mcap",), "npz_without_map": ("nomap.npz",)}
    for name, args in both.items():
        yield Case(f"errors/detect/{name}", ("detect", *args, "-o", "{out}"),
                   cwd="fixtures", error=True)
        yield Case(f"errors/inspect/{name}", ("inspect", *args), cwd="fixtures", error=True)
    # `detect` on this file exits 70 (MemoryError in the streamed MCAP block reader): a bug,
    # not a golden; `inspect` refuses it (exit 3)
    yield Case("errors/inspect/garbage_after_mcap_magic", ("inspect", "garbage.mcap"),
               cwd="fixtures", error=True)
    p2p = str(SAMPLES / "csv/assist_free_p2p.csv.gz")
    heavy = str(SAMPLES / "csv/heavy_free_p2p.csv.gz")
    for name, args in (
            ("shorter_than_warmup", ("detect", "too_short.csv")),
            ("config_value_out_of_range", ("detect", p2p, "--config", "bad_eta.toml")),
            ("config_value_wrong_type", ("detect", p2p, "--config", "bad_type.toml")),
            ("config_missing", ("detect", p2p, "--config", "no_such.toml")),
            ("config_other_rate", ("detect", heavy, "--config", str(SAMPLES / CONFIG["assist"]))),
            ("glob_matches_nothing", ("detect", "nothing*.csv")),
            ("unknown_option", ("detect", "too_short.csv", "--bogus"))):
        yield Case(f"errors/detect/{name}", (*args, "-o", "{out}"), cwd="fixtures", error=True)
    yield Case("errors/calibrate/too_short",
               ("calibrate", "too_short.csv", "-o", "{out}/x.toml"), cwd="fixtures", error=True)
    yield Case("errors/identify/too_short",
               ("identify", "too_short.csv", "-o", "{out}/m.json"), cwd="fixtures", error=True)


def all_cases() -> list[Case]:
    cases = [*_detect_cases(), *_other_cases(), *_error_cases()]
    unknown = (_QUICK | _SLOW) - {c.id for c in cases}
    assert not unknown, unknown
    return [Case(c.id, c.argv, c.cwd, c.texts, c.digests, c.error, _tier(c.id)) for c in cases]


# ------------------------------------------------------------------------------ fixtures
def _iso(seconds: str) -> str:
    """'12.348000000' (s since the first sample) → an ISO-8601 UTC stamp from 2024-05-01 12:00."""
    whole, _, frac = seconds.partition(".")
    ns = int(whole) * 10**9 + int((frac + "000000000")[:9])
    assert ns % 1000 == 0, seconds
    t = datetime(2024, 5, 1, 12, 0, 0, tzinfo=UTC) + timedelta(microseconds=ns // 1000)
    return t.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """np.savez, but with fixed member dates and attributes (the same bytes every run)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED) as zf:
        for key, a in arrays.items():
            info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.create_system, info.external_attr = 3, 0o644 << 16
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.ascontiguousarray(a), version=(1, 0),
                                      allow_pickle=False)
            zf.writestr(info, buf.getvalue())


def build_fixtures(d: Path) -> None:
    """Write the variant and refused inputs into ``d`` (deterministic, from the sample logs'
    bytes only: no impactcli code, so a reader's change cannot change its own fixtures)."""
    with gzip.open(SAMPLES / VARIANT_SOURCE, "rt", encoding="utf-8", newline="") as f:
        lines = f.read().splitlines()
    header, rows = lines[0], lines[1:]

    def text(ls: Iterable[str]) -> str:
        return "".join(x + "\n" for x in ls)

    (d / "semicolon.csv").write_text(text(x.replace(",", ";") for x in lines), "utf-8")
    (d / "iso_time.csv").write_text(
        text([header, *(_iso(r.split(",", 1)[0]) + "," + r.split(",", 1)[1] for r in rows)]),
        "utf-8")
    names = header.split(",")
    table = np.array([[float(c) for c in r.split(",")] for r in rows])
    joints = list(dict.fromkeys(n.split(".")[0] for n in names[1:]))
    arrays = {"t": table[:, 0]}
    for s in NPZ_SIGNALS:
        arrays[s] = table[:, [names.index(f"{j}.{s}") for j in joints]]
    _write_npz(d / "p2p.npz", arrays)
    cmap = {"format": "npz", "time": {"key": "t", "unit": "s"},
            "joints": [{"name": j, **{s: {"key": s, "index": k} for s in NPZ_SIGNALS}}
                       for k, j in enumerate(joints)]}
    (d / "p2p.map.json").write_text(json.dumps(cmap, indent=1) + "\n", "utf-8")

    head = lines[:501]
    bad = head[99].split(",")
    bad[1] = "abc"
    (d / "bad_cell.csv").write_text(text([*head[:99], ",".join(bad), *head[100:]]), "utf-8")
    (d / "ragged.csv").write_text(text([*head[:199], "1,2,3", *head[200:]]), "utf-8")
    (d / "one_row.csv").write_text(text(lines[:2]), "utf-8")
    (d / "too_short.csv").write_text(text(lines[:101]), "utf-8")   # 0.4 s < the warm-up
    (d / "empty.csv").write_text("", "utf-8")
    mcap = (SAMPLES / "mcap/assist_free_p2p.mcap").read_bytes()
    (d / "truncated.mcap").write_bytes(mcap[:100_000])
    (d / "not_mcap.mcap").write_bytes(b"hello, this is not an mcap file at all")
    (d / "garbage.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 4)
    _write_npz(d / "nomap.npz", {"t": np.arange(5.0)})
    cfg = (SAMPLES / CONFIG["assist"]).read_text("utf-8")
    for name, old, new in (("bad_eta.toml", "\neta = 2\n", "\neta = -1\n"),
                           ("bad_type.toml", "\np = 20\n", '\np = "twenty"\n')):
        assert cfg.count(old) == 1, old
        (d / name).write_text(cfg.replace(old, new), "utf-8")


# ------------------------------------------------------------------------------ running
def normalise(text: str, places: dict[str, Path]) -> str:
    """Replace each place's absolute path (as given and resolved) by ``<NAME>``, longest
    first, only where the path ends (not inside a longer name)."""
    subs = {str(q): f"<{name}>" for name, p in places.items() for q in (p, p.resolve())}
    for s in sorted(subs, key=len, reverse=True):
        text = re.sub(re.escape(s) + r"(?![\w.-])", lambda _m, s=s: subs[s], text)
    return text


def run_case(case: Case, invoke: Invoke, fixtures: Path, out: Path) -> Outcome:
    """Run ``case`` with outputs in ``out`` (an empty folder) → its normalised answers."""
    cwd = {"samples": SAMPLES, "root": ROOT, "fixtures": fixtures}[case.cwd]
    places = {"OUT": out, "FIXTURES": fixtures, "SAMPLES": SAMPLES, "ROOT": ROOT}
    argv = [a.replace("{out}", str(out)) for a in case.argv]
    code, stdout, stderr = invoke(argv, cwd)
    res = Outcome(record={"exit_code": code})
    if case.error:
        res.record.update(stdout=normalise(stdout, places), stderr=normalise(stderr, places))
        return res
    if code != 0:
        raise RuntimeError(f"{case.id}: exit {code}\n{stderr[-3000:]}")
    for src, dest in case.texts:
        raw = stdout if src == "-" else (out / src).read_text("utf-8")
        res.texts[dest] = normalise(raw, places)
    sha: dict[str, str] = {}
    content: dict[str, object] = {}
    for name in case.digests:
        data = (out / name).read_bytes()
        if name.endswith(".parquet"):
            content[name] = signals_summary(data)
        else:
            text = normalise(data.decode("utf-8"), places)
            data = text.encode("utf-8")
            content[name] = skeleton_sha256(text)
        sha[name] = hashlib.sha256(data).hexdigest()
    if sha:
        res.record["sha256"] = sha
        res.record["content"] = content
    return res


def load_records() -> dict[str, dict[str, object]]:
    return json.loads(RESULTS.read_text("utf-8")) if RESULTS.exists() else {}


# ------------------------------------------------------------------------------ comparing
#: A number in a text output (not one inside a word, as ``j2``).
_NUMBER = re.compile(r"(?<![\w.])-?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
#: A sha256 in an output: of the log, config and URDF it names the same bytes on every
#: machine; of a model identified here it follows the model's last bits.
_SHA256 = re.compile(r"\b[0-9a-f]{64}\b")
#: Two machines' answers agree when each float is within RTOL of the golden's (integers,
#: strings and the shape exactly). The last bits of a float differ between CPUs (OpenBLAS and
#: NumPy pick their SIMD kernels by CPU: AVX-512 or AVX2), and an ill-conditioned least
#: squares passes them on: an identified model's parameters agree to ~2e-7 between an
#: AVX-512 and an AVX2 machine, a calibration's predicted false-alarm rates to ~6e-8 ...
RTOL, ATOL = 1e-6, 1e-12
#: ... and model selection's cross-validation figures (``fit.selection``: fold fits of the
#: heavy geared arm's joint 2) to ~1.4e-4.
RTOL_LOOSE, LOOSE_KEYS = 1e-3, frozenset({"selection"})
#: ``IMPACTCLI_GOLDEN_EXACT=1``: the same bytes or a difference (on the goldens' machine, to
#: show a reshaping changed no answer in any bit).
EXACT = os.environ.get("IMPACTCLI_GOLDEN_EXACT") == "1"


def _close(x: float, y: float, rtol: float = RTOL) -> bool:
    """Two floats agree: equal (NaN with NaN), or both finite and within ``rtol``."""
    if x == y or (math.isnan(x) and math.isnan(y)):
        return True
    return (math.isfinite(x) and math.isfinite(y)
            and abs(x - y) <= ATOL + rtol * max(abs(x), abs(y)))


def _is_float(token: str) -> bool:
    return any(c in token for c in ".eE")


def _tokens_agree(old: str, new: str) -> bool:
    """Two texts are the same but for floats within :data:`RTOL` and sha256s."""
    s0, s1 = _SHA256.sub("<sha256>", old), _SHA256.sub("<sha256>", new)
    if _NUMBER.sub("#", s0) != _NUMBER.sub("#", s1):
        return False
    return all(a == b or (_is_float(a) and _is_float(b) and _close(float(a), float(b)))
               for a, b in zip(_NUMBER.findall(s0), _NUMBER.findall(s1), strict=True))


def _values_agree(old: object, new: object, rtol: float = RTOL) -> bool:
    """Parsed answers agree: the same keys, lengths, integers and strings (sha256s aside),
    floats within ``rtol`` (:data:`RTOL_LOOSE` under a key of :data:`LOOSE_KEYS`)."""
    if isinstance(old, dict) and isinstance(new, dict):
        return old.keys() == new.keys() and all(
            _values_agree(v, new[k], RTOL_LOOSE if k in LOOSE_KEYS else rtol)
            for k, v in old.items())
    if isinstance(old, list) and isinstance(new, list):
        return len(old) == len(new) and all(_values_agree(a, b, rtol)
                                            for a, b in zip(old, new, strict=True))
    if isinstance(old, float) and isinstance(new, float):
        return _close(old, new, rtol)
    if isinstance(old, str) and isinstance(new, str):
        return _SHA256.sub("<sha256>", old) == _SHA256.sub("<sha256>", new)
    return type(old) is type(new) and old == new


def agree(dest: str, old: str, new: str) -> bool:
    """A golden text and today's agree beyond a float's last bits (:data:`RTOL`): JSON and
    TOML compared as values, other texts token by token."""
    if old == new:
        return True
    if EXACT:
        return False
    try:
        if dest.endswith(".json"):
            return _values_agree(json.loads(old), json.loads(new))
        if dest.endswith(".toml"):
            return _values_agree(tomllib.loads(old), tomllib.loads(new))
    except ValueError:
        return False
    return _tokens_agree(old, new)


def skeleton_sha256(text: str) -> str:
    """The sha256 of ``text`` with every sha256 and number masked: a report's HTML, the same
    on every machine (its numbers are its JSON's, compared there)."""
    masked = _NUMBER.sub("#", _SHA256.sub("<sha256>", text))
    return hashlib.sha256(masked.encode("utf-8")).hexdigest()


def signals_summary(data: bytes) -> dict[str, object]:
    """What a signals Parquet holds, in numbers two machines share to :data:`RTOL`: its schema
    and metadata, its rows, and per column the NaN count, min, max, Σ|x|, Σx² and Σ i·x over
    the sample index i (so a detector's decisions give their count and where they lie)."""
    import pyarrow.parquet as pq

    table = pq.read_table(io.BytesIO(data))
    meta = {k.decode(): v.decode() for k, v in (table.schema.metadata or {}).items()}
    cols: dict[str, list[float]] = {}
    for name in table.column_names:
        x = table.column(name).to_numpy().astype(float)
        keep = ~np.isnan(x)
        ok = x[keep]
        cols[name] = ([float(x.size - ok.size), float(ok.min()), float(ok.max()),
                       float(np.abs(ok).sum()), float((ok * ok).sum()),
                       float(np.flatnonzero(keep).astype(float) @ ok)] if ok.size
                      else [float(x.size)])
    return {"schema": str(table.schema.remove_metadata()), "metadata": meta,
            "rows": table.num_rows, "columns": cols}


def _summary_agrees(old: object, new: object) -> bool:
    """Two :func:`signals_summary` s agree: as values (:func:`_values_agree`), but a
    column's min and max to :data:`RTOL` of the larger of their magnitudes — a min near 0
    of a column that reaches thousands (a statistic at rest) holds the column's precision,
    not its own."""
    if not (isinstance(old, dict) and isinstance(new, dict) and "columns" in old
            and "columns" in new):
        return _values_agree(old, new)
    rest = _values_agree({k: v for k, v in old.items() if k != "columns"},
                         {k: v for k, v in new.items() if k != "columns"})
    a, b = old["columns"], new["columns"]
    if not (rest and isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys()):
        return False
    for name, w in a.items():
        g = b[name]
        if not (isinstance(w, list) and isinstance(g, list) and len(w) == len(g)):
            return False
        if len(w) > 2:
            scale = max(abs(w[1]), abs(w[2]))
            if not all(abs(x - y) <= RTOL * scale + ATOL for x, y in zip(w[1:3], g[1:3],
                                                                        strict=True)):
                return False
        if not (_values_agree([w[0], *w[3:]], [g[0], *g[3:]]) if len(w) > 2
                else _values_agree(w, g)):
            return False
    return True


def _record_agrees(want: dict[str, object] | None, got: dict[str, object]) -> bool:
    """A case's record agrees: its exit code; an error's stdout and stderr; each digest's
    content (a Parquet's :func:`signals_summary`, a text's :func:`skeleton_sha256`), with the
    sha256 of its bytes the same on the goldens' machine only."""
    if want == got:
        return True
    if EXACT or want is None or want.keys() != got.keys():
        return False
    return all(
        (key == "sha256" and isinstance(w, dict) and isinstance(g, dict) and w.keys() == g.keys())
        or (key in ("stdout", "stderr") and _tokens_agree(str(w), str(g)))
        or (key == "content" and isinstance(w, dict) and isinstance(g, dict)
            and w.keys() == g.keys() and all(
                # a skeleton's sha256 exactly; a summary beyond its floats' last bits
                w[n] == g[n] if isinstance(g[n], str) else _summary_agrees(w[n], g[n])
                for n in g))
        or (key not in ("sha256", "content") and _values_agree(w, g))
        for key, g in got.items() for w in (want[key],))


def differences(case: Case, got: Outcome, records: dict[str, dict[str, object]]) -> list[str]:
    """What differs between ``got`` and the goldens beyond a float's last bits (empty: the
    same answers). The goldens were made on one machine; on it the answers are the same bytes,
    and on another CPU the same to :data:`RTOL` (:func:`agree`)."""
    out = []
    want = records.get(case.id)
    if not _record_agrees(want, got.record):
        out.append(f"{case.id}: record {json.dumps(got.record, sort_keys=True)[:2000]}\n"
                   f"  golden {json.dumps(want, sort_keys=True)[:2000]}")
    for dest, text in got.texts.items():
        path = GOLDEN / dest
        old = path.read_bytes().decode("utf-8") if path.exists() else ""
        if not agree(dest, old, text):
            diff = difflib.unified_diff(old.splitlines(), text.splitlines(), f"golden/{dest}",
                                        "now", n=2, lineterm="")
            out.append("\n".join(list(diff)[:60]))
    return out


_MAIN = ("import sys; sys.path.insert(0, sys.argv.pop(1)); "
         "from impactcli.cli import main; main(prog_name='impactcli')")


def invoke_process(argv: list[str], cwd: Path) -> tuple[int, str, str]:
    """The CLI of this checkout in a fresh process."""
    p = subprocess.run([sys.executable, "-c", _MAIN, str(ROOT), *argv], cwd=cwd,
                       capture_output=True, encoding="utf-8", check=False)
    return p.returncode, p.stdout, p.stderr


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="cases whose id starts with this")
    ap.add_argument("--check", action="store_true", help="compare; write nothing")
    args = ap.parse_args()
    cases = [c for c in all_cases() if c.id.startswith(args.only)]
    records = load_records()
    problems: list[str] = []
    texts: dict[str, str] = {}
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        fixtures = Path(tmp) / "fixtures"
        fixtures.mkdir()
        build_fixtures(fixtures)
        for i, case in enumerate(cases):
            out = Path(tmp) / f"out{i}"
            out.mkdir()
            t = time.perf_counter()
            try:
                got = run_case(case, invoke_process, fixtures, out)
            except RuntimeError as e:  # a case that should succeed failed
                if not args.check:
                    raise
                problems.append(str(e))
                continue
            shutil.rmtree(out)
            print(f"{time.perf_counter() - t:6.1f} s  {case.tier:5}  {case.id}", flush=True)
            if args.check:
                problems += differences(case, got, records)
            else:
                records[case.id] = got.record
                texts.update(got.texts)
    if not args.check:
        if not args.only:  # a full run: no golden of a removed case stays
            records = {c.id: records[c.id] for c in cases}
            for d in OUTPUT_DIRS:
                shutil.rmtree(GOLDEN / d, ignore_errors=True)
        for dest, text in texts.items():
            (GOLDEN / dest).parent.mkdir(parents=True, exist_ok=True)
            (GOLDEN / dest).write_bytes(text.encode("utf-8"))
        RESULTS.write_text(json.dumps(records, indent=1, sort_keys=True, ensure_ascii=False)
                           + "\n", "utf-8")
    print(f"{len(cases)} cases in {time.perf_counter() - t_all:.0f} s"
          + (f"; {len(problems)} differ" if args.check else ""))
    for p in problems:
        print(p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
