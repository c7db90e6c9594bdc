"""Inputs and outputs named by URL (fsspec): ``file://``, ``s3://``, ``gs://``, ``memory://``...

- Reading: a URL other than ``file://`` is fetched to a private temporary file (same file
  name, so the format is still known by its suffix), read there, and deleted. The log's
  ``source.path`` is the URL and its ``sha256`` is that of the fetched bytes; error messages
  name the URL, never the temporary file. ``file://`` URLs are read in place (no fsspec),
  rosbag2 folders included; a remote folder (a rosbag2 folder on S3, ...) is refused with a
  LogFormatError: fetch it and give the local folder.
- Globs (``*``, ``?``, ``[...]``) in local paths and URLs are expanded in sorted order; a
  local folder (or ``file://`` URL) that is not a rosbag2 folder stands for the logs in it
  (:func:`impactcli.logs.paths.folder_logs`), as a glob would.
- Writing under a URL prefix (:func:`put_file_atomic`): the file is uploaded to
  ``<name>.part-<random>`` and then moved onto ``<name>``. On a local or POSIX-like file
  system the move is an atomic rename; on object stores (S3, GCS) a move is copy-then-delete:
  the final object appears whole (object stores never show a partial object), while a
  ``.part-…`` object may be left behind by a crash.
- Transient I/O errors (:func:`is_transient`: timeouts, connection errors, ``EIO``,
  ``EAGAIN``…; never a missing file or a permission error) are retried :data:`IO_RETRIES`
  times with exponential backoff (:data:`BACKOFF_S` × 2^k) by :func:`retry_transient`.

Remote protocols need ``fsspec`` (and its protocol package, e.g. ``s3fs``), imported only
when a remote URL is used.
"""

from __future__ import annotations

import contextlib
import errno
import glob as _glob
import os
import re
import shutil
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any, TypeVar
from urllib.parse import unquote, urlsplit

from ..errors import ImpactError, LogFormatError
from ..files import temporary_folder

__all__ = [
    "BACKOFF_S", "IO_RETRIES", "expand_inputs", "fetched", "is_transient", "is_url", "join_url",
    "load_by_url", "local_copy", "local_path", "put_file_atomic", "read_log_url",
    "refuse_remote_folder", "retry_transient", "url_name",
]

T = TypeVar("T")

#: Retries after a transient I/O error (so at most IO_RETRIES + 1 attempts).
IO_RETRIES = 3
#: First backoff delay [s]; doubled after every retry (0.5, 1, 2 s).
BACKOFF_S = 0.5
#: errno values worth retrying: the device, network or server may recover.
TRANSIENT_ERRNOS = frozenset(
    getattr(errno, n) for n in (
        "EIO", "EAGAIN", "EBUSY", "EINTR", "ETIMEDOUT", "ECONNRESET", "ECONNABORTED",
        "ECONNREFUSED", "EPIPE", "ENETDOWN", "ENETUNREACH", "EHOSTUNREACH", "ESTALE",
    ) if hasattr(errno, n)
)
FSSPEC_HINT = "pip install fsspec (and the protocol's package, e.g. s3fs for s3://)"
_SCHEME = re.compile(r"^([A-Za-z][A-Za-z0-9+.\-]+)://")
_GLOB_CHARS = re.compile(r"[*?\[]")


def is_url(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a URL (``scheme://...``; a Windows drive ``C:\\`` is not)."""
    return isinstance(path, str) and _SCHEME.match(path) is not None


def _scheme(url: str) -> str:
    m = _SCHEME.match(url)
    return m.group(1).lower() if m else ""


def local_path(path: str | os.PathLike[str]) -> Path | None:
    """The local file a path or ``file://`` URL names; None for a remote URL."""
    if not is_url(path):
        return Path(path)
    s = str(path)
    if _scheme(s) != "file":
        return None
    parts = urlsplit(s)
    if parts.netloc not in ("", "localhost"):
        return None
    return Path(unquote(parts.path))


def url_name(path: str) -> str:
    """The last component of a path or URL (``s3://b/x/run.csv.gz`` → ``run.csv.gz``)."""
    return str(path).rstrip("/").rsplit("/", 1)[-1]


def join_url(prefix: str, name: str) -> str:
    """``prefix/name`` for a folder path or a URL prefix."""
    if is_url(prefix):
        return prefix.rstrip("/") + "/" + name
    return str(Path(prefix) / name)


def _fs(url: str) -> tuple[Any, str]:
    try:
        from fsspec.core import url_to_fs
    except ImportError:
        raise ImpactError(f"{url}: reading URLs needs fsspec: {FSSPEC_HINT}") from None
    try:
        fs, p = url_to_fs(url)
    except (ImportError, ValueError) as err:  # unknown protocol, or its package missing
        raise ImpactError(f"{url}: {err}") from None
    return fs, p


def is_transient(err: BaseException) -> bool:
    """Whether an error (or any error it was raised from) is a transient I/O error."""
    seen: set[int] = set()
    e: BaseException | None = err
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, FileNotFoundError | PermissionError | IsADirectoryError
                      | NotADirectoryError):
            return False
        if isinstance(e, TimeoutError | ConnectionError):
            return True
        if isinstance(e, OSError) and e.errno in TRANSIENT_ERRNOS:
            return True
        e = e.__cause__ or e.__context__
    return False


def retry_transient(fn: Callable[[], T], *, retries: int | None = None,
                    backoff_s: float | None = None,
                    on_retry: Callable[[BaseException, int], None] | None = None) -> T:
    """Call ``fn()``; on a transient error retry up to ``retries`` times with backoff.

    Args:
        fn: the operation (no arguments).
        retries: default :data:`IO_RETRIES`.
        backoff_s: first delay [s], doubled each retry; default :data:`BACKOFF_S`.
        on_retry: called with (error, retry number ≥ 1) before each retry.
    Returns:
        ``fn()``'s result; the last error is raised when every attempt failed.
    """
    n = IO_RETRIES if retries is None else retries
    delay = BACKOFF_S if backoff_s is None else backoff_s
    for k in range(n + 1):
        try:
            return fn()
        except Exception as err:
            if k == n or not is_transient(err):
                raise
            if on_retry is not None:
                on_retry(err, k + 1)
            time.sleep(delay * 2**k)
    raise AssertionError("unreachable")  # pragma: no cover


@contextmanager
def local_copy(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A local file holding the bytes of ``path`` (a local path, ``file://`` or remote URL).

    Local files are yielded as they are; a remote URL is downloaded to a private temporary
    folder under its own file name, deleted on exit. OSErrors propagate (FileNotFoundError
    for a missing object) for the caller to name and classify.
    """
    lp = local_path(path)
    if lp is not None:
        yield lp
        return
    url = str(path)
    fs, p = _fs(url)
    with temporary_folder("impactcli-url-") as tmpdir:
        target = tmpdir / (url_name(p) or "download")
        fs.get_file(p, str(target))
        yield target


def _renamed(err: ImpactError, old: str, new: str) -> ImpactError:
    """The same error with the temporary file's name replaced by the URL."""
    msg = str(err).replace(old, new)
    if msg == str(err):
        return err
    try:
        out = type(err)(msg)
    except Exception:  # an error class with another constructor: keep it as it is
        return err
    out.__cause__ = err.__cause__
    return out


@contextmanager
def fetched(path: str | os.PathLike[str], what: str = "file") -> Iterator[Path]:
    """:func:`local_copy` whose errors name the URL as given: an ImpactError raised in the
    block is renamed (the temporary file's name → the URL), a missing object or another
    I/O error is a LogFormatError (for other I/O errors the OSError is raised from it, so
    :func:`is_transient` still sees it)."""
    given = str(path)
    try:
        with local_copy(given) as lp:
            try:
                yield lp
            except ImpactError as err:
                if str(lp) == given:
                    raise
                raise _renamed(err, str(lp), given) from err.__cause__
    except FileNotFoundError:
        raise LogFormatError(f"{given}: {what} not found") from None
    except PermissionError as err:
        raise LogFormatError(f"{given}: {what} not readable (permission denied)") from err
    except OSError as err:
        raise LogFormatError(f"{given}: cannot fetch: {err}") from err


def load_by_url(path: str | os.PathLike[str], loader: Callable[[Path], T],
                what: str = "file") -> T:
    """``loader(local file)`` for a path or URL; errors name the URL as given
    (:func:`fetched`).

    Used for robot descriptions, models, configs, labels and logs given as URLs.
    Raises:
        LogFormatError: the URL names no object.
    """
    with fetched(path, what) as lp:
        return loader(lp)


def refuse_remote_folder(url: str) -> None:
    """Raise LogFormatError when a remote URL names a folder (rosbag2 folders are read
    locally only)."""
    if local_path(url) is None:
        fs, p = _fs(url)
        try:
            is_dir = bool(fs.isdir(p))
        except Exception:  # a protocol that cannot tell: fetching says what is wrong
            is_dir = False
        if is_dir:
            raise LogFormatError(
                f"{url}: a folder (rosbag2) is read from a local path or file:// URL only; "
                "copy it to a local folder first"
            )


def read_log_url(url: str, reader: Callable[..., Any], **kwargs: Any) -> Any:
    """Read the log a URL names with ``reader`` (:func:`impactcli.logs.read_log`) on a local
    copy; the returned log's ``source.path`` is ``url`` and its sha256 the bytes' own.

    Raises:
        LogFormatError: a remote URL naming a folder (rosbag2 folders are read locally only).
    """
    refuse_remote_folder(url)
    log = load_by_url(url, lambda lp: reader(lp, **kwargs), "log file")
    return replace(log, source=replace(log.source, path=url))


def expand_inputs(patterns: Sequence[str]) -> list[str]:
    """Expand globs in local paths and URLs (sorted, duplicates removed, order kept), and
    local folders that are not rosbag2 folders into the logs in them
    (:func:`impactcli.logs.paths.folder_logs`, by name).

    A pattern that matches nothing, or a folder without a log, is kept as it is (its job
    then fails with a clear message); a name without glob characters is never checked here
    but for being such a folder.
    """
    out: list[str] = []
    for pat in patterns:
        s = str(pat)
        if not _GLOB_CHARS.search(s):
            out.extend(_folder_logs(s))
            continue
        if not is_url(s):
            hits = sorted(_glob.glob(s, recursive=True))
        elif (lp := local_path(s)) is not None:
            hits = ["file://" + h for h in sorted(_glob.glob(str(lp), recursive=True))]
        else:
            fs, p = _fs(s)
            hits = [fs.unstrip_protocol(h) for h in sorted(fs.glob(p)) if not fs.isdir(h)]
        out.extend([x for h in hits for x in _folder_logs(h)] or [s])
    return list(dict.fromkeys(out))


def _folder_logs(item: str) -> list[str]:
    """A local folder that is not a rosbag2 folder as the logs in it (``file://`` URLs
    for a ``file://`` folder); anything else, or a folder without a log, as it is."""
    from .paths import folder_logs, is_rosbag2_folder

    lp = local_path(item)
    if lp is None or not lp.is_dir() or is_rosbag2_folder(lp):
        return [item]
    try:
        logs = folder_logs(lp)
    except LogFormatError:
        return [item]
    if not logs:
        return [item]
    if is_url(item):
        return ["file://" + str(p) for p in logs]
    return [str(Path(item) / p.name) for p in logs]


def put_file_atomic(local: str | os.PathLike[str], target: str) -> None:
    """Copy a local file to ``target`` (a local path or URL) so that it appears whole.

    Local targets: temporary sibling + :func:`os.replace`. URLs: upload to
    ``<target>.part-<random>``, then move (object stores: copy then delete).
    """
    lp = local_path(target)
    if lp is not None:
        from ..files import atomic_output

        with open(local, "rb") as src, atomic_output(lp, "wb") as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
        return
    fs, p = _fs(target)
    part = f"{p}.part-{uuid.uuid4().hex[:12]}"
    parent = p.rsplit("/", 1)[0] if "/" in p else ""
    if parent:
        fs.makedirs(parent, exist_ok=True)
    try:
        fs.put_file(str(local), part)
        fs.mv(part, p)
    except BaseException:
        with contextlib.suppress(Exception):  # the upload may not have created it
            fs.rm(part)
        raise
