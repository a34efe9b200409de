"""PSO-BA (hybridnav.planners.psoba.planner, hybridnav.planners.psoba.sensors)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from matplotlib.figure import Figure

from hybridnav import HybridnavError
from hybridnav.planners.psoba.planner import (
    PSOBAPlanner,
    disk_candidates,
    pso_ba,
    psoba_fitness,
)
from hybridnav.planners.psoba.sensors import (
    Scene,
    feasible,
    gap_index,
    gap_vector,
    local_search,
    near_room_walls,
    ray_entry,
    sector_ranges,
    sensing_vector,
)
from hybridnav.world import (
    Circle,
    MovingCircle,
    Polygon,
    Rectangle,
    Segment,
    World,
    load_scenario,
    scenario_from_dict,
)


def _scenario(obstacles, robots, max_time=200.0, size=20.0):
    return scenario_from_dict({
        "name": "psoba-test", "dt": 0.1, "max_time": max_time,
        "workspace": {"xmin": 0.0, "xmax": size, "ymin": 0.0, "ymax": size},
        "obstacles": obstacles, "robots": robots})


def _robot(start, goal, model="point_mass", radius=0.3, goal_radius=0.3):
    return {"name": "r", "model": model, "start": list(start), "goal": list(goal),
            "goal_radius": goal_radius, "radius": radius}


#: a U-shaped trap open towards the start; the goal lies behind its bottom
U_TRAP = [{"type": "rectangle", "min": [6.0, 6.0], "max": [14.0, 6.5]},
          {"type": "rectangle", "min": [13.5, 6.0], "max": [14.0, 14.0]},
          {"type": "rectangle", "min": [6.0, 13.5], "max": [14.0, 14.0]}]


def _boundary_samples(world: World, t: float = 0.0, m: int = 20001) -> np.ndarray:
    """Dense points on every obstacle's boundary (an independent reference for the sensors)."""
    pts = []
    th = np.linspace(0.0, 2 * np.pi, m)
    s = np.linspace(0.0, 1.0, m)[:, None]
    for o in world.obstacles:
        if isinstance(o, (Circle, MovingCircle)):
            c = o.center_at(t) if isinstance(o, MovingCircle) else np.asarray(o.center)
            pts.append(c + o.radius * np.c_[np.cos(th), np.sin(th)])
        elif isinstance(o, Segment):
            pts.append(np.asarray(o.a) + s * (np.asarray(o.b) - np.asarray(o.a)))
        else:
            V = o.vertices
            for a, b in zip(V, np.roll(V, -1, axis=0)):
                pts.append(a + s * (b - a))
    return np.concatenate(pts)


def _binned_min(p: np.ndarray, Q: np.ndarray, n: int = 12) -> np.ndarray:
    D = Q - p
    sec = (np.mod(np.arctan2(D[:, 1], D[:, 0]), 2 * np.pi) / (2 * np.pi / n)).astype(int) % n
    out = np.full(n, np.inf)
    dist = np.hypot(D[:, 0], D[:, 1])
    np.minimum.at(out, sec, dist)
    return out


# ---- sensing and gap vectors -------------------------------------------------------------------

def test_gap_vector_on_hand_made_sensing_vectors():
    # the paper's Figure 8 example
    vs = [1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1]
    assert gap_vector(vs).astype(int).tolist() == [0, 0, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0]
    assert gap_vector(np.zeros(12, bool)).all()
    assert not gap_vector(np.ones(12, bool)).any()
    # one sensed sector j closes the gaps on both of its sides: j - 1 and j (wrapping around)
    for j in (0, 5, 11):
        vs = np.zeros(12, bool)
        vs[j] = True
        assert set(np.flatnonzero(~gap_vector(vs))) == {(j - 1) % 12, j}
    # batches of vectors
    assert gap_vector([[1, 0, 0, 0], [0, 0, 1, 0]]).astype(int).tolist() == [[0, 1, 1, 0],
                                                                             [1, 0, 0, 1]]
    with pytest.raises(HybridnavError, match=r"vs: expected bits \(0/1 or bool\), got"):
        gap_vector([0, 2, 1])


def test_gap_index_is_the_gap_centred_nearest_the_direction():
    # gap j (0-based) is centred on the boundary ray at (j + 1) * 30 degrees
    assert gap_index(0.0, 12) == 11
    assert gap_index(math.radians(30), 12) == 0
    assert gap_index(math.radians(44), 12) == 0
    assert gap_index(math.radians(46), 12) == 1
    assert gap_index(math.radians(-90), 12) == 8
    assert sensing_vector([1.0, 2.0, np.inf], 2.0).tolist() == [True, False, False]


# ---- range sensors ------------------------------------------------------------------------------

def test_range_sensors_give_exact_distances_to_a_circle_and_a_segment():
    p = np.array([[5.0, 5.0]])
    # a circle whose centre lies at 45 degrees: sensor 1 (30..60 degrees) reads |c - p| - r
    world = World((0, 20, 0, 20), (Circle((9.0, 9.0), 1.0),))
    r = sector_ranges(Scene.build(world), p)[0]
    assert r[1] == pytest.approx(math.hypot(4, 4) - 1.0, abs=1e-12)
    assert np.isinf(np.delete(r, 1)).all()       # it subtends 2 asin(1 / 5.66) = 20 degrees
    # a larger one (30.7 degrees) also reaches sectors 0 and 2, through their boundary rays at
    # 30 and 60 degrees: the chord distance |c - p| cos(15) - sqrt(r^2 - (|c - p| sin 15)^2)
    world = World((0, 20, 0, 20), (Circle((9.0, 9.0), 1.5),))
    r = sector_ranges(Scene.build(world), p)[0]
    h = math.hypot(4, 4)
    off = h * math.sin(math.radians(15))
    chord = h * math.cos(math.radians(15)) - math.sqrt(1.5**2 - off**2)
    np.testing.assert_allclose(r[:3], [chord, h - 1.5, chord], rtol=1e-12)
    assert np.isinf(r[3:]).all()
    # a segment x = 8, -1 <= y <= 9 seen from (5, 5): sector 0 holds its foot (8, 5); sector 1
    # is bounded by the 30 degree ray (3 / cos 30); the 60 degree ray misses (y = 10.2 > 9) and
    # the end (8, 9) at 53.1 degrees lies in sector 1 but farther; sector 11 reads the foot
    # again (it lies on its boundary ray at 0 degrees); the lower end (8, -1) is at -63.4
    # degrees, in sector 9 (-90..-60), where the -60 degree ray hits at 3 / cos 60 = 6
    world = World((0, 20, 0, 20), (Segment((8.0, -1.0), (8.0, 9.0)),))
    r = sector_ranges(Scene.build(world), p)[0]
    assert r[0] == pytest.approx(3.0, abs=1e-12)
    assert r[1] == pytest.approx(3.0 / math.cos(math.radians(30)), abs=1e-12)
    assert r[11] == pytest.approx(3.0, abs=1e-12)
    assert r[10] == pytest.approx(3.0 / math.cos(math.radians(30)), abs=1e-12)
    assert r[9] == pytest.approx(6.0, abs=1e-12)
    assert np.isinf(r[2:9]).all()
    # the same numbers as the minimum over densely sampled segment points binned by angle
    ref = _binned_min(p[0], _boundary_samples(world))
    np.testing.assert_allclose(r, ref, atol=2e-3)


def test_range_sensors_match_binned_boundary_samples_on_a_cluttered_map():
    world = load_scenario("rfd-pso-700").world
    rng = np.random.default_rng(5)
    P = rng.uniform(0, 700, (60, 2))
    P = P[world.clearance(P) > 5.0][:25]
    got = sector_ranges(Scene.build(world), P)
    Q = _boundary_samples(world, m=40001)
    for p, row in zip(P, got):
        np.testing.assert_allclose(row, _binned_min(p, Q), atol=0.05)


def test_sensors_see_moving_circles_where_they_are_now():
    mc = MovingCircle((2.0, 10.0), 1.0, 0.5, 0.0)       # moving along +x at 0.5
    world = World((0, 20, 0, 20), (mc,))
    p = np.array([[12.0, 10.0]])
    for t in (0.0, 6.0, 12.0):
        scene = Scene.build(world.static(), world.moving(), t=t)
        r = sector_ranges(scene, p)[0]
        expect = abs(12.0 - (2.0 + 0.5 * t)) - 1.0
        assert r[5] == pytest.approx(expect, abs=1e-12)   # the circle is at 180 degrees
        assert scene.clearance(p)[0] == pytest.approx(world.clearance(p, t=t)[0], abs=1e-12)
    # swept over [t, t + h] it is the capsule between the two centres
    swept = Scene.build(world.static(), world.moving(), t=6.0, horizon=4.0)
    q = np.array([[6.0, 12.0], [7.5, 10.0], [3.0, 10.0], [9.0, 11.0]])   # axis (5, 10)-(7, 10)
    np.testing.assert_allclose(swept.clearance(q), [1.0, -0.5, 1.0, math.sqrt(5) - 1.0],
                               atol=1e-12)


def test_scene_clearance_and_ray_casts_agree_with_the_world():
    world = World((0, 30, 0, 30), (Circle((10, 10), 2), Rectangle((18, 4), (24, 9)),
                                   Polygon(((5, 20), (12, 22), (8, 27))),
                                   Segment((20, 15), (27, 25)),
                                   MovingCircle((15, 28), 1.5, 0.7, -1.2)))
    rng = np.random.default_rng(0)
    P = rng.uniform(0, 30, (400, 2))
    for t in (0.0, 7.5):
        scene = Scene.build(world.static(), world.moving(), t=t)
        np.testing.assert_allclose(scene.clearance(P), world.clearance(P, t=t), atol=1e-12)
        # a ray's first entry within `inflate` of an obstacle: the segment up to it is clear,
        # a little beyond it is not
        out = P[world.clearance(P, t=t) > 1.0][:60]
        ang = rng.uniform(0, 2 * np.pi, len(out))
        U = np.c_[np.cos(ang), np.sin(ang)]
        for p, u in zip(out, U):
            lam = ray_entry(scene, p, u[None], 0.5)[0, 0]
            if not np.isfinite(lam):
                far = p + 60 * u
                assert not world.segment_collides(p, far, radius=0.5, t=t)[0]
                continue
            assert not world.segment_collides(p, p + lam * u, radius=0.5 - 1e-9, t=t)[0]
            assert world.segment_collides(p, p + (lam + 1e-6) * u, radius=0.5, t=t)[0]


def test_room_wall_detection_follows_the_paper_conditions():
    near = near_room_walls([[1.0, 5.0], [9.5, 9.5], [5.0, 5.0]], (0, 10, 0, 10), 2.0)
    assert near.tolist() == [[True, False, False, False], [False, True, False, True],
                             [False, False, False, False]]


# ---- local search ---------------------------------------------------------------------------------

@pytest.mark.parametrize("case", ["inside circle", "oblique rectangle", "thin wall",
                                  "polygon", "moving circle"])
def test_local_search_puts_the_point_at_ds_with_a_free_segment(case):
    ds, radius = 1.0, 0.5
    obstacles = {
        "inside circle": (Circle((10.0, 5.0), 2.0),),
        "oblique rectangle": (Rectangle((8.0, 2.0), (12.0, 9.0)),),
        "thin wall": (Segment((9.0, 0.5), (9.0, 9.5)),),
        "polygon": (Polygon(((8.0, 3.0), (12.0, 1.0), (11.0, 9.0))),),
        "moving circle": (MovingCircle((10.0, -5.0), 1.5, 1.0, math.pi / 2),),
    }[case]
    world = World((0, 20, 0, 20), obstacles)
    t = 10.0
    p = np.array([2.0, 4.0])
    c = np.array([10.0, 5.0]) if case == "inside circle" else np.array([16.0, 6.5])
    scene = Scene.build(world.static(), world.moving(), t=t, walls=True)
    assert not feasible(scene, p, c, radius)
    out, repaired = local_search(scene, p, c, ds, radius)
    assert repaired
    # exactly ds from the nearest obstacle (the world's own clearance, at the same time)
    assert world.clearance(out, t=t)[0] == pytest.approx(ds, abs=1e-9)
    # on the ray p -> c, between them, and the whole segment keeps ds
    d, u = out - p, (c - p) / np.hypot(*(c - p))
    assert abs(d[0] * u[1] - d[1] * u[0]) < 1e-12 and 0 < d @ u < np.hypot(*(c - p))
    assert not world.segment_collides(p, out, radius=ds - 1e-9, t=t)[0]
    # the first such point: a little farther along the ray is closer than ds
    assert world.clearance(out + 1e-6 * u, t=t)[0] < ds


def test_local_search_agrees_with_eq_22_head_on_and_leaves_feasible_points_alone():
    world = World((0, 20, 0, 20), (Circle((10.0, 10.0), 2.0),))
    scene = Scene.build(world, walls=True)
    p, c, ds = np.array([1.5, 10.0]), np.array([12.0, 10.0]), 1.0
    out, repaired = local_search(scene, p, c, ds, 0.5)
    # eq. 22 with Wq = (8, 10), the obstacle point nearest Wp on the line: Wp + (Wpi - Wp) *
    # (|Wp - Wq| - ds) / |Wp - Wpi|
    q = np.array([8.0, 10.0])
    eq22 = p + (c - p) * (np.hypot(*(p - q)) - ds) / np.hypot(*(p - c))
    assert repaired and np.allclose(out, eq22, atol=1e-12)
    free, repaired = local_search(scene, p, np.array([3.0, 14.0]), ds, 0.5)
    assert not repaired and np.array_equal(free, [3.0, 14.0])
    # a candidate passing between 0.5 and 1.0 from the circle is feasible, not repaired
    c2 = np.array([10.0, 12.7])
    assert 0.5 < world.clearance(c2)[0] < 1.0
    assert not local_search(scene, np.array([4.0, 12.7]), c2, ds, 0.5)[1]
    # the workspace border counts as a wall
    out, repaired = local_search(scene, np.array([18.0, 10.0]), np.array([25.0, 10.0]), ds, 0.5)
    assert repaired and out == pytest.approx([19.0, 10.0], abs=1e-12)
    with pytest.raises(HybridnavError, match=r"ds: expected ds >= radius >= 0, got ds=0.2, "
                                             r"radius=0.5"):
        local_search(scene, p, c, 0.2, 0.5)


# ---- fitness and PSO-BA -------------------------------------------------------------------------

def test_fitness_values_by_hand():
    p, g = np.array([0.0, 0.0]), np.array([10.0, 0.0])
    X = np.array([[10.0, 0.0], [0.0, 10.0], [5.0, 5.0], [-3.0, 0.0], [0.0, 0.0]])
    got = psoba_fitness(X, p, g, st=10.0, w1=0.5, floor=0.3)
    dn = 0.3 + 0.7 * math.sqrt(50) / 10            # (5, 5): 7.071 from the goal, 45 degrees
    expect = [1 / (0.5 * 0.3 + 0.001),              # the goal: distance floor, angle 0
              1 / (0.5 * 1.0 + 0.5 * 1.0 + 0.001),  # 14.1 > ST: distance 1; 90 degrees
              1 / (0.5 * dn + 0.5 * 0.5 + 0.001),
              1 / (0.5 * 1.0 + 0.5 * 2.0 + 0.001),  # behind the robot: 180 degrees
              1 / (0.5 * 1.0 + 0.001)]              # the robot's own position: d = ST, angle 0
    np.testing.assert_allclose(got, expect, rtol=1e-14)
    # w1 = 1: distance only; w1 = 0: angle only
    np.testing.assert_allclose(psoba_fitness(X[:3], p, g, 10.0, w1=1.0),
                               [1 / 0.301, 1 / 1.001, 1 / (dn + 0.001)], rtol=1e-14)
    np.testing.assert_allclose(psoba_fitness(X[:3], p, g, 10.0, w1=0.0),
                               [1 / 0.001, 1 / 1.001, 1 / 0.501], rtol=1e-14)
    # the normalised distance stays in [floor, 1]: the fitness is bounded by 1 / (w1 floor + e)
    far = psoba_fitness(np.array([[100.0, 0.0]]), p, g, 10.0)
    assert far[0] == pytest.approx(1 / (0.5 + 0.001))
    with pytest.raises(HybridnavError, match=r"st: expected a positive distance, got 0.0"):
        psoba_fitness(X, p, g, st=0.0)
    with pytest.raises(HybridnavError, match=r"w1: expected a weight in \[0, 1\], got 1.5"):
        psoba_fitness(X, p, g, st=1.0, w1=1.5)


def test_pso_ba_finds_the_best_point_of_the_disk():
    p, g, step = np.array([3.0, 4.0]), np.array([13.0, 9.0]), 1.5

    def fit(X):
        return psoba_fitness(disk_candidates(X, p, step), p, g, 20.0)

    res = pso_ba(fit, p - step, p + step, seed=7, particles=4, pso_iterations=3, bats=12,
                 bat_iterations=12, alpha_bounds=(0.2, 0.9), gamma_bounds=(0.1, 0.8))
    best = p + step * (g - p) / np.hypot(*(g - p))   # on the circle, towards the goal
    x = disk_candidates(res.x, p, step)[0]
    assert np.hypot(*(x - best)) < 0.02 * step
    assert res.fitness == pytest.approx(fit(res.x[None])[0], rel=1e-15)
    assert res.fitness <= fit(best[None])[0] + 1e-12
    assert 0.2 <= res.alpha <= 0.9 and 0.1 <= res.gamma <= 0.8
    assert res.bat_runs == 4 * (3 + 1)              # one bat run per evaluated particle
    assert np.all((res.pso.population >= [0.2, 0.1]) & (res.pso.population <= [0.9, 0.8]))
    again = pso_ba(fit, p - step, p + step, seed=7, particles=4, pso_iterations=3, bats=12,
                   bat_iterations=12, alpha_bounds=(0.2, 0.9), gamma_bounds=(0.1, 0.8))
    assert np.array_equal(again.x, res.x) and again.alpha == res.alpha
    with pytest.raises(HybridnavError, match=r"alpha_bounds: expected 0 < lo < hi <= 1, got "
                                             r"\(0.5, 1.5\)"):
        pso_ba(fit, p - 1, p + 1, alpha_bounds=(0.5, 1.5))


# ---- runs --------------------------------------------------------------------------------------

def _obstacle_clearance(world: World, r) -> float:
    """Footprint clearance to the obstacles along a trajectory, obstacles at the same times."""
    return float(np.min(world.clearance(r.states[:, :2], t=r.t)))


def test_pso_ba_dynamic_robot2_reaches_robot1_without_collisions():
    s = load_scenario("pso-ba-dynamic")
    planner = PSOBAPlanner()
    res = planner.run(s, seed=0)
    out = {r.name: r for r in res.robots}
    assert out["robot1"].outcome == "reached" and out["robot2"].outcome == "reached"
    assert min(r.min_clearance for r in res.robots) > 0
    for r in res.robots:
        rad = s.robot(r.name).radius
        assert _obstacle_clearance(s.world, r) > rad           # moving circles at the same t
        assert r.metrics["path_points"] > 0 and r.metrics["pso_ba_runs"] > 0
        assert r.metrics["planning_time"] > 0
    # planning happens inside the loop whose wall time compute_time shares equally among the
    # active robots: the robots' planning together fits in it (one robot's need not fit its share)
    assert sum(r.metrics["planning_time"] for r in res.robots) <= sum(
        r.compute_time for r in res.robots)
    # robot2 ends within its goal radius of robot1's position at that time
    r1, r2 = out["robot1"], out["robot2"]
    k = np.searchsorted(r1.t, r2.t[-1])
    at = r1.states[min(k, len(r1.t) - 1), :2]
    assert np.hypot(*(r2.states[-1, :2] - at)) <= s.robot("robot2").goal_radius
    # the followed robot was a moving target: robot2 finished after robot1 left its start
    assert r2.time_to_goal > r1.t[1]
    files = planner.diagnostics(s, res)
    assert isinstance(files["pso_ba.png"], Figure)
    table = res.extras["path_points_robot2"]
    assert list(table) == ["t", "x", "y", "mode", "fitness", "alpha", "gamma"]
    assert len(table["t"]) == r2.metrics["path_points"]


def test_a_static_scenario_is_reached_by_the_differential_drive():
    s = load_scenario("rfd-pso-700")
    r = PSOBAPlanner().run(s, seed=0).robots[0]
    assert r.outcome == "reached"
    assert r.min_clearance > 0
    assert r.path_length > math.dist(s.robots[0].start, s.robots[0].goal)
    assert r.metrics["wall_episodes"] >= 1 and r.metrics["ls_repairs"] >= 1


def test_a_moving_obstacle_crossing_the_straight_line_is_avoided():
    mc = {"type": "moving_circle", "center": [10.0, 1.0], "radius": 1.0, "velocity": 0.5,
          "heading": math.pi / 2}
    s = _scenario([mc], [_robot((2.0, 10.0), (18.0, 10.0), radius=0.5)], max_time=120.0)
    # driving straight at the planner's speed (1 radius per second) would collide
    t = np.arange(0.0, 40.0, 0.1)
    straight = np.c_[np.minimum(2.0 + 0.5 * t, 18.0), np.full_like(t, 10.0)]
    assert np.min(s.world.clearance(straight, t=t)) < 0.5
    r = PSOBAPlanner().run(s, seed=0).robots[0]
    assert r.outcome == "reached" and r.min_clearance > 0
    assert _obstacle_clearance(s.world, r) > 0.5
    assert r.metrics["wall_episodes"] >= 1


def test_robots_avoid_each_other_head_on():
    # two robots swapping places on (almost) the same line: driving straight they would collide
    robots = [{"name": "a", "model": "point_mass", "start": [2.0, 10.0], "goal": [18.0, 10.0],
               "radius": 0.5, "goal_radius": 0.3},
              {"name": "b", "model": "point_mass", "start": [18.0, 10.2], "goal": [2.0, 10.2],
               "radius": 0.5, "goal_radius": 0.3}]
    res = PSOBAPlanner().run(_scenario([], robots), seed=0)
    assert [r.outcome for r in res.robots] == ["reached", "reached"]
    assert min(r.min_clearance for r in res.robots) > 0
    a, b = res.robots
    k = min(len(a.t), len(b.t))
    gap = np.hypot(*(a.states[:k, :2] - b.states[:k, :2]).T) - 1.0
    assert gap.min() == pytest.approx(min(a.min_clearance, b.min_clearance), abs=1e-9)
    assert sum(r.metrics["wall_episodes"] for r in res.robots) >= 1


@pytest.mark.slow
def test_memory_of_visited_points_gets_out_of_a_u_trap():
    s = _scenario(U_TRAP, [_robot((9.0, 10.0), (18.0, 10.0))], max_time=150.0)
    r = PSOBAPlanner().run(s, seed=0).robots[0]
    assert r.outcome == "reached" and r.min_clearance > 0
    assert r.metrics["memory_refusals"] > 0
    # without the memory the robot leaves towards the goal straight back into the trap
    r0 = PSOBAPlanner(memory=0.0).run(s, seed=0).robots[0]
    assert r0.outcome != "reached" and r0.metrics["memory_refusals"] == 0
    assert r0.metrics["wall_episodes"] > r.metrics["wall_episodes"]


def test_room_boundary_makes_wall_following_change_direction():
    # a wall from just above the floor: the way below it is too narrow; the nearest free gap
    # is downwards, so the robot first turns right, meets the room's wall and turns back
    wall = {"type": "segment", "a": [8.0, 0.5], "b": [8.0, 15.0]}
    s = _scenario([wall], [_robot((2.0, 1.0), (18.0, 1.0))])
    r = PSOBAPlanner().run(s, seed=0).robots[0]
    assert r.outcome == "reached" and r.min_clearance > 0
    assert r.metrics["direction_changes"] == 1
    assert r.states[:, 1].max() > 15.0              # round the top end of the wall


def test_an_enclosed_robot_ends_without_hanging():
    box = [{"type": "segment", "a": a, "b": b} for a, b in
           [([3, 3], [7, 3]), ([7, 3], [7, 7]), ([7, 7], [3, 7]), ([3, 7], [3, 3])]]
    s = _scenario(box, [_robot((5.0, 5.0), (15.0, 15.0))], max_time=40.0)
    r = PSOBAPlanner().run(s, seed=0).robots[0]
    assert r.outcome in ("stuck", "timeout") and r.t[-1] <= 40.0 + 1e-9
    assert r.min_clearance > 0


@pytest.mark.slow
def test_equal_seeds_reproduce_exactly():
    s = _scenario(U_TRAP, [_robot((9.0, 10.0), (18.0, 10.0), model="unicycle")], max_time=150.0)
    pl = PSOBAPlanner()                       # one instance: runs leave nothing behind
    ra, rb, rc = (pl.run(s, seed=sd) for sd in (3, 3, 4))
    a, b = ra.robots[0], rb.robots[0]
    assert a.outcome == "reached"
    assert np.array_equal(a.states, b.states)
    ta, tb, tc = (r.extras["path_points_r"] for r in (ra, rb, rc))
    assert ta.keys() == tb.keys()
    for k in ta:                                      # NaN fitness of wall points is equal
        np.testing.assert_array_equal(ta[k], tb[k])
    drop = ("planning_time",)
    assert {k: v for k, v in a.metrics.items() if k not in drop} == \
        {k: v for k, v in b.metrics.items() if k not in drop}
    # another seed tunes the bats differently
    tuned = np.column_stack([ta["alpha"], ta["gamma"]])[ta["mode"] == "goal"]
    other = np.column_stack([tc["alpha"], tc["gamma"]])[tc["mode"] == "goal"]
    assert tuned.shape != other.shape or not np.array_equal(tuned, other)


def test_bad_parameters_and_scenarios_give_exact_errors():
    with pytest.raises(HybridnavError, match=r"^planner pso-ba: ds: expected more than "
                                             r"1 \+ margin = 1.1 robot radii, got 1.05$"):
        PSOBAPlanner(ds=1.05)
    with pytest.raises(HybridnavError, match=r"^planner pso-ba: alpha_max: expected more than "
                                             r"alpha_min = 0.5, got 0.5$"):
        PSOBAPlanner(alpha_min=0.5, alpha_max=0.5)
    with pytest.raises(HybridnavError, match=r"^planner pso-ba: gamma_max: expected more than "
                                             r"gamma_min = 1.0, got 1.0$"):
        PSOBAPlanner(gamma_min=1.0)
    with pytest.raises(HybridnavError, match=r"^planner pso-ba: w1: expected a number in "
                                             r"\[0, 1\], got 1.5$"):
        PSOBAPlanner(w1="1.5")
    with pytest.raises(HybridnavError, match=r"^planner pso-ba: sensors: expected an integer, "
                                             r"got 12.5$"):
        PSOBAPlanner(sensors=12.5)
    with pytest.raises(HybridnavError, match=r"^planner pso-ba: unknown parameter 'alpha'"):
        PSOBAPlanner(alpha=0.9)
    driven = PSOBAPlanner.models              # from the registry: a new disk model joins
    assert {"point_mass", "unicycle"} <= set(driven) and "tractor_trailer" not in driven
    with pytest.raises(HybridnavError, match=re.escape(
            f"robots[0].model: planner pso-ba drives {', '.join(driven)}, got 'tractor_trailer'")):
        PSOBAPlanner().run(load_scenario("tractor-trailer-1"))
    assert PSOBAPlanner.moving_obstacles and PSOBAPlanner.moving_targets
    assert PSOBAPlanner.stochastic
