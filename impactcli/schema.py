"""JSON Schemas shipped in ``schemas/``: locating them and validating documents against them."""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

from .errors import ImpactError


def schema_dir() -> Path:
    """The folder holding the JSON Schemas (inside the wheel, or the repo's ``schemas/``)."""
    here = Path(__file__).resolve().parent
    for cand in (here / "schemas", here.parent / "schemas"):
        if cand.is_dir():
            return cand
    raise FileNotFoundError("impactcli's schemas/ folder is missing from this installation")


@functools.cache
def load_schema(name: str) -> dict[str, Any]:
    """Load ``schemas/<name>.schema.json``."""
    data: dict[str, Any] = json.loads((schema_dir() / f"{name}.schema.json").read_text("utf-8"))
    return data


def validate(doc: Any, name: str, error: type[ImpactError], where: str) -> None:
    """Validate ``doc`` against schema ``name``; raise ``error`` with one line naming ``where``.

    The message names the JSON path of the first (best-matching) violation.
    """
    import jsonschema

    validator = jsonschema.Draft202012Validator(load_schema(name))
    best = jsonschema.exceptions.best_match(validator.iter_errors(doc))
    if best is not None:
        loc = "/".join(str(p) for p in best.absolute_path) or "(top level)"
        raise error(f"{where}: {loc}: {best.message}")
