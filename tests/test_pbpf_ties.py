"""PBPF ranks near-tied members as the NumPy loop does (reproducers from a review).

PBPF's fitness is the path length, and the bacterial GA compares members by it (``argmin`` over
each bacterium's clones, ``argsort`` for the gene transfer). Members whose runs reach the goal
along nearly the same path (a world without obstacles, or one far from the path) differ by a few
ulps: when the compiled cycle summed ``sqrt(dx^2 + dy^2)`` and the NumPy loop ``hypot(dx, dy)``,
the rounding reordered them and the two searches kept other gains. The compiled APF cycle now
sums ``hypot`` as NumPy does.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from hybridnav import planners
from hybridnav.world import load_scenario

SCENARIO = """\
name = "{name}"
description = "review-40 reproducer: one point-mass robot, start and goal in a generic direction"
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


def _scenario(tmp_path, name, extra=""):
    path = tmp_path / f"{name}.toml"
    path.write_text(SCENARIO.format(name=name, extra=extra))
    return load_scenario(str(path))


@pytest.fixture
def compiled():
    from hybridnav.native import lockstep as native_lockstep

    if not native_lockstep.available():
        pytest.skip("no compiler: the NumPy loop is the only one")


def _tuned(s, seed, monkeypatch, native, **params):
    monkeypatch.setenv("HYBRIDNAV_NATIVE", "1" if native else "0")
    p = planners.get("pbpf", **params)
    run = copy.copy(p)
    run.values = p.scaled_values(s)
    return run.prepare(s, np.random.default_rng(seed))


def test_pbpf_fitness_lengths_are_the_numpy_loops_to_the_bit(tmp_path, compiled):
    """The fitness the GA ranks: the compiled lengths must order the members as NumPy's do; on
    this world they differ in the last bits and the best member is another one."""
    from hybridnav.planners.field.worldstack import WorldStack

    s = _scenario(tmp_path, "free-pm")
    p = copy.copy(planners.get("pbpf"))
    p.values = p.scaled_values(s)
    r = s.robots[0]
    single = dataclasses.replace(s, robots=[r])
    rng = np.random.default_rng(7)
    base = np.log([p.values[g] for g in ("xi", "eta", "rho0")])
    gains = np.exp(base + np.log(10.0) * rng.uniform(-1, 1, (20, 3)))
    stack = WorldStack([single.world])
    radius, overrides = single.model(r).radius, p.model_overrides(r)
    got = p._compiled(single, gains, radius, overrides, stack)
    want = p._numpy(single, gains, radius, overrides, stack)
    assert (want.outcome == "reached").all()
    assert np.argmin(got.path_length[0]) == np.argmin(want.path_length[0])
    np.testing.assert_array_equal(got.path_length, want.path_length)


def test_pbpf_tunes_the_same_gains_in_a_world_without_obstacles(tmp_path, monkeypatch, compiled):
    s = _scenario(tmp_path, "free-pm")
    fast = _tuned(s, 0, monkeypatch, True, population=4, generations=1)
    slow = _tuned(s, 0, monkeypatch, False, population=4, generations=1)
    np.testing.assert_array_equal(fast.gains, slow.gains)


def test_pbpf_runs_the_same_with_a_far_obstacle(tmp_path, monkeypatch, compiled):
    """One circle away from the straight path: the two searches keep different gains (xi 1.88
    vs 3.28 on c263cd6) and the runs differ by more than rounding."""
    s = _scenario(tmp_path, "one-circle-pm", FAR_CIRCLE)
    fast = _tuned(s, 0, monkeypatch, True, population=4, generations=2)
    slow = _tuned(s, 0, monkeypatch, False, population=4, generations=2)
    np.testing.assert_array_equal(fast.gains, slow.gains)
    monkeypatch.setenv("HYBRIDNAV_NATIVE", "1")
    a = planners.get("pbpf", population=4, generations=2).run(s, seed=0)
    monkeypatch.setenv("HYBRIDNAV_NATIVE", "0")
    b = planners.get("pbpf", population=4, generations=2).run(s, seed=0)
    np.testing.assert_array_equal(a.robots[0].states, b.robots[0].states)
