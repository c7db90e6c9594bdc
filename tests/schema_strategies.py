"""Hypothesis strategies that draw documents from impactcli's own JSON Schemas.

Covers the subset of JSON Schema (2020-12) that ``schemas/`` uses: ``type``, ``enum``,
``const``, ``properties`` / ``required`` / ``additionalProperties`` / ``propertyNames``,
``items`` / ``minItems`` / ``maxItems`` / ``uniqueItems``, numeric bounds, ``pattern``,
string lengths, ``oneOf`` / ``anyOf`` / ``allOf`` / ``not`` / ``if``, and ``$ref`` into
``$defs``. Every drawn document is checked against the whole schema, so a branch this
module draws too loosely is filtered rather than trusted.

The value space is deliberately wide: non-ASCII and punctuation in names and keys, empty
tables, floats from subnormal to 1e308, optional properties present or absent, nulls
where the schema allows them.
"""

from __future__ import annotations

import functools
import json
import string
from typing import Any

import jsonschema
from hypothesis import strategies as st

from impactcli.schema import load_schema

#: Characters names and keys are drawn from: ASCII letters and punctuation, blanks inside
#: a name, and non-ASCII letters of several scripts (no dot: a dot ends a joint name).
NAME_ALPHABET = (string.ascii_letters + string.digits + "_-+ /#[]()'\"\\=:,;"
                 + "éüßøÅÆΩλθжЖ关节ロボット😀")
#: Objects and arrays without a size limit in the schema get at most this many entries.
MAX_ENTRIES = 3

_FLOATS = st.floats(allow_nan=False, allow_infinity=False)
_TEXT = st.text(NAME_ALPHABET, max_size=12)


def _names(min_size: int = 1) -> st.SearchStrategy[str]:
    return st.text(NAME_ALPHABET.replace(".", ""), min_size=min_size, max_size=10).filter(
        lambda s: s.strip() == s and s != "")


def _number(node: dict[str, Any], integer: bool) -> st.SearchStrategy[Any]:
    lo = node.get("minimum", node.get("exclusiveMinimum"))
    hi = node.get("maximum", node.get("exclusiveMaximum"))
    if integer:
        lo_i = None if lo is None else int(lo) + (1 if "exclusiveMinimum" in node else 0)
        hi_i = None if hi is None else int(hi) - (1 if "exclusiveMaximum" in node else 0)
        # a 64-bit signed integer: what TOML, and every reader of it, holds
        return st.integers(lo_i if lo_i is not None else -(2**63),
                           hi_i if hi_i is not None else 2**63 - 1)
    floats = st.floats(min_value=lo, max_value=hi, allow_nan=False, allow_infinity=False,
                       exclude_min="exclusiveMinimum" in node,
                       exclude_max="exclusiveMaximum" in node)
    ints = st.integers(-(2**31) if lo is None else int(lo) + 1,
                       2**31 if hi is None else max(int(lo or 0) + 1, int(hi) - 1))
    return st.one_of(floats, ints.filter(lambda v: jsonschema.Draft202012Validator(
        node).is_valid(v)))


def _any_json(depth: int = 2) -> st.SearchStrategy[Any]:
    """Open-ended JSON values (``{"type": "object"}`` without properties): scalars, nested
    objects whose values may be null, lists of non-null values."""
    scalar = st.one_of(st.booleans(), _FLOATS, st.integers(-(2**63), 2**63 - 1), _TEXT)
    if depth == 0:
        return scalar
    inner = _any_json(depth - 1)
    return st.one_of(scalar, st.lists(inner, max_size=MAX_ENTRIES),
                     st.dictionaries(_names(), st.one_of(inner, st.none()),
                                     max_size=MAX_ENTRIES))


class _Drawer:
    def __init__(self, root: dict[str, Any]) -> None:
        self.root = root

    def resolve(self, node: dict[str, Any]) -> dict[str, Any]:
        ref = node.get("$ref")
        if isinstance(ref, str) and ref.startswith("#/$defs/"):
            base = self.root["$defs"][ref.split("/")[-1]]
            rest = {k: v for k, v in node.items() if k != "$ref"}
            return self.resolve({**base, **rest})
        return node

    def draw(self, node: Any, depth: int = 0) -> st.SearchStrategy[Any]:  # noqa: PLR0911
        if node is True or node == {}:
            return _any_json()
        node = self.resolve(node)
        if "const" in node:
            return st.just(node["const"])
        if "enum" in node:
            return st.sampled_from(node["enum"])
        for key in ("oneOf", "anyOf"):
            if key in node:
                base = {k: v for k, v in node.items() if k != key}
                return st.one_of([self.draw({**base, **self.resolve(b)}, depth)
                                  for b in node[key]])
        if "allOf" in node:
            merged = {k: v for k, v in node.items() if k != "allOf"}
            for part in node["allOf"]:
                merged = {**merged, **self.resolve(part)}
            return self.draw(merged, depth)
        t = node.get("type")
        if isinstance(t, list):
            return st.one_of([self.draw({**node, "type": x}, depth) for x in t])
        if t is None:
            t = "object" if "properties" in node or "required" in node else None
        if t is None:
            return _any_json()
        return self._typed(t, node, depth)

    def _typed(self, t: str, node: dict[str, Any], depth: int) -> st.SearchStrategy[Any]:  # noqa: PLR0911
        if t == "null":
            return st.none()
        if t == "boolean":
            return st.booleans()
        if t in ("number", "integer"):
            return _number(node, t == "integer")
        if t == "string":
            if "pattern" in node and node["pattern"] != "^[^.]+$":
                return st.from_regex(node["pattern"], fullmatch=True)
            lo, hi = node.get("minLength", 0), node.get("maxLength", 16)
            if node.get("pattern") == "^[^.]+$":
                return _names(max(lo, 1))
            return st.text(NAME_ALPHABET, min_size=lo, max_size=hi)
        if t == "array":
            items = node.get("items", True)
            lo = node.get("minItems", 0)
            hi = node.get("maxItems", max(lo, MAX_ENTRIES))
            return st.lists(self.draw(items, depth + 1), min_size=lo, max_size=hi,
                            unique_by=(lambda v: json.dumps(v, sort_keys=True))
                            if node.get("uniqueItems") else None)
        return self._object(node, depth)

    def _object(self, node: dict[str, Any], depth: int) -> st.SearchStrategy[Any]:
        props: dict[str, Any] = node.get("properties", {})
        required = set(node.get("required", []))
        extra = node.get("additionalProperties", True)
        if not props and extra is True:
            return st.dictionaries(_names(), _any_json(), max_size=MAX_ENTRIES)
        fixed = {k: self.draw(v, depth + 1) for k, v in props.items() if k in required}
        optional = {k: self.draw(v, depth + 1) for k, v in props.items() if k not in required}
        parts: list[st.SearchStrategy[dict[str, Any]]] = [st.fixed_dictionaries(
            fixed, optional=optional)]
        if isinstance(extra, dict):
            names = node.get("propertyNames", {})
            keys = (st.sampled_from(names["enum"]) if "enum" in names
                    else _names()).filter(lambda k: k not in props)
            parts.append(st.dictionaries(keys, self.draw(extra, depth + 1),
                                         max_size=MAX_ENTRIES))
        return st.tuples(*parts).map(lambda ds: {k: v for d in ds for k, v in d.items()})


@functools.cache
def _validator(name: str) -> jsonschema.Draft202012Validator:
    return jsonschema.Draft202012Validator(load_schema(name))


def from_schema(name: str, node: dict[str, Any] | None = None) -> st.SearchStrategy[Any]:
    """Documents valid against ``schemas/<name>.schema.json`` (or one of its sub-nodes,
    ``node``, validated against the sub-node with the root's ``$defs``). Built once per
    schema node: a composite strategy draws from it again and again, and hypothesis would
    otherwise analyse a fresh strategy at every draw."""
    return _from_schema(name, None if node is None else json.dumps(node, sort_keys=True))


@functools.cache
def _from_schema(name: str, node_json: str | None) -> st.SearchStrategy[Any]:
    root = load_schema(name)
    drawer = _Drawer(root)
    if node_json is None:
        return drawer.draw(root).filter(_validator(name).is_valid)
    node = json.loads(node_json)
    checker = jsonschema.Draft202012Validator({**node, "$defs": root.get("$defs", {})})
    return drawer.draw(node).filter(checker.is_valid)
