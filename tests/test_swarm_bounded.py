"""Optimizers given a bounded objective skip exact values, and run exactly as without the bound.

The step planners' objective is the step fitness where a candidate's move is feasible and +inf
elsewhere; the fitness is a cheap lower bound, the feasibility the costly part. ``acor`` and
``fastep`` compute the exact value only where it can change the run
(:class:`~hybridnav.planners.swarm._core.BoundedObjective`); everything they return must be
the same as when every value is computed.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridnav.planners.swarm import acor, fastep
from hybridnav.planners.swarm._core import BoundedObjective


def _problem(seed: int, quantum: float, infeasible: float, nan: float):
    """A fitness (rounded to ``quantum``: ties), a 'feasibility' that refuses about
    ``infeasible`` of the points (and about ``nan`` of them get a NaN fitness), as a plain and
    as a bounded objective, and a log of the rows whose exact value was asked for."""
    rng = np.random.default_rng(seed)
    c = rng.uniform(-1, 1, 2)
    w = rng.uniform(1, 9, 2)
    asked = []

    def fitness(X):
        g = np.hypot(X[:, 0] - c[0], X[:, 1] - c[1]) + 0.3 * np.sin(w[0] * X[:, 0])
        if quantum:
            g = np.round(g / quantum) * quantum
        g[np.sin(97 * X[:, 0] + 31 * X[:, 1]) > 1 - 2 * nan] = np.nan
        return g

    def feasible(X):
        return np.cos(w[1] * 13 * X[:, 0] - 7 * X[:, 1]) >= 2 * infeasible - 1

    def plain(X):
        return np.where(feasible(X), fitness(X), np.inf)

    def refine(X, B):
        asked.append(len(X))
        return np.where(feasible(X), B, np.inf)

    return plain, BoundedObjective(fitness, refine), asked


def _same(a, b):
    assert a.x.tobytes() == b.x.tobytes()
    assert a.fun == b.fun or (np.isnan(a.fun) and np.isnan(b.fun))
    assert (a.nfev, a.ncalls, a.nit, a.message) == (b.nfev, b.ncalls, b.nit, b.message)
    assert a.population.tobytes() == b.population.tobytes()
    assert a.values.tobytes() == b.values.tobytes()
    for k in ("best", "population_best", "mean", "nfev"):
        assert getattr(a.history, k).tobytes() == getattr(b.history, k).tobytes(), k
    assert a.history.extra.keys() == b.history.extra.keys()
    for k in a.history.extra:
        assert a.history.extra[k].tobytes() == b.history.extra[k].tobytes(), k


problems = dict(seed=st.integers(0, 2**32 - 1), quantum=st.sampled_from([0.0, 0.05, 0.5, 2.0]),
                infeasible=st.sampled_from([0.0, 0.3, 0.7, 0.97, 1.0]),
                nan=st.sampled_from([0.0, 0.05]))


@settings(max_examples=60, deadline=None)
@given(k=st.integers(2, 40), m=st.integers(1, 400), iterations=st.integers(1, 4),
       goal=st.booleans(), **problems)
def test_acor_with_a_bound_is_acor(seed, quantum, infeasible, nan, k, m, iterations, goal):
    plain, bounded, asked = _problem(seed, quantum, infeasible, nan)
    kw = dict(k=k, m=m, iterations=iterations, seed=seed, q=0.5, xi=1.0,
              init=np.array([[0.25, -0.5]]) if goal else None)
    _same(acor(plain, ([-2, -2], [2, 2]), **kw), acor(bounded, ([-2, -2], [2, 2]), **kw))


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 30), iterations=st.integers(1, 12), goal=st.booleans(), **problems)
def test_fastep_with_a_bound_is_fastep(seed, quantum, infeasible, nan, n, iterations, goal):
    plain, bounded, asked = _problem(seed, quantum, infeasible, nan)
    kw = dict(n=n, iterations=iterations, seed=seed,
              init=np.array([[0.25, -0.5]]) if goal else None)
    _same(fastep(plain, ([-2, -2], [2, 2]), **kw), fastep(bounded, ([-2, -2], [2, 2]), **kw))


def test_the_bound_saves_exact_values():
    """ACO-Kinematic's sizes: most samples cannot enter the archive and are not refined."""
    plain, bounded, asked = _problem(3, 0.0, 0.3, 0.0)
    _same(acor(plain, ([-2, -2], [2, 2]), k=300, m=10000, iterations=1, seed=1, q=0.5, xi=1.0),
          acor(bounded, ([-2, -2], [2, 2]), k=300, m=10000, iterations=1, seed=1, q=0.5,
               xi=1.0))
    assert sum(asked) < 300 + 10000 // 4
    asked.clear()
    _same(fastep(plain, ([-2, -2], [2, 2]), n=50, iterations=30, seed=1),
          fastep(bounded, ([-2, -2], [2, 2]), n=50, iterations=30, seed=1))
    assert sum(asked) < 50 + 30 * 100
