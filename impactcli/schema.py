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


def restore_nulls(doc: Any, name: str) -> Any:
    """``doc`` with the required properties that may be null, and are absent, set to None.

    A TOML file has no null, so a document embedded in a TOML config (a model) loses its
    null values on the way; this puts them back before the document is validated. Only
    ``properties``/``additionalProperties`` of objects and ``$ref`` into ``$defs`` are
    followed (what impactcli's schemas use).
    """
    root = load_schema(name)

    def resolve(node: dict[str, Any]) -> dict[str, Any]:
        ref = node.get("$ref")
        if isinstance(ref, str) and ref.startswith("#/$defs/"):
            return resolve(root["$defs"][ref.split("/")[-1]])
        return node

    def nullable(node: dict[str, Any]) -> bool:
        node = resolve(node)
        t = node.get("type")
        return t == "null" or (isinstance(t, list) and "null" in t) or any(
            isinstance(o, dict) and nullable(o) for o in node.get("oneOf", []))

    def walk(x: Any, node: dict[str, Any]) -> Any:
        node = resolve(node)
        if not isinstance(x, dict):
            return x
        props = node.get("properties", {})
        extra = node.get("additionalProperties")
        out = {}
        for k, v in x.items():
            sub = props.get(k, extra if isinstance(extra, dict) else None)
            out[k] = walk(v, sub) if isinstance(sub, dict) else v
        for k in node.get("required", []):
            if k not in out and isinstance(props.get(k), dict) and nullable(props[k]):
                out[k] = None
        return out

    return walk(doc, root)
