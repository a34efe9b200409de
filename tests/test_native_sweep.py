"""The compiled block steps of the swept-footprint check (:func:`hybridnav.native.boxes.
reach_first`, :func:`~hybridnav.native.boxes.disks_near`) equal the NumPy steps they replace,
bit for bit (samples exactly at ``reach``, boxes exactly at the threshold, NaN and infinite
samples, short last stretches, empty batches), and the check falls back to NumPy, with the same
verdicts, where no compiler is found."""

from __future__ import annotations

import ctypes
import os
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hybridnav import models, native
from hybridnav.native import boxes
from hybridnav.planners.step import sweep
from hybridnav.planners.step.stepfit import Surroundings, feasible_steps
from hybridnav.world import Circle, MovingCircle, Rectangle, Segment, World

needs_kernel = pytest.mark.skipif(boxes._library() is None, reason="no C compiler")


def _numpy_reach_first(monkeypatch, traj, P, nst, reach, reach2):
    with monkeypatch.context() as mp:
        mp.setenv(native.ENV, "0")
        assert boxes.reach_first(traj, P, nst, sweep._STRIDE, reach, reach2) is None
        return sweep._reach_first(traj, P, nst, reach, reach2)


def _same(got, want):
    assert len(got) == len(want)
    for g, w in zip(got, want):
        assert g.shape == w.shape and g.dtype == w.dtype
        assert np.array_equal(g, w, equal_nan=True)


def _spoil(rng, arrays, fractions):
    """Put non-finite values ({value: fraction}, in that order) into each array, in place."""
    for a in arrays:
        flat = a.reshape(-1)
        for value, fraction in fractions.items():
            flat[rng.random(flat.size) < fraction] = value


def _obstacle_boxes(rng, K):
    """K obstacle boxes on the half grid (empty ones too) and their paddings."""
    o_lo = rng.integers(-6, 6, (K, 2)).astype(float) * 0.5
    o_hi = o_lo + rng.integers(0, 3, (K, 2)) * 0.5
    return o_lo, o_hi, rng.integers(0, 3, K) * 0.5


def _trajectories(rng, na, n1, nx, special):
    """Rollout-like samples on a half grid round targets on the grid: many samples exactly at
    the distance 2.5 = hypot(1.5, 2) (3-4-5) or 0 from their target."""
    traj = rng.integers(-8, 8, (na, n1, nx)).astype(float) * 0.5
    P = rng.integers(-4, 4, (na, 2)).astype(float) * 0.5
    touch = rng.random((na, n1)) < 0.1
    traj[..., 0] = np.where(touch, P[:, None, 0] + 1.5, traj[..., 0])
    traj[..., 1] = np.where(touch, P[:, None, 1] - 2.0, traj[..., 1])
    if special:
        _spoil(rng, [traj], {np.nan: 0.03, np.inf: 0.02, -np.inf: 0.02})
        P[rng.random(P.shape) < 0.05] = np.nan
    return traj, P


@needs_kernel
@pytest.mark.parametrize("special", [False, True])
@pytest.mark.parametrize("na,n1,nx", [(40, 65, 2), (30, 33, 5), (9, 12, 4), (5, 2, 3), (0, 9, 2),
                                      (3, 9, 2)])
def test_compiled_reach_first_equals_numpy(na, n1, nx, special, monkeypatch):
    rng = np.random.default_rng([na, n1, nx, special])
    nst = -(-(n1 - 1) // sweep._STRIDE)
    for reach in (2.5, 0.0, 1.0, 1e-9, 4.0, 2.5 * (1 + 2e-16), 2.5 * (1 - 2e-16), 1e-160, np.inf,
                  -1.0, np.nan):
        traj, P = _trajectories(rng, na, n1, nx, special)
        reach2 = reach * reach * (1.0 + 1e-9)
        got = boxes.reach_first(traj, P, nst, sweep._STRIDE, reach, reach2)
        assert got is not None
        want = _numpy_reach_first(monkeypatch, traj, P, nst, reach, reach2)
        _same(got, want)
        _same(sweep._reach_first(traj, P, nst, reach, reach2), want)   # the caller's choice
    # samples a hair inside and outside reach (where only hypot decides), huge and tiny ones
    P = np.zeros((1, 2))
    for reach in (1.0, 3.0, 1e-140, 1e140):
        for scale in (1 - 4e-16, 1 - 2e-16, 1.0, 1 + 2e-16, 1 + 4e-16, 1 + 1e-10):
            d = reach * scale
            traj = np.array([[[5 * reach, 0.0], [d * 0.6, d * 0.8], [d / np.sqrt(2), -d / np.sqrt(2)],
                              [d, 0.0], [1e300, 1e300], [0.0, 0.0]]])
            for a, b in ((1, 6), (2, 6), (3, 6), (4, 6)):
                part = np.ascontiguousarray(np.concatenate([traj[:, :1], traj[:, a:b]], axis=1))
                reach2 = reach * reach * (1.0 + 1e-9)
                _same(boxes.reach_first(part, P, 1, sweep._STRIDE, reach, reach2),
                      _numpy_reach_first(monkeypatch, part, P, 1, reach, reach2))
    # the prefilter decides which rows are looked at: a box just out of reach2 hides a sample
    traj = np.array([[[0.0, 0.0], [3.0, 0.0]]])
    P = np.array([[0.0, 0.0]])
    for reach2 in (0.0, -1.0, np.nan):
        _same(boxes.reach_first(traj, P, 1, sweep._STRIDE, 1.0, reach2),
              _numpy_reach_first(monkeypatch, traj, P, 1, 1.0, reach2))


@needs_kernel
@settings(max_examples=150, deadline=None)
@given(st.integers(1, 6), st.integers(2, 20), st.integers(0, 2**32 - 1),
       st.sampled_from([0.0, 0.5, 2.5, 3.0]))
def test_compiled_reach_first_on_random_blocks(na, n1, seed, reach):
    rng = np.random.default_rng(seed)
    traj, P = _trajectories(rng, na, n1, 2, seed % 3 == 0)
    nst = -(-(n1 - 1) // sweep._STRIDE)
    reach2 = reach * reach * (1.0 + 1e-9)
    got = boxes.reach_first(traj, P, nst, sweep._STRIDE, reach, reach2)
    with mock.patch.dict(os.environ, {native.ENV: "0"}):     # (hypothesis: no monkeypatch)
        want = sweep._reach_first(traj, P, nst, reach, reach2)
    _same(got, want)


def _numpy_disks_near(monkeypatch, C, thr, workspace, o_lo, o_hi, o_pad):
    """Each disk's box along its stretch (sweep._stretch_boxes) and the border or any obstacle
    box near it (sweep._boxes_near), the NumPy way."""
    with monkeypatch.context() as mp:
        mp.setenv(native.ENV, "0")
        assert boxes.disks_near(C, thr, workspace, o_lo, o_hi, o_pad) is None
        xmin, xmax, ymin, ymax = workspace
        lo, hi, near = [], [], []
        for j in range(C.shape[2]):
            lo_j, hi_j = sweep._stretch_boxes(C[:, :, j:j + 1], 1)
            lo_j, hi_j = lo_j[:, 0], hi_j[:, 0]
            t = np.asarray(thr[j])
            border = ~((lo_j[:, 0] - xmin >= t) & (xmax - hi_j[:, 0] >= t)
                       & (lo_j[:, 1] - ymin >= t) & (ymax - hi_j[:, 1] >= t))
            near.append(border | sweep._boxes_near(lo_j, hi_j, o_lo, o_hi, o_pad, t).any(-1))
            lo.append(lo_j)
            hi.append(hi_j)
        return np.stack(lo, axis=1), np.stack(hi, axis=1), np.stack(near, axis=1)


@needs_kernel
@pytest.mark.parametrize("special", [False, True])
@pytest.mark.parametrize("ns,n1,nd,K", [(40, 9, 5, 7), (8, 9, 2, 1), (3, 4, 3, 0), (0, 9, 4, 3),
                                        (6, 1, 2, 4)])
def test_compiled_disks_near_equals_numpy(ns, n1, nd, K, special, monkeypatch):
    rng = np.random.default_rng([ns, n1, nd, K, special])
    workspace = (-3.0, 3.0, -2.5, 3.5)
    for _ in range(15):
        C = rng.integers(-8, 8, (ns, n1, nd, 2)).astype(float) * 0.5
        o_lo, o_hi, o_pad = _obstacle_boxes(rng, K)
        if special:
            _spoil(rng, (C, o_lo, o_hi), {np.nan: 0.04, np.inf: 0.02})
        thr = rng.integers(0, 4, nd) * 0.5 + rng.choice([0.0, 1e-9], nd)
        got = boxes.disks_near(C, thr, workspace, o_lo, o_hi, o_pad)
        assert got is not None
        _same(got, _numpy_disks_near(monkeypatch, C, thr, workspace, o_lo, o_hi, o_pad))


@needs_kernel
@pytest.mark.parametrize("special", [False, True])
@pytest.mark.parametrize("M,K", [(60, 9), (7, 1), (0, 4), (5, 0)])
def test_compiled_pieces_near_equals_numpy(M, K, special, monkeypatch):
    """The pieces' boxes, border and obstacle flags of _Sweep.touches's pruning
    (_Sweep._near_each on np.minimum / np.maximum of the end points)."""
    rng = np.random.default_rng([M, K, special, 3])
    workspace = (-3.0, 3.0, -2.5, 3.5)
    for _ in range(20):
        A = rng.integers(-8, 8, (M, 2)).astype(float) * 0.5
        B = np.where(rng.random((M, 2)) < 0.2, A, rng.integers(-8, 8, (M, 2)) * 0.5)  # points
        o_lo, o_hi, o_pad = _obstacle_boxes(rng, K)
        if special:
            _spoil(rng, (A, B, o_lo), {np.nan: 0.05, -np.inf: 0.03})
        thr = float(rng.choice([0.0, 0.5, 1.0 + 1e-9]))
        got = boxes.pieces_near(A, B, thr, workspace, o_lo, o_hi, o_pad)
        assert got is not None
        lo, hi = np.minimum(A, B), np.maximum(A, B)
        xmin, xmax, ymin, ymax = workspace
        border = ~((lo[:, 0] - xmin >= thr) & (xmax - hi[:, 0] >= thr)
                   & (lo[:, 1] - ymin >= thr) & (ymax - hi[:, 1] >= thr))
        with monkeypatch.context() as mp:
            mp.setenv(native.ENV, "0")
            frozen = sweep._boxes_near(lo, hi, o_lo, o_hi, o_pad, thr)
        _same(got, (lo, hi, border, frozen))


def _static_reference(world, A, B, obs, radius):
    ref = np.zeros(len(A), dtype=bool)
    singles = world.singles()
    with np.errstate(all="ignore"):
        for o in range(len(singles)):
            at = np.flatnonzero(obs == o)
            ref[at] = singles[o].segment_collides(A[at], B[at], radius=radius)
    return ref


@pytest.mark.parametrize("special", [False, True])
def test_compiled_static_hits_equal_each_obstacles_own_test(special):
    """_Sweep.touches's exact test of (piece, static obstacle) pairs: each obstacle's own
    World.segment_collides, to the boolean. Half-integer grids make moves that touch, end on or
    run along edges and circles; NaN and infinite end points where ``special``."""
    from hybridnav.world import Polygon

    world = World((-6.0, 6.0, -6.0, 6.0), (
        Circle((0.0, 0.0), 1.0), Rectangle((1.0, 1.0), (3.0, 2.0)),
        Segment((-4.0, -1.0), (-1.0, -4.0)), Polygon([(-4.0, 2.0), (-2.0, 2.0), (-3.0, 4.0)]),
        Circle((3.0, -3.0), 0.5)))
    rng = np.random.default_rng([special, 11])
    seen = set()
    for _ in range(30):
        M = 400
        A = rng.integers(-12, 12, (M, 2)).astype(float) * 0.5
        B = np.where(rng.random((M, 2)) < 0.2, A, rng.integers(-12, 12, (M, 2)) * 0.5)
        if special:
            _spoil(rng, (A, B), {np.nan: 0.05, np.inf: 0.03, -np.inf: 0.03})
        obs = rng.integers(0, len(world.obstacles), M)
        radius = float(rng.choice([0.0, 0.5, 1.0]))
        got = boxes.static_hits(world, A, B, obs, radius)
        ref = _static_reference(world, A, B, obs, radius)
        assert np.array_equal(got, ref)
        seen.update(ref.tolist())
    assert seen == {True, False}


@pytest.mark.parametrize("scenario", ["fastep-s2", "tractor-trailer-1", "turtlebot-office",
                                      "pso-ba-dynamic"])
def test_compiled_static_hits_on_the_built_in_worlds(scenario):
    from hybridnav.world import load_scenario

    full = load_scenario(scenario).world
    world = World(full.workspace, tuple(o for o in full.obstacles
                                         if not isinstance(o, MovingCircle)))
    lo, hi, _ = world.boxes()
    rng = np.random.default_rng(4)
    k = rng.integers(0, len(world.obstacles), 3000)
    A = rng.uniform(lo[k] - 1.0, hi[k] + 1.0)
    B = A + rng.normal(0.0, 0.7, A.shape)
    for radius in (0.0, 0.2):
        got = boxes.static_hits(world, A, B, k, radius)
        assert np.array_equal(got, _static_reference(world, A, B, k, radius))
    if full._c_moving:               # moving circles: the NumPy path
        assert boxes.static_hits(full, A, B, k, 0.2) is None


def test_other_arrays_go_to_numpy():
    assert boxes.reach_first(np.zeros((3, 5, 1)), np.zeros((3, 2)), 1, 8, 1.0, 1.0) is None
    assert boxes.reach_first(np.zeros((3, 5, 2)), np.zeros((2, 2)), 1, 8, 1.0, 1.0) is None
    assert boxes.reach_first(np.zeros((3, 5, 2), dtype=np.float32), np.zeros((3, 2)), 1, 8,
                             1.0, 1.0) is None
    C = np.zeros((3, 4, 2, 2))
    assert boxes.disks_near(C, np.zeros(3), (0, 1, 0, 1), np.zeros((1, 2)), np.zeros((1, 2)),
                            np.zeros(1)) is None                   # a threshold per disk
    assert boxes.disks_near(C[..., :1], np.zeros(2), (0, 1, 0, 1), np.zeros((1, 2)),
                            np.zeros((1, 2)), np.zeros(1)) is None


def _env(t):
    world = World((0.0, 50.0, 0.0, 50.0), (
        Circle((20.0, 20.0), 4.0), Segment((10.0, 35.0), (25.0, 42.0)),
        Rectangle((30.0, 5.0), (38.0, 12.0)), MovingCircle((5.0, 25.0), 1.5, 0.6, 0.3)))
    robots = (np.array([[15.0, 12.0], [28.0, 40.0]]), np.array([1.0, 0.7]))
    return Surroundings.at(world, t, robots[0], robots)


@pytest.mark.parametrize("name,kw,x0,steps", [
    ("point_mass", {"dt": 0.5, "radius": 0.5, "jit": False}, [8.0, 10.0], 150),
    ("tractor_trailer", {"dt": 0.5, "jit": False}, [27.0, 26.0, 2.0, 1.5, 0.0], 61)])
def test_feasible_steps_without_a_compiler_are_the_same(name, kw, x0, steps, monkeypatch,
                                                         tmp_path):
    """No compiler: the box kernels are unavailable, the NumPy steps give the same verdicts
    (moving circles and other robots included, so the compiled disks' boxes are extended by the
    moving ones)."""
    m = models.get(name, **kw)
    rng = np.random.default_rng(steps)
    P = rng.uniform(1.0, 49.0, size=(300, 2))
    x0 = np.array(x0)
    kws = {"steps": steps, "reach": 2.0, "margin": 0.3}
    want = [feasible_steps(m, x0, P, _env(t), **kws) for t in (0.0, 7.5)]
    monkeypatch.setenv("HYBRIDNAV_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    monkeypatch.setattr(native, "_LOADED", {})
    monkeypatch.setattr(native, "_KERNELS", {})
    assert boxes._library() is None
    assert boxes.reach_first(np.zeros((1, 9, 2)), np.zeros((1, 2)), 1, 8, 1.0, 1.0) is None
    for t, w in zip((0.0, 7.5), want):
        assert np.array_equal(feasible_steps(m, x0, P, _env(t), **kws), w)


@needs_kernel
def test_the_extension_and_ctypes_call_the_same_functions(monkeypatch):
    """pycall's generated entry point and the ctypes binding call the same compiled code: the
    same boxes; arguments it cannot take are refused, not misread."""
    from hybridnav.native import pycall

    ext = pycall._from_extension("boxes", boxes._SIGNATURES)
    if ext is None:
        pytest.skip("no Python.h: the ctypes binding is the only one")
    lib = pycall._from_ctypes("boxes", boxes._SIGNATURES)
    rng = np.random.default_rng(5)
    traj, P = _trajectories(rng, 20, 33, 4, True)
    outs = []
    for fns in (ext, lib):
        lo, hi, first = np.empty((20, 4, 2)), np.empty((20, 4, 2)), np.empty(20, dtype=np.int64)
        fns["hn_reach_first"](20, 33, 4, sweep._STRIDE, traj, 33 * 4, 4, P, 2.5, 6.25, lo, hi,
                              first)
        outs.append((lo, hi, first))
    _same(outs[0], outs[1])
    with pytest.raises(TypeError):
        ext["hn_reach_first"](20, 33)
    with pytest.raises(TypeError):
        ext["hn_reach_first"](20, 33, 4, sweep._STRIDE, "not an array", 33 * 4, 4, P, 2.5, 6.25,
                              lo, hi, first)
    assert pycall._wrapper("m", {"f": ([ctypes.c_int], None)}) is None
