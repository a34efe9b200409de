"""The genetic algorithm (DEAP operators) behind the step interface.

Generation 0 is the starting vector, ``init_local`` of the rest drawn around it (Gaussian,
``init_sigma`` of each gene's range, repaired) and the others uniformly in the box. Every later
generation: tournament selection of ``population - elite`` parents, crossover of consecutive
pairs with ``crossover_prob``, mutation with ``mutation_prob``, repair, evaluation of the
changed individuals only, and elitism through a hall of fame whose best ``elite`` members enter
the next generation unchanged.

Defaults: population 100, 25 generations (2,600 evaluations at most: the EFFC paper's GA),
tournament 3, 2 elites, SBX (eta 15) with probability 0.9, polynomial mutation (eta 20, each
gene with probability 0.2) with probability 0.3.
"""

from __future__ import annotations

import random
from typing import Any, ClassVar

import numpy as np
from deap import tools

from hybridnav.errors import HybridnavError
from hybridnav.params import Param
from hybridnav.tuner.optimizers.base import (
    Optimizer,
    Problem,
    random_state,
    rng_state,
    set_random_state,
    set_rng_state,
)
from hybridnav.tuner.optimizers.operators import (
    SBX,
    Individual,
    Polynomial,
    crossover_from,
    deap_random,
    describe,
    mutation_from,
)

__all__ = ["GA", "Evolutionary", "initial_population"]

_UNIT = {"lo": 0.0, "hi": 1.0}


def initial_population(problem: Problem, n: int, local: float, sigma: float,
                       rng: np.random.Generator) -> np.ndarray:
    """The start, ``round(local (n - 1))`` Gaussian neighbours of it (``sigma`` of each gene's
    range) and uniform random vectors, all repaired."""
    x0 = problem.x0
    n_local = int(round(local * (n - 1)))
    span = problem.upper - problem.lower
    near = problem.clip(x0 + rng.normal(0.0, 1.0, (n_local, problem.dim)) * sigma * span)
    far = problem.clip(problem.lower + span * rng.random((n - 1 - n_local, problem.dim)))
    return np.vstack([x0[None], near, far])


class Evolutionary(Optimizer):
    """What the real-coded evolutionary optimizers (:class:`GA`, :class:`NSGA2`) share: their
    operator objects, generation 0 (:func:`initial_population`), DEAP individuals and their
    JSON state."""

    def _check(self) -> None:
        v = self.values
        v["crossover"] = crossover_from(v["crossover"], f"{self.name}: crossover")
        v["mutation"] = mutation_from(v["mutation"], f"{self.name}: mutation")

    def config(self) -> dict[str, Any]:
        c = super().config()
        c["crossover"], c["mutation"] = describe(c["crossover"]), describe(c["mutation"])
        return c

    def _setup(self, problem: Problem, seed: int) -> None:
        v = self.values
        self.rnd = random.Random(seed)
        self.rng = np.random.default_rng(seed)
        self._m = problem.n_obj
        X = initial_population(problem, v["population"], v["init_local"], v["init_sigma"],
                               self.rng)
        self.pop = [Individual(x, self._m) for x in X]
        self._pending: list[Individual] = []
        self._low, self._up = problem.lower.tolist(), problem.upper.tolist()

    def _reevaluate(self) -> np.ndarray:
        """Generation 0 of a stage: the whole population is evaluated (again)."""
        for ind in self.pop:
            del ind.fitness.values
        self._pending = list(self.pop)
        return np.array(self.pop, dtype=float)

    def population(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array(self.pop, dtype=float),
                np.array([i.fitness.values for i in self.pop], dtype=float))

    def _new_stage(self) -> None:
        pass                                  # ask() at generation 0 re-evaluates the population

    @staticmethod
    def _dump(ind) -> dict[str, Any]:
        return {"x": list(ind), "f": list(ind.fitness.values) if ind.fitness.valid else None}

    def _load(self, d) -> Individual:
        ind = Individual(d["x"], self._m)
        if d["f"] is not None:
            ind.fitness.values = tuple(d["f"])
        return ind

    def _random_state(self) -> dict[str, Any]:
        return {"python_random": random_state(self.rnd), "numpy_random": rng_state(self.rng)}

    def _set_random_state(self, state: dict[str, Any]) -> None:
        self.rnd = set_random_state(state["python_random"])
        self.rng = set_rng_state(state["numpy_random"])


class GA(Evolutionary):
    """Genetic algorithm: tournament selection, crossover and mutation objects, elitism.

    Parameters
    ----------
    population, generations, tournament, elite, crossover_prob, mutation_prob, init_local,
    init_sigma : see ``GA.parameters``
    crossover : SBX, Blend, "sbx", "blend" or {kind = ..., settings}
    mutation : Polynomial, Gaussian, "polynomial", "gaussian" or {kind = ..., settings}
    """

    name = "ga"
    parameters: ClassVar[dict[str, Param]] = {
        "population": Param(100, "individuals per generation", lo=2, hi=100_000),
        "generations": Param(25, "generations after the initial one", lo=0, hi=100_000),
        "tournament": Param(3, "tournament size", lo=1),
        "elite": Param(2, "hall-of-fame members copied into every new generation", lo=0),
        "crossover": Param(SBX(), "crossover operator (SBX or Blend)", kind=object),
        "crossover_prob": Param(0.9, "probability that a pair is crossed", **_UNIT),
        "mutation": Param(Polynomial(), "mutation operator (Polynomial or Gaussian)",
                          kind=object),
        "mutation_prob": Param(0.3, "probability that an individual mutates", **_UNIT),
        "init_local": Param(0.5, "generation 0: fraction drawn around the starting system",
                            **_UNIT),
        "init_sigma": Param(0.1, "their Gaussian spread, fraction of each gene's range",
                            lo=0.0),
    }

    def _check(self) -> None:
        super()._check()
        v = self.values
        if v["elite"] >= v["population"]:
            raise HybridnavError(f"{self.name}: elite: expected fewer elites than the "
                                 f"population ({v['population']}), got {v['elite']}")
        if v["tournament"] > v["population"]:
            raise HybridnavError(f"{self.name}: tournament: expected at most the population "
                                 f"({v['population']}), got {v['tournament']}")

    # ---- run -------------------------------------------------------------------------------

    def _setup(self, problem: Problem, seed: int) -> None:
        super()._setup(problem, seed)
        self.hof = None

    def ask(self) -> np.ndarray:
        v = self.values
        if self.generation == 0:            # (re-)evaluate the whole population
            self._offspring = None
            return self._reevaluate()
        elite = v["elite"]
        with deap_random(self.rnd):
            offspring = [self._clone(i) for i in tools.selTournament(
                self.pop, len(self.pop) - elite, v["tournament"])]
            for a, b in zip(offspring[::2], offspring[1::2]):
                if self.rnd.random() < v["crossover_prob"]:
                    v["crossover"](a, b, self._low, self._up)
                    del a.fitness.values, b.fitness.values
            for ind in offspring:
                if self.rnd.random() < v["mutation_prob"]:
                    v["mutation"](ind, self._low, self._up)
                    del ind.fitness.values
        changed = [i for i in offspring if not i.fitness.valid]
        if changed:
            fixed = self.problem.repair(np.array(changed, dtype=float))
            for ind, r in zip(changed, fixed):
                ind[:] = r.tolist()
        self._pending, self._offspring = changed, offspring
        return np.array(changed, dtype=float).reshape(len(changed), self.problem.dim)

    def tell(self, X: np.ndarray, F: np.ndarray) -> None:
        F = np.asarray(F, dtype=float).reshape(len(self._pending), self._m)
        for ind, f in zip(self._pending, F):
            ind.fitness.values = tuple(float(x) for x in f)
        if self._offspring is None:          # generation 0 of a stage
            self.hof = tools.HallOfFame(max(1, self.values["elite"]))
            self.hof.update(self.pop)
        else:
            elite = self.values["elite"]
            self.pop = [self._clone(h) for h in self.hof[:elite]] + self._offspring
            self.hof.update(self.pop)
        self._pending, self._offspring = [], None
        self.generation += 1

    def best(self) -> tuple[np.ndarray, np.ndarray]:
        """The hall of fame's best vector and its objectives."""
        h = self.hof[0]
        return np.array(h, dtype=float), np.array(h.fitness.values, dtype=float)

    def _clone(self, ind: Individual) -> Individual:
        new = Individual(ind, self._m)
        if ind.fitness.valid:
            new.fitness.values = ind.fitness.values
        return new

    # ---- state -----------------------------------------------------------------------------

    def _state(self) -> dict[str, Any]:
        return {"population": [self._dump(i) for i in self.pop],
                "hall_of_fame": [self._dump(i) for i in self.hof] if self.hof else None,
                **self._random_state()}

    def _set_state(self, state: dict[str, Any]) -> None:
        self.pop = [self._load(d) for d in state["population"]]
        self.hof = None
        if state["hall_of_fame"] is not None:
            self.hof = tools.HallOfFame(max(1, self.values["elite"]))
            self.hof.update([self._load(d) for d in state["hall_of_fame"]])
        self._set_random_state(state)
