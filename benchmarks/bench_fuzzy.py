"""FuzzySystem.evaluate vs scikit-fuzzy's ControlSystemSimulation.compute(), per evaluation.

For each system: scikit-fuzzy's ``compute()`` timed per call (default simulation settings, a fresh
random input every call, input assignment not counted), ``evaluate`` at batch 1 (Python floats, one
call per sample) and at batch 1000 (one call on arrays, best of ``--repeat``), as evaluations per
second and as ratios to scikit-fuzzy (targets: >= 20x at batch 1, >= 1000x per evaluation at batch
1000), and the largest difference from scikit-fuzzy over the reference samples (where
scikit-fuzzy gives no output, ``evaluate`` must give the file's ``default``). At batch 1 a system
switches to the C evaluator after ``hybridnav.fuzzy._native.AFTER`` calls (if it is built; the
first system of a run with an empty cache starts its build and keeps the Python path meanwhile).
Then, per system, one sample per call against the exported C: ``FuzzySystem.evaluate`` on the
Python path and with the compiled C evaluator (``use_native()``; called with literal keywords, as
the planners call it, and with ``**dict``), and the C export (``hybridnav.fuzzy.export.to_c``)
compiled here into a shared library and called through ctypes (our own fresh export, so in this
process; ``export.sil.CompiledFIS`` runs C in a child process instead), on input buffers filled
beforehand: the bare ctypes call), as ns per sample (best of ``--repeat`` passes over
``--samples`` random inputs) and the ratio to ctypes (target: at most 2); and whether the C
evaluator's outputs equal the Python path's bit for bit. The load average is printed first and
last (``os.getloadavg``): the machine is shared.
Run: ``python benchmarks/bench_fuzzy.py [--systems effc-2rule effc-5rule] [--ref 300]``
(``--one-sample-only`` skips the scikit-fuzzy table).
"""

from __future__ import annotations

import argparse
import keyword
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

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


def _best(fn, repeat: int, n: int) -> float:
    """Best seconds per sample of ``fn()`` (one pass over ``n`` samples) over ``repeat`` runs."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, (time.perf_counter() - t0) / n)
    return best


def bench_one_sample(name: str, n: int, repeat: int, rng: np.random.Generator,
                     workdir: Path) -> dict:
    import ctypes
    import subprocess

    from hybridnav.fuzzy.export import c_identifier, to_c

    fs = fuzzy.load(name)
    names = fs.input_names
    lo = np.array([v.range[0] for v in fs.inputs])
    hi = np.array([v.range[1] for v in fs.inputs])
    rows = rng.uniform(lo, hi, (n, len(names))).tolist()
    kws = [dict(zip(names, r)) for r in rows]

    # the C export through ctypes: the bare call on prefilled buffers
    code = to_c(fs)
    (workdir / f"{code.basename}.h").write_text(code.header)
    (workdir / f"{code.basename}.c").write_text(code.source)
    lib = workdir / f"lib{code.basename}.so"
    subprocess.run([os.environ.get("CC", "gcc"), "-std=c99", "-O2", "-shared", "-fPIC", "-o",
                    str(lib), str(workdir / f"{code.basename}.c")], check=True, timeout=300)
    real = ctypes.c_double
    fn = getattr(ctypes.CDLL(str(lib)), f"{c_identifier(code.basename)}_evaluate")
    fn.restype, fn.argtypes = real, [ctypes.POINTER(real)]
    bufs = [(real * len(names))(*r) for r in rows]

    def run_ctypes():
        for b in bufs:
            fn(b)

    # evaluate called as the planners call it: literal keywords (generated for these names)
    literal = all(k.isidentifier() and not keyword.iskeyword(k) for k in names)
    args = ", ".join(f"x{j}" for j in range(len(names)))
    if literal:
        ns: dict = {}
        exec(f"def run(fs, rows):\n    for {args}, in rows:\n"
             f"        fs.evaluate({', '.join(f'{k}=x{j}' for j, k in enumerate(names))})\n", ns)
        run_literal = ns["run"]

    def run_dict(fs):
        for k in kws:
            fs.evaluate(**k)

    py = fuzzy.load(name)
    py._countdown = sys.maxsize       # stays on the Python path (never asks for the C one)
    t_py = _best(lambda: run_dict(py), max(2, repeat // 2), n)
    native = fs.use_native()
    r = {"native": native, "py": t_py}
    # interleaved, so that a load change on the shared machine hits all of them alike
    t_c, t_lit, t_dict = np.inf, np.inf, np.inf
    for _ in range(repeat):
        t_c = min(t_c, _best(run_ctypes, 1, n))
        if literal:
            t_lit = min(t_lit, _best(lambda: run_literal(fs, rows), 1, n))
        t_dict = min(t_dict, _best(lambda: run_dict(fs), 1, n))
    r.update(ctypes=t_c, literal=t_lit, dict=t_dict)
    ours = np.array([fs.evaluate(**k) for k in kws])
    ref = np.array([py._engine.evaluate_scalar(list(rw)) for rw in rows])
    c_out = np.array([fn(b) for b in bufs])
    r["equal"] = bool(np.array_equal(ours, ref, equal_nan=True))
    r["c_diff"] = float(np.max(np.abs(c_out - ours)))
    return r


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=fuzzy.builtin_names(),
                    help="built-in names or .json paths")
    ap.add_argument("--ref", type=int, default=300, help="scikit-fuzzy evaluations per system")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--samples", type=int, default=2000,
                    help="random inputs per pass of the one-sample table")
    ap.add_argument("--one-sample-only", action="store_true",
                    help="skip the scikit-fuzzy table")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    print("load average (1, 5, 15 min): %.2f %.2f %.2f" % os.getloadavg())
    if not args.one_sample_only:
        skfuzzy_table(args, rng)
    one_sample_table(args, rng)
    print("load average (1, 5, 15 min): %.2f %.2f %.2f" % os.getloadavg())


def one_sample_table(args, rng: np.random.Generator) -> None:
    print(f"\none sample per call, ns per sample (best of {args.repeat} passes over "
          f"{args.samples} inputs):")
    print(f"{'system':<12} {'C export, ctypes':>17} {'evaluate(k=x)':>14} {'ratio':>6} "
          f"{'evaluate(**d)':>14} {'ratio':>6} {'Python path':>12} {'speed-up':>9}  "
          "C evaluator == Python path; max |C export - evaluate|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.systems:
            r = bench_one_sample(name, args.samples, args.repeat, rng, Path(tmp))
            lit = (f"{r['literal'] * 1e9:11.0f} ns {r['literal'] / r['ctypes']:5.2f}x"
                   if np.isfinite(r["literal"]) else f"{'n/a':>14} {'':>6}")
            print(f"{name:<12} {r['ctypes'] * 1e9:14.0f} ns {lit} "
                  f"{r['dict'] * 1e9:11.0f} ns {r['dict'] / r['ctypes']:5.2f}x "
                  f"{r['py'] * 1e9:9.0f} ns {r['py'] / r['literal']:8.1f}x  "
                  f"{'bit for bit' if r['equal'] else 'DIFFERENT'}"
                  f"{'' if r['native'] else ' (no C evaluator here: Python path)'}; "
                  f"{r['c_diff']:.1e}")
    print("ratio: evaluate / the C export called through ctypes (the target: at most 2); "
          "speed-up: Python path / evaluate(k=x)")


def skfuzzy_table(args, rng: np.random.Generator) -> None:
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
