"""Standalone C99 code that evaluates a fuzzy system exactly as :meth:`FuzzySystem.evaluate`.

:func:`to_c` returns a header and a source file with no dependencies (not even ``libm``) and no
dynamic allocation. The working arrays live on the stack; their size is fixed at generation time
and printed in the header. The semantics are scikit-fuzzy's and the arithmetic that of
:class:`~hybridnav.fuzzy.engine.CompiledSystem`'s scalar path, so C and Python agree to
rounding (about 1e-15 of the output range in double):

1. a NaN input gives a NaN output (a bit test: it survives ``-ffast-math``); inputs are clipped
   to their range;
2. membership = ``np.interp`` of the term sampled on ``np.linspace(lo, hi, points)``: the tables
   hold the samples and numpy's slopes (17 significant digits, so ``double`` tables are
   bit-exact); the interval is guessed from the uniform grid and corrected against the samples
   (binary search where the grid's arithmetic would not be finite);
3. AND = min, OR = max, NOT = ``1 - x``; a rule's strength is its degree times its weight; an
   output term's cut is the largest strength of its rules;
4. no output term with a positive cut and a positive sample: the output is the default;
5. otherwise the centroid of ``max_t min(c_t, term_t)`` on the output universe upsampled at the
   points where a sampled term crosses its cut (scikit-fuzzy's ``defuzz.centroid`` integrates
   that polyline exactly), from precomputed tables instead of a loop over the universe:

   - the plain-universe integral: with at most
     :data:`~hybridnav.fuzzy.engine.SUBSETS_SCALAR_MAX` terms by the max-min identity over term
     subsets and prefix sums of each subset's sorted samples (one binary search per subset),
     otherwise one weighted pass over the samples; moments about the range's midpoint;
   - the crossing points: at most one per monotone run of a term, found by binary search; each
     adds the closed-form triangle by which it changes its interval's integral;
   - where the whole aggregated area is tiny (below :data:`~hybridnav.fuzzy.engine.TINY_AREA`
     of the output range in double, :data:`TINY_AREA_FLOAT` in float) those identities'
     cancellation would show, and the direct loop (scikit-fuzzy's own) is used.

``double`` is the default. Define ``<PREFIX>_REAL`` as ``float`` when compiling (or generate with
``real="float"``) for single precision: the tables are rounded to float, results then differ from
the double ones by about 1e-6 of the output range; more where float cannot resolve the geometry:
a cut so small that its crossing points fall within float resolution of the samples (2e-3 of the
range at a cut of 2e-6 on a spike term), an output range far from zero relative to its width
(float has 7 digits for both), cuts below float's range (the default is returned). Compile with ``-ffp-contract=off`` where the
compiler would otherwise fuse multiply-adds (GCC in ``-std=gnu*`` mode on FMA hardware) if
bit-for-bit agreement with the Python evaluator matters; agreement to ~1e-12 holds either way.
``benchmarks/bench_fuzzy_c.py`` times it against a hand-written evaluator of the same system.

The source ends with the system it was generated from (a comment: :data:`SYSTEM_MARK`, then the
``hybridnav-fis/1`` JSON in rows): :func:`embedded_system` reads it back, and
:class:`~hybridnav.fuzzy.export.sil.CompiledFIS` regenerates both files from it and refuses to
compile a file that differs (an edited or foreign file is compiled only when trusted explicitly).
"""

from __future__ import annotations

import itertools
import json
import re
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.fuzzy.engine import (
    SUBSETS_SCALAR_MAX,
    TINY_AREA,
    centroid_weights,
    interp_slopes,
    min_sum_table,
    universe,
)
from hybridnav.fuzzy.export._common import check_names, comment_text, description_lines
from hybridnav.fuzzy.export.c_runtime import runtime
from hybridnav.fuzzy.mf import sample
from hybridnav.fuzzy.spec import And, Antecedent, Not, Or, TermRef
from hybridnav.fuzzy.system import FuzzySystem, loads

__all__ = ["CCode", "to_c", "c_identifier", "max_crossings", "monotone_runs",
           "TINY_AREA_FLOAT", "SYSTEM_MARK", "embedded_system"]

#: The line that opens the comment at the end of an exported source holding its system.
SYSTEM_MARK = ("/* hybridnav-system (the fuzzy system this file was generated from: "
               "hybridnav-fis/1 JSON,")
#: Prefix of the rows of that JSON (the rows joined are the JSON text).
_ROW = " *|"
_ROW_WIDTH = 96

#: A float build computes the centroid directly below this fraction of the output range of
#: aggregated area (where the table identities' float rounding would show).
TINY_AREA_FLOAT = 1e-2


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
        ``max over y > 0 of #{i : (f[i] >= y) != (f[i+1] >= y)}``: the crossing points one
        cut can add for this term, never more than ``len(monotone_runs(f))`` (what the C code's
        buffers are sized by). The count only changes at the sample values, and on
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


def _finite(system: FuzzySystem, key: str, **arrays: np.ndarray) -> None:
    """Refuse (naming ``key``) a system whose C tables would hold a non-finite number."""
    for what, a in arrays.items():
        if not np.all(np.isfinite(a)):
            raise HybridnavError(
                f"{system.source + ': ' if system.source else ''}C export: {key}: expected a "
                f"range whose samples and integrals stay finite in double, got one that makes "
                f"the {what} overflow")


def _table(values: Sequence[float], K: str, indent: str = "    ", per_line: int = 4) -> str:
    """Table entries as ``K(literal)``: the macro casts each to the build's real type, so a float
    build has no implicit double-to-float conversion (-Wconversion -Werror clean)."""
    lits = [f"{K}({_lit(v)})" for v in values]
    rows = [", ".join(lits[i:i + per_line]) for i in range(0, len(lits), per_line)]
    return (",\n" + indent).join(rows)


def monotone_runs(f: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs ``(a, b)`` of samples on which ``f`` is monotone (non-strictly).

    Parameters
    ----------
    f : ndarray
        A term sampled on its universe.

    Returns
    -------
    list of (int, int)
        First and last sample of each run; consecutive runs share their end sample, so every
        interval ``[i, i + 1]`` belongs to exactly one run. On a run the test ``f >= y`` flips at
        most once, for any level ``y``; rounding the samples to ``float`` keeps them monotone.
    """
    runs: list[tuple[int, int]] = []
    a, d = 0, 0
    for i in range(len(f) - 1):
        step = int(f[i + 1] > f[i]) - int(f[i + 1] < f[i])
        if step == 0 or d == 0 or step == d:
            d = d or step
            continue
        runs.append((a, i))
        a, d = i, step
    runs.append((a, len(f) - 1))
    return runs


def _uniform_inverse(xs: np.ndarray) -> float:
    """``(M - 1) / (hi - lo)`` for the C interval guess, or 0 (binary search) where it or the
    guess's arithmetic would not be finite and positive in double and in float."""
    with np.errstate(all="ignore"):
        span = float(xs[-1] - xs[0])
        inv = (len(xs) - 1) / span if span > 0 else 0.0
        span32 = np.float32(xs[-1]) - np.float32(xs[0])
        inv32 = np.float32(inv)
        ok = (np.isfinite(inv) and inv > 0 and np.isfinite(inv32) and inv32 > 0
              and np.isfinite(span32) and np.isfinite(span32 * inv32))
    return inv if ok else 0.0


def _slopes(xs: np.ndarray, F: np.ndarray) -> np.ndarray:
    """np.interp's slopes, 0 where two samples coincide (the C code then uses the sample)."""
    with np.errstate(all="ignore"):
        S = interp_slopes(xs, F)
    return np.where(np.isfinite(S), S, 0.0)


def _plain_integral(p: str, K: str, xs: np.ndarray, Fo: np.ndarray,
                    used: Sequence[str]) -> tuple[str, list[str]]:
    """C statements that add the plain-universe area and moment of ``max_t min(cut[t], f_t)``
    to ``area`` and ``mom``, and the tables they read.

    With at most :data:`~hybridnav.fuzzy.engine.SUBSETS_SCALAR_MAX` terms (as the Python
    evaluator's scalar path): the max-min identity over term subsets and prefix sums over each
    subset's sorted values (a binary search and two multiply-adds per subset); otherwise the
    weighted sum over the samples.
    """
    W = centroid_weights(xs - 0.5 * (xs[0] + xs[-1]))  # moments about the midpoint
    T, M = Fo.shape
    if T > SUBSETS_SCALAR_MAX:
        code = (f"    for (i = 0; i < {M}; ++i) {{\n"
                f"        const {p}_real y = {p}_agg(cut, i);\n"
                f"        area += {p}_w[i] * y;\n"
                f"        mom += {p}_w[{M} + i] * y;\n"
                f"    }}\n")
        return code, [f"/* area and moment weights of the samples (trapezoids) */\n"
                      f"static const {p}_real {p}_w[{2 * M}] = {{\n    "
                      f"{_table(W.ravel(), K)}\n}};"]
    lines = ["    /* plain universe: sum over term subsets S of (-1)^(|S|+1) sum_j w_j "
             "min(c_S, g_S[j]), g_S = min of S's terms, c_S = min of their cuts: prefix sums "
             "over the sorted g_S */",
             f"    {p}_real c;"]
    tables = []
    n = 0
    for size in range(1, T + 1):
        for sub in itertools.combinations(range(T), size):
            lv, P, Q = min_sum_table(Fo[list(sub)].min(axis=0), W)
            L = len(lv)
            names = " & ".join(used[t] for t in sub)
            tables.append(f"/* subset {n} ({names}): sorted values; then area P, moment P, area Q,"
                          f" moment Q ({L + 1} each) */\n"
                          f"static const {p}_real {p}_sub{n}_lv[{L}] = {{\n    "
                          f"{_table(lv, K)}\n}};\n"
                          f"static const {p}_real {p}_sub{n}_pq[{4 * (L + 1)}] = {{\n    "
                          f"{_table(np.concatenate([P[0], P[1], Q[0], Q[1]]), K)}\n}};")
            c = f"cut[{sub[0]}]"
            for t in sub[1:]:
                c = f"{p}_min({c}, cut[{t}])"
            op = "+=" if size % 2 else "-="
            q = f"{p}_sub{n}_pq"
            lines += [f"    c = {c};",
                      "    if (c > 0) {",
                      f"        k = {p}_lower_bound({p}_sub{n}_lv, {L}, c);",
                      f"        area {op} {q}[k] + c * {q}[{2 * (L + 1)} + k];",
                      f"        mom {op} {q}[{L + 1} + k] + c * {q}[{3 * (L + 1)} + k];",
                      "    }"]
            n += 1
    return "\n".join(lines) + "\n", tables


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

    # ---- input tables: samples, memberships and np.interp slopes (sample-major)
    leaves: dict[tuple[str, str], int] = {}
    tables: list[str] = []
    fuzz_calls: list[str] = []
    for k, v in enumerate(system.inputs):
        xs = universe(v)
        F = np.stack([sample(t.mf, t.params, xs) for t in v.terms])
        S = _slopes(xs, F)
        _finite(system, f"inputs[{k}].range", samples=xs, memberships=F)
        m, nt = len(xs), len(v.terms)
        k0 = len(leaves)
        for t in v.terms:
            leaves[(v.name, t.name)] = len(leaves)
        tables.append(f"/* input {k}: {v.name}, {m} samples over [{_lit(v.range[0])}, "
                      f"{_lit(v.range[1])}], terms {', '.join(v.term_names())}: "
                      + "; ".join(f"{t.name} = {t.mf} {' '.join(_lit(q) for q in t.params)}"
                                  for t in v.terms) + " */")
        tables.append(f"static const {p}_real {p}_in{k}_x[{m}] = {{\n    {_table(xs, K)}\n}};")
        tables.append(f"static const {p}_real {p}_in{k}_f[{nt * m}] = {{\n    "
                      f"{_table(F.T.ravel(), K, per_line=max(nt, 4 // nt * nt))}\n}};")
        tables.append(f"static const {p}_real {p}_in{k}_s[{nt * m}] = {{\n    "
                      f"{_table(S.T.ravel(), K, per_line=max(nt, 4 // nt * nt))}\n}};")
        fuzz_calls.append(f"    {p}_fuzzify(in[{k}], {p}_in{k}_x, {p}_in{k}_f, {p}_in{k}_s, {m}, "
                          f"{nt}, {K}({_lit(xs[0])}), {K}({_lit(_uniform_inverse(xs))}), "
                          f"mu + {k0});")

    # ---- output tables: the terms some rule names (others never have a cut)
    o = system.output
    xs = universe(o)
    used = [t.name for t in o.terms if any(r.then == t.name for r in system.rules)]
    Fo = np.stack([sample(t.mf, t.params, xs) for t in o.terms if t.name in used])
    So = _slopes(xs, Fo)
    width = float(xs[-1] - xs[0])
    M, T = len(xs), len(used)
    runs = [monotone_runs(f) for f in Fo]
    run0 = np.cumsum([0] + [len(r) for r in runs]).tolist()
    positive = [1 if np.any(f > 0) else 0 for f in Fo]
    tables.append(f"/* output: {o.name}, {M} samples over [{_lit(o.range[0])}, "
                  f"{_lit(o.range[1])}], terms named by rules: {', '.join(used)} */")
    tables.append(f"static const {p}_real {p}_out_x[{M}] = {{\n    {_table(xs, K)}\n}};")
    rows = ",\n".join(f"    /* {name} */\n    {_table(Fo[j], K)}" for j, name in enumerate(used))
    tables.append(f"static const {p}_real {p}_out_f[{T * M}] = {{\n{rows}\n}};")
    rows = ",\n".join(f"    /* {name} */\n    {_table(So[j], K)}" for j, name in enumerate(used))
    tables.append(f"static const {p}_real {p}_out_s[{T * M}] = {{\n{rows}\n}};")
    tables.append(f"static const int {p}_out_positive[{T}] = {{ "
                  f"{', '.join(map(str, positive))} }};")
    tables.append(f"/* monotone runs (first, last sample) of each term: a level crosses a run at "
                  f"most once; term t owns runs run0[t] to run0[t+1] - 1 */\n"
                  f"static const int {p}_out_runs[{2 * run0[-1]}] = {{ "
                  f"{', '.join(f'{a}, {b}' for r in runs for a, b in r)} }};\n"
                  f"static const int {p}_out_run0[{T + 1}] = {{ {', '.join(map(str, run0))} }};")
    _finite(system, "output.range", samples=xs, memberships=Fo,
            **{"centroid weights": centroid_weights(xs)})
    plain, plain_tables = _plain_integral(p, K, xs, Fo, used)
    tables.extend(plain_tables)

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
    n_runs = run0[-1]
    # the frames of evaluate, defuzzify and (where every activation is tiny) the direct centroid
    stack = (n_leaves + T + 3 * n_runs + 16) * real_bytes + 8 * n_runs
    guard = f"{P}_H_INCLUDED"
    safe_name = comment_text(system.name)
    described = "".join(f" * {line}".rstrip() + "\n" for line in
                        ([""] if system.description else []) + description_lines(system.description))
    header = f"""\
/* {base}.h -- fuzzy system '{safe_name}' (hybridnav-fis/1), generated by hybridnav.
 * Standalone C99: no dependencies, no dynamic allocation, no global state (reentrant).
 * Evaluates exactly like hybridnav's FuzzySystem.evaluate (scikit-fuzzy's Mamdani semantics).
 * Stack use of {p}_evaluate: about {stack} bytes with {real}.
 *
 *     {p}_real in[{P}_N_INPUTS];
 *     in[{in_macros[0]}] = ...;
 *     {p}_real out = {p}_evaluate(in);
{described} */
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
 * Do not edit: regenerate with `hybridnav export SYSTEM.json --format c` (the system is at the
 * end of this file; hybridnav verify refuses an edited file unless given --trust).
 * Semantics: scikit-fuzzy's Mamdani inference (see {base}.h). */
#include <stdint.h>  /* freestanding: uint32_t, uint64_t for the NaN test */
#include "{base}.h"

/* a table constant in the build's real type (an explicit conversion: no -Wconversion warning) */
#define {K}(x) (({p}_real)(x))
#define {P}_N_LEAVES {n_leaves}
#define {P}_N_OUT_TERMS {T}
#define {P}_M {M}
#define {P}_EPS (({p}_real)2.220446049250313e-16)  /* numpy's finfo(float).eps */
#define {P}_N_RUNS {n_runs}  /* monotone runs of the output terms: most crossing points */
#define {P}_THIRD {K}({_lit(1.0 / 3.0)})
#define {P}_MID {K}({_lit(0.5 * (xs[0] + xs[-1]))})  /* moments are taken about this point */
/* below this aggregated area the table identities' rounding (about 1e-16 of the output range
 * in double, 1e-7 in float) would matter: the centroid is then computed directly */
#define {P}_TINY (sizeof({p}_real) < sizeof(double) ? {K}({_lit(TINY_AREA_FLOAT * width)}) \
                                                    : {K}({_lit(TINY_AREA * width)}))

{chr(10).join(tables)}
{runtime(p, plain, subsets=T <= SUBSETS_SCALAR_MAX)}
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
    return CCode(base, header, source + _system_comment(system))


def _system_comment(system: FuzzySystem) -> str:
    """The comment that carries ``system`` at the end of the source: compact ASCII JSON with
    ``/`` escaped as ``\\/`` and ``*`` as ``\\u002a`` (so it holds neither a comment's end nor
    its start, nor a trigraph line splice), in rows none of which ends with a space (editors
    strip those) or a backslash (a line splice)."""
    text = json.dumps(system.to_dict(), ensure_ascii=True, allow_nan=False,
                      separators=(",", ":")).replace("/", "\\/").replace("*", "\\u002a")
    rows = []
    i = 0
    while i < len(text):
        j = min(i + _ROW_WIDTH, len(text))
        while j > i + 1 and text[j - 1] in " \\":        # no splice, nothing to strip
            j -= 1
        rows.append(text[i:j])
        i = j
    return (f"\n{SYSTEM_MARK}\n"
            " * slashes and asterisks escaped, in rows): hybridnav regenerates this file and its\n"
            " * header from it, and compiles them only if they are what it writes.\n"
            + "".join(f"{_ROW}{r}\n" for r in rows) + " */\n")


def embedded_system(source: str, where: str) -> FuzzySystem | None:
    """The system a C export's source carries at its end, or None when it carries none.

    Parameters
    ----------
    source : str
        The text of an exported ``.c`` file.
    where : str
        The file, for error messages.

    Returns
    -------
    FuzzySystem or None
        The system :func:`to_c` wrote into ``source``; regenerating from it (with the file's
        base name and real type) gives the export back unless the file was edited.

    Raises
    ------
    HybridnavError
        The comment is there but does not hold a valid ``hybridnav-fis/1`` system (the message
        does not quote the file).
    """
    lines = source.splitlines()
    try:
        k = lines.index(SYSTEM_MARK)
    except ValueError:
        return None
    rows = []
    for line in lines[k + 3:]:
        if not line.startswith(_ROW):
            break
        rows.append(line[len(_ROW):])
    try:
        return loads("".join(rows), where)
    except HybridnavError:
        raise HybridnavError(f"{where}: hybridnav-system: expected the hybridnav-fis/1 JSON of "
                             "the system the file was generated from, got an invalid one") from None
