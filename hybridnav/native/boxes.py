"""The boxes of the swept-footprint check's pruning (``boxes.c``) bound to NumPy:
:func:`boxes_near` is :func:`hybridnav.planners.step.sweep._boxes_near` for one threshold and one
set of obstacle boxes, in one pass instead of a dozen NumPy operations over (boxes, obstacles);
:func:`near_any` is the border test and the any over the obstacles of
:meth:`~hybridnav.planners.step.sweep._Sweep._near_each` in one pass; :func:`stretch_boxes` is :func:`~hybridnav.planners.step.sweep._stretch_boxes` (exact minima and
maxima, NaN where a coordinate is NaN); :func:`disks_near` is, for every footprint disk of the
stretches the sweep checks, its box along the stretch and :func:`near_any` with its own threshold,
in one pass; :func:`reach_first` is, for one block of rollout samples, the stretch boxes and the
first sample within reach of each target (:func:`hybridnav.planners.step.sweep._reach_first`);
:func:`pieces_near` is the pruning of :meth:`~hybridnav.planners.step.sweep._Sweep.touches`
(the pieces' boxes, the border test and :func:`boxes_near`) in one pass; :func:`static_hits` is
its exact test of the (piece, static obstacle) pairs the pruning leaves (each obstacle's
:meth:`~hybridnav.world.World.segment_collides`).
The same IEEE operations in the same order: the same booleans, NaN boxes included (the tests
compare them). ``None`` where it does not apply (no compiler, kernels switched off, arrays of other
shapes), and the caller runs its NumPy path.
"""

from __future__ import annotations

from collections.abc import Callable
from ctypes import c_double, c_int64, c_void_p

import numpy as np

from hybridnav.native import pycall

__all__ = ["boxes_near", "disks_near", "near_any", "pieces_near", "reach_first",
           "static_hits", "stretch_boxes"]

#: the kernel's functions: symbol -> (argtypes, restype)
_SIGNATURES = {
    "hn_boxes_near": ([c_int64, c_int64, c_void_p, c_void_p, c_void_p, c_void_p, c_void_p,
                       c_double, c_void_p], None),
    "hn_stretch_boxes": ([c_int64] * 5 + [c_void_p] + [c_int64] * 3 + [c_void_p, c_void_p],
                         None),
    "hn_near_any": ([c_int64, c_void_p, c_void_p] + [c_double] * 5 + [
        c_int64, c_void_p, c_void_p, c_void_p, c_void_p], None),
    "hn_disks_near": ([c_int64] * 3 + [c_void_p] + [c_int64] * 3 + [c_void_p] + [c_double] * 4
                      + [c_int64] + [c_void_p] * 6, None),
    "hn_pieces_near": ([c_int64, c_void_p, c_void_p] + [c_double] * 5 + [c_int64]
                       + [c_void_p] * 7, None),
    "hn_reach_first": ([c_int64] * 4 + [c_void_p, c_int64, c_int64, c_void_p, c_double,
                        c_double, c_void_p, c_void_p, c_void_p], None),
    "hn_static_hits": ([c_int64, c_void_p, c_void_p, c_void_p, c_double] + [c_void_p] * 9,
                       None)}


def _library() -> dict[str, Callable] | None:
    """The kernel's functions by symbol, built and loaded once per process (``None``:
    unavailable or switched off; :func:`hybridnav.native.pycall.functions`)."""
    return pycall.functions("boxes", _SIGNATURES)


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
        lib["hn_boxes_near"](M, K, lo, hi, o_lo, o_hi, o_pad, float(thr), out)
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
    lib["hn_stretch_boxes"](na, n1, m, nst, stride, pts, st[0] // 8, st[1] // 8, st[2] // 8,
                            lo, hi)
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
        lib["hn_near_any"](out.size, lo, hi, float(thr), xmin, xmax, ymin, ymax, K, o_lo, o_hi,
                           o_pad, out)
    return out


def _strides(a: np.ndarray) -> tuple[int, ...] | None:
    """The element strides of a float64 array whose last axis is adjacent, else ``None`` (an
    empty array: zeros, nothing is read)."""
    st = a.strides
    if a.dtype == np.float64 and not a.size:
        return (0,) * a.ndim
    if a.dtype != np.float64 or (a.shape[-1] > 1 and st[-1] != 8) or min(st) < 0 or any(
            s % 8 for s in st):
        return None
    return tuple(s // 8 for s in st)


def disks_near(C: np.ndarray, thr: np.ndarray, workspace, o_lo, o_hi, o_pad):
    """For the footprint disk centres ``C`` (ns, samples, nd, 2) along ``ns`` stretches: each
    disk's box ``lo, hi`` (ns, nd, 2) over the samples and whether the border or an obstacle box
    (K, 2) padded by ``o_pad`` may come within ``thr[j]`` of disk ``j``'s box, (ns, nd): for
    every disk :func:`stretch_boxes` of one stretch and :func:`near_any`. ``None`` without the
    kernel or for other shapes."""
    if C.ndim != 4 or C.shape[3] != 2 or not C.shape[1]:
        return None
    args = _operands(np.empty((0, 2)), np.empty((0, 2)), o_lo, o_hi, o_pad, 0.0)
    st = _strides(C)
    if args is None or st is None:
        return None
    lib, _, _, o_lo, o_hi, o_pad = args
    ns, n1, nd, _ = C.shape
    thr = np.ascontiguousarray(thr, dtype=np.float64)
    if thr.shape != (nd,):
        return None
    lo, hi = np.empty((ns, nd, 2)), np.empty((ns, nd, 2))
    out = np.empty((ns, nd), dtype=bool)
    if out.size:
        xmin, xmax, ymin, ymax = (float(v) for v in workspace)
        lib["hn_disks_near"](ns, n1, nd, C, st[0], st[1], st[2], thr, xmin, xmax, ymin, ymax,
                             o_lo.shape[0], o_lo, o_hi, o_pad, lo, hi, out)
    return lo, hi, out


def reach_first(traj: np.ndarray, P: np.ndarray, nst: int, stride: int, reach: float,
                reach2: float):
    """For rollout samples ``traj`` (na, n1, nx) towards the targets ``P`` (na, 2): the boxes
    ``lo, hi`` (na, nst, 2) of the positions along each stretch of ``stride`` pieces, and per
    row the first of the samples ``1 ..`` within ``reach`` of its target, minus one (-1: none;
    only looked for where a box comes within ``reach2``). ``None`` without the kernel or for
    other arrays."""
    if traj.ndim != 3 or traj.shape[2] < 2 or not traj.shape[1]:
        return None
    lib = _library()
    st = _strides(traj)
    if lib is None or st is None:
        return None
    na, n1, _ = traj.shape
    P = np.ascontiguousarray(P, dtype=np.float64)
    if P.shape != (na, 2):
        return None
    lo, hi = np.empty((na, nst, 2)), np.empty((na, nst, 2))
    first = np.empty(na, dtype=np.int64)
    if na:
        lib["hn_reach_first"](na, n1, nst, stride, traj, st[0], st[1], P, float(reach),
                              float(reach2), lo, hi, first)
    return lo, hi, first


def pieces_near(A: np.ndarray, B: np.ndarray, thr: float, workspace, o_lo, o_hi, o_pad):
    """For the pieces ``A -> B`` (M, 2 each): their boxes ``lo, hi`` (``np.minimum``,
    ``np.maximum``), whether each comes within the scalar ``thr`` of the border of
    ``workspace`` (M,) and of each obstacle box (K, 2) padded by ``o_pad`` (M, K), as
    :func:`near_any` and :func:`boxes_near` test them; ``None`` without the kernel or for other
    shapes."""
    A = np.ascontiguousarray(A, dtype=np.float64)
    B = np.ascontiguousarray(B, dtype=np.float64)
    if A.ndim != 2 or A.shape[1:] != (2,) or B.shape != A.shape:
        return None
    args = _operands(A, B, o_lo, o_hi, o_pad, thr)
    if args is None:
        return None
    lib, A, B, o_lo, o_hi, o_pad = args
    M, K = len(A), len(o_lo)
    lo, hi = np.empty((M, 2)), np.empty((M, 2))
    border, out = np.empty(M, dtype=bool), np.empty((K, M), dtype=bool)
    if M:
        xmin, xmax, ymin, ymax = (float(v) for v in workspace)
        lib["hn_pieces_near"](M, A, B, float(thr), xmin, xmax, ymin, ymax, K, o_lo, o_hi, o_pad,
                              lo, hi, border, out)
    return lo, hi, border, out.T


def _packed(world):
    """A static world's obstacles as :func:`static_hits` reads them (built once per world)."""
    views = world.__dict__.setdefault("_views", {})
    if "static_hits" not in views:
        K = len(world.obstacles)
        ccol = np.full(K, -1, dtype=np.int64)
        ccol[world._c_idx] = np.arange(world._c_idx.size)
        gcol = np.full(K, -1, dtype=np.int64)
        gcol[world._g_idx] = np.arange(world._g_idx.size)
        gstart = np.append(world._g_start, len(world._eA)).astype(np.int64)
        views["static_hits"] = (
            ccol, gcol, np.ascontiguousarray(world._c0, dtype=np.float64).reshape(-1, 2),
            np.ascontiguousarray(world._cr, dtype=np.float64),
            np.ascontiguousarray(world._eA, dtype=np.float64).reshape(-1, 2),
            np.ascontiguousarray(world._eB, dtype=np.float64).reshape(-1, 2), gstart,
            np.ascontiguousarray(world._g_closed, dtype=np.uint8))
    return views["static_hits"]


def static_hits(world, A: np.ndarray, B: np.ndarray, obstacle: np.ndarray,
                radius: float) -> np.ndarray | None:
    """Whether the move ``A[i] -> B[i]`` (a disk of ``radius``) hits obstacle ``obstacle[i]``
    of ``world`` (static obstacles only): ``world.singles()[obstacle[i]].segment_collides`` for
    each pair, the same booleans (the same IEEE operations in the same order), in one pass.
    ``None`` without the kernel, for moving circles or other shapes."""
    lib = _library()
    if lib is None or world._c_moving:
        return None
    A = np.ascontiguousarray(A, dtype=np.float64)
    B = np.ascontiguousarray(B, dtype=np.float64)
    obstacle = np.ascontiguousarray(obstacle, dtype=np.int64)
    if A.ndim != 2 or A.shape[1:] != (2,) or B.shape != A.shape or obstacle.shape != (len(A),):
        return None
    out = np.zeros(len(A), dtype=bool)
    if len(A):
        if obstacle.min() < 0 or obstacle.max() >= len(world.obstacles):
            raise IndexError("static_hits: obstacle index out of range")
        lib["hn_static_hits"](len(A), A, B, obstacle, float(radius), *_packed(world), out)
    return out
