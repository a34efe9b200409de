"""The falsification search: finds failures of a bad system, obeys the generator's rules,
replays exactly with the planner, and is reproducible from its seed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybridnav import planners
from hybridnav.tuner.falsify import bounds, falsify, world_from_vector
from hybridnav.tuner.job import load_job
from hybridnav.worldgen import WorldGenerator, solvable

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
        ref = planners.get("effc", fis=fis).run(w).robots[0]
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

    cost = job.cost("train")
    got = falsify_systems(cost, {"start": job.start_system(), "apf": "apf"}, budget=90,
                          population=30, keep=3, seed=4)
    assert list(got) == ["start", "apf"]
    again = falsify(cost, "apf", budget=90, population=30, keep=3, seed=4)
    a = got["apf"]
    assert a.evaluations == 90 and 0 < a.valid and a.costs == again.costs
    for w, outcome, clear in zip(a.worlds, a.outcomes, a.clearances):
        ref = planners.get("apf", **dict(job["planner"])).run(w).robots[0]
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
