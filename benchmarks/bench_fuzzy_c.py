"""Generated C code vs FuzzySystem.evaluate at batch 1, per evaluation.

For each system: the C code from ``hybridnav.fuzzy.export.to_c`` compiled with ``-O2`` (C99) and
timed inside C (``clock_gettime``, ``--calls`` evaluations over an array of random inputs, best of
``--repeat``); ``FuzzySystem.evaluate`` timed per call with Python floats (batch 1, best of
``--repeat``); the ratio; and the largest difference between the two on those inputs.
Run: ``python benchmarks/bench_fuzzy_c.py [--systems effc-2rule effc-5rule] [--calls 200000]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from hybridnav import fuzzy
from hybridnav.fuzzy.export import c_identifier, to_c

BENCH_MAIN = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "{base}.h"

/* argv: file of N rows of inputs, number of timed calls, repeats.
 * prints: best ns per call, then the N outputs (%.17g) */
int main(int argc, char **argv)
{{
    FILE *f;
    double *x, best = 1e300;
    int n = 0, cap = 1024, i, r, calls, repeat;
    volatile {p}_real sink = 0;
    if (argc != 4) return 2;
    calls = atoi(argv[2]);
    repeat = atoi(argv[3]);
    f = fopen(argv[1], "r");
    if (!f) return 2;
    x = malloc(sizeof(double) * (size_t)cap);
    while (x && fscanf(f, "%lf", &x[n]) == 1) {{
        if (++n == cap) {{ cap *= 2; x = realloc(x, sizeof(double) * (size_t)cap); }}
    }}
    fclose(f);
    if (!x) return 2;
    n /= {P}_N_INPUTS;
    {{
        {p}_real *in = malloc(sizeof({p}_real) * (size_t)(n * {P}_N_INPUTS));
        if (!in) return 2;
        for (i = 0; i < n * {P}_N_INPUTS; ++i) in[i] = ({p}_real)x[i];
        for (r = 0; r < repeat; ++r) {{
            struct timespec t0, t1;
            double dt;
            clock_gettime(CLOCK_MONOTONIC, &t0);
            for (i = 0; i < calls; ++i) sink += {p}_evaluate(in + (i % n) * {P}_N_INPUTS);
            clock_gettime(CLOCK_MONOTONIC, &t1);
            dt = ((double)(t1.tv_sec - t0.tv_sec) * 1e9 + (double)(t1.tv_nsec - t0.tv_nsec)) / calls;
            if (dt < best) best = dt;
        }}
        printf("%.6g\n", best);
        for (i = 0; i < n; ++i) printf("%.17g\n", (double){p}_evaluate(in + i * {P}_N_INPUTS));
        free(in);
    }}
    free(x);
    (void)sink;
    return 0;
}}
"""


def bench(fs: fuzzy.FuzzySystem, n: int, calls: int, repeat: int, cc: str,
          rng: np.random.Generator, workdir: Path) -> dict[str, float]:
    lo = np.array([v.range[0] for v in fs.inputs])
    hi = np.array([v.range[1] for v in fs.inputs])
    X = rng.uniform(lo, hi, (n, len(lo)))

    code = to_c(fs)
    p = c_identifier(code.basename)
    (workdir / f"{code.basename}.h").write_text(code.header)
    (workdir / f"{code.basename}.c").write_text(code.source)
    (workdir / "bench.c").write_text(BENCH_MAIN.format(base=code.basename, p=p, P=p.upper()))
    exe = workdir / f"bench_{code.basename}"
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-o", str(exe),
                    str(workdir / "bench.c"), str(workdir / f"{code.basename}.c")], check=True)
    data = workdir / "inputs.txt"
    np.savetxt(data, X, fmt="%.17g")
    out = subprocess.run([str(exe), str(data), str(calls), str(repeat)], check=True,
                         capture_output=True, text=True).stdout.split()
    t_c = float(out[0]) * 1e-9
    y_c = np.array([float(v) for v in out[1:]])

    names = fs.input_names
    kw = [dict(zip(names, row)) for row in X.tolist()]
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for k in kw:
            fs.evaluate(**k)
        best = min(best, (time.perf_counter() - t0) / len(kw))
    y_py = fs.evaluate(**{name: X[:, j] for j, name in enumerate(names)})
    return {"c": t_c, "py": best, "diff": float(np.max(np.abs(y_c - y_py)))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=fuzzy.builtin_names(),
                    help="built-in names or .json / .fll / .fis paths")
    ap.add_argument("--inputs", type=int, default=2000, help="random input rows per system")
    ap.add_argument("--calls", type=int, default=200000, help="timed C calls per repeat")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cc", default=os.environ.get("CC") or shutil.which("gcc") or "cc")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"{'system':<12} {'C (-O2), per call':>18} {'evaluate, batch 1':>18} "
          f"{'ratio':>8}  max |C - evaluate|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.systems:
            fs = fuzzy.load_any(name)
            r = bench(fs, args.inputs, args.calls, args.repeat, args.cc, rng, Path(tmp))
            print(f"{fs.name:<12} {r['c'] * 1e9:14.0f} ns {r['py'] * 1e6:15.1f} us "
                  f"{r['py'] / r['c']:7.0f}x  {r['diff']:.1e}")


if __name__ == "__main__":
    main()
