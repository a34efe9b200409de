"""CMA-ES (Hansen & Ostermeier 2001; DEAP's ``cma.Strategy``) behind the step interface.

The search runs in coordinates normalized to the box (each gene's range maps to [0, 1]), from
the starting vector with step size ``sigma`` (a fraction of every range). Each generation samples
``lambda_`` points from DEAP's strategy — with this optimizer's own seeded generator, not NumPy's
global one — clips and repairs them, evaluates them and updates the strategy with the repaired
points (the values belong to them).

Defaults: ``lambda_ = 4 + 3 ln d`` (DEAP's and Hansen's), ``sigma`` 0.1 of every range, 150
generations after the initial one (the initial generation evaluates only the start; 1,651
evaluations for 12 free numbers), and no early stopping on validation unless ``tune`` is given a
``patience`` (a generation of CMA-ES is a dozen samples: its validation best stalls for long
stretches while the step size adapts).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from deap import cma

from hybridnav.errors import HybridnavError
from hybridnav.params import Param
from hybridnav.tuner.optimizers.base import Optimizer, Problem, rng_state, set_rng_state
from hybridnav.tuner.optimizers.operators import Individual

__all__ = ["CMAES"]

# the strategy's attributes that change during a run (the rest follow from its settings)
_DYNAMIC = ("centroid", "sigma", "pc", "ps", "C", "diagD", "B", "BD", "cond", "update_count")


class _Strategy(cma.Strategy):
    """DEAP's strategy, sampling from a given generator."""

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        arz = rng.standard_normal((self.lambda_, self.dim))
        return self.centroid + self.sigma * np.dot(arz, self.BD.T)


class CMAES(Optimizer):
    """Covariance matrix adaptation evolution strategy.

    Parameters
    ----------
    generations : int
    lambda_ : int
        Offspring per generation (0: ``4 + 3 ln d``).
    sigma : float
        Initial step size, a fraction of each gene's range.
    """

    name = "cmaes"
    parameters: ClassVar[dict[str, Param]] = {
        "generations": Param(150, "generations after the initial one", lo=0, hi=100_000),
        "lambda_": Param(0, "offspring per generation (0: 4 + 3 ln d; else at least 2)", lo=0,
                         hi=100_000),
        "sigma": Param(0.1, "initial step, a fraction of each gene's range", lo=0.0,
                       lo_open=True, hi=10.0),
    }
    default_patience = 0

    def _check(self) -> None:
        if self.values["lambda_"] == 1:
            raise HybridnavError(f"{self.name}: lambda_: expected 0 (4 + 3 ln d) or an integer "
                                 ">= 2, got 1")

    def _setup(self, problem: Problem, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self._span = problem.upper - problem.lower
        z0 = (problem.x0 - problem.lower) / self._span
        kw = {}
        if self.values["lambda_"]:
            kw["lambda_"] = self.values["lambda_"]
        self.strategy = _Strategy(centroid=z0.tolist(), sigma=self.values["sigma"], **kw)
        self._X = problem.x0[None].copy()
        self._F = np.full((1, problem.n_obj), np.inf)
        self._pending: np.ndarray | None = None

    def _to_x(self, Z: np.ndarray) -> np.ndarray:
        return self.problem.lower + np.clip(Z, 0.0, 1.0) * self._span

    def ask(self) -> np.ndarray:
        if self.generation == 0:
            self._pending = self.problem.x0[None].copy()
        else:
            Z = self.strategy.sample(self.rng)
            self._pending = self.problem.repair(self._to_x(Z))
        return self._pending

    def tell(self, X: np.ndarray, F: np.ndarray) -> None:
        F = np.asarray(F, dtype=float).reshape(len(self._pending), -1)
        if self.generation > 0:
            pop = []
            for x, f in zip(self._pending, F):
                ind = Individual((x - self.problem.lower) / self._span)
                ind.fitness.values = (float(f[0]) if np.isfinite(f[0]) else 1e300,)
                pop.append(ind)
            self.strategy.update(pop)
        self._X, self._F = self._pending, F
        self._pending = None
        self.generation += 1

    def population(self) -> tuple[np.ndarray, np.ndarray]:
        return self._X, self._F

    def _new_stage(self) -> None:
        pass

    def _state(self) -> dict[str, Any]:
        s = {k: (v.tolist() if isinstance(v, np.ndarray) else v)
             for k, v in vars(self.strategy).items() if k in _DYNAMIC}
        # the arrays' memory order too: np.dot rounds differently on C and Fortran order
        order = {k: "F" for k, v in vars(self.strategy).items()
                 if k in _DYNAMIC and isinstance(v, np.ndarray) and v.ndim == 2
                 and v.flags.f_contiguous and not v.flags.c_contiguous}
        return {"strategy": s, "order": order, "numpy_random": rng_state(self.rng),
                "X": self._X.tolist(), "F": self._F.tolist()}

    def _set_state(self, state: dict[str, Any]) -> None:
        order = state.get("order", {})
        for k, v in state["strategy"].items():
            if k not in _DYNAMIC:
                raise HybridnavError(f"checkpoint: optimizer.strategy.{k}: unknown key")
            setattr(self.strategy, k,
                    np.array(v, dtype=float, order=order.get(k, "C")) if isinstance(v, list)
                    else v)
        self.rng = set_rng_state(state["numpy_random"])
        self._X = np.array(state["X"], dtype=float)
        self._F = np.array(state["F"], dtype=float)
