"""JSON Schemas shipped in ``schemas/``: locating them and validating documents against them."""

from __future__ import annotations

import functools
import json
import math
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


@functools.cache
def _validator(name: str) -> Any:
    """The validator of schema ``name``, made once (it resolves its references as it goes)."""
    import jsonschema

    return jsonschema.Draft202012Validator(load_schema(name))


def validate(doc: Any, name: str, error: type[ImpactError], where: str) -> None:
    """Validate ``doc`` against schema ``name``; raise ``error`` with one line naming ``where``.

    The message names the JSON path of the first (best-matching) violation. A NaN anywhere
    is refused first (JSON Schema's number bounds let it through, and no writer of the tool
    puts one in a file).
    """
    import jsonschema

    nan = _nan_path(doc)
    if nan is not None:
        raise error(f"{where}: {'/'.join(nan) or '(top level)'}: nan is not a number this "
                    "field can take")

    best = jsonschema.exceptions.best_match(_validator(name).iter_errors(doc))
    if best is not None:
        loc = "/".join(str(p) for p in best.absolute_path) or "(top level)"
        raise error(f"{where}: {loc}: {best.message}")


def _nan_path(doc: Any, path: tuple[str, ...] = ()) -> tuple[str, ...] | None:
    """The path of the first NaN in ``doc`` (mappings and lists, depth first), or None."""
    if isinstance(doc, float):
        return path if math.isnan(doc) else None
    if isinstance(doc, dict):
        items: Any = doc.items()
    elif isinstance(doc, list | tuple):
        items = enumerate(doc)
    else:
        return None
    for k, v in items:
        found = _nan_path(v, (*path, str(k)))
        if found is not None:
            return found
    return None


def omit_nulls(doc: Any) -> Any:
    """``doc`` with every null value of a mapping left out, recursively.

    The one form of every document the tool writes and reads back (configs, models, robot
    descriptions): TOML has no null, so a field without a value is absent in every format,
    and the schemas make such fields optional. Items of lists are kept as they are; no
    writer puts a null in a list (a per-joint value that can be missing is a table keyed
    by joint name).
    """
    if isinstance(doc, dict):
        return {k: omit_nulls(v) for k, v in doc.items() if v is not None}
    if isinstance(doc, list | tuple):
        return [omit_nulls(v) for v in doc]
    return doc
