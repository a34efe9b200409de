"""Ant colony optimization for continuous domains, ACOR (Socha & Dorigo 2008)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.planners.swarm._core import (
    BoundsLike,
    Objective,
    OptResult,
    Run,
    SeedLike,
    check_int,
    check_real,
    decisive,
    fold,
    uniform_population,
)

__all__ = ["ACO_KINEMATIC", "acor", "acor_weights"]

#: ACO-Kinematic's navigation parameters (Chaudhary et al. 2022, Table 1): archive size 300,
#: sample size 10000, deviation-distance ratio 1, intensification factor 0.5.
ACO_KINEMATIC: dict[str, Any] = {"k": 300, "m": 10000, "xi": 1.0, "q": 0.5}


def acor_weights(k: int, q: float) -> NDArray[np.float64]:
    """The weights of the ranked archive, ``w_l = exp(-(l-1)^2 / (2 q^2 k^2)) / (q k sqrt(2 pi))``.

    Parameters
    ----------
    k : int
        Archive size (``k >= 2``).
    q : float
        Intensification factor (``q > 0``): small ``q`` concentrates the choice on the best
        solutions.

    Returns
    -------
    ndarray, shape (k,)
        ``w_1, ..., w_k`` for the archive ranked best first (not normalized; the probability
        of choosing solution ``l`` is ``w_l / sum(w)``).
    """
    k = check_int("k", k, 2)
    q = check_real("q", q, 0.0, lo_open=True)
    rank = np.arange(k, dtype=float)  # l - 1
    return np.exp(-rank**2 / (2.0 * q**2 * k**2)) / (q * k * np.sqrt(2.0 * np.pi))


def _probabilities(k: int, q: float) -> NDArray[np.float64]:
    # w_l / sum(w) computed from the exponents alone, so tiny q never divides 0 by 0
    rank = np.arange(k, dtype=float)
    e = np.exp(-rank**2 / (2.0 * q**2 * k**2))
    return e / e.sum()


def _mean_abs_distance(S: NDArray[np.float64]) -> NDArray[np.float64]:
    """``D[l, i] = sum_e |S[e, i] - S[l, i]|`` for all archive members, O(k log k) per column."""
    k = S.shape[0]
    order = np.argsort(S, axis=0, kind="stable")
    s = np.take_along_axis(S, order, axis=0)
    csum = np.cumsum(s, axis=0)
    total = csum[-1]
    idx = np.arange(k)[:, None]
    below = s * idx - (csum - s)  # sum over smaller elements of (s_l - s_e)
    above = (total - csum) - s * (k - 1 - idx)  # sum over larger elements of (s_e - s_l)
    D = np.empty_like(S)
    np.put_along_axis(D, order, below + above, axis=0)
    return np.maximum(D, 0.0)


def acor(f: Objective, bounds: BoundsLike, *, k: int = 50, m: int = 2,
         iterations: int | None = 100, max_evals: int | None = None, target: float | None = None,
         seed: SeedLike = None, init: ArrayLike | None = None, q: float = 1e-4,
         xi: float = 0.85) -> OptResult:
    """Minimize ``f`` with ACOR, ant colony optimization for continuous domains.

    The archive holds the ``k`` best solutions found, ranked best first; solution ``l`` has the
    weight ``w_l`` of :func:`acor_weights`. Each iteration ``m`` ants each choose one archive
    solution ``l`` with probability ``w_l / sum(w)`` (one Gaussian kernel per ant, used for every
    coordinate, as in Socha & Dorigo) and sample every coordinate ``i`` from a normal distribution
    with mean ``s_l,i`` and standard deviation
    ``sigma_l,i = xi * sum_e |s_e,i - s_l,i| / (k - 1)``. The ``m`` new solutions are evaluated in
    one call of ``f``, merged with the archive, and the worst ``m`` are dropped (ties keep archive
    members first), so the archive is elitist. Samples outside the box are reflected back in at
    the bounds (mirror walls). The rotated coordinate system of Socha & Dorigo's Section 5.3 is
    not implemented.

    With a :class:`~hybridnav.planners.swarm._core.BoundedObjective` only the samples that can
    enter the archive are evaluated exactly (:func:`_sample_values`); the run is the same.

    The defaults are Socha & Dorigo's standard values (``k = 50``, ``m = 2``, ``q = 1e-4``,
    ``xi = 0.85``); ACO-Kinematic's navigation values are :data:`ACO_KINEMATIC`
    (``acor(f, bounds, **ACO_KINEMATIC)`` or ``minimize("acor", ..., preset="aco-kinematic")``).

    Parameters
    ----------
    f : callable
        Vectorized objective: ``f(X)`` with ``X`` of shape ``(N, d)`` returns ``N`` values;
        NaN counts as ``+inf``.
    bounds : (lower, upper)
        Box of the search, two sequences of length ``d`` with ``lower < upper``.
    k : int, optional
        Archive size (``k >= 2``); the initial archive is ``k`` uniformly random points.
    m : int, optional
        Number of ants (new solutions) per iteration ("sample size").
    iterations : int or None, optional
        Maximum number of iterations.
    max_evals : int or None, optional
        Maximum number of evaluated points (``k`` initially, ``m`` per iteration).
    target : float or None, optional
        Stop as soon as a value ``<= target`` has been found.
    seed : int, SeedSequence, Generator or None, optional
        Seed of the one :class:`numpy.random.Generator` all randomness comes from.
    init : array_like, shape (r, d), optional
        Starting archive points (``r <= k``); the others are uniformly random.
    q : float, optional
        Intensification factor (``q > 0``).
    xi : float, optional
        Deviation-distance ratio (``xi > 0``), the speed of convergence.

    Returns
    -------
    OptResult
        ``population``/``values`` are the final archive, best first.

    References
    ----------
    K. Socha, M. Dorigo, "Ant colony optimization for continuous domains", Eur. J. Oper. Res.
    185(3), 1155-1173 (2008).
    """
    k = check_int("k", k, 2)
    m = check_int("m", m, 1)
    q = check_real("q", q, 0.0, lo_open=True)
    xi = check_real("xi", xi, 0.0, lo_open=True)
    run = Run("acor", f, bounds, iterations, max_evals, target, seed)
    run.check_budget(k, m)
    p = _probabilities(k, q)
    S = uniform_population(run.rng, run.lower, run.upper, k, init)
    FS = run.evaluate(S)
    order = np.argsort(FS, kind="stable")
    S, FS = S[order], FS[order]
    run.record(FS)
    while run.more():
        sigma = xi * _mean_abs_distance(S) / (k - 1)
        chosen = run.rng.choice(k, size=m, p=p)
        Z = S[chosen] + sigma[chosen] * run.rng.standard_normal((m, run.d))
        Z, _ = fold(Z, run.lower, run.upper)
        FZ = _sample_values(run, Z, FS) if run.bounded else run.evaluate(Z)
        allS = np.concatenate([S, Z])
        allF = np.concatenate([FS, FZ])
        keep = np.argsort(allF, kind="stable")[:k]
        S, FS = allS[keep], allF[keep]
        run.record(FS)
    params: dict[str, Any] = dict(k=k, m=m, q=q, xi=xi)
    return run.result(S, FS, params)


def _sample_values(run: Run, Z: NDArray[np.float64], FS: NDArray[np.float64]) -> NDArray[np.float64]:
    """The samples' values as far as the archive's update needs them, for a bounded objective:
    exact for every sample that can be among the ``k`` best of archive and samples, ``+inf`` for
    the others (one evaluation in the budget and the best point, as :meth:`Run.evaluate`).

    The samples are refined in the order of their bounds, a batch at a time, while a bound is at
    most the ``k``-th best value known (archive ``FS``, ``k`` values, and the samples refined so
    far). A sample left out has a bound, so a value, above that; ``k`` known values are at most
    it, so the sample is not among the ``k`` kept (ties included: they are refined), and nor is
    it the best point (the best value so far is at most the archive's). The archive after the
    merge, its order and the best point are those of every value computed.
    """
    k, m = len(FS), len(Z)
    B = run.lower_bound(Z)
    lb = decisive(B)
    FZ = np.full(m, np.inf)
    todo = np.flatnonzero(lb < np.inf)            # a bound of +inf: the value is +inf
    todo = todo[np.argsort(lb[todo], kind="stable")]
    sorted_lb = lb[todo]
    kth = float(FS[-1])                           # the archive is sorted: its k-th best
    done = 0
    size = k
    while done < len(todo):
        stop = int(np.searchsorted(sorted_lb, kth, side="right"))   # bounds <= kth
        if stop <= done:
            break
        rows = todo[done:min(stop, done + size)]
        FZ[rows] = run.refine(Z, B, rows)
        done += len(rows)
        known = np.concatenate([FS, FZ[todo[:done]]])
        kth = float(np.partition(known, k - 1)[k - 1])
        # the next batch: about what is still missing for k finite values at the rate found so
        # far, at most as many as done (the rate of the best bounds says little of the rest)
        finite = int(np.count_nonzero(np.isfinite(known)))
        rate = max(np.count_nonzero(np.isfinite(FZ[todo[:done]])) / done, 1.0 / 64)
        size = max(1, min(max(k // 4, int(1.25 * max(k - finite, k // 4) / rate)), done))
    run.account(Z, FZ)
    return FZ
