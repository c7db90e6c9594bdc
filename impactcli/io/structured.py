"""Reading small structured files (JSON / YAML / TOML) into mappings, with clear errors."""

from __future__ import annotations

import json
import os
import tomllib
from pathlib import Path
from typing import Any

from ..errors import ImpactError


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
