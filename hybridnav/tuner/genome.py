"""Genomes: real vectors that map to the free parameters of a fuzzy system.

Genes, in this order:

* ``mf``: every parameter of every term of the free variables, bounded by the variable's range
  widened by ``free.margin`` times its width on each side (or by ``free.bounds``) — a Z or S
  curve can then reach past the range end, so a rule can fire on the whole input range; widths and slopes (``gaussmf`` sigma, ``gbellmf`` a and b, ``sigmf``
  slope) get their own positive bounds;
* ``switch`` (``free.rule_switches``): one gene in [0, 1] per rule, the rule is on when >= 0.5
  (at least one rule always stays on: the one with the largest gene);
* ``weight`` (``free.rule_weights``): the rule weight, in [0, 1];
* ``consequent`` (``free.rule_consequents``): in [0, T), the output term ``floor(gene)``.

Real-valued switches and consequents let the same SBX/polynomial operators act on every gene.
:meth:`GenomeSpace.repair` keeps each term's parameters valid (clipped to the bounds, ordered:
``zmf``/``smf`` a < b, ``trimf`` a <= b <= c, ``trapmf`` a <= b <= c <= d).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybridnav.fuzzy import FuzzySystem

__all__ = ["Gene", "GenomeSpace"]

_ORDERED = ("zmf", "smf", "trimf", "trapmf")


@dataclass(frozen=True)
class Gene:
    """One free number: what it is, where it goes, its bounds."""

    kind: str            # "mf", "switch", "weight", "consequent"
    var: int             # variable index (inputs first, then the output) for "mf"; else -1
    term: int            # term index for "mf"; rule index otherwise
    param: int           # parameter index for "mf"; else -1
    lower: float
    upper: float
    label: str


class GenomeSpace:
    """The free parameters of a job's starting system, as a bounded real vector."""

    def __init__(self, template: FuzzySystem, free: dict[str, Any]) -> None:
        self.template = template
        self.variables = list(template.inputs) + [template.output]
        bounds = free.get("bounds", {})
        genes: list[Gene] = []
        for vi, v in enumerate(self.variables):
            if v.name not in free.get("mf", []):
                continue
            if v.name in bounds:
                lo, hi = bounds[v.name]
            else:                   # positions may reach past the range by margin * width
                pad = float(free.get("margin", 0.0)) * (v.range[1] - v.range[0])
                lo, hi = v.range[0] - pad, v.range[1] + pad
            width = hi - lo
            for ti, t in enumerate(v.terms):
                for pi, _ in enumerate(t.params):
                    b = _param_bounds(t.mf, pi, lo, hi, width)
                    genes.append(Gene("mf", vi, ti, pi, b[0], b[1],
                                      f"{v.name}.{t.name}.{t.mf}[{pi}]"))
        n_terms = len(template.output.terms)
        for ri, _ in enumerate(template.rules):
            if free.get("rule_switches"):
                genes.append(Gene("switch", -1, ri, -1, 0.0, 1.0, f"rule{ri + 1}.on"))
            if free.get("rule_weights"):
                genes.append(Gene("weight", -1, ri, -1, 0.0, 1.0, f"rule{ri + 1}.weight"))
            if free.get("rule_consequents"):
                genes.append(Gene("consequent", -1, ri, -1, 0.0, n_terms - 1e-9,
                                  f"rule{ri + 1}.then"))
        self.genes = genes
        self.lower = np.array([g.lower for g in genes])
        self.upper = np.array([g.upper for g in genes])
        self.labels = [g.label for g in genes]
        self._out_index = {t.name: j for j, t in enumerate(template.output.terms)}

    @property
    def size(self) -> int:
        return len(self.genes)

    # ---- encode / repair / decode ------------------------------------------------------------

    def encode(self, system: FuzzySystem | None = None) -> np.ndarray:
        """The genome of ``system`` (default: the template), clipped to the bounds."""
        s = system or self.template
        variables = list(s.inputs) + [s.output]
        x = np.empty(self.size)
        for k, g in enumerate(self.genes):
            if g.kind == "mf":
                x[k] = variables[g.var].terms[g.term].params[g.param]
            elif g.kind == "switch":
                x[k] = 1.0
            elif g.kind == "weight":
                x[k] = s.rules[g.term].weight
            else:
                x[k] = self._out_index[s.rules[g.term].then] + 0.5
        return self.repair(x[None])[0]

    def random(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` genomes drawn uniformly within the bounds, repaired."""
        return self.repair(self.lower + (self.upper - self.lower) * rng.random((n, self.size)))

    def repair(self, X: np.ndarray) -> np.ndarray:
        """Clip to the bounds and restore each term's parameter order (rows of ``X``)."""
        X = np.clip(np.asarray(X, dtype=float), self.lower, self.upper)
        groups: dict[tuple[int, int], list[int]] = {}
        for k, g in enumerate(self.genes):
            if g.kind == "mf":
                groups.setdefault((g.var, g.term), []).append(k)
        for (vi, ti), cols in groups.items():
            mf = self.variables[vi].terms[ti].mf
            if mf not in _ORDERED or len(cols) < 2:
                continue
            cols = sorted(cols, key=lambda c: self.genes[c].param)
            X[:, cols] = np.sort(X[:, cols], axis=1)
            if mf in ("zmf", "smf"):            # strictly a < b
                a, b = cols
                width = self.upper[b] - self.lower[a]
                eps = 1e-6 * width
                tight = X[:, b] - X[:, a] < eps
                X[tight, b] = np.minimum(X[tight, a] + eps, self.upper[b])
                X[tight, a] = X[tight, b] - eps
        return X

    def arrays(self, X: np.ndarray):
        """Per-member MF parameters, rule weights and consequents for a ``SystemFamily``."""
        X = np.atleast_2d(X)
        K = len(X)
        params = [[list(map(list, (t.params for t in v.terms))) for v in self.variables]
                  for _ in range(K)]
        weights = np.tile([r.weight for r in self.template.rules], (K, 1)).astype(float)
        cons = np.tile([self._out_index[r.then] for r in self.template.rules], (K, 1))
        switches = np.ones_like(weights, dtype=bool)
        for k, g in enumerate(self.genes):
            col = X[:, k]
            if g.kind == "mf":
                for m in range(K):
                    params[m][g.var][g.term][g.param] = float(col[m])
            elif g.kind == "switch":
                switches[:, g.term] = col >= 0.5
            elif g.kind == "weight":
                weights[:, g.term] = col
            else:
                cons[:, g.term] = np.minimum(col.astype(int), len(self.template.output.terms) - 1)
        # at least one rule on: the one whose switch gene is largest
        sw_cols = [k for k, g in enumerate(self.genes) if g.kind == "switch"]
        if sw_cols:
            none = ~switches.any(axis=1)
            if none.any():
                best = np.argmax(X[np.ix_(none, sw_cols)], axis=1)
                rules = [self.genes[sw_cols[b]].term for b in best]
                switches[np.flatnonzero(none), rules] = True
        weights = np.where(switches, weights, 0.0)
        n_in = len(self.template.inputs)
        return ([p[:n_in] for p in params], [p[n_in] for p in params], weights, cons, switches)

    def system(self, x: np.ndarray, name: str | None = None,
               description: str | None = None) -> FuzzySystem:
        """The fuzzy system of one genome (switched-off rules removed)."""
        inp, out, weights, cons, switches = self.arrays(np.asarray(x)[None])
        d = copy.deepcopy(self.template.to_dict())
        if name:
            d["name"] = name
        if description is not None:
            d["description"] = description
        for vi, v in enumerate(d["inputs"]):
            for ti, t in enumerate(v["terms"]):
                t["params"] = [float(p) for p in inp[0][vi][ti]]
        for ti, t in enumerate(d["output"]["terms"]):
            t["params"] = [float(p) for p in out[0][ti]]
        terms = [t["name"] for t in d["output"]["terms"]]
        rules = []
        for ri, r in enumerate(d["rules"]):
            if not switches[0, ri]:
                continue
            r = dict(r)
            r["then"] = terms[int(cons[0, ri])]
            r["weight"] = float(weights[0, ri])
            rules.append(r)
        d["rules"] = rules
        return FuzzySystem.from_dict(d)


def _param_bounds(mf: str, index: int, lo: float, hi: float, width: float) -> tuple[float, float]:
    """Bounds of one MF parameter: positions within [lo, hi], widths and slopes positive."""
    if mf == "gaussmf" and index == 1:
        return 1e-3 * width, width
    if mf == "gbellmf" and index == 0:
        return 1e-3 * width, width
    if mf == "gbellmf" and index == 1:
        return 0.1, 10.0
    if mf == "sigmf" and index == 1:
        return -50.0 / width, 50.0 / width
    return lo, hi
