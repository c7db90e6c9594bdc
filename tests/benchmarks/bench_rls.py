"""Benchmark: adaptive evaluator (RLS + regressor + F1/F2 + RMS + decision) throughput.

Run:  python tests/benchmarks/bench_rls.py  [--seconds 600] [--release REF]

Targets (docs/performance.md, "The adaptive evaluator"): ≥ 1,000,000 axis-samples/s at 2
joints (nu = 34) and ≥ 300,000 at 7 joints (nu = 64), one core. padasip's FilterRLS is run
on the same regression (the regressors phi(k) of axis 0, rebuilt from the evaluator's own
outputs) and reported as a ratio. Numba compilation is excluded (one warm-up call on a short slice).

The last rows time the chunked form (``evaluate_chunk``, state in, state out): its fixed
cost per call [µs] (state copy, checks, dispatch of the axes; timed on empty chunks) as a
share of a 4096-sample chunk's time, and the whole log in chunks of 4096 against one call.

A third row times the wind-up guard's own path: 7 joints of which the last 4 stand still
(their reference inputs are exactly 0), with the regulariser off (``regularization = 0``,
else P stays below the cap), so the per-coordinate cap of :mod:`impactcli.detect.rls`
scales P at most samples of a long enough log; ``capped`` is that share.

``--release REF`` first runs the same measurement on the package of git ref ``REF`` (a
temporary worktree, imported through PYTHONPATH in a fresh process), so both figures come
from one run on one machine. The batch RLS column uses ``tests/reference/rls.py`` (loaded
by path) on whichever package is imported.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal

from impactcli.config import AdaptiveConfig
from impactcli.detect.adaptive import evaluate_chunk

try:
    from impactcli.detect.axes import EvaluatorState
except ImportError:  # a release before the state moved next to the kernel
    from impactcli.detect.adaptive import EvaluatorState  # type: ignore[attr-defined,no-redef]

FS = 250.0
ROOT = Path(__file__).resolve().parents[2]


def _reference_rls() -> Any:
    """tests/reference/rls.py of this tree, on whichever ``impactcli`` is already imported
    (this tree's, or a release's through PYTHONPATH)."""
    sys.path.insert(0, str(ROOT))  # after impactcli's import: only ``tests`` comes from here
    from tests.reference import rls

    return rls


def evaluate(r: np.ndarray, u: np.ndarray, fs: float, v_stat: np.ndarray,
             cfg: AdaptiveConfig, threads: int = 1) -> Any:
    """The compiled evaluator on a whole log: one chunk from the initial state."""
    st = EvaluatorState.initial(r.shape[1], cfg, fs)
    return evaluate_chunk(st, r, u, fs, v_stat, cfg, threads)[0]


def data(joints: int, n: int, seed: int = 0, still: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Triangle references; the last ``still`` joints stand still (inputs exactly 0)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    per = 2.0 + 0.37 * np.arange(joints)
    pos = np.stack([0.8 * signal.sawtooth(2 * np.pi * t / p, 0.5) for p in per], axis=1)
    if still:
        pos[:, joints - still:] = 0.3
    v = np.gradient(pos, axis=0) * FS
    acc = np.gradient(v, axis=0) * FS
    u = np.stack([np.tanh(50 * v), acc])
    r = 0.3 * np.tanh(50 * v) + 0.002 * acc + 0.03 * rng.standard_normal(pos.shape)
    return r, u


def regressors(r: np.ndarray, vd: np.ndarray, u: np.ndarray, cfg: AdaptiveConfig,
               j: int) -> np.ndarray:
    """phi(k) of axis j (eq. 51–54), as the evaluator builds it."""
    n, J = r.shape

    def lagged(x: np.ndarray, order: int) -> np.ndarray:
        out = np.zeros((n, order))
        for d in range(1, order + 1):
            out[d:, d - 1] = x[:-d]
        return out

    cols = [lagged(r[:, j], cfg.eta), lagged(vd[:, j], cfg.p)]
    for i, rho in enumerate(cfg.rho):
        for ll in range(J):
            cols.append(lagged(u[i, :, ll], rho))
    return np.hstack(cols)


def best_of(fn, repeats: int = 9) -> float:
    """Best CPU time of this process [s] (process_time: robust to other processes sharing
    the cores; on an idle machine it equals wall time for this single-threaded code)."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=400.0, help="log length [s] at 250 Hz")
    ap.add_argument("--padasip-samples", type=int, default=20_000)
    ap.add_argument("--release", default=None,
                    help="also measure the package of this git ref, first, in the same run")
    args = ap.parse_args()
    if args.release:
        _run_release(args.release, sys.argv[1:])
        print(f"this tree ({ROOT}):")
    import padasip as pa

    rls_run = _reference_rls().rls_run

    cfg = AdaptiveConfig()
    n = int(args.seconds * FS)
    print(f"machine: {platform.platform()} | {platform.processor() or platform.machine()} | "
          f"cpu_count={os.cpu_count()} | python {platform.python_version()}")
    print(f"log: {n} samples at {FS:g} Hz; Table I settings; best of 9, CPU time; "
          f"load average {os.getloadavg()[0]:.1f}")
    print(f"{'joints':>6} {'nu':>4} {'evaluator axis-samples/s':>26} {'target':>10} "
          f"{'RLS-only upd/s':>15} {'padasip upd/s':>14} {'ratio eval/padasip':>19}")
    for joints, target, still in ((2, 1_000_000, 0), (7, 300_000, 0), (7, 300_000, 4)):
        nn = n if joints == 2 else n // 3
        r, u = data(joints, nn, still=still)
        # the guard's row without the regulariser (a release before it has no such field)
        off = ({"regularization": 0.0} if "regularization" in
               {f.name for f in dataclasses.fields(AdaptiveConfig)} else {})
        row_cfg = AdaptiveConfig(**off) if still else cfg
        v_stat = np.full(joints, 0.1)
        evaluate(r[:200], u[:, :200], FS, v_stat, row_cfg, threads=1)  # compile / load cache
        res = evaluate(r, u, FS, v_stat, row_cfg, threads=1)
        dt = best_of(lambda r=r, u=u, v_stat=v_stat, c=row_cfg: evaluate(r, u, FS, v_stat, c,
                                                                           threads=1))
        rate = nn * joints / dt
        Phi = regressors(r, res.v_dyn, u, row_cfg, 0)
        nu = Phi.shape[1]
        rls_run(Phi[:100], r[:100, 0])
        dt_rls = best_of(lambda Phi=Phi, r=r: rls_run(Phi, r[:, 0], keep_history=False))
        m = min(args.padasip_samples, nn)
        flt = pa.filters.FilterRLS(nu, mu=cfg.forgetting_factor, w="zeros")

        def pada(flt=flt, Phi=Phi, r=r, m=m) -> None:
            for k in range(m):
                flt.adapt(r[k, 0], Phi[k])

        dt_p = best_of(pada, repeats=1)
        rate_p = m / dt_p
        capped = getattr(res, "n_capped", np.zeros(0))
        note = (f"   {still} still; capped {capped.sum() / (nn * joints):.0%} of axis-samples"
                if still else "")
        print(f"{joints:>6} {nu:>4} {rate:>26,.0f} {target:>10,} {nn / dt_rls:>15,.0f} "
              f"{rate_p:>14,.0f} {rate / rate_p:>19.1f}x"
              f"{'' if rate >= target else '   BELOW TARGET'}{note}")
    print(f"{'joints':>6} {'nu':>4} {'fixed µs/chunk':>15} {'= % of a 4096 chunk':>20} "
          f"{'chunks of 4096: s':>18} {'whole log: s':>13}")
    for joints in (2, 7):
        nn = n if joints == 2 else n // 3
        r, u = data(joints, nn)
        v_stat = np.full(joints, 0.1)
        st0 = EvaluatorState.initial(joints, cfg, FS)
        calls = 1000

        def empty(st0=st0, r=r, u=u, v_stat=v_stat, calls=calls) -> None:
            for _ in range(calls):  # the whole cost of a call but the samples' work
                evaluate_chunk(st0, r[:0], u[:, :0], FS, v_stat, cfg)

        fixed = best_of(empty, 5) / calls
        dt = best_of(lambda r=r, u=u, v_stat=v_stat: evaluate(r, u, FS, v_stat, cfg, threads=1),
                     5)

        def chunked(r=r, u=u, v_stat=v_stat) -> None:
            st = EvaluatorState.initial(r.shape[1], cfg, FS)
            for a in range(0, r.shape[0], 4096):
                _, st = evaluate_chunk(st, r[a:a + 4096], u[:, a:a + 4096], FS, v_stat, cfg)

        dc = best_of(chunked, 5)
        print(f"{joints:>6} {cfg.n_params(joints):>4} {fixed * 1e6:>15.0f} "
              f"{fixed / (dt * 4096 / nn):>20.2%} {dc:>18.3f} {dt:>13.3f}")

def _run_release(ref: str, argv: list[str]) -> None:
    """This script on the package of ``ref`` (a temporary git worktree), in a fresh process."""
    with tempfile.TemporaryDirectory() as tmp:
        where = Path(tmp) / "release"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(where), ref],
                       check=True, capture_output=True)
        try:
            rest = [a for i, a in enumerate(argv) if a != "--release"
                    and not (i > 0 and argv[i - 1] == "--release")
                    and not a.startswith("--release=")]
            print(f"release {ref}:", flush=True)
            env = dict(os.environ, PYTHONPATH=str(where))
            subprocess.run([sys.executable, __file__, *rest], env=env, check=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(where)],
                           check=False, capture_output=True)


if __name__ == "__main__":
    main()
