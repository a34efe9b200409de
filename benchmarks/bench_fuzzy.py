"""FuzzySystem.evaluate vs scikit-fuzzy's ControlSystemSimulation.compute(), per evaluation.

For each system: scikit-fuzzy's ``compute()`` timed per call (default simulation settings, a fresh
random input every call, input assignment not counted), ``evaluate`` at batch 1 (Python floats, one
call per sample) and at batch 1000 (one call on arrays, best of ``--repeat``), as evaluations per
second and as ratios to scikit-fuzzy (targets: >= 20x at batch 1, >= 1000x per evaluation at batch
1000), and the largest difference from scikit-fuzzy over the reference samples (where
scikit-fuzzy gives no output, ``evaluate`` must give the file's ``default``).
Run: ``python benchmarks/bench_fuzzy.py [--systems effc-2rule effc-5rule] [--ref 300]``.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from hybridnav import fuzzy


def bench(fs: fuzzy.FuzzySystem, n_ref: int, repeat: int, rng: np.random.Generator) -> dict:
    from skfuzzy import control as ctrl

    names = fs.input_names
    lo = np.array([v.range[0] for v in fs.inputs])
    hi = np.array([v.range[1] for v in fs.inputs])
    X = rng.uniform(lo, hi, (max(n_ref, 1000), len(names)))

    # scikit-fuzzy, one compute() per sample
    cs = fs.to_skfuzzy()
    used = {a.label for a in cs.antecedents}
    sim = ctrl.ControlSystemSimulation(cs)
    ref = np.full(n_ref, np.nan)
    t_sk = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # skfuzzy 0.5.0 on NumPy >= 2.4
        for k in range(n_ref):
            for j, name in enumerate(names):
                if name in used:
                    sim.input[name] = float(X[k, j])
            t0 = time.perf_counter()
            sim.compute()
            t_sk += time.perf_counter() - t0
            ref[k] = sim.output.get(fs.output.name, np.nan)
    t_sk /= n_ref

    # batch 1: one call per sample with Python floats
    rows = X[:1000].tolist()
    kw = [dict(zip(names, r)) for r in rows]
    best1 = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for k in kw:
            fs.evaluate(**k)
        best1 = min(best1, (time.perf_counter() - t0) / len(kw))

    # batch 1000: one call on arrays
    cols = {name: np.ascontiguousarray(X[:1000, j]) for j, name in enumerate(names)}
    fs.evaluate(**cols)
    best1000 = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(20):
            fs.evaluate(**cols)
        best1000 = min(best1000, (time.perf_counter() - t0) / 20 / 1000)

    got = fs.evaluate(**{name: X[:n_ref, j] for j, name in enumerate(names)})
    fired = ~np.isnan(ref)
    diff = float(np.max(np.abs(got[fired] - ref[fired]))) if fired.any() else 0.0
    default_ok = bool(np.all(got[~fired] == fs.output.default))
    return {"sk": t_sk, "b1": best1, "b1000": best1000, "diff": diff, "nofire": int((~fired).sum()),
            "default_ok": default_ok, "n": n_ref}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=fuzzy.builtin_names(),
                    help="built-in names or .json paths")
    ap.add_argument("--ref", type=int, default=300, help="scikit-fuzzy evaluations per system")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"{'system':<12} {'skfuzzy compute()':>18} {'evaluate, batch 1':>28} "
          f"{'evaluate, batch 1000':>30}  max |diff| vs skfuzzy")
    for name in args.systems:
        fs = fuzzy.load(name)
        r = bench(fs, args.ref, args.repeat, rng)
        print(f"{fs.name:<12} {r['sk'] * 1e3:8.3f} ms/eval   "
              f"{1 / r['b1']:9.0f} eval/s {r['b1'] * 1e6:6.1f} us ({r['sk'] / r['b1']:5.0f}x)   "
              f"{1 / r['b1000']:10.0f} eval/s {r['b1000'] * 1e9:5.0f} ns ({r['sk'] / r['b1000']:5.0f}x)  "
              f"{r['diff']:.1e} over {r['n'] - r['nofire']} samples; {r['nofire']} with no rule "
              f"fired -> default {'OK' if r['default_ok'] else 'WRONG'}")


if __name__ == "__main__":
    main()
