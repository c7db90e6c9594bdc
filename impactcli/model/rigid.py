"""The rough rigid model (docs/method.md §2, eq. 7–8): tau_hat = Y(q, q', q'') theta, and its file.

The model file (``schemas/model.schema.json``) holds the structure, the parameter names and
values, the robot description used, the filter settings, the fit statistics, the sha256 of
the log it was identified on and the tool version. :func:`read_model` validates it.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import TOOL_NAME, __version__
from ..errors import ModelError
from . import structures

MODEL_SCHEMA_VERSION = "1.0"
_CHUNK = 4096


@dataclass(frozen=True, eq=False)
class RigidModel:
    """A rigid model linear in its parameters: tau_hat = Y(q, q', q'') theta (eq. 7).

    Attributes:
        kind: ``decoupled``, ``coupled``, ``planar`` or ``urdf``.
        joint_names: J joint names, in the order of the columns of q and tau.
        param_names: P parameter names (``<joint>.<name>``; base parameters).
        theta: (P,) parameter values [SI: kg·m², kg·m, N·m·s/rad, N·m].
        structure: structure settings (``coulomb_slope_rad_s``, ``offset``,
            ``motor_inertia``; coupled ``velocity_products``; planar ``link_lengths`` [m]
            and ``gravity`` [m/s²]; urdf ``urdf_xml``, ``urdf_sha256``, ``base_columns``).
        filter: the derivative/torque filter used in identification (method, cut-off Hz…).
        fit: fit statistics (per joint RMS errors, condition number, robust weights…).
        robot: the robot description used (its mapping form) or None.
        input_sha256: sha256 of the log it was identified on ("" if made in code).

    Equality is not defined on the fields (arrays); compare :attr:`sha256`.
    """

    kind: str
    joint_names: tuple[str, ...]
    param_names: tuple[str, ...]
    theta: np.ndarray
    structure: dict[str, Any] = field(default_factory=dict)
    filter: dict[str, Any] = field(default_factory=dict)
    fit: dict[str, Any] = field(default_factory=dict)
    robot: dict[str, Any] | None = None
    input_sha256: str = ""

    def __post_init__(self) -> None:
        if self.kind not in structures.KINDS:
            raise ModelError(f"unknown model kind {self.kind!r}")
        th = np.array(self.theta, dtype=np.float64).reshape(-1)
        if th.shape[0] != len(self.param_names):
            raise ModelError(
                f"model has {len(self.param_names)} parameter names but {th.shape[0]} values"
            )
        if not np.all(np.isfinite(th)):
            raise ModelError("model parameters are not all finite")
        th.setflags(write=False)
        object.__setattr__(self, "theta", th)
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "param_names", tuple(self.param_names))

    @property
    def n_joints(self) -> int:
        """Number of joints J."""
        return len(self.joint_names)

    def regressor(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """(N, J, P) regressor Y(q, q', q'') [q rad, q' rad/s, q'' rad/s²]."""
        return structures.regressor(self.kind, self.joint_names, self.structure, q, qd, qdd)

    def predict(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """(N, J) model torque tau_hat = Y theta [N·m] (eq. 7), computed in chunks."""
        q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=np.float64)) for x in (q, qd, qdd))
        out = np.empty(q.shape)
        for s in range(0, q.shape[0], _CHUNK):
            e = s + _CHUNK
            out[s:e] = structures.predict(self.kind, self.joint_names, self.structure,
                                          q[s:e], qd[s:e], qdd[s:e], self.theta)
        return out

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """(N, J, J) inertia matrix M(q) [kg·m²] from the regressor.

        M e_i = Y(q, 0, e_i) θ − Y(q, 0, 0) θ (friction and offset cancel at q' = 0).
        """
        q = np.atleast_2d(np.asarray(q, dtype=np.float64))
        n, nj = q.shape
        zero = np.zeros_like(q)
        base = self.predict(q, zero, zero)
        m = np.empty((n, nj, nj))
        for i in range(nj):
            e = np.zeros_like(q)
            e[:, i] = 1.0
            m[:, :, i] = self.predict(q, zero, e) - base
        return m

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping in the model file format (schemas/model.schema.json); a field
        without a value (None, a non-finite statistic) is left out, as TOML must."""
        from ..schema import omit_nulls

        d: dict[str, Any] = omit_nulls({
            "schema_version": MODEL_SCHEMA_VERSION,
            "tool": {"name": TOOL_NAME, "version": __version__},
            "kind": self.kind,
            "joint_names": list(self.joint_names),
            "parameters": [
                {"name": n, "value": float(v)}
                for n, v in zip(self.param_names, self.theta, strict=True)
            ],
            "structure": _jsonable(self.structure),
            "filter": _jsonable(self.filter),
            "fit": _jsonable(self.fit),
            "robot": _jsonable(self.robot),
            "input_sha256": self.input_sha256,
        })
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any], where: str = "model") -> RigidModel:
        """Build from the mapping of :meth:`to_dict` (validated against the schema)."""
        from ..schema import validate

        validate(d, "model", ModelError, where)
        params = d["parameters"]
        model = cls(
            kind=d["kind"], joint_names=tuple(d["joint_names"]),
            param_names=tuple(p["name"] for p in params),
            theta=np.array([p["value"] for p in params], dtype=np.float64),
            structure=dict(d.get("structure") or {}), filter=dict(d.get("filter") or {}),
            fit=dict(d.get("fit") or {}), robot=d.get("robot"),
            input_sha256=str(d.get("input_sha256", "")),
        )
        expected = structures.param_names(model.kind, model.joint_names, model.structure)
        if list(expected) != list(model.param_names):
            raise ModelError(
                f"{where}: parameter names do not match a {model.kind} model of joints "
                f"{list(model.joint_names)}"
            )
        return model

    def canonical_json(self) -> str:
        """Canonical JSON text (sorted keys, no whitespace) — what :attr:`sha256` hashes."""
        return json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"), allow_nan=False)

    @property
    def sha256(self) -> str:
        """Hex sha256 of the canonical JSON of the model."""
        return hashlib.sha256(self.canonical_json().encode("utf-8")).hexdigest()


def _jsonable(x: Any) -> Any:  # noqa: PLR0911 (one return per JSON type)
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.floating | float):
        v = float(x)
        return v if np.isfinite(v) else None
    if isinstance(x, np.bool_):
        return bool(x)
    return x
