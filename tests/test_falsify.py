"""The falsification search: finds failures of a bad system, obeys the generator's rules,
replays exactly with the planner, and is reproducible from its seed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybridnav import planners
from hybridnav.tuner.falsify import bounds, falsify, world_from_vector
from hybridnav.tuner.job import load_job
from hybridnav.world.generator import WorldGenerator, solvable

JOB = """
name = "f"
[scenarios]
train = ["effc-train-1"]
"""


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    p = tmp_path_factory.mktemp("f") / "job.toml"
    p.write_text(JOB)
    return load_job(p)


def test_finds_reproducible_failures_that_replay_with_the_planner(job):
    fis = job.start_system()
    a = falsify(job.cost("train"), fis, budget=90, population=30, keep=3, seed=4)
    b = falsify(job.cost("train"), fis, budget=90, population=30, keep=3, seed=4)
    assert a.evaluations == 90 and 0 < a.valid <= 90 and a.failures >= 1
    assert [w.name for w in a.worlds] == [w.name for w in b.worlds] and a.costs == b.costs
    assert a.costs == sorted(a.costs, reverse=True)
    gen = WorldGenerator(resolution=0.05)
    for w, outcome, clear in zip(a.worlds, a.outcomes, a.clearances):
        r = w.robots[0]
        assert solvable(w, 0.05) and math.dist(r.start, r.goal) >= gen.min_distance
        assert np.all(w.world.clearance(np.array([r.start, r.goal])) >= 0.25 - 1e-9)
        ref = planners.get("effc", fis=fis, **dict(job["planner"])).run(w).robots[0]
        assert ref.outcome == outcome != "reached"
        assert ref.min_clearance == pytest.approx(clear, abs=1e-9)


def test_vectors_breaking_the_rules_are_rejected():
    gen = WorldGenerator()
    lo, hi = bounds(gen, 2)
    x = (lo + hi) / 2
    x[:4] = [1.0, 1.0, 1.2, 1.2]                         # start and goal too close
    assert world_from_vector(x, gen, "w") is None
    x[:5] = [0.5, 0.5, 4.5, 4.5, 0.0]
    x[5:] = [0.5, 0.5, 0.3, 2.5, 2.5, 0.3]               # the first circle covers the start
    w = world_from_vector(x, gen, "w")
    assert w is not None and len(w.world.obstacles) == 1
    x[5:] = [2.5, 2.5, 0.3, 2.5, 3.15, 0.3]              # a 5 cm gap between the two: dropped
    w = world_from_vector(x, gen, "w")
    assert len(w.world.obstacles) == 1


def test_apf_is_searched_like_a_fuzzy_system_and_its_finds_replay_with_the_apf_planner(job):
    from hybridnav.tuner.falsify import falsify_systems, rates
    from hybridnav.tuner.heldout import baseline

    cost = job.cost("train")
    got = falsify_systems(cost, {"start": job.start_system(), "apf": "apf"}, budget=90,
                          population=30, keep=3, seed=4)
    assert list(got) == ["start", "apf"]
    again = falsify(cost, "apf", budget=90, population=30, keep=3, seed=4)
    a = got["apf"]
    assert a.evaluations == 90 and 0 < a.valid and a.costs == again.costs
    for w, outcome, clear in zip(a.worlds, a.outcomes, a.clearances):
        ref = planners.get("apf", **baseline(dict(job["planner"]))).run(w).robots[0]
        assert ref.outcome == outcome != "reached"
        assert ref.min_clearance == pytest.approx(clear, abs=1e-9)
    # the start searched alone with the same seed is the same search
    assert got["start"].costs == falsify(cost, job.start_system(), budget=90, population=30,
                                         keep=3, seed=4).costs
    table = rates(got).set_index("system")
    from scipy.stats import binomtest

    for label, r in got.items():
        row = table.loc[label]
        assert (row.valid, row.failures, row.collisions) == (r.valid, r.failures, r.collisions)
        assert r.collisions <= r.failures
        ci = binomtest(r.collisions, r.valid).proportion_ci(method="wilson")
        assert (row.collisions_ci_low, row.collisions_ci_high) == pytest.approx(
            (ci.low, ci.high), abs=1e-12)


def test_an_unknown_baseline_is_refused(job):
    from hybridnav.errors import HybridnavError

    with pytest.raises(HybridnavError, match=r"falsify: system: expected a FuzzySystem or "
                                             r"'apf', got 'hapf'"):
        falsify(job.cost("train"), "hapf", budget=30)


def test_structures_in_the_search_space_are_switched_and_placed_as_the_generator_does():
    from hybridnav.errors import HybridnavError
    from hybridnav.tuner.falsify import STRUCTURES
    from hybridnav.world import Segment
    from hybridnav.world.generator import cup_parts

    gen = WorldGenerator(resolution=0.05)
    lo, hi = bounds(gen, 1, {"cups": 1, "gaps": 1})
    assert len(lo) == 5 + 3 + 5 + 5
    assert list(lo[8:13]) == [0.0, 0.35, -gen.lateral, gen.cup_width[0], gen.cup_depth[0]]
    assert list(hi[13:]) == [1.0, 0.65, gen.lateral, gen.gap_width[1], gen.gap_wall[1]]
    start, goal = np.array([0.8, 0.8]), np.array([4.2, 4.2])
    circle = [4.2, 0.8, 0.2]                               # far from the line
    cup = [1.0, 0.5, 0.0, 1.0, 0.6]
    x = np.array([*start, *goal, 0.0, *circle, *cup, 0.0, 0.5, 0.0, 0.3, 1.0])
    w = world_from_vector(x, gen, "t", {"cups": 1, "gaps": 1})
    segs = [o for o in w.world.obstacles if isinstance(o, Segment)]
    assert len(segs) == 3                                  # the cup on, the gap off
    u = (goal - start) / np.linalg.norm(goal - start)
    ref = cup_parts(start + 0.5 * (goal - start), u, 1.0, 0.6)
    assert np.allclose([[s.a, s.b] for s in segs], [[r["a"], r["b"]] for r in ref])
    x[8] = 0.0                                             # the cup off too: the circle only
    assert len(world_from_vector(x, gen, "t", {"cups": 1, "gaps": 1}).world.obstacles) == 1
    x[13] = 1.0                                            # a gap across the line, 0.3 wide
    assert len(world_from_vector(x, gen, "t", {"cups": 1, "gaps": 1}).world.obstacles) == 3
    x[8] = 1.0                                             # cup and gap at the same place:
    assert world_from_vector(x, gen, "t", {"cups": 1, "gaps": 1}) is None     # too narrow
    assert set(STRUCTURES) == {"cups", "corridors", "gaps"}
    with pytest.raises(HybridnavError, match="falsify: structures.walls: unknown"):
        bounds(gen, 1, {"walls": 1})
    with pytest.raises(HybridnavError, match=r"structures.cups: expected an integer in \[0, 10\]"):
        bounds(gen, 1, {"cups": -1})


def test_a_search_with_structures_is_reproducible_and_replays(job):
    fis = job.start_system()
    a = falsify(job.cost("train"), fis, budget=60, population=30, keep=2, seed=1,
                structures={"cups": 1})
    b = falsify(job.cost("train"), fis, budget=60, population=30, keep=2, seed=1,
                structures={"cups": 1})
    assert a.costs == b.costs and a.valid > 0
    for w, outcome in zip(a.worlds, a.outcomes):
        assert solvable(w, 0.05)
        p = planners.get("effc", fis=fis, **dict(job["planner"]))
        assert p.run(w).robots[0].outcome == outcome


def test_finds_with_segments_are_told_apart():
    from hybridnav.tuner.falsify import _same

    gen = WorldGenerator(resolution=0.05)
    x = np.array([0.8, 0.8, 4.2, 4.2, 0.0, 4.2, 0.8, 0.2, 1.0, 0.5, 0.0, 1.0, 0.6])
    a = world_from_vector(x, gen, "a", {"cups": 1})
    y = x.copy()
    y[11] = 1.3                                         # a wider cup
    b = world_from_vector(y, gen, "b", {"cups": 1})
    assert _same(a, a) and not _same(a, b)
    z = x.copy()
    z[8] = 0.0                                          # no cup at all
    assert not _same(a, world_from_vector(z, gen, "c", {"cups": 1}))


def test_search_sizes_are_checked_by_name(job):
    from hybridnav.errors import HybridnavError

    cost = job.cost("train")
    with pytest.raises(HybridnavError, match=r"falsify: budget: expected at least the population "
                                             r"\(30 worlds"):
        falsify(cost, "apf", budget=10, population=30)
    with pytest.raises(HybridnavError, match="falsify: keep"):
        falsify(cost, "apf", budget=30, keep=-1)
    r = falsify(cost, "apf", budget=30, population=30, keep=0, seed=1)
    assert r.worlds == [] and r.evaluations == 30
