"""File-system helpers at the edge: hashing inputs, reading small structured files, and
writing outputs atomically.

No output file is ever visible half-written: content goes to a temporary file
in the same folder and is moved into place with :func:`os.replace`. A structured input
(JSON, YAML or TOML, by suffix) that is missing, unreadable or not a mapping is one
error line naming the file (:func:`load_mapping`).
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import re
import secrets
import shutil
import signal
import tempfile
import threading
import time
import tomllib
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

from .errors import ImpactError, Interrupted, OutputError, TempSpaceError


def sha256_file(path: str | os.PathLike[str], chunk: int = 1 << 20) -> str:
    """Return the hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


#: errno values that are the output side's fault whoever meets them (a full disk, a quota,
#: a read-only file system, a file too large): an output that cannot be written, exit 2.
OUTPUT_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG})
#: A ``.part`` file named without its writer's process id (made by an older version) is
#: stale once this old [s].
LEGACY_PART_AGE_S = 3600.0


def output_error(path: str | os.PathLike[str], err: BaseException) -> OutputError:
    """The one line of an output that cannot be written: its path and the reason."""
    why = err.strerror if isinstance(err, OSError) and err.strerror else str(err)
    return OutputError(f"cannot write {path}: {why or type(err).__name__}")


def part_path(target: str | os.PathLike[str]) -> Path:
    """A new empty temporary sibling of ``target`` (0666 less the umask):
    ``.<name>.<pid>-<random>.part``, the writer's process id in its name so that a later run
    can tell a killed writer's file (:func:`remove_stale_parts`)."""
    t = Path(target)
    for _ in range(100):
        tmp = t.with_name(f".{t.name}.{os.getpid()}-{secrets.token_hex(4)}.part")
        try:
            os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))
        except FileExistsError:
            continue
        except OSError as err:
            raise output_error(target, err) from err
        return tmp
    raise OutputError(f"cannot write {target}: no free temporary name beside it")


def discard(path: str | os.PathLike[str], folder: bool = False) -> None:
    """Remove a temporary file (or, with ``folder``, a folder and everything in it); nothing
    when it is gone. All of it even when a stop signal lands as it runs: the removal is then
    done again and the stop raised (:mod:`impactcli.run.stopping` ignores further signals
    once a stop is under way, so the second removal runs to its end)."""
    def remove() -> None:
        if folder:
            shutil.rmtree(path, ignore_errors=True)
        else:
            with suppress(FileNotFoundError):
                os.unlink(path)

    try:
        remove()
    except Interrupted:
        remove()
        raise


def sync_output(tmp: str | os.PathLike[str]) -> None:
    """Flush a finished temporary output to the disk (``fsync``): a full disk or a failed
    device that the writes did not report shows here. Every output goes through it
    (:func:`finish_output`): the seam where the tests inject a full disk."""
    fd = os.open(tmp, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def finish_output(tmp: str | os.PathLike[str], target: str | os.PathLike[str],
                  verify: Callable[[Path], None] | None = None) -> None:
    """Move a written temporary file onto ``target`` once it is on the disk
    (:func:`sync_output`) and ``verify(tmp)`` accepts it (raising names what is wrong);
    on any failure the temporary file is removed, ``target`` is untouched and the error is
    :func:`output_error`'s one line naming ``target``."""
    try:
        sync_output(tmp)
        if verify is not None:
            verify(Path(tmp))
        os.replace(tmp, target)
    except BaseException as err:
        discard(tmp)
        if isinstance(err, OSError | ValueError):
            raise output_error(target, err) from err
        raise


def check_size(expected: int) -> Callable[[Path], None]:
    """A :func:`finish_output` check: the file holds the ``expected`` bytes written."""
    def verify(tmp: Path) -> None:
        size = tmp.stat().st_size
        if size != expected:
            raise ValueError(f"{size} bytes on disk of {expected} written (truncated)")
    return verify


@contextmanager
def atomic_output(path: str | os.PathLike[str], mode: str = "wb",
                  verify: Callable[[Path], None] | None = None) -> Iterator[IO]:  # type: ignore[type-arg]
    """Open a temporary sibling of ``path`` for writing; move it into place on success,
    once flushed to the disk and checked: its size is what was written, and ``verify``
    (if given) accepts it (:func:`finish_output`).

    On any exception the temporary file is removed and ``path`` is untouched; a write
    that fails for want of space or a read-only disk (:data:`OUTPUT_ERRNOS`) is an
    :class:`~impactcli.errors.OutputError` naming ``path`` (exit 2).
    """
    target = Path(path)
    prepare_output(target)
    tmp: Path | None = None
    try:
        with whole():  # a stop signal cannot fall between the file and its removal below
            tmp = part_path(target)
        encoding = None if "b" in mode else "utf-8"
        with open(tmp, mode, encoding=encoding) as f:
            yield f
            f.flush()
            written = f.tell() if "b" in mode else f.buffer.tell()  # type: ignore[attr-defined]
        size_ok = check_size(written)

        def checks(p: Path) -> None:
            size_ok(p)
            if verify is not None:
                verify(p)

        finish_output(tmp, target, checks)
    except BaseException as err:
        if tmp is not None:
            discard(tmp)
        if isinstance(err, OSError) and err.errno in OUTPUT_ERRNOS:
            raise output_error(path, err) from err
        raise


def remove_stale_parts(folder: str | os.PathLike[str]) -> list[Path]:
    """Remove the ``.part`` files a killed run left in ``folder`` (not recursive): those
    whose writer (the process id in the name, :func:`part_path`) is no longer running, and
    those without one older than :data:`LEGACY_PART_AGE_S`. Another run still writing the
    folder keeps its own. Returns the files removed."""
    d = Path(folder)
    if not d.is_dir():
        return []
    gone = []
    now = time.time()
    for p in d.glob(".*.part"):
        pid = _part_pid(p.name)
        try:
            stale = (not process_running(pid) if pid is not None
                     else now - p.stat().st_mtime > LEGACY_PART_AGE_S)
            if stale and p.is_file():
                p.unlink()
                gone.append(p)
        except OSError:  # gone meanwhile, or not ours to remove: left alone
            continue
    return gone


#: The temporary folders this tool makes in TMPDIR: ``impactcli-<what>-<pid>-<8 random>``
#: (:func:`temp_prefix`; ``tempfile.mkdtemp``'s 8 characters). ``<what>`` holds a hyphen
#: (``report-q``) only in names with a process id: older versions made none such, and
#: ``impactcli-release-notes-20240101`` is no folder of ours.
_TEMP_NAME = re.compile(r"impactcli-(?:[a-z]+-(?:(\d+)-)?|[a-z]+(?:-[a-z]+)+-(\d+)-)"
                        r"[a-z0-9_]{8}")


def temp_prefix(prefix: str) -> str:
    """A temporary folder's name prefix (``impactcli-<what>-``) with this process's id, by
    which a later run tells a killed run's folder (:func:`remove_stale_temp`)."""
    return f"{prefix}{os.getpid()}-" if prefix.startswith("impactcli-") else prefix


def remove_stale_temp(folder: str | os.PathLike[str] | None = None) -> tuple[int, int]:
    """Remove the temporary folders (:data:`_TEMP_NAME`) in ``folder`` (TMPDIR) whose process
    no longer runs — what a run killed with ``kill -9`` (or a power cut) left — and those
    without one (older versions) older than :data:`LEGACY_PART_AGE_S`; return how many and
    their bytes. A running process's (another run on this machine) are kept; one that cannot
    be removed is left alone."""
    d = Path(folder if folder is not None else tempfile.gettempdir())
    count = size = 0
    try:
        names = [p for p in d.iterdir() if p.name.startswith("impactcli-")]
    except OSError:
        return 0, 0
    now = time.time()
    for p in names:
        m = _TEMP_NAME.fullmatch(p.name)
        pid = None if m is None else (m[1] or m[2])
        try:
            if m is None or p.is_symlink() or not p.is_dir() or (
                    process_running(int(pid)) if pid is not None
                    else now - p.stat().st_mtime <= LEGACY_PART_AGE_S):
                continue
        except OSError:  # gone meanwhile
            continue
        held = 0
        for root, _, files in os.walk(p):
            for f in files:
                with suppress(OSError):
                    held += os.lstat(os.path.join(root, f)).st_size
        shutil.rmtree(p, ignore_errors=True)
        if not p.exists():
            count, size = count + 1, size + held
    return count, size


def _part_pid(name: str) -> int | None:
    """The writer's process id in a ``.part`` file's name (:func:`part_path`), or None."""
    stem = name[: -len(".part")]
    tail = stem.rsplit(".", 1)[-1]
    pid, dash, rand = tail.partition("-")
    return int(pid) if dash and pid.isdigit() and len(rand) == 8 else None


def process_running(pid: int) -> bool:
    """Whether process ``pid`` runs on this machine (a zombie counts as ended)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            return f.read().rsplit(")", 1)[-1].split()[0] != "Z"
    except OSError:  # no /proc (not Linux): the signal test is all there is
        return True


def check_output_folder(path: str | os.PathLike[str]) -> None:
    """OutputError unless ``path`` is, or could be created as, a folder (nothing is made)."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputError(f"cannot write into {path}: it exists and is not a folder")
    q = p
    while not q.exists() and q != q.parent:
        q = q.parent
    if q.exists() and not q.is_dir():
        raise OutputError(f"cannot write into {path}: {q} is a file, not a folder")
    if q.exists() and not os.access(q, os.W_OK):
        raise OutputError(f"cannot write into {path}: no permission to write in {q}")


def prepare_output(path: str | os.PathLike[str]) -> None:
    """Create ``path``'s folder if needed; OutputError (one line, exit 2) when ``path``
    cannot be an output file there (its folder is a file, ``path`` is a folder, no
    permission). Call it for every output before writing the first, so a bad second
    output leaves nothing half done."""
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputError(f"cannot write {path}: a part of its folder path is a file, "
                          "not a folder") from None
    except OSError as err:
        raise OutputError(f"cannot write {path}: {err.strerror or err}") from err
    if target.is_dir():
        raise OutputError(f"cannot write {path}: it is a folder")
    if not os.access(target.parent, os.W_OK):
        raise OutputError(f"cannot write {path}: no permission to write in {target.parent}")


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically; a ``.json`` file must parse back."""
    verify = check_json if Path(path).suffix.lower() == ".json" else None
    with atomic_output(path, "w", verify=verify) as f:
        f.write(text)


def check_json(tmp: Path) -> None:
    """A :func:`finish_output` check: the file parses as JSON."""
    try:
        json.loads(tmp.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ValueError(f"it does not parse back: {err}") from err


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_output(path, "wb") as f:
        f.write(data)


def load_mapping(
    path: str | os.PathLike[str], error: type[ImpactError], what: str,
) -> dict[str, Any]:
    """Load a JSON, YAML or TOML file (by suffix) that must hold a mapping.

    Raises ``error`` (an ImpactError subclass) with one line naming the file on any problem.
    """
    p = Path(path)
    if not p.is_file():
        if not p.exists() and any(c in str(p) for c in "*?["):
            raise error(f"{p}: the pattern matches no file")
        raise error(f"{p}: {what} file not found")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise error(f"{p}: cannot read {what}: {err}") from err
    suffix = p.suffix.lower()
    try:
        if suffix in (".yaml", ".yml"):
            import yaml

            data = yaml.safe_load(text)
            if data is None:  # an empty (or comment-only) YAML document
                data = {}
        elif suffix == ".toml":
            data = tomllib.loads(text)
        else:
            data = json.loads(text)
    except Exception as err:  # parser errors of three libraries, all reported the same way
        msg = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise error(f"{p}: {what} does not parse: {msg}") from err
    if not isinstance(data, dict):
        raise error(f"{p}: {what} must be a mapping at top level, got {type(data).__name__}")
    return data


def temp_space_error(err: OSError) -> Exception:
    """The one-line error of a temporary file that cannot be written (a full or unwritable
    ``TMPDIR``): :class:`~impactcli.errors.TempSpaceError` naming the folder."""
    return TempSpaceError(
        f"temporary folder {tempfile.gettempdir()}: {err.strerror or err} while writing the "
        "replay's temporary files (a long log needs up to about 1 kB per sample for 7 joints "
        "there); set TMPDIR to a folder with room")


@contextmanager
def temp_space() -> Iterator[None]:
    """Around writes into ``TMPDIR`` (a spill, its flush or close): an OSError becomes
    :func:`temp_space_error`'s one line instead of a traceback."""
    try:
        yield
    except OSError as err:
        raise temp_space_error(err) from err


#: A stop signal held by :func:`whole`: ``[depth of the blocks open, the signal held or 0]``
#: (the main thread's only: signal handlers run there).
_whole = [0, 0]


@contextmanager
def whole() -> Iterator[None]:
    """Run the block whole: a stop signal that arrives in it is held and raised as
    :class:`~impactcli.errors.Interrupted` when the block ends — SIGINT and SIGTERM while
    :func:`impactcli.run.stopping.stop_on_signals` (or a pool worker's handler) stands;
    under Python's default handlers a Ctrl-C raises at once, as ever. For file operations a
    stop must not cut in half: a temporary file or folder made and its removal registered.
    (A removal is made whole by :func:`discard`.) In the main thread only (elsewhere the
    block runs as it is: signal handlers run in the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _whole[0] += 1
    try:
        yield
    finally:
        _whole[0] -= 1
        signum, _whole[1] = (_whole[1], 0) if _whole[0] == 0 else (0, _whole[1])
        if signum:
            raise Interrupted(signum, signal.Signals(signum).name)


def hold_stop(signum: int) -> bool:
    """Called by a stop signal's handler: True when a :func:`whole` block runs (the stop is
    held until it ends; the handler must not raise), else False."""
    if _whole[0] == 0:
        return False
    _whole[1] = _whole[1] or signum
    return True


@contextmanager
def temporary_folder(prefix: str, folder: str | os.PathLike[str] | None = None
                     ) -> Iterator[Path]:
    """A new temporary folder (``tempfile.mkdtemp(prefix=prefix, dir=folder)``) for the
    block, removed with everything in it when the block ends; made :func:`whole` and
    removed by :func:`discard`, so a stop signal cannot leave it behind."""
    path: Path | None = None
    try:
        with whole():
            path = Path(tempfile.mkdtemp(prefix=temp_prefix(prefix), dir=folder))
        yield path
    finally:
        if path is not None:
            discard(path, folder=True)
