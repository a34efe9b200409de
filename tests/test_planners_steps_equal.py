"""Faster forms of the step planners' pieces equal the forms they replace, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from hybridnav.planners.step.stepfit import GoalDistance
from hybridnav.world import load_scenario


def _goal_distance_loop(gd, P, goal):
    """GoalDistance.__call__ as first written: the 2 x 2 cells one after the other."""
    g = gd.grid
    field, radius = gd._field(goal)
    P = np.asarray(P, dtype=float).reshape(-1, 2)
    goal = np.asarray(goal, float).reshape(2)
    base = np.floor((P - np.asarray(g.origin)) / g.resolution - 0.5).astype(int)
    best = np.full(len(P), np.inf)
    for dc in (0, 1):
        for dr in (0, 1):
            cells = base + np.array([dc, dr])
            inside = g.in_bounds(cells)
            val = np.full(len(P), np.inf)
            val[inside] = field[g.cell_index(cells[inside])]
            c = g.to_world(cells)
            best = np.minimum(best, val + np.hypot(P[:, 0] - c[:, 0], P[:, 1] - c[:, 1]))
    straight = np.hypot(P[:, 0] - goal[0], P[:, 1] - goal[1])
    return np.where(straight < radius, straight, best)


@pytest.mark.filterwarnings("ignore:invalid value encountered in cast")
@pytest.mark.parametrize("name", ["fastep-s2", "tractor-trailer-1"])
def test_goal_distance_equals_the_cell_by_cell_loop(name):
    scenario = load_scenario(name)
    gd = GoalDistance(scenario, inflate=scenario.robots[0].radius)
    rng = np.random.default_rng(len(name))
    xmin, xmax, ymin, ymax = scenario.world.workspace
    for goal in (np.array(scenario.robots[0].goal, float), np.array([xmin, ymax])):
        for n in (0, 1, 7, 500):
            P = np.column_stack([rng.uniform(xmin - 3, xmax + 3, n),
                                 rng.uniform(ymin - 3, ymax + 3, n)])
            P[rng.random(n) < 0.05] = np.nan
            P[rng.random(n) < 0.05] = goal
            assert gd(P, goal).tobytes() == _goal_distance_loop(gd, P, goal).tobytes()


@pytest.mark.parametrize("planner,scenario", [("fastep-kinematic", "fastep-s3"),
                                              ("aco-kinematic", "fastep-s1")])
def test_runs_are_the_same_with_the_compiled_kernels_off(planner, scenario, monkeypatch):
    """The attraction loop and the sweep's box kernels switched off (HYBRIDNAV_NATIVE=0, read
    at every call): the same run, state for state."""
    from hybridnav import planners

    runs = []
    for env in ("1", "0"):
        monkeypatch.setenv("HYBRIDNAV_NATIVE", env)
        result = planners.get(planner).run(load_scenario(scenario), seed=0)
        runs.append([(r.outcome, r.states.tobytes()) for r in result.robots])
    assert runs[0] == runs[1]


@pytest.mark.filterwarnings("ignore:invalid value encountered in cast")
@pytest.mark.parametrize("name", ["fastep-s2", "tractor-trailer-1"])
def test_step_fitness_is_row_by_row(name):
    """The planners evaluate the fitness of the feasible candidates only: a row's value does not
    depend on the other rows (straight-line and geodesic distance, circles, edges, robots)."""
    from hybridnav.planners.step.stepfit import Surroundings, step_fitness

    scenario = load_scenario(name)
    world = scenario.world
    xmin, xmax, ymin, ymax = world.workspace
    rng = np.random.default_rng(3)
    robots = rng.uniform(xmin, xmax, (2, 2))
    env = Surroundings.at(world, 0.0, robots, (robots, np.array([0.5, 0.7])))
    gd = GoalDistance(scenario, inflate=scenario.robots[0].radius)
    goal = np.array(scenario.robots[0].goal, float)
    X = np.column_stack([rng.uniform(xmin - 1, xmax + 1, 400), rng.uniform(ymin - 1, ymax + 1, 400)])
    X[::37] = np.nan
    X[5] = goal
    X[6] = robots[0]
    for dist in (None, gd):
        full = step_fitness(X, goal, env, 0.18, 0.18, 0.18, 0.01, goal_distance=dist)
        for sel in (np.arange(0), np.array([5]), np.flatnonzero(rng.random(400) < 0.3)):
            part = step_fitness(X[sel], goal, env, 0.18, 0.18, 0.18, 0.01, goal_distance=dist)
            assert part.tobytes() == full[sel].tobytes()


@pytest.mark.parametrize("planner,scenario", [("fastep-kinematic", "fastep-s3"),
                                              ("aco-kinematic", "fastep-s1")])
def test_runs_are_the_same_when_every_candidate_is_checked(planner, scenario, monkeypatch):
    """The step fitness as a lower bound (only the candidates whose value can change the
    swarm's run get the swept-footprint check) against every candidate's value computed: the
    same run, state for state."""
    from hybridnav import planners
    from hybridnav.planners.swarm import _core

    runs = []
    for bounded in (True, False):
        if not bounded:
            monkeypatch.setattr(_core.Run, "bounded", property(lambda self: False))
        result = planners.get(planner).run(load_scenario(scenario), seed=0)
        runs.append([(r.outcome, r.states.tobytes()) for r in result.robots])
    assert runs[0] == runs[1]
