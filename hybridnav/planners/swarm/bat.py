"""Bat algorithm (Yang 2010)."""

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
    uniform_population,
)

__all__ = ["bat"]


def bat(f: Objective, bounds: BoundsLike, *, n: int = 30, iterations: int | None = 100,
        max_evals: int | None = None, target: float | None = None, seed: SeedLike = None,
        init: ArrayLike | None = None, fmin: float = 0.0, fmax: float = 2.0,
        loudness: float = 1.0, pulse_rate: float = 0.5, alpha: float = 0.9,
        gamma: float = 0.9, walk: float = 0.01, vmax: float | None = None) -> OptResult:
    """Minimize ``f`` with Yang's bat algorithm.

    Each bat ``i`` has a position ``x_i`` (value ``F_i``), a velocity ``v_i`` (initially 0), a
    loudness ``A_i`` (initially ``loudness``) and a pulse rate ``r_i`` (initially ``pulse_rate``
    = ``r0``). In iteration ``t = 1, 2, ...``, with ``x*`` the best point found so far, all bats
    at once:

    1. frequency ``f_i = fmin + (fmax - fmin) beta``, ``beta`` uniform in ``[0, 1]``;
       velocity ``v_i <- v_i + (x* - x_i) f_i`` (clipped to ``vmax`` if given); candidate
       ``s_i = x_i + v_i``.
       Yang's paper writes ``(x_i - x*)``, which with ``f_i >= 0`` pushes bats *away* from the
       best and makes the velocities grow geometrically; we use the attracting sign (our
       choice, as in many later implementations).
    2. local random walk: if ``rand > r_i``, the candidate is replaced by
       ``s_i = x* + walk * mean(A) * eps * (upper - lower)``, ``eps`` uniform in ``[-1, 1]^d``
       (Yang's ``x_old + eps A^t`` around the best, scaled to the box by ``walk``).
    3. candidates are clipped to the box and evaluated in one call of ``f``.
    4. acceptance: if ``f(s_i) <= F_i`` and ``rand < A_i``, the bat moves to ``s_i`` and its
       schedules advance: ``A_i <- alpha A_i`` and ``r_i <- r0 (1 - exp(-gamma t))``.
       Bats only move to points that are no worse, so the population is elitist. ``x*`` is
       updated from every evaluated point (accepted or not), as in Yang's code, but once per
       generation (Yang updates it bat by bat; here the whole swarm moves at once).

    Parameters
    ----------
    f : callable
        Vectorized objective: ``f(X)`` with ``X`` of shape ``(N, d)`` returns ``N`` values;
        NaN counts as ``+inf``.
    bounds : (lower, upper)
        Box of the search, two sequences of length ``d`` with ``lower < upper``.
    n : int, optional
        Number of bats.
    iterations : int or None, optional
        Maximum number of iterations.
    max_evals : int or None, optional
        Maximum number of evaluated points (``n`` initially and per iteration).
    target : float or None, optional
        Stop as soon as a value ``<= target`` has been found.
    seed : int, SeedSequence, Generator or None, optional
        Seed of the one :class:`numpy.random.Generator` all randomness comes from.
    init : array_like, shape (m, d), optional
        Starting points (``m <= n``); the other bats start uniformly at random.
    fmin, fmax : float, optional
        Frequency range, ``0 <= fmin <= fmax``.
    loudness : float, optional
        Initial loudness ``A0 > 0`` (Yang suggests 1 to 2; values above 1 accept every
        improvement until ``A`` has decayed below 1).
    pulse_rate : float, optional
        Initial and limiting pulse rate ``r0`` in ``[0, 1]``.
    alpha : float, optional
        Loudness decay factor, ``0 < alpha <= 1``.
    gamma : float, optional
        Pulse rate growth constant, ``gamma >= 0``.
    walk : float, optional
        Local walk scale as a fraction of the box size, ``walk > 0``.
    vmax : float or None, optional
        If given, velocities are clipped to ``[-vmax, vmax] (upper - lower)`` after each update
        (not in Yang's algorithm, whose velocities can grow without bound: the frequency-tuned
        update is a random product of matrices of determinant 1). ``None``: no limit.

    Returns
    -------
    OptResult
        ``state`` holds the final ``velocity``, ``loudness``, ``pulse_rate`` and ``accepted``
        (number of accepted moves per bat); ``history.extra`` the means ``loudness`` and
        ``pulse_rate`` after each iteration.

    References
    ----------
    X.-S. Yang, "A new metaheuristic bat-inspired algorithm", in Nature Inspired Cooperative
    Strategies for Optimization (NICSO 2010), Studies in Computational Intelligence 284, 2010.
    """
    n = check_int("n", n, 1)
    fmin = check_real("fmin", fmin, 0.0)
    fmax = check_real("fmax", fmax, fmin)
    A0 = check_real("loudness", loudness, 0.0, lo_open=True)
    r0 = check_real("pulse_rate", pulse_rate, 0.0, 1.0)
    alpha = check_real("alpha", alpha, 0.0, 1.0, lo_open=True)
    gamma = check_real("gamma", gamma, 0.0)
    walk = check_real("walk", walk, 0.0, lo_open=True)
    vmax = None if vmax is None else check_real("vmax", vmax, 0.0, lo_open=True)
    run = Run("bat", f, bounds, iterations, max_evals, target, seed)
    run.check_budget(n, n)
    d = run.d
    X = uniform_population(run.rng, run.lower, run.upper, n, init)
    V = np.zeros((n, d))
    A = np.full(n, A0)
    r = np.full(n, r0)
    accepted = np.zeros(n, dtype=np.int64)
    F = run.evaluate(X)
    run.record(F, loudness=float(A.mean()), pulse_rate=float(r.mean()))
    while run.more():
        t = run.nit
        best = run.best_x.copy()
        freq = fmin + (fmax - fmin) * run.rng.random(n)
        V = V + (best - X) * freq[:, None]
        if vmax is not None:
            V = np.clip(V, -vmax * run.span, vmax * run.span)
        S = X + V
        local = run.rng.random(n) > r
        eps = run.rng.uniform(-1.0, 1.0, (n, d))
        S[local] = best + walk * A.mean() * eps[local] * run.span
        S = np.clip(S, run.lower, run.upper)
        FS = run.evaluate(S)
        acc = (FS <= F) & (run.rng.random(n) < A)
        X[acc], F[acc] = S[acc], FS[acc]
        A[acc] *= alpha
        r[acc] = r0 * (1.0 - np.exp(-gamma * t))
        accepted += acc
        run.record(F, loudness=float(A.mean()), pulse_rate=float(r.mean()))
    params: dict[str, Any] = dict(n=n, fmin=fmin, fmax=fmax, loudness=A0, pulse_rate=r0,
                                  alpha=alpha, gamma=gamma, walk=walk, vmax=vmax)
    return run.result(X, F, params, state={"velocity": V, "loudness": A, "pulse_rate": r,
                                           "accepted": accepted})
