"""The compiled box-to-box pruning test equals the NumPy one boolean for boolean (NaN and
infinite corners, boxes exactly at the threshold, empty sets), and the NumPy path remains."""

from __future__ import annotations

import numpy as np
import pytest

from hybridnav import native
from hybridnav.native import boxes
from hybridnav.planners.step.sweep import _boxes_near


def _numpy(monkeypatch, *args):
    with monkeypatch.context() as mp:
        mp.setenv(native.ENV, "0")
        assert boxes.boxes_near(*args) is None
        return _boxes_near(*args)


def _case(rng, shape, K, special):
    lo = rng.integers(-6, 6, shape + (2,)).astype(float) * 0.5
    hi = lo + rng.integers(0, 4, shape + (2,)) * 0.5
    o_lo = rng.integers(-6, 6, (K, 2)).astype(float) * 0.5
    o_hi = o_lo + rng.integers(0, 3, (K, 2)) * 0.5
    o_pad = rng.integers(0, 3, K) * 0.5
    if special:
        for a in (lo, hi, o_lo, o_hi):
            flat = a.reshape(-1)
            flat[rng.random(flat.size) < 0.05] = np.nan
            flat[rng.random(flat.size) < 0.03] = np.inf
            flat[rng.random(flat.size) < 0.03] = -np.inf
    thr = float(rng.choice([0.0, 0.5, 1.0, 1.5 + 1e-9]))
    return lo, hi, o_lo, o_hi, o_pad, thr


@pytest.mark.parametrize("special", [False, True])
@pytest.mark.parametrize("shape,K", [((50,), 9), ((20, 8), 5), ((7, 3), 1), ((0,), 4),
                                     ((5,), 0), ((3, 2, 4), 6)])
def test_compiled_boxes_near_equals_numpy(shape, K, special, monkeypatch):
    if boxes._library() is None:
        pytest.skip("no C compiler")
    rng = np.random.default_rng([K, len(shape), special])
    for _ in range(20):
        args = _case(rng, shape, K, special)
        got = boxes.boxes_near(*args)
        assert got is not None and got.dtype == bool
        want = _numpy(monkeypatch, *args)
        assert got.shape == want.shape and np.array_equal(got, want)
        assert np.array_equal(_boxes_near(*args), want)      # the caller takes the kernel


def test_other_shapes_go_to_numpy():
    lo = np.zeros((3, 2))
    assert boxes.boxes_near(lo, lo, np.zeros((2, 3, 2)), np.zeros((2, 3, 2)), np.zeros(3),
                            0.5) is None                       # boxes per time
    assert boxes.boxes_near(lo, lo, np.zeros((3, 2)), np.zeros((3, 2)), np.zeros(3),
                            np.full(3, 0.5)) is None           # a threshold per box


@pytest.mark.parametrize("na,n1,m,view", [(30, 65, 1, True), (30, 17, 3, False), (5, 9, 1, True),
                                          (7, 12, 2, False), (4, 2, 1, True), (0, 17, 1, True)])
def test_compiled_stretch_boxes_equal_numpy(na, n1, m, view, monkeypatch):
    """Views of a rollout (positions among other state) and whole footprints; short last
    stretches; NaN and infinite samples."""
    from hybridnav.planners.step.sweep import _STRIDE, _stretch_boxes

    if boxes._library() is None:
        pytest.skip("no C compiler")
    rng = np.random.default_rng([na, n1, m])
    nst = -(-(n1 - 1) // _STRIDE)
    for special in (False, True):
        if view:
            traj = rng.standard_normal((na, n1, 5))
            pts = traj[:, :, None, :2]
        else:
            pts = rng.standard_normal((na, n1, m, 2))
        if special:
            flat = pts.reshape(-1) if not view else traj.reshape(-1)
            flat[rng.random(flat.size) < 0.02] = np.nan
            flat[rng.random(flat.size) < 0.02] = np.inf
        got = boxes.stretch_boxes(pts, nst, _STRIDE)
        assert got is not None
        with monkeypatch.context() as mp:
            mp.setenv(native.ENV, "0")
            want = _stretch_boxes(pts, nst)
        for g, w in zip(got, want):
            assert g.shape == w.shape and np.array_equal(g, w, equal_nan=True)


@pytest.mark.parametrize("special", [False, True])
@pytest.mark.parametrize("shape,K", [((50,), 9), ((20, 8), 5), ((7, 3), 1), ((0,), 4), ((6,), 0)])
def test_compiled_near_any_equals_border_or_any_obstacle(shape, K, special, monkeypatch):
    """As sweep._Sweep._near_each's ``border | frozen.any(axis=-1)``, NaN corners near."""
    if boxes._library() is None:
        pytest.skip("no C compiler")
    rng = np.random.default_rng([K, len(shape), special, 7])
    workspace = (-3.0, 3.0, -2.5, 3.5)
    for _ in range(20):
        lo, hi, o_lo, o_hi, o_pad, thr = _case(rng, shape, K, special)
        got = boxes.near_any(lo, hi, thr, workspace, o_lo, o_hi, o_pad)
        xmin, xmax, ymin, ymax = workspace
        border = ~((lo[..., 0] - xmin >= thr) & (xmax - hi[..., 0] >= thr)
                   & (lo[..., 1] - ymin >= thr) & (ymax - hi[..., 1] >= thr))
        want = border | _numpy(monkeypatch, lo, hi, o_lo, o_hi, o_pad, thr).any(axis=-1)
        assert got is not None and got.shape == want.shape and np.array_equal(got, want)
