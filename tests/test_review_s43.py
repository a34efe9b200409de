"""Hostile review of the s43 changes (commanded_rates buffers, simulate's stuck window, the
tuner's side process): reproducers of what broke, and checks of what the changes claim."""

import casadi as cs
import numpy as np
import pytest

from hybridnav.models import MODELS


def _old_rates(m, X, T):
    """commanded_rates as it was at ebb7c18: the parameters a runtime input of fn.map(n)."""
    s = m.sym
    rates = m.body_rates(m.controller(s.x, s.target, s.p), s.p)
    if rates is None:
        return None
    n = len(X)
    if n == 0:
        return np.zeros((0, 2))
    fn = cs.Function("rates", [s.x, s.target, s.p], [rates])
    return np.asarray(fn.map(n)(X.T, T.T, m.p_value())).reshape(2, n).T


def _same_bits(a, b):
    return a.shape == b.shape and bool(np.all((a.view(np.int64) == b.view(np.int64))
                                              | (np.isnan(a) & np.isnan(b))))


@pytest.mark.parametrize("params", [dict(k_alpha=3.0), dict(k_alpha=7.3, k_rho=3.7, L=0.3),
                                    dict(k_alpha=1e300)])
def test_commanded_rates_bit_for_bit_with_non_default_gains(params):
    """Folding the parameter values into the rates function lets CasADi reassociate
    (k_alpha*e)*L into (k_alpha*L)*e: the last bits of v and omega differ from the old path for
    most gains (the defaults k_alpha=2 hide it: times 2 is exact)."""
    m = MODELS["unicycle"](jit=False, **params)
    rng = np.random.default_rng(1)
    X, T = rng.normal(size=(2000, 3)) * 5, rng.normal(size=(2000, 2)) * 5
    assert _same_bits(m.commanded_rates(X, T), _old_rates(m, X, T))


def test_commanded_rates_follow_values_changed_after_first_call():
    """The old path passed p_value() at every call; the substituted function is built once."""
    m = MODELS["unicycle"](jit=False)
    X, T = np.zeros((3, 3)), np.ones((3, 2))
    m.commanded_rates(X, T)
    m.values["k_rho"] = 0.25
    assert _same_bits(m.commanded_rates(X, T), _old_rates(m, X, T))
    np.testing.assert_array_equal(m.commanded_rates(X, T),
                                  MODELS["unicycle"](jit=False, k_rho=0.25).commanded_rates(X, T))


@pytest.mark.parametrize("name,params", [(n, {}) for n in MODELS]
                         + [("unicycle", dict(controller="heading", max_turn=0.3, speed=0.33)),
                            ("unicycle", dict(wheel_max=0.3, v_max=0.22, omega_max=2.84))])
@pytest.mark.parametrize("n", [0, 1, 3, 64])
def test_commanded_rates_match_old_path_every_model(name, params, n):
    m = MODELS[name](**params)
    rng = np.random.default_rng(n)
    X, T = rng.normal(size=(n, m.nx)) * 3, rng.normal(size=(n, 2)) * 3
    special = [0.0, -0.0, np.nan, np.inf, -np.inf, 1e308, 5e-324]
    for k in range(min(n, len(special))):
        X[k, k % m.nx] = special[k]
    new, old = m.commanded_rates(X, T), _old_rates(m, X, T)
    assert (new is None) == (old is None)
    if new is not None:
        assert _same_bits(new, old)


# ---- simulate: the no-progress window ------------------------------------------------------


def _one_robot_scenario(max_time=2.0):
    from hybridnav.world import scenario_from_dict
    return scenario_from_dict({
        "name": "t", "dt": 0.1, "max_time": max_time, "units": "m",
        "workspace": {"xmin": -10.0, "xmax": 10.0, "ymin": -10.0, "ymax": 10.0},
        "obstacles": [], "robots": [{"name": "R", "model": "point_mass", "start": [0.0, 0.0],
                                     "goal": [5.0, 0.0], "goal_radius": 0.1, "radius": 0.1}]})


@pytest.mark.parametrize("stuck_window", [1e8, 1e12])
def test_simulate_window_far_longer_than_the_run_is_no_memory_error(stuck_window):
    """stuck_window is only bounded below (planners' Param lo=0), so a huge value is a valid way
    to say "never"; the buffer of 2 * (window + 1) positions per robot is allocated from the
    window alone (2e9 rows for 1e8 s at dt 0.1) and numpy raises MemoryError, where the old loop
    simply never tested it. lockstep already cuts the window to steps + 1 (stuck_cycles)."""
    from hybridnav.planners.simulate import simulate
    s = _one_robot_scenario()
    (r,), _ = simulate(s, [s.model(s.robots[0])], lambda sim: sim.goals(),
                       stuck_window=stuck_window)
    assert r.outcome == "timeout" and len(r.t) == 21


# ---- tune: the side process of the SIL check --------------------------------------------------

_LEAVE = """
import sys, time
import hybridnav.tuner.run as run
t0 = time.time()
try:
    with run._SideTask(time.sleep, 30, elsewhere=True):   # a long SIL check, elsewhere
        time.sleep(1)                        # (the path figure)
        raise {exc}("in the path figure")
except {exc}:
    pass
print("left the block after %.1f s" % (time.time() - t0), flush=True)
"""


@pytest.mark.parametrize("exc", ["KeyboardInterrupt", "RuntimeError"])
def test_an_error_beside_the_side_process_does_not_wait_for_it_at_exit(exc):
    """_SideTask's docstring: "leaving the block (an error, Ctrl-C) ... does not wait for it".
    The block is left at once, but ProcessPoolExecutor's atexit hook joins its manager thread,
    which waits for the running task: `hybridnav tune` says "interrupted" (or prints the figure's
    error) and then the process stays until the whole SIL check is done (30 s here; a job's
    SIL takes seconds to minutes)."""
    import os
    import subprocess
    import sys
    import time

    t0 = time.time()
    done = subprocess.run([sys.executable, "-c", _LEAVE.format(exc=exc)], capture_output=True,
                          text=True, timeout=120, env={**os.environ, "PYTHONPATH": os.getcwd()})
    took = time.time() - t0
    assert "left the block after" in done.stdout, done.stderr
    assert took < 15, f"the process exited {took:.0f} s after it started (the task: 30 s)"
