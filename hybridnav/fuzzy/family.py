"""Evaluate many fuzzy systems of one shape at once: a whole GA population in one call.

A :class:`SystemFamily` is built from a template system. Its members share the template's inputs
(names, ranges, universe points, term names and MF types), its output universe and its rule
antecedents; each member has its own MF parameters, rule weights and rule consequents. A weight of
0 switches a rule off (a rule that never fires adds nothing to scikit-fuzzy's aggregation; the only
trace is a zero-level cut, whose upsampling points coincide with universe samples).

:meth:`SystemFamily.evaluate` takes, for a batch of ``B`` samples, the member each sample belongs
to and the crisp inputs, and returns the crisp outputs with scikit-fuzzy's Mamdani semantics, as
:meth:`hybridnav.fuzzy.FuzzySystem.evaluate` does for one system (same clipping, interpolation,
min/max/1-x, weights, min implication, max aggregation, centroid over the universe upsampled at
each term's crossings of its cut level, and the default where nothing fires) — vectorized over
the whole batch: no Python loop over members or samples.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError
from hybridnav.fuzzy.mf import sample
from hybridnav.fuzzy.spec import And, Not, TermRef

__all__ = ["FamilyTables", "SystemFamily", "upsampled_centroid"]

FloatArray = NDArray[np.float64]
_EPS = np.finfo(float).eps


@dataclass
class FamilyTables:
    """Sampled membership tables of ``K`` members (built by :meth:`SystemFamily.tables`)."""

    inputs: list[FloatArray]        # per input: (K, terms, points)
    output: FloatArray              # (K, output terms, output points)
    weights: FloatArray             # (K, rules)
    consequents: NDArray[np.intp]   # (K, rules), index into the output terms
    #: (K, rules, inputs) per-member conjunctive antecedents, or None (the template's rules):
    #: per input 0 = don't care, 1..T = term T-1, T+1..2T = NOT term (code - T - 1)
    antecedents: NDArray[np.intp] | None = None

    @property
    def size(self) -> int:
        return self.output.shape[0]


class SystemFamily:
    """Systems shaped like ``template`` with per-member MF parameters, weights and consequents."""

    def __init__(self, template) -> None:
        self.template = template
        self.inputs = template.inputs
        self.output = template.output
        self.rules = template.rules
        self.input_names = tuple(v.name for v in self.inputs)
        self.x_in = [np.linspace(v.range[0], v.range[1], v.points) for v in self.inputs]
        self.x_out = np.linspace(self.output.range[0], self.output.range[1], self.output.points)
        self._term_index = {(v.name, t.name): (i, j) for i, v in enumerate(self.inputs)
                            for j, t in enumerate(v.terms)}
        self._out_index = {t.name: j for j, t in enumerate(self.output.terms)}

    # ---- tables ---------------------------------------------------------------------------

    def tables(self, input_params: Sequence[Sequence[Sequence[Sequence[float]]]],
               output_params: Sequence[Sequence[Sequence[float]]],
               weights: ArrayLike | None = None,
               consequents: ArrayLike | None = None,
               antecedents: ArrayLike | None = None) -> FamilyTables:
        """Sample every member's membership functions.

        Parameters
        ----------
        input_params : [member][input][term] -> params
        output_params : [member][term] -> params
        weights : (K, rules), optional
            Default: the template's weights.
        consequents : (K, rules) of output-term indices, optional
            Default: the template's.
        antecedents : (K, rules, inputs) of term codes, optional
            Per member its own conjunctive rule antecedents (rule learning), replacing the
            template's: per input 0 = don't care, ``1 + j`` = term ``j``, ``1 + T + j`` = NOT
            term ``j`` (``T`` terms); a rule whose inputs are all "don't care" fires fully.
        """
        K = len(output_params)
        tin = []
        for i, v in enumerate(self.inputs):
            arr = np.empty((K, len(v.terms), v.points))
            for k in range(K):
                for j, t in enumerate(v.terms):
                    arr[k, j] = sample(t.mf, input_params[k][i][j], self.x_in[i])
            tin.append(arr)
        tout = np.empty((K, len(self.output.terms), self.output.points))
        for k in range(K):
            for j, t in enumerate(self.output.terms):
                tout[k, j] = sample(t.mf, output_params[k][j], self.x_out)
        if weights is None:
            weights = np.tile([r.weight for r in self.rules], (K, 1))
        if consequents is None:
            consequents = np.tile([self._out_index[r.then] for r in self.rules], (K, 1))
        weights = np.asarray(weights, dtype=float).reshape(K, len(self.rules))
        consequents = np.asarray(consequents, dtype=np.intp).reshape(K, len(self.rules))
        if np.any((consequents < 0) | (consequents >= len(self.output.terms))):
            raise HybridnavError("consequents: expected output-term indices")
        if antecedents is not None:
            antecedents = np.asarray(antecedents, dtype=np.intp).reshape(
                K, len(self.rules), len(self.inputs))
            top = np.array([2 * len(v.terms) for v in self.inputs])
            if np.any((antecedents < 0) | (antecedents > top)):
                raise HybridnavError("antecedents: expected term codes in [0, 2 T]")
        return FamilyTables(tin, tout, weights, consequents, antecedents)

    def tables_of(self, systems: Sequence) -> FamilyTables:
        """Tables of concrete systems shaped like the template (rules by position)."""
        for s in systems:
            if (tuple(v.name for v in s.inputs) != self.input_names
                    or len(s.rules) != len(self.rules)):
                raise HybridnavError(f"fuzzy system {s.name!r}: not shaped like "
                                     f"{self.template.name!r}")
        return self.tables(
            [[[t.params for t in v.terms] for v in s.inputs] for s in systems],
            [[t.params for t in s.output.terms] for s in systems],
            [[r.weight for r in s.rules] for s in systems],
            [[self._out_index[r.then] for r in s.rules] for s in systems],
        )

    # ---- evaluation -----------------------------------------------------------------------

    def _cuts(self, tables: FamilyTables, member: NDArray[np.intp],
              inputs: Mapping[str, ArrayLike]):
        """Rule strengths (B, R) and the output terms' cut levels (B, T) and use (B, T)."""
        B = len(member)
        mu: dict[tuple[int, int], FloatArray] = {}
        for i, v in enumerate(self.inputs):
            x = np.asarray(inputs[v.name], dtype=float).ravel()
            xs = self.x_in[i]
            xc = np.minimum(np.maximum(x, xs[0]), xs[-1])
            idx = np.searchsorted(xs, xc, side="right") - 1
            np.minimum(idx, len(xs) - 2, out=idx)
            x0 = xs[idx]
            frac = (xc - x0) / (xs[idx + 1] - x0)
            table = tables.inputs[i]
            y0 = table[member, :, idx]                            # (B, terms)
            y1 = table[member, :, idx + 1]
            vals = y0 + (y1 - y0) * frac[:, None]                 # np.interp's formula
            nan = np.isnan(x)
            if nan.any():
                vals[nan] = np.nan
            for j in range(len(v.terms)):
                mu[(i, j)] = vals[:, j]
        R = len(self.rules)
        T = len(self.output.terms)
        if tables.antecedents is not None:
            # AND of the parts as the template path computes it (fmin: NaN only when every part
            # is NaN); "don't care" is no part (NaN here), a rule without parts fires fully
            strength = np.full((B, R), np.nan)
            codes = tables.antecedents[member]                   # (B, R, inputs)
            for i, v in enumerate(self.inputs):
                vals = np.column_stack([mu[(i, j)] for j in range(len(v.terms))])
                ext = np.concatenate([np.full((B, 1), np.nan), vals, 1.0 - vals], axis=1)
                strength = np.fmin(strength, np.take_along_axis(ext, codes[:, :, i], axis=1))
            strength[(codes == 0).all(axis=2)] = 1.0
        else:
            strength = np.empty((B, R))
            for r, rule in enumerate(self.rules):
                strength[:, r] = self._fire(rule.antecedent, mu)
        strength *= tables.weights[member]
        cons = tables.consequents[member]                        # (B, R)
        cuts = np.zeros((B, T))
        used = np.zeros((B, T), dtype=bool)
        for t in range(T):
            sel = cons == t
            used[:, t] = sel.any(axis=1)
            cuts[:, t] = np.max(np.where(sel, strength, 0.0), axis=1, initial=0.0)
        return strength, cuts, used

    def evaluate(self, tables: FamilyTables, member: ArrayLike,
                 inputs: Mapping[str, ArrayLike]) -> FloatArray:
        """Crisp outputs for samples ``b`` of members ``member[b]`` with inputs ``inputs[name][b]``.

        Computed by the compiled kernel (:mod:`hybridnav.native`) where a C compiler is found,
        else in NumPy; the two agree to rounding.

        Returns
        -------
        ndarray, shape (B,)
        """
        member = np.asarray(member, dtype=np.intp).ravel()
        from hybridnav.native.lockstep import family_evaluate

        out = family_evaluate(self, tables, member, inputs)     # compiled, where available
        if out is not None:
            return out
        strength, cuts, used = self._cuts(tables, member, inputs)
        out = upsampled_centroid(self.x_out, tables.output[member], cuts, used,
                                 self.output.default)
        out[np.isnan(strength).any(axis=1)] = np.nan
        # a NaN input gives a NaN output, as FuzzySystem.evaluate does, whatever the rules
        for v in self.inputs:
            x = np.asarray(inputs[v.name], dtype=float).ravel()
            out[np.isnan(x)] = np.nan
        return out

    def fired(self, tables: FamilyTables, member: ArrayLike,
              inputs: Mapping[str, ArrayLike]) -> NDArray[np.bool_]:
        """Whether any rule fires (the aggregated output has a positive area) at each sample;
        where it does not, :meth:`evaluate` returns the output's ``default``.

        Returns
        -------
        ndarray of bool, shape (B,)
        """
        member = np.asarray(member, dtype=np.intp).ravel()
        _, cuts, used = self._cuts(tables, member, inputs)
        # min(cut, F) > 0 somewhere exactly when the cut is positive and the term is not zero
        positive = tables.output.max(axis=2) > 0                 # (K, T)
        return np.any(used & (cuts > 0) & positive[member], axis=1)

    def coverage_points(self, grid: int = 41, max_points: int = 4096) -> list[FloatArray]:
        """The points :meth:`uncovered` checks: the ``grid``-per-axis grid over the input ranges
        (range ends included) for one or two inputs or while it has at most ``max_points``
        points; beyond (three inputs or more), the first ``max_points`` points of the Halton
        sequence over the ranges plus the ``2^d`` corners (deterministic, and as even as a
        grid)."""
        d = len(self.inputs)
        if d <= 2 or grid ** d <= max_points:
            axes = [np.linspace(v.range[0], v.range[1], grid) for v in self.inputs]
            return [m.ravel() for m in np.meshgrid(*axes, indexing="ij")]
        from scipy.stats import qmc

        U = qmc.Halton(d, scramble=False).random(max_points)
        corners = np.array(np.meshgrid(*[[0.0, 1.0]] * d, indexing="ij")).reshape(d, -1).T
        U = np.vstack([corners, U])
        lo = np.array([v.range[0] for v in self.inputs])
        hi = np.array([v.range[1] for v in self.inputs])
        P = lo + U * (hi - lo)
        return [P[:, i] for i in range(d)]

    def uncovered(self, tables: FamilyTables, grid: int = 41,
                  max_points: int = 4096) -> FloatArray:
        """Per member, the fraction of the input space where no rule fires (the output falls
        back to ``default``), on :meth:`coverage_points` (a ``grid``-per-axis grid, range ends
        included, up to ``max_points`` points). Members are checked a few at a time, so memory
        stays bounded whatever the population.

        Returns
        -------
        ndarray, shape (K,)
        """
        mesh = self.coverage_points(grid, max_points)
        n = len(mesh[0])
        K = tables.size
        out = np.empty(K)
        block = max(1, 200_000 // n)
        for a in range(0, K, block):
            b = min(K, a + block)
            member = np.repeat(np.arange(a, b), n)
            X = {v.name: np.tile(m, b - a) for v, m in zip(self.inputs, mesh)}
            ok = self.fired(tables, member, X).reshape(b - a, n)
            out[a:b] = 1.0 - ok.mean(axis=1)
        return out

    def _fire(self, a, mu) -> FloatArray:
        if isinstance(a, TermRef):
            return mu[self._term_index[(a.input, a.term)]]
        if isinstance(a, Not):
            return 1.0 - self._fire(a.item, mu)
        parts = [self._fire(x, mu) for x in a.items]
        op = np.fmin if isinstance(a, And) else np.fmax
        acc = parts[0]
        for p in parts[1:]:
            acc = op(acc, p)
        return acc


def upsampled_centroid(xs: FloatArray, F: FloatArray, cuts: FloatArray,
                       used: NDArray[np.bool_], default: float) -> FloatArray:
    """Centroid of ``max_t min(cut_t, F_t)`` on the universe upsampled at the crossings.

    ``xs`` is the output universe (M,), ``F`` (B, T, M) the output term samples of each sample,
    ``cuts`` (B, T) their cut levels; terms not used by any rule of the sample's system
    (``used`` False) are left out; ``default`` where nothing fires. Computed directly from
    ``min(cut, F)``, so it stays exact however small the cuts are. scikit-fuzzy adds only each term's crossings of its
    own cut level to the universe, so between grid points without a crossing its aggregated
    curve is the straight line between the grid values: the integral is the trapezoid sum on
    the grid, corrected on the few intervals that contain crossings.
    """
    B, T, M = F.shape
    x0, x1, dx = xs[:-1], xs[1:], np.diff(xs)
    cut = np.where(used, cuts, 0.0)
    A = np.minimum(cut[:, 0, None], F[:, 0])                 # (B, M) on the grid
    for t in range(1, T):
        np.maximum(A, np.minimum(cut[:, t, None], F[:, t]), out=A)
    # trapezoid sums on the grid as matrix-vector products: per interval
    # area = dx (ya + yb) / 2 and moment = (ya + yb) dx x0 / 2 + (ya + 2 yb) dx^2 / 6
    ssum = A[:, :-1] + A[:, 1:]
    c1, c2 = dx * x0 / 2.0, dx * dx / 6.0
    total = ssum @ (dx / 2.0)
    moment_total = ssum @ c1 + (ssum + A[:, 1:]) @ c2
    # scikit-fuzzy's _interp_universe_fast: where "F >= cut" changes between neighbouring
    # samples it adds the linear crossing point. For a zero cut ("F > 0" changes) those
    # points coincide with universe samples up to rounding and change nothing: skipped.
    c3 = np.where(used & (cuts > 0), cuts, np.inf)[:, :, None]
    above = F >= c3
    cross = above[:, :, :-1] != above[:, :, 1:]
    bi, ti, ii = np.nonzero(cross)
    if len(bi):
        key = bi * (M - 1) + ii
        uk, inv = np.unique(key, return_inverse=True)
        ub, ui = uk // (M - 1), uk % (M - 1)
        Fl, Fr = F[bi, ti, ii], F[bi, ti, ii + 1]
        p = x0[ii] + (cuts[bi, ti] - Fl) * dx[ii] / (Fr - Fl)
        pts = np.repeat(x0[ui][:, None], T + 2, axis=1)        # (U, T+2)
        pts[:, -1] = x1[ui]
        pts[inv, 1 + ti] = p
        pts = np.sort(pts, axis=1)
        frac = (pts - x0[ui][:, None]) / dx[ui][:, None]
        G0 = F[ub, :, ui]                                     # (U, T)
        G1 = F[ub, :, ui + 1]
        lerp = G0[:, :, None] + (G1 - G0)[:, :, None] * frac[:, None, :]
        agg = np.max(np.minimum(cut[ub][:, :, None], lerp), axis=1)   # (U, T+2)
        xa, xb, ga, gb = pts[:, :-1], pts[:, 1:], agg[:, :-1], agg[:, 1:]
        w = xb - xa
        fine_area = (0.5 * w * (ga + gb)).sum(axis=1)
        fine_moment = (w * (xa * (ga + gb) / 2.0 + w * (ga + 2.0 * gb) / 6.0)).sum(axis=1)
        s_u = ssum[ub, ui]
        base_area = s_u * dx[ui] / 2.0
        base_moment = s_u * c1[ui] + (s_u + A[ub, ui + 1]) * c2[ui]
        total = total + np.bincount(ub, fine_area - base_area, minlength=B)
        moment_total = moment_total + np.bincount(ub, fine_moment - base_moment, minlength=B)
    crisp = moment_total / np.fmax(total, _EPS)
    return np.where(A.max(axis=1) > 0, crisp, default)
