"""alias: removed in M — the file helpers are :mod:`impactcli.files`; modules of other work
packages still import them from here."""

from .files import (  # alias: removed in M
    atomic_output,
    atomic_write_bytes,
    atomic_write_text,
    check_output_folder,
    prepare_output,
    sha256_file,
)
from .files import umask as _umask  # alias: removed in M (outputs/rerun.py)

__all__ = [
    "_umask",
    "atomic_output",
    "atomic_write_bytes",
    "atomic_write_text",
    "check_output_folder",
    "prepare_output",
    "sha256_file",
]
