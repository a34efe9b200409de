"""The world generator: seeded, solvable (checked against networkx), TOML round trip, errors."""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import pytest

from hybridnav import HybridnavError
from hybridnav.world import (
    Circle,
    Rectangle,
    Segment,
    World,
    load_scenario,
    save_scenario,
)
from hybridnav.world.grid import rasterize
from hybridnav.worldgen import WorldGenerator, generator_from_table, solvable


def test_worlds_are_seeded_and_independent_of_the_count():
    gen = WorldGenerator()
    a = gen.generate(5, seed=11)
    b = gen.generate(3, seed=11)
    assert a[:3] == b                                  # world i depends on (seed, i) only
    c = gen.generate(3, seed=12)
    assert all(x != y for x in a for y in c)           # another seed: other worlds
    assert len({w.name for w in a + c}) == 8


def test_defaults_are_effc_scale():
    worlds = WorldGenerator().generate(40, seed=5)
    for w in worlds:
        assert w.world.workspace == (0.0, 5.0, 0.0, 5.0)
        (r,) = w.robots
        assert r.model == "unicycle" and r.radius == 0.1 and r.goal_radius == 0.1
        assert 1 <= len(w.world.obstacles) <= 6
        assert all(isinstance(o, Circle) and 0.15 <= o.radius <= 0.45
                   for o in w.world.obstacles)
        # start and goal near opposite corners of a diagonal, heading within 0.5 rad of the goal
        assert math.dist(r.start, r.goal) > 3.0
        to_goal = math.atan2(r.goal[1] - r.start[1], r.goal[0] - r.start[0])
        d = math.remainder(r.initial["theta"] - to_goal, 2 * math.pi)
        assert abs(d) <= 0.5 + 1e-12
        # footprints clear of obstacles by the margin
        assert np.all(w.world.clearance(np.array([r.start, r.goal])) >= 0.1 + 0.15 - 1e-9)
    counts = [len(w.world.obstacles) for w in worlds]
    assert min(counts) == 1 and max(counts) == 6


def _networkx_path_exists(scenario, res):
    grid = rasterize(scenario.world, res, inflate=scenario.robots[0].radius, border=True)
    g = grid.to_networkx(diagonal=True, corner_cutting=False)
    r = scenario.robots[0]
    a, b = (tuple(int(v) for v in grid.to_cell(np.array(p))[0]) for p in (r.start, r.goal))
    if a not in g or b not in g:
        return False
    return nx.has_path(g, a, b)


def test_every_world_is_solvable_by_an_independent_search():
    gen = WorldGenerator(circles=(4, 9), radius=(0.3, 0.6), segments=(0, 2),
                         rectangles=(0, 2), resolution=0.05)
    worlds = gen.generate(12, seed=3)
    kinds = {type(o) for w in worlds for o in w.world.obstacles}
    assert kinds == {Circle, Segment, Rectangle}
    for w in worlds:
        assert _networkx_path_exists(w, 0.05)


def test_solvable_rejects_a_walled_off_goal():
    s = WorldGenerator().world(0, seed=1)
    r = s.robots[0]
    gx, gy = r.goal                                  # four walls boxing the goal in
    blocked = World(s.world.workspace, (*s.world.obstacles,
                                        Rectangle((gx - 0.6, gy - 0.6),
                                                  (gx + 0.6, gy - 0.45)),
                                        Rectangle((gx - 0.6, gy + 0.45),
                                                  (gx + 0.6, gy + 0.6)),
                                        Rectangle((gx - 0.6, gy - 0.6),
                                                  (gx - 0.45, gy + 0.6)),
                                        Rectangle((gx + 0.45, gy - 0.6),
                                                  (gx + 0.6, gy + 0.6))))
    from dataclasses import replace

    boxed = replace(s, world=blocked)
    assert solvable(s, 0.025) and not solvable(boxed, 0.025)
    assert not _networkx_path_exists(boxed, 0.025)


def test_random_layout_and_heading():
    gen = WorldGenerator(layout="random", heading="random", min_distance=3.0)
    worlds = gen.generate(20, seed=2)
    for w in worlds:
        r = w.robots[0]
        assert math.dist(r.start, r.goal) >= 3.0
    headings = [w.robots[0].initial["theta"] for w in worlds]
    assert max(headings) - min(headings) > math.pi      # spread over the circle


def test_written_scenarios_load_back_equal(tmp_path):
    for w in WorldGenerator(segments=(1, 1), rectangles=(1, 1)).generate(3, seed=4):
        p = save_scenario(w, tmp_path / f"{w.name}.toml")
        assert load_scenario(p) == w


def test_generate_command_writes_toml_files(tmp_path):
    from hybridnav.cli import main

    assert main(["generate", "--count", "3", "--seed", "9", "--out", str(tmp_path / "w"),
                 "--set", "circles=[2, 3]", "--set", "layout=random"]) == 0
    files = sorted((tmp_path / "w").glob("*.toml"))
    assert [f.name for f in files] == ["gen-9-000.toml", "gen-9-001.toml", "gen-9-002.toml"]
    ref = WorldGenerator(circles=(2, 3), layout="random").generate(3, seed=9)
    assert [load_scenario(f) for f in files] == ref
    assert main(["generate", "--count", "2", "--out", str(tmp_path / "x"),
                 "--set", "circles=[3, 1]"]) == 2


@pytest.mark.parametrize("table, key, text", [
    ({"generate": 3, "radius": [0.5, 0.1]}, "w.radius", "low <= high"),
    ({"generate": 3, "radius": [0.0, 0.1]}, "w.radius[0]", "expected a number in [1e-06, inf), got 0.0"),
    ({"generate": 3, "circles": [1, 2, 3]}, "w.circles", "expected [low, high]"),
    ({"generate": 3, "circles": [1.5, 2]}, "w.circles[0]", "expected an integer, got 1.5"),
    ({"generate": 3, "clutter": 2.0}, "w.clutter", "expected a number in [0, 1], got 2.0"),
    ({"generate": 3, "heading": "north"}, "w.heading", "expected one of goal, random"),
    ({"generate": 3, "resolution": 1e-5}, "w.resolution", "at most 2000 cells"),
    ({"generate": 3, "dt": 1e-6, "max_time": 100.0}, "w.max_time", "at most 1e6 steps"),
    ({"generate": 3, "name": "a/b"}, "w.name", "without slashes"),
    ({"generate": 3, "size": 1.0, "robot_radius": 0.3}, "w.robot_radius", "quarter"),
    ({"generate": 3, "colour": 1}, "w.colour", "unknown key"),
    ({"generate": -1}, "w.generate", "expected an integer in [1, 10000], got -1"),
    ({"seed": 1}, "w.generate", "missing"),
    ([1, 2], "w", "expected a table"),
])
def test_bad_settings_name_the_key(table, key, text):
    with pytest.raises(HybridnavError) as info:
        generator_from_table(table, "job.toml: ", "w")
    msg = str(info.value)
    assert msg.startswith(f"job.toml: {key}: ") and text in msg


def test_impossible_settings_fail_cleanly():
    gen = WorldGenerator(circles=(40, 40), radius=(0.9, 1.0), min_gap=0.0, max_tries=2)
    with pytest.raises(HybridnavError, match="no solvable world in 2 draws for gen-0-000"):
        gen.world(0, seed=0)


def test_no_gap_narrower_than_min_gap():
    from hybridnav.worldgen import _outline

    gen = WorldGenerator(circles=(6, 10), radius=(0.2, 0.5), rectangles=(0, 2), min_gap=0.3)
    for w in gen.generate(10, seed=6):
        obs = w.world.obstacles
        for i, a in enumerate(obs):
            pts = _outline(a, 400)
            border = np.min(np.minimum.reduce([pts[:, 0], 5 - pts[:, 0], pts[:, 1],
                                               5 - pts[:, 1]]))
            assert not 0.001 < border < 0.3 - 0.001
            for b in obs[i + 1:]:          # solid to solid: overlapping shapes give d < 0
                d = min(float(np.min(World((-9, 9, -9, 9), (b,)).clearance(pts))),
                        float(np.min(World((-9, 9, -9, 9), (a,)).clearance(_outline(b, 400)))))
                assert not 0.001 < d < 0.3 - 0.001, (a, b, d)
