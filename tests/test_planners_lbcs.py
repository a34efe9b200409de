"""The LbCS planner: reaches open goals, stalls in the local minimum the analysis finds."""

from __future__ import annotations

import casadi as cs
import numpy as np
import pytest

from hybridnav import HybridnavError, models, planners
from hybridnav.analysis import find_equilibria
from hybridnav.world import load_scenario, scenario_from_dict, scenario_to_dict


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
    s = load_scenario("tractor-trailer-1")
    data = scenario_to_dict(s)
    data["robots"][0] = {"name": "U", "model": "unicycle", "start": [5.0, 45.0],
                         "goal": [45.0, 5.0]}
    with pytest.raises(HybridnavError) as err:
        planners.get("lbcs").run(scenario_from_dict(data))
    driven = planners.PLANNERS["lbcs"].models          # from the registry: a new model joins
    assert {"point_mass", "tractor_trailer"} <= set(driven) and "unicycle" not in driven
    assert str(err.value) == ("tractor-trailer-1: robots[0].model: planner lbcs drives "
                              f"{', '.join(driven)}, got 'unicycle'")


def _lyapunov_along(lb, states, goal):
    L = cs.Function("L", [lb.sym.x, lb.sym.target, lb.sym.p], [lb.lyapunov_function()])
    return np.asarray(L.map(len(states))(states[:, :2].T, goal, lb.p_value())).ravel()


def test_lbcs_drives_the_tractor_trailer_down_L_to_its_goal():
    s = load_scenario("tractor-trailer-1")
    planner = planners.get("lbcs")
    r = planner.run(s).robots[0]
    assert r.state_names[:4] == ("x", "y", "theta0", "theta1")
    assert r.outcome == "reached" and r.min_clearance > 0       # tractor and trailer footprints
    assert np.hypot(*(r.states[-1, :2] - s.robots[0].goal)) <= s.robots[0].goal_radius
    # the tractor follows the LbCS descent direction: L (built with the tractor-trailer's radius)
    # at the tractor's reference point decreases from every recorded step to the next; the model
    # is nonholonomic, so this is a property of this run, not of the scheme (module docstring)
    lb = planner.lbcs(s, "TT1", rp=s.model(s.robots[0]).radius)
    vals = _lyapunov_along(lb, r.states, s.robots[0].goal)
    assert np.all(np.diff(vals) < 0)
    assert vals[-1] < 1e-3 * vals[0]
    # and the tractor's disk stays in the free space that L is defined on
    assert np.all(lb.admissible(r.states[:, :2]))


def test_lbcs_commands_at_most_the_go_to_goal_speed_along_the_lbcs_velocity():
    from hybridnav.planners.lbcs import _capped_carrot

    m = models.get("tractor_trailer")
    X = np.array([[0.0, 0.0, 0, 0, 0], [1.0, 1.0, 0, 0, 0], [2.0, 0.0, 0, 0, 0]])
    goals = np.array([[10.0, 0.0], [1.0, 5.0], [5.0, 4.0]])
    V = np.array([[3.0, 0.0], [0.0, 0.1], [0.0, 0.0]])   # capped, free, zero
    T = _capped_carrot(m, X, V, goals)
    np.testing.assert_allclose(T[0], goals[0])           # along the goal at the cap: the goal
    np.testing.assert_allclose(T[1], [1.0, 1.0 + 0.1 / m.values["alpha"]])
    np.testing.assert_allclose(T[2], X[2, :2])


def test_lbcs_moves_point_masses_alike_alone_and_next_to_a_tractor_trailer():
    s = load_scenario("tractor-trailer-1")
    pm = {"name": "P", "model": "point_mass", "start": [45.0, 45.0], "goal": [45.0, 28.0],
          "goal_radius": 0.5, "radius": 0.5}
    alone, mixed = scenario_to_dict(s), scenario_to_dict(s)
    alone["robots"] = [pm]
    mixed["robots"].append(pm)
    ra = planners.get("lbcs").run(scenario_from_dict(alone)).robots[0]
    rm = planners.get("lbcs").run(scenario_from_dict(mixed)).robots
    assert [r.outcome for r in rm] == ["reached", "reached"] and ra.outcome == "reached"
    assert rm[1].state_names == ("x", "y")                  # the LbCS model itself
    np.testing.assert_array_equal(rm[1].states, ra.states)


def test_lbcs_tractor_trailer_speed_stays_within_the_go_to_goal_law_near_obstacles():
    # beta = 0.1 (Table 4's range): uncapped, |grad L| near the first circle commands ~60 units/s
    # and the tractor jumps ~6 units in one cycle; capped, the speed v <= alpha * distance to the
    # goal, so the tractor's reference point moves at most v sqrt(1 + tan(phi)^2 / 4) per second
    # with |phi| <= (7/9) pi/2
    s = load_scenario("tractor-trailer-1")
    r = planners.get("lbcs", beta=0.1).run(s).robots[0]
    assert r.outcome == "reached" and r.min_clearance > 0
    alpha = s.model(s.robots[0]).values["alpha"]
    dist = np.hypot(*(r.states[:, :2] - s.robots[0].goal).T)
    step = np.hypot(*np.diff(r.states[:, :2], axis=0).T)
    bound = s.dt * alpha * dist.max() * np.sqrt(1 + np.tan(7 / 9 * np.pi / 2) ** 2 / 4)
    assert step.max() <= bound
