"""The model kind and the coupled model's ridge penalty, chosen by held-back error
(docs/models.md, "Choosing the model"; docs/method.md §2, "Identification").

A model that fits the log it was identified on need not carry over to another motion: a
coupled model (186 parameters on a 6-joint arm) fitted on one free log can miss another
by more than the decoupled one. So the choice is judged on motion the fit did not see:

* **Held back across logs.** With two or more logs, each log in turn is held back and the
  others are fitted (leave-one-log-out: logs of other motion families are judged on a
  motion the fit never saw). With one log, each of :data:`STRETCHES` contiguous stretches
  of it in turn, with a margin of the zero-phase filter's memory on both sides (the rows
  nearby are as good as the stretch itself) — not only its tail.
* **Candidates, simplest first.** ``decoupled``, then ``coupled`` with its ridge penalty
  λ on the cross terms from the strongest to the weakest of ``ridge_lambdas`` (an infinite
  λ is the decoupled model exactly: all are judged on the same coupled rows, each joint on
  its own, as each is fitted).
* **The one-standard-error rule**, per joint: each candidate's held-back mean squared
  error relative to the held-back torque's mean square, averaged over the held-back
  parts; the simplest candidate whose mean is within one standard error (over the parts)
  of the least is chosen. The richer model must be clearly better held back, not just
  better on average. A joint that gets a finite λ keeps its cross terms; the model is
  ``coupled`` when any joint does, else ``decoupled``.
* **Named kinematics are used as named.** A robot description with planar or URDF
  kinematics names its model (``planar``, ``urdf``): it is used, with its held-back error
  measured alike and shown beside the others.

The rows are those identification fits (:mod:`impactcli.model.rows`). The fits of the
held-back comparison are weighted least squares with the robust weights of the decoupled
fit on all rows (what the robust fit leaves out — contacts, glitches — does not steer
any candidate); each candidate's held-back error is the plain RMS over the held-back rows.
The chosen model is then fitted on all logs (:func:`impactcli.model.identification.fit_rows`,
the coupled one with the chosen penalties) and carries the record in ``fit.selection``.
"""

from __future__ import annotations

import dataclasses
import itertools
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ImpactWarning
from ..types import RobotDescription, RobotLog
from . import payload as _payload
from . import structures
from .fit import robust_lstsq, solve_normal
from .identification import (
    IdentifyStream,
    default_kind,
    fit_rows,
    frozen_params,
    identify_many,
    many_sha256,
    prepare_rows,
)
from .identify_options import IdentifyOptions
from .rigid import RigidModel
from .rows import COUPLED_MIN_ROWS, Rows

_HUGE = 1e300

#: The least cut of the held-back RMS error [fraction] for which the coupled model's
#: cross terms are kept (besides the one-standard-error rule): a few per cent is what a
#: pose outside the free logs costs them (docs/models.md, "Choosing the model").
MIN_GAIN = 0.25

#: Contiguous stretches a single log is cut into for the held-back comparison.
STRETCHES = 5

PAYLOAD_RULE = (
    "each log held out in turn; the others fitted with one load and with a payload per log; "
    "the held-out log's payload estimated on its first seconds, the arm's parameters held; "
    "per-log payloads when, on a joint, their held-out mean squared error relative to the "
    "torque's is one standard error below one load's and their RMS error at least 25 % less")

RULE = ("one-standard-error rule: per joint, the simplest candidate (decoupled, then coupled "
        "from the strongest ridge penalty to the weakest) whose held-back mean squared error, "
        "relative to the held-back torque's and averaged over the held-back parts, is within "
        "one standard error of the least")


@dataclass(frozen=True)
class Fold:
    """One held-back part: its name, the rows held back, the rows fitted."""

    name: str
    test: np.ndarray
    train: np.ndarray


def folds_of(sizes: Sequence[int], names: Sequence[str], gap: int,
             stretches: int = STRETCHES) -> tuple[list[Fold], str]:
    """The held-back parts of stacked rows (``sizes``: rows per log, in order) and how they
    were made: one per log with two or more logs, else ``stretches`` contiguous stretches
    with ``gap`` rows left out of the fit on each side."""
    n = int(sum(sizes))
    idx = np.arange(n)
    if len(sizes) >= 2:
        edges = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        out = [Fold(f"log {nm}", idx[a:b], np.concatenate([idx[:a], idx[b:]]))
               for nm, a, b in zip(names, edges[:-1], edges[1:], strict=True) if b > a]
        return out, f"leave-one-log-out over {len(out)} logs"
    cuts = np.linspace(0, n, stretches + 1).astype(int)
    out = []
    for k, (a, b) in enumerate(itertools.pairwise(cuts)):
        if b <= a:
            continue
        lo, hi = max(0, a - gap), min(n, b + gap)
        out.append(Fold(f"stretch {k + 1} of {stretches} ({100 * a // n}–{100 * b // n} % of "
                        f"the log)", idx[a:b], np.concatenate([idx[:lo], idx[hi:]])))
    return out, (f"{len(out)} contiguous stretches of the log held back in turn "
                 f"(margin {gap} row(s))")


def row_counts(rows: Sequence[Rows]) -> list[int]:
    """Each log's fitted and held-back rows (:func:`stacked`'s sizes, without stacking)."""
    return [r.y_fit.shape[0] + (0 if r.y_hold is None else r.y_hold[0].shape[0])
            for r in rows]


def stacked(rows: Sequence[Rows]) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """(N, J, P) regressor and (N, J) torques of every log's fitted and held-back rows, in
    time order, log after log; the rows per log."""
    ys, ts, sizes = [], [], []
    for r in rows:
        y, t = [r.y_fit], [r.tau_fit]
        if r.y_hold is not None:
            y.append(r.y_hold[0])
            t.append(r.y_hold[1])
        ys += y
        ts += t
        sizes.append(int(sum(a.shape[0] for a in y)))
    return np.concatenate(ys), np.concatenate(ts), sizes


def held_back_errors(a: np.ndarray, t: np.ndarray, w: np.ndarray, pen: np.ndarray,
                     trials: Sequence[float], folds: Sequence[Fold]) -> np.ndarray:
    """(len(trials), folds) held-back mean squared error [N·m²] of one joint's row for each
    ridge penalty in ``trials`` (``inf``: the penalised columns off).

    Weighted least squares (row weights ``w``) on the column-normalised normal equations
    of the fitted rows, the penalty relative to each column's energy over all rows and
    scaled by the fitted rows' share of it (docs/models.md, "Choosing the model"); a 1e-10
    floor keeps columns constant in the fitted rows determined.
    """
    p = a.shape[1]
    own = ~pen
    d = np.sqrt(np.einsum("i,ij,ij->j", w, a, a))
    d[d == 0] = 1.0
    an = a / d
    out = np.empty((len(trials), len(folds)))
    wsum = max(float(np.sum(w)), 1e-300)
    for f, fold in enumerate(folds):
        tr = fold.train
        aw = an[tr] * w[tr, None]
        g = aw.T @ an[tr]
        h = aw.T @ t[tr]
        share = float(np.sum(w[tr])) / wsum
        for i, lam in enumerate(trials):
            th = np.zeros(p)
            if np.isinf(lam):
                k = np.flatnonzero(own)
                th[k] = solve_normal(g[np.ix_(k, k)] + 1e-10 * np.eye(k.size), h[k])
            else:
                th = solve_normal(g + np.diag(lam * share * pen + 1e-10), h)
            r = an[fold.test] @ th - t[fold.test]
            out[i, f] = float(np.mean(r**2))
    return np.where(np.isfinite(out), out, _HUGE)  # a failed solve: never chosen


def one_se(rel: np.ndarray, rms: np.ndarray | None = None,
           min_gain: float = 0.0) -> tuple[int, int, float]:
    """(chosen, least, standard error) of the one-standard-error rule over candidates,
    simplest first: ``rel`` (candidates, parts) relative held-back errors. With ``rms``
    (candidates,) their pooled held-back RMS errors, a candidate richer than the first
    must also cut the first's by ``min_gain`` (rms <= (1 - min_gain) × the first's),
    else the first is chosen."""
    mean = rel.mean(axis=1)
    best = int(np.argmin(mean))
    k = rel.shape[1]
    se = float(np.std(rel[best], ddof=1) / np.sqrt(k)) if k > 1 else 0.0
    ok = mean <= mean[best] + se
    if rms is not None:
        ok[1:] &= rms[1:] <= (1.0 - min_gain) * rms[0]
    ok[0] = ok[0] or not ok[1:].any()
    return int(np.flatnonzero(ok)[0]), best, se


def _rms(mse: np.ndarray, sizes: np.ndarray) -> float:
    """Pooled RMS [N·m] over held-back parts of ``sizes`` rows from their mean squares."""
    return float(np.sqrt(np.sum(mse * sizes) / max(float(np.sum(sizes)), 1.0)))


@dataclass(frozen=True)
class Choice:
    """What the held-back comparison chose: the kind, the coupled penalty per joint
    (``inf``: cross terms off) and the record (``fit.selection`` of the model)."""

    kind: str
    lambdas: tuple[float, ...]
    record: dict[str, Any]
    payloads: bool = False


def choose(coupled: Sequence[Rows], names: Sequence[str], options: IdentifyOptions,
           named: Sequence[Rows] | None = None) -> Choice:
    """The choice (module doc) from each log's coupled rows (``names``: the logs), and the
    rows of a kind the robot's kinematics name (``named``: used as named, its held-back
    error measured alike)."""
    y, tau, sizes = stacked(coupled)
    first = coupled[0]
    joints, structure = first.joints, first.structure
    nj = len(joints)
    folds, how = folds_of(sizes, names, max(r.cv_gap for r in coupled))
    part = "held-out logs" if len(sizes) >= 2 else "held-back stretches"
    fsize = np.array([f.test.size for f in folds], dtype=float)
    pnames = structures.param_names("coupled", joints, structure)
    pen_all = structures.coupled_penalised(joints, structure)
    frozen = frozen_params("coupled", joints, pnames, list(first.still or []))
    live = np.array([nm not in frozen for nm in pnames]) & np.any(y != 0.0, axis=(0, 1))
    pr = len(pnames) // nj
    # robust weights of the decoupled fit on all rows (own columns only)
    own_cols = np.flatnonzero(live & ~pen_all)
    _, w, _ = robust_lstsq(y[:, :, own_cols], tau, options, separable=True)
    trials = [float("inf"), *sorted((float(v) for v in options.ridge_lambdas), reverse=True)]
    per_joint: dict[str, Any] = {}
    lambdas: list[float] = []
    for j, jn in enumerate(joints):
        block = np.arange(j * pr, (j + 1) * pr)
        cols = block[live[block]]
        pen = pen_all[cols]
        a = np.ascontiguousarray(y[:, j, cols])
        t = tau[:, j]
        use = trials if pen.any() else trials[:1]
        mse = held_back_errors(a, t, w[:, j], pen, use, folds)
        tms = np.array([max(float(np.mean(t[f.test] ** 2)), 1e-300) for f in folds])
        rel = mse / tms[None, :]
        pick, _, se = one_se(rel, np.array([_rms(m, fsize) for m in mse]), MIN_GAIN)
        lambdas.append(use[pick])
        dec = {"rms_nm": _rms(mse[0], fsize), "rel_mse": float(rel[0].mean()),
               "parts_rms_nm": [float(np.sqrt(v)) for v in mse[0]]}
        entry: dict[str, Any] = {"decoupled": dec, "se_rel_mse": se}
        if len(use) > 1:
            bc = 1 + int(np.argmin(rel[1:].mean(axis=1)))
            ci = pick if pick > 0 else bc
            entry["coupled"] = {"lambda": use[ci], "rms_nm": _rms(mse[ci], fsize),
                                "rel_mse": float(rel[ci].mean()),
                                "parts_rms_nm": [float(np.sqrt(v)) for v in mse[ci]],
                                "better_parts": int(np.sum(mse[ci] < mse[0]))}
        entry["chosen"] = "coupled" if pick > 0 else "decoupled"
        if pick > 0:
            entry["lambda"] = use[pick]
        entry["reason"] = _joint_reason(jn, entry, len(folds), part)
        per_joint[jn] = entry
    kind = "coupled" if any(np.isfinite(v) for v in lambdas) else "decoupled"
    record: dict[str, Any] = {
        "rule": RULE, "held_back": how, "parts": [f.name for f in folds],
        "candidates": {
            "decoupled": {"parameters": len(structures.param_names("decoupled", joints,
                                                                   structure))},
            "coupled": {"parameters": len(pnames)},
        },
        "joints": per_joint,
    }
    if named is not None:
        nk = named[0].kind
        nerr = named_errors(named, names, options)
        record["candidates"][nk] = {"parameters": len(structures.param_names(
            nk, named[0].joints, named[0].structure))}
        for jn, e in zip(joints, nerr, strict=True):
            per_joint[jn][nk] = e
        kind = nk
        pay = payload_errors(named, names, options) if options.payload_per_log else None
        if pay is not None:
            record["payload"] = pay
            if pay["chosen"]:  # the named kind is judged as it is fitted: a load per log
                for jn, e in pay["joints"].items():
                    per_joint[jn][nk] = dict(per_joint[jn][nk], rms_nm=e["per_log_rms_nm"],
                                             parts_rms_nm=e["parts_per_log_rms_nm"])
    record["chosen"] = kind
    record["named"] = named is not None
    record["reason"] = _reason(kind, per_joint, len(folds), part, named is not None)
    if named is not None and (odd := _named_misfit(kind, per_joint, names)) is not None:
        warnings.warn(odd, ImpactWarning, stacklevel=2)
    return Choice(kind, tuple(lambdas), record,
                  payloads=bool(record.get("payload", {}).get("chosen")))


def payload_errors(rows: Sequence[Rows], names: Sequence[str],
                   options: IdentifyOptions) -> dict[str, Any] | None:
    """Per joint, the held-out error of a kind with kinematics fitted with one load for all
    logs and with a payload per log (:mod:`impactcli.model.payload`), and whether the
    per-log payloads are chosen; None with one log or without kinematics.

    Each log in turn is held out; the others are fitted both ways (robust). The held-out
    log's own payload is unknown to the fit: it is estimated, the arm's parameters held,
    on the log's first :data:`impactcli.model.payload.START_S` seconds — as detection
    estimates the load a log starts with — and both fits are judged on the rest of the
    log. The payloads per log are chosen when the one-standard-error rule, with the least
    gain :data:`MIN_GAIN`, picks them on any joint (a load is one body: the joints that
    carry it best tell it)."""
    first = rows[0]
    pay = _payload.basis(first.kind, first.joints, first.structure)
    if pay is None or len(rows) < 2:
        return None
    b = pay[0]
    p = b.shape[0]
    logs = [stacked([r]) for r in rows]
    mse = np.zeros((2, len(rows), len(first.joints)))
    tms = np.zeros((len(rows), len(first.joints)))
    sizes = np.zeros(len(rows))
    start_mass: list[float | None] = []
    for t, (yt, tt, _) in enumerate(logs):
        ys = [lg[0] for i, lg in enumerate(logs) if i != t]
        tr = np.concatenate([lg[1] for i, lg in enumerate(logs) if i != t])
        one, _, _ = robust_lstsq(np.concatenate(ys), tr, options, ridge=np.full(p, 1e-10))
        augs = _payload.augment(ys, b)
        prior = _payload.log_weights(augs, [lg[1] for i, lg in enumerate(logs) if i != t],
                                     options)
        aug = np.concatenate(augs)
        per, _, _ = robust_lstsq(aug, tr, options, ridge=np.full(aug.shape[2], 1e-10),
                                 prior=prior)
        per = per[:p]
        ns = _payload.start_rows(rows[t].filter_info, rows[t].y_fit.shape[0])
        w = _payload.weigh(yt[:ns] @ b, tt[:ns] - yt[:ns] @ per, pay[1])
        start_mass.append(w.mass_kg if w.supported else None)
        if tt.shape[0] - ns < 10:  # the log is all start: judged on all of it
            ns = 0
        rest = slice(ns, None)
        for c, th in enumerate((one, _payload.shifted_theta(per, b, w.pi))):
            mse[c, t] = np.mean((yt[rest] @ th - tt[rest]) ** 2, axis=0)
        tms[t] = np.maximum(np.mean(tt[rest] ** 2, axis=0), 1e-300)
        sizes[t] = tt[rest].shape[0]
    joints: dict[str, Any] = {}
    chosen = False
    for j, jn in enumerate(first.joints):
        rel = mse[:, :, j] / tms[None, :, j]
        rms = np.array([_rms(mse[c, :, j], sizes) for c in range(2)])
        pick, _, se_rel = one_se(rel, rms, MIN_GAIN)
        chosen |= pick == 1
        joints[jn] = {"one_load_rms_nm": float(rms[0]), "per_log_rms_nm": float(rms[1]),
                      "parts_one_load_rms_nm": [float(np.sqrt(v)) for v in mse[0, :, j]],
                      "parts_per_log_rms_nm": [float(np.sqrt(v)) for v in mse[1, :, j]],
                      "se_rel_mse": se_rel, "chosen": "per_log" if pick == 1 else "one_load"}
    return {"rule": PAYLOAD_RULE, "parameters": list(pay[1]),
            "start_s": _payload.START_S, "chosen": bool(chosen), "joints": joints,
            "start_mass_kg": {nm: v for nm, v in zip(names, start_mass, strict=True)
                              if v is not None}}


def named_errors(rows: Sequence[Rows], names: Sequence[str],
                  options: IdentifyOptions) -> list[dict[str, Any]]:
    """Per joint, the held-back error of a kind fitted as a whole (planar, urdf: columns
    shared between joints' rows), with the robust weights of its fit on all rows."""
    y, tau, sizes = stacked(rows)
    folds, _ = folds_of(sizes, names, max(r.cv_gap for r in rows))
    nj = y.shape[1]
    live = np.flatnonzero(np.any(y != 0.0, axis=(0, 1)))
    y = y[:, :, live]
    _, w, _ = robust_lstsq(y, tau, options)
    trms = np.sqrt(np.mean(tau**2, axis=0))
    s = 1.0 / np.maximum(trms, 1e-12 * max(float(trms.max()), 1e-300))
    d = np.sqrt(np.einsum("nj,njp->p", w * s**2, y * y))
    d[d == 0] = 1.0
    yn = y / d
    mse = np.empty((len(folds), nj))
    for f, fold in enumerate(folds):
        tr = fold.train
        sw = np.sqrt(w[tr] * s**2)
        a = (yn[tr] * sw[:, :, None]).reshape(-1, yn.shape[2])
        g = a.T @ a
        h = a.T @ (tau[tr] * sw).reshape(-1)
        th = solve_normal(g + 1e-10 * np.eye(g.shape[0]), h)
        r = yn[fold.test] @ th - tau[fold.test]
        mse[f] = np.mean(r**2, axis=0)
    mse = np.where(np.isfinite(mse), mse, _HUGE)
    fsize = np.array([f.test.size for f in folds], dtype=float)
    out = []
    for j in range(nj):
        tms = np.array([max(float(np.mean(tau[f.test, j] ** 2)), 1e-300) for f in folds])
        out.append({"rms_nm": _rms(mse[:, j], fsize),
                    "rel_mse": float(np.mean(mse[:, j] / tms)),
                    "parts_rms_nm": [float(np.sqrt(v)) for v in mse[:, j]]})
    return out


#: The robot's kinematics predict a joint's held-back torque this many times worse than a
#: model without kinematics: the description is likely not this arm's (the sample arms'
#: planar descriptions predict 0.75–0.9× the coupled model's error; a trial's swapped
#: joint order, 1.85×).
MISFIT_FACTOR = 1.5


def _named_misfit(kind: str, per: dict[str, Any], names: Sequence[str]) -> str | None:
    """The warning when the named kinematics predict some joint's held-back torque more
    than :data:`MISFIT_FACTOR` times worse than the best model without them, else None."""
    worse = {}
    for j, e in per.items():
        best = min(e[k]["rms_nm"] for k in ("decoupled", "coupled") if k in e)
        if e[kind]["rms_nm"] > MISFIT_FACTOR * best:
            worse[j] = (e[kind]["rms_nm"], best)
    if not worse:
        return None
    j = max(worse, key=lambda x: worse[x][0] / worse[x][1])
    a, b = worse[j]
    return (f"{', '.join(names)}: the robot's {kind} kinematics predict the held-back torque "
            f"of {', '.join(worse)} worse than a model without them ({j}: {a:.3g} against "
            f"{b:.3g} N·m RMS): the description may not be this arm's — its joints in chain "
            "order from the base, a planar arm's first angle from the horizontal, its link "
            "lengths (docs/formats.md, 'Robot description'); forces and links follow it")


def _joint_reason(jn: str, e: dict[str, Any], k: int, part: str) -> str:
    d = e["decoupled"]["rms_nm"]
    c = e.get("coupled")
    if c is None:
        return f"decoupled: joint {jn} has no cross terms to fit"
    if e["chosen"] == "coupled":
        return (f"coupled: held-back error {c['rms_nm']:.3g} N·m RMS on {jn} vs {d:.3g} "
                f"decoupled, on {c['better_parts']} of {k} {part}")
    if c["rel_mse"] >= e["decoupled"]["rel_mse"]:
        return (f"decoupled: coupled's held-back error on {jn} is not below decoupled's "
                f"({c['rms_nm']:.3g} vs {d:.3g} N·m RMS; better on {c['better_parts']} of "
                f"{k} {part})")
    return (f"decoupled: coupled's held-back error on {jn} ({c['rms_nm']:.3g} vs {d:.3g} "
            f"N·m RMS, better on {c['better_parts']} of {k} {part}) is within one standard "
            "error of decoupled's: not clearly better")


def _reason(kind: str, per: dict[str, Any], k: int, part: str, named: bool) -> str:
    """One line: which kind and why, naming the joint(s) that decided."""
    if named:
        worst = max(per, key=lambda j: per[j]["decoupled"]["rms_nm"])
        e = per[worst]
        other = f"{e['decoupled']['rms_nm']:.3g} decoupled" + (
            f", {e['coupled']['rms_nm']:.3g} coupled" if "coupled" in e else "")
        return (f"{kind}: the robot's kinematics (--robot), used as named; held-back error "
                f"{e[kind]['rms_nm']:.3g} N·m RMS on {worst} vs {other} ({k} {part})")
    if kind == "coupled":
        gain = sorted((j for j in per if per[j]["chosen"] == "coupled"),
                      key=lambda j: per[j]["coupled"]["rms_nm"] - per[j]["decoupled"]["rms_nm"])
        lines = [f"held-back error {per[j]['coupled']['rms_nm']:.3g} N·m RMS on {j} vs "
                 f"{per[j]['decoupled']['rms_nm']:.3g} decoupled, on "
                 f"{per[j]['coupled']['better_parts']} of {k} {part}" for j in gain[:2]]
        off = [j for j in per if per[j]["chosen"] != "coupled"]
        return ("coupled: " + "; ".join(lines)
                + (f" (cross terms off on {', '.join(off)})" if off else ""))
    cands = [j for j in per if "coupled" in per[j]]
    if not cands:
        return "decoupled: no joint has cross terms to fit"
    j = min(cands, key=lambda x: per[x]["coupled"]["rms_nm"] - per[x]["decoupled"]["rms_nm"])
    c, d = per[j]["coupled"]["rms_nm"], per[j]["decoupled"]["rms_nm"]
    if c >= d:
        return (f"decoupled: coupled is no better held back on any joint (closest: {j}, "
                f"{c:.3g} vs {d:.3g} N·m RMS, {k} {part})")
    return (f"decoupled: coupled is not clearly better held back on any joint (largest gain: "
            f"{j}, {c:.3g} vs {d:.3g} N·m RMS, within one standard error over {k} {part})")


def _chosen_model(choice: Choice, rows: Mapping[str, Sequence[Rows]], paths: Sequence[str],
                  robot: RobotDescription | None, options: IdentifyOptions,
                  input_sha256: str) -> RigidModel:
    """The chosen kind fitted on all rows, with the record in ``fit.selection``."""
    lam = choice.lambdas if choice.kind == "coupled" else None
    model = fit_rows(rows[choice.kind], paths, robot=robot, options=options,
                     input_sha256=input_sha256, lambdas=lam, payloads=choice.payloads)
    return dataclasses.replace(model, fit=dict(model.fit, selection=choice.record))


def coupled_too_big(n_joints: int, n_samples: int, options: IdentifyOptions,
                    where: str) -> str | None:
    """The warning when the coupled candidate cannot be held within
    ``options.coupled_max_mb`` even at the rows it needs (J × J(5J+1) numbers a row: the
    memory grows with the cube of the joint count), else None: then the choice is the
    decoupled model, the coupled one not tried."""
    rows = min(COUPLED_MIN_ROWS, max(int(n_samples), 1))
    mb = rows * 8.0 * n_joints * n_joints * (5 * n_joints + 1) / 2**20
    if mb <= options.coupled_max_mb:
        return None
    return (f"{where}: model kind decoupled: the coupled candidate was not tried — "
            f"{n_joints} joints make its regressor about {mb / 1024:.3g} GiB at the "
            f"{rows} rows it needs, above coupled_max_mb = {options.coupled_max_mb:g} MB")


def select_model(logs: Sequence[RobotLog], *, robot: RobotDescription | None = None,
                 options: IdentifyOptions = IdentifyOptions()) -> RigidModel:
    """The model of the kind (and coupled penalty) that predicts best held back (module
    doc), fitted on all ``logs``; ``fit.selection`` records the choice and why. The same
    arguments as :func:`impactcli.model.identify_many` without ``kind``, which it replaces
    when the user names no model kind."""
    paths = [lg.source.path for lg in logs]
    named = default_kind(robot)
    big = coupled_too_big(len(logs[0].joint_names), sum(lg.n_samples for lg in logs),
                          options, ", ".join(paths)) if named == "decoupled" else None
    if big is not None:
        warnings.warn(big, ImpactWarning, stacklevel=2)
        return identify_many(logs, robot=robot, kind="decoupled", options=options)
    rows: dict[str, list[Rows]] = {}
    rows[named] = [prepare_rows(lg, robot, named, options) for lg in logs]
    with warnings.catch_warnings():  # the same warnings as the rows above: said once
        warnings.simplefilter("ignore")
        joints = rows[named][0].joints  # a URDF's: the logged joints it models
        rows["coupled"] = [prepare_rows(lg.select(joints), None, "coupled", options)
                           for lg in logs]
    choice = choose(rows["coupled"], paths, options,
                    named=None if named == "decoupled" else rows[named])
    return _chosen_model(choice, rows, paths, robot, options, many_sha256(logs))


def identify_correction(logs: Sequence[RobotLog], *, robot: RobotDescription | None = None,
                        options: IdentifyOptions = IdentifyOptions()) -> RigidModel:
    """The correction model of the controller's channels (:mod:`impactcli.model.generators`:
    identified on what the channel leaves out) over several calibration logs:
    :func:`identify_many`'s fit of the robot's kind, with a payload per log where the kind
    has kinematics and a payload per log predicts clearly better held out
    (:func:`payload_errors`; recorded under ``fit["payload_choice"]``). A load the
    controller's model does not know shows in its channel as that mass's torque, so logs
    that carry different loads are told apart as with the tool's own model. When one load
    for all logs is as good, the model is :func:`identify_many`'s to the last bit."""
    if not options.payload_per_log or len(logs) < 2:
        return identify_many(logs, robot=robot, options=options)
    rows = [prepare_rows(lg, robot, None, options) for lg in logs]
    paths = [lg.source.path for lg in logs]
    pay = payload_errors(rows, paths, options)
    chosen = pay is not None and pay["chosen"]
    model = fit_rows(rows, paths, robot=robot, options=options,
                     input_sha256=many_sha256(logs), payloads=chosen)
    return (dataclasses.replace(model, fit=dict(model.fit, payload_choice=pay)) if chosen
            else model)


class SelectStream:
    """:func:`select_model` on one log fed in chunks (the detect of a log without a
    config): the decoupled and the coupled rows built in the same pass, the choice made
    on contiguous stretches of the log. Use as :class:`IdentifyStream`."""

    def __init__(self, streams: dict[str, IdentifyStream]) -> None:
        self.streams = streams

    @classmethod
    def start(cls, joint_names: Sequence[str], n: int, sample_rate_hz: float, duration_s: float, *,
              robot: RobotDescription | None = None,
              options: IdentifyOptions = IdentifyOptions(), where: str = "log",
              input_sha256: str = "") -> SelectStream:
        """Plan it (raises what :meth:`IdentifyStream.start` raises); the decoupled model
        alone, warned, where the coupled one cannot be held (:func:`coupled_too_big`)."""
        big = coupled_too_big(len(joint_names), n, options, where)
        if big is not None:
            warnings.warn(big, ImpactWarning, stacklevel=2)
        return cls({k: IdentifyStream.start(joint_names, n, sample_rate_hz, duration_s, robot=robot,
                                            kind=k, options=options, where=where,
                                            input_sha256=input_sha256)
                    for k in (("decoupled",) if big else ("decoupled", "coupled"))})

    def feed(self, t: np.ndarray, q: np.ndarray, tau: np.ndarray) -> None:
        """The next samples, as :meth:`IdentifyStream.feed`."""
        for s in self.streams.values():
            s.feed(t, q, tau)

    def finish(self) -> RigidModel:
        """The chosen model, fitted on the whole log."""
        dec = self.streams["decoupled"]
        if "coupled" not in self.streams:  # too big to try (:meth:`start`)
            return dec.finish()
        rows: dict[str, list[Rows]] = {"decoupled": [dec.rows()]}
        with warnings.catch_warnings():  # the same warnings as the rows above: said once
            warnings.simplefilter("ignore")
            rows["coupled"] = [self.streams["coupled"].rows()]
        choice = choose(rows["coupled"], [dec.where], dec.options)
        return _chosen_model(choice, rows, [dec.where], dec.robot, dec.options,
                             dec.input_sha256)


def describe(record: dict[str, Any]) -> list[str]:
    """Lines for the terminal: the kind chosen and why, and each candidate's held-back
    RMS error per joint [N·m]."""
    kinds = [k for k in ("decoupled", "coupled", "planar", "urdf") if k in record["candidates"]]
    lines = [f"model kind: {record['reason']}",
             f"  held back: {record['held_back']}; rule: the simplest candidate within one "
             "standard error of the least held-back error (these choose the kind; the fit "
             "table's held columns are the final fit's own held-back part, another figure)"]
    w = max(5, *(len(j) for j in record["joints"]))
    lines.append(f"  {'joint':<{w}}  " + "  ".join(f"{k:>14}" for k in kinds)
                 + "  chosen   [held-back RMS error, N·m]")
    for jn, e in record["joints"].items():
        cells = []
        for k in kinds:
            if k not in e:
                cells.append(f"{'—':>14}")
            elif k == "coupled":
                cells.append(f"{e[k]['rms_nm']:>7.3g} λ {e[k]['lambda']:<5.0e}")
            else:
                cells.append(f"{e[k]['rms_nm']:>14.3g}")
        chosen = record["chosen"] if record.get("named") else e["chosen"]
        if chosen == "coupled" and "lambda" in e:
            chosen += f" (λ {e['lambda']:.0e})"
        lines.append(f"  {jn:<{w}}  " + "  ".join(cells) + f"  {chosen}")
    lines += _payload_lines(record)
    if record["chosen"] == "coupled" and not record["held_back"].startswith("leave-one-log"):
        lines.append("  chosen on stretches of one log: a motion or pose the log lacks is not "
                     "judged (a coupled model's cross terms may not carry over); calibrate on "
                     "several free logs of the robot's motions")
    return lines


def _payload_lines(record: dict[str, Any]) -> list[str]:
    """The held-out comparison of one load against a payload per log (:func:`payload_errors`),
    or why there is none across several logs."""
    pay = record.get("payload")
    if pay is None:
        if record["chosen"] in ("decoupled", "coupled") and \
                record["held_back"].startswith("leave-one-log"):
            return [f"  payload per log: not fitted: {_payload.NO_KINEMATICS}"]
        return []
    return payload_lines(pay)


def payload_lines(pay: dict[str, Any]) -> list[str]:
    """:func:`payload_errors`' comparison in one line."""
    cells = ", ".join(f"{jn} {e['one_load_rms_nm']:.3g} → {e['per_log_rms_nm']:.3g}"
                      for jn, e in pay["joints"].items())
    verdict = ("a payload per log (clearly better held out)" if pay["chosen"]
               else "one load for all logs (a payload per log is not clearly better)")
    return [f"  payload: one load for all logs → a payload per log, held-out RMS error "
            f"[N·m] (each held-out log's load estimated on its first {pay['start_s']:g} s): "
            f"{cells}; chosen: {verdict}"]
