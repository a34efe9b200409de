"""Plan-then-track planners: astar, dijkstra, rfd, pso, rfd-pso (hybridnav.planners.path.planners)."""

from __future__ import annotations

import copy
import dataclasses
import math
import re
from types import SimpleNamespace

import networkx as nx
import numpy as np
import pytest
from matplotlib.figure import Figure

from hybridnav import HybridnavError
from hybridnav.planners.path.planners import (
    AStarPlanner,
    DijkstraPlanner,
    PSOPathPlanner,
    RFDPlanner,
    RFDPSOPlanner,
    grid_rectangles,
    obstacle_world,
    pull_tight,
    resample_waypoints,
)
from hybridnav.results import OUTCOMES, path_length, read_result
from hybridnav.world import (
    Circle,
    World,
    builtin_data_path,
    load_scenario,
    scenario_from_dict,
)
from hybridnav.world.grid import build_grid, load_movingai_scen

ALL = (AStarPlanner, DijkstraPlanner, RFDPlanner, PSOPathPlanner, RFDPSOPlanner)

# A 20 x 20 m room with a wall from the bottom and a circle: the way from (2, 2) to (18, 4)
# goes over the wall.
SYNTH = {
    "name": "paths-synthetic", "dt": 0.1, "max_time": 200.0,
    "workspace": {"xmin": 0.0, "xmax": 20.0, "ymin": 0.0, "ymax": 20.0},
    "obstacles": [{"type": "rectangle", "min": [8.0, 0.0], "max": [10.0, 12.0]},
                  {"type": "circle", "center": [14.0, 14.0], "radius": 2.0}],
    "robots": [{"name": "r", "model": "point_mass", "start": [2.0, 2.0], "goal": [18.0, 4.0],
                "goal_radius": 0.3, "radius": 0.3}],
    "grid": {"resolution": 0.5},
}


def synthetic(**robot):
    data = copy.deepcopy(SYNTH)
    data["robots"][0].update(robot)
    return scenario_from_dict(data)


def distance_to_polyline(P, path):
    """Distance of each point of P (N, 2) to the polyline ``path`` (M, 2)."""
    A, B = path[:-1][None], path[1:][None]
    AB = B - A
    s = np.clip(np.sum((P[:, None] - A) * AB, axis=2) / np.maximum(np.sum(AB * AB, axis=2), 1e-300),
                0, 1)
    Q = A + s[..., None] * AB
    return np.hypot(*(P[:, None] - Q).transpose(2, 0, 1)).min(axis=1)


def planned(result, k=0):
    """The planned path of robot ``k`` as the result carries it (extras ``planned_<robot>``)."""
    tab = result.extras[f"planned_{result.robots[k].name}"]
    return np.column_stack([tab["x"], tab["y"]])


def plan_is_valid(scenario, result, clearance):
    """The planned path runs start -> goal, is collision-free and its length is reported."""
    r = scenario.robots[0]
    robot_result = result.robots[0]
    p = SimpleNamespace(points=planned(result))
    assert len(p.points)
    np.testing.assert_array_equal(p.points[0], r.start)
    np.testing.assert_array_equal(p.points[-1], r.goal)
    world = obstacle_world(scenario)
    assert not world.segment_collides(p.points[:-1], p.points[1:], radius=clearance).any()
    assert robot_result.metrics["planned_length"] == pytest.approx(path_length(p.points),
                                                                   rel=1e-12)
    assert robot_result.metrics["waypoints"] == len(p.points) - 2
    assert 0 < robot_result.metrics["planning_time"] <= robot_result.compute_time


# --------------------------------------------------------------------------------------------
# Every planner reaches the goal
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("model", ["point_mass", "unicycle"])
@pytest.mark.parametrize("cls", ALL, ids=lambda c: c.name)
def test_every_planner_reaches_the_goal_of_the_synthetic_room(cls, model):
    s = synthetic(model=model)
    planner = cls()
    res = planner.run(s, seed=0)
    r = res.robots[0]
    assert res.planner == cls.name and res.seed == 0
    assert r.outcome == "reached" and r.min_clearance > 0
    assert np.hypot(*(r.states[-1, :2] - s.robots[0].goal)) <= s.robots[0].goal_radius
    # the planned path keeps the robot radius plus the margin (a quarter cell) from obstacles
    # (grid paths: half the margin, the chords between cell centres may dip below the
    # inflation a little)
    cell = s.grid.resolution
    plan_is_valid(s, res, 0.3 + (0.25 if cls in (PSOPathPlanner, RFDPSOPlanner)
                                        else 0.125) * cell)
    # the robot stays near its path: within the lookahead (point mass) or a cell (unicycle)
    dev = distance_to_polyline(r.states[:, :2], planned(res))
    assert dev.max() < (0.5 if model == "point_mass" else 1.0) * cell
    assert r.summary()["smoothness"] >= 0


@pytest.mark.parametrize("cls", (AStarPlanner, DijkstraPlanner, RFDPlanner, RFDPSOPlanner),
                         ids=lambda c: c.name)
def test_reaches_the_goal_of_rfd_pso_700_with_the_differential_drive(cls):
    s = load_scenario("rfd-pso-700")
    res = cls().run(s, seed=0)
    r = res.robots[0]
    assert s.robots[0].model == "unicycle"
    assert r.outcome == "reached" and r.min_clearance > 0
    plan_is_valid(s, res, 12.5 if cls is RFDPSOPlanner else 11.25)
    # no path can be shorter than the straight line (80, 450) -> (600, 100)
    assert r.metrics["planned_length"] > math.hypot(520, 350)


@pytest.mark.long
def test_pso_alone_on_rfd_pso_700():
    s = load_scenario("rfd-pso-700")
    # seed 8 finds a collision-free path in its first run
    res = PSOPathPlanner().run(s, seed=8)
    r = res.robots[0]
    assert r.outcome == "reached" and r.metrics["pso_runs"] == 1 and r.min_clearance > 0
    plan_is_valid(s, res, 12.5)
    # seed 0's single run ends on a path with a colliding segment: no plan, the robot is stuck
    # (not an exception); a few restarts find one
    r0 = PSOPathPlanner().run(s, seed=0).robots[0]
    assert r0.outcome == "stuck" and r0.metrics["planned_length"] is None
    assert len(r0.t) == 1 and r0.path_length == 0.0
    r3 = PSOPathPlanner(restarts=6).run(s, seed=0).robots[0]
    assert r3.outcome == "reached" and 1 < r3.metrics["pso_runs"] <= 7


@pytest.mark.parametrize("cls", ALL, ids=lambda c: c.name)
def test_every_planner_reaches_the_goal_of_arena(cls):
    s = load_scenario("arena")
    res = cls().run(s, seed=0)
    r = res.robots[0]
    assert r.outcome == "reached"
    # the map's cells are the obstacles the run is checked against
    assert 0 < r.min_clearance < math.inf
    plan_is_valid(s, res, 0.4)


# --------------------------------------------------------------------------------------------
# Lengths against references
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("cls", (AStarPlanner, DijkstraPlanner), ids=lambda c: c.name)
def test_grid_planners_plan_movingai_optimal_length_on_arena(cls):
    s = load_scenario("arena")
    (q,) = [q for q in load_movingai_scen(builtin_data_path("arena.map.scen"))
            if q.start == (3, 45) and q.goal == (39, 11)]
    # without a margin the 0.4-radius robot blocks no cell: the grid is the benchmark's map
    r = cls(margin=0.0).run(s).robots[0]
    assert r.metrics["planned_length"] == pytest.approx(q.optimal_length, abs=1e-6)
    assert r.metrics["grid_length"] == pytest.approx(q.optimal_length, abs=1e-6)
    assert r.outcome == "reached" and r.min_clearance > 0


@pytest.mark.parametrize("scenario", ["arena", "rfd-pso-700"])
def test_astar_length_is_networkx_optimal_on_the_inflated_grid(scenario):
    s = load_scenario(scenario)
    planner = AStarPlanner()
    r = planner.run(s).robots[0]
    p = planner.plans(s)[0]                  # the same plan, with the planner's internals
    assert r.metrics["planned_length"] == p.length
    grid = p.info["grid"]
    cells = grid.to_cell(np.array([s.robots[0].start, s.robots[0].goal]))
    ref = nx.astar_path_length(grid.to_networkx(), tuple(cells[0]), tuple(cells[1]),
                               weight="weight")
    assert r.metrics["grid_length"] == pytest.approx(ref, rel=1e-12)
    # the followed path swaps the end cells' centres for the exact start and goal
    centres = p.info["search"].points
    swap = (np.hypot(*(centres[1] - s.robots[0].start)) - np.hypot(*(centres[1] - centres[0]))
            + np.hypot(*(centres[-2] - s.robots[0].goal)) - np.hypot(*(centres[-2] - centres[-1])))
    assert r.metrics["planned_length"] == pytest.approx(ref + swap, rel=1e-12)
    # the inflated grid keeps the robot radius plus the margin (0.25 cells) around obstacles
    assert grid.occ.sum() > build_grid(s).occ.sum()
    d = DijkstraPlanner().run(s).robots[0]
    assert d.metrics["grid_length"] == pytest.approx(ref, rel=1e-12)


@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.long),
                                  pytest.param(2, marks=pytest.mark.long)])
def test_rfd_pso_is_never_longer_than_its_rfd_path(seed):
    s = load_scenario("rfd-pso-700")
    rfd, hybrid = RFDPlanner(), RFDPSOPlanner()
    ra, rb = rfd.run(s, seed=seed), hybrid.run(s, seed=seed)
    a, b = ra.robots[0], rb.robots[0]
    # the same seed plans the same RFD path in both
    np.testing.assert_array_equal(planned(ra), np.column_stack(
        [rb.extras["rfd_path_" + rb.robots[0].name][k] for k in "xy"]))
    assert b.metrics["rfd_length"] == a.metrics["planned_length"]
    assert b.metrics["planned_length"] <= a.metrics["planned_length"]
    # the seed particle: corners from the RFD path, points added on straight pieces only; it
    # is no longer than the RFD path and collision-free
    seed_pts = np.column_stack([rb.extras["rfd_seed_" + rb.robots[0].name][k] for k in "xy"])
    vertices = {tuple(v) for v in planned(ra)}
    for j in range(1, len(seed_pts) - 1):
        if tuple(seed_pts[j]) not in vertices:
            assert distance_to_polyline(seed_pts[j][None], seed_pts[[j - 1, j + 1]])[0] < 1e-9
    assert path_length(seed_pts) <= a.metrics["planned_length"] + 1e-9
    assert not obstacle_world(s).segment_collides(seed_pts[:-1], seed_pts[1:], radius=12.5).any()
    # ... and the PSO ends no worse than it
    assert b.metrics["planned_length"] <= path_length(seed_pts) + 1e-9
    assert b.outcome == "reached"


# --------------------------------------------------------------------------------------------
# Seeds, failures, errors
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("cls", (RFDPlanner, PSOPathPlanner, RFDPSOPlanner), ids=lambda c: c.name)
def test_seeds_reproduce_results_exactly(cls):
    s = synthetic()
    planners = [cls() for _ in range(3)]
    runs = [p.run(s, seed=k) for p, k in zip(planners, (5, 5, 6), strict=True)]
    a, b = runs[0].robots[0], runs[1].robots[0]
    np.testing.assert_array_equal(a.states, b.states)
    timing = ("planning_time", "compute_time")
    sa, sb = ({k: v for k, v in r.summary().items() if k not in timing} for r in (a, b))
    assert sa == sb
    # another seed plans another path
    assert not np.array_equal(planned(runs[0]), planned(runs[2]))
    assert cls.stochastic


def test_an_unreachable_goal_ends_stuck_for_every_planner():
    data = copy.deepcopy(SYNTH)
    # a closed box of four walls around the goal
    data["obstacles"] = [{"type": "rectangle", "min": lo, "max": hi} for lo, hi in
                         (([15, 1], [19, 2]), ([15, 6], [19, 7]), ([15, 1], [16, 7]),
                          ([18, 1], [19, 7]))]
    data["robots"][0]["goal"] = [17.0, 4.0]
    s = scenario_from_dict(data)
    for cls in ALL:
        r = cls(iterations=20, particles=10).run(s, seed=0).robots[0] \
            if issubclass(cls, PSOPathPlanner) else cls().run(s, seed=0).robots[0]
        assert r.outcome == "stuck", cls.name
        assert r.metrics["planned_length"] is None and r.metrics["waypoints"] is None
        assert len(r.t) == 1 and r.metrics["planning_time"] > 0
        assert r.outcome in OUTCOMES


def test_a_goal_inside_the_inflation_ends_stuck():
    # 0.3 from the wall: free for the 0.3-radius robot, blocked once the margin is added
    s = synthetic(goal=[10.45, 4.0])
    r = AStarPlanner().run(s).robots[0]
    assert r.outcome == "stuck" and r.metrics["planned_length"] is None


@pytest.mark.parametrize("cls, kwargs, message", [
    (AStarPlanner, {"heuristic": "chebyshev"},
     ("planner astar: heuristic: expected one of octile, euclidean, manhattan, zero, got "
      "'chebyshev'")),
    (PSOPathPlanner, {"waypoints": 0},
     "planner pso: waypoints: expected an integer >= 1, got 0"),
    (PSOPathPlanner, {"waypoints": 2.5}, "planner pso: waypoints: expected an integer, got 2.5"),
    (RFDPSOPlanner, {"vmax": 1.5},
     "planner rfd-pso: vmax: expected a number in (0, 1], got 1.5"),
    (RFDPlanner, {"drops": "many"}, "planner rfd: drops: expected an integer, got 'many'"),
    (DijkstraPlanner, {"heuristic": "octile"},
     ("planner dijkstra: unknown parameter 'heuristic'; expected one of: corner_cutting, "
      "diagonal, grid, lookahead, margin, shorten, speed, stuck_radius, stuck_window")),
    (RFDPSOPlanner, {"speed": 0.0},
     "planner rfd-pso: speed: expected a positive number, got 0.0"),
])
def test_bad_parameters_give_the_exact_error(cls, kwargs, message):
    with pytest.raises(HybridnavError) as info:
        cls(**kwargs)
    assert str(info.value) == message


def test_moving_obstacles_and_targets_and_other_models_are_refused():
    for cls in ALL:
        assert cls.moving_obstacles is False and cls.moving_targets is False
    s = load_scenario("pso-ba-dynamic")
    with pytest.raises(HybridnavError, match="robots\\[1\\].goal_follow: planner rfd-pso does "
                                             "not handle moving targets"):
        RFDPSOPlanner().run(s)
    data = copy.deepcopy(SYNTH)
    data["obstacles"].append({"type": "moving_circle", "center": [5.0, 15.0], "radius": 1.0,
                              "velocity": 0.1, "heading": 0.0})
    with pytest.raises(HybridnavError, match="obstacles: planner astar does not handle moving "
                                             "obstacles"):
        AStarPlanner().run(scenario_from_dict(data))
    driven = PSOPathPlanner.models            # from the registry: a new disk model joins
    assert {"point_mass", "unicycle"} <= set(driven) and "tractor_trailer" not in driven
    with pytest.raises(HybridnavError, match=re.escape(
            f"robots[0].model: planner pso drives {', '.join(driven)}, got 'tractor_trailer'")):
        PSOPathPlanner().run(load_scenario("tractor-trailer-1"))


# --------------------------------------------------------------------------------------------
# Helpers and diagnostics
# --------------------------------------------------------------------------------------------


def test_grid_rectangles_cover_exactly_the_blocked_cells():
    s = load_scenario("arena")
    grid = build_grid(s)
    rects = grid_rectangles(grid)
    assert len(rects) < grid.occ.sum() / 5
    cells = np.argwhere(np.ones(grid.shape, dtype=bool))[:, ::-1]
    centres = grid.to_world(cells)
    world = World(s.world.workspace, tuple(rects))
    blocked = world.clearance(centres) < 0
    np.testing.assert_array_equal(blocked.reshape(grid.shape), grid.occ)
    # and no cell is covered twice: the areas add up
    area = sum((r.max[0] - r.min[0]) * (r.max[1] - r.min[1]) for r in rects)
    assert area == grid.occ.sum() * grid.resolution ** 2
    assert len(obstacle_world(s).obstacles) == len(rects)
    assert len(obstacle_world(load_scenario("rfd-pso-700")).obstacles) == 9


def test_resample_and_pull_tight_keep_the_polyline():
    P = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])
    W = resample_waypoints(P, 6)
    assert len(W) == 6
    full = np.vstack([P[0], W, P[-1]])
    assert path_length(full) == pytest.approx(7.0, rel=1e-15)
    assert distance_to_polyline(W, P).max() < 1e-15
    assert any(np.array_equal(w, P[1]) for w in W)           # the corner is kept
    many = resample_waypoints(np.array([[0, 0], [1, 0], [1, 1], [2, 1], [2, 2.0]]), 2)
    assert len(many) == 3                                     # never drops a vertex
    world = World((-1, 5, -1, 5), ())
    np.testing.assert_array_equal(pull_tight(full, world, 0.1), P[[0, 2]])
    blocked = World((-1, 5, -1, 5), (Circle((2.4, 1.8), 0.5),))   # on the shortcut
    tight = pull_tight(full, blocked, 0.1)
    assert path_length(tight) <= path_length(full)
    assert not blocked.segment_collides(tight[:-1], tight[1:], radius=0.1).any()


def test_diagnostics_draw_the_planned_paths(tmp_path):
    s = synthetic()
    for cls, n_axes in ((AStarPlanner, 1), (RFDPSOPlanner, 2)):
        planner = cls()
        res = planner.run(s, seed=0)
        figs = planner.diagnostics(s, res)
        assert list(figs) == ["planned_paths.png"]
        fig = figs["planned_paths.png"]
        assert isinstance(fig, Figure) and len(fig.axes) == n_axes
        lines = [ln for ln in fig.axes[0].lines if ln.get_linestyle() == "--"]
        assert any(np.array_equal(np.column_stack(ln.get_data()), planned(res)) for ln in lines)
        # the same figure from the result read back from disk
        res.write(tmp_path / cls.name)
        again = planner.diagnostics(s, read_result(tmp_path / cls.name))["planned_paths.png"]
        lines = [ln for ln in again.axes[0].lines if ln.get_linestyle() == "--"]
        assert any(np.array_equal(np.column_stack(ln.get_data()), planned(res)) for ln in lines)
    # a result without planned paths draws nothing
    assert AStarPlanner().diagnostics(s, dataclasses.replace(res, extras={})) == {}
