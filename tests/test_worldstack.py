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
    from hybridnav.world.generator import WorldGenerator

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


@pytest.mark.parametrize("per_side", [1, 4, 32])
def test_cell_candidates_hold_every_nearest_obstacle(per_side):
    """``WorldStack.cells``: the obstacle nearest to any point of a cell (ties included) is one
    of the cell's candidates, so a search of the candidates alone answers as the full search."""
    worlds = [w for w in _worlds() if not any(o.__class__ is MovingCircle for o in w.obstacles)]
    stack = WorldStack(worlds)
    geo, off, col = stack.cells(per_side)
    rng = np.random.default_rng(1)
    n = 20000
    env = rng.integers(0, len(worlds), n)
    ws = stack.ws[env]                                     # the workspace widened by half
    u = rng.uniform(-0.5, 1.5, (n, 2))
    P = np.stack([ws[:, 0] + u[:, 0] * (ws[:, 1] - ws[:, 0]),
                  ws[:, 2] + u[:, 1] * (ws[:, 3] - ws[:, 2])], axis=1)
    P[:3] = [[2.5, 2.25], [1.0, 1.5], [1.5, 1.5]]          # ties and surface points
    env[:3] = [0, 0, 1]
    _, D, *_ = stack._distances(P, env, 0.0, False)
    kof = stack.column_obstacle()
    fx = (P[:, 0] - geo[env, 0]) * geo[env, 2]
    fy = (P[:, 1] - geo[env, 1]) * geo[env, 3]
    inside = (fx >= 0) & (fx < per_side) & (fy >= 0) & (fy < per_side)
    assert inside.sum() > n // 2 and (~inside).sum() > 100       # both routes are exercised
    checked = 0
    for i in np.flatnonzero(inside & stack.has_obstacles[env]):
        cell = (env[i] * per_side + int(fy[i])) * per_side + int(fx[i])
        cand = set(col[off[cell]:off[cell + 1]].tolist())
        d = D[i, :stack.C + stack.G]
        best = np.flatnonzero(d == d.min())
        assert set(best.tolist()) <= cand
        checked += 1
        # the first minimum in obstacle order is found among the candidates alone
        cd = sorted(cand, key=lambda c: (d[c], kof[env[i], c]))
        full = min(range(stack.C + stack.G), key=lambda c: (d[c], kof[env[i], c]))
        assert cd[0] == full
    assert checked > 1000


def test_no_cells_with_moving_obstacles():
    stack = WorldStack(_worlds())
    assert stack.moving and stack.cells(8) is None
