"""The LbCS planner: reaches open goals, stalls in the local minimum the analysis finds."""

from __future__ import annotations

import numpy as np
import pytest

from hybridnav import HybridnavError, models, planners
from hybridnav.analysis import find_equilibria
from hybridnav.world import load_scenario


def test_lbcs_stalls_in_the_local_minimum_of_the_trap():
    s = load_scenario("aco-local-minimum")
    r = planners.get("lbcs").run(s).robots[0]
    assert r.outcome == "stuck" and r.time_to_goal is None
    lb = models.LbCS.from_scenario(s)
    eqs = find_equilibria(lb, target=s.robots[0].goal, region={"x": (0, 50), "y": (0, 50)})
    minima = [e.state for e in eqs if e.kind == "stable" and not e.is_target]
    assert min(np.linalg.norm(r.states[-1, :2] - m) for m in minima) < 0.05


def test_lbcs_reaches_open_goals_without_collisions():
    res = planners.get("lbcs").run(load_scenario("fastep-s1"))
    r = res.robots[0]
    assert r.outcome == "reached" and r.min_clearance > 0
    # the closed loop is the LbCS gradient flow: L never increases along the run
    s = load_scenario("fastep-s1")
    lb = models.LbCS.from_scenario(s)
    import casadi as cs
    L = cs.Function("L", [lb.sym.x, lb.sym.target, lb.sym.p], [lb.lyapunov_function()])
    vals = np.array([float(L(x, s.robots[0].goal, lb.p_value())) for x in r.states])
    assert np.all(np.diff(vals) <= 1e-9 * vals[0])


def test_lbcs_refuses_what_it_cannot_model():
    with pytest.raises(HybridnavError, match="the LbCS model takes circle obstacles only"):
        planners.get("lbcs").run(load_scenario("fastep-s3"))
    with pytest.raises(HybridnavError, match="planner lbcs drives point_mass"):
        planners.get("lbcs").run(load_scenario("tractor-trailer-1"))
