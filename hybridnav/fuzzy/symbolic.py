"""A fuzzy system as one exact CasADi expression, with scikit-fuzzy's semantics.

:func:`to_casadi` writes what :meth:`hybridnav.fuzzy.FuzzySystem.evaluate` computes (see
:mod:`hybridnav.fuzzy.engine`) as straight-line CasADi SX, so a fuzzy controller closed around a
model can be simulated, differentiated, linearized and certified by the analysis tools
(:mod:`hybridnav.analysis`) like any other expression:

1. inputs clipped to their ranges: ``fmin(fmax(x, lo), hi)``;
2. memberships: ``np.interp`` on each input's sampled universe is the polyline through the
   samples, written as a sum of trapezoids over the runs of equal samples (a hat per sample where
   the samples differ), so that it is exact in real arithmetic and, in floating point, exactly
   0 in a zero tail and exactly 1 on a plateau (a rule that does not fire does not fire, ``NOT``
   of a full membership is 0) and relatively accurate in a Gaussian's tiny tail;
3. AND = ``fmin``, OR = ``fmax``, NOT = ``1 - x``; firing strength times weight; each output
   term's cut is the largest strength of its rules;
4. the aggregated output ``A(y) = max_t min(c_t, g_t(y))`` integrated as scikit-fuzzy's polyline
   over the output universe plus the points where each sampled term crosses its cut: the universe
   part ``sum_j W_j A(y_j)``, and in every interval a term can cross, the crossing points (those
   of inactive terms put at the interval's left end, where they add nothing), sorted by a
   ``fmin``/``fmax`` network and added as the triangles the engine adds;
5. centroid ``moment / fmax(area, eps)``, or the output's ``default`` where no term with a
   positive sample has a positive cut.

Memberships are the exact polylines in real arithmetic (``np.interp``'s own formula is not quite:
its rounded slopes leave ulp-sized steps at the samples), so in floating point a membership here
and in the engine differ by about 1e-16 absolute. The output agrees to the same order wherever
the cuts are well above that (the built-in systems: 2e-15 over their whole input ranges). Where
a term's cut is itself tiny (a ``NOT`` of a membership 1e-13 short of 1), scikit-fuzzy's centroid
moves its crossing points by amounts set by that rounding, and the two can differ by 1e-5 of the
output range: there neither is more exact than the other. Inputs must be finite (a NaN input gives
NaN in ``evaluate`` but not here: CasADi's ``fmin`` drops NaNs).
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as cs
import numpy as np

__all__ = ["to_casadi"]

_EPS = float(np.finfo(float).eps)


def _membership(v, xs: Sequence[float], F: Sequence[float]):
    """``np.interp(v, xs, F)`` for ``v`` in ``[xs[0], xs[-1]]``, exactly in real arithmetic and
    faithfully in floating point: the polyline through the samples as ``sum_r c_r T_r(v)`` over
    the runs ``r`` of equal samples (value ``c_r``), ``T_r`` the trapezoid that is 1 on the run
    and falls linearly to 0 at the neighbouring samples (a hat for a run of one sample). Inside a
    run the value is exactly ``c_r`` (a plateau at 1 stays 1, so ``NOT`` of it is exactly 0; a
    zero tail stays 0, so a rule that does not fire does not fire), and a tiny value (a Gaussian's
    tail) keeps its relative accuracy. Continuous, with kinks (``fmin``/``fmax``) at the samples.
    """
    M = len(xs)
    runs = []
    a = 0
    for k in range(1, M + 1):
        if k == M or F[k] != F[a]:
            runs.append((a, k - 1, F[a]))
            a = k
    out = cs.SX(0)
    for lo, hi, c in runs:
        if c == 0.0:
            continue
        up = 1.0 if lo == 0 else cs.fmin(1.0, (v - xs[lo - 1]) / (xs[lo] - xs[lo - 1]))
        down = 1.0 if hi == M - 1 else cs.fmin(1.0, (xs[hi + 1] - v) / (xs[hi + 1] - xs[hi]))
        if isinstance(up, float) and isinstance(down, float):
            out = out + c
        else:
            out = out + c * cs.fmax(0.0, cs.fmin(up, down))
    return out


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
    for (lo, hi, xs, F, _S), x in zip(eng._in_py, inputs):
        v = cs.fmin(cs.fmax(cs.SX(x), lo), hi)
        T = len(F[0])
        for t in range(T):
            mu.append(_membership(v, xs, [row[t] for row in F]))
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
