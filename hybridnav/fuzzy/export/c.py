"""Standalone C99 code that evaluates a fuzzy system exactly as :meth:`FuzzySystem.evaluate`.

:func:`to_c` returns a header and a source file with no dependencies (not even ``libm``) and no
dynamic allocation. The working arrays live on the stack; their size is fixed at generation time
and printed in the header. The arithmetic is scikit-fuzzy's, step for step:

1. a NaN input gives a NaN output; inputs are clipped to their range;
2. membership = ``np.interp`` of the term sampled on ``np.linspace(lo, hi, points)``: the tables
   are the sampled values (17 significant digits, so ``double`` tables are bit-exact), the
   interval is found by binary search and the value is ``slope * (x - x[j]) + f[j]`` with
   ``slope = (f[j+1] - f[j]) / (x[j+1] - x[j])``, numpy's formula;
3. AND = min, OR = max, NOT = ``1 - x``; a rule's strength is its degree times its weight; an
   output term's cut is the largest strength of its rules;
4. no output term with a positive cut and a positive sample: the output is the default;
5. otherwise the output universe gets, for every term with cut ``c > 0``, the points where the
   sampled term crosses ``c`` (``x[i] + (c - f[i]) * (x[i+1] - x[i]) / (f[i+1] - f[i])`` on
   every interval where ``f >= c`` flips); the aggregated value at every point is
   ``max_t min(c_t, interp(point))``; the result is scikit-fuzzy's ``defuzz.centroid`` of that
   polyline, ``sum(moment * area) / fmax(sum(area), DBL_EPSILON)``.

``double`` is the default. Define ``<PREFIX>_REAL`` as ``float`` when compiling (or generate with
``real="float"``) for single precision: the tables are rounded to float, results then differ from
the double ones by about 1e-6 of the output range. Compile with ``-ffp-contract=off`` where the
compiler would otherwise fuse multiply-adds (GCC in ``-std=gnu*`` mode on FMA hardware) if
bit-for-bit agreement with the Python evaluator matters; agreement to ~1e-12 holds either way.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.fuzzy.engine import universe
from hybridnav.fuzzy.export._common import check_names, comment_text
from hybridnav.fuzzy.mf import sample
from hybridnav.fuzzy.spec import And, Antecedent, Not, Or, TermRef
from hybridnav.fuzzy.system import FuzzySystem

__all__ = ["CCode", "to_c", "c_identifier", "max_crossings"]


class CCode(NamedTuple):
    """Generated C code: ``basename.h`` and ``basename.c``."""

    #: File name stem of both files; the source includes ``"<basename>.h"``.
    basename: str
    #: The header text.
    header: str
    #: The source text.
    source: str


def c_identifier(name: str) -> str:
    """A C identifier made from ``name``: other characters become ``_``; a leading digit gets
    ``fis_`` in front; lower case.

    Parameters
    ----------
    name : str

    Returns
    -------
    str
    """
    s = re.sub(r"[^A-Za-z0-9_]", "_", name).lower()
    if not s or s[0].isdigit():
        s = f"fis_{s}"
    return s


def max_crossings(f: np.ndarray) -> int:
    """Most intervals where the sampled ``f`` crosses one level ``y > 0``.

    Parameters
    ----------
    f : ndarray
        A term sampled on its universe.

    Returns
    -------
    int
        ``max over y > 0 of #{i : (f[i] >= y) != (f[i+1] >= y)}``: the size the C crossing
        buffer needs for this term. The count only changes at the sample values, and on
        ``(levels[k-1], levels[k]]`` equals its value at ``levels[k]``.
    """
    levels = np.unique(f[f > 0])
    best = 0
    for s in range(0, len(levels), 256):
        ge = f[:, None] >= levels[None, s:s + 256]
        best = max(best, int((ge[1:] != ge[:-1]).sum(axis=0).max()))
    return best


def _lit(x: float) -> str:
    """A C floating literal that reads back as exactly ``x`` (as a double)."""
    s = repr(float(x))
    if "e" not in s and "." not in s and "n" not in s:  # pragma: no cover - repr has '.' or 'e'
        s += ".0"
    return s


def _table(values: Sequence[float], K: str, indent: str = "    ", per_line: int = 4) -> str:
    """Table entries as ``K(literal)``: the macro casts each to the build's real type, so a float
    build has no implicit double-to-float conversion (-Wconversion -Werror clean)."""
    lits = [f"{K}({_lit(v)})" for v in values]
    rows = [", ".join(lits[i:i + per_line]) for i in range(0, len(lits), per_line)]
    return (",\n" + indent).join(rows)


def to_c(system: FuzzySystem, basename: str | None = None, *, real: str = "double") -> CCode:
    """Generate the C99 header and source for ``system``.

    Parameters
    ----------
    system : FuzzySystem
    basename : str, optional
        File name stem (default: :func:`c_identifier` of the system's name). The functions and
        macros are prefixed with :func:`c_identifier` of it: ``<p>_evaluate``,
        ``<P>_N_INPUTS``, ``<P>_IN_<INPUT>``.
    real : {"double", "float"}
        The default of the ``<P>_REAL`` macro.

    Returns
    -------
    CCode
        ``(basename, header, source)``.

    Raises
    ------
    HybridnavError
        Bad ``basename``/``real``, a variable or term name that is not an identifier (naming its
        key), or two inputs whose names give the same C macro.
    """
    if real not in ("double", "float"):
        raise HybridnavError(f"C export: real must be 'double' or 'float', got {real!r}")
    check_names(system, "c")
    base = basename if basename is not None else c_identifier(system.name)
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", base) or base in (".", ".."):
        raise HybridnavError(f"C export: invalid file base name {base!r}: expected letters, "
                             "digits, '_', '.' or '-' (it is written into #include and comments)")
    p = c_identifier(base)
    P = p.upper()
    R = f"{P}_REAL"
    K = f"{P}_K"
    in_macros = [f"{P}_IN_{c_identifier(v.name).upper()}" for v in system.inputs]
    if len(set(in_macros)) != len(in_macros):
        raise HybridnavError(f"{system.source + ': ' if system.source else ''}C export: input "
                             f"names {[v.name for v in system.inputs]} give clashing C macros "
                             f"{in_macros}")
    n_in = len(system.inputs)

    # ---- input tables
    leaves: dict[tuple[str, str], int] = {}
    tables: list[str] = []
    fuzz_calls: list[str] = []
    for k, v in enumerate(system.inputs):
        xs = universe(v)
        F = np.stack([sample(t.mf, t.params, xs) for t in v.terms])
        m, nt = len(xs), len(v.terms)
        k0 = len(leaves)
        for t in v.terms:
            leaves[(v.name, t.name)] = len(leaves)
        tables.append(f"/* input {k}: {v.name}, {m} samples over [{_lit(v.range[0])}, "
                      f"{_lit(v.range[1])}], terms {', '.join(v.term_names())} */")
        tables.append(f"static const {p}_real {p}_in{k}_x[{m}] = {{\n    {_table(xs, K)}\n}};")
        rows = ",\n".join(f"    /* {t.name} ({t.mf} {' '.join(_lit(q) for q in t.params)}) */\n"
                          f"    {_table(F[j], K)}" for j, t in enumerate(v.terms))
        tables.append(f"static const {p}_real {p}_in{k}_f[{nt * m}] = {{\n{rows}\n}};")
        fuzz_calls.append(f"    {p}_fuzzify(in[{k}], {p}_in{k}_x, {p}_in{k}_f, {m}, {nt}, "
                          f"mu + {k0});")

    # ---- output tables: the terms some rule names (others never have a cut)
    o = system.output
    xs = universe(o)
    used = [t.name for t in o.terms if any(r.then == t.name for r in system.rules)]
    Fo = np.stack([sample(t.mf, t.params, xs) for t in o.terms if t.name in used])
    M, T = len(xs), len(used)
    # float tables may cross a level at other intervals than the double ones
    n_cross = max(sum(max(max_crossings(f), max_crossings(f.astype(np.float32).astype(float)))
                      for f in Fo), 1)
    positive = [1 if np.any(f > 0) else 0 for f in Fo]
    tables.append(f"/* output: {o.name}, {M} samples over [{_lit(o.range[0])}, "
                  f"{_lit(o.range[1])}], terms named by rules: {', '.join(used)} */")
    tables.append(f"static const {p}_real {p}_out_x[{M}] = {{\n    {_table(xs, K)}\n}};")
    rows = ",\n".join(f"    /* {name} */\n    {_table(Fo[j], K)}" for j, name in enumerate(used))
    tables.append(f"static const {p}_real {p}_out_f[{T * M}] = {{\n{rows}\n}};")
    tables.append(f"static const int {p}_out_positive[{T}] = {{ "
                  f"{', '.join(map(str, positive))} }};")

    # ---- rules
    n_leaves = len(leaves)

    def expr(a: Antecedent) -> str:
        if isinstance(a, TermRef):
            return f"mu[{leaves[(a.input, a.term)]}]"
        if isinstance(a, Not):
            return f"(({p}_real)1 - {expr(a.item)})"
        fn = f"{p}_min" if isinstance(a, And) else f"{p}_max"
        assert isinstance(a, (And, Or))
        out = expr(a.items[0])
        for it in a.items[1:]:
            out = f"{fn}({out}, {expr(it)})"
        return out

    rule_lines: list[str] = []
    first = [True] * T
    for j, r in enumerate(system.rules):
        t = used.index(r.then)
        s = expr(r.antecedent)
        if r.weight != 1.0:
            s = f"{s} * ({p}_real){_lit(r.weight)}"
        rule_lines.append(f"    /* rule {j}: -> {r.then}, weight {_lit(r.weight)} */")
        if first[t]:
            rule_lines.append(f"    cut[{t}] = {s};")
            first[t] = False
        else:
            rule_lines.append(f"    s = {s};")
            rule_lines.append(f"    if (s > cut[{t}]) cut[{t}] = s;")

    s_decl = f"\n    {p}_real s;" if any(ln.startswith("    s = ") for ln in rule_lines) else ""
    real_bytes = 8 if real == "double" else 4
    stack = (n_leaves + T + n_cross + 2 * (M + n_cross)) * real_bytes
    guard = f"{P}_H_INCLUDED"
    safe_name = comment_text(system.name)
    header = f"""\
/* {base}.h -- fuzzy system '{safe_name}' (hybridnav-fis/1), generated by hybridnav.
 * Standalone C99: no dependencies, no dynamic allocation, no global state (reentrant).
 * Evaluates exactly like hybridnav's FuzzySystem.evaluate (scikit-fuzzy's Mamdani semantics).
 * Stack use of {p}_evaluate: about {stack} bytes with {real}.
 *
 *     {p}_real in[{P}_N_INPUTS];
 *     in[{in_macros[0]}] = ...;
 *     {p}_real out = {p}_evaluate(in);
 */
#ifndef {guard}
#define {guard}

#ifdef __cplusplus
extern "C" {{
#endif

/* The floating-point type: define {R} as float (for every file that includes this header,
 * and {base}.c) for single precision. */
#ifndef {R}
#define {R} {real}
#endif
typedef {R} {p}_real;

/* Number of inputs, and the index of each input in the array given to {p}_evaluate. */
#define {P}_N_INPUTS {n_in}
{chr(10).join(f"#define {m} {k}  /* {v.name}: range [{_lit(v.range[0])}, {_lit(v.range[1])}] */"
              for k, (m, v) in enumerate(zip(in_macros, system.inputs)))}

/* Output '{o.name}', range [{_lit(o.range[0])}, {_lit(o.range[1])}]; returned when no rule fires: */
#define {P}_DEFAULT (({p}_real){_lit(o.default)})

/* The crisp output for crisp inputs (in[{P}_IN_...]). Inputs outside their range count as
 * the nearest end; a NaN input gives NaN. */
{p}_real {p}_evaluate(const {p}_real in[{P}_N_INPUTS]);

#ifdef __cplusplus
}}
#endif

#endif /* {guard} */
"""

    source = f"""\
/* {base}.c -- fuzzy system '{safe_name}' (hybridnav-fis/1), generated by hybridnav.
 * Do not edit: regenerate with `hybridnav export SYSTEM.json --format c`.
 * Semantics: scikit-fuzzy's Mamdani inference (see {base}.h). */
#include <stdint.h>  /* freestanding: uint32_t, uint64_t for the NaN test */
#include "{base}.h"

/* a table constant in the build's real type (an explicit conversion: no -Wconversion warning) */
#define {K}(x) (({p}_real)(x))
#define {P}_N_LEAVES {n_leaves}
#define {P}_N_OUT_TERMS {T}
#define {P}_M {M}
#define {P}_N_CROSS {n_cross}  /* most crossing points the output terms can add */
#define {P}_EPS (({p}_real)2.220446049250313e-16)  /* numpy's finfo(float).eps */

{chr(10).join(tables)}

/* NaN by its bits (exponent all ones, mantissa not zero): -ffast-math may drop a v != v test,
 * it cannot drop this one */
static int {p}_isnan({p}_real v)
{{
    union {{ {p}_real r; uint32_t u32; uint64_t u64; }} b;
    b.u64 = 0;
    b.r = v;
    if (sizeof v == sizeof(uint32_t))
        return (b.u32 & 0x7fffffffu) > 0x7f800000u;
    return (b.u64 & 0x7fffffffffffffffu) > 0x7ff0000000000000u;
}}

static {p}_real {p}_min({p}_real a, {p}_real b) {{ return b < a ? b : a; }}
static {p}_real {p}_max({p}_real a, {p}_real b) {{ return b > a ? b : a; }}

/* largest j with x[j] <= v, for x[0] <= v <= x[m-1] */
static int {p}_interval(const {p}_real *x, int m, {p}_real v)
{{
    int lo = 0, hi = m - 1;
    if (v >= x[m - 1]) return m - 1;
    while (hi - lo > 1) {{
        int mid = lo + (hi - lo) / 2;
        if (x[mid] <= v) lo = mid; else hi = mid;
    }}
    return lo;
}}

/* np.interp(v, x, f) for x[0] <= v <= x[m-1] */
static {p}_real {p}_interp(const {p}_real *x, const {p}_real *f, int m, {p}_real v)
{{
    int j;
    {p}_real slope;
    if (v <= x[0]) return f[0];
    if (v >= x[m - 1]) return f[m - 1];
    j = {p}_interval(x, m, v);
    if (x[j] == v) return f[j];
    slope = (f[j + 1] - f[j]) / (x[j + 1] - x[j]);
    return slope * (v - x[j]) + f[j];
}}

/* memberships of the clipped input v in the nt terms sampled in f (term-major, m samples) */
static void {p}_fuzzify({p}_real v, const {p}_real *x, const {p}_real *f, int m, int nt,
                        {p}_real *mu)
{{
    int j, t;
    if (v < x[0]) v = x[0];
    if (v > x[m - 1]) v = x[m - 1];
    j = {p}_interval(x, m, v);
    for (t = 0; t < nt; ++t) {{
        const {p}_real *ft = f + t * m;
        if (j == m - 1 || x[j] == v) {{
            mu[t] = ft[j];
        }} else {{
            {p}_real slope = (ft[j + 1] - ft[j]) / (x[j + 1] - x[j]);
            mu[t] = slope * (v - x[j]) + ft[j];
        }}
    }}
}}

/* centroid of max_t min(cut[t], term t) on the universe upsampled at the cut crossings */
static {p}_real {p}_defuzzify(const {p}_real cut[{P}_N_OUT_TERMS])
{{
    {p}_real px[{P}_N_CROSS] = {{0}};
    {p}_real ux[{P}_M + {P}_N_CROSS], uy[{P}_M + {P}_N_CROSS];
    {p}_real sum_ma = 0, sum_a = 0;
    int t, i, k, n = 0, m = 0, fired = 0;
    const {p}_real *x = {p}_out_x;

    for (t = 0; t < {P}_N_OUT_TERMS; ++t)
        if (cut[t] > 0 && {p}_out_positive[t]) fired = 1;
    if (!fired) return {P}_DEFAULT;

    /* crossing points of every term with a positive cut (skfuzzy's _interp_universe_fast) */
    for (t = 0; t < {P}_N_OUT_TERMS; ++t) {{
        const {p}_real c = cut[t], *f = {p}_out_f + t * {P}_M;
        if (!(c > 0)) continue;
        for (i = 0; i + 1 < {P}_M; ++i) {{
            if ((f[i] >= c) != (f[i + 1] >= c) && n < {P}_N_CROSS)
                px[n++] = x[i] + (c - f[i]) * (x[i + 1] - x[i]) / (f[i + 1] - f[i]);
        }}
    }}
    for (i = 1; i < n; ++i) {{  /* insertion sort: few points */
        {p}_real v = px[i];
        for (k = i; k > 0 && px[k - 1] > v; --k) px[k] = px[k - 1];
        px[k] = v;
    }}
    /* merge with the universe; aggregated membership at every point */
    i = 0;
    k = 0;
    while (i < {P}_M || k < n) {{
        {p}_real v, y = 0;
        if (k >= n || (i < {P}_M && x[i] <= px[k])) {{
            v = x[i];
            for (t = 0; t < {P}_N_OUT_TERMS; ++t)
                if (cut[t] > 0) y = {p}_max(y, {p}_min(cut[t], {p}_out_f[t * {P}_M + i]));
            ++i;
        }} else {{
            v = px[k];
            for (t = 0; t < {P}_N_OUT_TERMS; ++t)
                if (cut[t] > 0)
                    y = {p}_max(y, {p}_min(cut[t], {p}_interp(x, {p}_out_f + t * {P}_M, {P}_M, v)));
            ++k;
        }}
        ux[m] = v;
        uy[m] = y;
        ++m;
    }}
    /* skfuzzy.defuzz.centroid */
    for (i = 1; i < m; ++i) {{
        const {p}_real x1 = ux[i - 1], x2 = ux[i], y1 = uy[i - 1], y2 = uy[i];
        {p}_real moment, area;
        if ((y1 == y2 && y2 == 0) || x1 == x2) continue;
        if (y1 == y2) {{
            moment = ({p}_real)0.5 * (x1 + x2);
            area = (x2 - x1) * y1;
        }} else if (y1 == 0 && y2 != 0) {{
            moment = ({p}_real)2.0 / ({p}_real)3.0 * (x2 - x1) + x1;
            area = ({p}_real)0.5 * (x2 - x1) * y2;
        }} else if (y2 == 0 && y1 != 0) {{
            moment = ({p}_real)1.0 / ({p}_real)3.0 * (x2 - x1) + x1;
            area = ({p}_real)0.5 * (x2 - x1) * y1;
        }} else {{
            moment = ({p}_real)2.0 / ({p}_real)3.0 * (x2 - x1) * (y2 + ({p}_real)0.5 * y1)
                     / (y1 + y2) + x1;
            area = ({p}_real)0.5 * (x2 - x1) * (y1 + y2);
        }}
        sum_ma += moment * area;
        sum_a += area;
    }}
    return sum_ma / (sum_a > {P}_EPS ? sum_a : {P}_EPS);
}}

{p}_real {p}_evaluate(const {p}_real in[{P}_N_INPUTS])
{{
    {p}_real mu[{P}_N_LEAVES];
    {p}_real cut[{P}_N_OUT_TERMS];{s_decl}
    int i;
    for (i = 0; i < {P}_N_INPUTS; ++i)
        if ({p}_isnan(in[i])) return in[i];  /* NaN in, NaN out (also under -ffast-math) */
{chr(10).join(fuzz_calls)}
{chr(10).join(rule_lines)}
    return {p}_defuzzify(cut);
}}
"""
    return CCode(base, header, source)
