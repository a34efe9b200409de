"""PSO-BA (Abed et al. 2022, Algorithm 1): a particle swarm tunes the bat algorithm's loudness
decay ``alpha`` and pulse-rate constant ``gamma``; each particle is scored by one bat run. A
general optimizer (it knows nothing of robots; the PSO-BA planner gives it its fitness)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError
from hybridnav.planners.swarm._core import OptResult
from hybridnav.planners.swarm.bat import bat
from hybridnav.planners.swarm.pso import pso

__all__ = ["PSOBAResult", "pso_ba"]


@dataclass
class PSOBAResult:
    """Outcome of one PSO-BA search.

    Attributes
    ----------
    x : ndarray, shape (d,)
        The best bat position found over all bat runs.
    fitness : float
        Its fitness.
    alpha, gamma : float
        The bat parameters of the run that found it.
    bat_runs : int
        Bat searches run (one per PSO particle evaluation).
    pso : OptResult
        The PSO over ``(alpha, gamma)`` (its values are minus the best fitness of each run).
    run_best : ndarray, shape (bat_runs, d)
        The best bat of each bat run, in the order the runs ran: the candidates the search
        compared (what an animation of the planner shows).
    run_fitness : ndarray, shape (bat_runs,)
        Their fitness.
    """

    x: NDArray[np.float64]
    fitness: float
    alpha: float
    gamma: float
    bat_runs: int
    pso: OptResult = field(repr=False)
    run_best: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 0)), repr=False)
    run_fitness: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0), repr=False)


def pso_ba(fitness, lower: ArrayLike, upper: ArrayLike, *, seed=None, particles: int = 5,
           pso_iterations: int = 5, bats: int = 12, bat_iterations: int = 12,
           alpha_bounds: tuple[float, float] = (0.1, 1.0),
           gamma_bounds: tuple[float, float] = (0.0, 1.0),
           init: ArrayLike | None = None, pso_w: float = 0.7298, pso_c1: float = 1.49618,
           pso_c2: float = 1.49618) -> PSOBAResult:
    """Maximize ``fitness`` with bats whose ``(alpha, gamma)`` a PSO tunes (Algorithm 1).

    Each PSO particle ``s = (alpha, gamma)`` is evaluated by one run of
    :func:`~hybridnav.planners.swarm.bat` (``bats`` bats, ``bat_iterations`` iterations, minimizing
    ``-fitness``) with those parameters; its PSO value is minus the best fitness that run found.
    :func:`~hybridnav.planners.swarm.pso` (``particles`` particles, ``pso_iterations``
    iterations) minimizes that value over the box ``alpha_bounds x gamma_bounds``. The result is the
    best bat of all runs.

    Parameters
    ----------
    fitness : callable
        Vectorized: ``fitness(X)``, ``X`` of shape ``(N, d)``, returns ``N`` values (higher is
        better).
    lower, upper : array_like, shape (d,)
        The bats' box.
    seed : int, SeedSequence, Generator or None
        Seed of the one generator the PSO and every bat run draw from.
    particles, pso_iterations, bats, bat_iterations : int
    alpha_bounds : (float, float)
        Range of the loudness decay, ``0 < lo < hi <= 1``.
    gamma_bounds : (float, float)
        Range of the pulse-rate constant, ``0 <= lo < hi``.
    init : array_like, shape (m, d), optional
        Starting bats of every run (``m <= bats``).
    pso_w, pso_c1, pso_c2 : float
        The PSO's inertia weight and coefficients (:func:`~hybridnav.planners.swarm.pso`'s
        defaults; the paper's eq. 9 has no inertia factor, ``pso_w = 1``).

    Returns
    -------
    PSOBAResult
    """
    a_lo, a_hi = map(float, alpha_bounds)
    g_lo, g_hi = map(float, gamma_bounds)
    if not 0.0 < a_lo < a_hi <= 1.0:
        raise HybridnavError(f"alpha_bounds: expected 0 < lo < hi <= 1, got {alpha_bounds!r}")
    if not 0.0 <= g_lo < g_hi:
        raise HybridnavError(f"gamma_bounds: expected 0 <= lo < hi, got {gamma_bounds!r}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    lo = np.asarray(lower, dtype=float)
    hi = np.asarray(upper, dtype=float)
    best: dict[str, Any] = {"f": -np.inf, "x": None, "alpha": math.nan, "gamma": math.nan,
                            "runs": 0}
    run_best: list[NDArray[np.float64]] = []
    run_fitness: list[float] = []

    def neg_fitness(X: NDArray[np.float64]) -> NDArray[np.float64]:
        return -np.asarray(fitness(X), dtype=float)

    def run_bats(S: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.empty(len(S))
        for k, (a, g) in enumerate(S):
            a = min(max(float(a), a_lo), a_hi)
            res = bat(neg_fitness, (lo, hi), n=bats, iterations=bat_iterations, seed=rng,
                      init=init, alpha=a, gamma=float(g))
            best["runs"] += 1
            out[k] = res.fun
            run_best.append(res.x.copy())
            run_fitness.append(-float(res.fun))
            if -res.fun > best["f"]:
                best.update(f=-res.fun, x=res.x.copy(), alpha=a, gamma=float(g))
        return out

    opt = pso(run_bats, ([a_lo, g_lo], [a_hi, g_hi]), n=particles, iterations=pso_iterations,
              seed=rng, w=pso_w, c1=pso_c1, c2=pso_c2)
    return PSOBAResult(x=best["x"], fitness=float(best["f"]), alpha=best["alpha"],
                       gamma=best["gamma"], bat_runs=best["runs"], pso=opt,
                       run_best=np.array(run_best, dtype=float).reshape(len(run_best), len(lo)),
                       run_fitness=np.array(run_fitness, dtype=float))
