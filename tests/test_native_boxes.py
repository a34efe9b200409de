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
