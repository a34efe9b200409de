"""Generated C code vs a hand-written C evaluator of the same system, and vs FuzzySystem.evaluate.

For each system: the C code from ``hybridnav.fuzzy.export.to_c`` compiled with ``-O2`` (C99) and
timed inside C (``clock_gettime``, ``--calls`` evaluations over an array of random inputs, best of
``--repeat``); for systems of the EFFC family's shape (inputs ``dtheta`` and ``alpha`` and output
``w``, each with a ``low`` zmf and a ``high`` smf; rules ANDs of input terms) the same timing of
:data:`HAND`, the evaluator an engineer would write for it by hand (closed-form memberships, the
output sampled once, one pass over the universe inserting scikit-fuzzy's crossing points and
integrating each segment in closed form), compiled in the same program; ``FuzzySystem.evaluate``
timed per call with Python floats (batch 1, best of ``--repeat``: after its first few
hundred calls its C evaluator, where one is available; ``bench_fuzzy.py`` times both paths); the
ratios (generated over hand-written is the issue's target: at most 2); and the largest
differences from ``evaluate``
(the hand-written one evaluates the input terms in closed form where scikit-fuzzy interpolates
their samples, so it differs by the sampling error, about 1e-4).
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
from hybridnav.fuzzy.spec import And, TermRef

#: The hand-written evaluator; {constants} and {rules} are filled from the system (the numbers
#: and rule lines a person would type), everything else is fixed.
HAND = r"""
#define HAS_HAND 1
#define HAND_CALL(v) hand_evaluate(v)
#define HAND_CALL_DISCRETE(v) hand_evaluate_discrete(v)
#define HAND_M {M}
{constants}

static double hand_zmf(double x, double a, double b)  /* skfuzzy.zmf */
{{
    double t;
    if (x <= a) return 1.0;
    if (x >= b) return 0.0;
    if (x < 0.5 * (a + b)) {{ t = (x - a) / (b - a); return 1.0 - 2.0 * t * t; }}
    t = (x - b) / (b - a);
    return 2.0 * t * t;
}}

static double hand_smf(double x, double a, double b)  /* skfuzzy.smf */
{{
    double t;
    if (x <= a) return 0.0;
    if (x >= b) return 1.0;
    if (x <= 0.5 * (a + b)) {{ t = (x - a) / (b - a); return 2.0 * t * t; }}
    t = (x - b) / (b - a);
    return 1.0 - 2.0 * t * t;
}}

static double hand_min(double a, double b) {{ return b < a ? b : a; }}
static double hand_max(double a, double b) {{ return b > a ? b : a; }}
static double hand_clip(double x, double lo, double hi) {{ return x < lo ? lo : x > hi ? hi : x; }}

static double hand_x[HAND_M], hand_low[HAND_M], hand_high[HAND_M];

static void hand_init(void)  /* the output terms sampled on np.linspace(W_LO, W_HI, HAND_M) */
{{
    int i;
    const double step = (W_HI - W_LO) / (HAND_M - 1);
    for (i = 0; i < HAND_M; ++i) {{
        hand_x[i] = i == HAND_M - 1 ? W_HI : W_LO + i * step;
        hand_low[i] = hand_zmf(hand_x[i], W_LOW_A, W_LOW_B);
        hand_high[i] = hand_smf(hand_x[i], W_HIGH_A, W_HIGH_B);
    }}
}}

/* area and first moment of the segment (x1, y1)-(x2, y2) */
#define HAND_SEG(x1, y1, x2, y2) do {{ const double h_ = (x2) - (x1);                         \
    area += 0.5 * h_ * ((y1) + (y2));                                                        \
    mom += h_ / 6.0 * ((x1) * (2.0 * (y1) + (y2)) + (x2) * ((y1) + 2.0 * (y2))); }} while (0)

/* np.interp(v, linspace(lo, hi, m), term sampled there): the term in closed form at the two
 * neighbouring samples, interpolated (scikit-fuzzy interpolates the sampled term) */
static double hand_term(double v, double lo, double hi, int m, int z, double a, double b)
{{
    const double step = (hi - lo) / (m - 1);
    double x0, x1, f0, f1;
    int j;
    v = hand_clip(v, lo, hi);
    j = (int)((v - lo) / step);
    if (j > m - 2) j = m - 2;
    x0 = j * step + lo;
    x1 = j + 1 == m - 1 ? hi : (j + 1) * step + lo;
    f0 = z ? hand_zmf(x0, a, b) : hand_smf(x0, a, b);
    f1 = z ? hand_zmf(x1, a, b) : hand_smf(x1, a, b);
    return v == x0 ? f0 : (f1 - f0) / (x1 - x0) * (v - x0) + f0;
}}

/* the cuts of the output terms low and high; 0 if no rule fires */
static int hand_cuts(const double in[2], double *low, double *high)
{{
    const double d = in[D_INDEX], a = in[A_INDEX];
    const double dtheta_low = hand_term(d, D_LO, D_HI, D_M, 1, D_LOW_A, D_LOW_B);
    const double dtheta_high = hand_term(d, D_LO, D_HI, D_M, 0, D_HIGH_A, D_HIGH_B);
    const double alpha_low = hand_term(a, A_LO, A_HI, A_M, 1, A_LOW_A, A_LOW_B);
    const double alpha_high = hand_term(a, A_LO, A_HI, A_M, 0, A_HIGH_A, A_HIGH_B);
    *low = 0;
    *high = 0;
{rules}
    (void)dtheta_low; (void)dtheta_high; (void)alpha_low; (void)alpha_high;
    return *low > 0 || *high > 0;
}}

/* scikit-fuzzy's centroid: one pass over the universe, inserting the points where a term
 * crosses its cut, each segment integrated in closed form */
double hand_evaluate(const double in[2])
{{
    double low, high, area = 0, mom = 0, px, py;
    int i;
    if (in[0] != in[0] || in[1] != in[1]) return in[0] + in[1];
    if (!hand_cuts(in, &low, &high)) return W_DEFAULT;
    px = hand_x[0];
    py = hand_max(hand_min(low, hand_low[0]), hand_min(high, hand_high[0]));
    for (i = 1; i < HAND_M; ++i) {{
        const double x0 = hand_x[i - 1], x1 = hand_x[i];
        const double l0 = hand_low[i - 1], l1 = hand_low[i], h0 = hand_high[i - 1], h1 = hand_high[i];
        double q[2], y;
        int n = 0, k;
        if (low > 0 && (l0 >= low) != (l1 >= low)) q[n++] = x0 + (low - l0) * (x1 - x0) / (l1 - l0);
        if (high > 0 && (h0 >= high) != (h1 >= high)) q[n++] = x0 + (high - h0) * (x1 - x0) / (h1 - h0);
        if (n == 2 && q[1] < q[0]) {{ y = q[0]; q[0] = q[1]; q[1] = y; }}
        for (k = 0; k < n; ++k) {{
            const double t = (q[k] - x0) / (x1 - x0);
            y = hand_max(hand_min(low, l0 + t * (l1 - l0)), hand_min(high, h0 + t * (h1 - h0)));
            HAND_SEG(px, py, q[k], y);
            px = q[k];
            py = y;
        }}
        y = hand_max(hand_min(low, l1), hand_min(high, h1));
        HAND_SEG(px, py, x1, y);
        px = x1;
        py = y;
    }}
    return mom / (area > 2.220446049250313e-16 ? area : 2.220446049250313e-16);
}}

/* the textbook shortcut: sum x y / sum y over the universe samples, no crossing points. Not
 * scikit-fuzzy's centroid (it differs by up to a few 1e-3), timed as the lower bound */
double hand_evaluate_discrete(const double in[2])
{{
    double low, high, sy = 0, sxy = 0;
    int i;
    if (in[0] != in[0] || in[1] != in[1]) return in[0] + in[1];
    if (!hand_cuts(in, &low, &high)) return W_DEFAULT;
    for (i = 0; i < HAND_M; ++i) {{
        const double y = hand_max(hand_min(low, hand_low[i]), hand_min(high, hand_high[i]));
        sy += y;
        sxy += hand_x[i] * y;
    }}
    return sxy / sy;
}}
"""

NO_HAND = r"""
#define HAS_HAND 0
#define HAND_CALL(v) 0.0
#define HAND_CALL_DISCRETE(v) 0.0
static void hand_init(void) {}
"""

BENCH_MAIN = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "{base}.h"
{hand}
/* argv: file of N rows of inputs, number of timed calls, repeats.
 * prints: best ns per call of the generated code, of the hand-written one and of its discrete
 * variant (0 if none), then per row the three outputs (%.17g) */
static volatile double sink;

/* ns per call of the generated (which = 0), hand-written (1) or discrete hand-written (2)
 * evaluator */
static double time_calls(const {p}_real *in, int n, int calls, int which)
{{
    struct timespec t0, t1;
    int i;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    if (which == 0)
        for (i = 0; i < calls; ++i) sink += {p}_evaluate(in + (i % n) * {P}_N_INPUTS);
    else if (which == 1)
        for (i = 0; i < calls; ++i) sink += HAND_CALL(in + (i % n) * {P}_N_INPUTS);
    else
        for (i = 0; i < calls; ++i) sink += HAND_CALL_DISCRETE(in + (i % n) * {P}_N_INPUTS);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    return ((double)(t1.tv_sec - t0.tv_sec) * 1e9 + (double)(t1.tv_nsec - t0.tv_nsec)) / calls;
}}

int main(int argc, char **argv)
{{
    FILE *f;
    double *x, best = 1e300, best_hand = 1e300, best_discrete = 1e300;
    int n = 0, cap = 1024, i, r, calls, repeat;
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
        hand_init();
        for (r = 0; r < repeat; ++r) {{
            double dt;
            dt = time_calls(in, n, calls, 0);
            if (dt < best) best = dt;
            if (HAS_HAND) {{
                dt = time_calls(in, n, calls, 1);
                if (dt < best_hand) best_hand = dt;
                dt = time_calls(in, n, calls, 2);
                if (dt < best_discrete) best_discrete = dt;
            }}
        }}
        printf("%.6g\n%.6g\n%.6g\n", best, HAS_HAND ? best_hand : 0.0,
               HAS_HAND ? best_discrete : 0.0);
        for (i = 0; i < n; ++i)
            printf("%.17g %.17g %.17g\n", (double){p}_evaluate(in + i * {P}_N_INPUTS),
                   HAND_CALL(in + i * {P}_N_INPUTS), HAND_CALL_DISCRETE(in + i * {P}_N_INPUTS));
        free(in);
    }}
    free(x);
    return 0;
}}
"""


def hand_source(fs: fuzzy.FuzzySystem) -> str | None:
    """:data:`HAND` for ``fs``, or None where ``fs`` is not of the EFFC family's shape."""
    def shaped(v):
        return [(t.name, t.mf) for t in v.terms] == [("low", "zmf"), ("high", "smf")]

    names = fs.input_names
    if (sorted(names) != ["alpha", "dtheta"] or fs.output.name != "w"
            or not all(shaped(v) for v in (*fs.inputs, fs.output))):
        return None
    consts = {"W_DEFAULT": fs.output.default, "W_LO": fs.output.range[0],
              "W_HI": fs.output.range[1]}
    for key, v in (("D", fs.inputs[names.index("dtheta")]), ("A", fs.inputs[names.index("alpha")]),
                   ("W", fs.output)):
        if key != "W":
            consts.update({f"{key}_INDEX": names.index(v.name), f"{key}_LO": v.range[0],
                           f"{key}_HI": v.range[1], f"{key}_M": v.points})
        for t in v.terms:
            consts[f"{key}_{t.name.upper()}_A"], consts[f"{key}_{t.name.upper()}_B"] = t.params
    rules = []
    for r in fs.rules:
        a = r.antecedent
        items = a.items if isinstance(a, And) else (a,)
        if not all(isinstance(i, TermRef) for i in items):
            return None
        s = f"{items[0].input}_{items[0].term}"
        for i in items[1:]:
            s = f"hand_min({s}, {i.input}_{i.term})"
        if r.weight != 1.0:
            s = f"{s} * {r.weight!r}"
        rules.append(f"    *{r.then} = hand_max(*{r.then}, {s});")
    constants = "\n".join(f"#define {k} {v!r}" for k, v in consts.items())
    return HAND.format(M=fs.output.points, constants=constants, rules="\n".join(rules))


def bench(fs: fuzzy.FuzzySystem, n: int, calls: int, repeat: int, cc: str,
          rng: np.random.Generator, workdir: Path) -> dict[str, float]:
    lo = np.array([v.range[0] for v in fs.inputs])
    hi = np.array([v.range[1] for v in fs.inputs])
    X = rng.uniform(lo, hi, (n, len(lo)))

    code = to_c(fs)
    p = c_identifier(code.basename)
    hand = hand_source(fs)
    (workdir / f"{code.basename}.h").write_text(code.header)
    (workdir / f"{code.basename}.c").write_text(code.source)
    (workdir / "bench.c").write_text(BENCH_MAIN.format(base=code.basename, p=p, P=p.upper(),
                                                       hand=hand or NO_HAND))
    exe = workdir / f"bench_{code.basename}"
    subprocess.run([cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-o", str(exe),
                    str(workdir / "bench.c"), str(workdir / f"{code.basename}.c")], check=True)
    data = workdir / "inputs.txt"
    np.savetxt(data, X, fmt="%.17g")
    out = subprocess.run([str(exe), str(data), str(calls), str(repeat)], check=True,
                         capture_output=True, text=True).stdout.split()
    t_c, t_hand, t_disc = (float(v) * 1e-9 for v in out[:3])
    y = np.array([float(v) for v in out[3:]]).reshape(-1, 3)

    names = fs.input_names
    kw = [dict(zip(names, row)) for row in X.tolist()]
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for k in kw:
            fs.evaluate(**k)
        best = min(best, (time.perf_counter() - t0) / len(kw))
    y_py = fs.evaluate(**{name: X[:, j] for j, name in enumerate(names)})
    return {"c": t_c, "py": best, "diff": float(np.max(np.abs(y[:, 0] - y_py))),
            "hand": t_hand if hand else np.nan,
            "hand_diff": float(np.max(np.abs(y[:, 1] - y_py))) if hand else np.nan,
            "discrete": t_disc if hand else np.nan,
            "discrete_diff": float(np.max(np.abs(y[:, 2] - y_py))) if hand else np.nan}


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
    print(f"{'system':<12} {'generated C':>12} {'hand, exact':>12} {'ratio':>6} "
          f"{'hand, discrete':>15} {'ratio':>6} {'evaluate':>10} {'ratio':>6}   max |x - evaluate|: "
          "generated, hand exact, hand discrete")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.systems:
            fs = fuzzy.load_any(name)
            r = bench(fs, args.inputs, args.calls, args.repeat, args.cc, rng, Path(tmp))
            if np.isfinite(r["hand"]):
                hand = (f"{r['hand'] * 1e9:9.0f} ns {r['c'] / r['hand']:5.2f}x "
                        f"{r['discrete'] * 1e9:12.0f} ns {r['c'] / r['discrete']:5.2f}x")
            else:
                hand = f"{'n/a':>12} {'':>6} {'n/a':>15} {'':>6}"
            print(f"{fs.name:<12} {r['c'] * 1e9:9.0f} ns {hand} {r['py'] * 1e6:7.1f} us "
                  f"{r['py'] / r['c']:5.0f}x   {r['diff']:.1e}, {r['hand_diff']:.1e}, "
                  f"{r['discrete_diff']:.1e}")
    print("ratios: generated / hand-written (the target: at most 2); evaluate / generated")

if __name__ == "__main__":
    main()
