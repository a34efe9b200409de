"""Swarm optimizers (hybridnav.planners.swarm): accuracy on standard functions, invariants,
the documented rules of each method, and input validation."""

from __future__ import annotations

import ast
import inspect
import math
import pathlib

import numpy as np
import pytest
from scipy.optimize import differential_evolution

from hybridnav import HybridnavError
from hybridnav.planners import swarm
from hybridnav.planners.swarm import (
    ACO_KINEMATIC,
    OPTIMIZERS,
    PRESETS,
    acor,
    acor_weights,
    bat,
    fastep,
    firefly,
    minimize,
    pso,
)
from hybridnav.planners.swarm.functions import (
    FUNCTIONS,
    ackley,
    rastrigin,
    rosenbrock,
    sphere,
)

NAMES = list(OPTIMIZERS)
# small budgets for the invariant tests (population parameter and iterations)
SMALL = {
    "firefly": dict(n=8, iterations=6),
    "fastep": dict(n=8, iterations=6),
    "acor": dict(k=8, m=5, iterations=6),
    "pso": dict(n=8, iterations=6),
    "bat": dict(n=8, iterations=6),
}
# evaluations per call: initial population, then per iteration
SIZES = {"firefly": (8, 8), "fastep": (8, 16), "acor": (8, 5), "pso": (8, 8), "bat": (8, 8)}


def small(name):
    """The small budget of ``name``; an optimizer registered later takes ``n=8``."""
    return SMALL.get(name, dict(n=8, iterations=6))


def sizes(name):
    """Evaluations per call of ``name``; for an optimizer registered later, what its first call
    and its second show (the contract tests then hold every later iteration to it)."""
    if name in SIZES:
        return SIZES[name]
    rec = Recorder(sphere)
    minimize(name, rec, ([-1, -1], [1, 1]), seed=0, **dict(small(name), iterations=1))
    return rec.calls[0].shape[0], rec.calls[1].shape[0]


class Recorder:
    """Wrap an objective and keep a copy of every array it is called with."""

    def __init__(self, f):
        self.f = f
        self.calls: list[np.ndarray] = []

    def __call__(self, X):
        self.calls.append(np.array(X, copy=True))
        return self.f(X)

    @property
    def points(self) -> np.ndarray:
        return np.concatenate(self.calls)


# ------------------------------------------------------------------------------------------------
# the test functions themselves


def test_functions_minimum_values_and_shapes():
    X = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.5, -0.2, 3.0]])
    assert sphere(X)[0] == 0.0 and rastrigin(X)[0] == 0.0 and ackley(X)[0] == 0.0
    assert rosenbrock(X)[1] == 0.0
    # hand values at (0.5, -0.2, 3.0)
    assert sphere(X)[2] == pytest.approx(0.25 + 0.04 + 9.0)
    assert rosenbrock(X)[2] == pytest.approx(100 * (-0.2 - 0.25)**2 + 0.25
                                             + 100 * (3.0 - 0.04)**2 + 1.2**2)
    r = 30 + (0.25 - 10 * math.cos(math.pi)) + (0.04 - 10 * math.cos(-0.4 * math.pi)) \
        + (9.0 - 10 * math.cos(6 * math.pi))
    assert rastrigin(X)[2] == pytest.approx(r)
    for tf in FUNCTIONS.values():
        assert tf.f(np.zeros((4, 5)) + tf.xstar).shape == (4,)
        assert np.allclose(tf.f(np.full((1, 5), tf.xstar)), 0.0, atol=1e-14)


# ------------------------------------------------------------------------------------------------
# accuracy: (method, function, d, parameters, tolerance on f - 0, seeds that must reach it of 5)
#
# Budgets (evaluations): firefly 400 iterations x 25 = 10 025; fastep 100 x 100 + 50 = 10 050
# (2-D, paper defaults) or 300 x 100 + 50 = 30 050 (10-D, damping 0.97); acor m = 10, 1000
# iterations = 10 050; pso 300 x 30 + 30 = 9030; bat 500 x n + n (15 030 for n = 30).
# Tolerances are what the runs reach with margin (measured over 20 seeds, see the report).

ACCURACY = [
    ("firefly", "sphere", 10, dict(iterations=400), 1e-5, 4),
    ("firefly", "rosenbrock", 2, dict(iterations=400), 1e-3, 5),
    ("firefly", "rastrigin", 2, dict(iterations=400), 1e-6, 4),
    ("firefly", "ackley", 2, dict(iterations=400), 1e-4, 5),
    ("firefly", "ackley", 5, dict(iterations=400), 1e-3, 5),
    ("fastep", "sphere", 2, dict(iterations=100), 1e-5, 5),
    ("fastep", "rosenbrock", 2, dict(iterations=100), 1e-2, 5),
    ("fastep", "rastrigin", 2, dict(iterations=100), 1e-2, 5),
    ("fastep", "ackley", 2, dict(iterations=100), 5e-2, 5),
    ("fastep", "sphere", 10, dict(iterations=300, damping=0.97), 1e-6, 5),
    ("acor", "sphere", 10, dict(m=10, iterations=1000), 1e-20, 5),
    ("acor", "rosenbrock", 2, dict(m=10, iterations=1000), 1e-12, 5),
    ("acor", "rastrigin", 2, dict(m=10, iterations=1000), 1e-2, 3),
    ("acor", "ackley", 2, dict(m=10, iterations=1000), 1e-12, 5),
    ("acor", "rastrigin", 2, dict(preset="aco-kinematic", iterations=10), 1e-8, 5),
    ("pso", "sphere", 10, dict(iterations=300), 1e-12, 5),
    ("pso", "rosenbrock", 2, dict(iterations=300), 1e-7, 5),
    ("pso", "rastrigin", 2, dict(iterations=300), 1e-2, 4),
    ("pso", "ackley", 2, dict(iterations=300), 1e-10, 5),
    ("pso", "ackley", 10, dict(iterations=300), 1e-4, 5),
    ("bat", "sphere", 10, dict(iterations=500), 1e-4, 5),
    ("bat", "rosenbrock", 2, dict(iterations=500), 1e-4, 5),
    ("bat", "rastrigin", 2, dict(n=50, iterations=500, vmax=0.1), 1e-2, 4),
    ("bat", "ackley", 2, dict(n=50, iterations=500, vmax=0.05), 3e-2, 5),
]


@pytest.mark.parametrize("name,fname,d,params,tol,need", ACCURACY,
                         ids=[f"{c[0]}-{c[1]}-{c[2]}d" for c in ACCURACY])
def test_reaches_known_optimum(name, fname, d, params, tol, need):
    tf = FUNCTIONS[fname]
    results = [minimize(name, tf.f, tf.bounds(d), seed=seed, **params) for seed in range(5)]
    values = np.array([r.fun for r in results])
    assert np.sum(values <= tol) >= need, values
    for r in results:
        assert r.fun == pytest.approx(float(tf.f(r.x[None])[0]), abs=0, rel=1e-12)
        if r.fun <= tol and fname in ("sphere", "rosenbrock"):  # unimodal: x near the minimizer
            assert np.max(np.abs(r.x - tf.xstar)) <= _sublevel_extent(fname, tol) + 1e-12


def _sublevel_extent(fname, tol):
    """How far from the minimizer (max norm) a point with ``f <= tol`` can be. Sphere:
    ``sqrt(tol)``. 2-D Rosenbrock ``(1 - x1)^2 + 100 (x2 - x1^2)^2``: ``|x1 - 1| <= e`` with
    ``e = sqrt(tol)``, and ``|x2 - 1| <= |x2 - x1^2| + |x1^2 - 1| <= sqrt(tol / 100) + e (2 + e)``
    (the valley is long and flat: f = 0.005 at (1.07, 1.145))."""
    e = math.sqrt(tol)
    return e if fname == "sphere" else max(e, math.sqrt(tol / 100) + e * (2 + e))


def _tilted(X):
    X = np.atleast_2d(X)
    c = np.array([0.3, -0.7, 1.1])
    return (np.sum((X - c) ** 2 * np.array([1.0, 2.0, 0.5]), axis=1)
            + 0.3 * np.sin(3 * X[:, 0]) * X[:, 1] + 0.2 * np.cos(2 * X[:, 2]))


@pytest.fixture(scope="module")
def tilted_reference():
    bounds = [(-2.0, 2.0)] * 3
    ref = differential_evolution(lambda x: float(_tilted(x)[0]), bounds, seed=0, tol=1e-12,
                                 polish=True)
    return ref


@pytest.mark.parametrize("name,params,tol", [
    ("firefly", dict(iterations=300), 1e-7),
    ("fastep", dict(iterations=100), 1e-2),
    ("acor", dict(m=10, iterations=500), 1e-10),
    ("pso", dict(iterations=200), 1e-10),
    ("bat", dict(iterations=500), 1e-4),
])
def test_matches_differential_evolution_without_closed_form(name, params, tol, tilted_reference):
    lo, hi = np.full(3, -2.0), np.full(3, 2.0)
    for seed in range(3):
        r = minimize(name, _tilted, (lo, hi), seed=seed, **params)
        assert r.fun >= tilted_reference.fun - 1e-9
        assert r.fun - tilted_reference.fun < tol


# ------------------------------------------------------------------------------------------------
# invariants shared by every optimizer


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_result_and_no_global_state(name):
    tf = FUNCTIONS["rastrigin"]
    state = np.random.get_state()[1].copy()
    a = minimize(name, tf.f, tf.bounds(3), seed=123, **small(name))
    b = minimize(name, tf.f, tf.bounds(3), seed=123, **small(name))
    c = minimize(name, tf.f, tf.bounds(3), seed=np.random.default_rng(123), **small(name))
    d = minimize(name, tf.f, tf.bounds(3), seed=124, **small(name))
    assert np.array_equal(np.random.get_state()[1], state)  # global numpy state untouched
    for other in (b, c):
        assert np.array_equal(a.x, other.x) and a.fun == other.fun
        assert np.array_equal(a.population, other.population)
        assert np.array_equal(a.history.best, other.history.best)
        assert np.array_equal(a.history.mean, other.history.mean)
    assert not np.array_equal(a.population, d.population)


def _toward_corner(X):
    # minimum at the corner (lower, upper): pushes every method against two walls
    return X[:, 0] - X[:, 1] + 0.1 * np.sum(X**2, axis=1)


@pytest.mark.parametrize("name", NAMES)
def test_every_evaluated_point_is_inside_the_bounds(name):
    lo, hi = np.array([-1.0, 2.0, 0.0]), np.array([1.0, 2.5, 10.0])
    rec = Recorder(_toward_corner)
    params = dict(small(name), iterations=40)
    if name == "pso":
        params["vmax"] = 1.0  # the largest allowed steps
    if name == "acor":
        params["xi"] = 3.0  # wide kernels: many samples fall outside and are reflected
    minimize(name, rec, (lo, hi), seed=7, **params)
    P = rec.points
    assert P.shape[1] == 3 and np.all(P >= lo) and np.all(P <= hi)


@pytest.mark.parametrize("name", NAMES)
def test_one_objective_call_per_iteration_with_the_whole_swarm(name):
    rec = Recorder(sphere)
    r = minimize(name, rec, ([-1, -1], [1, 1]), seed=1, **small(name))
    first, per = sizes(name)
    assert r.nit == 6 and r.ncalls == len(rec.calls) == r.nit + 1
    assert [c.shape[0] for c in rec.calls] == [first] + [per] * r.nit
    assert r.nfev == first + per * r.nit == r.history.nfev[-1]
    assert np.array_equal(r.history.nfev, first + per * np.arange(r.nit + 1))


@pytest.mark.parametrize("name", NAMES)
def test_max_evals_and_target_budgets(name):
    first, per = sizes(name)
    params = dict(small(name), iterations=None)
    r = minimize(name, sphere, ([-1, -1], [1, 1]), seed=2, max_evals=first + 3 * per + per - 1,
                 **params)
    assert r.nfev == first + 3 * per and r.nit == 3 and r.message == "max_evals"
    r = minimize(name, sphere, ([-1, -1], [1, 1]), seed=2, **dict(small(name), iterations=5))
    assert r.message == "iterations" and r.nit == 5
    r = minimize(name, sphere, ([-1, -1], [1, 1]), seed=2, target=0.05,
                 **dict(small(name), iterations=10_000))
    assert r.message == "target" and r.fun <= 0.05 and r.nit < 10_000
    assert r.history.best[-2] > 0.05 or r.nit == 0  # it stopped at the first hit
    with pytest.raises(HybridnavError, match=r"^max_evals: .*initial population"):
        minimize(name, sphere, ([-1, -1], [1, 1]), max_evals=first - 1, **params)


@pytest.mark.parametrize("name", NAMES)
def test_history_best_is_monotone_and_matches_the_result(name):
    tf = FUNCTIONS["ackley"]
    r = minimize(name, tf.f, tf.bounds(3), seed=3, **dict(small(name), iterations=30))
    h = r.history
    assert len(h.best) == len(h.mean) == len(h.population_best) == len(h.nfev) == r.nit + 1
    assert np.all(np.diff(h.best) <= 0)
    assert h.best[-1] == r.fun and np.all(h.population_best >= h.best)
    assert np.all(h.mean >= h.population_best)
    assert r.values.shape == (r.population.shape[0],)
    assert np.array_equal(r.values, tf.f(r.population))


@pytest.mark.parametrize("name", ["fastep", "acor", "bat"])
def test_elitist_methods_never_lose_their_best(name):
    tf = FUNCTIONS["rastrigin"]
    r = minimize(name, tf.f, tf.bounds(4), seed=4, **dict(small(name), iterations=40))
    assert np.all(np.diff(r.history.population_best) <= 0)
    if name == "acor":  # the archive holds the k best points ever evaluated
        assert np.array_equal(r.history.population_best, r.history.best)
    if name in ("acor", "bat"):  # members are only ever replaced by better ones
        assert np.all(np.diff(r.history.mean) <= 0)


@pytest.mark.parametrize("name", NAMES)
def test_nan_counts_as_infinity(name):
    def f(X):
        v = sphere(X - 0.5)
        v[X[:, 0] > 0.0] = np.nan  # the unconstrained minimum is in the NaN region
        return v

    r = minimize(name, f, ([-1, -1], [1, 1]), seed=5, **dict(small(name), iterations=30))
    assert r.x[0] <= 0.0 and np.isfinite(r.fun)
    assert not np.any(np.isnan(r.values)) and not np.any(np.isnan(r.history.best))
    everything_nan = minimize(name, lambda X: np.full(len(X), np.nan), ([-1], [1]), seed=5,
                              **small(name))
    assert everything_nan.fun == math.inf and np.all(everything_nan.values == math.inf)


@pytest.mark.parametrize("name", NAMES)
def test_init_points_are_the_first_evaluated(name):
    rec = Recorder(sphere)
    init = np.array([[0.25, -0.5], [0.0, 0.0]])
    r = minimize(name, rec, ([-1, -1], [1, 1]), seed=6, init=init, **small(name))
    assert np.array_equal(rec.calls[0][:2], init)
    assert r.fun == 0.0 and np.array_equal(r.x, [0.0, 0.0])  # the best point is kept


# ------------------------------------------------------------------------------------------------
# firefly and FAStep


def test_firefly_move_is_yangs_formula_with_relative_distance():
    # 1-D, alpha = 0: firefly at 1 moves towards the brighter one at 0 by beta(r) (0 - 1),
    # with r relative to the box size 4; the brightest (at 0) moves randomly by alpha * eps = 0.
    rec = Recorder(lambda X: np.abs(X[:, 0]))
    beta0, gamma = 0.8, 3.0
    firefly(rec, ([-2.0], [2.0]), n=2, iterations=1, seed=0, init=[[0.0], [1.0]], alpha=0.0,
            beta0=beta0, gamma=gamma)
    beta = beta0 * np.exp(-gamma * (1.0 / 4.0) ** 2)
    assert rec.calls[1][:, 0] == pytest.approx([0.0, 1.0 - beta], abs=1e-15)


def test_firefly_moves_towards_every_brighter_one_in_turn():
    # three fireflies on a line, alpha = 0: the dimmest (at 2) first moves towards the brightest
    # (at 0), then, from there, towards the second (at 1), with x_j and F from the generation start
    rec = Recorder(lambda X: np.abs(X[:, 0]))
    firefly(rec, ([-2.0], [2.0]), n=3, iterations=1, seed=0, init=[[0.0], [1.0], [2.0]],
            alpha=0.0, beta0=1.0, gamma=2.0)
    b = lambda r: np.exp(-2.0 * (r / 4.0) ** 2)
    x2 = 2.0 + b(2.0) * (0.0 - 2.0)
    x2 = x2 + b(abs(1.0 - x2)) * (1.0 - x2)
    x1 = 1.0 + b(1.0) * (0.0 - 1.0)
    assert rec.calls[1][:, 0] == pytest.approx([0.0, x1, x2], abs=1e-15)


@pytest.mark.parametrize("fn", [firefly, fastep])
def test_alpha_is_damped_geometrically(fn):
    r = fn(sphere, ([-1, -1], [1, 1]), n=4, iterations=5, seed=0, alpha=0.3, damping=0.5)
    assert np.isnan(r.history.extra["alpha"][0])
    assert r.history.extra["alpha"][1:] == pytest.approx(0.3 * 0.5 ** np.arange(5))


def _fastep_one_generation(f, init, **kw):
    rec = Recorder(f)
    r = fastep(rec, ([-10.0], [10.0]), n=3, iterations=1, seed=0, init=init, alpha=0.0, **kw)
    return r, rec


def test_fastep_non_improving_move_is_replaced_by_the_stepping_ahead_move():
    # Values |x| at the three starting points, +100 anywhere else: no standard move improves,
    # so every firefly but the best takes eq. 4, z_i = x_b + beta(r_ib) (x_i - x_b) (alpha = 0),
    # even though z_i is worse; the best (at 0) keeps its place.
    start = [0.0, 1.0, 5.0]

    def f(X):
        x = X[:, 0]
        return np.abs(x) + 100.0 * ~np.isin(x, start)

    beta0, gamma = 2.0, 1.0
    r, rec = _fastep_one_generation(f, [[s] for s in start], beta0=beta0, gamma=gamma)
    beta = lambda r_: beta0 * np.exp(-gamma * (r_ / 20.0) ** 2)
    expected = [0.0, beta(1.0) * 1.0, beta(5.0) * 5.0]
    assert r.population[:, 0] == pytest.approx(expected, abs=1e-12)
    assert r.values[1] > 100 and r.values[2] > 100  # accepted although worse
    assert list(r.state["stepped"]) == [False, True, True]
    # the stepping-ahead candidates are the second half of the generation's single call
    assert rec.calls[1].shape == (6, 1)
    assert rec.calls[1][3:, 0] == pytest.approx(expected, abs=1e-12)
    assert r.history.extra["stepped"][1] == pytest.approx(2 / 3)


def test_fastep_improving_standard_move_is_preferred():
    # plain |x|: the standard move of the firefly at 1 towards 0 overshoots to 1 - beta(1) ~ -0.995
    # which is better than 1, so it is kept although the stepping-ahead move (~1.99) is not used
    beta0, gamma = 2.0, 1.0
    r, _ = _fastep_one_generation(lambda X: np.abs(X[:, 0]), [[0.0], [1.0], [9.0]],
                                  beta0=beta0, gamma=gamma)
    b1 = beta0 * np.exp(-gamma * (1.0 / 20.0) ** 2)
    assert r.population[1, 0] == pytest.approx(1.0 - b1, abs=1e-12)
    assert not r.state["stepped"][1]


def test_fastep_defaults_are_the_papers_table_1():
    sig = inspect.signature(fastep).parameters
    assert (sig["n"].default, sig["beta0"].default, sig["alpha"].default,
            sig["damping"].default) == (50, 2.0, 0.2, 0.8)
    assert PRESETS["fastep"]["fastep-kinematic"] == {
        "n": 50, "gamma": sig["gamma"].default, "beta0": 2.0, "alpha": 0.2, "damping": 0.8}


# ------------------------------------------------------------------------------------------------
# ACOR


def test_acor_weights_against_hand_computation():
    # k = 3, q = 0.5: qk = 1.5, w_l = exp(-(l-1)^2 / 4.5) / (1.5 sqrt(2 pi))
    c = 1.0 / (1.5 * math.sqrt(2.0 * math.pi))
    assert c == pytest.approx(0.2659615202676218)
    hand = [c, c * math.exp(-1 / 4.5), c * math.exp(-4 / 4.5)]
    assert acor_weights(3, 0.5) == pytest.approx(hand, rel=1e-14)
    assert acor_weights(3, 0.5) == pytest.approx([0.26596152, 0.21296534, 0.10934005], rel=1e-7)
    # Socha & Dorigo's default q = 1e-4 puts all the weight on the best solution
    w = acor_weights(50, 1e-4)
    assert w[0] == pytest.approx(1 / (1e-4 * 50 * math.sqrt(2 * math.pi))) and w[1] == 0.0
    # ACO-Kinematic: q = 0.5, k = 300 (weights decrease with rank, none vanishes)
    w = acor_weights(300, 0.5)
    assert np.all(np.diff(w) < 0) and w[-1] / w[0] == pytest.approx(math.exp(-299**2 / 45000))


def test_acor_chooses_kernels_by_weight_and_spreads_by_xi():
    # archive {0, 10, 20} in [-100, 100]; tiny xi: every sample sits at its kernel's mean, so the
    # share of samples at each archive point estimates p_l = w_l / sum(w).
    rec = Recorder(lambda X: np.abs(X[:, 0] - 0.0))
    m = 40_000
    acor(rec, ([-100.0], [100.0]), k=3, m=m, q=0.5, xi=1e-9, iterations=1, seed=0,
         init=[[0.0], [10.0], [20.0]])
    Z = rec.calls[1][:, 0]
    nearest = np.argmin(np.abs(Z[:, None] - np.array([0.0, 10.0, 20.0])), axis=1)
    w = acor_weights(3, 0.5)
    share = np.bincount(nearest, minlength=3) / m
    assert share == pytest.approx(w / w.sum(), abs=0.01)  # 4 sigma of a binomial at m = 40 000
    # sigma_l,i = xi * sum_e |s_e - s_l| / (k - 1): for the kernel at 10 that is xi * 10
    xi = 0.5
    rec = Recorder(lambda X: np.abs(X[:, 0] - 10.0))
    acor(rec, ([-1000.0], [1000.0]), k=3, m=m, q=1e-6, xi=xi, iterations=1, seed=1,
         init=[[0.0], [10.0], [20.0]])  # q -> 0: always the best kernel (at 10)
    Z = rec.calls[1][:, 0]
    assert np.mean(Z) == pytest.approx(10.0, abs=0.1)
    assert np.std(Z) == pytest.approx(xi * (10 + 10) / 2, rel=0.02)


def test_acor_archive_is_sorted_and_keeps_the_best_k():
    rec = Recorder(rastrigin)
    r = acor(rec, ([-5, -5], [5, 5]), k=10, m=7, iterations=5, seed=3)
    P = rec.points
    V = rastrigin(P)
    assert np.all(np.diff(r.values) >= 0)
    assert r.values == pytest.approx(np.sort(V)[:10])


def test_aco_kinematic_preset():
    assert ACO_KINEMATIC == {"k": 300, "m": 10000, "xi": 1.0, "q": 0.5}
    r = minimize("acor", sphere, ([-1, -1], [1, 1]), preset="aco-kinematic", iterations=2, seed=0)
    assert r.params["k"] == 300 and r.params["m"] == 10000 and r.nfev == 300 + 2 * 10000
    r = minimize("acor", sphere, ([-1, -1], [1, 1]), preset="aco-kinematic", m=50, iterations=2,
                 seed=0)
    assert r.params["m"] == 50 and r.params["k"] == 300  # explicit parameters win


# ------------------------------------------------------------------------------------------------
# PSO


def _fold(x, lo, hi):
    span = hi - lo
    y = np.mod(x - lo, 2 * span)
    return lo + np.where(y > span, 2 * span - y, y)


def test_pso_reflects_position_and_reverses_velocity_at_the_walls():
    # one particle, w = 1, c1 = c2 = 0: constant speed, bouncing between the walls; the evaluated
    # positions are the straight line x0 + t v0 folded into the box, and the final velocity is
    # +-v0 according to the direction of travel.
    lo, hi = np.array([0.0, -1.0]), np.array([1.0, 3.0])
    x0 = np.array([0.5, 1.0])
    rec = Recorder(sphere)
    r = pso(rec, (lo, hi), n=1, iterations=25, seed=4, init=[x0], w=1.0, c1=0.0, c2=0.0,
            vmax=0.3)
    xs = rec.points
    v0 = xs[1] - xs[0]  # |v0| <= 0.3 of the box from the middle: the first step does not reflect
    t = np.arange(26)[:, None]
    assert xs == pytest.approx(_fold(x0 + t * v0, lo, hi), abs=1e-12)
    n_walls = np.floor((x0 + 25 * v0 - lo) / (hi - lo))  # walls crossed per coordinate
    assert np.all(n_walls != 0)  # the test really bounced
    assert r.state["velocity"][0] == pytest.approx(np.where(n_walls % 2, -v0, v0), abs=1e-12)


def test_pso_velocity_is_clamped_and_inertia_schedule():
    rec = Recorder(sphere)
    r = pso(rec, ([-1, -1], [1, 1]), n=10, iterations=8, seed=5, vmax=0.05, c1=2.0, c2=2.0,
            w=0.9, w_end=0.4)
    steps = np.diff(np.stack(rec.calls), axis=0)
    assert np.all(np.abs(steps) <= 0.05 * 2 + 1e-12)
    assert np.all(np.abs(r.state["velocity"]) <= 0.1 + 1e-12)
    assert r.history.extra["w"][1:] == pytest.approx(np.linspace(0.9, 0.4, 8))
    # personal bests are the best point each particle has visited
    visited = np.stack(rec.calls)  # (iterations + 1, n, d)
    vals = np.array([sphere(v) for v in visited])
    assert r.state["pbest_values"] == pytest.approx(vals.min(axis=0))


def test_rfd_pso_preset():
    r = minimize("pso", sphere, ([-1, -1], [1, 1]), preset="rfd-pso", iterations=3, seed=0)
    assert (r.params["w"], r.params["c1"], r.params["c2"]) == (0.5, 0.75, 0.75)


# ------------------------------------------------------------------------------------------------
# bat


def test_bat_loudness_and_pulse_rate_schedules():
    # A0 = 1000 keeps rand < A true for 65 acceptances, so a bat accepts exactly when its
    # candidate is no worse: the acceptances are visible in the recorded calls.
    A0, r0, alpha, gamma = 1000.0, 0.6, 0.9, 0.05
    rec = Recorder(sphere)
    r = bat(rec, ([-5, -5], [5, 5]), n=6, iterations=30, seed=8, loudness=A0, pulse_rate=r0,
            alpha=alpha, gamma=gamma, walk=1e-5)  # walk steps of 1e-5 * A * 10 ~ 0.1
    F = sphere(rec.calls[0])
    count = np.zeros(6, dtype=int)
    last = np.zeros(6, dtype=int)
    for t, S in enumerate(rec.calls[1:], start=1):
        FS = sphere(S)
        acc = FS <= F
        F = np.where(acc, FS, F)
        count += acc
        last[acc] = t
    assert np.array_equal(r.state["accepted"], count) and count.max() < 60 and count.sum() > 12
    assert r.state["loudness"] == pytest.approx(A0 * alpha ** count, rel=1e-12)
    expected_r = np.where(count > 0, r0 * (1 - np.exp(-gamma * last)), r0)
    assert r.state["pulse_rate"] == pytest.approx(expected_r, rel=1e-12)
    assert r.history.extra["loudness"][-1] == pytest.approx(np.mean(A0 * alpha ** count))
    assert r.values == pytest.approx(F)


def test_bat_low_loudness_rejects_every_move():
    # rand < A never holds for A = 1e-300: the bats never move, but the best point evaluated is
    # still reported (and steers the velocities)
    rec = Recorder(sphere)
    r = bat(rec, ([-1, -1], [1, 1]), n=5, iterations=20, seed=9, loudness=1e-300)
    assert np.array_equal(r.population, rec.calls[0]) and np.all(r.state["accepted"] == 0)
    assert r.fun == sphere(rec.points).min() < sphere(rec.calls[0]).min()
    assert np.all(r.history.population_best == r.history.population_best[0])


def test_bat_walk_scales_with_the_mean_loudness():
    # pulse rate 0: every candidate is a local walk around the best, inside best +- walk A (hi-lo)
    rec = Recorder(sphere)
    bat(rec, ([-4, -4], [4, 4]), n=50, iterations=1, seed=10, pulse_rate=0.0, loudness=0.5,
        walk=0.1)
    best = rec.calls[0][np.argmin(sphere(rec.calls[0]))]
    dev = np.abs(rec.calls[1] - best)
    assert dev.max() <= 0.1 * 0.5 * 8 + 1e-12 and dev.max() > 0.3


# ------------------------------------------------------------------------------------------------
# input validation


@pytest.mark.parametrize("bounds,pattern", [
    (([0, 0], [1]), r"^bounds: .*same length"),
    (([0, 1], [1, 1]), r"^bounds: lower\[1\] = 1 is not below upper\[1\] = 1"),
    (([0, 2], [1, 1]), r"^bounds: lower\[1\]"),
    (([0, np.nan], [1, 1]), r"^bounds: lower\[1\] = nan is not finite"),
    (([0, 0], [1, np.inf]), r"^bounds: upper\[1\] = inf is not finite"),
    (([[0, 0]], [[1, 1]]), r"^bounds: lower and upper must be 1-D"),
    (([], []), r"^bounds: .*d >= 1"),
    ((0, 1, 2), r"^bounds: expected \(lower, upper\)"),
    ("ab", r"^bounds: expected \(lower, upper\)"),
    ((["a"], [1]), r"^bounds: expected \(lower, upper\), two sequences of numbers"),
])
@pytest.mark.parametrize("name", NAMES)
def test_bad_bounds(name, bounds, pattern):
    with pytest.raises(HybridnavError, match=pattern):
        minimize(name, sphere, bounds, **small(name))


@pytest.mark.parametrize("name", NAMES)
def test_bad_budgets_and_objectives(name):
    b = ([-1, -1], [1, 1])
    params = small(name)
    with pytest.raises(HybridnavError, match=r"^iterations: expected an integer >= 1, got 0"):
        minimize(name, sphere, b, **dict(params, iterations=0))
    with pytest.raises(HybridnavError, match=r"^iterations: .*2.5"):
        minimize(name, sphere, b, **dict(params, iterations=2.5))
    with pytest.raises(HybridnavError, match=r"^iterations: give a budget"):
        minimize(name, sphere, b, **dict(params, iterations=None))
    with pytest.raises(HybridnavError, match=r"^max_evals: expected an integer >= 1, got -5"):
        minimize(name, sphere, b, max_evals=-5, **params)
    with pytest.raises(HybridnavError, match=r"^target: expected a finite number"):
        minimize(name, sphere, b, target=float("nan"), **params)
    with pytest.raises(HybridnavError, match=r"^f: expected a callable"):
        minimize(name, "sphere", b, **params)
    with pytest.raises(HybridnavError, match=r"^f: returned shape \(8, 1\) for 8 points"):
        minimize(name, lambda X: sphere(X)[:, None], b, **params)
    with pytest.raises(HybridnavError, match=r"^f: returned shape \(\) for 8 points"):
        minimize(name, lambda X: 1.0, b, **params)
    with pytest.raises(HybridnavError, match=r"^f: returned list that is not an array of real"):
        minimize(name, lambda X: ["x"] * len(X), b, **params)
    with pytest.raises(HybridnavError, match=r"^init: expected an \(m, 2\) array of points"):
        minimize(name, sphere, b, init=[[0.0, 0.0, 0.0]], **params)
    with pytest.raises(HybridnavError, match=r"^init: point 1 = \[0.0, 2.0\] is outside bounds"):
        minimize(name, sphere, b, init=[[0.0, 0.0], [0.0, 2.0]], **params)
    with pytest.raises(HybridnavError, match=r"^init: 9 points given for a population of 8"):
        minimize(name, sphere, b, init=np.zeros((9, 2)), **params)
    with pytest.raises(HybridnavError, match=r"^seed: "):
        minimize(name, sphere, b, seed=-1, **params)


@pytest.mark.parametrize("fn,kwargs,pattern", [
    (firefly, dict(n=0), r"^n: expected an integer >= 1, got 0"),
    (firefly, dict(alpha=-0.1), r"^alpha: expected a non-negative number"),
    (firefly, dict(gamma=float("inf")), r"^gamma: expected a finite number"),
    (firefly, dict(beta_min=2.0), r"^beta_min: expected a number in \[0, 1\]"),
    (firefly, dict(damping=0.0), r"^damping: expected a number in \(0, 1\]"),
    (fastep, dict(damping=1.5), r"^damping: "),
    (fastep, dict(beta0=-1), r"^beta0: "),
    (fastep, dict(n=True), r"^n: expected an integer"),
    (acor, dict(k=1), r"^k: expected an integer >= 2, got 1"),
    (acor, dict(m=0), r"^m: expected an integer >= 1"),
    (acor, dict(q=0.0), r"^q: expected a positive number"),
    (acor, dict(xi=-1.0), r"^xi: "),
    (pso, dict(vmax=0.0), r"^vmax: expected a number in \(0, 1\]"),
    (pso, dict(vmax=1.5), r"^vmax: "),
    (pso, dict(c1=-1.0), r"^c1: "),
    (pso, dict(w="0.7"), r"^w: expected a number, got '0.7'"),
    (bat, dict(fmin=1.0, fmax=0.5), r"^fmax: expected a number in \[1, inf\)"),
    (bat, dict(loudness=0.0), r"^loudness: "),
    (bat, dict(pulse_rate=1.2), r"^pulse_rate: expected a number in \[0, 1\]"),
    (bat, dict(alpha=0.0), r"^alpha: "),
    (bat, dict(walk=0.0), r"^walk: "),
    (bat, dict(vmax=-1.0), r"^vmax: "),
])
def test_bad_method_parameters(fn, kwargs, pattern):
    with pytest.raises(HybridnavError, match=pattern):
        fn(sphere, ([-1], [1]), iterations=2, **kwargs)


def test_minimize_registry_and_errors():
    assert set(OPTIMIZERS) >= {"firefly", "fastep", "acor", "pso", "bat"}
    direct = pso(rastrigin, ([-3, -3], [3, 3]), n=6, iterations=4, seed=11, c1=1.0)
    via = minimize("pso", rastrigin, ([-3, -3], [3, 3]), n=6, iterations=4, seed=11, c1=1.0)
    assert np.array_equal(direct.population, via.population) and via.method == "pso"
    with pytest.raises(HybridnavError, match=r"^name: unknown optimizer 'ga'; expected one of: "
                                             r"firefly, fastep, acor, pso, bat"):
        minimize("ga", sphere, ([-1], [1]))
    with pytest.raises(HybridnavError, match=r"^colour: unknown parameter of pso; expected one "
                                             r"of: .*vmax"):
        minimize("pso", sphere, ([-1], [1]), colour=3)
    with pytest.raises(HybridnavError, match=r"^n: unknown parameter of acor"):
        minimize("acor", sphere, ([-1], [1]), n=3)
    with pytest.raises(HybridnavError, match=r"^preset: unknown preset 'x' for bat; expected one "
                                             r"of: \(none\)"):
        minimize("bat", sphere, ([-1], [1]), preset="x")
    r = minimize("firefly", sphere, ([-1], [1]), n=3, iterations=2, seed=0)
    assert r.params["n"] == 3 and r.params["iterations"] == 2 and r.params["max_evals"] is None


def test_bounds_accept_scipy_bounds_object():
    from scipy.optimize import Bounds

    r = pso(sphere, Bounds([-1, -2], [1, 2]), n=4, iterations=2, seed=0)
    assert r.x.shape == (2,)


# ------------------------------------------------------------------------------------------------
# documentation and layering


@pytest.mark.parametrize("fn", [*OPTIMIZERS.values(), minimize, acor_weights])
def test_docstrings_document_every_parameter(fn):
    doc = inspect.getdoc(fn)
    assert "Parameters\n----------" in doc and "Returns\n-------" in doc
    for p in inspect.signature(fn).parameters.values():
        if p.kind is p.VAR_KEYWORD:
            assert f"**{p.name}" in doc
            continue
        assert any(line.startswith(p.name) or f", {p.name}" in line.split(" : ")[0]
                   for line in doc.splitlines()), p.name


def test_swarm_package_knows_nothing_about_robots():
    pkg = pathlib.Path(swarm.__file__).parent
    # (hybridnav.native.attract: the firefly loop in C, built by hybridnav.native; neither knows
    # robots)
    allowed = ("numpy", "scipy", "hybridnav.errors", "hybridnav.params", "hybridnav.planners.swarm", "__future__",
               "collections", "dataclasses", "inspect", "logging", "math", "numbers", "typing",
               "hybridnav.native.attract")
    for path in pkg.glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                mods = [node.module or ""]
            else:
                continue
            for mod in mods:
                assert mod.startswith(allowed), f"{path.name} imports {mod}"
