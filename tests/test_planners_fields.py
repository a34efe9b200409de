"""Potential-field planners, the shared simulation loop and lockstep batches."""

from __future__ import annotations

import copy
import dataclasses
import json
import math

import numpy as np
import pytest

from hybridnav import HybridnavError, planners
from hybridnav.planners.field.apf import apf_force
from hybridnav.planners.field.hapf import harmonic_field
from hybridnav.planners.field.lockstep import lockstep_field
from hybridnav.planners.simulate import simulate
from hybridnav.world import Circle, World, load_scenario, scenario_from_dict
from hybridnav.world.grid import build_grid


def small_scenario(obstacles=(), start=(0.0, 0.0), goal=(3.0, 0.0), model="point_mass",
                   max_time=200.0, extra=None):
    robot = {"name": "R", "model": model, "start": list(start), "goal": list(goal),
             "goal_radius": 0.1, "radius": 0.1, **(extra or {})}
    return scenario_from_dict({
        "name": "t", "dt": 0.1, "max_time": max_time, "units": "m",
        "workspace": {"xmin": -1.0, "xmax": 4.0, "ymin": -2.0, "ymax": 2.0},
        "obstacles": list(obstacles), "robots": [robot]})


def test_apf_force_is_minus_the_gradient_of_the_potential():
    world = World((-5, 5, -5, 5), (Circle((1.0, 0.5), 0.4), Circle((-1.0, -1.0), 0.3)))
    g = dict(xi=1.3, sigma0=1.0, eta=0.07, rho0=0.8)
    goal = np.array([2.0, 1.0])

    def potential(p):
        d = np.linalg.norm(p - goal)
        u = 0.5 * g["xi"] * d**2 if d <= g["sigma0"] else g["xi"] * (d * g["sigma0"]
                                                                     - 0.5 * g["sigma0"]**2)
        for ob in world.obstacles:
            rho = ob.clearance(p[None])[0] - 0.1
            if rho <= g["rho0"]:
                u += 0.5 * g["eta"] * (1 / rho - 1 / g["rho0"]) ** 2
        return u

    rng = np.random.default_rng(1)
    P = rng.uniform(-2, 3, (40, 2))
    P = P[world.clearance(P) > 0.3]
    F = apf_force(world, P, np.tile(goal, (len(P), 1)), 0.1, 0.0, **g)
    h = 1e-6
    for p, f in zip(P, F):
        grad = [(potential(p + h * e) - potential(p - h * e)) / (2 * h) for e in np.eye(2)]
        np.testing.assert_allclose(f, -np.array(grad), rtol=1e-5, atol=1e-6)


def test_apf_goes_straight_without_obstacles_and_stalls_in_a_trap():
    free = small_scenario()
    res = planners.get("apf").run(free)
    r = res.robots[0]
    assert r.outcome == "reached" and r.time_to_goal is not None
    assert r.path_length == pytest.approx(3.0 - 0.1, abs=0.011)   # a straight line to the disk
    trap = load_scenario("effc-env-a")
    r = planners.get("apf").run(trap).robots[0]
    assert r.outcome == "stuck" and r.time_to_goal is None
    assert math.dist(r.states[-1, :2], trap.robots[0].goal) > 0.5


def test_harmonic_field_has_no_local_minimum_and_obeys_the_maximum_principle():
    s = load_scenario("effc-env-a")
    grid = build_grid(s, inflate=s.robots[0].radius)
    centers = grid.to_world(np.argwhere(np.ones(grid.shape, bool))[:, ::-1]).reshape(
        grid.shape + (2,))
    goal = np.hypot(*(centers - np.asarray(s.robots[0].goal)).transpose(2, 0, 1)) <= 0.1
    phi = harmonic_field(grid, goal & ~grid.occ)
    free = ~grid.occ & ~goal
    assert phi[free].min() > 0 and phi[free].max() < 1
    # every free cell has a 4-neighbour with a strictly smaller value: no local minimum
    padded = np.pad(phi, 1, constant_values=1.0)
    neigh = np.minimum.reduce([padded[2:, 1:-1], padded[:-2, 1:-1], padded[1:-1, 2:],
                               padded[1:-1, :-2]])
    reachable = free & (phi < 1 - 1e-12)
    assert np.all(neigh[reachable] < phi[reachable])
    # and it is the mean of its neighbours (the discrete Laplace equation)
    mean = (padded[2:, 1:-1] + padded[:-2, 1:-1] + padded[1:-1, 2:] + padded[1:-1, :-2]) / 4
    assert np.abs(mean[free] - phi[free]).max() < 1e-10


def test_hapf_escapes_the_trap_that_stops_apf():
    r = planners.get("hapf").run(load_scenario("effc-env-a")).robots[0]
    assert r.outcome == "reached" and r.min_clearance > 0


def test_pbpf_is_reproducible_and_improves_on_its_starting_gains():
    s = load_scenario("effc-env-b")
    a = planners.get("pbpf", population=4, generations=2).run(s, seed=7)
    b = planners.get("pbpf", population=4, generations=2).run(s, seed=7)
    assert a.to_dict()["robots"][0]["path_length"] == b.to_dict()["robots"][0]["path_length"]
    p = planners.get("pbpf", population=4, generations=2)
    res = p.run(s, seed=7)
    log = list(res.extras[f"swarm_best_{res.robots[0].name}"]["best"])
    assert all(x >= y for x, y in zip(log, log[1:]))          # elitist: never worse
    assert res.robots[0].outcome == "reached"
    default = planners.get("apf").run(s).robots[0]
    assert default.outcome != "reached" or res.robots[0].path_length <= default.path_length


def _pbpf_population(s, seed, n, **params):
    """PBPF's fitness runs of ``n`` random gain rows on ``s``'s first robot, compiled and in
    NumPy (``(compiled, numpy)`` lockstep results)."""
    from hybridnav.native import lockstep as native_lockstep
    from hybridnav.planners.field.worldstack import WorldStack

    if not native_lockstep.available():
        pytest.skip("no compiler: the NumPy loop is the only one")
    p = copy.copy(planners.get("pbpf", **params))
    p.values = p.scaled_values(s)               # as a run does: speed and gains at its scale
    r = s.robots[0]
    single = dataclasses.replace(s, robots=[r])
    rng = np.random.default_rng(seed)
    base = np.log([p.values[g] for g in ("xi", "eta", "rho0")])
    gains = np.exp(base + np.log(10.0) * rng.uniform(-1, 1, (n, 3)))
    stack = WorldStack([single.world])
    radius, overrides = single.model(r).radius, p.model_overrides(r)
    got = p._compiled(single, gains, radius, overrides, stack)
    assert got is not None
    return got, p._numpy(single, gains, radius, overrides, stack)


def _assert_same_runs(got, want):
    for key in ("outcome", "path_length", "time", "min_clearance", "final_distance",
                "final_states"):
        np.testing.assert_array_equal(getattr(got, key), getattr(want, key), err_msg=key)


@pytest.mark.parametrize("name, margin", [("effc-train-2", 0.0), ("effc-env-a", 0.0),
                                          ("effc-env-a", 0.05), ("effc-env-b", 0.0),
                                          ("pso-ba-dynamic", 0.0), ("pso-ba-dynamic", 0.05),
                                          ("turtlebot-office", 0.0)])
def test_pbpf_population_runs_compiled_as_in_numpy(name, margin):
    """PBPF's fitness: each member's own gains in the compiled APF cycle give the NumPy
    lockstep's runs to the bit (outcomes, lengths, times, clearances and final states)."""
    got, want = _pbpf_population(load_scenario(name), 1, 24, safety_margin=margin)
    assert len(np.unique(want.path_length)) > 12          # the gains matter
    _assert_same_runs(got, want)


# PBPF ranks its members by path length (argmin over each bacterium's clones, argsort for the
# gene transfer). Members that reach the goal along nearly the same path (no obstacle near it)
# differ by a few ulps: when the compiled cycle summed sqrt(dx^2 + dy^2) and NumPy hypot(dx, dy),
# the rounding reordered them and the two searches kept other gains (a review's reproducers).
TIE_WORLD = """\
name = "{name}"
description = "one point-mass robot, start and goal in a generic direction"
units = "m"
dt = 0.1
max_time = 600.0

[workspace]
xmin = 0.0
xmax = 50.0
ymin = 0.0
ymax = 50.0

[[robots]]
name = "robot"
model = "point_mass"
start = [27.824435307310257, 28.60345208660854]
goal = [10.929969552976505, 26.197023436422256]
goal_radius = 0.5
radius = 0.5
{extra}"""

FAR_CIRCLE = """
[[obstacles]]
type = "circle"
center = [20.0, 40.0]
radius = 3.0
"""


def _tie_world(tmp_path, name, extra=""):
    path = tmp_path / f"{name}.toml"
    path.write_text(TIE_WORLD.format(name=name, extra=extra))
    return load_scenario(str(path))


def _tuned_gains(s, seed, monkeypatch, native, **params):
    monkeypatch.setenv("HYBRIDNAV_NATIVE", "1" if native else "0")
    run = copy.copy(planners.get("pbpf", **params))
    run.values = run.scaled_values(s)
    return run.prepare(s, np.random.default_rng(seed)).gains


def test_pbpf_near_tied_lengths_are_the_numpy_loops_to_the_bit(tmp_path):
    got, want = _pbpf_population(_tie_world(tmp_path, "free-pm"), 7, 20)
    assert (want.outcome == "reached").all()
    assert np.argmin(got.path_length[0]) == np.argmin(want.path_length[0])
    _assert_same_runs(got, want)


@pytest.mark.parametrize("extra, generations", [("", 1), (FAR_CIRCLE, 2)],
                         ids=["no-obstacle", "far-circle"])
def test_pbpf_tunes_the_same_gains_among_near_ties(tmp_path, monkeypatch, extra, generations):
    s = _tie_world(tmp_path, "tie", extra)
    fast = _tuned_gains(s, 0, monkeypatch, True, population=4, generations=generations)
    slow = _tuned_gains(s, 0, monkeypatch, False, population=4, generations=generations)
    np.testing.assert_array_equal(fast, slow)


def test_pbpf_tunes_the_same_gains_with_and_without_the_compiled_cycle(monkeypatch):
    s = load_scenario("effc-env-b")
    fast = planners.get("pbpf", population=4, generations=2).run(s, seed=3)
    monkeypatch.setenv("HYBRIDNAV_NATIVE", "0")
    slow = planners.get("pbpf", population=4, generations=2).run(s, seed=3)
    np.testing.assert_array_equal(fast.robots[0].states, slow.robots[0].states)
    assert fast.robots[0].outcome == slow.robots[0].outcome
    key = f"swarm_best_{s.robots[0].name}"
    np.testing.assert_array_equal(fast.extras[key]["best"], slow.extras[key]["best"])


@pytest.mark.parametrize("name", ["effc-train-1", "effc-env-b"])
def test_pbpf_searches_what_it_runs_with_the_safety_filter(name):
    """The gain search simulates the run the planner makes: with a safety margin, the best
    fitness is the path length of the run with the tuned gains (the search used to leave the
    filter out)."""
    s = load_scenario(name)
    res = planners.get("pbpf", population=4, generations=2, safety_margin=0.05).run(s, seed=3)
    r = res.robots[0]
    best = list(res.extras[f"swarm_best_{r.name}"]["best"])[-1]
    assert r.outcome == "reached"
    assert r.path_length == pytest.approx(best, rel=1e-12)


def test_lockstep_matches_the_per_robot_simulation():
    s = load_scenario("effc-train-1")
    apf = planners.get("apf")
    one = apf.run(s).robots[0]

    def field(env, members, P, goals, t):
        return apf_force(s.world, P, goals, 0.1, t, xi=1.0, sigma0=1.0, eta=0.05, rho0=0.5)

    res = lockstep_field([s], 3, field, model_overrides=apf.model_overrides(s.robots[0]))
    assert list(res.outcome[0]) == [one.outcome] * 3
    np.testing.assert_allclose(res.path_length[0], one.path_length, rtol=1e-9)
    np.testing.assert_allclose(res.time[0], one.time_to_goal, rtol=1e-9)


def test_simulate_outcomes_collided_out_of_bounds_timeout():
    s = small_scenario([{"type": "circle", "center": [1.5, 0.0], "radius": 0.3}])
    model = s.model(s.robots[0])
    straight = lambda sim: sim.goals()                           # noqa: E731 ignores obstacles
    (r,), _ = simulate(s, [model], straight)
    assert r.outcome == "collided" and r.min_clearance < 0
    away = small_scenario(goal=(3.0, 0.0))
    (r,), _ = simulate(away, [away.model(away.robots[0])],
                       lambda sim: sim.positions + np.array([[-5.0, 0.0]]))
    assert r.outcome == "out_of_bounds"
    slow = small_scenario(max_time=1.0)
    (r,), _ = simulate(slow, [slow.model(slow.robots[0])], lambda sim: sim.goals())
    assert r.outcome == "timeout" and len(r.t) == 11 and r.time_to_goal is None
    (r,), _ = simulate(slow, [slow.model(slow.robots[0])], lambda sim: sim.positions,
                       stuck_window=0.5)
    assert r.outcome == "stuck"


def test_simulate_tells_a_robot_contact_from_an_obstacle_contact():
    """min_robot_clearance: the clearance to the other robots alone, so that a collided robot
    that touched a robot (< 0) is told from one that hit an obstacle; none with one robot."""
    def two(obstacles=(), goal_b=(0.0, 0.0), start_b=(3.0, 0.0)):
        robots = [{"name": "A", "model": "point_mass", "start": [0.0, 0.0], "goal": [3.0, 0.0],
                   "goal_radius": 0.1, "radius": 0.1},
                  {"name": "B", "model": "point_mass", "start": list(start_b),
                   "goal": list(goal_b), "goal_radius": 0.1, "radius": 0.1}]
        return scenario_from_dict({
            "name": "t2", "dt": 0.1, "max_time": 200.0, "units": "m",
            "workspace": {"xmin": -1.0, "xmax": 4.0, "ymin": -2.0, "ymax": 2.0},
            "obstacles": list(obstacles), "robots": robots})

    straight = lambda sim: sim.goals()                           # noqa: E731 ignores everything
    s = two()                                                    # head-on
    (a, b), _ = simulate(s, [s.model(r) for r in s.robots], straight)
    assert a.outcome == b.outcome == "collided"
    assert a.metrics["min_robot_clearance"] < 0 and b.metrics["min_robot_clearance"] < 0
    s = two([{"type": "circle", "center": [1.5, 0.0], "radius": 0.3}], goal_b=(3.0, 1.5),
            start_b=(0.0, 1.5))                                 # side by side, A hits the circle
    (a, b), _ = simulate(s, [s.model(r) for r in s.robots], straight, stuck_window=0)
    assert a.outcome == "collided" and a.min_clearance < 0
    assert a.metrics["min_robot_clearance"] == pytest.approx(1.3)       # 1.5 apart, radii 0.1
    assert b.outcome == "reached" and b.metrics["min_robot_clearance"] == pytest.approx(1.3)
    one = small_scenario()
    (r,), _ = simulate(one, [one.model(one.robots[0])], straight)
    assert "min_robot_clearance" not in r.metrics


def test_planner_parameters_are_validated():
    with pytest.raises(HybridnavError, match="planner apf: unknown parameter 'rh0'"):
        planners.get("apf", rh0=1.0)
    with pytest.raises(HybridnavError, match=r"planner apf: eta: expected a non-negative number"):
        planners.get("apf", eta=-1)
    with pytest.raises(HybridnavError, match="unknown planner 'apff'"):
        planners.get("apff")
    assert planners.get("apf", rho0="0.25").values["rho0"] == 0.25      # parsed from --set
    with pytest.raises(HybridnavError, match=r"robots\[1\]\.goal_follow: planner hapf does not handle"):
        planners.get("hapf").run(load_scenario("pso-ba-dynamic"))


def test_run_cli_writes_the_result_contract(tmp_path):
    from hybridnav.cli import main

    out = tmp_path / "r"
    assert main(["run", "effc-train-2", "--planner", "hapf", "--seed", "3", "--out",
                 str(out)]) == 0
    data = json.loads((out / "result.json").read_text())
    assert data["planner"] == "hapf" and data["seed"] == 3 and data["scenario"] == "effc-train-2"
    assert data["robots"][0]["outcome"] == "reached"
    header = (out / "trajectory_robot.csv").read_text().splitlines()[0]
    assert header == "t,x,y,theta"
    assert (out / "path.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["run", "effc-train-2", "--planner", "apf", "--set", "eta=x", "--out",
                 str(out)]) == 2


def test_multi_robot_runs_together_and_robots_are_obstacles_to_each_other():
    s = load_scenario("aco-three-robots")
    s = dataclasses.replace(s, max_time=20.0)
    res = planners.get("apf", speed=1.0, rho0=5.0, sigma0=10.0).run(s)
    assert [r.name for r in res.robots] == [r.name for r in s.robots]
    for r in res.robots:
        assert r.outcome in ("reached", "stuck", "timeout", "collided")
        assert r.t[-1] <= 20.0 + 1e-9


def test_apf_lockstep_is_the_planner_run_by_run():
    """The held-out tables' ``apf`` rows come from one lockstep batch: per world, what the
    ``apf`` planner does (outcome, length, time, clearance), including worlds without obstacles
    beside worlds with (the packed arrays' padding must add no force)."""
    from hybridnav.planners.field.apf import apf_lockstep
    from hybridnav.tuner.evaluate import scenario_set
    from hybridnav.world.generator import WorldGenerator

    scen = [load_scenario("effc-env-a"), load_scenario("effc-train-1")] + \
        WorldGenerator(segments=(0, 2), rectangles=(0, 2)).generate(6, seed=4)
    empty = dataclasses.replace(scen[-1], name="empty",
                                world=dataclasses.replace(scen[-1].world, obstacles=[]))
    scen.append(empty)
    params = {"speed": 0.1, "stuck_window": 10.0}
    res = apf_lockstep(scenario_set(scen), params)
    outcomes = set()
    for e, s in enumerate(scen):
        r = planners.get("apf", **params).run(s).robots[0]
        outcomes.add(r.outcome)
        assert res.outcome[e, 0] == r.outcome, s.name
        assert res.path_length[e, 0] == pytest.approx(r.path_length, rel=1e-9)
        assert res.min_clearance[e, 0] == pytest.approx(r.min_clearance, rel=1e-9)
        if r.outcome == "reached":
            assert res.time[e, 0] == pytest.approx(r.time_to_goal, rel=1e-12)
    assert {"reached", "stuck"} <= outcomes


def _scaled_scenario(name: str, k: float):
    """The scenario with every length times k (time and angles unchanged)."""
    from hybridnav.world import scenario_from_dict, scenario_to_dict

    d = scenario_to_dict(load_scenario(name))
    d["name"] = f"{name}-x{k:g}"
    d["workspace"] = {key: v * k for key, v in d["workspace"].items()}
    for o in d["obstacles"]:
        for key in ("min", "max", "center", "start", "end"):
            if key in o:
                o[key] = [v * k for v in o[key]]
        for key in ("vertices", "points"):
            if key in o:
                o[key] = [[v * k for v in p] for p in o[key]]
        if "radius" in o:
            o["radius"] *= k
    for r in d["robots"]:
        r["start"], r["goal"] = [v * k for v in r["start"]], [v * k for v in r["goal"]]
        r["radius"] *= k
        r["goal_radius"] *= k
    return scenario_from_dict(d)


@pytest.mark.parametrize("planner", ["apf", "effc", "hapf"])
def test_field_planners_defaults_follow_the_scale_of_the_scenario(planner):
    # every length x4 (exact in binary): the same run, every position x4
    ref = planners.get(planner).run(load_scenario("effc-env-a"))
    big = planners.get(planner).run(_scaled_scenario("effc-env-a", 4.0))
    a, b = ref.robots[0], big.robots[0]
    assert big.params["scale"] == 4.0 and ref.params["scale"] == 1.0
    assert big.params["speed"] == pytest.approx(4 * ref.params["speed"])
    assert a.outcome == b.outcome
    n = min(len(a.states), len(b.states))
    assert abs(len(a.states) - len(b.states)) <= 1
    assert np.allclose(b.states[:n, :2], 4 * a.states[:n, :2], atol=1e-6 * 4)
    assert b.path_length == pytest.approx(4 * a.path_length, rel=1e-6)


def test_apf_reaches_on_a_centimetre_scenario_and_set_values_are_kept():
    s = load_scenario("fastep-s1")                 # cm, robot radius 0.5: scale 5
    r = planners.get("apf").run(s)
    assert r.robots[0].outcome == "reached" and r.params["scale"] == 5.0
    assert r.params["speed"] == pytest.approx(0.5) and r.params["eta"] == pytest.approx(0.05 * 5**4)
    # the declared defaults as written (scale 1): the EFFC-scale speed stalls there
    assert planners.get("apf", scale=1).run(s).robots[0].outcome == "stuck"
    # a value the user sets is not scaled
    p = planners.get("apf", speed=1.0).run(s).params
    assert p["speed"] == 1.0 and p["rho0"] == pytest.approx(2.5)
    # the instance can run scenarios of other scales one after the other
    planner = planners.get("apf")
    assert planner.run(load_scenario("effc-env-b")).params["speed"] == 0.1
    assert planner.run(s).params["speed"] == pytest.approx(0.5)


@pytest.mark.parametrize("window_s, wander", [(0.5, 300), (1.0, 57), (2.0, 41), (0.3, 0)])
def test_simulate_stuck_test_reads_the_last_window_of_the_path(window_s, wander):
    """A robot that wanders for ``wander`` cycles (round a circle), then trembles
    in place, stops as "stuck" at the first cycle whose last ``window + 1`` positions fit in the
    stuck radius about their mean -- computed here from the recorded path itself, over histories
    many windows long (the loop keeps them in a buffer it shifts)."""
    s = small_scenario(goal=(3.5, 1.5), max_time=100.0)
    rng = np.random.default_rng(int(window_s * 10) + wander)

    def wobble(sim):
        P = sim.positions
        if sim.k < wander:
            return P + 2.0 * np.array([[np.cos(sim.k / 10), np.sin(sim.k / 10)]])
        return P + rng.normal(scale=1e-3, size=P.shape)

    radius = 0.02
    (r,), _ = simulate(s, [s.model(s.robots[0])], wobble, stuck_window=window_s,
                       stuck_radius=radius)
    window = int(round(window_s / s.dt))
    P = r.states[:, :2]
    first = None
    for j in range(window, len(P)):
        recent = P[j - window:j + 1]
        if np.max(np.hypot(*(recent - recent.mean(axis=0)).T)) < radius:
            first = j
            break
    assert first is not None and first > 2 * (window + 1) or wander == 0
    assert r.outcome == "stuck" and len(P) - 1 == first
