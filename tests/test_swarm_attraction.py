"""The firefly attraction moves equal Yang's loop as first written, bit for bit, random draws
included (ties, infinite and NaN values, one firefly, all tied)."""

from __future__ import annotations

import numpy as np
import pytest

from hybridnav import native
from hybridnav.native import attract
from hybridnav.planners.swarm._core import Run
from hybridnav.planners.swarm.firefly import _attraction_moves, _beta


def _reference(run, X, F, alpha_t, beta0, gamma, beta_min):
    """The loop over j as it was first written: a boolean mask of the movers per j."""
    n, d = X.shape
    inv_diag2 = 1.0 / float(run.span @ run.span)
    Y = X.copy()
    moved = np.zeros(n, dtype=bool)
    for j in np.argsort(F, kind="stable"):
        movers = F[j] < F
        k = int(np.count_nonzero(movers))
        if k == 0:
            break
        diff = X[j] - Y[movers]
        beta = _beta(np.einsum("ij,ij->i", diff, diff) * inv_diag2, beta0, gamma, beta_min)
        Y[movers] += beta[:, None] * diff + alpha_t * (run.rng.random((k, d)) - 0.5) * run.span
        moved |= movers
    still = ~moved
    Y[still] += alpha_t * (run.rng.random((int(np.count_nonzero(still)), d)) - 0.5) * run.span
    return np.clip(Y, run.lower, run.upper)


def _values(rng, n, kind):
    F = rng.standard_normal(n)
    if kind == "ties":
        F = rng.integers(0, 4, n).astype(float)
    elif kind == "special":
        F = rng.choice([-np.inf, np.inf, np.nan, 0.0, 1.0, -1.0, 2.5], n)
    elif kind == "mixed":
        F[rng.random(n) < 0.3] = np.inf
        F[rng.random(n) < 0.1] = np.nan
        F[rng.random(n) < 0.2] = 0.5
    elif kind == "equal":
        F[:] = 3.0
    elif kind == "nan":
        F[:] = np.nan
    return F


@pytest.mark.parametrize("compiled", [True, "ctypes", False])
@pytest.mark.parametrize("kind", ["plain", "ties", "special", "mixed", "equal", "nan"])
@pytest.mark.parametrize("d", [1, 2, 3])
def test_attraction_moves_equal_the_loop_bit_for_bit(kind, d, compiled, monkeypatch):
    """Every path: the compiled loop (d <= 2, where a compiler is) called through the generated
    extension or through ctypes, and the NumPy loop."""
    if not compiled:
        monkeypatch.setenv(native.ENV, "0")
    elif compiled == "ctypes":
        from hybridnav.native import pycall

        monkeypatch.setitem(native._KERNELS, "attract:functions",
                            pycall._from_ctypes("attract", attract._SIGNATURES))
    rng = np.random.default_rng([d, len(kind)])
    for trial in range(40):
        n = int(rng.integers(1, 60))
        lower = -rng.random(d) * 5
        upper = lower + 0.1 + rng.random(d) * 10
        X = lower + rng.random((n, d)) * (upper - lower)
        F = _values(rng, n, kind)
        args = (float(rng.random()), float(rng.choice([0.0, 1.0, 2.0])),
                float(rng.choice([0.0, 1.0, 100.0])))
        beta_min = float(rng.choice([0.0, 0.5])) * args[1]
        outs, states = [], []
        for fn in (_reference, _attraction_moves):
            run = Run("firefly", lambda Z: Z[:, 0], (lower, upper), 1, None, None, trial)
            outs.append(fn(run, X, F, *args, beta_min))
            states.append(run.rng.random())      # the same number of draws were taken
        assert outs[0].tobytes() == outs[1].tobytes()
        assert states[0] == states[1]


def test_the_compiled_loop_runs_where_it_applies(monkeypatch):
    """With a compiler, d <= 2 goes to C; d = 3 and HYBRIDNAV_NATIVE=0 do not (Ys untouched)."""
    if attract._library() is None:
        pytest.skip("no C compiler")
    Xs = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.5]])
    E, order, first = np.zeros((3, 2)), np.array([2, 0, 1]), np.array([1, 2])
    Ys = Xs.copy()
    assert attract.moves(Xs, Ys, E, order, first, 3, 0.1, 1.0, 2.0, 0.0)
    assert not np.array_equal(Ys, Xs)
    Y3 = np.zeros((3, 3))
    assert not attract.moves(Y3, Y3, np.zeros((3, 3)), order, first, 3, 0.1, 1.0, 2.0, 0.0)
    monkeypatch.setenv(native.ENV, "0")
    Ys = Xs.copy()
    assert not attract.moves(Xs, Ys, E, order, first, 3, 0.1, 1.0, 2.0, 0.0)
    assert np.array_equal(Ys, Xs)


def test_the_compiled_loop_equals_numpy_on_a_real_swarm():
    """Whole runs of both firefly optimizers agree with the kernel on and off (history included)."""
    from hybridnav.planners.swarm import fastep, firefly
    from hybridnav.planners.swarm.functions import rastrigin

    for fn in (fastep, firefly):
        runs = []
        for env in ("1", "0"):
            with pytest.MonkeyPatch.context() as mp:
                mp.setenv(native.ENV, env)
                r = fn(rastrigin, ([-5.0, -5.0], [5.0, 5.0]), n=30, iterations=40, seed=3)
            runs.append((r.x.tobytes(), r.population.tobytes(), np.asarray(r.history.best).tobytes()))
        assert runs[0] == runs[1]
