"""Fit sanity of an identified model (docs/method.md §2, "Fit sanity"): negative
inertia-like or friction parameters whose terms matter, joints predicted worse than zero
torque on the held-back part, joints standing still there — each an ImpactWarning and a
line of ``fit["sanity"]``.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from ..errors import ImpactWarning
from . import structures
from .identify_options import IdentifyOptions

INERTIA_LIKE: dict[str, tuple[str, ...]] = {
    "decoupled": ("inertia",), "coupled": ("inertia",), "planar": ("ZZR", "Ia"), "urdf": (),
}
_UNITS = {"inertia": "kg·m²", "ZZR": "kg·m²", "Ia": "kg·m²", "fv": "N·m·s/rad", "fc": "N·m"}


def _mass_diagonal(
    kind: str, joints: tuple[str, ...], structure: dict[str, Any], theta: np.ndarray,
    poses: np.ndarray,
) -> np.ndarray:
    """(k, J) diagonal of M(q) at ``poses``: M e_i = Y(q, 0, e_i) θ − Y(q, 0, 0) θ."""
    zero = np.zeros_like(poses)
    base = structures.predict(kind, joints, structure, poses, zero, zero, theta)
    out = np.empty(poses.shape)
    for i in range(poses.shape[1]):
        e = np.zeros_like(poses)
        e[:, i] = 1.0
        out[:, i] = (structures.predict(kind, joints, structure, poses, zero, e, theta)
                     - base)[:, i]
    return out


def fit_sanity(
    kind: str, joints: tuple[str, ...], names: list[str], theta: np.ndarray,
    y_reg: np.ndarray, tau: np.ndarray, fit: dict[str, Any], still: list[str],
    hold_still: list[str], hold_still_fraction: np.ndarray | None, poses: np.ndarray | None,
    acc_rms: np.ndarray | None, structure: dict[str, Any], options: IdentifyOptions,
    where: str,
) -> list[str]:
    """Fit sanity (module doc, step 5): warn, one line per joint, and return the lines."""
    msgs: list[str] = []
    trms = np.sqrt(np.mean(tau**2, axis=0))
    # a negative term is reported when it is larger than what the fit leaves unexplained
    # (the robust residual scale) and than sanity_share of the torque: else its sign is
    # not determined by the log (a decoupled model of a coupled arm trades friction for
    # the coupling it lacks)
    res = np.einsum("njp,p->nj", y_reg, theta) - tau
    per_joint = fit["robust"].get("robust_scale_nm")
    scale = ([per_joint[j] for j in joints] if per_joint
             else np.sqrt(np.mean(res**2, axis=0)))
    floor = np.maximum(options.sanity_share * trms, np.asarray(scale, dtype=np.float64))
    bad: dict[str, dict[str, list[str]]] = {j: {"inertia": [], "friction": []} for j in joints}
    index = {nm: i for i, nm in enumerate(names)}
    for i, nm in enumerate(names):
        jn, term = nm.split(".", 1)
        if term not in INERTIA_LIKE.get(kind, ()) or theta[i] >= 0 or jn not in bad:
            continue
        j = joints.index(jn)
        size = abs(theta[i]) * float(np.sqrt(np.mean(y_reg[:, j, i] ** 2)))
        if size >= floor[j]:
            bad[jn]["inertia"].append(f"{nm} = {theta[i]:.3g} {_UNITS[term]}")
    # friction: fv and fc are judged together (on a log of near-constant speeds they trade
    # against each other): negative when the friction torque fv q' + fc tanh(q'/v_s) on
    # the log's motion pushes the joint along its motion on average (feeds energy)
    for j, jn in enumerate(joints):
        iv, ic = index.get(f"{jn}.fv"), index.get(f"{jn}.fc")
        if iv is None or ic is None or (theta[iv] >= 0 and theta[ic] >= 0):
            continue
        f = theta[iv] * y_reg[:, j, iv] + theta[ic] * y_reg[:, j, ic]
        power = float(np.mean(f * y_reg[:, j, iv]))
        if power < 0 and float(np.sqrt(np.mean(f**2))) >= floor[j]:
            bad[jn]["friction"].append(
                f"{jn}.fv = {theta[iv]:.3g} {_UNITS['fv']}, {jn}.fc = {theta[ic]:.3g} "
                f"{_UNITS['fc']} drive the joint instead of braking it")
    if kind == "urdf" and poses is not None and poses.size:
        diag = _mass_diagonal(kind, joints, structure, theta, poses)
        for j, jn in enumerate(joints):
            low = float(diag[:, j].min())
            acc = float(acc_rms[j]) if acc_rms is not None else 1.0
            if jn not in still and low < 0 and abs(low) * acc >= floor[j]:
                k = int(np.sum(diag[:, j] < 0))
                bad[jn]["inertia"].append(
                    f"M[{jn},{jn}] down to {low:.3g} kg·m², at {k} of {len(diag)} poses of the log")
    for jn, groups in bad.items():
        what = [g for g in ("inertia", "friction") if groups[g]]
        if what:
            detail = "; ".join(groups["inertia"] + groups["friction"])
            msgs.append(f"{where}: joint {jn}: negative {' and '.join(what)} ({detail}): a "
                        "torque (or current) of the wrong sign, or a model that does not "
                        "describe this joint")
    hold = fit["joints"].get("holdout")
    if hold:
        for jn in joints:
            h = hold[jn]
            if jn in hold_still or not h["torque_rms_nm"] > 0:
                continue
            if h["rms_nm"] >= h["torque_rms_nm"]:
                msgs.append(
                    f"{where}: joint {jn}: predicted worse than zero torque on the held-back "
                    f"part (RMS error {h['rms_nm']:.3g} N·m >= the torque's own RMS "
                    f"{h['torque_rms_nm']:.3g} N·m): do not rely on its model")
        new = [j for j in hold_still if j not in still]
        frac = dict(zip(joints, hold_still_fraction if hold_still_fraction is not None
                        else np.ones(len(joints)), strict=True))
        how = (f"|q'| < {options.still_speed_rad_s:g} rad/s, where friction is stiction: any "
               "torque within it")
        if new and len(new) + len(still) == len(joints):
            least = min(frac[j] for j in new)
            msgs.append(
                f"{where}: the arm stands still in the held-back part (every joint, in at "
                f"least {100 * least:.0f} % of it; {how}): relative errors there are not "
                "meaningful and are not given")
        else:
            msgs += [f"{where}: joint {j} stands still in {100 * frac[j]:.0f} % of the "
                     f"held-back part ({how}): its held-back relative error is not "
                     "meaningful and is not given" for j in new]
    for m in msgs:
        warnings.warn(m, ImpactWarning, stacklevel=4)
    return msgs
