"""The step planners' swept-footprint check (:mod:`hybridnav.planners.step.sweep`) is the exact
piecewise test it prunes, and what it prunes with is sound: clear maps, obstacle boxes, one
world per obstacle, the footprint's extent, rollouts in chunks. Runs are the same as before the
check was pruned (values recorded from that code)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybridnav import models, planners
from hybridnav.planners.step.stepfit import Surroundings, feasible_steps
from hybridnav.world import (
    Circle,
    MovingCircle,
    Polygon,
    Rectangle,
    Segment,
    World,
    load_scenario,
    point_segment_distance,
)

NO_ROBOTS = (np.zeros((0, 2)), np.zeros(0))


def _reference(model, x0, P, env, steps, reach, margin, end_margin=None):
    """:func:`feasible_steps` by its definition, the slow way: the whole rollout; every piece
    of every footprint disk up to the first sample within reach tested against the whole world
    (moving circles frozen at the piece's start), the other robots' disks and the border (at
    the piece's end); the whole-body disk swept from there to the candidate."""
    n = len(P)
    world, moving = env.world, env.world.moving()
    static = world.static()
    oc, orad = env.robot_discs
    traj = model.rollout(np.broadcast_to(x0, (n, model.nx)), P, steps)
    within = np.hypot(traj[..., 0] - P[:, None, 0], traj[..., 1] - P[:, None, 1]) <= reach
    last = np.where(within.any(axis=1), within.argmax(axis=1), steps)
    C, radii = model.footprint(traj.reshape(-1, model.nx))
    C = C.reshape(n, steps + 1, len(radii), 2)
    k = np.broadcast_to(np.arange(steps), (n, steps))
    used = k < last[:, None]
    bad = np.zeros(n, dtype=bool)
    for j, rad in enumerate(radii):
        need = rad + margin
        A, B = C[:, :-1, j][used], C[:, 1:, j][used]
        hit = ~world.inside_workspace(B, need)
        if static.obstacles:
            hit |= static.segment_collides(A, B, radius=need)
        if moving.obstacles:
            hit |= moving.segment_collides(A, B, radius=need, t=env.t + k[used] * model.dt)
        if len(orad):
            dd, _ = point_segment_distance(oc[None], A[:, None], B[:, None])
            hit |= np.any(dd < need + orad[None], axis=1)
        rows = np.broadcast_to(np.arange(n)[:, None], used.shape)[used]
        bad[rows[hit]] = True
    end = traj[np.arange(n), last, :2]
    body = model.radius + (margin if end_margin is None else end_margin)
    seen = np.ones(n, dtype=bool)
    if world.obstacles:
        seen &= ~world.segment_collides(end, P, radius=body, t=env.t + last * model.dt)
    if len(orad):
        dd, _ = point_segment_distance(oc[None], end[:, None], P[:, None])
        seen &= ~np.any(dd < body + orad[None], axis=1)
    return ~bad & seen


def _world():
    return World((0.0, 50.0, 0.0, 50.0), (
        Circle((20.0, 20.0), 4.0), Circle((35.0, 30.0), 3.0), Circle((8.0, 40.0), 2.0),
        Segment((10.0, 35.0), (25.0, 42.0)), Rectangle((30.0, 5.0), (38.0, 12.0)),
        Polygon(((40.0, 38.0), (46.0, 40.0), (42.0, 46.0))),
        MovingCircle((5.0, 25.0), 1.5, 0.6, 0.3), MovingCircle((45.0, 20.0), 2.0, 0.4, 2.5)))


# model, its parameters, x0 (the rest 0), rollout steps, candidates, margin (CasADi's virtual
# machine: the same numbers for the check and the reference, without compiling every batch size)
CASES = [
    ("point_mass", {"dt": 0.5, "radius": 0.5, "jit": False}, [8.0, 10.0], 150, 1500, 0.3),
    ("point_mass", {"dt": 0.5, "radius": 0.5, "jit": False}, [26.0, 28.0], 37, 300, 0.0),
    ("unicycle", {"dt": 0.25, "radius": 0.4, "jit": False}, [12.0, 30.0, -0.5], 97, 300, 0.2),
    ("tractor_trailer", {"dt": 0.5, "jit": False}, [8.0, 10.0, 0.3, 0.3], 120, 400, 0.2),
    ("tractor_trailer", {"dt": 0.5, "jit": False}, [27.0, 26.0, 2.0, 1.5], 61, 1100, 0.4),
]


@pytest.mark.parametrize("name, kw, x0, steps, n, margin", CASES)
def test_feasible_steps_is_the_exact_piecewise_test(name, kw, x0, steps, n, margin):
    """Random candidates (some within reach at the start), static and moving obstacles of
    every kind, other robots, planning at t = 0 and later; batches that take the short blocks
    and the clear map (1000 and more) and those that do not."""
    m = models.get(name, **kw)
    x0 = np.array(x0 + [0.0] * (m.nx - len(x0)))
    rng = np.random.default_rng(len(x0) * 100 + steps)
    P = np.vstack([x0[:2] + [0.5, -0.3], rng.uniform(1.0, 49.0, size=(n - 1, 2))])
    robots = (np.array([[15.0, 12.0], [28.0, 40.0]]), np.array([1.0, 0.7]))
    for t, env_robots, reach, end_margin in ((0.0, NO_ROBOTS, 1.0, None), (7.5, robots, 2.5, 0.0)):
        env = Surroundings.at(_world(), t, env_robots[0], env_robots)
        got = feasible_steps(m, x0, P, env, steps=steps, reach=reach, margin=margin,
                             end_margin=end_margin)
        ref = _reference(m, x0, P, env, steps, reach, margin, end_margin)
        assert got.any() and (~got).any()
        assert np.array_equal(got, ref), np.flatnonzero(got != ref)


def test_feasible_steps_of_a_model_that_does_not_say_how_far_its_footprint_reaches():
    """A footprint of two offset disks and no ``footprint_extent``: the check bounds the disks
    themselves."""
    from hybridnav.models.point_mass import PointMass

    class TwoDisks(PointMass):
        name = "two_disks_test"

        def footprint(self, X):
            X = np.asarray(X, dtype=float).reshape(-1, self.nx)
            off = np.array([[0.6, 0.0], [-0.5, 0.3]])
            return X[:, None, :2] + off[None], np.array([0.4, 0.3])

    m = TwoDisks(dt=0.5, jit=False)
    assert m.footprint_extent is None
    x0 = np.array([10.0, 12.0])
    rng = np.random.default_rng(11)
    P = rng.uniform(1.0, 49.0, size=(1200, 2))
    robots = (np.array([[15.0, 12.0]]), np.array([1.0]))
    env = Surroundings.at(_world(), 3.0, robots[0], robots)
    got = feasible_steps(m, x0, P, env, steps=90, reach=1.0, margin=0.2)
    assert got.any() and (~got).any()
    assert np.array_equal(got, _reference(m, x0, P, env, 90, 1.0, 0.2))


def test_feasible_steps_in_a_world_without_obstacles_and_with_no_candidates():
    m = models.get("point_mass", dt=0.5, radius=0.5)
    env = Surroundings.at(World((0.0, 10.0, 0.0, 10.0)), 0.0, np.zeros((0, 2)), NO_ROBOTS)
    P = np.array([[5.0, 5.0], [9.9, 5.0], [0.2, 0.2], [5.2, 5.0]])
    x0 = np.array([5.0, 5.0])
    got = feasible_steps(m, x0, P, env, steps=50, reach=0.5, margin=0.1)
    assert np.array_equal(got, _reference(m, x0, P, env, 50, 0.5, 0.1))
    assert got.tolist() == [True, False, False, True]     # the border; within reach at once
    assert feasible_steps(m, x0, np.zeros((0, 2)), env, steps=50, reach=0.5,
                          margin=0.1).shape == (0,)
    assert feasible_steps(m, x0, P, env, steps=0, reach=0.5, margin=0.1).tolist() == \
        _reference(m, x0, P, env, 0, 0.5, 0.1).tolist()


def test_feasible_steps_of_nan_states_and_candidates_are_those_of_the_exact_test():
    """NaN boxes are near everything, so NaN samples reach the exact tests (which reject a move
    through NaN at the border, and a NaN segment for a polygon's interior)."""
    m = models.get("point_mass", dt=0.5, radius=0.5, jit=False)
    env = Surroundings.at(_world(), 1.0, np.zeros((0, 2)), NO_ROBOTS)
    P = np.array([[5.0, 5.0], [np.nan, 20.0], [44.0, 30.0], [26.0, np.nan]])
    for x0 in ([30.0, 20.0], [np.nan, 20.0]):
        x0 = np.array(x0)
        for n in (4, 1200):            # without and with the clear map
            Pn = np.resize(P, (n, 2))
            got = feasible_steps(m, x0, Pn, env, steps=40, reach=1.0, margin=0.1)
            assert np.array_equal(got, _reference(m, x0, Pn, env, 40, 1.0, 0.1))


# ---- what the check prunes with ---------------------------------------------------------------

@pytest.mark.parametrize("scenario", ["fastep-s2", "pso-ba-dynamic", "aco-case-study-2"])
def test_a_free_box_of_the_clear_map_is_farther_than_reach_from_everything(scenario):
    world = load_scenario(scenario).world
    static = world.static()
    xmin, xmax, ymin, ymax = world.workspace
    span = xmax - xmin
    rng = np.random.default_rng(5)
    n = 50_000
    c = rng.uniform([xmin - 0.1 * span, ymin - 0.1 * span], [xmax + 0.1 * span, ymax + 0.1 * span],
                    (n, 2))
    half = rng.uniform(0.0, span / 30, (n, 2))
    lo, hi = c - half, c + half
    for reach in (0.0, 0.02 * span, 0.1 * span):
        cm = world.clear_map(reach)
        free = cm.free(lo, hi)
        assert 0.005 < free.mean() < 0.95
        for u in [rng.uniform(size=(n, 2)) for _ in range(4)] + [np.zeros((n, 2)), np.ones((n, 2)),
                                                                  np.array([[0.0, 1.0]] * n)]:
            pts = (lo + u * (hi - lo))[free]
            assert np.all(world.border_clearance(pts) > reach)
            assert np.all(static.clearance(pts) > reach)
    bad = np.array([[np.nan, 1.0], [20.0, 20.0], [np.inf, 3.0]])
    assert not world.clear_map(0.1).free(bad, np.array([[2.0, 2.0], [np.nan, 21.0], [4.0, 4.0]])).any()
    assert world.clear_map(0.1) is world.clear_map(0.1 + 1e-9 * span)    # one map for close reaches


def test_obstacle_boxes_hold_the_obstacles_and_single_worlds_add_up():
    world = _world()
    rng = np.random.default_rng(2)
    # every obstacle's surface points lie within its pad of its box, moving circles over time
    lo, hi, pad = world.boxes(2.0, 9.0)
    for k, o in enumerate(world.obstacles):
        ts = rng.uniform(2.0, 9.0, 200) if isinstance(o, MovingCircle) else np.zeros(200)
        if isinstance(o, (Circle, MovingCircle)):
            ang = rng.uniform(0, 2 * math.pi, 200)
            c = o.center_at(ts) if isinstance(o, MovingCircle) else np.array(o.center)
            pts = c + o.radius * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        else:
            A, B = o._A, o._B
            e = rng.integers(0, len(A), 200)
            s = rng.uniform(size=(200, 1))
            pts = A[e] + s * (B[e] - A[e])
        gap = np.hypot(*np.maximum(np.maximum(lo[k] - pts, pts - hi[k]), 0.0).T)
        assert np.all(gap <= pad[k] + 1e-12)
    per_time, _, _ = world.boxes(np.array([1.0, 2.0]), np.array([3.0, 4.0]))
    assert per_time.shape == (2, len(world.obstacles), 2)
    # a world's swept-disk test is true exactly where one of its single worlds' is
    A = rng.uniform(0, 50, (3000, 2))
    B = A + rng.normal(0, 3, (3000, 2))
    t = rng.uniform(0, 20, 3000)
    for r in (0.0, 0.7):
        whole = world.segment_collides(A, B, radius=r, t=t)
        parts = np.zeros(len(A), dtype=bool)
        for w in world.singles():
            parts |= w.segment_collides(A, B, radius=r, t=t)
        assert np.array_equal(whole, parts) and whole.any() and (~whole).any()


@pytest.mark.parametrize("name", ["point_mass", "unicycle", "tractor_trailer"])
def test_footprint_extent_bounds_the_footprint(name):
    rng = np.random.default_rng(1)
    for kw in ({}, {"L": 3.0, "Lt": 2.5, "b": 0.6, "c": 0.0}) if name == "tractor_trailer" \
            else ({}, {"radius": 1.7}):
        m = models.get(name, **kw)
        X = rng.uniform(-40, 40, (5000, m.nx))
        C, r = m.footprint(X)
        reach = np.hypot(*(C - X[:, None, :2]).transpose(2, 0, 1)) + r
        assert reach.max() <= m.footprint_extent * (1 + 1e-12)
        assert reach.max() >= m.footprint_extent * (1 - 1e-3)     # and is not loose


def test_tractor_trailer_footprint_is_the_broadcast_formula_bit_for_bit():
    """The footprint is computed one coordinate at a time; the disks are those of the formula
    (tractor disks along ``u0`` from ``(x, y)``, trailer disks along ``u1`` from the hitch)."""
    m = models.get("tractor_trailer", L=2.3, Lt=1.9, b=0.8, c=0.3)
    q = m.values
    rng = np.random.default_rng(3)
    X = np.vstack([rng.uniform(-100, 100, (20000, 5)), rng.normal(0, 1e-6, (50, 5))])
    (lt, nt, rt), (lr, nr, rr) = m._bodies()
    u0 = np.stack([np.cos(X[:, 2]), np.sin(X[:, 2])], axis=1)
    u1 = np.stack([np.cos(X[:, 3]), np.sin(X[:, 3])], axis=1)
    pos = X[:, :2]
    s_t = (np.arange(nt) + 0.5) / nt * lt - lt / 2
    hitch = pos - (q["L"] / 2 + q["c"]) * u0
    s_r = (np.arange(nr) + 0.5) / nr * lr
    ref = np.concatenate([pos[:, None, :] + s_t[None, :, None] * u0[:, None, :],
                          hitch[:, None, :] - s_r[None, :, None] * u1[:, None, :]], axis=1)
    C, radii = m.footprint(X)
    assert np.array_equal(C, ref)
    assert np.array_equal(radii, np.concatenate([np.full(nt, rt), np.full(nr, rr)]))


def test_tractor_trailer_footprint_follows_a_changed_parameter():
    """The disk layout is kept between calls, but not past a change of the parameters."""
    m = models.get("tractor_trailer")
    X = np.random.default_rng(4).uniform(-5, 5, (50, 5))
    m.footprint(X)
    m.values["Lt"] = m.values["Lt"] * 2.5
    C, radii = m.footprint(X)
    C2, radii2 = models.get("tractor_trailer", Lt=m.values["Lt"]).footprint(X)
    assert np.array_equal(C, C2) and np.array_equal(radii, radii2)
    radii[:] = 0.0                                   # the caller's copy
    assert np.array_equal(m.footprint(X)[1], radii2)


# ---- whole runs are the same as before ---------------------------------------------------------

# recorded from the code before the pruned check (commit e216dda): per robot, outcome, states,
# planned steps and final state
RUNS = [
    ("fastep-kinematic", "fastep-s3", 0, {},
     [("reached", 563, 1, [44.544524069876886, 5.197339678419176])]),
    ("aco-kinematic", "tractor-trailer-1", 0, {"k": 30, "m": 500},
     [("reached", 602, 2, [45.09276960316895, 5.48928055681309, -1.7559149833340153,
                           -1.7537392035923716, -0.002220340974604088])]),
    ("fastep-kinematic", "pso-ba-dynamic", 0, {"n": 20, "iterations": 10},
     [("reached", 596, 3, [21.654016769393174, 62.47739350620111]),
      ("reached", 854, 30, [29.52749333504064, 61.132833544951595])]),
]


@pytest.mark.parametrize("planner, scenario, seed, params, robots", RUNS)
def test_runs_are_those_of_the_unpruned_check(planner, scenario, seed, params, robots):
    res = planners.get(planner, **params).run(load_scenario(scenario), seed=seed)
    assert len(res.robots) == len(robots)
    for r, (outcome, n, planned, final) in zip(res.robots, robots):
        assert (r.outcome, len(r.states), r.metrics["steps_planned"]) == (outcome, n, planned)
        np.testing.assert_allclose(r.states[-1], final, rtol=0, atol=1e-12)
