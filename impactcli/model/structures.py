"""Model structures linear in their parameters: tau = Y(q, q', q'') theta (docs/method.md §2,
eq. 7). What each kind assumes and how it measured: docs/models.md, "The kinds".

Every structure ends, per joint j, with friction columns (Fv x1' + Fs sign(x1')): ``fv``
(viscous, q'_j), ``fc`` (Coulomb through the smooth sign tanh(q'_j / v_s), v_s =
``coulomb_slope_rad_s``) and, optionally, ``offset`` (a constant torque).

* ``decoupled`` — per joint, no kinematics: ``inertia`` q''_j, ``gcos`` cos q_j, ``gsin``
  sin q_j + friction. Works on any robot.
* ``coupled`` — every joint's motion in every joint's torque, no kinematics: per joint row
  the decoupled terms + ``acc:k``, ``cos:k``, ``sin:k`` of every other joint k +
  ``cos:k+l``, ``sin:k+l`` of neighbouring joints (+ ``vel:k*l`` with
  ``velocity_products``) + friction: 5J + 1 parameters per joint. Block diagonal (each
  joint fitted on its own); the cross terms are ridge-regularised in identification.
* ``planar`` — a serial arm in a vertical plane (docs/formats.md, "Robot description"): the
  exact rigid-body model in base parameters, ``ZZR``, ``MXR``, ``MYR`` per link (masses
  regrouped), optional reflected motor inertia ``Ia`` for joints 2..n.
* ``urdf`` — any serial arm: Pinocchio's joint-torque regressor (10 inertial parameters
  per body) + optional ``Ia`` + friction, reduced to base parameters by pivoted QR on random
  states; the kept columns are stored in the model (``base_columns``).

Regressors are returned as (N, J, P) arrays: Y[k, j, :] @ theta = tau_j at sample k [N·m].
"""

from __future__ import annotations

import hashlib
from typing import Any

import numba as nb
import numpy as np

from ..errors import ModelError
from ..logs.urdf import pinocchio, reduced_model, urdf_joint_order

KINDS: tuple[str, ...] = ("decoupled", "coupled", "planar", "urdf")

PIN_PARAMS: tuple[str, ...] = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def friction_names(joint: str, structure: dict[str, Any]) -> list[str]:
    """Names of the friction (and offset) parameters of one joint."""
    names = [f"{joint}.fv", f"{joint}.fc"]
    if structure.get("offset", True):
        names.append(f"{joint}.offset")
    return names


def _friction_block(qd: np.ndarray, structure: dict[str, Any]) -> np.ndarray:
    """(N, J, F) friction columns of each joint (only on its own row)."""
    vs = float(structure["coulomb_slope_rad_s"])
    cols = [qd, np.tanh(qd / vs)]
    if structure.get("offset", True):
        cols.append(np.ones_like(qd))
    return np.stack(cols, axis=-1)


# ---------------------------------------------------------------- decoupled
def decoupled_names(joints: tuple[str, ...], structure: dict[str, Any]) -> list[str]:
    """Parameter names of the decoupled structure (per joint, in joint order)."""
    out: list[str] = []
    for j in joints:
        out += [f"{j}.inertia", f"{j}.gcos", f"{j}.gsin", *friction_names(j, structure)]
    return out


def decoupled_regressor(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, structure: dict[str, Any]
) -> np.ndarray:
    """(N, J, P) regressor of the decoupled structure (block diagonal over joints)."""
    n, nj = q.shape
    per = np.concatenate(
        [np.stack([qdd, np.cos(q), np.sin(q)], axis=-1), _friction_block(qd, structure)], axis=-1
    )  # (N, J, p)
    p = per.shape[-1]
    y = np.zeros((n, nj, nj * p))
    for j in range(nj):
        y[:, j, j * p:(j + 1) * p] = per[:, j, :]
    return y


def decoupled_predict(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                      structure: dict[str, Any], theta: np.ndarray) -> np.ndarray:
    """(N, J) ``rowdot`` of :func:`decoupled_regressor` with theta, the same bits, without
    forming the (N, J, J·p) block-diagonal regressor (J times the work, nearly all zeros:
    each row's sum over the zero columns adds only signed zeros, reproduced where the sum
    is zero)."""
    per = np.concatenate(
        [np.stack([qdd, np.cos(q), np.sin(q)], axis=-1), _friction_block(qd, structure)], axis=-1
    )  # (N, J, p): the regressor's nonzero entries
    return _block_dot(np.ascontiguousarray(per), np.ascontiguousarray(theta, dtype=np.float64))


@nb.njit(cache=True, nogil=True)
def _block_dot(per: np.ndarray, x: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """out[r, j] = sum_i per[r, j, i] x[j p + i], as :func:`_rowdot` sums the full row."""
    n, nj, p = per.shape
    out = np.empty((n, nj))
    for r in range(n):
        for j in range(nj):
            acc = 0.0  # the zeros before the block add +0 (round to nearest)
            for i in range(p):
                acc += per[r, j, i] * x[j * p + i]
            if acc == 0.0:  # then the zeros after the block may flip its sign
                for k in range((j + 1) * p, nj * p):
                    acc += 0.0 * x[k]
            out[r, j] = acc
    return out


# ---------------------------------------------------------------- coupled
def _pairs(nj: int) -> list[tuple[int, int]]:
    return [(k, m) for k in range(nj) for m in range(k, nj)]


def _coupled_layout(nj: int, structure: dict[str, Any]) -> np.ndarray:
    """(J, P_row) column indices into :func:`coupled_features` of each joint's row, in the
    order of :func:`coupled_names`."""
    # feature blocks: qdd (J) | cos q (J) | sin q (J) | q' (J) | tanh(q'/v_s) (J) | 1 |
    # cos(q_k + q_k+1) (J-1) | sin(q_k + q_k+1) (J-1) | q'_k q'_l, k <= l (optional)
    acc, cq, sq, vel, sgn, one = 0, nj, 2 * nj, 3 * nj, 4 * nj, 5 * nj
    cs, ss = 5 * nj + 1, 5 * nj + 1 + (nj - 1)
    vp = 5 * nj + 1 + 2 * (nj - 1)
    rows = []
    for j in range(nj):
        r = [acc + j, cq + j, sq + j]
        for k in range(nj):
            if k != j:
                r += [acc + k, cq + k, sq + k]
        for k in range(nj - 1):
            r += [cs + k, ss + k]
        if structure.get("velocity_products", False):
            r += [vp + i for i in range(len(_pairs(nj)))]
        r += [vel + j, sgn + j] + ([one] if structure.get("offset", True) else [])
        rows.append(r)
    return np.array(rows, dtype=np.intp)


def coupled_row_names(joints: tuple[str, ...], structure: dict[str, Any]) -> list[list[str]]:
    """Parameter names of each joint's row (the model's parameters, row after row)."""
    out: list[list[str]] = []
    nj = len(joints)
    for j, nm in enumerate(joints):
        r = [f"{nm}.inertia", f"{nm}.gcos", f"{nm}.gsin"]
        for k, other in enumerate(joints):
            if k != j:
                r += [f"{nm}.acc:{other}", f"{nm}.cos:{other}", f"{nm}.sin:{other}"]
        for k in range(nj - 1):
            pair = f"{joints[k]}+{joints[k + 1]}"
            r += [f"{nm}.cos:{pair}", f"{nm}.sin:{pair}"]
        if structure.get("velocity_products", False):
            r += [f"{nm}.vel:{joints[k]}*{joints[m]}" for k, m in _pairs(nj)]
        r += friction_names(nm, structure)
        out.append(r)
    return out


def coupled_names(joints: tuple[str, ...], structure: dict[str, Any]) -> list[str]:
    """Parameter names of the coupled structure (joint after joint)."""
    return [n for row in coupled_row_names(joints, structure) for n in row]


#: parameters of a coupled row that are not ridge-penalised (the decoupled model's)
COUPLED_OWN: tuple[str, ...] = ("inertia", "gcos", "gsin", "fv", "fc", "offset")


def coupled_penalised(joints: tuple[str, ...], structure: dict[str, Any]) -> np.ndarray:
    """(P,) True for the cross terms of the coupled structure (ridge-penalised)."""
    return np.array([n.split(".", 1)[1] not in COUPLED_OWN
                     for n in coupled_names(joints, structure)], dtype=bool)


def coupled_features(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, structure: dict[str, Any]
) -> np.ndarray:
    """(N, F) the functions of the motion that the coupled rows are made of (shared by all
    rows; :func:`coupled_assemble` lays them out). F = 7J − 1 (+ J(J+1)/2)."""
    vs = float(structure["coulomb_slope_rad_s"])
    n, nj = q.shape
    cols = [qdd, np.cos(q), np.sin(q), qd, np.tanh(qd / vs), np.ones((n, 1))]
    s = q[:, :-1] + q[:, 1:]
    cols += [np.cos(s), np.sin(s)]
    if structure.get("velocity_products", False):
        k, m = np.array(_pairs(nj)).T
        cols.append(qd[:, k] * qd[:, m])
    return np.concatenate(cols, axis=1)


def coupled_assemble(f: np.ndarray, nj: int, structure: dict[str, Any]) -> np.ndarray:
    """(N, J, J·P_row) block-diagonal regressor from :func:`coupled_features`."""
    lay = _coupled_layout(nj, structure)
    pr = lay.shape[1]
    y = np.zeros((f.shape[0], nj, nj * pr))
    for j in range(nj):
        y[:, j, j * pr:(j + 1) * pr] = f[:, lay[j]]
    return y


def coupled_regressor(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, structure: dict[str, Any]
) -> np.ndarray:
    """(N, J, P) regressor of the coupled structure (block diagonal over joints)."""
    return coupled_assemble(coupled_features(q, qd, qdd, structure), q.shape[1], structure)


def coupled_predict(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, structure: dict[str, Any],
    theta: np.ndarray,
) -> np.ndarray:
    """(N, J) Y theta of the coupled structure without forming the (N, J, P) regressor."""
    f = coupled_features(q, qd, qdd, structure)
    nj = q.shape[1]
    lay = _coupled_layout(nj, structure)
    th = np.asarray(theta, dtype=np.float64).reshape(nj, lay.shape[1])
    return np.stack([rowdot(f[:, lay[j]], th[j]) for j in range(nj)], axis=1)


# ---------------------------------------------------------------- planar
def planar_names(joints: tuple[str, ...], structure: dict[str, Any]) -> list[str]:
    """Parameter names of the planar structure (grouped per joint)."""
    out: list[str] = []
    for i, j in enumerate(joints):
        out += [f"{j}.ZZR", f"{j}.MXR", f"{j}.MYR"]
        if structure.get("motor_inertia", True) and i > 0:
            out.append(f"{j}.Ia")
        out += friction_names(j, structure)
    return out


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.asarray(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])


def planar_inertial_regressor(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, link_lengths: list[float], gravity: list[float]
) -> np.ndarray:
    """(N, n, 3n) rigid-body regressor of a planar serial arm in base parameters.

    Columns per link i: ZZR_i, MXR_i, MYR_i. With h_i = R(phi_i) [MX, MY] (first moment about
    joint i) and a_i the acceleration of joint i's origin, link i's contribution to the
    torque of joint k <= i is ZZ phi_i'' + h_i x (a_i - g) + (p_i - p_k) x h_i''.
    """
    n_s, n = q.shape
    ll = np.asarray(link_lengths, dtype=np.float64)
    g = np.asarray(gravity, dtype=np.float64)
    phi, phid, phidd = np.cumsum(q, 1), np.cumsum(qd, 1), np.cumsum(qdd, 1)
    u = np.stack([np.cos(phi), np.sin(phi)], axis=-1)  # (N, n, 2) along link
    ju = np.stack([-u[..., 1], u[..., 0]], axis=-1)  # across link
    p = np.zeros((n_s, n, 2))
    a = np.zeros((n_s, n, 2))
    for i in range(1, n):
        p[:, i] = p[:, i - 1] + ll[i - 1] * u[:, i - 1]
        a[:, i] = a[:, i - 1] + ll[i - 1] * (
            phidd[:, i - 1, None] * ju[:, i - 1] - phid[:, i - 1, None] ** 2 * u[:, i - 1]
        )
    y = np.zeros((n_s, n, 3 * n))
    for i in range(n):
        ag = a[:, i] - g
        w2 = phid[:, i, None] ** 2
        hdd_x = phidd[:, i, None] * ju[:, i] - w2 * u[:, i]
        hdd_y = -phidd[:, i, None] * u[:, i] - w2 * ju[:, i]
        mom_x = _cross(u[:, i], ag)
        mom_y = _cross(ju[:, i], ag)
        for k in range(i + 1):
            r = p[:, i] - p[:, k]
            y[:, k, 3 * i] = phidd[:, i]
            y[:, k, 3 * i + 1] = mom_x + _cross(r, hdd_x)
            y[:, k, 3 * i + 2] = mom_y + _cross(r, hdd_y)
    return y


def planar_regressor(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, structure: dict[str, Any]
) -> np.ndarray:
    """(N, J, P) regressor of the planar structure, columns in :func:`planar_names` order."""
    n_s, n = q.shape
    inert = planar_inertial_regressor(q, qd, qdd, structure["link_lengths"], structure["gravity"])
    fric = _friction_block(qd, structure)
    cols: list[np.ndarray] = []
    for i in range(n):
        cols.append(inert[:, :, 3 * i:3 * i + 3])
        if structure.get("motor_inertia", True) and i > 0:
            c = np.zeros((n_s, n, 1))
            c[:, i, 0] = qdd[:, i]
            cols.append(c)
        f = np.zeros((n_s, n, fric.shape[-1]))
        f[:, i, :] = fric[:, i, :]
        cols.append(f)
    return np.concatenate(cols, axis=-1)


# ---------------------------------------------------------------- urdf
def urdf_full_names(joints: tuple[str, ...], structure: dict[str, Any]) -> list[str]:
    """Names of all columns of the URDF structure before base reduction (every name is
    ``<log joint>.<parameter>``: a URDF joint renamed by ``urdf_joint_map`` goes by the
    log's name)."""
    ujoints = urdf_joint_order(joints, structure)
    model = reduced_model(structure["urdf_xml"], ujoints, structure.get("urdf_path", "URDF"))
    back = dict(zip(ujoints, joints, strict=True))
    names = [f"{back.get(nm, nm)}.{p}" for nm in list(model.names)[1:] for p in PIN_PARAMS]
    if structure.get("motor_inertia", True):
        names += [f"{j}.Ia" for j in joints]
    for j in joints:
        names += friction_names(j, structure)
    return names


def urdf_full_regressor(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
    joints: tuple[str, ...], structure: dict[str, Any],
) -> np.ndarray:
    """(N, J, P_full) Pinocchio joint-torque regressor + Ia + friction, rows in ``joints`` order."""
    pin = pinocchio()
    ujoints = urdf_joint_order(joints, structure)
    model = reduced_model(structure["urdf_xml"], ujoints, structure.get("urdf_path", "URDF"))
    data = model.createData()
    n_s, n = q.shape
    jids = [model.getJointId(j) for j in ujoints]
    iq = [model.joints[i].idx_q for i in jids]
    nq = [model.joints[i].nq for i in jids]
    iv = np.array([model.joints[i].idx_v for i in jids])
    qv = np.tile(pin.neutral(model), (n_s, 1))
    for c, (a, m) in enumerate(zip(iq, nq, strict=True)):
        if m == 1:
            qv[:, a] = q[:, c]
        else:  # continuous joint: (cos, sin)
            qv[:, a], qv[:, a + 1] = np.cos(q[:, c]), np.sin(q[:, c])
    v = np.zeros((n_s, model.nv))
    acc = np.zeros((n_s, model.nv))
    v[:, iv], acc[:, iv] = qd, qdd
    pin_cols = 10 * (model.njoints - 1)
    y_in = np.empty((n_s, n, pin_cols))
    for k in range(n_s):
        yk = pin.computeJointTorqueRegressor(model, data, qv[k], v[k], acc[k])
        y_in[k] = yk[iv, :]
    cols = [y_in]
    if structure.get("motor_inertia", True):
        ia = np.zeros((n_s, n, n))
        ia[:, np.arange(n), np.arange(n)] = qdd
        cols.append(ia)
    fric = _friction_block(qd, structure)
    nf = fric.shape[-1]
    fr = np.zeros((n_s, n, n * nf))
    for j in range(n):
        fr[:, j, j * nf:(j + 1) * nf] = fric[:, j, :]
    cols.append(fr)
    return np.concatenate(cols, axis=-1)


def urdf_base_columns(
    joints: tuple[str, ...], structure: dict[str, Any], n_states: int = 40
) -> list[int]:
    """Indices of an independent set of full URDF columns (base parameters), by pivoted QR.

    Evaluated on ``n_states`` random states (fixed seed: deterministic), column-normalised;
    a column is kept when its pivot exceeds 1e-8 of the largest.
    """
    rng = np.random.default_rng(12345)
    n = len(joints)
    q = rng.uniform(-np.pi, np.pi, (n_states, n))
    qd = rng.normal(0, 1.0, (n_states, n))
    qdd = rng.normal(0, 3.0, (n_states, n))
    y = urdf_full_regressor(q, qd, qdd, joints, structure).reshape(n_states * n, -1)
    norms = np.linalg.norm(y, axis=0)
    nz = np.flatnonzero(norms > 1e-10 * norms.max())
    from scipy.linalg import qr  # identification only (0.3 s to import)

    _, r, piv = qr(y[:, nz] / norms[nz], mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    rank = int(np.sum(d > 1e-8 * d[0]))
    return sorted(int(nz[i]) for i in piv[:rank])


def urdf_structure(
    urdf_xml: str, joints: tuple[str, ...], base: dict[str, Any], where: str,
    joint_map: dict[str, str] | None = None, robot: str | None = None,
) -> dict[str, Any]:
    """The structure mapping of a URDF model (parses the URDF, finds its base columns).

    Args:
        joint_map: {log joint: URDF joint} for names that differ (stored, for these
            ``joints`` only, as ``urdf_joint_map``).
        robot: the shipped robot the URDF is (stored as ``urdf_robot``).
    """
    s = dict(base)
    s["urdf_xml"] = urdf_xml
    s["urdf_path"] = where
    s["urdf_sha256"] = hashlib.sha256(urdf_xml.encode("utf-8")).hexdigest()
    if robot:
        s["urdf_robot"] = robot
    renamed = {j: str(joint_map[j]) for j in joints if joint_map and joint_map.get(j, j) != j}
    if renamed:
        s["urdf_joint_map"] = renamed
    reduced_model(urdf_xml, urdf_joint_order(joints, s), where)
    s["base_columns"] = urdf_base_columns(joints, s)
    return s


# ---------------------------------------------------------------- dispatch
def param_names(kind: str, joints: tuple[str, ...], structure: dict[str, Any]) -> list[str]:
    """Parameter names of ``kind`` (base parameters for planar and urdf)."""
    if kind == "decoupled":
        return decoupled_names(joints, structure)
    if kind == "coupled":
        return coupled_names(joints, structure)
    if kind == "planar":
        return planar_names(joints, structure)
    if kind == "urdf":
        full = urdf_full_names(joints, structure)
        return [full[i] for i in structure["base_columns"]]
    raise ModelError(f"unknown model kind {kind!r} (choose from {', '.join(KINDS)})")


def regressor(
    kind: str, joints: tuple[str, ...], structure: dict[str, Any],
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
) -> np.ndarray:
    """(N, J, P) regressor Y(q, q', q'') of ``kind`` [q rad, q' rad/s, q'' rad/s²]."""
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=np.float64)) for x in (q, qd, qdd))
    if not q.shape == qd.shape == qdd.shape or q.shape[1] != len(joints):
        raise ModelError(
            f"q, qd, qdd must all be (N, {len(joints)}), got {q.shape}, {qd.shape}, {qdd.shape}"
        )
    if kind == "decoupled":
        return decoupled_regressor(q, qd, qdd, structure)
    if kind == "coupled":
        return coupled_regressor(q, qd, qdd, structure)
    if kind == "planar":
        return planar_regressor(q, qd, qdd, structure)
    if kind == "urdf":
        y = urdf_full_regressor(q, qd, qdd, joints, structure)
        return y[:, :, structure["base_columns"]]
    raise ModelError(f"unknown model kind {kind!r} (choose from {', '.join(KINDS)})")


def predict(
    kind: str, joints: tuple[str, ...], structure: dict[str, Any],
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, theta: np.ndarray,
) -> np.ndarray:
    """(N, J) model torque Y(q, q', q'') theta [N·m] (``coupled`` without forming Y)."""
    if kind in ("coupled", "decoupled"):
        q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=np.float64)) for x in (q, qd, qdd))
        if not q.shape == qd.shape == qdd.shape or q.shape[1] != len(joints):
            raise ModelError(
                f"q, qd, qdd must all be (N, {len(joints)}), got {q.shape}, {qd.shape}, "
                f"{qdd.shape}"
            )
        if kind == "decoupled":
            return decoupled_predict(q, qd, qdd, structure, theta)
        return coupled_predict(q, qd, qdd, structure, theta)
    y = regressor(kind, joints, structure, q, qd, qdd)
    n, nj, p = y.shape
    return rowdot(y.reshape(n * nj, p), np.asarray(theta, dtype=np.float64)).reshape(n, nj)


def rowdot(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(N,) the dot product of each row of ``a`` (N, P) with ``x`` (P,), summed in column
    order: each row's value is the same bits whatever other rows are in the call (a BLAS
    product's rounding may depend on a row's place in its blocks), so a chunked replay
    equals the whole-log one (:mod:`impactcli.model.causal`). Compiled (numba)."""
    return _rowdot(np.ascontiguousarray(a, dtype=np.float64),
                   np.ascontiguousarray(x, dtype=np.float64))


@nb.njit(cache=True, nogil=True)
def _rowdot(a: np.ndarray, x: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    n, p = a.shape
    out = np.zeros(n)
    for r in range(n):
        acc = 0.0
        for i in range(p):
            acc += a[r, i] * x[i]
        out[r] = acc
    return out

