"""Firefly algorithm (Yang 2008/2009) and the stepping-ahead firefly algorithm FAStep.

Conventions shared by :func:`firefly` and :func:`fastep`
---------------------------------------------------------
* Distances are measured relative to the box: ``r_ij = ||x_i - x_j|| / ||upper - lower||``, so
  ``r`` lies in ``[0, 1]`` and ``gamma`` is dimensionless: the same ``gamma`` behaves the same
  in any box (``gamma`` on raw distances is ``gamma / L^2`` for a box of diagonal ``L``; Yang
  notes that ``gamma`` must be linked to the scale of the problem). Attractiveness is
  ``beta(r) = (beta0 - beta_min) exp(-gamma r^2) + beta_min`` (``beta_min = 0``: the plain
  ``beta0 exp(-gamma r^2)``).
* The random step is ``alpha_t * eps`` with ``eps`` uniform in ``[-1/2, 1/2]^d`` times the box
  size ``upper - lower`` (Yang's ``alpha (rand - 1/2) scale``), and ``alpha_t = alpha
  damping^(t-1)`` in iteration ``t = 1, 2, ...``.
* Points leaving the box are clipped to it (Yang's ``findlimits``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.native.attract import moves as compiled_moves
from hybridnav.planners.swarm._core import (
    BoundsLike,
    Objective,
    OptResult,
    Run,
    SeedLike,
    check_int,
    check_real,
    decisive,
    uniform_population,
)

__all__ = ["fastep", "firefly"]


def _beta(r2: NDArray[np.float64], beta0: float, gamma: float,
          beta_min: float) -> NDArray[np.float64]:
    return (beta0 - beta_min) * np.exp(-gamma * r2) + beta_min


def _attraction_moves(run: Run, X: NDArray[np.float64], F: NDArray[np.float64], alpha_t: float,
                      beta0: float, gamma: float, beta_min: float) -> NDArray[np.float64]:
    """Yang's standard firefly moves of one generation, vectorized over the movers.

    Firefly ``i`` moves towards every firefly ``j`` that is strictly brighter (``F[j] < F[i]``),
    one move after the other, ``j`` visited from the brightest down (Yang's ``fa_mincon`` order),
    each move ``x_i <- x_i + beta(r_ij) (x_j - x_i) + alpha_t eps`` using ``x_j`` and ``F`` from the
    start of the generation and the current ``x_i``. A firefly with no brighter one (the brightest,
    and any tied with it, and any with a NaN value) makes one random move ``x_i + alpha_t eps``.
    The result is the same as Yang's double loop.

    The random steps are drawn as that loop draws them -- for each ``j`` one row per mover, the
    movers in index order, then one row per firefly that did not move, in index order -- but in
    one call. The loop over ``j`` works on the swarm sorted by brightness, where the movers of
    ``j`` are a contiguous run (every firefly strictly dimmer than ``j``; NaN values sort last and
    never move), so each attraction is a handful of operations on a slice -- or one call of the
    compiled loop (:mod:`hybridnav.native.attract`, with NumPy's exp), where it applies.
    """
    n, d = X.shape
    inv_diag2 = 1.0 / float(run.span @ run.span)
    order = np.argsort(F, kind="stable")
    Fs = F[order]
    m = n - int(np.count_nonzero(np.isnan(Fs)))                 # NaNs sort last
    first = np.searchsorted(Fs[:m], Fs[:m], side="right")       # movers of the p-th: first[p]:m
    J = int(np.count_nonzero(first < m))                        # the js that have movers
    first = first[:J]
    total = int(np.sum(m - first))
    moved = np.zeros(n, dtype=bool)
    if J:
        moved[order[first[0]:m]] = True
    E = alpha_t * (run.rng.random((total + n - int(np.count_nonzero(moved)), d)) - 0.5) * run.span
    Y = X.copy()
    if J:
        Xs = X[order]
        Ys = Xs.copy()
        if not compiled_moves(Xs, Ys, E, order, first, m, inv_diag2, gamma, beta0, beta_min):
            # row of E of each (j, mover): j's block, then the mover's rank in index order
            movers = Fs[:J, None] < F[None, :]                  # (J, n), index order
            rank = np.cumsum(movers, axis=1) - 1
            off = np.concatenate([[0], np.cumsum(m - first)[:-1]])
            Es = E[np.clip(off[:, None] + rank[:, order], 0, max(total - 1, 0))]  # (J, n, d)
            for p, s in enumerate(first.tolist()):
                V = Ys[s:m]
                diff = Xs[p] - V
                beta = _beta(np.einsum("ij,ij->i", diff, diff) * inv_diag2, beta0, gamma,
                             beta_min)
                V += beta[:, None] * diff + Es[p, s:m]
        Y[order] = Ys
    Y[~moved] += E[total:]
    return np.clip(Y, run.lower, run.upper)


def _check_common(n: int, alpha: float, beta0: float, gamma: float, beta_min: float,
                  damping: float) -> tuple[int, float, float, float, float, float]:
    n = check_int("n", n, 1)
    alpha = check_real("alpha", alpha, 0.0)
    beta0 = check_real("beta0", beta0, 0.0)
    gamma = check_real("gamma", gamma, 0.0)
    beta_min = check_real("beta_min", beta_min, 0.0, beta0)
    damping = check_real("damping", damping, 0.0, 1.0, lo_open=True)
    return n, alpha, beta0, gamma, beta_min, damping


def firefly(f: Objective, bounds: BoundsLike, *, n: int = 25, iterations: int | None = 100,
            max_evals: int | None = None, target: float | None = None, seed: SeedLike = None,
            init: ArrayLike | None = None, alpha: float = 0.5, beta0: float = 1.0,
            gamma: float = 1.0, beta_min: float = 0.0, damping: float = 0.97) -> OptResult:
    """Minimize ``f`` with Yang's firefly algorithm.

    Each generation every firefly moves towards every strictly brighter (lower ``f``) firefly,
    one attraction after the other from the brightest down, each move
    ``x_i <- x_i + beta0 exp(-gamma r_ij^2) (x_j - x_i) + alpha_t eps`` (Yang 2009, eq. 3, as in
    his ``fa_mincon`` code: positions ``x_j`` and brightness from the start of the generation, a
    fresh random step per attraction). The brightest firefly moves randomly. The swarm is then
    evaluated in one call of ``f``. The population is *not* elitist (fireflies always move); the
    best point ever evaluated is kept in the result.

    Parameters
    ----------
    f : callable
        Vectorized objective: ``f(X)`` with ``X`` of shape ``(N, d)`` returns ``N`` values;
        NaN counts as ``+inf``.
    bounds : (lower, upper)
        Box of the search, two sequences of length ``d`` with ``lower < upper``.
    n : int, optional
        Number of fireflies.
    iterations : int or None, optional
        Maximum number of generations (``None``: limited by ``max_evals`` only).
    max_evals : int or None, optional
        Maximum number of evaluated points; a generation that would exceed it is not started.
        Each generation costs ``n`` evaluations, the initial swarm ``n``.
    target : float or None, optional
        Stop as soon as a value ``<= target`` has been found.
    seed : int, SeedSequence, Generator or None, optional
        Seed of the one :class:`numpy.random.Generator` all randomness comes from.
    init : array_like, shape (m, d), optional
        Starting points (``m <= n``); the other fireflies start uniformly at random.
    alpha : float, optional
        Random step as a fraction of the box size (``eps`` uniform in ``[-1/2, 1/2]`` times
        ``upper - lower``).
    beta0 : float, optional
        Attractiveness at distance 0.
    gamma : float, optional
        Light absorption coefficient; distances are relative to the box diagonal.
    beta_min : float, optional
        Minimum attractiveness (Yang's ``betamin``), ``0 <= beta_min <= beta0``.
    damping : float, optional
        Step size damping: ``alpha_t = alpha damping^(t-1)`` in generation ``t``.

    Returns
    -------
    OptResult
        ``history.extra["alpha"]`` holds ``alpha_t`` (``nan`` in row 0).

    References
    ----------
    X.-S. Yang, *Nature-Inspired Metaheuristic Algorithms*, Luniver Press, 2008.
    X.-S. Yang, "Firefly algorithms for multimodal optimization", SAGA 2009, LNCS 5792.
    """
    n, alpha, beta0, gamma, beta_min, damping = _check_common(n, alpha, beta0, gamma, beta_min,
                                                              damping)
    run = Run("firefly", f, bounds, iterations, max_evals, target, seed)
    run.check_budget(n, n)
    X = uniform_population(run.rng, run.lower, run.upper, n, init)
    F = run.evaluate(X)
    run.record(F, alpha=np.nan)
    while run.more():
        alpha_t = alpha * damping ** (run.nit - 1)
        X = _attraction_moves(run, X, F, alpha_t, beta0, gamma, beta_min)
        F = run.evaluate(X)
        run.record(F, alpha=alpha_t)
    params: dict[str, Any] = dict(n=n, alpha=alpha, beta0=beta0, gamma=gamma, beta_min=beta_min,
                                  damping=damping)
    return run.result(X, F, params)


def fastep(f: Objective, bounds: BoundsLike, *, n: int = 50, iterations: int | None = 100,
           max_evals: int | None = None, target: float | None = None, seed: SeedLike = None,
           init: ArrayLike | None = None, alpha: float = 0.2, beta0: float = 2.0,
           gamma: float = 100.0, beta_min: float = 0.0, damping: float = 0.8) -> OptResult:
    """Minimize ``f`` with the stepping-ahead firefly algorithm FAStep (Nand et al. 2021).

    Defaults are FAStep-Kinematic's Table 1 (``n = 50``, ``beta0 = 2``, ``alpha = 0.2``, damping
    ``0.8``). The table leaves ``gamma`` blank; ``gamma = 100`` is our choice. Distances are
    relative to the box diagonal ``L``, so this is ``gamma = 100 / L^2`` in the problem's units,
    i.e. ``gamma = 1`` for a box of diagonal 10 (a 7 x 7 step-planning window). With
    ``beta0 = 2``, eq. 4 moves a firefly *away* from the best when ``beta > 1``, i.e. for
    ``r < sqrt(ln 2 / gamma)``; ``gamma = 100`` makes that radius 8 % of the diagonal, while
    fireflies farther out land close to the best. On 2-D test functions (sphere, Rosenbrock,
    Rastrigin, Ackley, 20 seeds, 100 iterations) ``gamma = 100`` reached the optimum more
    reliably than ``gamma`` in {1, 3, 10, 30} (e.g. Rastrigin below 1e-2 in 20/20 runs against
    4/20 with ``gamma = 1``). With ``damping = 0.8`` the random step has shrunk by 1e-5 after 50
    generations, so FAStep converges (or stalls) within about 50-100 generations; for more than
    about 3 dimensions use a damping near 1 (e.g. 0.97) and a larger budget.

    Each generation, for every firefly ``i`` (``x_b`` is the brightest firefly of the generation):

    1. the standard move ``y_i``: the firefly moves towards every brighter firefly exactly as in
       :func:`firefly` (FAStep-Kinematic eq. 3; the paper prints ``x_i - x_j`` there, which
       would move *away* from the brighter firefly, and we use Yang's ``x_j - x_i``);
    2. the stepping-ahead move ``z_i = x_b + beta(r_ib) (x_i - x_b) + alpha_t eps_i`` (eq. 4) with
       ``r_ib = ||x_i - x_b||`` relative to the box diagonal;
    3. the preference-based update: if ``f(y_i) < f(x_i)`` the firefly takes the standard move
       ``y_i``; otherwise ("if the fitness of the new position is not better, then update the
       position using eq. (4)") it takes the stepping-ahead move ``z_i`` *unconditionally*, even
       when ``z_i`` is worse than ``x_i`` -- this replaces the standard algorithm's "otherwise the
       firefly remains where it is" and is what lets FAStep leave local minima.
    4. Elitism (our choice, the paper does not say): the brightest firefly ``b`` keeps its position
       when neither of its moves improves it, so the swarm's best value never increases. (The
       best point ever evaluated can still be a stepping-ahead candidate that lost to a preferred
       standard move; the result reports it.)

    To keep one call of ``f`` per generation, ``y`` and ``z`` of all fireflies are evaluated
    together: a generation costs ``2 n`` evaluations (the initial swarm ``n``). With a
    :class:`~hybridnav.planners.swarm._core.BoundedObjective` only the values the generation
    uses are computed exactly (:func:`_generation_values`); the run is the same.

    Parameters
    ----------
    f : callable
        Vectorized objective: ``f(X)`` with ``X`` of shape ``(N, d)`` returns ``N`` values;
        NaN counts as ``+inf``.
    bounds : (lower, upper)
        Box of the search, two sequences of length ``d`` with ``lower < upper``.
    n : int, optional
        Number of fireflies.
    iterations : int or None, optional
        Maximum number of generations.
    max_evals : int or None, optional
        Maximum number of evaluated points (``n + 2 n`` per generation).
    target : float or None, optional
        Stop as soon as a value ``<= target`` has been found.
    seed : int, SeedSequence, Generator or None, optional
        Seed of the one :class:`numpy.random.Generator` all randomness comes from.
    init : array_like, shape (m, d), optional
        Starting points (``m <= n``); the other fireflies start uniformly at random.
    alpha : float, optional
        Random step ("mutation coefficient") as a fraction of the box size.
    beta0 : float, optional
        Attractiveness at distance 0 ("attraction coefficient base value").
    gamma : float, optional
        Light absorption coefficient; distances are relative to the box diagonal.
    beta_min : float, optional
        Minimum attractiveness, ``0 <= beta_min <= beta0``.
    damping : float, optional
        "Mutation coefficient damping ratio": ``alpha_t = alpha damping^(t-1)``.

    Returns
    -------
    OptResult
        ``history.extra["alpha"]`` holds ``alpha_t``; ``history.extra["stepped"]`` the fraction
        of fireflies that took the stepping-ahead move; ``state["stepped"]`` the mask of the
        last generation.

    References
    ----------
    R. Nand, B. N. Sharma, K. Chaudhary, "Stepping ahead firefly algorithm and hybridization
    with evolution strategy for global optimization problems", Appl. Soft Comput. 109 (2021).
    K. Chaudhary et al., "Robot motion control using stepping ahead firefly algorithm and
    kinematic equations", IEEE Access (2024), Section IV and Table 1.
    """
    n, alpha, beta0, gamma, beta_min, damping = _check_common(n, alpha, beta0, gamma, beta_min,
                                                              damping)
    run = Run("fastep", f, bounds, iterations, max_evals, target, seed)
    run.check_budget(n, 2 * n)
    inv_diag2 = 1.0 / float(run.span @ run.span)
    X = uniform_population(run.rng, run.lower, run.upper, n, init)
    F = run.evaluate(X)
    run.record(F, alpha=np.nan, stepped=np.nan)
    stepped = np.zeros(n, dtype=bool)
    while run.more():
        alpha_t = alpha * damping ** (run.nit - 1)
        b = int(np.argmin(F))
        Y = _attraction_moves(run, X, F, alpha_t, beta0, gamma, beta_min)
        diff = X - X[b]
        beta = _beta(np.einsum("ij,ij->i", diff, diff) * inv_diag2, beta0, gamma, beta_min)
        Z = X[b] + beta[:, None] * diff + alpha_t * (run.rng.random(X.shape) - 0.5) * run.span
        Z = np.clip(Z, run.lower, run.upper)
        V = (_generation_values(run, np.concatenate([Y, Z]), F) if run.bounded
             else run.evaluate(np.concatenate([Y, Z])))
        FY, FZ = V[:n], V[n:]
        better = FY < F
        stepped = ~better
        if not better[b] and not FZ[b] < F[b]:  # elitism: the brightest stays put
            stepped[b] = False
            Y[b], FY[b] = X[b], F[b]
        X = np.where(stepped[:, None], Z, Y)
        F = np.where(stepped, FZ, FY)
        run.record(F, alpha=alpha_t, stepped=float(np.mean(stepped)))
    params: dict[str, Any] = dict(n=n, alpha=alpha, beta0=beta0, gamma=gamma, beta_min=beta_min,
                                  damping=damping)
    return run.result(X, F, params, state={"stepped": stepped})


def _generation_values(run: Run, V: NDArray[np.float64], F: NDArray[np.float64]
                       ) -> NDArray[np.float64]:
    """The values of one FAStep generation's ``V = [Y; Z]`` (standard, then stepping-ahead
    moves of the ``n`` fireflies whose values are ``F``) as far as the generation uses them, for
    a bounded objective: ``+inf`` where the exact value cannot change the run (one evaluation in
    the budget and the best point, as :meth:`Run.evaluate`).

    * ``y_i`` is taken only when ``f(y_i) < F_i``: with a bound ``>= F_i`` it is not, and it
      is not a new best either (``F_i`` is at least the best value so far);
    * ``z_i`` is taken whenever ``y_i`` is not, so it is needed when ``y_i``'s bound rules
      ``y_i`` out, or once ``y_i`` has turned out no better (a second call, for those only,
      when the objective says its values are costly; otherwise asked with the others);
      otherwise only when its bound is below the best value so far (it may be a new best).

    Every value the generation uses -- the preference test, the values carried, the elitism
    test and the best point -- is then the exact one.
    """
    n = len(F)
    B = run.lower_bound(V)
    lb = decisive(B)
    out = np.full(2 * n, np.inf)
    live = lb < np.inf                           # a bound of +inf: the value is +inf
    need_y = live[:n] & (lb[:n] < F)
    if getattr(run.f, "costly", True):
        need_z = live[n:] & (~need_y | (lb[n:] < run.best_f))
    else:                                        # one call: every z_i that may be needed
        need_z = live[n:]
    rows = np.flatnonzero(np.concatenate([need_y, need_z]))
    out[rows] = run.refine(V, B, rows)
    later = n + np.flatnonzero(live[n:] & ~need_z & ~(out[:n] < F))
    if len(later):
        out[later] = run.refine(V, B, later)
    run.account(V, out)
    return out
