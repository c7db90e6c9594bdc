"""The model file (``impactcli identify -o model.json``, ``--model``): read and written at
the edge, so that :mod:`impactcli.model` never opens a file (docs/formats.md, "Model and
detector config")."""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..errors import ModelError
from ..model import RigidModel


def write_model(model: RigidModel, path: str | os.PathLike[str]) -> None:
    """Write ``model`` as indented JSON, atomically."""
    from ..files import atomic_write_text

    atomic_write_text(path, json.dumps(model.to_dict(), indent=2, allow_nan=False) + "\n")


def read_model(path: str | os.PathLike[str]) -> RigidModel:
    """Read and validate a model file; ModelError naming the file on any problem."""
    p = Path(path)
    if not p.is_file():
        raise ModelError(f"{p}: model file not found")
    if p.suffix.lower() in (".toml", ".yaml", ".yml"):
        raise ModelError(f"{p}: a model is the JSON file `impactcli identify` writes; a "
                         f"{p.suffix} file is a detector config — give it with --config")
    try:
        d = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ModelError(f"{p}: model does not parse: {err}") from err
    if not isinstance(d, dict):
        raise ModelError(f"{p}: model must be a JSON object")
    return RigidModel.from_dict(d, str(p))
