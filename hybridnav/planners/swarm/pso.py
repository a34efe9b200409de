"""Particle swarm optimization (Kennedy & Eberhart 1995; inertia weight, Shi & Eberhart 1998)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hybridnav.planners.swarm._core import (
    BoundsLike,
    Objective,
    OptResult,
    Run,
    SeedLike,
    check_int,
    check_real,
    fold,
    mean_value,
    uniform_population,
)

__all__ = ["pso"]


def pso(f: Objective, bounds: BoundsLike, *, n: int = 30, iterations: int | None = 100,
        max_evals: int | None = None, target: float | None = None, seed: SeedLike = None,
        init: ArrayLike | None = None, w: float = 0.7298, w_end: float | None = None,
        c1: float = 1.49618, c2: float = 1.49618, vmax: float = 0.2) -> OptResult:
    """Minimize ``f`` with global-best particle swarm optimization.

    Each iteration, for every particle (all at once, one call of ``f``)::

        v <- w_t v + c1 r1 (p - x) + c2 r2 (g - x)      r1, r2 uniform in [0, 1]^d
        v <- clip(v, -vmax (upper - lower), vmax (upper - lower))
        x <- x + v

    where ``p`` is the particle's best point and ``g`` the swarm's best point (taken at the start
    of the iteration: synchronous update). A coordinate that leaves the box is reflected back
    inside (``x <- 2 upper - x`` or ``x <- 2 lower - x``) and that velocity component is reversed;
    since ``vmax <= 1`` one reflection always suffices. Initial velocities are uniform in
    ``[-vmax, vmax] (upper - lower)``.

    Parameters
    ----------
    f : callable
        Vectorized objective: ``f(X)`` with ``X`` of shape ``(N, d)`` returns ``N`` values;
        NaN counts as ``+inf``.
    bounds : (lower, upper)
        Box of the search, two sequences of length ``d`` with ``lower < upper``.
    n : int, optional
        Number of particles.
    iterations : int or None, optional
        Maximum number of iterations.
    max_evals : int or None, optional
        Maximum number of evaluated points (``n`` initially and per iteration).
    target : float or None, optional
        Stop as soon as a value ``<= target`` has been found.
    seed : int, SeedSequence, Generator or None, optional
        Seed of the one :class:`numpy.random.Generator` all randomness comes from.
    init : array_like, shape (m, d), optional
        Starting points (``m <= n``); the other particles start uniformly at random.
    w : float, optional
        Inertia weight (default: Clerc's constriction-equivalent 0.7298).
    w_end : float or None, optional
        If given, the inertia decreases linearly from ``w`` (first iteration) to ``w_end`` (last
        iteration the budget allows), e.g. ``w=0.9, w_end=0.4``.
    c1, c2 : float, optional
        Cognitive and social acceleration coefficients (default 1.49618 each).
    vmax : float, optional
        Velocity limit as a fraction of the box size, ``0 < vmax <= 1``.

    Returns
    -------
    OptResult
        ``population``/``values`` are the final positions; ``state`` holds ``velocity``,
        ``pbest`` and ``pbest_values``; ``history.extra`` holds ``w`` and ``pbest_mean``.

    References
    ----------
    J. Kennedy, R. Eberhart, "Particle swarm optimization", Proc. ICNN 1995.
    Y. Shi, R. Eberhart, "A modified particle swarm optimizer", Proc. IEEE CEC 1998.
    M. Clerc, J. Kennedy, "The particle swarm - explosion, stability, and convergence in a
    multidimensional complex space", IEEE Trans. Evol. Comput. 6(1), 2002.
    """
    n = check_int("n", n, 1)
    w = check_real("w", w)
    w_end = None if w_end is None else check_real("w_end", w_end)
    c1 = check_real("c1", c1, 0.0)
    c2 = check_real("c2", c2, 0.0)
    vmax = check_real("vmax", vmax, 0.0, 1.0, lo_open=True)
    run = Run("pso", f, bounds, iterations, max_evals, target, seed)
    run.check_budget(n, n)
    planned = run.planned_iterations(n, n)
    vlim = vmax * run.span
    X = uniform_population(run.rng, run.lower, run.upper, n, init)
    V = run.rng.uniform(-vlim, vlim, (n, run.d))
    F = run.evaluate(X)
    P, PF = X.copy(), F.copy()
    run.record(F, w=np.nan, pbest_mean=mean_value(PF))
    while run.more():
        t = run.nit
        w_t = w if w_end is None else w + (w_end - w) * (t - 1) / max(planned - 1, 1)
        g = P[int(np.argmin(PF))]
        r1 = run.rng.random((n, run.d))
        r2 = run.rng.random((n, run.d))
        V = w_t * V + c1 * r1 * (P - X) + c2 * r2 * (g - X)
        V = np.clip(V, -vlim, vlim)
        X, flipped = fold(X + V, run.lower, run.upper)
        V = np.where(flipped, -V, V)
        F = run.evaluate(X)
        improved = F < PF
        P[improved], PF[improved] = X[improved], F[improved]
        run.record(F, w=w_t, pbest_mean=mean_value(PF))
    params: dict[str, Any] = dict(n=n, w=w, w_end=w_end, c1=c1, c2=c2, vmax=vmax)
    return run.result(X, F, params, state={"velocity": V, "pbest": P, "pbest_values": PF})
