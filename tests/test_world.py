"""Geometry of hybridnav.world against independent references (dense boundary sampling,
analytic formulas, matplotlib's point-in-path test)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from matplotlib.path import Path as MplPath
from scipy.spatial import ConvexHull

from hybridnav.errors import HybridnavError
from hybridnav.world import (
    Circle,
    MovingCircle,
    Polygon,
    Rectangle,
    Segment,
    World,
    point_segment_distance,
    points_in_convex_polygon,
    segment_segment_distance,
)

RNG_SEED = 20240521


# ---------------------------------------------------------------------------------------------
# independent references
# ---------------------------------------------------------------------------------------------


def sample_boundary(obstacle, n=20000):
    """Dense points on an obstacle's surface (for brute-force distances)."""
    if isinstance(obstacle, Circle):
        a = np.linspace(0, 2 * np.pi, n, endpoint=False)
        return np.asarray(obstacle.center) + obstacle.radius * np.column_stack([np.cos(a), np.sin(a)])
    if isinstance(obstacle, Segment):
        s = np.linspace(0, 1, n)[:, None]
        return np.asarray(obstacle.a) * (1 - s) + np.asarray(obstacle.b) * s
    V = obstacle.vertices
    W = np.roll(V, -1, axis=0)
    k = n // len(V)
    s = np.linspace(0, 1, k, endpoint=False)[None, :, None]
    return (V[:, None, :] * (1 - s) + W[:, None, :] * s).reshape(-1, 2)  # edge after edge


def brute_distance(obstacle, P, n=20000):
    B = sample_boundary(obstacle, n)
    return np.min(np.linalg.norm(P[:, None, :] - B[None, :, :], axis=2), axis=1)


def inside_reference(obstacle, P):
    """Strictly-inside test independent of hybridnav (analytic / matplotlib)."""
    if isinstance(obstacle, Circle):
        return np.linalg.norm(P - np.asarray(obstacle.center), axis=1) < obstacle.radius
    if isinstance(obstacle, Segment):
        return np.zeros(len(P), bool)
    return MplPath(obstacle.vertices).contains_points(P)


def sampling_tol(obstacle, n=20000):
    B = sample_boundary(obstacle, n)
    step = np.max(np.linalg.norm(np.diff(B, axis=0), axis=1))
    return step / 2 + 1e-9


def random_points(rng, n, lo=-10, hi=10):
    return rng.uniform(lo, hi, size=(n, 2))


OBSTACLES = [
    Circle((1.0, 2.0), 3.0),
    Segment((-4.0, -1.0), (5.0, 3.0)),
    Rectangle((-3.0, -2.0), (4.0, 1.5)),
    Polygon(((0.0, 0.0), (6.0, 1.0), (5.0, 5.0), (-1.0, 4.0))),
    Polygon(((0.0, 0.0), (-1.0, 4.0), (5.0, 5.0), (6.0, 1.0))),  # clockwise
]


# ---------------------------------------------------------------------------------------------
# single obstacles
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("obstacle", OBSTACLES, ids=lambda o: type(o).__name__)
def test_clearance_matches_brute_force_and_sign(obstacle):
    rng = np.random.default_rng(RNG_SEED)
    P = random_points(rng, 300)
    c = obstacle.clearance(P)
    assert c.shape == (300,)
    ref = brute_distance(obstacle, P)
    np.testing.assert_allclose(np.abs(c), ref, atol=sampling_tol(obstacle))
    inside = inside_reference(obstacle, P)
    assert np.all(c[inside] <= 0)
    assert np.all(c[~inside] >= 0)
    if isinstance(obstacle, Segment):
        assert np.all(c >= 0)
    else:
        assert inside.any() and (~inside).any()


@pytest.mark.parametrize("obstacle", OBSTACLES, ids=lambda o: type(o).__name__)
def test_nearest_lies_on_surface_at_clearance_distance(obstacle):
    rng = np.random.default_rng(RNG_SEED + 1)
    P = random_points(rng, 300)
    Q = obstacle.nearest(P)
    assert Q.shape == (300, 2)
    np.testing.assert_allclose(obstacle.clearance(Q), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(P - Q, axis=1), np.abs(obstacle.clearance(P)), atol=1e-9)


def test_circle_analytic_and_center_point():
    c = Circle((1.0, -1.0), 2.0)
    np.testing.assert_allclose(c.clearance([[4.0, 3.0], [1.0, -1.0], [1.0, 1.0]]), [3.0, -2.0, 0.0])
    # the centre has a (conventional) nearest point on the circle
    np.testing.assert_allclose(c.nearest([1.0, -1.0]), [[3.0, -1.0]])


def test_rectangle_matches_box_sdf_and_polygon():
    rect = Rectangle((-3.0, -2.0), (4.0, 1.5))
    rng = np.random.default_rng(RNG_SEED + 2)
    P = random_points(rng, 500)
    c = np.array([0.5, -0.25])
    h = np.array([3.5, 1.75])
    q = np.abs(P - c) - h
    sdf = np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(np.max(q, axis=1), 0)
    np.testing.assert_allclose(rect.clearance(P), sdf, atol=1e-12)
    np.testing.assert_allclose(rect.to_polygon().clearance(P), sdf, atol=1e-12)


def test_polygon_orientation_does_not_matter():
    rng = np.random.default_rng(RNG_SEED + 3)
    P = random_points(rng, 200)
    ccw, cw = OBSTACLES[3], OBSTACLES[4]
    np.testing.assert_allclose(ccw.clearance(P), cw.clearance(P))
    np.testing.assert_allclose(ccw.nearest(P), cw.nearest(P))
    assert cw.points[1] == (-1.0, 4.0)  # kept as given


@pytest.mark.parametrize(
    "points",
    [
        [(0, 0), (1, 0)],  # too few
        [(0, 0), (2, 0), (1, 0.2), (2, 2), (0, 2)],  # non-convex (dent)
        [(0, 0), (1, 1), (2, 2)],  # collinear, zero area
        [(0, 0), (1, 0), (1, 0), (0, 1)],  # repeated point
        # pentagram: every turn has the same sign but it winds twice
        [(math.cos(a), math.sin(a)) for a in np.radians([90, 234, 18, 162, 306])],
    ],
)
def test_polygon_rejects_invalid(points):
    with pytest.raises(HybridnavError):
        Polygon(tuple(points))


def test_obstacle_constructor_validation():
    with pytest.raises(HybridnavError, match="radius"):
        Circle((0, 0), -1.0)
    with pytest.raises(HybridnavError, match="zero-length"):
        Segment((1, 1), (1, 1))
    with pytest.raises(HybridnavError, match="max"):
        Rectangle((0, 0), (0, 1))
    with pytest.raises(HybridnavError, match="center"):
        Circle((0, float("nan")), 1.0)
    with pytest.raises(HybridnavError, match="workspace"):
        World((0, 0, 0, 1))


def test_moving_circle_position():
    m = MovingCircle((1.0, 2.0), 0.5, velocity=2.0, heading=math.pi / 3)
    t = 3.5
    expected = (1.0 + 2.0 * math.cos(math.pi / 3) * t, 2.0 + 2.0 * math.sin(math.pi / 3) * t)
    c = m.at(t)
    assert isinstance(c, Circle) and c.radius == 0.5
    np.testing.assert_allclose(c.center, expected)
    np.testing.assert_allclose(m.center_at([0.0, t]), [m.center, expected])
    P = np.array([[0.0, 0.0], [5.0, 5.0]])
    np.testing.assert_allclose(m.clearance(P, t), c.clearance(P))
    np.testing.assert_allclose(m.nearest(P, t), c.nearest(P))


# ---------------------------------------------------------------------------------------------
# kernels
# ---------------------------------------------------------------------------------------------


coord = st.floats(-10, 10, allow_nan=False, allow_infinity=False)
point = st.tuples(coord, coord)


@settings(max_examples=150, deadline=None)
@given(point, point, point, point)
def test_segment_segment_distance_vs_sampling(p0, p1, q0, q1):
    p0, p1, q0, q1 = map(np.asarray, (p0, p1, q0, q1))
    s = np.linspace(0, 1, 401)[:, None]
    P = p0 * (1 - s) + p1 * s
    Q = q0 * (1 - s) + q1 * s
    ref = np.min(np.linalg.norm(P[:, None] - Q[None], axis=2))
    d = float(segment_segment_distance(p0, p1, q0, q1))
    step = (np.linalg.norm(p1 - p0) + np.linalg.norm(q1 - q0)) / 400
    assert d <= ref + 1e-9
    assert d >= ref - step - 1e-9


def test_point_segment_distance_broadcasts():
    P = np.zeros((5, 1, 2))
    A = np.array([[1.0, -1.0], [2.0, 0.0], [0.0, 0.0]])
    B = np.array([[1.0, 1.0], [3.0, 0.0], [0.0, 0.0]])  # last one is a point
    d, Q = point_segment_distance(P, A, B)
    assert d.shape == (5, 3) and Q.shape == (5, 3, 2)
    np.testing.assert_allclose(d[0], [1.0, 2.0, 0.0])
    np.testing.assert_allclose(Q[0], [[1.0, 0.0], [2.0, 0.0], [0.0, 0.0]])


def test_segment_segment_distance_cases():
    # crossing, touching, parallel, collinear-disjoint
    assert segment_segment_distance([0, 0], [2, 2], [0, 2], [2, 0]) == 0.0
    assert segment_segment_distance([0, 0], [1, 0], [1, 0], [1, 5]) == 0.0
    assert segment_segment_distance([0, 0], [4, 0], [1, 2], [3, 2]) == pytest.approx(2.0)
    assert segment_segment_distance([0, 0], [1, 0], [3, 0], [5, 0]) == pytest.approx(2.0)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**32 - 1))
def test_random_convex_polygon_vs_references(seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-5, 5, size=(rng.integers(3, 12), 2))
    hull = ConvexHull(pts)
    V = pts[hull.vertices]
    if rng.random() < 0.5:
        V = V[::-1]
    poly = Polygon(tuple(map(tuple, V)))
    P = random_points(rng, 100, -7, 7)
    inside_ref = MplPath(V).contains_points(P)
    inside = points_in_convex_polygon(P, V)
    c = poly.clearance(P)
    ref = brute_distance(poly, P, n=4000)
    np.testing.assert_allclose(np.abs(c), ref, atol=sampling_tol(poly, n=4000))
    # points well away from the boundary must agree exactly with the independent inside test
    clear = np.abs(c) > 1e-6
    assert np.array_equal(inside[clear], inside_ref[clear])
    assert np.array_equal((c < 0)[clear], inside_ref[clear])


# ---------------------------------------------------------------------------------------------
# World
# ---------------------------------------------------------------------------------------------


def make_world():
    return World(
        (-10.0, 10.0, -8.0, 8.0),
        (
            Circle((-5.0, 4.0), 1.5),
            Segment((-2.0, -6.0), (-2.0, 0.0)),
            Rectangle((2.0, -5.0), (5.0, -2.0)),
            Polygon(((3.0, 2.0), (7.0, 3.0), (5.0, 6.0))),
            MovingCircle((0.0, 5.0), 1.0, velocity=0.5, heading=-math.pi / 2),
        ),
    )


def test_world_clearance_is_min_over_obstacles():
    w = make_world()
    rng = np.random.default_rng(RNG_SEED + 4)
    P = random_points(rng, 400)
    for t in (0.0, 4.0):
        per = np.column_stack(
            [(o.clearance(P, t) if isinstance(o, MovingCircle) else o.clearance(P)) for o in w.obstacles]
        )
        np.testing.assert_allclose(w.clearance(P, t=t), per.min(axis=1))
        np.testing.assert_allclose(w.clearance(P, t=t, radius=0.3), per.min(axis=1) - 0.3)
        c, q, idx = w.nearest(P, t=t)
        np.testing.assert_array_equal(idx, per.argmin(axis=1))
        np.testing.assert_allclose(c, per.min(axis=1))
        assert q.shape == (400, 2)
        np.testing.assert_allclose(np.linalg.norm(P - q, axis=1), np.abs(c), atol=1e-9)
        # the nearest point lies on the surface of obstacle idx
        for k, o in enumerate(w.obstacles):
            sel = idx == k
            if sel.any():
                on = o.clearance(q[sel], t) if isinstance(o, MovingCircle) else o.clearance(q[sel])
                np.testing.assert_allclose(on, 0.0, atol=1e-9)


def test_world_per_point_times():
    w = make_world()
    P = np.array([[0.0, 5.0], [0.0, 5.0], [0.0, 3.0]])
    t = np.array([0.0, 4.0, 4.0])  # the circle moves down 2 units in 4 s
    c = w.clearance(P, t=t)
    np.testing.assert_allclose(c[0], -1.0)
    np.testing.assert_allclose(c[1], 1.0)
    np.testing.assert_allclose(c[2], -1.0)
    with pytest.raises(HybridnavError, match="t"):
        w.clearance(P, t=np.zeros(2))


def test_world_shapes_and_single_point():
    w = make_world()
    assert w.clearance([0.0, 0.0]).shape == (1,)
    assert w.collides(np.zeros((7, 2))).shape == (7,)
    c, q, i = w.nearest(np.zeros((0, 2)))
    assert c.shape == (0,) and q.shape == (0, 2) and i.shape == (0,)
    with pytest.raises(HybridnavError):
        w.clearance(np.zeros((3, 3)))


def test_empty_world():
    w = World((0, 1, 0, 1))
    assert np.all(np.isinf(w.clearance(np.zeros((3, 2)))))
    c, q, i = w.nearest(np.zeros((2, 2)))
    assert np.all(i == -1) and np.all(np.isnan(q))
    assert not w.collides(np.zeros((2, 2)), radius=5).any()
    assert not w.segment_collides(np.zeros((2, 2)), np.ones((2, 2)), 0.1).any()


def test_border_clearance_and_inside_workspace():
    w = World((0.0, 10.0, 0.0, 5.0))
    P = np.array([[1.0, 1.0], [5.0, 4.5], [-1.0, 2.0], [13.0, 9.0], [10.0, 5.0]])
    np.testing.assert_allclose(w.border_clearance(P), [1.0, 0.5, -1.0, -5.0, 0.0])
    np.testing.assert_array_equal(w.inside_workspace(P), [True, True, False, False, True])
    np.testing.assert_array_equal(w.inside_workspace(P, radius=0.75), [True, False, False, False, False])


def test_collides_touching_is_not_collision():
    w = World((-5, 5, -5, 5), (Circle((0.0, 0.0), 1.0),))
    P = np.array([[2.0, 0.0], [1.9, 0.0]])
    np.testing.assert_array_equal(w.collides(P, radius=1.0), [False, True])


def test_segment_collides_vs_dense_sampling():
    w = make_world()
    rng = np.random.default_rng(RNG_SEED + 5)
    n, k = 600, 801
    A = random_points(rng, n, -9, 9)
    B = A + rng.normal(scale=4.0, size=(n, 2))
    s = np.linspace(0, 1, k)
    for radius, t in ((0.0, 0.0), (0.4, 0.0), (0.25, 3.0)):
        hit = w.segment_collides(A, B, radius=radius, t=t)
        S = (A[:, None, :] * (1 - s)[None, :, None] + B[:, None, :] * s[None, :, None]).reshape(-1, 2)
        cmin = w.clearance(S, t=t).reshape(n, k).min(axis=1)
        step = np.linalg.norm(B - A, axis=1) / (k - 1)
        # the clearance is 1-Lipschitz: true min is within step/2 below the sampled min
        sure_hit = cmin < radius
        sure_free = cmin - step / 2 > radius + 1e-12
        assert np.all(hit[sure_hit])
        assert not np.any(hit[sure_free])
        assert sure_hit.sum() > 50 and sure_free.sum() > 50  # the test exercises both outcomes
        assert (sure_hit | sure_free).mean() > 0.9  # undecided: grazes, and point moves across walls


def test_segment_collides_per_move_times():
    w = make_world()
    rng = np.random.default_rng(RNG_SEED + 6)
    A = random_points(rng, 200, -9, 9)
    B = A + rng.normal(scale=3.0, size=(200, 2))
    t = rng.uniform(0, 10, 200)
    together = w.segment_collides(A, B, radius=0.3, t=t)
    one_by_one = [w.segment_collides(A[i], B[i], radius=0.3, t=t[i])[0] for i in range(0, 200, 7)]
    np.testing.assert_array_equal(together[::7], one_by_one)


def test_segment_collides_containment_and_thin_walls():
    w = World((-10, 10, -10, 10), (Rectangle((-5.0, -5.0), (5.0, 5.0)), Segment((8.0, -3.0), (8.0, 3.0))))
    # a move entirely inside the rectangle, far from its edges
    assert w.segment_collides([[-1.0, 0.0]], [[1.0, 0.0]])[0]
    # crossing a zero-thickness wall with a point robot
    assert w.segment_collides([[7.0, 0.0]], [[9.0, 0.0]])[0]
    # passing the wall's end: free for a point, blocked for a disk of radius 0.6
    assert not w.segment_collides([[7.0, 3.5]], [[9.0, 3.5]])[0]
    assert w.segment_collides([[7.0, 3.5]], [[9.0, 3.5]], radius=0.6)[0]
    # zero-length move == point query
    assert w.segment_collides([[0.0, 0.0]], [[0.0, 0.0]])[0]
    assert not w.segment_collides([[9.0, 9.0]], [[9.0, 9.0]])[0]


def test_static_and_moving_views():
    w = make_world()
    assert len(w.static().obstacles) == 4
    assert all(isinstance(o, MovingCircle) for o in w.moving().obstacles)
    assert w.static().workspace == w.workspace
    P = np.array([[0.0, 5.0]])
    assert w.collides(P)[0] and not w.static().collides(P)[0]
