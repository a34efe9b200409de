"""Pseudo-bacterial potential field (Orozco-Rosas, Montiel & Sepúlveda 2015).

Offline, a pseudo-bacterial genetic algorithm (Nawa & Furuhashi) chooses the APF gains
``(xi, eta, rho0)`` for each robot of the scenario; then the APF runs with them. A bacterium is a
gain vector (searched in log space within ``gain_range`` of the APF defaults). Each generation:

* **bacterial mutation**: for every gene, in a random order drawn per generation, each bacterium
  is cloned ``clones`` times, the clones get that gene re-drawn at random, all clones and the
  original are evaluated, and the best one's gene is kept;
* **gene transfer**: the population is sorted; ``infections`` times a random bacterium of the
  better half copies a random gene into a random bacterium of the worse half.

The fitness of gains is the length of the APF path they produce (with the escape-circle safety
filter where the run has it: ``safety_margin`` and heading-controlled robots), or ``penalty``
times the straight-line distance plus the distance left when the robot does not reach the goal.
The search sees the map's exact geometry, also for a run with ``sensor = "lidar"``. The whole
population is simulated in lockstep: in the compiled APF control cycle with one gain row per
member (:func:`hybridnav.native.lockstep.apf_run`), or in NumPy
(:func:`hybridnav.planners.field.lockstep.lockstep_field`) where no compiler is found. Static
goals only (the search needs a fixed target).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import numpy as np

from hybridnav.planners.base import Param, searches_table
from hybridnav.planners.field.apf import APF, apf_force
from hybridnav.planners.field.lockstep import lockstep_field
from hybridnav.planners.field.worldstack import WorldStack

__all__ = ["PBPF"]

GENES = ("xi", "eta", "rho0")


@dataclasses.dataclass(frozen=True)
class _Tuned:
    """A run's tuned gains ``(n_robots, 3)`` and each robot's best fitness per generation."""

    gains: np.ndarray
    logs: list


class PBPF(APF):
    """APF whose gains a pseudo-bacterial GA tunes for the scenario first."""

    name = "pbpf"
    description = "pseudo-bacterial potential field: a bacterial GA tunes the APF gains offline"
    moving_targets = False
    stochastic = True
    parameters: ClassVar[dict[str, Param]] = {
        **APF.parameters,
        "population": Param(10, "bacteria", lo=2),
        "generations": Param(8, "generations", lo=1),
        "clones": Param(3, "clones per bacterium in the bacterial mutation", lo=1),
        "infections": Param(4, "gene transfers per generation", lo=0),
        "gain_range": Param(10.0, "search xi, eta, rho0 within [default / r, default * r]",
                            lo=1.0),
        "penalty": Param(10.0, "fitness of a run that fails: penalty * start-goal distance + "
                               "distance left", lo=0.0),
    }

    def prepare(self, scenario, rng: np.random.Generator) -> Any:
        """Tune the gains for each robot; returns ``(n_robots, 3)`` gains and the search log."""
        v = self.values
        base = np.log([v[g] for g in GENES])
        span = math.log(v["gain_range"])
        lo, hi = base - span, base + span
        tuned, logs = [], []
        for r in scenario.robots:
            single = dataclasses.replace(scenario, robots=[r])
            best, history = self._search(single, rng, lo, hi)
            tuned.append(np.exp(best))
            logs.append(history)
        return _Tuned(np.array(tuned), logs)

    def extras(self, scenario, state) -> dict[str, Any]:
        """Best fitness per generation of each robot's gain search (``swarm_best_<robot>``:
        ``plan`` 0, ``iteration`` the generation, ``best``), as every swarm search records it."""
        return {f"swarm_best_{r.name}": searches_table([np.asarray(h, dtype=float)])
                for r, h in zip(scenario.robots, state.logs)}

    def diagnostics(self, scenario, result):
        """``signals.png`` and ``pbpf_search.png`` (best fitness per generation, per robot)."""
        from hybridnav.plotting import plot_gain_search

        out = dict(super().diagnostics(scenario, result))
        fig = plot_gain_search(result, length=scenario.units)
        if fig is not None:
            out["pbpf_search.png"] = fig
        return out

    def gains(self, state: Any, idx: np.ndarray) -> dict[str, Any]:
        g = dict(super().gains(state, idx))
        for j, name in enumerate(GENES):
            g[name] = state.gains[idx, j]
        return g

    def _fitness(self, scenario, genomes: np.ndarray, stack=None) -> np.ndarray:
        """APF path length per log-gain vector (lockstep), penalized when the goal is missed.

        The population runs in the compiled control cycle
        (:func:`hybridnav.native.lockstep.apf_run` with one gain row per member) where it
        applies, else in NumPy: the same runs to the bit."""
        v = self.values
        gains = np.exp(genomes)
        radius = scenario.model(scenario.robots[0]).radius
        r = scenario.robots[0]
        overrides = self.model_overrides(r)
        res = self._compiled(scenario, gains, radius, overrides, stack)
        if res is None:
            res = self._numpy(scenario, gains, radius, overrides, stack)
        d0 = math.dist(r.start, r.goal)
        ok = res.outcome[0] == "reached"
        return np.where(ok, res.path_length[0], v["penalty"] * d0 + res.final_distance[0])

    def _compiled(self, scenario, gains, radius, overrides, stack):
        from hybridnav.native.lockstep import apf_run
        from hybridnav.planners.field.lockstep import prepare

        batch = prepare([scenario], len(gains), overrides, stack)
        return apf_run(batch, self.values, radius=np.array([float(radius)]), record_paths=False,
                       gains=gains)

    def _numpy(self, scenario, gains, radius, overrides, stack):
        v = self.values

        def field(env, members, P, goals, t):
            g = gains[members]
            F = apf_force(scenario.world, P, goals, radius, t, xi=g[:, 0], sigma0=v["sigma0"],
                          eta=g[:, 1], rho0=g[:, 2])
            small = np.hypot(F[:, 0], F[:, 1]) <= v["force_tol"] * g[:, 0] * v["sigma0"]
            F[small] = np.nan                  # a local minimum: stuck, as APF.velocity says
            return F

        return lockstep_field([scenario], len(gains), field, model_overrides=overrides,
                              speed=v["speed"], stuck_window=v["stuck_window"],
                              stuck_radius=v["stuck_radius"], stack=stack,
                              safety={"margin": v["safety_margin"], "max_turn": v["max_turn"]})

    def _search(self, scenario, rng, lo, hi):
        v = self.values
        n, nc, ng = v["population"], v["clones"], len(GENES)
        stack = WorldStack([scenario.world])         # one world packed for the whole search
        pop = lo + (hi - lo) * rng.random((n, ng))
        fit = self._fitness(scenario, pop, stack)
        history = [float(fit.min())]
        for _ in range(v["generations"]):
            # bacterial mutation, gene by gene; all bacteria and their clones in one batch
            for gene in rng.permutation(ng):
                clones = np.repeat(pop[:, None, :], nc + 1, axis=1)
                clones[:, 1:, gene] = lo[gene] + (hi[gene] - lo[gene]) * rng.random((n, nc))
                cf = self._fitness(scenario, clones.reshape(-1, ng), stack).reshape(n, nc + 1)
                cf[:, 0] = fit               # the original keeps its known fitness
                best = np.argmin(cf, axis=1)
                pop = clones[np.arange(n), best]
                fit = cf[np.arange(n), best]
            # gene transfer from the better half into the worse half
            if v["infections"] and n >= 2:
                order = np.argsort(fit, kind="stable")
                good, bad = order[: n // 2], order[n // 2:]
                targets = rng.choice(bad, size=v["infections"])
                sources = rng.choice(good, size=v["infections"])
                genes = rng.integers(0, ng, size=v["infections"])
                infected = pop.copy()
                infected[targets, genes] = pop[sources, genes]
                touched = np.unique(targets)
                fit[touched] = self._fitness(scenario, infected[touched], stack)
                pop = infected
            history.append(float(fit.min()))
        return pop[int(np.argmin(fit))], history
