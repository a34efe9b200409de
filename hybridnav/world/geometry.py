"""Geometry kernels: distances between points, segments and convex polygons, broadcasting over
arrays (implemented once, used by every obstacle and by :class:`~hybridnav.world.World`)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError

__all__ = ["point_segment_distance", "points_in_convex_polygon", "segment_segment_distance"]

FloatArray = NDArray[np.float64]


def _points(P: ArrayLike, name: str = "P") -> FloatArray:
    """Return ``P`` as a float ``(N, 2)`` array (a ``(2,)`` point becomes ``(1, 2)``)."""
    arr = np.asarray(P, dtype=float)
    if arr.ndim == 1 and arr.shape[0] == 2:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise HybridnavError(f"{name}: expected an (N, 2) array of points, got shape {arr.shape}")
    return arr


def _cross(u: FloatArray, v: FloatArray) -> FloatArray:
    """z component of the 2-D cross product, broadcasting over leading axes."""
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _project(P: FloatArray, A: FloatArray, B: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Distance from points to segments and the nearest segment points (broadcasting)."""
    AB = B - A
    AP = P - A
    den = np.sum(AB * AB, axis=-1)
    num = np.sum(AP * AB, axis=-1)
    safe = den > 0.0
    s = np.where(safe, num / np.where(safe, den, 1.0), 0.0)
    s = np.clip(s, 0.0, 1.0)
    Q = A + s[..., None] * AB
    D = P - Q
    return np.hypot(D[..., 0], D[..., 1]), Q


def point_segment_distance(
    P: ArrayLike, A: ArrayLike, B: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Distance from points to segments, and the nearest points on the segments.

    Parameters
    ----------
    P, A, B : array_like, shape (..., 2)
        Points and segment end points; the leading axes broadcast against each other.
        Zero-length segments (``A == B``) are allowed and act as points.

    Returns
    -------
    dist : ndarray, shape (...)
        Euclidean distance from each point to its segment.
    nearest : ndarray, shape (..., 2)
        The nearest point on the segment.
    """
    return _project(np.asarray(P, float), np.asarray(A, float), np.asarray(B, float))


def _seg_seg(P0: FloatArray, P1: FloatArray, Q0: FloatArray, Q1: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Segment-segment distance and whether the segments cross properly (interiors cross)."""
    d = np.minimum(
        np.minimum(_project(P0, Q0, Q1)[0], _project(P1, Q0, Q1)[0]),
        np.minimum(_project(Q0, P0, P1)[0], _project(Q1, P0, P1)[0]),
    )
    dp = P1 - P0
    dq = Q1 - Q0
    o1 = _cross(dp, Q0 - P0)
    o2 = _cross(dp, Q1 - P0)
    o3 = _cross(dq, P0 - Q0)
    o4 = _cross(dq, P1 - Q0)
    proper = ((o1 > 0) & (o2 < 0) | (o1 < 0) & (o2 > 0)) & ((o3 > 0) & (o4 < 0) | (o3 < 0) & (o4 > 0))
    return np.where(proper, 0.0, d), proper


def segment_segment_distance(
    P0: ArrayLike, P1: ArrayLike, Q0: ArrayLike, Q1: ArrayLike
) -> FloatArray:
    """Minimum distance between segments ``P0-P1`` and ``Q0-Q1`` (broadcasting).

    Parameters
    ----------
    P0, P1, Q0, Q1 : array_like, shape (..., 2)
        End points; leading axes broadcast. Zero-length segments are allowed.

    Returns
    -------
    ndarray, shape (...)
        Zero where the segments intersect (or touch), otherwise the smallest of the four
        end-point-to-segment distances (the minimum of two non-intersecting segments is always
        attained at an end point).
    """
    P0, P1, Q0, Q1 = (np.asarray(a, float) for a in (P0, P1, Q0, Q1))
    return _seg_seg(P0, P1, Q0, Q1)[0]


def _through_interior(
    A: FloatArray, B: FloatArray, eA: FloatArray, eB: FloatArray, starts: NDArray[np.int_]
) -> NDArray[np.bool_]:
    """Whether segments A[i]-B[i] meet the open interior of convex CCW polygons (Cyrus-Beck).

    ``eA``/``eB`` are the polygons' edges packed one polygon after another, ``starts`` the index
    of each polygon's first edge. Returns (N, G). Exact: the segment's parameter interval where
    it is strictly on the inner side of every edge must be non-empty.
    """
    E = (eB - eA)[None]                      # (1, E, 2)
    num = _cross(E, A[:, None, :] - eA[None])  # (N, E): f(0)
    den = _cross(E, (B - A)[:, None, :])       # (N, E): f'(s)
    with np.errstate(divide="ignore", invalid="ignore"):
        root = -num / den
    lo = np.where(den > 0, root, -np.inf)
    hi = np.where(den < 0, root, np.inf)
    dead = (den == 0) & (num <= 0)
    lo = np.maximum(np.maximum.reduceat(lo, starts, axis=1), 0.0)
    hi = np.minimum(np.minimum.reduceat(hi, starts, axis=1), 1.0)
    dead = np.logical_or.reduceat(dead, starts, axis=1)
    return (lo < hi) & ~dead


def _convex_turns(V: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Cross and dot products of consecutive edges of the closed polygon ``V`` (M, 2)."""
    E = np.roll(V, -1, axis=0) - V
    En = np.roll(E, -1, axis=0)
    return _cross(E, En), np.sum(E * En, axis=-1)


def _ccw_convex(points: ArrayLike) -> FloatArray:
    """Validate a convex polygon and return its vertices counter-clockwise.

    Raises
    ------
    HybridnavError
        Fewer than 3 points, repeated consecutive points, zero area, non-convex, or
        self-intersecting (winding more than once).
    """
    V = np.asarray(points, dtype=float)
    if V.ndim != 2 or V.shape[1] != 2:
        raise HybridnavError(f"expected a list of [x, y] points, got shape {V.shape}")
    if V.shape[0] < 3:
        raise HybridnavError(f"expected at least 3 points, got {V.shape[0]}")
    E = np.roll(V, -1, axis=0) - V
    if np.any(np.hypot(E[:, 0], E[:, 1]) == 0.0):
        raise HybridnavError("expected distinct consecutive points (a repeated point was found)")
    area2 = float(np.sum(_cross(V, np.roll(V, -1, axis=0))))
    scale = float(np.max(np.abs(V - V.mean(axis=0)))) or 1.0
    if abs(area2) <= 1e-12 * scale * scale:
        spread = _cross(V - V[0], np.roll(V, -1, axis=0) - V[0])
        if np.all(np.abs(spread) <= 1e-12 * scale * scale):
            raise HybridnavError("expected a polygon with non-zero area (points are collinear)")
        raise HybridnavError("expected a convex polygon, got a self-intersecting outline "
                             "(e.g. a bow tie) whose parts cancel to zero area")
    if area2 < 0:
        V = V[::-1].copy()
    cr, dt = _convex_turns(V)
    tol = 1e-12 * scale * scale
    turning = float(np.sum(np.arctan2(cr, dt)))
    if np.any(cr < -tol) or abs(turning - 2.0 * math.pi) > 1e-6:
        raise HybridnavError("expected a convex polygon (points in clockwise or counter-clockwise order)")
    return V


def points_in_convex_polygon(P: ArrayLike, vertices: ArrayLike) -> NDArray[np.bool_]:
    """Whether points lie in a convex polygon (boundary included).

    Parameters
    ----------
    P : array_like, shape (N, 2)
        Query points.
    vertices : array_like, shape (M, 2)
        Convex polygon, either orientation.

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    V = _ccw_convex(vertices)
    P = _points(P)
    W = np.roll(V, -1, axis=0)
    cr = _cross((W - V)[None, :, :], P[:, None, :] - V[None, :, :])
    return np.all(cr >= 0.0, axis=1)




def _nearest_on_circle(P: FloatArray, C: FloatArray, R: FloatArray) -> FloatArray:
    """Row-wise nearest points: P (N,2), C (N,2), R (N,) -> (N,2)."""
    D = P - C
    n = np.hypot(D[:, 0], D[:, 1])
    zero = n == 0.0
    U = np.where(zero[:, None], np.array([1.0, 0.0]), D / np.where(zero, 1.0, n)[:, None])
    return C + R[:, None] * U
