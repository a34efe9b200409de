"""NSGA-II (Deb et al. 2002; DEAP's non-dominated sorting and crowding) behind the step
interface, for several objectives (all minimized).

Generation 0 is initialized as the GA's (the start, neighbours of it, uniform vectors). Every
later generation: binary tournaments on rank and crowding distance (``selTournamentDCD``),
crossover and mutation objects as the GA's, repair, evaluation of the ``population`` children,
and environmental selection of the next population from parents and children
(``selNSGA2``). The first front of the carried population is the Pareto front it reports.

Defaults: population 100 (a multiple of 4, as DEAP's tournament needs), 25 generations, SBX
(eta 15) with probability 0.9, polynomial mutation (eta 20) with probability 1 and each gene
with probability 1/d when ``gene_prob`` is 0.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from deap import tools

from hybridnav.errors import HybridnavError
from hybridnav.params import Param
from hybridnav.tuner.optimizers.base import Problem
from hybridnav.tuner.optimizers.ga import Evolutionary
from hybridnav.tuner.optimizers.operators import SBX, Individual, Polynomial, deap_random

__all__ = ["NSGA2", "non_dominated"]


def non_dominated(F: np.ndarray) -> np.ndarray:
    """Mask of the rows of ``F`` (all minimized) that no other row dominates."""
    F = np.asarray(F, dtype=float)
    le = np.all(F[:, None, :] <= F[None, :, :], axis=2)
    lt = np.any(F[:, None, :] < F[None, :, :], axis=2)
    dominated = np.any(le & lt, axis=0)
    return ~dominated


class NSGA2(Evolutionary):
    """Elitist non-dominated sorting genetic algorithm for several objectives."""

    name = "nsga2"
    multiobjective = True
    default_patience = 0
    parameters: ClassVar[dict[str, Param]] = {
        "population": Param(100, "individuals per generation (a multiple of 4)", lo=4,
                            hi=100_000),
        "generations": Param(25, "generations after the initial one", lo=0, hi=100_000),
        "crossover": Param(SBX(), "crossover operator (SBX or Blend)", kind=object),
        "crossover_prob": Param(0.9, "probability that a pair is crossed", lo=0.0, hi=1.0),
        "mutation": Param(Polynomial(gene_prob=0.0), "mutation operator (gene_prob 0: 1/d)",
                          kind=object),
        "mutation_prob": Param(1.0, "probability that a child mutates", lo=0.0, hi=1.0),
        "init_local": Param(0.5, "generation 0: fraction drawn around the start", lo=0.0,
                            hi=1.0),
        "init_sigma": Param(0.1, "their Gaussian spread, fraction of each gene's range",
                            lo=0.0),
    }

    def _check(self) -> None:
        super()._check()
        v = self.values
        if v["population"] % 4:
            raise HybridnavError(f"{self.name}: population: expected a multiple of 4 (DEAP's "
                                 f"tournament on rank and crowding), got {v['population']}")

    def _setup(self, problem: Problem, seed: int) -> None:
        super()._setup(problem, seed)
        mut = self.values["mutation"]
        if getattr(mut, "gene_prob", None) == 0.0:
            self._mutation = type(mut)(**{**vars(mut), "gene_prob": 1.0 / max(problem.dim, 1)})
        else:
            self._mutation = mut

    def ask(self) -> np.ndarray:
        v = self.values
        if self.generation == 0:
            self._children = None
            return self._reevaluate()
        with deap_random(self.rnd):
            parents = tools.selTournamentDCD(self.pop, len(self.pop))
            children = [Individual(p, self._m) for p in parents]
            for a, b in zip(children[::2], children[1::2]):
                if self.rnd.random() < v["crossover_prob"]:
                    v["crossover"](a, b, self._low, self._up)
            for c in children:
                if self.rnd.random() < v["mutation_prob"]:
                    self._mutation(c, self._low, self._up)
        fixed = self.problem.repair(np.array(children, dtype=float))
        for c, r in zip(children, fixed):
            c[:] = r.tolist()
        self._pending, self._children = children, children
        return fixed

    def tell(self, X: np.ndarray, F: np.ndarray) -> None:
        F = np.asarray(F, dtype=float).reshape(len(self._pending), self._m)
        F = np.where(np.isnan(F), np.inf, F)
        for ind, f in zip(self._pending, F):
            ind.fitness.values = tuple(float(x) for x in f)
        pool = self.pop if self._children is None else self.pop + self._children
        # selNSGA2 also assigns the crowding distances selTournamentDCD needs
        self.pop = tools.selNSGA2(pool, len(self.pop))
        self._pending, self._children = [], None
        self.generation += 1

    def _state(self) -> dict[str, Any]:
        return {"population": [{"x": list(i), "f": list(i.fitness.values)
                                if i.fitness.valid else None,
                                "crowding": getattr(i.fitness, "crowding_dist", None)}
                               for i in self.pop],
                **self._random_state()}

    def _set_state(self, state: dict[str, Any]) -> None:
        pop = []
        for d in state["population"]:
            ind = Individual(d["x"], self._m)
            if d["f"] is not None:
                ind.fitness.values = tuple(d["f"])
            if d.get("crowding") is not None:
                ind.fitness.crowding_dist = d["crowding"]
            pop.append(ind)
        self.pop = pop
        self._set_random_state(state)
