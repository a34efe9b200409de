"""What of a fuzzy system a tuner may change: :class:`TunableSettings` (MATLAB's
``getTunableSettings``).

A :class:`TunableSettings` is built from a system. Per variable, term and membership-function
parameter it says whether the number is free and within which bounds; per rule whether the rule may
be switched off, whether its weight and its consequent are free. It maps a system to a bounded real
vector (:meth:`~TunableSettings.to_vector`) and a vector back to a system
(:meth:`~TunableSettings.to_system`), a whole population of vectors to the sampled tables one
batched evaluation needs (:meth:`~TunableSettings.tables`), repairs invalid vectors
(:meth:`~TunableSettings.repair`) and prints as a table.

Genes, in this order:

* ``mf``: each free parameter of each term of each variable (inputs in order, then the output).
  Positions are bounded by the variable's range widened by ``margin`` times its width on each side
  (or by the bounds given with :meth:`~TunableSettings.bound`) — a Z or S curve can then reach past
  the range end, so that a rule can fire on the whole input range; widths and slopes (``gaussmf``
  sigma, ``gbellmf`` a and b, ``sigmf`` slope) get their own positive bounds;
* per rule, when free: ``switch`` (in [0, 1]; the rule is on when >= 0.5, and at least one rule
  always stays on: the one with the largest gene), ``weight`` (in [0, 1]), ``consequent`` (in
  [0, T), the output term ``floor(gene)``).

Real-valued switches and consequents let the same real-coded operators act on every gene.
:meth:`~TunableSettings.repair` clips to the bounds and keeps each term's parameters valid
(``zmf``/``smf`` a < b, ``trimf`` a <= b <= c, ``trapmf`` a <= b <= c <= d).

Settings are immutable: :meth:`~TunableSettings.free`, :meth:`~TunableSettings.fix`,
:meth:`~TunableSettings.bound` and :meth:`~TunableSettings.rules` return new settings::

    s = TunableSettings(fis).fix("tip").bound("service", 0, 12).rules(weights=True)
"""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.params import short_repr

__all__ = ["Gene", "TunableSettings"]

_ORDERED = ("zmf", "smf", "trimf", "trapmf")
#: per MF type, the parameters at the left and right end of its support (None: unbounded)
_EDGES = {"zmf": (None, 1), "smf": (0, None), "trimf": (0, 2), "trapmf": (0, 3)}
_RULE_KINDS = ("switch", "weight", "consequent")
_PATH = re.compile(r"^(?P<var>[^.\[\]]+)(?:\.(?P<term>[^.\[\]]+)(?:\.(?P<mf>[^.\[\]]+))?)?"
                   r"(?:\[(?P<param>\d+)\])?$")


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


class TunableSettings:
    """The free numbers of a fuzzy system and their bounds.

    Parameters
    ----------
    system : FuzzySystem
        The system to tune (the template: its structure is kept, its numbers are the start).
    mf : bool or iterable of str, optional
        Which membership-function parameters are free: True (default) every parameter of every
        variable, False none, or paths ``"var"``, ``"var.term"`` or ``"var.term[i]"`` (also
        ``"var.term.mf[i]"``, as the table's labels write them).
    rule_switches, rule_weights, rule_consequents : bool, optional
        Whether every rule may be switched off, whether the rule weights and the rules' output
        terms are free (default: none of them).
    margin : float, optional
        Term positions may pass a variable's range ends by this times its width (default 0.25).
    bounds : mapping of str to (lo, hi), optional
        Per variable name, the bounds of its term positions (replaces range and margin).
    min_overlap : float, optional
        An interpretability constraint, kept by :meth:`repair`: the supports of neighbouring
        terms (in the variable's term order; ``zmf``, ``smf``, ``trimf``, ``trapmf``) overlap by at
        least this fraction of the variable's range, so that no input falls between two terms
        (default 0: not enforced).

    Attributes
    ----------
    template : FuzzySystem
    genes : list of Gene
    lower, upper : ndarray
        The bounds of the vector.
    labels : list of str
        Per gene ``var.term.mf[i]``, ``rule3.on``, ``rule3.weight`` or ``rule3.then``.

    Examples
    --------
    >>> from hybridnav import fuzzy
    >>> s = TunableSettings(fuzzy.builtin("effc-2rule"), mf=["alpha"], rule_weights=True)
    >>> s.size
    6
    >>> s.to_system(s.to_vector()) == s.to_system(s.to_vector())
    True
    """

    def __init__(self, system, *, mf: bool | Iterable[str] = True, rule_switches: bool = False,
                 rule_weights: bool = False, rule_consequents: bool = False,
                 margin: float = 0.25, bounds: Mapping[str, Sequence[float]] | None = None,
                 min_overlap: float = 0.0) -> None:
        from hybridnav.fuzzy import FuzzySystem

        if not isinstance(system, FuzzySystem):
            raise HybridnavError(f"system: expected a FuzzySystem, got {type(system).__name__}")
        self.template = system
        self.variables = list(system.inputs) + [system.output]
        self._names = [v.name for v in self.variables]
        if not (isinstance(margin, (int, float)) and not isinstance(margin, bool)
                and math.isfinite(margin) and 0 <= margin <= 100):
            raise HybridnavError(f"margin: expected a number in [0, 100], got {margin!r}")
        self.margin = float(margin)
        if isinstance(min_overlap, bool) or not isinstance(min_overlap, (int, float)) or \
                not 0.0 <= min_overlap <= 1.0:
            raise HybridnavError(f"min_overlap: expected a number in [0, 1], got "
                                 f"{min_overlap!r}")
        self.min_overlap = float(min_overlap)
        self._learn = False
        self._codes0: np.ndarray | None = None    # learning: the slots' initial codes
        self._on0: np.ndarray | None = None
        self._free: set[tuple[int, int, int]] = set()
        self._bounds: dict[int, tuple[float, float]] = {}
        n_rules = len(system.rules)
        self._rule = {k: [False] * n_rules for k in _RULE_KINDS}
        if mf is True:
            self._free = set(self._mf_paths(None))
        elif mf is not False:
            if isinstance(mf, str):
                mf = [mf]
            if not isinstance(mf, (list, tuple, set)):
                raise HybridnavError(f"mf: expected true, false or a list of variable, term or "
                                     f"parameter paths, got {mf!r}")
            for path in mf:
                self._free |= set(self._mf_paths(path))
        for key, kind, on in (("rule_switches", "switch", rule_switches),
                              ("rule_weights", "weight", rule_weights),
                              ("rule_consequents", "consequent", rule_consequents)):
            if not isinstance(on, bool):
                raise HybridnavError(f"{key}: expected true or false, got {on!r}")
            self._rule[kind] = [on] * n_rules
        if bounds is not None and not isinstance(bounds, Mapping):
            raise HybridnavError(f"bounds: expected a table of [lo, hi] per variable, got "
                                 f"{bounds!r}")
        for name, b in (bounds or {}).items():
            self._set_bounds(name, b)
        self._build()

    # ---- construction --------------------------------------------------------------------

    @classmethod
    def from_table(cls, system, table: Mapping[str, Any], where: str = "") -> TunableSettings:
        """Settings from a job file's ``[settings]`` (or old ``[free]``) table.

        Keys: ``mf`` (variable, term or parameter paths that are free; the old name) or
        ``free``, ``fixed`` (paths fixed again), ``rule_switches``, ``rule_weights``,
        ``rule_consequents`` (for the rules numbered in ``rules``, 1-based; default all),
        ``margin``, ``bounds`` (``{var = [lo, hi]}``), ``min_overlap``.
        """
        t = dict(table)
        free = t.get("free", t.get("mf", True))
        rules = t.get("rules") or []
        try:
            s = cls(system, mf=free, margin=t.get("margin", 0.25),
                    bounds=t.get("bounds") or {}, min_overlap=t.get("min_overlap", 0.0))
            n = len(system.rules)
            if not (isinstance(rules, list) and all(
                    isinstance(r, int) and not isinstance(r, bool) and 1 <= r <= n
                    for r in rules)):
                raise HybridnavError(f"rules: expected rule numbers in [1, {n}], got {rules!r}")
            s = s.rules(switches=t.get("rule_switches", False),
                        weights=t.get("rule_weights", False),
                        consequents=t.get("rule_consequents", False),
                        which=[r - 1 for r in rules] if rules else None)
            for path in t.get("fixed", []):
                s = s.fix(path)
        except HybridnavError as exc:
            raise HybridnavError(f"{where}{exc}") from None
        return s

    @classmethod
    def learning(cls, system, max_rules: int = 10, *, keep_rules: bool = True,
                 mf: bool | Iterable[str] = False, rule_weights: bool = False,
                 margin: float = 0.25,
                 bounds: Mapping[str, Sequence[float]] | None = None) -> TunableSettings:
        """Settings that *learn* a rule base (MATLAB's ``OptimizationType = "learning"``).

        The system gets ``max_rules`` rule slots; per slot the genes are: on/off, per input a
        term, NOT a term, or "don't care", the consequent, and (``rule_weights``) the weight.
        The system's own rules that are conjunctions of (negated) terms over distinct inputs
        start in the first slots (a partial rule base); the other slots start off (an empty
        rule base when the system's rules are all left out by ``max_rules``). A slot whose
        inputs are all "don't care" is off; at least one slot is always on. Membership
        functions are fixed unless ``mf`` frees them (MATLAB's two-stage process learns the
        rules first, then tunes the MFs of the learned system: :func:`hybridnav.tuner.learn`).

        Parameters
        ----------
        system : FuzzySystem
            Its variables and terms; its rules are the initial rule base.
        max_rules : int
            Rule slots.
        keep_rules : bool
            Start from the system's rules (a partial rule base); False: from an empty one.
        mf, margin, bounds :
            As for :class:`TunableSettings` (default: membership functions fixed).
        rule_weights : bool
            Learn the rule weights too.
        """
        from hybridnav.fuzzy import FuzzySystem

        if not isinstance(system, FuzzySystem):
            raise HybridnavError(f"system: expected a FuzzySystem, got {type(system).__name__}")
        if isinstance(max_rules, bool) or not isinstance(max_rules, (int, np.integer)) or \
                not 1 <= max_rules <= 1000:
            raise HybridnavError(f"max_rules: expected an integer in [1, 1000], got "
                                 f"{max_rules!r}")
        max_rules = int(max_rules)
        if not isinstance(keep_rules, bool):
            raise HybridnavError(f"keep_rules: expected true or false, got {keep_rules!r}")
        names = list(system.input_names)
        codes, on, rules = [], [], []
        for r in system.rules:
            c = _conjunctive_codes(r.antecedent, system)
            if c is None or len(rules) == max_rules or not keep_rules:
                continue
            codes.append(c)
            on.append(True)
            rules.append({"if": [names[0], system.inputs[0].terms[0].name], "then": r.then,
                          "weight": r.weight})
        while len(rules) < max_rules:              # empty slots
            codes.append([0] * len(names))
            on.append(False)
            rules.append({"if": [names[0], system.inputs[0].terms[0].name],
                          "then": system.output.terms[0].name, "weight": 1.0})
        d = system.to_dict()
        d["rules"] = rules
        template = FuzzySystem.from_dict(d)
        s = cls(template, mf=mf, rule_weights=rule_weights, margin=margin, bounds=bounds)
        s._learn = True
        s.kept_rules = sum(on)               # the start's rules a slot could hold
        s._codes0 = np.array(codes, dtype=np.intp).reshape(max_rules, len(names))
        s._on0 = np.array(on, dtype=bool)
        s._build()
        return s

    @property
    def learns_rules(self) -> bool:
        """Whether these settings learn a rule base (:meth:`learning`)."""
        return self._learn

    def _copy(self) -> TunableSettings:
        new = copy.copy(self)
        new._free = set(self._free)
        new._bounds = dict(self._bounds)
        new._rule = {k: list(v) for k, v in self._rule.items()}
        return new

    def _mf_paths(self, path: str | None) -> list[tuple[int, int, int]]:
        """The (var, term, param) triples a path names (None: all)."""
        if path is None:
            return [(vi, ti, pi) for vi, v in enumerate(self.variables)
                    for ti, t in enumerate(v.terms) for pi in range(len(t.params))]
        m = _PATH.match(path) if isinstance(path, str) else None
        if m is None or m["var"] not in self._names:
            raise HybridnavError(f"{path!r}: expected a variable of {self.template.name!r} "
                                 f"({', '.join(self._names)}), optionally .term and [index]")
        vi = self._names.index(m["var"])
        v = self.variables[vi]
        terms = list(range(len(v.terms)))
        if m["term"] is not None:
            if m["term"] not in v.term_names():
                raise HybridnavError(f"{path!r}: {v.name} has no term {m['term']!r} (terms: "
                                     f"{', '.join(v.term_names())})")
            terms = [v.term_names().index(m["term"])]
            if m["mf"] is not None and m["mf"] != v.terms[terms[0]].mf:
                raise HybridnavError(f"{path!r}: {v.name}.{m['term']} is a "
                                     f"{v.terms[terms[0]].mf}, not a {m['mf']}")
        out = []
        for ti in terms:
            n = len(v.terms[ti].params)
            params = range(n)
            if m["param"] is not None:
                if m["term"] is None or int(m["param"]) >= n:
                    raise HybridnavError(f"{path!r}: a parameter index needs a term and must be "
                                         f"below its number of parameters ({n})")
                params = [int(m["param"])]
            out += [(vi, ti, pi) for pi in params]
        return out

    def _set_bounds(self, name: str, b: Any) -> None:
        if name not in self._names:
            raise HybridnavError(f"bounds.{name}: not a variable of {self.template.name!r} "
                                 f"({', '.join(self._names)})")
        ok = (isinstance(b, (list, tuple)) and len(b) == 2
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in b))
        if ok:
            try:
                lo, hi = float(b[0]), float(b[1])
            except OverflowError:
                ok = False
            else:
                ok = (math.isfinite(lo) and math.isfinite(hi) and lo < hi
                      and math.isfinite(hi - lo) and hi - lo > 1e-9 * max(abs(lo), abs(hi)))
        if not ok:
            raise HybridnavError(f"bounds.{name}: expected [lo, hi] with finite lo < hi (and a "
                                 f"finite width, not vanishing against lo and hi), got "
                                 f"{short_repr(b)}")
        self._bounds[self._names.index(name)] = (lo, hi)

    def _paths(self, paths) -> list[str]:
        for p in paths:
            if not isinstance(p, str):
                raise HybridnavError(f"{p!r}: expected a path 'var', 'var.term' or "
                                     "'var.term[i]'")
        return list(paths)

    def free(self, *paths: str) -> TunableSettings:
        """New settings with the parameters of ``paths`` (``var``, ``var.term``,
        ``var.term[i]``) free."""
        new = self._copy()
        for p in self._paths(paths):
            new._free |= set(new._mf_paths(p))
        new._build()
        return new

    def fix(self, *paths: str) -> TunableSettings:
        """New settings with the parameters of ``paths`` fixed at the template's values."""
        new = self._copy()
        for p in self._paths(paths):
            new._free -= set(new._mf_paths(p))
        new._build()
        return new

    def bound(self, variable: str, lo: float, hi: float) -> TunableSettings:
        """New settings whose term positions of ``variable`` lie in ``[lo, hi]``."""
        new = self._copy()
        new._set_bounds(variable, [lo, hi])
        new._build()
        return new

    def rules(self, *, switches: bool | None = None, weights: bool | None = None,
              consequents: bool | None = None, which: Iterable[int] | None = None
              ) -> TunableSettings:
        """New settings in which the rules ``which`` (0-based; default all) may be switched off
        (``switches``), and have free weights / consequents; None leaves a setting as it is."""
        new = self._copy()
        n = len(self.template.rules)
        idx = range(n) if which is None else list(which)
        for i in idx:
            if not (isinstance(i, int) and 0 <= i < n):
                raise HybridnavError(f"which: expected rule indices in [0, {n - 1}], got {i!r}")
        for kind, on in zip(_RULE_KINDS, (switches, weights, consequents)):
            if on is None:
                continue
            if not isinstance(on, bool):
                raise HybridnavError(f"{kind}es: expected true, false or None, got {on!r}"
                                     if kind == "switch" else
                                     f"{kind}s: expected true, false or None, got {on!r}")
            for i in idx:
                new._rule[kind][i] = bool(on)
        new._build()
        return new

    def _build(self) -> None:
        genes: list[Gene] = []
        for vi, v in enumerate(self.variables):
            if vi in self._bounds:
                lo, hi = self._bounds[vi]
            else:
                pad = self.margin * (v.range[1] - v.range[0])
                lo, hi = v.range[0] - pad, v.range[1] + pad
            width = hi - lo
            for ti, t in enumerate(v.terms):
                for pi, _ in enumerate(t.params):
                    if (vi, ti, pi) not in self._free:
                        continue
                    b = _param_bounds(t.mf, pi, lo, hi, width)
                    own = float(t.params[pi])      # the start is always inside its own box
                    genes.append(Gene("mf", vi, ti, pi, min(b[0], own), max(b[1], own),
                                      f"{v.name}.{t.name}.{t.mf}[{pi}]"))
        n_terms = len(self.template.output.terms)
        for ri, _ in enumerate(self.template.rules):
            if self._learn:
                genes.append(Gene("switch", -1, ri, -1, 0.0, 1.0, f"rule{ri + 1}.on"))
                for vi, v in enumerate(self.template.inputs):
                    genes.append(Gene("antecedent", vi, ri, -1, 0.0,
                                      2 * len(v.terms) + 1 - 1e-9, f"rule{ri + 1}.{v.name}"))
                genes.append(Gene("consequent", -1, ri, -1, 0.0, n_terms - 1e-9,
                                  f"rule{ri + 1}.then"))
                if self._rule["weight"][ri]:
                    genes.append(Gene("weight", -1, ri, -1, 0.0, 1.0, f"rule{ri + 1}.weight"))
                continue
            if self._rule["switch"][ri]:
                genes.append(Gene("switch", -1, ri, -1, 0.0, 1.0, f"rule{ri + 1}.on"))
            if self._rule["weight"][ri]:
                genes.append(Gene("weight", -1, ri, -1, 0.0, 1.0, f"rule{ri + 1}.weight"))
            if self._rule["consequent"][ri]:
                genes.append(Gene("consequent", -1, ri, -1, 0.0, n_terms - 1e-9,
                                  f"rule{ri + 1}.then"))
        self.genes = genes
        self.lower = np.array([g.lower for g in genes], dtype=float)
        self.upper = np.array([g.upper for g in genes], dtype=float)
        if not (np.all(np.isfinite(self.upper - self.lower))):
            k = int(np.flatnonzero(~np.isfinite(self.upper - self.lower))[0])
            raise HybridnavError(f"{genes[k].label}: its bounds [{self.lower[k]:g}, "
                                 f"{self.upper[k]:g}] have no finite width (range, margin or "
                                 "bounds too large)")
        self.labels = [g.label for g in genes]
        self._out_index = {t.name: j for j, t in enumerate(self.template.output.terms)}
        groups: dict[tuple[int, int], list[int]] = {}
        for k, g in enumerate(genes):
            if g.kind == "mf":
                groups.setdefault((g.var, g.term), []).append(k)
        self._groups = groups
        self._col = {(g.var, g.term, g.param): k for k, g in enumerate(genes) if g.kind == "mf"}
        self._switch_cols = [k for k, g in enumerate(genes) if g.kind == "switch"]
        self._family = None

    # ---- views ----------------------------------------------------------------------------

    @property
    def size(self) -> int:
        """The number of free numbers (the vector's length)."""
        return len(self.genes)

    def key(self) -> dict[str, Any]:
        """Everything that determines the vector space (for configuration hashes)."""
        return {"system": self.template.to_dict(), "labels": self.labels,
                "lower": self.lower.tolist(), "upper": self.upper.tolist(),
                "min_overlap": self.min_overlap,
                "learning": None if not self._learn else
                [self._codes0.tolist(), self._on0.tolist()]}

    def table(self):
        """One row per gene: label, kind, lower and upper bound, and the template's value.

        Returns
        -------
        pandas.DataFrame
        """
        import pandas as pd

        x0 = self.to_vector()
        return pd.DataFrame({"gene": self.labels, "kind": [g.kind for g in self.genes],
                             "lower": self.lower, "upper": self.upper, "start": x0})

    def __str__(self) -> str:
        head = (f"TunableSettings of {self.template.name!r}: {self.size} free numbers "
                f"({sum(g.kind == 'mf' for g in self.genes)} MF parameters, "
                f"{sum(g.kind != 'mf' for g in self.genes)} rule genes)")
        return head + ("\n" + self.table().to_string(index=False) if self.size else "")

    def __repr__(self) -> str:
        return (f"<TunableSettings of {self.template.name!r}: "
                f"{len(getattr(self, 'genes', []))} free numbers>")

    def __getstate__(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        d["_family"] = None                    # rebuilt where it is used
        return d

    # ---- encode / repair / decode -----------------------------------------------------------

    def to_vector(self, system=None) -> np.ndarray:
        """The vector of ``system`` (default: the template), clipped to the bounds and repaired.

        ``system`` must be shaped like the template (same variables, terms and rules).
        """
        s = system or self.template
        variables = list(s.inputs) + [s.output]
        if system is not None and (
                [(v.name, tuple(len(t.params) for t in v.terms)) for v in variables]
                != [(v.name, tuple(len(t.params) for t in v.terms)) for v in self.variables]
                or len(s.rules) != len(self.template.rules)):
            raise HybridnavError(f"system: {s.name!r} is not shaped like {self.template.name!r} "
                                 "(the same variables, terms and number of rules)")
        x = np.empty(self.size)
        for k, g in enumerate(self.genes):
            if g.kind == "mf":
                x[k] = variables[g.var].terms[g.term].params[g.param]
            elif g.kind == "switch":
                x[k] = 1.0 if not self._learn else (1.0 if self._on0[g.term] else 0.25)
            elif g.kind == "antecedent":
                x[k] = self._codes0[g.term, g.var] + 0.5
            elif g.kind == "weight":
                x[k] = s.rules[g.term].weight
            else:
                x[k] = self._out_index[s.rules[g.term].then] + 0.5
        return self.repair(x[None])[0]

    def _matrix(self, X) -> np.ndarray:
        X = np.array(X, dtype=float, ndmin=2)
        if X.ndim != 2 or X.shape[1] != self.size:
            raise HybridnavError(f"X: expected vectors of {self.size} numbers (shape (n, "
                                 f"{self.size})), got shape {X.shape}")
        return X

    def random(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` vectors drawn uniformly within the bounds, repaired."""
        return self.repair(self.lower + (self.upper - self.lower) * rng.random((n, self.size)))

    def repair(self, X: np.ndarray) -> np.ndarray:
        """Clip to the bounds and restore each term's parameter order (rows of ``X``)."""
        X = np.clip(self._matrix(X), self.lower, self.upper)
        for (vi, ti), cols in self._groups.items():
            mf = self.variables[vi].terms[ti].mf
            if mf not in _ORDERED:
                continue
            full = len(self.variables[vi].terms[ti].params)
            if len(cols) < full:               # some fixed: keep the order with the fixed ones
                X[:, cols] = self._order_partial(X[:, cols], vi, ti, cols)
                continue
            X[:, cols] = np.sort(X[:, cols], axis=1)
            if mf in ("zmf", "smf"):            # strictly a < b
                a, b = cols
                width = self.upper[b] - self.lower[a]
                eps = max(1e-6 * width, 8 * float(np.spacing(max(abs(self.upper[b]),
                                                                 abs(self.lower[a])))))
                tight = X[:, b] - X[:, a] < eps
                X[tight, b] = np.minimum(X[tight, a] + eps, self.upper[b])
                X[tight, a] = X[tight, b] - eps
        if self.min_overlap > 0:
            self._overlap(X)
        return X

    def _overlap(self, X: np.ndarray) -> None:
        """Widen neighbouring terms' supports towards each other until they overlap by
        ``min_overlap`` of the range (as far as the bounds allow; moving a support end outwards
        keeps every term's parameter order)."""
        for vi, v in enumerate(self.variables):
            need = self.min_overlap * (v.range[1] - v.range[0])
            for j in range(len(v.terms) - 1):
                e0, e1 = _EDGES.get(v.terms[j].mf), _EDGES.get(v.terms[j + 1].mf)
                if e0 is None or e1 is None or e0[1] is None or e1[0] is None:
                    continue
                kr = self._col.get((vi, j, e0[1]))
                kl = self._col.get((vi, j + 1, e1[0]))
                if kr is None and kl is None:
                    continue
                r = X[:, kr] if kr is not None else np.full(len(X), v.terms[j].params[e0[1]])
                left = X[:, kl] if kl is not None else np.full(len(X),
                                                               v.terms[j + 1].params[e1[0]])
                deficit = np.maximum(need - (r - left), 0.0)
                share = 0.5 if kr is not None and kl is not None else 1.0
                if kr is not None:                 # half each; what a bound stops, the other
                    X[:, kr] = np.minimum(r + share * deficit, self.upper[kr])
                    deficit = deficit - (X[:, kr] - r)
                if kl is not None:
                    X[:, kl] = np.maximum(left - deficit, self.lower[kl])
                    deficit = deficit - (left - X[:, kl])
                if kr is not None and kl is not None:
                    X[:, kr] = np.minimum(X[:, kr] + np.maximum(deficit, 0.0), self.upper[kr])

    def _order_partial(self, Xc: np.ndarray, vi: int, ti: int, cols: list[int]) -> np.ndarray:
        """Keep a term's free parameters between its fixed neighbours."""
        term = self.variables[vi].terms[ti]
        fixed = list(term.params)
        pis = [self.genes[c].param for c in cols]
        # zmf/smf need a < b strictly: keep a small gap from a fixed neighbour
        span = self.upper[cols[0]] - self.lower[cols[0]]
        gap = max(1e-6 * span, 8 * float(np.spacing(max(abs(self.upper[cols[0]]),
                                                         abs(self.lower[cols[0]])))))\
            if term.mf in ("zmf", "smf") else 0.0
        out = Xc.copy()
        for j, pi in enumerate(pis):
            lo = max([fixed[p] + gap for p in range(pi) if p not in pis], default=-np.inf)
            hi = min([fixed[p] - gap for p in range(pi + 1, len(fixed)) if p not in pis],
                     default=np.inf)
            out[:, j] = np.clip(out[:, j], lo, hi)
        return np.sort(out, axis=1)

    def arrays(self, X: np.ndarray):
        """Per member: input MF parameters, output MF parameters, rule weights, consequents and
        switches (what :meth:`hybridnav.fuzzy.family.SystemFamily.tables` takes)."""
        X = self._matrix(X)
        K = len(X)
        base = [[list(t.params) for t in v.terms] for v in self.variables]
        params = [[[list(p) for p in v] for v in base] for _ in range(K)]
        weights = np.tile([r.weight for r in self.template.rules], (K, 1)).astype(float)
        cons = np.tile([self._out_index[r.then] for r in self.template.rules], (K, 1))
        switches = np.ones_like(weights, dtype=bool)
        n_terms = len(self.template.output.terms)
        for k, g in enumerate(self.genes):
            col = X[:, k]
            if g.kind == "mf":
                for m in range(K):
                    params[m][g.var][g.term][g.param] = float(col[m])
            elif g.kind == "switch":
                switches[:, g.term] = col >= 0.5
            elif g.kind == "weight":
                weights[:, g.term] = col
            elif g.kind == "consequent":
                cons[:, g.term] = np.clip(col.astype(int), 0, n_terms - 1)
        if self._learn:
            codes = self._rule_codes(X)
            switches &= ~(codes == 0).all(axis=2)            # no antecedent: off
            none = ~switches.any(axis=1)
            if none.any():                                   # the largest switch gene stays on
                best = np.argmax(X[np.ix_(none, self._switch_cols)], axis=1)
                rules = [self.genes[self._switch_cols[b]].term for b in best]
                switches[np.flatnonzero(none), rules] = True
        elif self._switch_cols:                  # at least one rule on: the largest switch gene
            none = ~switches.any(axis=1)
            if none.any():
                best = np.argmax(X[np.ix_(none, self._switch_cols)], axis=1)
                rules = [self.genes[self._switch_cols[b]].term for b in best]
                switches[np.flatnonzero(none), rules] = True
        weights = np.where(switches, weights, 0.0)
        n_in = len(self.template.inputs)
        return ([p[:n_in] for p in params], [p[n_in] for p in params], weights, cons, switches)

    def _rule_codes(self, X: np.ndarray) -> np.ndarray:
        """Learning: per member and slot the antecedent codes ``(K, R, inputs)``; a slot kept on
        only because no other is has its first input's first term when it had no antecedent."""
        K = len(X)
        codes = np.tile(self._codes0, (K, 1, 1))
        for k, g in enumerate(self.genes):
            if g.kind == "antecedent":
                top = 2 * len(self.template.inputs[g.var].terms)
                codes[:, g.term, g.var] = np.clip(np.floor(X[:, k]).astype(np.intp), 0, top)
        sw = X[:, self._switch_cols]
        on = (sw >= 0.5) & ~(codes == 0).all(axis=2)
        none = ~on.any(axis=1)
        if none.any():
            slot = np.argmax(sw[none], axis=1)
            rows = np.flatnonzero(none)
            empty = (codes[rows, slot] == 0).all(axis=1)
            codes[rows[empty], slot[empty], 0] = 1
        return codes

    @property
    def family(self):
        """The :class:`~hybridnav.fuzzy.family.SystemFamily` of the template (built once)."""
        if self._family is None:
            from hybridnav.fuzzy.family import SystemFamily

            self._family = SystemFamily(self.template)
        return self._family

    def tables(self, X: np.ndarray):
        """The sampled tables of every row of ``X``, for one batched
        :meth:`~hybridnav.fuzzy.family.SystemFamily.evaluate` of the whole population."""
        inp, out, weights, cons, _ = self.arrays(X)
        codes = self._rule_codes(self._matrix(X)) if self._learn else None
        return self.family.tables(inp, out, weights, cons, codes)

    def to_system(self, x: np.ndarray, name: str | None = None,
                  description: str | None = None):
        """The fuzzy system of one vector (switched-off rules removed)."""
        x = np.asarray(x, dtype=float)
        if x.size != self.size:
            raise HybridnavError(f"x: expected a vector of {self.size} numbers, got shape "
                                 f"{x.shape}")
        inp, out, weights, cons, switches = self.arrays(x.reshape(1, -1))
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
        codes = self._rule_codes(x.reshape(1, -1))[0] if self._learn else None
        rules = []
        for ri, r in enumerate(d["rules"]):
            if not switches[0, ri]:
                continue
            r = dict(r)
            if codes is not None:
                r["if"] = _antecedent_of(codes[ri], self.template)
            r["then"] = terms[int(cons[0, ri])]
            r["weight"] = float(weights[0, ri])
            rules.append(r)
        d["rules"] = rules
        from hybridnav.fuzzy import FuzzySystem

        return FuzzySystem.from_dict(d)

    def systems(self, X: np.ndarray) -> list:
        """:meth:`to_system` of every row of ``X``."""
        return [self.to_system(x) for x in np.array(X, dtype=float, ndmin=2)]


def _conjunctive_codes(a, system) -> list[int] | None:
    """The codes of an antecedent that is a conjunction of (negated) terms over distinct
    inputs, or None."""
    from hybridnav.fuzzy.spec import And, Not, TermRef

    parts = list(a.items) if isinstance(a, And) else [a]
    names = list(system.input_names)
    codes = [0] * len(names)
    for p in parts:
        neg = isinstance(p, Not)
        ref = p.item if neg else p
        if not isinstance(ref, TermRef):
            return None
        i = names.index(ref.input)
        if codes[i]:
            return None
        terms = system.inputs[i].term_names()
        j = terms.index(ref.term)
        codes[i] = 1 + j + (len(terms) if neg else 0)
    return codes


def _antecedent_of(codes, system) -> Any:
    """The ``hybridnav-fis/1`` antecedent of a slot's codes (at least one is non-zero)."""
    parts: list[Any] = []
    for i, c in enumerate(codes):
        if c == 0:
            continue
        v = system.inputs[i]
        T = len(v.terms)
        ref = [v.name, v.terms[(c - 1) % T].name]
        parts.append(ref if c <= T else {"not": ref})
    return parts[0] if len(parts) == 1 else {"and": parts}


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
