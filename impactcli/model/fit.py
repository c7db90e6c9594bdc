"""Robust least squares of the identification (docs/method.md §2, "Identification", steps
3–4): Huber then Tukey bisquare reweighting with a robust scale per joint, the
coupled model's ridge on its cross terms chosen per joint by blocked cross-validation, and
the per-joint fit statistics. Pure maths on a stacked regressor (N, J, P).
"""

from __future__ import annotations

import itertools
from collections.abc import Collection, Sequence
from typing import Any

import numpy as np

from .identify_options import IdentifyOptions


def _robust_scale(res: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """(J,) 1.4826 × median absolute deviation per joint, floored."""
    med = np.median(res, axis=0)
    s = 1.4826 * np.median(np.abs(res - med), axis=0)
    return np.asarray(np.maximum(s, floor))


def robust_lstsq(
    y_reg: np.ndarray, tau: np.ndarray, options: IdentifyOptions,
    ridge: np.ndarray | None = None, separable: bool = False,
    prior: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Robust least squares tau ≈ Y theta over all samples and joints.

    Args:
        y_reg: (N, J, P) regressor; tau: (N, J) torques [N·m].
        ridge: optional (P,) penalties added to the diagonal of the column-normalised
            (unit-diagonal) weighted normal equations: ridge regression relative to each
            column's weighted energy (0: not penalised).
        separable: no column is non-zero in two joints' rows (decoupled, coupled): the
            normal equations are solved joint by joint (the same solution, less work).
        prior: optional (N, J) weights of the rows before the robust ones, e.g. each log's
            own noise level (:func:`impactcli.model.payload.log_weights`); the robust scale
            and weights judge the residuals scaled by their square roots.
    Returns:
        theta (P,), weights (N, J) in [0, 1], info (iterations, stage).
    """
    n, nj, p = y_reg.shape
    trms = np.sqrt(np.mean(tau**2, axis=0))
    floor = 1e-9 * np.maximum(trms, 1e-12)
    # per joint, only the columns that are non-zero in its rows (the decoupled model is
    # block diagonal; a chain's last joints see few columns): far less work per iteration
    blocks = []
    for j in range(nj):
        cols = np.flatnonzero(np.any(y_reg[:, j, :] != 0.0, axis=0))
        blocks.append((cols, np.ascontiguousarray(y_reg[:, j, cols])))

    def predict(th: np.ndarray) -> np.ndarray:
        return np.stack([aj @ th[cols] for cols, aj in blocks], axis=1)

    def wls(w: np.ndarray) -> np.ndarray:
        """Weighted normal equations (w: (N, J) row weights), diagonally scaled: accurate at
        the condition numbers the excitation check lets through (≤ 1/drop_tolerance)."""
        if separable:
            sol = np.zeros(p)
            for j, (cols, aj) in enumerate(blocks):
                awj = aj * w[:, j, None]
                sol[cols] = _scaled_solve(awj.T @ aj, awj.T @ tau[:, j],
                                          None if ridge is None else ridge[cols])
            return sol
        g = np.zeros((p, p))
        h = np.zeros(p)
        for j, (cols, aj) in enumerate(blocks):
            awj = aj * w[:, j, None]
            g[np.ix_(cols, cols)] += awj.T @ aj
            h[cols] += awj.T @ tau[:, j]
        return _scaled_solve(g, h, ridge)

    scale0 = np.maximum(trms, floor)
    pw = np.ones((n, nj)) if prior is None else np.asarray(prior, dtype=np.float64)
    sq = None if prior is None else np.sqrt(pw)
    theta = wls(pw / scale0**2 if prior is not None
                else np.broadcast_to(1.0 / scale0**2, (n, nj)))
    w = np.ones((n, nj))
    iters = {"huber": 0, "bisquare": 0}
    if options.robust == "none":
        return theta, w, {"iterations": iters}
    sigma = scale0
    for stage in ("huber", "bisquare"):
        if stage == "bisquare" and options.robust != "bisquare":
            break
        for _ in range(options.max_iter):
            res = tau - predict(theta)
            if sq is not None:
                res = res * sq
            if stage == "huber":
                sigma = _robust_scale(res, floor)
            u = np.abs(res) / sigma
            if stage == "huber":
                w = np.minimum(1.0, options.huber_k / np.maximum(u, 1e-300))
            else:
                c = options.bisquare_c
                w = np.where(u < c, (1.0 - (u / c) ** 2) ** 2, 0.0)
            new = wls(w / sigma**2 if prior is None else pw * w / sigma**2)
            iters[stage] += 1
            done = bool(np.linalg.norm(new - theta) <= 1e-7 * np.linalg.norm(theta))
            theta = new
            if done:
                break
    return theta, w, {"iterations": iters, "robust_scale_nm": sigma.tolist()}


def column_errors(a: np.ndarray, res: np.ndarray, nj: int, theta: np.ndarray,
                  keep: np.ndarray, p_own: int, names: Sequence[str]) -> dict[str, Any]:
    """The values and standard errors of the columns ``p_own`` onwards (``names``) of a fit
    (``a`` the (N·J, P) stacked regressor, ``res`` its (N, J) residual, ``keep`` the columns
    fitted): least squares with each joint's rows scaled by its residual RMS, the rows
    taken as independent (a column not kept: error None)."""
    rms = np.sqrt(np.mean(res**2, axis=0))
    rms = np.maximum(rms, 1e-9 * max(float(rms.max()), 1e-12))
    cols = np.flatnonzero(keep)
    ak = a[:, cols] / np.tile(rms, a.shape[0] // nj)[:, None]
    norms = np.maximum(np.linalg.norm(ak, axis=0), 1e-300)
    cov = np.linalg.pinv((ak / norms).T @ (ak / norms)) / np.outer(norms, norms)
    dof = max(a.shape[0] - cols.size, 1)
    s2 = float(np.sum((res / rms) ** 2)) / dof
    se: dict[int, float] = {int(c): float(np.sqrt(max(s2 * cov[i, i], 0.0)))
                            for i, c in enumerate(cols)}
    return {"names": list(names), "values": [float(v) for v in theta[p_own:]],
            "se": [se.get(p_own + i) for i in range(len(names))]}


def _scaled_solve(g: np.ndarray, h: np.ndarray, ridge: np.ndarray | None) -> np.ndarray:
    """Solve (g + ridge on the unit-diagonal scaling) x = h, diagonally scaled: accurate at
    the condition numbers the excitation check lets through (≤ 1/drop_tolerance)."""
    d = np.sqrt(np.diag(g))
    d[d == 0] = 1.0
    gs = g / d[:, None] / d[None, :]
    if ridge is not None:
        gs[np.diag_indices(gs.shape[0])] += ridge
    try:
        sol = np.linalg.solve(gs, h / d)
    except np.linalg.LinAlgError:
        sol, *_ = np.linalg.lstsq(gs, h / d, rcond=None)
    return np.asarray(sol) / d


def joint_stats(
    res: np.ndarray, tau: np.ndarray, joints: tuple[str, ...], still: Collection[str] = (),
) -> dict[str, Any]:
    """RMS error per joint, absolute and relative; a joint in ``still`` (standing still in
    that part) gets no relative errors (``still``: True) — they would only judge a constant."""
    out: dict[str, Any] = {}
    for j, name in enumerate(joints):
        rms = float(np.sqrt(np.mean(res[:, j] ** 2)))
        trms = float(np.sqrt(np.mean(tau[:, j] ** 2)))
        rng = float(np.ptp(tau[:, j]))
        st = name in still
        out[name] = {
            "rms_nm": rms,
            "torque_rms_nm": trms,
            "torque_range_nm": rng,
            "rms_rel_torque_rms": rms / trms if trms > 0 and not st else None,
            "rms_rel_range": rms / rng if rng > 0 and not st else None,
        }
        if st:
            out[name]["still"] = True
    return out


def _cv_ridge(
    a: np.ndarray, t: np.ndarray, w: np.ndarray, pen: np.ndarray,
    lambdas: Sequence[float], folds: int, gap: int, rule: str = "min",
) -> tuple[float, dict[str, float]]:
    """Ridge penalty of one joint's row by blocked cross-validation (see the module doc).

    Args:
        a: (n, p) the row's regressor columns; t: (n,) torque; w: (n,) row weights;
        pen: (p,) True for the penalised columns. lambdas: finite penalties to try.
        folds: number of contiguous stretches; gap: rows left out on each side of one.
    Returns:
        The penalty (``inf``: penalised columns off) and the left-out RMS error relative
        to the torque's weighted RMS at that penalty and with the cross terms off.
    """
    n, p = a.shape
    aw = a * w[:, None]
    g = aw.T @ a
    h = aw.T @ t
    d = np.sqrt(np.diag(g))
    d[d == 0] = 1.0
    g = g / d[:, None] / d[None, :]
    h = h / d
    an = a / d
    wt = float(np.sum(w * t**2)) or 1.0
    cuts = np.linspace(0, n, folds + 1).astype(int)
    parts = []
    for lo, hi in itertools.pairwise(cuts):
        if hi <= lo:
            continue
        z = slice(max(0, lo - gap), min(n, hi + gap))
        gz = (an[z] * w[z, None]).T @ an[z]
        hz = (an[z] * w[z, None]).T @ t[z]
        share = 1.0 - float(np.sum(w[z])) / max(float(np.sum(w)), 1e-300)
        parts.append((slice(lo, hi), g - gz, h - hz, share))
    own = ~pen

    def cv_error(lam: float) -> np.ndarray:
        err = []
        for f, gf, hf, share in parts:
            if np.isinf(lam):
                th = np.zeros(p)
                idx = np.flatnonzero(own)
                m = gf[np.ix_(idx, idx)] + 1e-10 * np.eye(idx.size)
                th[idx] = solve_normal(m, hf[idx])
            else:
                m = gf + np.diag(lam * share * pen + 1e-10)
                th = solve_normal(m, hf)
            r = an[f] @ th - t[f]
            err.append(float(np.sum(w[f] * r**2)))
        return np.array(err)

    trials = [*sorted(float(v) for v in lambdas), float("inf")]
    per_fold = np.array([cv_error(lam) for lam in trials])  # (trials, folds)
    errs = per_fold.sum(axis=1)
    k = int(np.argmin(errs))
    if rule == "1se":  # the strongest penalty within one standard error of the least error
        fw = np.array([max(float(np.sum(w[f])), 1e-300) for f, *_ in parts])
        mse = per_fold / fw
        se = float(np.std(mse[k], ddof=1) / np.sqrt(mse.shape[1])) if mse.shape[1] > 1 else 0.0
        k = int(np.flatnonzero(mse.mean(axis=1) <= mse[k].mean() + se).max())
    return trials[k], {"cv_rel_rms": float(np.sqrt(errs[k] / wt)),
                       "cv_rel_rms_decoupled": float(np.sqrt(errs[-1] / wt))}


def solve_normal(m: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve the normal equations m x = b; least squares where m is singular."""
    try:
        return np.asarray(np.linalg.solve(m, b))
    except np.linalg.LinAlgError:
        return np.asarray(np.linalg.lstsq(m, b, rcond=None)[0])


# ------------------------------------------------------------------ public


def fit_ridge(
    y_reg: np.ndarray, tau: np.ndarray, keep: np.ndarray, pen: np.ndarray,
    joints: tuple[str, ...], names: list[str], options: IdentifyOptions, cv_gap: int,
    fixed: Sequence[float] | None = None,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any], dict[str, Any], np.ndarray]:
    """Robust ridge fit of the coupled model, the penalty of each joint by blocked
    cross-validation (module doc, step 3), or ``fixed`` (J,) penalties (``inf``: cross terms
    off) chosen elsewhere — by held-back error across logs (:mod:`impactcli.model.selection`).
    Returns theta of the (new) kept columns, the robust weights, the robust info, the ridge
    record and the kept columns (a joint whose penalty is infinite loses its cross terms)."""
    n, nj, p = y_reg.shape
    cols = [np.flatnonzero(keep & np.any(y_reg[:, j, :] != 0.0, axis=0)) for j in range(nj)]
    trms = np.sqrt(np.mean(tau**2, axis=0))
    folds = int(min(options.ridge_folds, max(2, n // 20)))

    def choose(w: np.ndarray) -> tuple[list[float], list[dict[str, float]]]:
        lams: list[float] = []
        stats: list[dict[str, float]] = []
        for j in range(nj):
            c = cols[j]
            if not np.any(pen[c]):
                lams.append(float("inf"))
                stats.append({})
                continue
            lam, st = _cv_ridge(y_reg[:, j, c], tau[:, j], w[:, j], pen[c],
                                options.ridge_lambdas, folds, cv_gap, options.ridge_rule)
            lams.append(lam)
            stats.append(st)
        return lams, stats

    def run(lams: list[float]) -> tuple[np.ndarray, np.ndarray, dict[str, Any], np.ndarray]:
        use = keep.copy()
        ridge = np.zeros(p)
        for j in range(nj):
            c = cols[j][pen[cols[j]]]
            if np.isinf(lams[j]):
                use[c] = False
            else:
                ridge[c] = lams[j]
        th, w, info = robust_lstsq(y_reg[:, :, use], tau, options, ridge=ridge[use],
                                   separable=True)
        return th, w, info, use

    if fixed is not None:
        lams = [float(v) for v in fixed]
        th, w, info, use = run(lams)
        return th, w, info, {
            "penalised": "every term but a joint's own inertia, gcos, gsin, fv, fc, offset",
            "rule": "held-back error across logs or stretches of a log, one-standard-error "
                    "rule (the model's selection record); no lambda = infinite (cross terms "
                    "off)",
            "fits": 1,
            "joints": {nm: ({} if np.isinf(lams[j]) else {"lambda": lams[j]})
                       for j, nm in enumerate(joints)},
        }, use
    w0 = np.broadcast_to(1.0 / np.maximum(trms, 1e-300) ** 2, (n, nj))
    lams, stats = choose(np.asarray(w0))
    th, w, info, use = run(lams)
    rounds = 1
    if options.robust != "none":
        lams2, stats2 = choose(w)
        if lams2 != lams:
            lams, stats = lams2, stats2
            th, w, info, use = run(lams)
            rounds = 2
    record: dict[str, Any] = {
        "penalised": "every term but a joint's own inertia, gcos, gsin, fv, fc, offset",
        "rule": f"blocked cross-validation, {folds} contiguous stretches, margin "
                f"{cv_gap} row(s), "
                + ("the strongest penalty within one standard error of the least error"
                   if options.ridge_rule == "1se" else "the least error")
                + "; no lambda = infinite (cross terms off)",
        "fits": rounds,
        "joints": {
            nm: ({} if np.isinf(lams[j]) else {"lambda": lams[j]}) | stats[j]
            for j, nm in enumerate(joints)
        },
    }
    return th, w, info, record, use


#: inertia-like parameters checked for sign, per kind (urdf: the diagonal of M(q) instead)
