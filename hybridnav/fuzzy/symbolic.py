"""A fuzzy system as one exact CasADi expression, with scikit-fuzzy's semantics.

:func:`to_casadi` writes what :meth:`hybridnav.fuzzy.FuzzySystem.evaluate` computes (see
:mod:`hybridnav.fuzzy.engine`) as straight-line CasADi SX, so a fuzzy controller closed around a
model can be simulated, differentiated, linearized and certified by the analysis tools
(:mod:`hybridnav.analysis`) like any other expression:

1. inputs clipped to their ranges: ``fmin(fmax(x, lo), hi)``;
2. memberships: ``np.interp`` on each input's sampled universe is the polyline through the
   samples, written exactly as a sum of hinges ``F_0 + S_0 (x - x_0) + sum_j (S_j - S_{j-1})
   fmax(0, x - x_j)`` (one per change of slope), anchored at the side where the samples are zero
   (and for a triangle the ``fmin`` of both), so that a membership that is 0 in the engine is
   exactly 0 here and a rule that does not fire does not fire;
3. AND = ``fmin``, OR = ``fmax``, NOT = ``1 - x``; firing strength times weight; each output
   term's cut is the largest strength of its rules;
4. the aggregated output ``A(y) = max_t min(c_t, g_t(y))`` integrated as scikit-fuzzy's polyline
   over the output universe plus the points where each sampled term crosses its cut: the universe
   part ``sum_j W_j A(y_j)``, and in every interval a term can cross, the crossing points (those
   of inactive terms put at the interval's left end, where they add nothing), sorted by a
   ``fmin``/``fmax`` network and added as the triangles the engine adds;
5. centroid ``moment / fmax(area, eps)``, or the output's ``default`` where no term with a
   positive sample has a positive cut.

Equal in real arithmetic to the engine; in floating point the two agree to rounding (the tests
compare them at random points, and against scikit-fuzzy). Inputs must be finite (a NaN input gives
NaN in ``evaluate`` but not here: CasADi's ``fmin`` drops NaNs).
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as cs
import numpy as np

__all__ = ["to_casadi"]

_EPS = float(np.finfo(float).eps)


def _left(v, xs, F, S, lo: int, hi: int):
    """The polyline on samples ``lo..hi`` at ``v``, hinges anchored at ``xs[lo]`` (continued
    linearly beyond ``xs[hi]``): exactly ``F[lo]`` left of the first slope change."""
    out = F[lo] + S[lo] * (v - xs[lo]) if S[lo] != 0.0 else cs.SX(F[lo])
    for j in range(lo + 1, hi):
        ds = S[j] - S[j - 1]
        if ds != 0.0:
            out = out + ds * cs.fmax(0.0, v - xs[j])
    return out


def _right(v, xs, F, S, lo: int, hi: int):
    """The same anchored at ``xs[hi]``: exactly ``F[hi]`` right of the last slope change."""
    out = F[hi] - S[hi - 1] * (xs[hi] - v) if S[hi - 1] != 0.0 else cs.SX(F[hi])
    for j in range(lo + 1, hi):
        ds = S[j] - S[j - 1]
        if ds != 0.0:
            out = out + ds * cs.fmax(0.0, xs[j] - v)
    return out


def _membership(v, xs: Sequence[float], F: Sequence[float], S: Sequence[float]):
    """``np.interp(v, xs, F)`` for ``v`` in ``[xs[0], xs[-1]]``: the polyline as hinge sums, laid
    out so that where the samples are exactly 0 (a Z/S curve's tail, a triangle's feet) the value
    is exactly 0 in floating point too — a cut that is exactly 0 must stay 0, or a rule that does
    not fire would take the output away from its default."""
    M = len(xs)
    zl = F[0] == 0.0 and F[1] == 0.0
    zr = F[-1] == 0.0 and F[-2] == 0.0
    if zl and zr:
        k = int(np.argmax(F))
        rising = all(F[j] <= F[j + 1] for j in range(k))
        falling = all(F[j] >= F[j + 1] for j in range(k, M - 1))
        if rising and falling and 0 < k < M - 1:
            # unimodal: the rising part continued rightwards meets the falling part continued
            # leftwards at the peak; each is above the polyline on the other's side
            return cs.fmin(_left(v, xs, F, S, 0, k + 1), _right(v, xs, F, S, k - 1, M - 1))
    if zr and not zl:
        return _right(v, xs, F, S, 0, M - 1)
    return _left(v, xs, F, S, 0, M - 1)


def _sort(values: list):
    """Ascending, by an odd-even transposition network of fmin/fmax (exact)."""
    v = list(values)
    n = len(v)
    for r in range(n):
        for i in range(r % 2, n - 1, 2):
            v[i], v[i + 1] = cs.fmin(v[i], v[i + 1]), cs.fmax(v[i], v[i + 1])
    return v


def to_casadi(system, inputs: Sequence) -> cs.SX:
    """The crisp output of ``system`` at the CasADi expressions ``inputs`` (in
    ``system.input_names`` order), as one SX expression.

    Parameters
    ----------
    system : FuzzySystem
    inputs : sequence of casadi.SX
        One scalar expression per input variable.

    Returns
    -------
    casadi.SX
        A scalar.
    """
    eng = system._engine
    if len(inputs) != len(eng.input_names):
        raise ValueError(f"to_casadi: fuzzy system {system.name!r} takes the inputs "
                         f"{', '.join(eng.input_names)}, got {len(inputs)} expressions")
    mu: list = []
    for (lo, hi, xs, F, S), x in zip(eng._in_py, inputs):
        v = cs.fmin(cs.fmax(cs.SX(x), lo), hi)
        T = len(F[0])
        for t in range(T):
            mu.append(_membership(v, xs, [row[t] for row in F], [row[t] for row in S]))
    for op, kids in eng._prog:
        if op == 0:
            e = mu[kids[0]]
            for k in kids[1:]:
                e = cs.fmin(e, mu[k])
        elif op == 1:
            e = mu[kids[0]]
            for k in kids[1:]:
                e = cs.fmax(e, mu[k])
        else:
            e = 1.0 - mu[kids[0]]
        mu.append(e)
    strengths = [mu[k] * w for k, w in zip(eng._root_list, eng._weight_list)]
    cuts = []
    for b in eng._cut_lists:
        c = strengths[b[0]]
        for j in b[1:]:
            c = cs.fmax(c, strengths[j])
        cuts.append(c)
    xs, F, S = eng._out_py
    T, M = len(F), len(xs)

    def A_at(j):
        a = cs.fmin(F[0][j], cuts[0])
        for t in range(1, T):
            a = cs.fmax(a, cs.fmin(F[t][j], cuts[t]))
        return a

    def A_in(i, p):
        d = p - xs[i]
        a = cs.fmin(S[0][i] * d + F[0][i], cuts[0])
        for t in range(1, T):
            a = cs.fmax(a, cs.fmin(S[t][i] * d + F[t][i], cuts[t]))
        return a

    W = eng._W
    Aj = [A_at(j) for j in range(M)]
    area = sum(W[0, j] * Aj[j] for j in range(M))
    mom = sum(W[1, j] * Aj[j] for j in range(M))
    for i in range(M - 1):
        cand = []
        for t in range(T):
            f0, f1 = F[t][i], F[t][i + 1]
            if f0 == f1:
                continue
            c = cuts[t]
            # scikit-fuzzy: (f0 >= c) != (f1 >= c), c > 0: c in (min, max]
            active = (c > min(f0, f1)) * (c <= max(f0, f1)) * (c > 0)
            p = xs[i] + (c - f0) * (xs[i + 1] - xs[i]) / (f1 - f0)
            cand.append(cs.if_else(active, p, xs[i]))
        if not cand:
            continue
        lx, ly, x1, a1 = xs[i], Aj[i], xs[i + 1], Aj[i + 1]
        for p in _sort(cand):
            ap = A_in(i, p)
            da = 0.5 * ((x1 - lx) * ap - (x1 - p) * ly - (p - lx) * a1)
            area = area + da
            mom = mom + da * (lx + p + x1) * (1.0 / 3.0)
            lx, ly = p, ap
    fired = 0
    for t in range(T):
        if eng.out_positive[t]:
            fired = fired + (cuts[t] > 0)
    return cs.if_else(fired > 0, mom / cs.fmax(area, _EPS), eng.default)
