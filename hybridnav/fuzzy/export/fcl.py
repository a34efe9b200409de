"""IEC 61131-7 Fuzzy Control Language (FCL) export.

Every term is a point list ``TERM name := (x1, y1) (x2, y2) ... ;`` (piecewise linear, constant
beyond the first and last point), the form the standard defines, spanning the variable's
``RANGE``. The points cover exactly ``[lo, hi]``, so an input outside the range counts as its
nearest end, which is hybridnav's clipping. Triangles and trapezoids are exact (a step, e.g. a
``trimf`` with ``a == b`` inside the range, is two points with the same ``x``). Curved terms are
approximated with a maximum error of :data:`FCL_TOLERANCE` in membership:

- ``zmf`` / ``smf``: :data:`ZS_SEGMENTS` equal segments between ``a`` and ``b``: the curve is two
  parabolas with ``|f''| = 4 / (b - a)^2``, so linear interpolation over ``M`` equal segments is
  off by at most ``f'' h^2 / 8 = 1 / (2 M^2)`` (``M = 64``: ``1.2e-4``);
- ``gaussmf``, ``gbellmf``, ``sigmf``: segments halved until the interpolation error, measured at
  32 points inside each segment, is below ``FCL_TOLERANCE / 2``.

The file says so in a comment. Comments are ``//`` lines (IEC 61131-3 ed. 3; fuzzylite and
jFuzzyLogic read them, fuzzylite does not read ``(* *)``).

Rules are written in lower case (``RULE 1 : if x is a and y is not b then w is c with 0.5;``):
IEC keywords are case-insensitive, and fuzzylite's FCL reader hands the rule text to its own
case-sensitive rule parser, which silently drops rules written ``IF ... IS ... THEN``. Negation is
the ``is not`` form on a leaf, so rules are written in negation normal form (exact, see
:func:`hybridnav.fuzzy.export.normalize`); nested groups are parenthesized. ``AND : MIN``,
``OR : MAX``, ``ACT : MIN`` go in the ``RULEBLOCK``; ``METHOD : COG``, ``ACCU : MAX`` and
``DEFAULT := <default>`` in the ``DEFUZZIFY`` block (fuzzylite rejects ``ACCU`` in the rule block).
fuzzylite's ``COG`` uses its default resolution (100 midpoints); the standard has no way to ask
for more.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import numpy as np

from hybridnav.fuzzy.export._common import (
    _FCL_WORDS,
    _FUZZYLITE_WORDS,
    check_names,
    comment_text,
    description_lines,
    fnum,
    normalize,
    sampled_polyline,
    version,
)
from hybridnav.fuzzy.export.fll import rule_text
from hybridnav.fuzzy.spec import Term, Variable
from hybridnav.fuzzy.system import FuzzySystem

__all__ = ["to_fcl", "point_list", "FCL_TOLERANCE", "ZS_SEGMENTS"]

#: Equal segments of a zmf/smf point list: error 1 / (2 * 64**2) = 1.2e-4 (at most 1e-3 as
#: asked, with margin: small rule activations amplify membership errors in the centroid).
ZS_SEGMENTS = 64
#: Largest membership error of the point lists of curved terms: 1 / (2 * ZS_SEGMENTS**2).
FCL_TOLERANCE = 1.0 / (2 * ZS_SEGMENTS ** 2)
_CHECK = 32  # interior points at which an adaptive segment's error is measured
_MAX_POINTS = 20000


def _analytic(mf: str, p: tuple[float, ...]) -> Callable[[np.ndarray], np.ndarray]:
    """The analytic membership function (scikit-fuzzy's formula) as a vectorized callable."""
    if mf == "gaussmf":
        mean, sigma = p
        return lambda x: np.exp(-((x - mean) ** 2.0) / (2 * sigma ** 2.0))
    if mf == "gbellmf":
        a, b, c = p
        return lambda x: 1.0 / (1.0 + np.abs((x - c) / a) ** (2 * b))
    if mf == "sigmf":
        b, c = p
        return lambda x: 1.0 / (1.0 + np.exp(-c * (x - b)))
    if mf == "zmf":
        a, b = p
        m = 0.5 * (a + b)
        return lambda x: np.where(x <= a, 1.0, np.where(x <= m, 1 - 2 * ((x - a) / (b - a)) ** 2,
                                                         np.where(x <= b, 2 * ((x - b) / (b - a)) ** 2,
                                                                  0.0)))
    if mf == "smf":
        a, b = p
        m = 0.5 * (a + b)
        return lambda x: np.where(x <= a, 0.0, np.where(x <= m, 2 * ((x - a) / (b - a)) ** 2,
                                                         np.where(x <= b, 1 - 2 * ((x - b) / (b - a)) ** 2,
                                                                  1.0)))
    raise ValueError(mf)  # pragma: no cover


def _polyline(mf: str, p: tuple[float, ...], lo: float, hi: float,
              tol: float) -> list[tuple[float, float]]:
    """Points of a piecewise-linear version of the term (constant beyond both ends)."""
    if mf == "trimf":
        a, b, c = p  # a == b or b == c: a step (two points with the same x)
        return [(a, 0.0), (b, 1.0), (c, 0.0)]
    if mf == "trapmf":
        a, b, c, d = p
        return [(a, 0.0), (b, 1.0), (c, 1.0), (d, 0.0)]
    if mf in ("zmf", "smf"):
        a, b = p
        xs = a + (b - a) * np.arange(ZS_SEGMENTS + 1) / ZS_SEGMENTS
        xs[-1] = b
        f = _analytic(mf, p)
        return list(zip(xs.tolist(), f(xs).tolist()))
    # smooth terms: adaptive bisection on [lo, hi], starting from the natural breakpoints
    f = _analytic(mf, p)
    with np.errstate(over="ignore", under="ignore", divide="ignore", invalid="ignore"):
        centre = p[2] if mf == "gbellmf" else p[0]
        knots = sorted({lo, hi, *([centre] if lo < centre < hi else [])})
        if mf == "gbellmf":  # the bell's shoulders (|x - c| = a), where the curvature is largest
            knots = sorted({*knots, *(x for x in (centre - p[0], centre + p[0]) if lo < x < hi)})
        todo = [(knots[i], knots[i + 1]) for i in range(len(knots) - 1)][::-1]
        pts = [knots[0]]
        t = np.arange(1, _CHECK + 1) / (_CHECK + 1)
        while todo:
            u, v = todo.pop()
            fu, fv = float(f(np.array(u))), float(f(np.array(v)))
            xs = u + (v - u) * t
            e = np.max(np.abs(f(xs) - (fu + (fv - fu) * t)))
            if e > tol / 2 and v - u > (hi - lo) * 1e-9 and len(pts) < _MAX_POINTS:
                m = 0.5 * (u + v)
                todo += [(m, v), (u, m)]
            else:
                pts.append(v)
        xs = np.array(pts)
        return list(zip(xs.tolist(), f(xs).tolist()))


def point_list(term: Term, lo: float, hi: float,
               tol: float = FCL_TOLERANCE) -> list[tuple[float, float]]:
    """The FCL point list of a term over ``[lo, hi]``.

    Parameters
    ----------
    term : Term
    lo, hi : float
        The variable's range; the list starts at ``lo`` and ends at ``hi``.
    tol : float
        Largest membership error for curved terms (zmf/smf always use :data:`ZS_SEGMENTS`).

    Returns
    -------
    list of (x, y)
        Ascending ``x`` (equal ``x`` at a step); consecutive duplicates and interior points on
        a straight line through their neighbours are dropped.
    """
    poly = _polyline(term.mf, tuple(term.params), lo, hi, tol)

    def at(x: float, right: bool) -> float:
        """Value of the polyline at x (its right or left limit at a step)."""
        if x < poly[0][0] or (x == poly[0][0] and not right):
            return poly[0][1]
        if x > poly[-1][0] or (x == poly[-1][0] and right):
            return poly[-1][1]
        for (x0, y0), (x1, y1) in zip(poly, poly[1:]):
            if (x0 <= x < x1) if right else (x0 < x <= x1):
                return y0 + (y1 - y0) * (x - x0) / (x1 - x0)
        return poly[-1][1]  # pragma: no cover

    out = [(lo, at(lo, True))]
    out += [(x, y) for x, y in poly if lo < x < hi]
    out.append((hi, at(hi, False)))
    # drop repeats and collinear interior points (exactly on the segment through neighbours)
    res: list[tuple[float, float]] = []
    for pt in out:
        if res and pt == res[-1]:
            continue
        if len(res) >= 2 and res[-1][1] == res[-2][1] == pt[1] and res[-2][0] < res[-1][0] < pt[0]:
            res[-1] = pt
            continue
        res.append(pt)
    return res


def _real(x: float) -> str:
    """An IEC REAL literal (always with a decimal point before any exponent)."""
    s = fnum(x)
    if "e" in s and "." not in s.split("e")[0]:
        m, e = s.split("e")
        s = f"{m}.0e{e}"
    return s


def _ident(name: str) -> str:
    """The function block's name: an identifier that is no FCL or fuzzylite keyword."""
    s = re.sub(r"[^A-Za-z0-9_]", "_", name)
    bad = not s or s[0].isdigit() or s.lower() in _FCL_WORDS or s in _FUZZYLITE_WORDS
    return f"fb_{s}" if bad else s


def _terms(v: Variable, sampled: bool) -> list[str]:
    lo, hi = v.range
    out = []
    for t in v.terms:
        pl = sampled_polyline(v, t) if sampled else point_list(t, lo, hi)
        pts = " ".join(f"({_real(x)}, {_real(y)})" for x, y in pl)
        out.append(f"  TERM {t.name} := {pts};")
    return out


def to_fcl(system: FuzzySystem, *, sampled: bool = False) -> str:
    """The system as IEC 61131-7 FCL text.

    Parameters
    ----------
    system : FuzzySystem
    sampled : bool
        Use each term's universe samples as its point list: exactly the membership
        :meth:`FuzzySystem.evaluate` interpolates, instead of an approximation of the analytic
        function.

    Returns
    -------
    str
        FCL text ending with a newline (see the module docstring).

    Raises
    ------
    HybridnavError
        A variable or term name that is not an identifier or is a keyword of FCL or fuzzylite.
    """
    check_names(system, "fcl")
    system = normalize(system)
    curved = sorted({t.mf for v in (*system.inputs, system.output) for t in v.terms
                     if t.mf not in ("trimf", "trapmf")})
    o = system.output
    lines = [
        f"// hybridnav-fis/1 system '{comment_text(system.name)}' exported by hybridnav "
        f"{version()} as IEC 61131-7 FCL.",
        "// Terms are point lists over each RANGE (an input outside the range counts as its "
        "nearest end).",
    ]
    if sampled:
        lines.append("// Every term is its hybridnav universe samples (exactly the membership "
                     "hybridnav interpolates).")
    elif curved:
        lines.append(
            f"// Curved terms ({', '.join(curved)}) are point lists with membership error <= "
            f"{FCL_TOLERANCE:.2g} (zmf/smf: {ZS_SEGMENTS} equal segments, error "
            f"1/(2*{ZS_SEGMENTS}^2) = {FCL_TOLERANCE:.2g}; gaussmf/gbellmf/sigmf: adaptive "
            f"segments, error <= {FCL_TOLERANCE / 2:.2g}).")
    if not sampled:
        lines.append("// Triangles and trapezoids are exact.")
    lines.append("// When no rule fires the output is DEFAULT.")
    lines += [f"// {line}" for line in description_lines(system.description)]
    lines += ["", f"FUNCTION_BLOCK {_ident(system.name)}", "", "VAR_INPUT"]
    lines += [f"  {v.name} : REAL;" for v in system.inputs]
    lines += ["END_VAR", "", "VAR_OUTPUT", f"  {o.name} : REAL;", "END_VAR", ""]
    for v in system.inputs:
        lines += [f"FUZZIFY {v.name}", f"  RANGE := ({_real(v.range[0])} .. {_real(v.range[1])});",
                  *_terms(v, sampled), "END_FUZZIFY", ""]
    lines += [f"DEFUZZIFY {o.name}", f"  RANGE := ({_real(o.range[0])} .. {_real(o.range[1])});",
              *_terms(o, sampled), "  METHOD : COG;", "  ACCU : MAX;", f"  DEFAULT := {_real(o.default)};",
              "END_DEFUZZIFY", "", "RULEBLOCK rules", "  AND : MIN;", "  OR : MAX;", "  ACT : MIN;"]
    for k, r in enumerate(system.rules, start=1):
        w = "" if r.weight == 1.0 else f" with {_real(r.weight)}"
        lines.append(f"  RULE {k} : if {rule_text(r.antecedent)} then {o.name} is {r.then}{w};")
    lines += ["END_RULEBLOCK", "", "END_FUNCTION_BLOCK"]
    return "\n".join(lines) + "\n"
