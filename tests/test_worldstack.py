"""WorldStack answers exactly what each point's own World answers (bit for bit)."""

from __future__ import annotations

import numpy as np
import pytest

from hybridnav.planners.field.worldstack import WorldStack
from hybridnav.world import Circle, MovingCircle, Polygon, Rectangle, Segment, World


def _worlds():
    return [
        World((0, 5, 0, 5), (Circle((1, 1), 0.5), Rectangle((2, 2), (3, 2.5)),
                             Circle((2.5, 2.25), 0.3))),            # a circle overlapping a box
        World((-1, 4, -1, 4), (Segment((0, 0), (3, 3)), Polygon(((1, 2), (2, 2), (1.5, 3))))),
        World((0, 5, 0, 5), ()),                                       # no obstacles
        World((0, 10, 0, 8), (MovingCircle((2, 2), 0.4, 0.3, 0.5), Circle((6, 6), 1.0),
                              Rectangle((7, 1), (9, 2)), Segment((4, 0), (4, 3)))),
        World((0, 5, 0, 5), (Circle((2, 2), 0.2),)),
    ]


@pytest.mark.parametrize("t", [0.0, 3.7])
def test_stack_equals_each_world(t):
    worlds = _worlds()
    stack = WorldStack(worlds)
    rng = np.random.default_rng(0)
    n = 4000
    env = rng.integers(0, len(worlds), n)
    P = rng.uniform(-1.5, 10.5, (n, 2))
    # include exact ties: points equidistant from two obstacles and points on surfaces
    P[:3] = [[2.5, 2.25], [1.0, 1.5], [1.5, 1.5]]
    env[:3] = [0, 0, 1]
    clear, near = stack.nearest(P, env, t)
    cl = stack.clearance(P, env, t)
    bc = stack.border_clearance(P, env)
    for e, w in enumerate(worlds):
        sel = env == e
        ref_c = w.clearance(P[sel], t=t)
        assert np.array_equal(cl[sel], ref_c)
        assert np.array_equal(bc[sel], w.border_clearance(P[sel]))
        if w.obstacles:
            c, q, _ = w.nearest(P[sel], t=t)
            assert np.array_equal(clear[sel], c) and np.array_equal(near[sel], q)
        else:
            assert np.all(np.isinf(clear[sel])) and np.all(np.isnan(near[sel]))


def test_lockstep_with_a_stack_equals_the_planner_runs():
    from hybridnav import fuzzy, planners
    from hybridnav.fuzzy.family import SystemFamily
    from hybridnav.planners.field.effc import effc_force, effc_inputs_from
    from hybridnav.planners.field.lockstep import lockstep_field
    from hybridnav.world import load_scenario
    from hybridnav.worldgen import WorldGenerator

    scen = [load_scenario("effc-env-a"), load_scenario("effc-env-b")] + \
        WorldGenerator(segments=(1, 2), rectangles=(0, 1)).generate(3, seed=8)
    fis = fuzzy.builtin("effc-5rule")
    fam = SystemFamily(fis)
    tables = fam.tables_of([fis])
    stack = WorldStack([s.world for s in scen])
    radius = np.array([s.robots[0].radius for s in scen])

    def field(env, members, P, goals, t):
        clear, near = stack.nearest(P, env, t)
        d, a, fa, fr = effc_inputs_from(P, goals, clear, near, radius[env])
        return effc_force(fam.evaluate(tables, members, {"dtheta": d, "alpha": a}), fa, fr)

    res = lockstep_field(scen, 1, field, model_overrides={"controller": "heading",
                                                          "speed": 0.1,
                                                          "max_turn": np.pi / 4},
                         stack=stack)
    for e, s in enumerate(scen):
        r = planners.get("effc", fis=fis).run(s).robots[0]
        assert res.outcome[e, 0] == r.outcome
        assert res.path_length[e, 0] == pytest.approx(r.path_length, rel=1e-12)
        assert res.min_clearance[e, 0] == pytest.approx(r.min_clearance, rel=1e-12)
