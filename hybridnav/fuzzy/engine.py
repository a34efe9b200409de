"""Compiled, batched evaluation of a Mamdani system with scikit-fuzzy's exact semantics.

What scikit-fuzzy 0.5.0 does in ``ControlSystemSimulation.compute()`` (centroid defuzzification),
and what this module reproduces:

1. Inputs are clipped to the universe ``[lo, hi]`` (``_InputAcceptor.__setitem__``).
2. Input membership is ``np.interp(x, universe, term.mf)`` (``interp_membership``).
3. AND = ``np.fmin``, OR = ``np.fmax``, NOT = ``1. - x`` (``term._MembershipValueAccessor``).
4. Activation = firing strength * rule weight (``compute_rule``, step 2), accumulated per output
   term with ``np.fmax`` (step 3). Output terms named by no rule have no cut and are ignored.
5. ``CrispValueCalculator.find_memberships``: for every output term with a cut ``y`` the
   universe gets the points where the *sampled* term crosses ``y``
   (``_interp_universe_fast``: intervals ``i`` where ``mf >= y`` flips, ``y > 0``; the point
   ``x[i] + (y - mf[i]) * (x[i+1] - x[i]) / (mf[i+1] - mf[i])``), merged with ``np.union1d``
   (sorted, exact duplicates removed). The aggregated output is
   ``max_t min(cut_t, np.interp(new_universe, universe, mf_t))`` on that upsampled universe.
6. ``defuzz.defuzz`` raises when the aggregated samples sum to zero (here: the file's ``default``
   is returned); otherwise ``defuzz.centroid`` integrates the polyline exactly (trapezoids,
   zero-width segments skipped) and returns ``sum(moment * area) / fmax(sum(area), eps)``.

How it is vectorized. The polyline integral (area and first moment) is the integral over the
plain universe plus, for each crossing point, the exact change of the integral of the interval
it falls in:

- Plain universe: ``sum_j W_j A_j`` with fixed trapezoid/moment weights ``W`` and aggregated
  samples ``A_j = max_t min(c_t, f_t[j])``. With at most :data:`SUBSETS_MAX` terms this uses the
  max-min identity ``max_t a_t = sum_{S} (-1)^(|S|+1) min_{t in S} a_t`` and
  ``sum_j W_j min(c, g_j) = P[k] + c Q[k]`` (prefix sums over the sorted values of
  ``g = min_{t in S} f_t``, ``k = searchsorted``): no ``(M, B)`` array at all. With more terms it
  forms ``A`` as an ``(M, B)`` array and multiplies.
- Crossings: the intervals a sampled term crosses at a level ``y`` depend only on where ``y``
  falls among the term's distinct sample values, so they are a precomputed table indexed by
  ``searchsorted(levels, y)`` (a couple of intervals per level for scikit-fuzzy's MFs).
  Inserting a point into a polyline segment adds a triangle (closed form below). Several
  crossings in one interval (from different terms) are rare; those samples are ordered with an
  ``(N, N, b)`` comparison.
- Crossings at the level 0 are left out: they only add points equal (to rounding) to universe
  samples, changing the integral by rounding error at most.
"""

from __future__ import annotations

import bisect
import itertools
import math
import threading
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from hybridnav.fuzzy.mf import sample
from hybridnav.fuzzy.spec import (
    And,
    Antecedent,
    Not,
    Or,
    OutputVariable,
    Rule,
    TermRef,
    Variable,
)

__all__ = ["CompiledSystem", "universe", "SUBSETS_MAX", "centroid_weights", "min_sum_table",
           "interp_slopes", "TINY_AREA", "polyline_centroid", "SUBSETS_SCALAR_MAX"]

FloatArray = NDArray[np.float64]
_EPS = float(np.finfo(float).eps)
_AND, _OR, _NOT = 0, 1, 2

#: Up to this many output terms in rules, the plain-universe integral uses the max-min identity
#: (2**T - 1 subset tables) instead of an (M, B) array.
SUBSETS_MAX = 3
#: The scalar path (and the C export) use the subset tables up to this many terms.
SUBSETS_SCALAR_MAX = 4
#: Below this fraction of the output range the aggregated area is computed directly (see
#: ``CompiledSystem._direct``).
TINY_AREA = 1e-6


def universe(v: Variable) -> FloatArray:
    """The universe samples of a variable: ``np.linspace(lo, hi, points)``."""
    return np.linspace(v.range[0], v.range[1], v.points)


def interp_slopes(xs: FloatArray, F: FloatArray) -> FloatArray:
    """Per-interval slopes exactly as ``np.interp`` computes them.

    Parameters
    ----------
    xs : ndarray
        The universe (M,), ascending.
    F : ndarray
        Term samples (T, M).

    Returns
    -------
    ndarray
        ``(T, M)`` with a zero last column, so that ``S[t, j] * (x - xs[j]) + F[t, j]`` is
        ``np.interp(x, xs, F[t])`` bit for bit when ``xs[j] <= x < xs[j + 1]``.
    """
    S = np.zeros_like(F)
    S[:, :-1] = (F[:, 1:] - F[:, :-1]) / (xs[1:] - xs[:-1])
    return S


def _crossing_table(f: FloatArray) -> tuple[FloatArray, NDArray[np.intp]]:
    """Intervals where the sampled ``f`` crosses a level ``y > 0``, for every possible ``y``.

    Returns ``levels`` (the sorted distinct values of ``f``) and ``table`` of shape
    ``(len(levels) + 1, P)``: for ``k = searchsorted(levels, y)`` (so ``levels[k-1] < y <=
    levels[k]``), ``table[k]`` lists, ascending, the intervals ``i`` with
    ``(f[i] >= y) != (f[i+1] >= y)``, padded with -1. Interval ``i`` qualifies exactly for
    ``rank(min end) < k <= rank(max end)``.
    """
    levels = np.unique(f)
    lo = np.minimum(f[:-1], f[1:])
    hi = np.maximum(f[:-1], f[1:])
    start = np.searchsorted(levels, lo) + 1
    stop = np.searchsorted(levels, hi) + 1  # exclusive
    length = np.maximum(stop - start, 0)
    nrow = len(levels) + 1
    total = int(length.sum())
    if total == 0:
        return levels, np.full((nrow, 0), -1, dtype=np.intp)
    ivl = np.repeat(np.arange(len(lo)), length)
    k = np.repeat(start, length) + np.arange(total) - np.repeat(np.cumsum(length) - length, length)
    order = np.lexsort((ivl, k))
    k, ivl = k[order], ivl[order]
    counts = np.bincount(k, minlength=nrow)
    pos = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    table = np.full((nrow, int(counts.max())), -1, dtype=np.intp)
    table[k, pos] = ivl
    return levels, table


def centroid_weights(xs: FloatArray) -> FloatArray:
    """Weights ``W`` (2, M) with ``W @ y = (area, first moment)`` of the polyline ``(xs, y)``.

    Parameters
    ----------
    xs : ndarray
        The universe, ascending.

    Returns
    -------
    ndarray
        ``W[0]``: trapezoid weights; ``W[1]``: those of ``x * y``. These are the exact integrals
        of a piecewise linear function, what ``defuzz.centroid`` sums segment by segment.
    """
    dx = np.diff(xs)
    W = np.zeros((2, len(xs)))
    W[0, :-1] += 0.5 * dx
    W[0, 1:] += 0.5 * dx
    W[1, :-1] += dx / 6.0 * (2.0 * xs[:-1] + xs[1:])
    W[1, 1:] += dx / 6.0 * (xs[:-1] + 2.0 * xs[1:])
    return W


def min_sum_table(g: FloatArray, W: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Tables for ``sum_j W[:, j] * min(c, g[j]) = P[:, k] + c * Q[:, k]``, ``k = searchsorted``.

    Parameters
    ----------
    g : ndarray
        Samples (M,).
    W : ndarray
        Weights (2, M), e.g. :func:`centroid_weights`.

    Returns
    -------
    levels, P, Q : ndarray
        ``levels`` (sorted distinct ``g``), ``P`` and ``Q`` of shape ``(2, len(levels) + 1)``:
        ``P[:, k]`` sums ``W g`` over samples below ``levels[k]``, ``Q[:, k]`` sums ``W`` over
        the others.
    """
    levels, rank = np.unique(g, return_inverse=True)
    K = len(levels)
    P = np.zeros((2, K + 1))
    Q = np.zeros((2, K + 1))
    for r in range(2):
        P[r, 1:] = np.cumsum(np.bincount(rank, weights=W[r] * g, minlength=K))
        Q[r, :K] = np.cumsum(np.bincount(rank, weights=W[r], minlength=K)[::-1])[::-1]
    return levels, P, Q


def polyline_centroid(x: FloatArray, y: FloatArray) -> float:
    """``skfuzzy.defuzz.centroid(x, y)``: its segment formulas, vectorized.

    Parameters
    ----------
    x : ndarray
        Ascending points (M,), ``M >= 2``.
    y : ndarray
        Membership at them (M,).

    Returns
    -------
    float
        ``sum(moment * area) / fmax(sum(area), eps)`` over the segments that have width and
        height (rectangles, triangles and trapezoids as scikit-fuzzy distinguishes them).
    """
    x1, x2, y1, y2 = x[:-1], x[1:], y[:-1], y[1:]
    keep = ~(((y1 == y2) & (y2 == 0.0)) | (x1 == x2))
    x1, x2, y1, y2 = x1[keep], x2[keep], y1[keep], y2[keep]
    h = x2 - x1
    rect = y1 == y2
    up = ~rect & (y1 == 0.0)
    down = ~rect & ~up & (y2 == 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        moment = np.select([rect, up, down],
                           [0.5 * (x1 + x2), 2.0 / 3.0 * h + x1, 1.0 / 3.0 * h + x1],
                           2.0 / 3.0 * h * (y2 + 0.5 * y1) / (y1 + y2) + x1)
    area = np.select([rect, up, down], [h * y1, 0.5 * h * y2, 0.5 * h * y1], 0.5 * h * (y1 + y2))
    return float(np.sum(moment * area) / max(float(np.sum(area)), _EPS))


class CompiledSystem:
    """Precomputed arrays for one fuzzy system; evaluation is pure NumPy over the batch.

    Parameters
    ----------
    inputs : sequence of Variable
    output : OutputVariable
    rules : sequence of Rule
    chunk : int
        Batches are processed in chunks of this many samples (bounds memory and keeps the work
        arrays in cache).
    """

    def __init__(self, inputs: Sequence[Variable], output: OutputVariable, rules: Sequence[Rule],
                 chunk: int = 2048) -> None:
        self.chunk = int(chunk)
        self.default = float(output.default)
        self.input_names = tuple(v.name for v in inputs)

        # ---- inputs: universe and term samples (membership is np.interp, as in skfuzzy)
        self._in: list[tuple[FloatArray, FloatArray, int]] = []
        self._in_py: list[tuple[float, float, list[float], list[tuple[float, ...]],
                                list[tuple[float, ...]]]] = []
        col: dict[tuple[str, str], int] = {}
        K = 0
        for v in inputs:
            xs = universe(v)
            F = np.stack([sample(t.mf, t.params, xs) for t in v.terms])  # (T, M)
            S = interp_slopes(xs, F)
            self._in.append((xs, F, K))
            self._in_py.append((float(xs[0]), float(xs[-1]), xs.tolist(),
                                [tuple(r) for r in F.T.tolist()], [tuple(r) for r in S.T.tolist()]))
            for t in v.terms:
                col[(v.name, t.name)] = K
                K += 1
        self.n_leaves = K

        # ---- rule antecedents: a DAG of unique nodes, evaluated in groups of equal height and
        # operator; group members are consecutive rows of the node array
        nodes: dict[Antecedent, tuple[int, int, tuple[Antecedent, ...]]] = {}

        def visit(a: Antecedent) -> int:
            """Register ``a`` and return its height (leaves: 0)."""
            if isinstance(a, TermRef):
                return 0
            if a in nodes:
                return nodes[a][0]
            kids: tuple[Antecedent, ...] = (a.item,) if isinstance(a, Not) else a.items
            h = 1 + max(visit(k) for k in kids)
            op = _AND if isinstance(a, And) else _OR if isinstance(a, Or) else _NOT
            nodes[a] = (h, op, kids)
            return h

        for r in rules:
            visit(r.antecedent)
        order = sorted(nodes, key=lambda a: (nodes[a][0], nodes[a][1]))
        index: dict[Antecedent, int] = {a: K + n for n, a in enumerate(order)}
        n_nodes = K + len(order)
        self._one, self._zero = n_nodes, n_nodes + 1  # padding rows for AND / OR groups
        self.n_rows = n_nodes + 2

        def idx(a: Antecedent) -> int:
            return col[(a.input, a.term)] if isinstance(a, TermRef) else index[a]

        groups: list[tuple[int, int, int, NDArray[np.intp]]] = []
        prog: list[tuple[int, tuple[int, ...]]] = []
        n = 0
        while n < len(order):
            h, op, _ = nodes[order[n]]
            m = n
            while m < len(order) and nodes[order[m]][:2] == (h, op):
                m += 1
            kids = [[idx(k) for k in nodes[a][2]] for a in order[n:m]]
            width = max(len(k) for k in kids)
            pad = self._one if op == _AND else self._zero
            arr = np.array([k + [pad] * (width - len(k)) for k in kids], dtype=np.intp)
            groups.append((op, K + n, K + m, arr[:, 0] if op == _NOT else arr))
            prog.extend((op, tuple(k)) for k in kids)
            n = m
        self._groups = groups
        self._prog = prog
        self.rule_roots = np.array([idx(r.antecedent) for r in rules], dtype=np.intp)
        self.rule_weights = np.array([r.weight for r in rules], dtype=np.float64)
        self._root_list = self.rule_roots.tolist()
        self._weight_list = self.rule_weights.tolist()

        # ---- output: only terms named by some rule take part (others have no cut in skfuzzy)
        xs = universe(output)
        M = len(xs)
        self.out_x = xs
        used = [t for t in output.terms if any(r.then == t.name for r in rules)]
        self.out_terms = tuple(t.name for t in used)
        T = len(used)
        R = len(rules)
        by_term = [[j for j, r in enumerate(rules) if r.then == t.name] for t in used]
        width = max(len(b) for b in by_term)
        self._cut_idx = np.array([b + [R] * (width - len(b)) for b in by_term], dtype=np.intp)
        self._cut_lists = [tuple(b) for b in by_term]
        Fo = np.stack([sample(t.mf, t.params, xs) for t in used])  # (T, M)
        So = interp_slopes(xs, Fo)
        self.out_F = Fo
        # below this aggregated area the table identities' rounding matters: direct centroid
        self._tiny_area = TINY_AREA * float(xs[-1] - xs[0])
        self.out_positive = [bool(np.any(f > 0)) for f in Fo]
        self._out_positive = np.array(self.out_positive)
        W = centroid_weights(xs)
        self._W = W

        # plain-universe integral by the max-min identity (term subsets), small T only
        self._subsets: list[tuple[float, tuple[int, ...], FloatArray, FloatArray, FloatArray]] = []
        if T <= SUBSETS_SCALAR_MAX:
            for size in range(1, T + 1):
                for sub in itertools.combinations(range(T), size):
                    lv, P, Q = min_sum_table(Fo[list(sub)].min(axis=0), W)
                    self._subsets.append((1.0 if size % 2 else -1.0, sub, lv, P, Q))
        self._subsets_py = [(sign, sub, lv.tolist(), P[0].tolist(), P[1].tolist(), Q[0].tolist(),
                             Q[1].tolist()) for sign, sub, lv, P, Q in self._subsets]

        # crossing tables; slot n of the (N, B) crossing arrays is padded with its own dummy
        # interval D_n = M + 2n whose two ends coincide (x = hi; f = 0, then 1): a crossing
        # there is exactly x0 and adds exactly nothing, so no masks are needed
        tables = [_crossing_table(f) for f in Fo]
        self._levels = [lv for lv, _ in tables]
        widths = [tb.shape[1] for _, tb in tables]
        N = sum(widths)
        self.n_slots = N
        self._slot_term = np.repeat(np.arange(T), widths).astype(np.intp)
        self._tables_T: list[NDArray[np.intp]] = []
        n = 0
        for _, tb in tables:
            tbT = tb.T.copy()  # (P_t, levels + 1)
            for q in range(tbT.shape[0]):
                tbT[q][tbT[q] < 0] = M + 2 * (n + q)
            self._tables_T.append(tbT)
            n += tbT.shape[0]
        Mp = M + 2 * N
        self._xs_pad = np.concatenate([xs, np.full(2 * N, xs[-1])])
        self._Fo_pad = np.concatenate([Fo, np.tile([0.0, 1.0], (T, N))], axis=1)  # (T, Mp)
        self._So_pad = np.concatenate([So, np.zeros((T, 2 * N))], axis=1)
        self._Fo_flat = self._Fo_pad.ravel()
        self._slot_off = (self._slot_term * Mp)[:, None]
        pa, pb = np.triu_indices(N, 1)
        keep = self._slot_term[pa] != self._slot_term[pb]  # a term crosses an interval once
        self._pairs = (pa[keep], pb[keep])

        self._levels_py = [lv.tolist() for lv in self._levels]
        self._tables_py = [[tuple(int(i) for i in row if i >= 0) for row in tb] for _, tb in tables]
        self._out_py = (xs.tolist(), Fo.tolist(), So.tolist())
        self._tls = threading.local()

    # ------------------------------------------------------------------------------ batch path

    def evaluate_batch(self, X: Sequence[FloatArray]) -> FloatArray:
        """Evaluate on 1-D float arrays of equal length ``B``, one per input (in input order).

        Values outside an input's range count as its nearest end (scikit-fuzzy clips them);
        NaN inputs give NaN outputs.
        """
        B = len(X[0])
        out = np.empty(B)
        for s in range(0, B, self.chunk):
            e = min(B, s + self.chunk)
            out[s:e] = self._chunk([x[s:e] for x in X])
        return out

    def _chunk(self, X: Sequence[FloatArray]) -> FloatArray:
        B = len(X[0])
        V = np.empty((self.n_rows, B))
        V[self._one] = 1.0
        V[self._zero] = 0.0
        nan = None
        for (xs, F, k0), x in zip(self._in, X):
            bad = np.isnan(x)
            if bad.any():
                nan = bad if nan is None else nan | bad
            for t in range(len(F)):
                # skfuzzy's interp_membership; outside the universe np.interp returns the end
                # values, the same as clipping the input first
                V[k0 + t] = np.interp(x, xs, F[t])
        for op, s, e, kids in self._groups:
            if op == _NOT:
                np.subtract(1.0, V.take(kids, axis=0), out=V[s:e])
            elif op == _AND:
                np.minimum.reduce(V.take(kids, axis=0), axis=1, out=V[s:e])
            else:
                np.maximum.reduce(V.take(kids, axis=0), axis=1, out=V[s:e])
        R = len(self.rule_roots)
        Sx = np.empty((R + 1, B))
        np.multiply(V.take(self.rule_roots, axis=0), self.rule_weights[:, None], out=Sx[:R])
        Sx[R] = 0.0
        cuts = Sx.take(self._cut_idx, axis=0).max(axis=1)  # (T, B)
        out = self._defuzz(cuts)
        if nan is not None:
            out[nan] = np.nan
        return out

    def _defuzz(self, cuts: FloatArray) -> FloatArray:
        """Centroid of the clipped, max-aggregated output on skfuzzy's upsampled universe."""
        T, B = cuts.shape
        ks = [np.searchsorted(lv, cuts[t]) for t, lv in enumerate(self._levels)]
        if T <= SUBSETS_MAX:
            am = np.zeros((2, B))
            for sign, sub, lv, P, Q in self._subsets:
                if len(sub) == 1:
                    c, k = cuts[sub[0]], ks[sub[0]]
                else:
                    c = cuts[sub[0]]
                    for t in sub[1:]:
                        c = np.minimum(c, cuts[t])
                    k = np.searchsorted(lv, c)
                v = P.take(k, axis=1) + c * Q.take(k, axis=1)
                if sign > 0:
                    am += v
                else:
                    am -= v
            area, mom = am
        else:
            area, mom = self._dense(cuts)
        if self.n_slots:
            da, dm = self._crossings(cuts, ks)
            area += da
            mom += dm
        out = mom / np.maximum(area, _EPS)  # defuzz.centroid divides by fmax(area, eps)
        # scikit-fuzzy has no output where the aggregated samples are all zero, i.e. where
        # every output term has a zero cut or is zero at every universe sample
        fired = ((cuts > 0.0) & self._out_positive[:, None]).any(axis=0)
        if not fired.all():
            out[~fired] = self.default
        tiny = fired & (area < self._tiny_area)
        if tiny.any():
            out[tiny] = self._direct(cuts[:, tiny].T)
        return out

    def _direct(self, cuts: FloatArray) -> FloatArray:
        """The centroid computed directly, scikit-fuzzy's way, for samples ``cuts`` (B, T).

        The table identities above subtract quantities of the size of the output range, which
        leaves rounding noise of about 1e-16 of it in the area; where the whole aggregated area
        is that small (all activations tiny) the result must come from the polyline itself: per
        sample, the universe with every positive cut's crossing points (``np.union1d``), the
        aggregated curve from ``np.interp`` there, and ``defuzz.centroid``'s segment formulas.
        The exported C code's direct path computes the same.
        """
        xs, F = self.out_x, self.out_F
        out = np.empty(len(cuts))
        for b, c in enumerate(np.asarray(cuts, dtype=float)):
            live = [t for t in range(len(c)) if c[t] > 0.0]
            new = []
            for t in live:
                f = F[t]
                above = f >= c[t]
                i = np.flatnonzero(above[:-1] != above[1:])
                new.append(xs[i] + (c[t] - f[i]) * (xs[i + 1] - xs[i]) / (f[i + 1] - f[i]))
            u = np.union1d(xs, np.concatenate(new)) if new else xs
            agg = np.zeros(len(u))
            for t in live:
                np.maximum(agg, np.minimum(c[t], np.interp(u, xs, F[t])), out=agg)
            out[b] = polyline_centroid(u, agg)
        return out

    def _dense(self, cuts: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``W @ A`` with ``A = max_t min(c_t, f_t)`` formed as an ``(M, B)`` array."""
        T, B = cuts.shape
        M = len(self.out_x)
        buf = getattr(self._tls, "buf", None)
        if buf is None or buf.shape[1] < M * B:
            # reused: fresh arrays this large come from mmap and page-fault on every call
            buf = np.empty((2, M * max(B, min(self.chunk, 256))))
            self._tls.buf = buf
        A = buf[0, :M * B].reshape(M, B)
        tmp = buf[1, :M * B].reshape(M, B)
        Fo = self.out_F
        np.minimum(Fo[0][:, None], cuts[0], out=A)
        for t in range(1, T):
            np.maximum(A, np.minimum(Fo[t][:, None], cuts[t], out=tmp), out=A)
        area, mom = self._W @ A
        return area, mom

    def _crossings(self, cuts: FloatArray, ks: list[NDArray[np.intp]]
                   ) -> tuple[FloatArray, FloatArray]:
        """Change of (area, moment) from inserting skfuzzy's crossing points into the universe.

        Inserting a point ``p`` (value ``Ap``) into a polyline segment ``[l, r]`` adds the
        triangle ``(l, 0), (p, Ap - lin(p)), (r, 0)``: area
        ``((r - l) Ap - (r - p) Al - (p - l) Ar) / 2``, moment ``area (l + p + r) / 3``.
        Points of one interval are inserted left to right, so ``r`` is always the interval's
        right end and ``l`` the previous point (or the left end).
        """
        T = cuts.shape[0]
        xs, So, Fo = self._xs_pad, self._So_pad, self._Fo_pad
        i = np.concatenate([tb.take(k, axis=1) for tb, k in zip(self._tables_T, ks)])  # (N, B)
        ff = i + self._slot_off
        f0 = self._Fo_flat.take(ff)
        f1 = self._Fo_flat.take(ff + 1)
        x0 = xs.take(i)
        x1 = xs.take(i + 1)
        c = cuts.take(self._slot_term, axis=0)  # (N, B)
        p = x0 + (c - f0) * (x1 - x0) / (f1 - f0)  # scikit-fuzzy's _interp_universe_fast
        d = p - x0
        # the aggregated output at p (np.interp on the interval, as skfuzzy) and at both ends
        F0 = Fo[0].take(i)
        Ap = np.minimum(So[0].take(i) * d + F0, cuts[0])
        A0 = np.minimum(F0, cuts[0])
        A1 = np.minimum(Fo[0].take(i + 1), cuts[0])
        for t in range(1, T):
            Ft = Fo[t].take(i)
            np.maximum(Ap, np.minimum(So[t].take(i) * d + Ft, cuts[t]), out=Ap)
            np.maximum(A0, np.minimum(Ft, cuts[t]), out=A0)
            np.maximum(A1, np.minimum(Fo[t].take(i + 1), cuts[t]), out=A1)
        lx, ly = x0, A0
        pa, pb = self._pairs
        if len(pa):
            conflict = (i.take(pa, axis=0) == i.take(pb, axis=0)).any(axis=0)
            if conflict.any():
                cc = np.flatnonzero(conflict)
                lx, ly = x0.copy(), A0.copy()
                lx[:, cc], ly[:, cc] = _left_neighbours(i[:, cc], p[:, cc], Ap[:, cc],
                                                        x0[:, cc], A0[:, cc])
        da = 0.5 * ((x1 - lx) * Ap - (x1 - p) * ly - (p - lx) * A1)
        dm = da * (lx + p + x1) * (1.0 / 3.0)
        return da.sum(axis=0), dm.sum(axis=0)

    # ----------------------------------------------------------------------------- scalar path

    def evaluate_scalar(self, x: Sequence[float]) -> float:
        """Evaluate one sample (Python floats, one per input) in plain Python.

        The same arithmetic as the batch path (results agree to rounding).
        """
        mu: list[float] = []
        for (lo, hi, xs, F, S), v in zip(self._in_py, x):
            if math.isnan(v):
                return math.nan
            v = lo if v < lo else hi if v > hi else v
            j = bisect.bisect_right(xs, v) - 1  # np.interp's interval (j = M-1 at hi: slope 0)
            d = v - xs[j]
            mu.extend([s * d + f for s, f in zip(S[j], F[j])])
        for op, kids in self._prog:
            if op == _AND:
                mu.append(min([mu[k] for k in kids]))
            elif op == _OR:
                mu.append(max([mu[k] for k in kids]))
            else:
                mu.append(1.0 - mu[kids[0]])
        strengths = [mu[k] * w for k, w in zip(self._root_list, self._weight_list)]
        cuts = [max([strengths[j] for j in b]) for b in self._cut_lists]
        return self._defuzz_scalar(cuts)

    def _defuzz_scalar(self, cuts: list[float]) -> float:
        live = [t for t, c in enumerate(cuts) if c > 0.0]
        if not any(self.out_positive[t] for t in live):
            return self.default
        if self._subsets_py:
            area = mom = 0.0
            for sign, sub, lv, Pa, Pm, Qa, Qm in self._subsets_py:
                c = min([cuts[t] for t in sub])
                if c > 0.0:
                    k = bisect.bisect_left(lv, c)
                    area += sign * (Pa[k] + c * Qa[k])
                    mom += sign * (Pm[k] + c * Qm[k])
        else:
            Fo = self.out_F
            A = np.minimum(Fo[live[0]], cuts[live[0]])
            for t in live[1:]:
                np.maximum(A, np.minimum(Fo[t], cuts[t]), out=A)
            # a sequential sum (cumsum), not a BLAS dot product, whose order depends on the
            # build and the CPU: the C evaluator (_native.c) repeats this one bit for bit
            area, mom = np.cumsum(self._W * A, axis=1)[:, -1].tolist()
        xs, F, S = self._out_py
        groups: dict[int, list[tuple[float, int, float]]] = {}
        n = 0
        for t, c in enumerate(cuts):
            if c > 0.0:
                f = F[t]
                for slot, i in enumerate(self._tables_py[t][bisect.bisect_left(self._levels_py[t], c)]):
                    x0 = xs[i]
                    p = x0 + (c - f[i]) * (xs[i + 1] - x0) / (f[i + 1] - f[i])
                    d = p - x0
                    ap = max([min(S[s][i] * d + F[s][i], cuts[s]) for s in live])
                    groups.setdefault(i, []).append((p, n + slot, ap))
            n += len(self._tables_T[t])
        for i, pts in groups.items():
            if len(pts) > 1:
                pts.sort()
            x1 = xs[i + 1]
            lx = xs[i]
            ly = max([min(F[s][i], cuts[s]) for s in live])
            a1 = max([min(F[s][i + 1], cuts[s]) for s in live])
            for p, _, ap in pts:
                da = 0.5 * ((x1 - lx) * ap - (x1 - p) * ly - (p - lx) * a1)
                area += da
                mom += da * (lx + p + x1) * (1.0 / 3.0)
                lx, ly = p, ap
        if area < self._tiny_area:       # all activations tiny: see _direct
            return float(self._direct(np.array([cuts], dtype=float))[0])
        return mom / max(area, _EPS)


def _left_neighbours(i: NDArray[np.intp], p: FloatArray, Ap: FloatArray, x0: FloatArray,
                     A0: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Left neighbour (position, value) of each crossing among the crossings of its interval.

    Arrays are ``(N, b)`` and C-contiguous: rows are crossing slots, columns samples. Points are
    ordered by ``(p, slot)`` (ties give zero-width segments). A crossing with no earlier point in
    its interval gets ``(x0, A0)``.
    """
    N, b = i.shape
    pn, pm = p[:, None, :], p[None, :, :]
    earlier_slot = (np.arange(N)[None, :] < np.arange(N)[:, None])[:, :, None]  # [n, m]: m < n
    before = (i[:, None, :] == i[None, :, :]) & ((pm < pn) | ((pm == pn) & earlier_slot))
    jm = np.where(before, pm, -np.inf).argmax(axis=1)  # (N, b): the latest earlier point
    flat = jm * b + np.arange(b)
    has = before.any(axis=1)
    return np.where(has, p.take(flat), x0), np.where(has, Ap.take(flat), A0)
