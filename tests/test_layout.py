"""The package's layout holds (docs/development.md): imports go down the layers only, no
module imports itself back through others, no private name crosses a module, no CLI verb
imports another verb's module (only the shared options and formatting), no module is
over 700 lines, no two modules share a file name, and every file the code and docs cite is
in the repo. Read from the source with ``ast`` (function-local and TYPE_CHECKING imports
count too)."""

from __future__ import annotations

import ast
import functools
import re
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "impactcli"

#: Layers, low to high: a module may import its own layer and the ones below.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("impactcli", "impactcli.errors"),
    ("impactcli.clock", "impactcli.columns", "impactcli.cores", "impactcli.files",
     "impactcli.schema", "impactcli.spill"),
    ("impactcli.sample_channels", "impactcli.types", "impactcli.config"),
    ("impactcli.logs",),
    ("impactcli.model", "impactcli.sim"),
    ("impactcli.detect",),
    ("impactcli.quality",),
    ("impactcli.outputs",),
    ("impactcli.run",),
    ("impactcli.study",),
    ("impactcli.cli",),
    ("impactcli.__main__",),
)
#: Packages in the same layer that must not import each other.
APART = {("impactcli.sim", "impactcli.model"), ("impactcli.model", "impactcli.sim")}
MAX_LINES = 700


def _modules() -> dict[str, Path]:
    out = {}
    for f in sorted(PKG.rglob("*.py")):
        parts = list(f.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = f
    return out


MODULES = _modules()


def _imports(name: str, path: Path) -> list[tuple[str, str, int]]:
    """(target module, imported name or "", line) of every import of ``name``'s source."""
    is_pkg = path.name == "__init__.py"
    here = name.split(".") if is_pkg else name.split(".")[:-1]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(a.name, "", node.lineno) for a in node.names
                    if a.name.split(".")[0] == "impactcli"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[: len(here) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != "impactcli":
                continue
            for a in node.names:
                sub = f"{mod}.{a.name}"
                out.append((sub, "", node.lineno) if sub in MODULES
                           else (mod, a.name, node.lineno))
    return out


@functools.cache
def edges() -> dict[str, list[tuple[str, str, int]]]:
    """Every module's imports of impactcli (parsed once, when a test first asks)."""
    return {m: _imports(m, p) for m, p in MODULES.items()}


def _unit(mod: str) -> str:
    for layer in LAYERS:
        for u in sorted(layer, key=len, reverse=True):
            if mod == u or (u != "impactcli" and mod.startswith(u + ".")):
                return u
    return mod


def _layer(mod: str) -> int:
    u = _unit(mod)
    for i, layer in enumerate(LAYERS):
        if u in layer:
            return i
    raise AssertionError(f"{mod} is in no layer of tests/test_layout.py")


def test_every_module_is_in_a_layer() -> None:
    for m in MODULES:
        _layer(m)


def test_imports_go_down_the_layers_only() -> None:
    bad = [f"{MODULES[a].relative_to(ROOT)}:{line} imports {b}"
           for a, rows in edges().items() for b, _, line in rows
           if _layer(b) > _layer(a) or (_unit(a), _unit(b)) in APART]
    assert not bad, "\n".join(bad)


def test_no_import_cycle() -> None:
    graph = {a: {b for b, _, _ in rows if b in MODULES and b != a} for a, rows in edges().items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    assert not cycles, cycles


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def test_no_private_name_crosses_a_module() -> None:
    bad = [f"{MODULES[a].relative_to(ROOT)}:{line} imports {b}.{n}"
           for a, rows in edges().items() for b, n, line in rows
           if b != a and (_private(n) or _private(b.rsplit(".", 1)[-1]))]
    assert not bad, "\n".join(bad)


#: The cli modules that hold shared options or formatting helpers, which a verb may import;
#: every other cli module is a verb, whose logic no other verb imports (it lives in run/).
CLI_SHARED = ("impactcli.cli", "impactcli.cli.options", "impactcli.cli.fit_table")


def test_no_side_channel_through_the_click_context() -> None:
    """Options reach a verb as its parameters (the read options as one ReadOptions), never
    through the click context's ``meta``."""
    meta = re.compile(r"\bctx\.meta\b|\.meta\.(get|setdefault)\(|\.meta\[")
    bad = [m for m, p in MODULES.items() if meta.search(p.read_text("utf-8"))]
    assert not bad, bad


#: The one file the maths layers may read, and why.
MATHS_READS = {"impactcli.model.identification": "a robot description's URDF given by path, "
                                                  "when it does not carry its text"}


def test_model_detect_and_quality_never_open_a_file() -> None:
    """The maths layers (model/, detect/, quality/) never open, read or write a file: the
    readers, the store and the writers do (MATHS_READS names the one exception)."""
    io = re.compile(r"\bopen\(|\.read_text\(|\.write_text\(|\.read_bytes\(|np\.(load|save)\w*\(|"
                    r"atomic_write")
    bad = [m for m, p in MODULES.items()
           if _unit(m) in ("impactcli.model", "impactcli.detect", "impactcli.quality")
           and m not in MATHS_READS and io.search(p.read_text("utf-8"))]
    assert not bad, bad


def test_no_cli_verb_imports_another_verbs_logic() -> None:
    bad = [f"{MODULES[a].relative_to(ROOT)}:{line} imports {b}"
           for a, rows in edges().items() if _unit(a) == "impactcli.cli"
           for b, _, line in rows
           if _unit(b) == "impactcli.cli" and b != a and b not in CLI_SHARED
           and a != "impactcli.cli"]
    assert not bad, "\n".join(bad)


def test_no_test_imports_a_benchmark() -> None:
    """Benchmarks are scripts that measure; what a test and a benchmark share lives in a
    test helper module (tests/sample_criteria.py, tests/incident_criteria.py,
    tests/isolation_cases.py), not behind the benchmarks' folder put on sys.path."""
    pattern = re.compile(r"^\s*(from\s+(\.|tests\.)benchmarks\b|import\s+tests\.benchmarks\b"
                         r"|from\s+\.\s+import\s+benchmarks\b"
                         r"|sys\.path\.\w+\(.*[\"']benchmarks[\"'])", re.M)  # or by the path
    bad = [f.name for f in sorted((ROOT / "tests").glob("*.py"))
           if pattern.search(f.read_text("utf-8"))]
    assert not bad, bad


def test_the_channels_are_declared_once() -> None:
    """The channels of a sample are declared once, as the fields of
    impactcli.sample_channels.Channels: the log, the readers' chunks and the replay's arrays are
    Channels; no other class declares more than three of them (a record of the few it
    uses — the motion check's velocity and position, a JointState message's fields, the
    writers' torque, position and reference in a replay step — is not the channel set
    again); no other module lists channel names or renames channels.py's tuples of
    them (a test of membership in a few is not a list)."""
    import ast
    import dataclasses

    from impactcli.logs.layout import LogChunk
    from impactcli.run.replay import ChunkArrays
    from impactcli.sample_channels import CHANNEL_NAMES, CHANNELS, Channels
    from impactcli.types import RobotLog

    assert tuple(f.name for f in dataclasses.fields(Channels)) == CHANNEL_NAMES
    assert tuple(c.name for c in CHANNELS) == CHANNEL_NAMES
    for cls in (RobotLog, LogChunk, ChunkArrays):
        assert issubclass(cls, Channels), cls
    names = "|".join(CHANNEL_NAMES)
    spelled = re.compile(rf"^\w+(:[^=]+)?\s*=\s*[(\[{{]?\s*(\"({names})\",\s*){{2,}}", re.M)
    renamed = re.compile(r"^\w+(:[^=]+)?\s*=\s*\w*CHANNEL(S|_NAMES)\s*$", re.M)
    bad = []
    for m, p in MODULES.items():
        if m == "impactcli.sample_channels":
            continue
        text = p.read_text("utf-8")
        bad += [(m, "lists or renames channel names") for pattern in (spelled, renamed)
                if pattern.search(text)]
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ClassDef):
                own = [a.target.id for a in node.body if isinstance(a, ast.AnnAssign)
                       and isinstance(a.target, ast.Name) and a.target.id in CHANNEL_NAMES]
                if len(own) > 3:
                    bad.append((m, f"class {node.name} declares {own}"))
    assert not bad, bad


#: The modules that may make temporary files or folders other than through the one
#: temporary store (impactcli/spill.py), and why: none of them keeps per-sample columns.
TEMP_ALLOWED = {
    "impactcli.spill": "the one temporary store",
    "impactcli.files": "atomic outputs: a temporary file beside the output, then renamed",
    "impactcli.logs.write": "atomic logs written by `simulate` and the tests' writers",
    "impactcli.logs.urls": "a remote log or file downloaded before it is read",
    "impactcli.logs.urdf": "a URDF rewritten for Pinocchio's parser",
    "impactcli.run.batch": "a remote output prefix: the outputs made locally, then uploaded",
    "impactcli.cli.view": "the recording the viewer opens",
}


def test_one_temporary_store() -> None:
    """Per-sample columns spill through impactcli/spill.py only: no other module makes
    temporary files (beyond :data:`TEMP_ALLOWED`) or judges free disk space."""
    made = re.compile(r"tempfile\.(mkdtemp|mkstemp|TemporaryFile|TemporaryDirectory|"
                      r"NamedTemporaryFile|SpooledTemporaryFile)\b|disk_usage\(")
    bad = [m for m, p in MODULES.items()
           if m not in TEMP_ALLOWED and made.search(p.read_text("utf-8"))]
    assert not bad, bad
    judged = [m for m, p in MODULES.items() if m != "impactcli.spill"
              and re.search(r"disk_usage\(|MIN_FREE_BYTES\s*=", p.read_text("utf-8"))]
    assert not judged, judged


def test_no_test_imports_another_test_module() -> None:
    """What tests share lives in helper modules (tests/helpers.py, tests/message_logs.py,
    tests/stream_invariants.py, tests/fakes.py, ...), never in another test file."""
    pattern = re.compile(r"^\s*(from\s+(\.|tests\.)test_\w+\s+import|import\s+tests\.test_)",
                         re.M)
    bad = [f.name for f in sorted((ROOT / "tests").glob("*.py"))
           if pattern.search(f.read_text("utf-8"))]
    assert not bad, bad


#: Test files whose subject is the whole tool, not one module: what each holds.
ACROSS = {
    "test_acceptance.py": "the sample logs against the acceptance criteria",
    "test_golden.py": "every verb's outputs against the recorded goldens",
    "test_readme.py": "the README's commands and the docs' citations",
    "test_layout.py": "the package's structure",
    "test_roundtrip_property.py": "every file the tool writes, read back",
    "test_newcomer.py": "a new user's first commands, across verbs",
    "test_limits_stated.py": "every answer stating its own limits, across stages",
    "test_incident_criteria.py": "tests/incident_criteria.py, the incident benchmark's checks",
}


def test_every_test_file_is_named_after_what_it_tests() -> None:
    """tests/test_<name>.py: <name> starts with a module's or subpackage's name of
    impactcli (the verbs are cli's modules), or the file is one of ACROSS."""
    names = {p.stem for p in PKG.rglob("*.py")} | {p.name for p in PKG.rglob("*")
                                                     if p.is_dir()}
    bad = [t.name for t in sorted((ROOT / "tests").glob("test_*.py"))
           if t.name not in ACROSS
           and not any(t.stem[5:] == n or t.stem[5:].startswith(n + "_") for n in names)]
    assert not bad, f"test files not named after a module of impactcli: {bad}"


def test_no_module_over_700_lines() -> None:
    long = {m: n for m, p in MODULES.items()
            if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, long


def test_no_two_modules_share_a_file_name() -> None:
    seen: dict[str, list[str]] = defaultdict(list)
    for m, p in MODULES.items():
        if p.name not in ("__init__.py", "__main__.py"):
            seen[p.name].append(m)
    assert not {k: v for k, v in seen.items() if len(v) > 1}


def test_no_test_only_code_in_the_package() -> None:
    bad = [m for m, p in MODULES.items()
           if re.search(r"^\s*(from|import) tests\b", p.read_text(), re.M)]
    assert not bad


def test_no_issue_numbers_in_code_docs_or_tests() -> None:
    """The repo explains itself: a reader has no issue tracker, so nothing says "issue 21"."""
    cites = re.compile(r"\bissues? #?\d|\(#\d+\)", re.I)
    texts = [*PKG.rglob("*.py"), *(ROOT / "docs").glob("*.md"), ROOT / "README.md",
             *(ROOT / "tests").rglob("*.py")]
    bad = [f"{f.relative_to(ROOT)}:{n}" for f in texts if f.name != "test_layout.py"
           for n, line in enumerate(f.read_text("utf-8").splitlines(), 1)
           if cites.search(line)]
    assert not bad, bad


#: ``docs/x.md`` (or ``schemas/x.json``, ``sample_logs/...``) cited in code or docs.
CITED = re.compile(r"(?<![\w/.-])((?:docs|schemas|sample_logs|tests)/[\w./-]*\w)")


def test_every_file_cited_is_in_the_repo() -> None:
    texts = [*PKG.rglob("*.py"), *(ROOT / "docs").glob("*.md"), ROOT / "README.md",
             *(ROOT / "schemas").glob("*.json")]
    missing, n_cited = [], 0
    for f in texts:
        text = f.read_text()
        assert "../shared" not in text, f"{f.relative_to(ROOT)} cites ../shared"
        for m in CITED.finditer(text):
            cited = m.group(1).rstrip(".")
            if "*" in cited or "<" in cited:
                continue
            n_cited += 1
            if not (ROOT / cited).exists() and not any(ROOT.glob(cited + "*")):
                missing.append(f"{f.relative_to(ROOT)}: {cited}")
    assert n_cited > 50 and not missing, "\n".join(missing)


#: ``impactcli.pkg.module.name`` cited in code, docs and schemas.
DOTTED = re.compile(r"(?<![\w.])impactcli(?:\.\w+)+")


def _resolves(dotted: str) -> bool | None:
    """A dotted name is a module of the package, or a name in one (defined or imported);
    None when it does not start with a module of the package (a metadata key, a host)."""
    parts = dotted.split(".")
    for k in range(len(parts), 1, -1):
        base = ROOT.joinpath(*parts[:k])
        mod = base / "__init__.py" if base.is_dir() else base.with_suffix(".py")
        if mod.exists():
            rest = parts[k:]
            return not rest or re.search(rf"\b{re.escape(rest[0])}\b", mod.read_text()) is not None
    return None


def test_every_module_cited_exists() -> None:
    texts = [*PKG.rglob("*.py"), *(ROOT / "docs").glob("*.md"), ROOT / "README.md",
             ROOT / "sample_logs" / "README.md", *(ROOT / "schemas").glob("*.json")]
    missing, n_cited = [], 0
    for f in texts:
        for m in DOTTED.finditer(f.read_text()):
            found = _resolves(m.group(0).rstrip("."))
            n_cited += found is not None
            if found is False:
                missing.append(f"{f.relative_to(ROOT)}: {m.group(0)}")
    assert n_cited > 50 and not missing, "\n".join(sorted(set(missing)))
