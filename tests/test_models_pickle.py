"""Models and general systems pickle (process pools, Dask): as their class and settings, the
CasADi symbols and compiled functions rebuilt where they are unpickled."""

from __future__ import annotations

import pickle
from concurrent.futures import ProcessPoolExecutor

import casadi as cs
import numpy as np
import pytest

from hybridnav import models
from hybridnav.analysis import as_system


def _batch(m, n=5):
    rng = np.random.default_rng(0)
    X = rng.uniform(0.5, 1.5, (n, m.nx))
    return X, np.full((n, 2), 3.0)


@pytest.mark.parametrize("name, params", [("unicycle", {"k_alpha": 3.0}),
                                          ("point_mass", {}),
                                          ("tractor_trailer", {}),
                                          ("lbcs", {"obstacles": [(1.0, 1.0, 0.2)], "beta": 1.5})])
def test_a_used_model_pickles_and_steps_the_same(name, params):
    m = models.get(name, dt=0.05, **params)
    X, T = _batch(m)
    before = m.step(X, T)              # compiled functions and buffers are now cached
    m.commanded_rates(X, T)
    back = pickle.loads(pickle.dumps(m))
    assert type(back) is type(m)
    assert back.values == m.values and back.options == m.options and back.dt == 0.05
    assert np.array_equal(back.step(X, T), before)
    assert np.array_equal(back.rollout(X, T, 20), m.rollout(X, T, 20))


def test_values_changed_in_place_travel_with_the_model():
    m = models.get("unicycle")
    m.values["k_alpha"] = 2.5
    assert pickle.loads(pickle.dumps(m)).values["k_alpha"] == 2.5


def test_a_general_system_pickles_with_its_names_and_field():
    q = cs.SX.sym("q", 2)
    s = as_system((q, cs.vertcat(q[1], -cs.sin(q[0]) - 0.5 * q[1])), equilibrium=[0, 0],
                  states=["th", "om"], name="pendulum")
    back = pickle.loads(pickle.dumps(s))
    assert back.state_names == ("th", "om") and back.name == "pendulum"
    assert back._key() == s._key()
    assert np.array_equal(back.equilibrium, s.equilibrium)
    f0 = cs.Function("f", [s.sym.x], [s.closed_loop()])
    f1 = cs.Function("f", [back.sym.x], [back.closed_loop()])
    z = np.array([0.3, -0.2])
    assert np.array_equal(np.asarray(f0(z)), np.asarray(f1(z)))


def _rollout_end(m):
    X, T = _batch(m, 3)
    return m.rollout(X, T, 10)[:, -1]


def test_a_model_goes_to_a_process_pool():
    m = models.get("tractor_trailer")
    with ProcessPoolExecutor(1) as pool:
        there = pool.submit(_rollout_end, m).result()
    assert np.array_equal(there, _rollout_end(m))
