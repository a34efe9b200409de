"""Particle swarm optimization behind the step interface — the update of the project's own swarm
PSO (:func:`hybridnav.planners.swarm.pso`: inertia weight, synchronous global best, velocity
limit, reflection at the walls), asked and told one swarm at a time.

Generation 0 is the starting vector and ``n - 1`` particles uniform in the box; velocities start
uniform in ``[-vmax, vmax]`` times each range. Defaults: 30 particles, 60 generations, Clerc's
constriction-equivalent coefficients (w 0.7298, c1 = c2 = 1.49618), vmax 0.2.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from hybridnav.params import Param
from hybridnav.planners.swarm._core import fold
from hybridnav.tuner.optimizers.base import Optimizer, Problem, rng_state, set_rng_state

__all__ = ["PSO"]


class PSO(Optimizer):
    """Global-best particle swarm (Kennedy & Eberhart 1995, inertia weight of Shi & Eberhart)."""

    name = "pso"
    default_patience = 15
    parameters: ClassVar[dict[str, Param]] = {
        "n": Param(30, "particles", lo=2, hi=100_000),
        "generations": Param(60, "generations after the initial one", lo=0, hi=100_000),
        "w": Param(0.7298, "inertia weight"),
        "c1": Param(1.49618, "cognitive coefficient", lo=0.0),
        "c2": Param(1.49618, "social coefficient", lo=0.0),
        "vmax": Param(0.2, "velocity limit, a fraction of each range", lo=0.0, lo_open=True,
                      hi=1.0),
    }

    def _setup(self, problem: Problem, seed: int) -> None:
        v = self.values
        self.rng = np.random.default_rng(seed)
        span = problem.upper - problem.lower
        n = v["n"]
        X = problem.lower + span * self.rng.random((n, problem.dim))
        X[0] = problem.x0
        self.X = problem.clip(X)
        self.V = self.rng.uniform(-v["vmax"] * span, v["vmax"] * span, (n, problem.dim))
        self.F = np.full((n, 1), np.inf)
        self.P, self.PF = self.X.copy(), np.full(n, np.inf)

    def ask(self) -> np.ndarray:
        if self.generation == 0:
            return self.X
        v, p = self.values, self.problem
        vlim = v["vmax"] * (p.upper - p.lower)
        g = self.P[int(np.argmin(self.PF))]
        r1 = self.rng.random(self.X.shape)
        r2 = self.rng.random(self.X.shape)
        V = v["w"] * self.V + v["c1"] * r1 * (self.P - self.X) + v["c2"] * r2 * (g - self.X)
        V = np.clip(V, -vlim, vlim)
        X, flipped = fold(self.X + V, p.lower, p.upper)
        self.V = np.where(flipped, -V, V)
        self.X = p.repair(X)
        return self.X

    def tell(self, X: np.ndarray, F: np.ndarray) -> None:
        F = np.asarray(F, dtype=float).reshape(len(self.X), -1)
        f = np.where(np.isnan(F[:, 0]), np.inf, F[:, 0])
        improved = f < self.PF
        self.P[improved], self.PF[improved] = self.X[improved], f[improved]
        self.F = F
        self.generation += 1

    def population(self) -> tuple[np.ndarray, np.ndarray]:
        return self.X, self.F

    def _new_stage(self) -> None:
        self.PF[:] = np.inf                   # the personal bests' values are stale

    def _state(self) -> dict[str, Any]:
        return {"X": self.X.tolist(), "V": self.V.tolist(), "F": self.F.tolist(),
                "P": self.P.tolist(), "PF": self.PF.tolist(), "numpy_random": rng_state(self.rng)}

    def _set_state(self, state: dict[str, Any]) -> None:
        for k in ("X", "V", "F", "P", "PF"):
            setattr(self, k, np.array(state[k], dtype=float))
        self.rng = set_rng_state(state["numpy_random"])
