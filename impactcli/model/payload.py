"""Payloads at the flange (docs/models.md, "Payloads"; docs/method.md §2, "Payloads"): a
load as a shift of the base parameters, a load per calibration log, a load weighed on a
stretch of motion.

A payload is a rigid body fixed to the last link. Its inertial parameters π enter the rigid
model (eq. 7) linearly and, in the base parameters of the kinematic kinds, as a shift of
the arm's own: the torque of the arm carrying π is Y(q, q', q'') (θ + B π), exactly,
because a body's columns of the full rigid regressor are combinations of the base columns.

* ``planar`` — π = (``m``, ``mx``, ``my``, ``J``): the mass [kg], its first moments about
  the last joint in the last link's frame [kg·m] and its inertia about the last joint's
  axis [kg·m²]. The regrouping of the base parameters gives B: a mass m on the last link
  adds m l_k² to ZZR_k and m l_k to MXR_k of every earlier link k, ``mx`` to MXR_n, ``my``
  to MYR_n and ``J`` to ZZR_n.
* ``urdf`` — π = the last body's ten inertial parameters (Pinocchio's order: ``m``,
  ``mx``, ``my``, ``mz``, then the inertia at the joint frame). B is the least-squares map
  of those full columns onto the base columns over random states (:func:`basis`; exact to
  rounding, checked).
* ``decoupled``, ``coupled`` — no kinematics: a load at the flange is not a shift of their
  parameters that the motion could tell from the arm's own; logs with different loads are
  not told apart (:data:`NO_KINEMATICS`).

Only differences of load are seen by the motion: the arm's own last link and a payload
carried in every log are one body. So the calibration fits θ and one π per log but the
first (:func:`augment`), and then states every log's load relative to the lightest, whose
load the model's θ holds (:func:`rereference`). A load on a short stretch — a log's start,
a step mid-log — is weighed through gravity (:func:`weigh`): its mass and first moments,
its inertia that of a point mass.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import structures

#: The payload a log starts with is estimated on its first this many seconds [s]: the
#: warm-up's least length (``[warmup] min_s``), in which detection is off.
START_S = 3.0

#: Parameters of a planar payload and their units.
PLANAR_PARAMS: tuple[str, ...] = ("m", "mx", "my", "J")
UNITS: dict[str, str] = {"m": "kg", "mx": "kg·m", "my": "kg·m", "mz": "kg·m", "J": "kg·m²",
                         "Ixx": "kg·m²", "Ixy": "kg·m²", "Iyy": "kg·m²", "Ixz": "kg·m²",
                         "Iyz": "kg·m²", "Izz": "kg·m²"}

NO_KINEMATICS = ("the model has no kinematics (a robot description with planar or URDF "
                 "kinematics gives them): a load at the flange cannot be told from the arm's "
                 "own parameters, so logs that carry different loads are not told apart")

#: A centre of mass farther than this from the last joint is not a load [m] (a URDF arm;
#: a planar arm's reach is the sum of its link lengths).
REACH_M = 2.0

#: The relative residual of the URDF basis's least squares beyond which it is refused.
BASIS_TOLERANCE = 1e-6


def basis(kind: str, joints: tuple[str, ...],
          structure: dict[str, Any]) -> tuple[np.ndarray, tuple[str, ...]] | None:
    """(P, m) map B of a payload's m parameters onto the P base parameters of ``kind``, and
    the parameters' names; None for a kind without kinematics. Only parameters whose
    shifts are independent are kept (a URDF's last body has inertia terms no motion of
    the chain tells apart), in their order."""
    if kind == "planar":
        b, names = _planar_basis(joints, structure), PLANAR_PARAMS
    elif kind == "urdf":
        b, names = _urdf_basis(joints, structure), structures.PIN_PARAMS
    else:
        return None
    norms = np.linalg.norm(b, axis=0)
    live = np.flatnonzero(norms > 0)
    from scipy.linalg import qr  # identification only

    _, r, piv = qr(b[:, live] / norms[live], mode="economic", pivoting=True)
    d = np.abs(np.diag(r))
    kept = np.sort(live[piv[:int(np.sum(d > 1e-8 * d[0]))]])
    if not kept.size or kept[0] != 0:  # no mass the motion could weigh
        return None
    return b[:, kept], tuple(names[i] for i in kept)


def _planar_basis(joints: tuple[str, ...], structure: dict[str, Any]) -> np.ndarray:
    names = structures.planar_names(joints, structure)
    at = {nm: i for i, nm in enumerate(names)}
    ll = [float(v) for v in structure["link_lengths"]]
    b = np.zeros((len(names), len(PLANAR_PARAMS)))
    for k, jn in enumerate(joints[:-1]):  # the mass, regrouped into every earlier link
        b[at[f"{jn}.ZZR"], 0] += ll[k] ** 2
        b[at[f"{jn}.MXR"], 0] += ll[k]
    last = joints[-1]
    b[at[f"{last}.MXR"], 1] = 1.0
    b[at[f"{last}.MYR"], 2] = 1.0
    b[at[f"{last}.ZZR"], 3] = 1.0
    return b


def _urdf_basis(joints: tuple[str, ...], structure: dict[str, Any],
                n_states: int = 40) -> np.ndarray:
    from ..errors import ModelError

    full = structures.urdf_full_names(joints, structure)
    first = full.index(f"{joints[-1]}.{structures.PIN_PARAMS[0]}")
    cols = list(range(first, first + len(structures.PIN_PARAMS)))
    base = list(structure["base_columns"])
    rng = np.random.default_rng(54321)  # fixed: the same basis on every run
    n = len(joints)
    q = rng.uniform(-np.pi, np.pi, (n_states, n))
    qd = rng.normal(0, 1.0, (n_states, n))
    qdd = rng.normal(0, 3.0, (n_states, n))
    y = structures.urdf_full_regressor(q, qd, qdd, joints, structure).reshape(n_states * n, -1)
    b, *_ = np.linalg.lstsq(y[:, base], y[:, cols], rcond=None)
    err = float(np.linalg.norm(y[:, base] @ b - y[:, cols])) / max(
        float(np.linalg.norm(y[:, cols])), 1e-300)
    if err > BASIS_TOLERANCE:
        raise ModelError(f"the last body's columns are not combinations of the base columns "
                         f"(relative residual {err:.2g}): no payload basis")
    b[np.abs(b) < 1e-9 * max(float(np.abs(b).max()), 1e-300)] = 0.0
    return np.asarray(b)


def augment(ys: Sequence[np.ndarray], b: np.ndarray) -> list[np.ndarray]:
    """Each log's (N_k, J, P) rows with one payload block per log but the first appended:
    (N_k, J, P + (L − 1) m), log k ≥ 1's own block Y_k B, the others zero."""
    nlog, m = len(ys), b.shape[1]
    out = []
    for k, y in enumerate(ys):
        extra = np.zeros((*y.shape[:2], (nlog - 1) * m))
        if k >= 1:
            extra[:, :, (k - 1) * m:k * m] = y @ b
        out.append(np.concatenate([y, extra], axis=-1))
    return out


def rereference(theta: np.ndarray, pis: np.ndarray, b: np.ndarray,
                mass: int = 0) -> tuple[np.ndarray, np.ndarray, int]:
    """The arm's θ and every log's π (L, m; the first log's 0) restated relative to the
    lightest log (least ``pis[:, mass]``): θ + B π_lightest and π − π_lightest; and that
    log's index."""
    light = int(np.argmin(pis[:, mass]))
    return theta + b @ pis[light], pis - pis[light], light


def shifted_theta(theta: np.ndarray, b: np.ndarray, pi: np.ndarray) -> np.ndarray:
    """θ + B π: the arm's parameters carrying the payload π beyond the model's own."""
    return np.asarray(theta + b @ np.asarray(pi, dtype=np.float64))


def estimate(y_pay: np.ndarray, r: np.ndarray, tol: float = 1e-3,
             correlated: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The payload π (m,) that explains the torque ``r`` (n, J) [N·m] the model leaves out,
    through ``y_pay`` (n, J, m) = Y B, and its standard errors (m,): least squares with
    each joint's rows scaled by its residual RMS, on the columns the rows determine (a
    column whose pivot is below ``tol`` of the largest stays 0, its error infinite). The
    errors take each joint's own noise — the variance of what the fit leaves on it (a
    sandwich: the rows are scaled by the torque, not by the noise) — and its rows as
    independent, or, ``correlated``, as independent only every :func:`correlated_rows` of
    what the fit leaves on it (rows of a residual through the replay's filters are
    correlated over tens of rows)."""
    n, nj, m = y_pay.shape
    pi, se = np.zeros(m), np.full(m, np.inf)
    if n == 0:
        return pi, se
    scale = np.sqrt(np.mean(r**2, axis=0))
    scale = np.maximum(scale, 1e-9 * max(float(scale.max()), 1e-12))
    a = (y_pay / scale[None, :, None]).reshape(n * nj, m)
    t = (r / scale[None, :]).reshape(n * nj)
    norms = np.linalg.norm(a, axis=0)
    live = np.flatnonzero(norms > 1e-12 * max(float(norms.max()), 1e-300))
    if live.size == 0:
        return pi, se
    from scipy.linalg import qr  # identification only

    an = a[:, live] / norms[live]
    _, rr, piv = qr(an, mode="economic", pivoting=True)
    d = np.abs(np.diag(rr))
    keep = live[np.sort(piv[:int(np.sum(d > tol * d[0]))])]
    ak = a[:, keep] / norms[keep]
    sol, *_ = np.linalg.lstsq(ak, t, rcond=None)
    res = (ak @ sol - t).reshape(n, nj)
    dof = max(ak.shape[0] - keep.size, 1)
    per = ak.reshape(n, nj, keep.size)
    meat = np.zeros((keep.size, keep.size))
    for j in range(nj):  # each joint's rows with its own noise (and correlation)
        s2 = float(res[:, j] @ res[:, j]) / dof * nj
        if correlated:
            s2 *= correlated_rows(res[:, j:j + 1])
        meat += s2 * (per[:, j].T @ per[:, j])
    bread = np.linalg.pinv(ak.T @ ak)
    cov = bread @ meat @ bread
    pi[keep] = sol / norms[keep]
    se[keep] = np.sqrt(np.maximum(np.diag(cov), 0.0)) / norms[keep]
    return pi, se


#: The payload's parameters a stretch of motion weighs: its mass and first moments (its
#: inertia is then that of a point mass at its centre of mass, :func:`weigh`).
STATIC: tuple[str, ...] = ("m", "mx", "my", "mz")
#: A load change is weighed when its mass is this many standard errors from zero.
WEIGH_SIGMAS = 3.0


@dataclass(frozen=True)
class Weighed:
    """A load weighed on a stretch of motion (:func:`weigh`): ``pi`` in the basis' order,
    its mass [kg] and standard error, whether the motion determines its mass and centre of
    mass (``supported``) and whether the mass differs from zero by :data:`WEIGH_SIGMAS`
    standard errors (``weighed``)."""

    pi: np.ndarray
    mass_kg: float
    mass_se_kg: float
    supported: bool
    weighed: bool


def weigh(y_pay: np.ndarray, r: np.ndarray, names: Sequence[str]) -> Weighed:
    """The load change that explains the torque ``r`` (n, J) [N·m] the model leaves out
    through ``y_pay`` (n, J, m) = Y B over a stretch of motion: its mass and first moments
    π_s, with its inertia that of a point mass at its centre of mass, I(π_s) (a short
    stretch weighs a load through gravity, it does not spin it) — for a mass change
    weighed; a change within :data:`WEIGH_SIGMAS` standard errors of zero keeps no inertia.

    The moments alone first (:func:`estimate`); when they weigh a mass, the least squares
    of Y_s π_s + Y_I I(π_s), which is not linear in π_s, each joint's rows scaled by its
    residual RMS as :func:`estimate` scales them (``scipy.optimize.least_squares``, from
    the moments alone, the mass kept on its side of zero); its standard errors those of
    the model linearised there. (Solving the moments and the inertia they imply in turn
    need not converge: on 2.8 s of a 3 kg load on the simulated soft arm it walked to a
    centre of mass 0.9 m out that explained 75 % of the torque.)"""
    st = [i for i, nm in enumerate(names) if nm in STATIC]
    inert = [i for i, nm in enumerate(names) if nm not in STATIC]
    ys, yi = y_pay[:, :, st], y_pay[:, :, inert]
    pi = np.zeros(len(names))
    pi_s, se_s = estimate(ys, r, correlated=True)
    supported = bool(np.all(np.isfinite(se_s)))
    m, se_m = float(pi_s[0]), float(se_s[0])
    weighed = supported and abs(m) > WEIGH_SIGMAS * se_m
    if weighed and inert:
        pi_s, se_s = _point_mass(ys, yi, r, pi_s, [names[i] for i in st],
                                 [names[i] for i in inert])
        m, se_m = float(pi_s[0]), float(se_s[0])
        weighed = bool(np.isfinite(se_m)) and abs(m) > WEIGH_SIGMAS * se_m
    pi[st] = pi_s
    if weighed:
        pi[inert] = _point_inertia(m, dict(zip([names[i] for i in st], pi_s, strict=True)),
                                   [names[i] for i in inert])
    return Weighed(pi, m, se_m, supported, weighed)


def _point_mass(ys: np.ndarray, yi: np.ndarray, r: np.ndarray, start: np.ndarray,
                st: list[str], inert: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`weigh`'s least squares of a point mass: the moments (S,) from ``start`` and
    their standard errors, ``ys`` (n, J, S) and ``yi`` (n, J, I) the rows of the moments and
    of the inertia, ``r`` (n, J) the torque to explain."""
    from scipy.optimize import least_squares  # identification only

    scale = np.sqrt(np.mean(r**2, axis=0))
    scale = np.maximum(scale, 1e-9 * max(float(scale.max()), 1e-12))

    def inertia_of(p: np.ndarray) -> np.ndarray:
        return _point_inertia(float(p[0]), dict(zip(st, p, strict=True)), inert)

    def jac_i(p: np.ndarray) -> np.ndarray:  # ∂I/∂π_s (I is smooth away from m = 0)
        cols = []
        for k in range(p.size):
            h = 1e-6 * max(abs(float(p[k])), abs(float(p[0])))
            e = np.zeros(p.size)
            e[k] = h
            cols.append((inertia_of(p + e) - inertia_of(p - e)) / (2.0 * h))
        return np.stack(cols, axis=1)

    def fun(p: np.ndarray) -> np.ndarray:
        return ((r - ys @ p - yi @ inertia_of(p)) / scale).ravel()

    def jac(p: np.ndarray) -> np.ndarray:
        return -((ys + yi @ jac_i(p)) / scale[None, :, None]).reshape(-1, p.size)

    m0 = float(start[0])
    lo, hi = np.full(start.size, -np.inf), np.full(start.size, np.inf)
    if m0 > 0:  # the mass stays on its side of zero, where I(π_s) is defined
        lo[0] = 0.1 * m0
    else:
        hi[0] = 0.1 * m0
    fit = least_squares(fun, start, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac")
    p = fit.x if fit.cost <= 0.5 * float(np.sum(fun(start) ** 2)) else start
    d = jac_i(p)
    _, se = estimate(ys + yi @ d, r - yi @ (inertia_of(p) - d @ p), correlated=True)
    return np.asarray(p, dtype=np.float64), se


#: A row of a stretch weighed is a transient no load explains when what the load leaves
#: on some joint lies beyond this many robust standard deviations of that joint's
#: (1.4826 × the median absolute deviation; :func:`weigh_trimmed`).
OUTLIER_SIGMAS = 5.0
#: :func:`weigh_trimmed` leaves out at most this share of the rows; a larger share the load
#: does not explain is no transient: all rows are kept and the load's tests judge them.
TRIM_SHARE = 0.25


def weigh_trimmed(y_pay: np.ndarray, r: np.ndarray,
                  names: Sequence[str]) -> tuple[Weighed, np.ndarray]:
    """:func:`weigh` on a stretch's rows without those no load explains — a transient the
    rigid model does not hold (a log's start: the arm settling under a load, the
    residual's filters) — and the (n,) rows kept. A row is left out when what the load
    leaves on some joint exceeds :data:`OUTLIER_SIGMAS` robust standard deviations of
    that joint's; the load is weighed again on the rows kept until they no longer change
    (three rounds at most). Least squares weigh every row by its square: on the simulated
    soft arm (``assist_like``; the 3 kg start of tests/test_payload.py's
    ``test_a_start_load_no_calibration_log_carried_and_its_release``), 0.2 s of a start
    transient, up to 53 N·m from the true load's torque, put the load's centre of mass
    0.23 m from the true one, explaining 93 %; without those rows, 0.13 m and 99.5 %. The
    rows left out must be a start's — all within the stretch's first :data:`TRIM_SHARE` —
    and the load on the rows kept a steady mass (weighed, drifting by at most
    :data:`STEADY`); else every row is kept and the load's tests judge them (a load picked
    1.2 s into a 3 s stretch is not trimmed into a start load)."""
    n = y_pay.shape[0]
    keep = np.ones(n, dtype=bool)
    w = every = weigh(y_pay, r, names)  # on every row: the answer when none is left out
    for _ in range(3):
        if not w.supported:
            break
        e = r - y_pay @ w.pi
        med = np.median(e[keep], axis=0)
        spread = 1.4826 * np.median(np.abs(e[keep] - med), axis=0)
        spread = np.maximum(spread, 1e-12 * max(float(spread.max()), 1e-300))
        new = np.max(np.abs(e - med) / spread, axis=1) <= OUTLIER_SIGMAS
        if new.sum() < (1.0 - TRIM_SHARE) * n:
            return every, np.ones(n, dtype=bool)
        if np.array_equal(new, keep):
            break
        keep = new
        w = weigh(y_pay[keep], r[keep], names)
    out = np.flatnonzero(~keep)
    if out.size and not (w.weighed and out[-1] < TRIM_SHARE * n and drift(
            y_pay[keep], r[keep], names, w, np.flatnonzero(keep)) <= STEADY):
        return every, np.ones(n, dtype=bool)
    return w, keep


def drift(y_pay: np.ndarray, r: np.ndarray, names: Sequence[str], weighed: Weighed,
          at: np.ndarray | None = None) -> float:
    """How much the weighed load changes across the stretch, as a share of its mass: the
    change of mass from the stretch's first to its last row when its mass and first moments
    may drift linearly in time (``Y B (π + (t − t̄)/T π̇)``, by :func:`estimate`), over
    ``weighed``'s mass. A payload keeps its mass as the arm moves; a clamp or a press that
    builds up, eases off or follows the arm does not (its "mass" drifts, docs/method.md
    §5c). ``inf`` when the stretch does not determine the drift. ``at``: the rows' times
    (any unit; default evenly spaced), for a stretch with rows left out."""
    st = [i for i, nm in enumerate(names) if nm in STATIC]
    inert = [i for i, nm in enumerate(names) if nm not in STATIC]
    n = y_pay.shape[0]
    if n < 2 or weighed.mass_kg == 0.0:
        return float("inf")
    x = np.arange(n, dtype=np.float64) if at is None else np.asarray(at, dtype=np.float64)
    span = float(x[-1] - x[0])
    if not span > 0:
        return float("inf")
    tau = (x - 0.5 * (x[0] + x[-1])) / span  # −½ … ½ over the stretch
    ys = y_pay[:, :, st]
    pi, se = estimate(np.concatenate([ys, ys * tau[:, None, None]], axis=2),
                      r - y_pay[:, :, inert] @ weighed.pi[inert])
    dm = float(pi[len(st)])  # the mass term's drift: first row to last
    if not np.isfinite(se[len(st)]):
        return float("inf")
    return abs(dm) / abs(weighed.mass_kg)


def _point_inertia(m: float, pi: dict[str, float], names: Sequence[str]) -> np.ndarray:
    """The inertia parameters ``names`` of a point mass m [kg] at the centre of mass its
    first moments in ``pi`` give, about the last joint's frame."""
    c = {ax: pi.get(f"m{ax}", 0.0) / m for ax in "xyz"}
    point = {"J": m * (c["x"] ** 2 + c["y"] ** 2),
             "Ixx": m * (c["y"] ** 2 + c["z"] ** 2), "Iyy": m * (c["x"] ** 2 + c["z"] ** 2),
             "Izz": m * (c["x"] ** 2 + c["y"] ** 2), "Ixy": -m * c["x"] * c["y"],
             "Ixz": -m * c["x"] * c["z"], "Iyz": -m * c["y"] * c["z"]}
    return np.array([point[nm] for nm in names])


#: A weighed load is steady when its mass changes by at most this share of itself across
#: the stretch (:func:`drift`): a payload keeps its mass; a clamp that builds up does not.
STEADY = 0.25
#: A load's inertia is visible when the torque by which a mass and a steady force differ
#: (:func:`inertia`) is at least this many times what the better of the two fits leaves.
INERTIA_VISIBLE = 2.0
#: Visible or not, a step is no mass when the steady force's fit leaves less than the
#: mass's by this many standard deviations of that difference: a steady press hides its
#: want of inertia in what both fits leave when the motion is slow, yet the data still side
#: against a mass. The deviation counts the rows as independent only as far as the noise is
#: (:func:`correlated_rows` of what the mass and the force fitted together leave: what
#: either alone leaves holds the other's want, a smooth misfit): a residual through the
#: replay's filters is correlated over tens of rows, and counted as white it made a genuine
#: 2 kg pick on the simulated heavy-geared arm side "against a mass" at 4–12 deviations in
#: the windows after it (its inertia 7–12 % of what the fits leave: not visible), which
#: dated the pick 12 s late and hid a push made meanwhile (docs/method.md §5c).
INERTIA_AGAINST_Z = 3.0
#: The autocorrelation of what a fit leaves is summed up to this share of its rows.
MAX_LAG_SHARE = 0.25


def correlated_rows(x: np.ndarray) -> float:
    """How many consecutive rows of ``x`` (n, J) count as one independent row: the
    integrated autocorrelation time 1 + 2 Σ ρ_k of each column, summed over the lags
    before its first ρ_k ≤ 0 (at most :data:`MAX_LAG_SHARE` of the rows), averaged over the
    columns (unweighted: the columns are scaled alike where it is used); 1 for white rows
    (≥ 1)."""
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    if n < 4:
        return 1.0
    c = x - x.mean(axis=0)
    size = 1 << int(2 * n - 1).bit_length()
    f = np.fft.rfft(c, size, axis=0)
    acov = np.fft.irfft(f * np.conj(f), size, axis=0)[:n]
    taus = []
    for j in range(x.shape[1]):
        if acov[0, j] <= 0.0:
            continue
        rho = acov[1:max(1, int(MAX_LAG_SHARE * n)) + 1, j] / acov[0, j]
        stop = np.flatnonzero(rho <= 0.0)
        taus.append(1.0 + 2.0 * float(np.sum(rho[:stop[0] if stop.size else rho.size])))
    return max(1.0, float(np.mean(taus))) if taus else 1.0


def inertia(y_pay: np.ndarray, y_still: np.ndarray, r: np.ndarray, names: Sequence[str],
            weighed: Weighed) -> tuple[str, float]:
    """Whether the stretch's torque ``r`` (n, J) [N·m] carries the inertia of the weighed
    mass — the one thing a mass has that a steady force along gravity at its centre of mass
    has not (the same torque at rest: ``y_still`` (n, J, m), the payload rows with
    q' = q'' = 0). Both are fitted (the force by :func:`weigh` on ``y_still``); the torque
    by which the mass's motion differs from what any steady force can mimic is the part of
    (``y_pay`` − ``y_still``) π the still rows cannot fit. Returns ``"shows"`` when that
    torque stands out (:data:`INERTIA_VISIBLE` × what the better fit leaves) and the mass
    fits the stretch better than the force, ``"contradicts"`` when it stands out and the
    force fits better — or, stand out or not, the force fits better by
    :data:`INERTIA_AGAINST_Z` standard deviations (a press, not a mass) — ``"unseen"`` when
    it does not
    stand out (the motion too slow to tell them apart); and the ratio (rs − rd) / e of
    how much better the mass fits to that torque (+1 a mass, −1 a steady force without
    noise, beyond ±1 with it; scaled per joint as :func:`estimate` scales)."""
    st = [i for i, nm in enumerate(names) if nm in STATIC]
    scale = np.sqrt(np.mean(r**2, axis=0))
    scale = np.maximum(scale, 1e-9 * max(float(scale.max()), 1e-12))[None, :]
    still = weigh(y_still, r, names)
    rd = float(np.sum(((r - y_pay @ weighed.pi) / scale) ** 2))
    rs = float(np.sum(((r - y_still @ still.pi) / scale) ** 2))
    d = (((y_pay - y_still) @ weighed.pi) / scale).reshape(-1)
    a = (y_still[:, :, st] / scale[:, :, None]).reshape(d.size, len(st))
    coef, *_ = np.linalg.lstsq(a, d, rcond=None)
    e = float(np.sum((d - a @ coef) ** 2))
    if e <= 0.0:
        return "unseen", 0.0
    gain = (rs - rd) / e
    # rs − rd under white noise σ² per row: ± 2 σ √e about its mean (+e a mass, −e a force),
    # the rows counted as independent only as far as the noise is: what the mass and the
    # force together leave (what either alone leaves holds the other's want, smooth)
    both = np.concatenate([y_pay, y_still[:, :, st]], axis=2) / scale[:, :, None]
    x, *_ = np.linalg.lstsq(both.reshape(d.size, -1), (r / scale).reshape(-1), rcond=None)
    tau = correlated_rows(r / scale - both @ x)
    noise = 2.0 * np.sqrt(min(rd, rs) / d.size * e * tau)
    if rs - rd < -INERTIA_AGAINST_Z * noise:  # the force fits clearly better, seen or not
        return "contradicts", gain
    if e < INERTIA_VISIBLE * min(rd, rs):
        return "unseen", gain
    return ("shows" if gain > 0 else "contradicts"), gain


#: A load explains a stretch's residual when its torque accounts for at least this share
#: of the residual's energy there (the load's confidence).
EXPLAINED = 0.9


def explained(left: np.ndarray, y_pay: np.ndarray, pi: np.ndarray) -> float:
    """The share (≤ 1; 0 for no residual) of the energy of ``left`` (n, J) [N·m], the torque
    the model leaves out, that the load π accounts for through ``y_pay`` (n, J, m)."""
    energy = float(np.sum(left**2))
    if energy <= 0:
        return 0.0
    return max(0.0, 1.0 - float(np.sum((left - y_pay @ pi) ** 2)) / energy)


def step_onset(left: np.ndarray, d: np.ndarray) -> int:
    """Where a load's step began in ``left`` (n, J) [N·m], the torque the model leaves out,
    given ``d`` (n, J) [N·m] the torque of the load changed (Y B π over the same rows): the
    row τ that minimises Σ_{t<τ} ‖left_t‖² + Σ_{t≥τ} ‖left_t − d_t‖², the least-squares
    change point of a step of known signature (the matched filter's, τ = n: no step in the
    rows). The rows before it need not be free of error: a model error uncorrelated with
    ``d``, or smaller than half of it along it, does not move τ."""
    gain = np.sum(d * d, axis=1) - 2.0 * np.sum(left * d, axis=1)  # after − before, per row
    tail = np.concatenate([np.cumsum(gain[::-1])[::-1], [0.0]])  # Σ_{t≥τ}, τ = 0..n
    return int(np.argmin(tail))


def reach_m(model: Any) -> float:
    """How far from the last joint a load's centre of mass may lie [m]: a planar arm's
    link lengths summed, else :data:`REACH_M`."""
    if model.kind == "planar":
        return float(np.sum(model.structure["link_lengths"]))
    return REACH_M


def within_reach(names: Sequence[str], pi: np.ndarray, reach: float) -> bool:
    """The centre of mass the first moments of the load π (``names``' order) give lies
    within ``reach`` [m] (a load without mass: yes)."""
    m = float(pi[0])
    if m == 0:
        return True
    c = np.array([pi[names.index(f"m{ax}")] if f"m{ax}" in names else 0.0
                  for ax in "xyz"]) / m
    return bool(np.linalg.norm(c) <= reach)


def start_rows(filter_info: dict[str, Any], n_rows: int, seconds: float = START_S) -> int:
    """How many of a log's first fitted rows (:class:`impactcli.model.rows.Rows`) lie in
    its first ``seconds``."""
    fs = float(filter_info["sample_rate_hz"])
    dec = filter_info.get("decimation") or {}
    k1, k2 = int(dec.get("filtered_signals", 1)), int(dec.get("fit_rows", 1))
    first = float(filter_info.get("edge_trim_samples", 0)) / fs
    step = k1 * k2 / fs
    return int(min(n_rows, max(0, np.ceil((seconds - first) / step))))


def with_log_payloads(model: Any, b: np.ndarray, names: Sequence[str],
                      paths: Sequence[str]) -> Any:
    """The model fitted with a payload per log but the first (``fit["extra"]``, in
    :func:`augment`'s order) restated relative to the lightest log (:func:`rereference`),
    the loads recorded in ``fit["payloads"]``."""
    import dataclasses

    fit = dict(model.fit)
    ex = fit.pop("extra")
    m = len(names)
    vals = np.zeros((len(paths), m))
    ses = np.zeros((len(paths), m))
    vals[1:] = np.asarray(ex["values"], dtype=np.float64).reshape(-1, m)
    ses[1:] = np.array([np.inf if v is None else v for v in ex["se"]]).reshape(-1, m)
    theta, rel, light = rereference(model.theta, vals, b)
    se = np.sqrt(ses**2 + ses[light] ** 2)
    se[light] = 0.0
    fit["payloads"] = {
        "parameters": list(names), "units": [UNITS[nm] for nm in names],
        "relative_to": paths[light],
        "logs": [{"log": p, "values": dict(zip(names, (float(v) for v in rel[k]), strict=True)),
                  "se": {nm: float(v) for nm, v in zip(names, se[k], strict=True)
                         if np.isfinite(v)}}  # a parameter the logs do not determine: none
                 for k, p in enumerate(paths)],
    }
    return dataclasses.replace(model, theta=theta, fit=fit)


def calibration_loads(model: Any, names: Sequence[str] | None = None,
                      ) -> tuple[tuple[str, np.ndarray], ...]:
    """Each calibration log's payload π as the model's fit found it (relative to the
    lightest), in ``names``' order (default: the fit's); none when it fitted no payload per
    log."""
    rec = (getattr(model, "fit", None) or {}).get("payloads")
    if not rec:
        return ()
    order = list(rec["parameters"] if names is None else names)
    return tuple((str(e["log"]), np.array([e["values"][nm] for nm in order],
                                          dtype=np.float64)) for e in rec["logs"])


def log_payload(model: Any, path: str) -> np.ndarray | None:
    """The payload π the model's fit found on the calibration log ``path`` (relative to the
    lightest), None when it fitted no payload per log or not on that log."""
    return next((pi for log, pi in calibration_loads(model) if log == path), None)


def known_load(known: Sequence[tuple[str, np.ndarray]], base: np.ndarray, step: np.ndarray,
               se_kg: float, y_pay: np.ndarray, left: np.ndarray, names: Sequence[str],
               ) -> tuple[str, np.ndarray] | None:
    """Of the ``known`` loads (log, π), the one the arm carries after the weighed ``step``
    from the load ``base`` (π, all relative to one model): its mass within
    :data:`WEIGH_SIGMAS` standard errors (``se_kg``) of the mass after the step, and the
    step to it accounting for at least :data:`EXPLAINED` of ``left`` (n, J), the torque
    the model leaves out, through ``y_pay`` (n, J, m) — of those, the one that explains
    most. None when none is. A load fitted on a whole calibration log is known far better
    than one weighed on a few seconds (its inertia above all): it is the one to carry."""
    m = list(names).index("m")
    after = base + step
    best: tuple[float, str, np.ndarray] | None = None
    for log, pi in known:
        if abs(float(pi[m] - after[m])) > WEIGH_SIGMAS * se_kg:
            continue
        share = explained(left, y_pay, pi - base)
        if share >= EXPLAINED and (best is None or share > best[0]):
            best = (share, log, pi)
    return None if best is None else (best[1], best[2])


def carrying(model: Any, pi: np.ndarray) -> Any:
    """The model of the arm carrying π beyond the model's own load (θ + B π); the model
    itself when π is zero."""
    import dataclasses

    pi = np.asarray(pi, dtype=np.float64)
    if not np.any(pi):
        return model
    bb = basis(model.kind, model.joint_names, model.structure)
    assert bb is not None, "a payload needs a kind with kinematics"
    return dataclasses.replace(model, theta=shifted_theta(model.theta, bb[0], pi))


def own_load(model: Any, path: str) -> Any:
    """The model carrying the load its fit found on the calibration log ``path``
    (:func:`log_payload`); the model itself where it found none."""
    pi = log_payload(model, path)
    return model if pi is None else carrying(model, pi)


def alike(e: dict[str, Any]) -> bool:
    """Whether a log's fitted load (an item of ``fit.payloads.logs``) is the reference's
    within three standard errors."""
    se = (e.get("se") or {}).get("m")
    return se is not None and abs(e["values"]["m"]) <= WEIGH_SIGMAS * float(se)


def loaded_logs(model: Any) -> list[dict[str, Any]]:
    """The items of ``fit.payloads.logs`` whose load differs from the reference's (the one
    the model's parameters carry): [] when the fit has one load."""
    rec = (model.fit or {}).get("payloads") if model is not None else None
    if not rec:
        return []
    return [e for e in rec["logs"] if e["log"] != rec["relative_to"] and not alike(e)]


def log_weights(ys: Sequence[np.ndarray], taus: Sequence[np.ndarray],
                options: Any) -> np.ndarray:
    """(ΣN_k, J) prior weights of the stacked rows of logs fitted with a payload each
    (:func:`augment`'s rows ``ys``, torques ``taus``): each log's rows weighted by its own
    noise, 1 / s_kj², s_kj the robust scale (1.4826 × MAD) of log k's residual on joint j
    under a first robust fit of them all, normalised to a mean of 1 per joint. A heavier
    load brings larger errors the rigid model does not hold (a flexible joint's
    deflection grows with it): weighted alike, its log would pull the arm's parameters
    from the lighter logs'."""
    from .fit import robust_lstsq

    y, t = np.concatenate(ys), np.concatenate(taus)
    th, _, _ = robust_lstsq(y, t, options, ridge=np.full(y.shape[2], 1e-10))
    parts = []
    for yk, tk in zip(ys, taus, strict=True):
        r = yk @ th - tk
        s = 1.4826 * np.median(np.abs(r - np.median(r, axis=0)), axis=0)
        floor = 1e-9 * max(float(np.sqrt(np.mean(tk**2))), 1e-12)
        parts.append(np.broadcast_to(1.0 / np.maximum(s, floor) ** 2, tk.shape))
    w = np.concatenate(parts)
    return np.asarray(w / np.mean(w, axis=0))
