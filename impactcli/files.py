"""File-system helpers at the edge: hashing inputs, reading small structured files, and
writing outputs atomically.

No output file is ever visible half-written: content goes to a temporary file
in the same folder and is moved into place with :func:`os.replace`. A structured input
(JSON, YAML or TOML, by suffix) that is missing, unreadable or not a mapping is one
error line naming the file (:func:`load_mapping`).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

import numpy as np

from .errors import ImpactError, OutputError, TempSpaceError


def sha256_file(path: str | os.PathLike[str], chunk: int = 1 << 20) -> str:
    """Return the hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


@contextmanager
def atomic_output(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO]:  # type: ignore[type-arg]
    """Open a temporary sibling of ``path`` for writing; move it into place on success.

    On any exception the temporary file is removed and ``path`` is untouched.
    """
    target = Path(path)
    prepare_output(target)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part",
                                   dir=target.parent)
    except OSError as err:
        raise OutputError(f"cannot write {path}: {err.strerror or err}") from err
    try:
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(fd, mode, encoding=encoding) as f:
            yield f
        os.chmod(tmp, 0o666 & ~umask())  # mkstemp makes 0600; outputs are ordinary files
        try:
            os.replace(tmp, target)
        except OSError as err:
            raise OutputError(f"cannot write {path}: {err.strerror or err}") from err
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


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


def umask() -> int:
    """The process's file-mode creation mask (read without changing it)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_output(path, "w") as f:
        f.write(text)


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


def write_spill(f: Any, v: np.ndarray) -> None:
    """Append ``v``'s bytes to a spill file (:func:`temp_space`)."""
    with temp_space():
        f.write(np.ascontiguousarray(v).tobytes())
