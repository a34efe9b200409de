"""The boxes of the swept-footprint check's pruning (``boxes.c``) bound to NumPy:
:func:`boxes_near` is :func:`hybridnav.planners.step.sweep._boxes_near` for one threshold and one
set of obstacle boxes, in one pass instead of a dozen NumPy operations over (boxes, obstacles);
:func:`near_any` is the border test and the any over the obstacles of
:meth:`~hybridnav.planners.step.sweep._Sweep._near_each` in one pass; :func:`stretch_boxes` is :func:`~hybridnav.planners.step.sweep._stretch_boxes` (exact minima and
maxima, NaN where a coordinate is NaN).
The same IEEE operations in the same order: the same booleans, NaN boxes included (the tests
compare them). ``None`` where it does not apply (no compiler, kernels switched off, arrays of other
shapes), and the caller runs its NumPy path.
"""

from __future__ import annotations

import ctypes
from ctypes import c_double, c_int64, c_void_p

import numpy as np

from hybridnav import native

__all__ = ["boxes_near", "near_any", "stretch_boxes"]

def _library() -> ctypes.CDLL | None:
    """The kernel, built and loaded once per process (``None``: unavailable or switched off)."""
    return native.kernel("boxes", {
        "hn_boxes_near": ([c_int64, c_int64, c_void_p, c_void_p, c_void_p, c_void_p, c_void_p,
                           c_double, c_void_p], None),
        "hn_stretch_boxes": ([c_int64] * 5 + [c_void_p] + [c_int64] * 3 + [c_void_p, c_void_p],
                             None),
        "hn_near_any": ([c_int64, c_void_p, c_void_p] + [c_double] * 5 + [
            c_int64, c_void_p, c_void_p, c_void_p, c_void_p], None)})


def _operands(lo, hi, o_lo, o_hi, o_pad, thr):
    """``(lib, lo, hi, o_lo, o_hi, o_pad)`` as contiguous float64 for the box kernels, or ``None``
    (shapes the kernels do not take, or no kernel)."""
    if getattr(thr, "ndim", 0) or getattr(o_lo, "ndim", 0) != 2:
        return None
    lib = _library()
    if lib is None:
        return None
    lo, hi, o_lo, o_hi, o_pad = (np.ascontiguousarray(a, dtype=np.float64)
                                 for a in (lo, hi, o_lo, o_hi, o_pad))
    K = o_lo.shape[0]
    if (lo.shape[-1:] != (2,) or hi.shape != lo.shape or o_lo.shape != (K, 2)
            or o_hi.shape != (K, 2) or o_pad.shape != (K,)):
        return None
    return lib, lo, hi, o_lo, o_hi, o_pad


def boxes_near(lo, hi, o_lo, o_hi, o_pad, thr) -> np.ndarray | None:
    """Boxes ``lo, hi`` (..., 2) against obstacle boxes ``o_lo, o_hi`` (K, 2) padded by ``o_pad``
    (K,) and a scalar ``thr``: near, (..., K); ``None`` for other shapes or without the kernel."""
    args = _operands(lo, hi, o_lo, o_hi, o_pad, thr)
    if args is None:
        return None
    lib, lo, hi, o_lo, o_hi, o_pad = args
    K, M = o_lo.shape[0], lo.size // 2
    out = np.empty((K, M), dtype=bool)              # obstacle by obstacle: a view transposed
    if M and K:
        lib.hn_boxes_near(M, K, lo.ctypes.data, hi.ctypes.data, o_lo.ctypes.data,
                          o_hi.ctypes.data, o_pad.ctypes.data, float(thr), out.ctypes.data)
    return out.T.reshape(lo.shape[:-1] + (K,))


def stretch_boxes(pts: np.ndarray, nst: int, stride: int):
    """Boxes ``lo, hi`` (na, nst, 2) of the points ``pts`` (na, samples, m, 2) of each stretch of
    ``stride`` pieces; ``None`` without the kernel or for points that are not float64 with
    adjacent coordinates."""
    if pts.dtype != np.float64 or pts.ndim != 4 or pts.shape[3] != 2:
        return None
    lib = _library()
    if lib is None:
        return None
    na, n1, m, _ = pts.shape
    lo, hi = np.empty((na, nst, 2)), np.empty((na, nst, 2))
    if not lo.size:
        return lo, hi
    st = pts.strides
    if not (n1 and m) or st[3] != 8 or min(st) < 0 or any(s % 8 for s in st):
        return None
    lib.hn_stretch_boxes(na, n1, m, nst, stride, pts.ctypes.data, st[0] // 8, st[1] // 8,
                         st[2] // 8, lo.ctypes.data, hi.ctypes.data)
    return lo, hi


def near_any(lo, hi, thr, workspace, o_lo, o_hi, o_pad) -> np.ndarray | None:
    """Whether each box ``lo, hi`` (..., 2) comes within the scalar ``thr`` of the border of
    ``workspace`` (xmin, xmax, ymin, ymax) or of one of the obstacle boxes (K, 2) padded by
    ``o_pad``: (...); ``None`` where :func:`boxes_near` would be."""
    args = _operands(lo, hi, o_lo, o_hi, o_pad, thr)
    if args is None:
        return None
    lib, lo, hi, o_lo, o_hi, o_pad = args
    K = o_lo.shape[0]
    out = np.empty(lo.shape[:-1], dtype=bool)
    if out.size:
        xmin, xmax, ymin, ymax = (float(v) for v in workspace)
        lib.hn_near_any(out.size, lo.ctypes.data, hi.ctypes.data, float(thr), xmin, xmax, ymin,
                        ymax, K, o_lo.ctypes.data, o_hi.ctypes.data, o_pad.ctypes.data,
                        out.ctypes.data)
    return out
