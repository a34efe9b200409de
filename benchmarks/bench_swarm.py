"""Swarm optimizers on standard test functions: accuracy per evaluation budget, and speed.

For each optimizer x function x dimension, ``--seeds`` runs with the same evaluation budget
(``--evals``, default 10 000) report the median and worst final value (every function's minimum
is 0), the share of runs below 1e-2, and the time per run; scipy's ``differential_evolution``
(polish off, same number of evaluations, ``popsize=15``) is the reference row. It prints, it does
not assert. Run: ``python benchmarks/bench_swarm.py [--dims 2 10] [--seeds 10] [--evals 10000]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import differential_evolution

from hybridnav.planners.swarm import minimize
from hybridnav.planners.swarm.functions import FUNCTIONS

# population parameters; iterations follow from the evaluation budget
SETTINGS = {
    "firefly": {"n": 25},
    "fastep": {"n": 50},
    "acor": {"k": 50, "m": 10},
    "pso": {"n": 30},
    "bat": {"n": 30},
}


def run_swarm(name: str, fname: str, d: int, evals: int, seed: int) -> float:
    tf = FUNCTIONS[fname]
    params = dict(SETTINGS[name])
    if name == "fastep" and d > 3:
        params["damping"] = 0.97  # the paper's 0.8 freezes the swarm after ~50 generations
    r = minimize(name, tf.f, tf.bounds(d), seed=seed, iterations=None, max_evals=evals, **params)
    return r.fun


def run_de(fname: str, d: int, evals: int, seed: int) -> float:
    tf = FUNCTIONS[fname]
    lo, hi = tf.bounds(d)
    popsize = 15
    maxiter = max(evals // (popsize * d) - 1, 1)
    r = differential_evolution(lambda X: tf.f(X.T), list(zip(lo, hi)), seed=seed, popsize=popsize,
                               maxiter=maxiter, tol=0, polish=False, vectorized=True,
                               updating="deferred")
    return float(r.fun)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dims", type=int, nargs="+", default=[2, 10])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--evals", type=int, default=10_000)
    ap.add_argument("--functions", nargs="+", default=list(FUNCTIONS))
    args = ap.parse_args()
    print(f"budget {args.evals} evaluations, {args.seeds} seeds; values are f - 0")
    print(f"{'function':<11}{'d':>3}  {'method':<9}{'median':>10}{'worst':>10}{'<1e-2':>7}"
          f"{'s/run':>8}")
    for fname in args.functions:
        for d in args.dims:
            if fname == "rosenbrock" and d < 2:
                continue
            for name in [*SETTINGS, "scipy-de"]:
                t0 = time.perf_counter()
                if name == "scipy-de":
                    vals = [run_de(fname, d, args.evals, s) for s in range(args.seeds)]
                else:
                    vals = [run_swarm(name, fname, d, args.evals, s) for s in range(args.seeds)]
                dt = (time.perf_counter() - t0) / args.seeds
                v = np.array(vals)
                print(f"{fname:<11}{d:>3}  {name:<9}{np.median(v):>10.2e}{v.max():>10.2e}"
                      f"{np.mean(v < 1e-2):>7.0%}{dt:>8.3f}")


if __name__ == "__main__":
    main()
