"""Diagnosis: how far two replays of the adaptive evaluator started 1e-12 apart separate.

Run: ``python tests/benchmarks/evaluator_sensitivity.py [--logs NAME ...] [--eps 1e-12]
[--every 0.5]`` (about a minute for the twelve sample logs on 2 cores).

For each sample log (CSV, replayed with its arm's committed config) the residual r and the
threshold inputs u are made once, as the product makes them; the evaluator
(:func:`impactcli.detect.adaptive.evaluate_chunk`) then runs twice: on r, and on
r · (1 + eps) — a change of the size another CPU, BLAS or summation order makes. Printed per
log and axis:

* ``sep9`` / ``sep6``: the first time [s] at which the two runs' adaptive statistic
  r_rms − v_rms differs by more than 1e-9 / 1e-6 of its range (``-`` never);
* ``max_sep``: the largest difference of the statistic over its range;
* ``|pole|``: the largest modulus of the adapted threshold filter's poles (the roots of
  A_hat(z) = 1 + a_1 z^-1 + … + a_p z^-p, theta_v = [−a | b], eq. 33/48) along the log —
  median and maximum over the sampled instants, and the share of instants at or above 1;
* ``cond``: the largest condition number of P (eq. 39) over the sampled instants;
* ``capped``: the samples at which the wind-up guard scaled P (docs/method.md §3).

``--set KEY=VALUE ...`` overrides adaptive settings (``regularization=0`` for plain eq. 39);
``--reference`` adds the compiled kernel's largest difference from the plain NumPy reference
of the same equations.

The state is sampled every ``--every`` seconds (chunks; the chunked run is bit for bit the
one-chunk run). ``--json PATH`` writes the per-instant traces for plotting.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from impactcli.config import AdaptiveConfig  # noqa: E402
from impactcli.detect.adaptive import evaluate_chunk  # noqa: E402
from impactcli.detect.axes import EvaluatorState  # noqa: E402
from tests.sample_replay import SAMPLES, replay  # noqa: E402


def residual_and_inputs(name: str) -> tuple[np.ndarray, np.ndarray, float, np.ndarray,
                                            AdaptiveConfig]:
    """(r, u, fs, v_stat, adaptive cfg) of a sample log, as detect makes them with its arm's
    committed config (``tests/sample_replay.py``)."""
    return replay(name)


def trace(r: np.ndarray, u: np.ndarray, fs: float, v_stat: np.ndarray, cfg: object,
          every: int) -> dict[str, np.ndarray]:
    """The evaluator over the log in chunks of ``every`` samples: its statistic, and at
    each chunk's end the poles' largest modulus and cond(P) per axis."""
    n, J = r.shape
    st = EvaluatorState.initial(J, cfg, fs)  # type: ignore[arg-type]
    eta, p = st.cfg.eta, st.cfg.p
    stats, poles, conds, t_at = [], [], [], []
    res = None
    for a in range(0, n, every):
        b = min(n, a + every)
        res, st = evaluate_chunk(st, r[a:b], u[:, a:b], fs, v_stat)
        stats.append(res.statistic)
        pj, cj = [], []
        for j in range(J):
            a_coef = -st.theta[j, eta:eta + p]
            pj.append(float(np.max(np.abs(np.roots(np.r_[1.0, a_coef])))) if p else 0.0)
            cj.append(float(np.linalg.cond(st.P[j])))  # the kernel keeps P whole
        poles.append(pj)
        conds.append(cj)
        t_at.append(b / fs)
    assert res is not None
    return {"stat": np.concatenate(stats), "poles": np.array(poles), "cond": np.array(conds),
            "t": np.array(t_at), "capped": st.n_capped.copy(), "resets": st.n_resets.copy()}


def first_time(diff: np.ndarray, level: float, fs: float) -> str:
    idx = np.flatnonzero(diff > level)
    return f"{idx[0] / fs:.1f}" if idx.size else "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", nargs="*", default=None, help="sample log stems (default all)")
    ap.add_argument("--eps", type=float, default=1e-12, help="relative change of r")
    ap.add_argument("--every", type=float, default=0.5, help="state sampled every S seconds")
    ap.add_argument("--json", type=Path, default=None, help="write the traces here")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                    help="override adaptive settings, e.g. p=0 max_trace=inf")
    ap.add_argument("--reference", action="store_true",
                    help="also the largest difference of the compiled evaluator from the "
                         "plain NumPy reference of the same equations (tests/reference/"
                         "adaptive.py; slow: seconds per log)")
    args = ap.parse_args()
    names = args.logs or sorted(p.name.removesuffix(".csv.gz")
                                for p in (SAMPLES / "csv").glob("*.csv.gz"))
    out: dict[str, object] = {}
    print(f"eps = {args.eps:g} (relative change of the residual)")
    print(f"{'log':24s} ax {'sep9':>6s} {'sep6':>6s} {'max_sep':>9s} {'|pole| med':>10s} "
          f"{'max':>6s} {'>=1':>5s} {'cond max':>9s} {'capped':>7s} {'resets':>6s}")
    for name in names:
        t0 = time.perf_counter()
        r, u, fs, v_stat, cfg = residual_and_inputs(name)
        if args.set:
            import dataclasses
            kw = {k: type(getattr(cfg, k) if getattr(cfg, k) is not None else 1.0)(v)
                  for k, v in (x.split("=", 1) for x in args.set)}
            cfg = dataclasses.replace(cfg, **kw)
        every = max(1, round(args.every * fs))
        base = trace(r, u, fs, v_stat, cfg, every)
        pert = trace(r * (1.0 + args.eps), u, fs, v_stat, cfg, every)
        for j in range(r.shape[1]):
            s0, s1 = base["stat"][:, j], pert["stat"][:, j]
            rng = float(np.ptp(s0[np.isfinite(s0)])) or 1.0
            d = np.abs(s1 - s0) / rng
            pl = base["poles"][:, j]
            print(f"{name:24s} {j + 1:2d} {first_time(d, 1e-9, fs):>6s} "
                  f"{first_time(d, 1e-6, fs):>6s} {float(d.max()):9.2e} "
                  f"{float(np.median(pl)):10.4f} {float(pl.max()):6.3f} "
                  f"{float(np.mean(pl >= 1.0)):5.2f} {float(base['cond'][:, j].max()):9.2e} "
                  f"{int(base['capped'][j]):7d} {int(base['resets'][j]):6d}")
            out[f"{name}/{j + 1}"] = {"t": base["t"].tolist(), "pole": pl.tolist(),
                                      "cond": base["cond"][:, j].tolist(),
                                      "sep": d[every - 1::every].tolist()}
        if args.reference:
            from tests.reference.adaptive import evaluate, evaluate_reference

            a = evaluate(r, u, fs, v_stat, cfg)  # type: ignore[arg-type]
            b = evaluate_reference(r, u, fs, v_stat, cfg)  # type: ignore[arg-type]
            worst = max(float(np.max(np.abs(getattr(a, k) - getattr(b, k))
                                     / max(float(np.ptp(getattr(b, k))), 1e-300)))
                        for k in ("r_tilde", "v_dyn", "r_rms", "v_rms"))
            print(f"{name:24s} kernel against the reference: {worst:.2e} of the range")
        print(f"  ({time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    if args.json:
        args.json.write_text(json.dumps(out))


if __name__ == "__main__":
    main()
