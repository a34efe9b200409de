"""Workspaces, obstacles, robots and scenarios.

This module holds the geometry every planner and model shares:

* obstacle shapes (:class:`Circle`, :class:`Segment`, :class:`Rectangle`, :class:`Polygon`,
  :class:`MovingCircle`) with vectorized signed-distance (``clearance``) and nearest-point queries;
* :class:`World`: a rectangular workspace plus obstacles, with queries vectorized over ``(N, 2)``
  point arrays *and* over obstacles (obstacles are packed into arrays once, at construction);
* :class:`Robot` and :class:`Scenario`, and the TOML loader :func:`load_scenario` with validation
  (:func:`scenario_from_dict`) and its inverse :func:`scenario_to_dict`.

Conventions
-----------
* Points are ``(N, 2)`` float arrays of ``(x, y)``; a single ``(2,)`` point is accepted and treated
  as ``N = 1`` (results are still ``(1,)`` / ``(1, 2)``).
* ``clearance`` is a signed distance: positive outside an obstacle, zero on its surface, negative
  inside. A :class:`Segment` has no inside, so its clearance is the (never negative) distance.
* A disk of radius ``r`` centred at ``p`` *collides* when ``clearance(p) < r``: touching is not a
  collision. Collision queries concern obstacles only; leaving the workspace is a separate question
  (:meth:`World.inside_workspace`, :meth:`World.border_clearance`).
* Moving circles move linearly, ``x(t) = x0 + v cos(heading) t``, ``y(t) = y0 + v sin(heading) t``;
  :class:`World` queries take the time ``t`` (a scalar, or one time per point).
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError, where
from hybridnav.fileio import atomic_write_text

__all__ = [
    "MODEL_NAMES",
    "OBSTACLE_TYPES",
    "Circle",
    "Segment",
    "Rectangle",
    "Polygon",
    "MovingCircle",
    "Obstacle",
    "World",
    "Robot",
    "GridSpec",
    "Scenario",
    "point_segment_distance",
    "segment_segment_distance",
    "points_in_convex_polygon",
    "load_scenario",
    "scenario_from_dict",
    "scenario_to_dict",
    "scenario_to_toml",
    "save_scenario",
    "list_scenarios",
    "builtin_data_path",
    "toml_dumps",
]

log = logging.getLogger(__name__)

#: Robot model names a scenario may use; the model registry (``hybridnav.models``) must match.
MODEL_NAMES: tuple[str, ...] = ("point_mass", "tractor_trailer", "unicycle")

#: Obstacle ``type`` values of the TOML schema.
OBSTACLE_TYPES: tuple[str, ...] = ("circle", "segment", "rectangle", "polygon", "moving_circle")

_SCENARIO_PACKAGE = "hybridnav.scenarios"

FloatArray = NDArray[np.float64]


# --------------------------------------------------------------------------------------------
# Geometry kernels (broadcasting; implemented once, used by every obstacle and by World)
# --------------------------------------------------------------------------------------------


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
        raise HybridnavError("expected a polygon with non-zero area (points are collinear)")
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


# --------------------------------------------------------------------------------------------
# Obstacles
# --------------------------------------------------------------------------------------------


def _pt(value: Any, what: str) -> tuple[float, float]:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise HybridnavError(f"{what}: expected a finite point [x, y], got {value!r}")
    return (float(arr[0]), float(arr[1]))


def _finite(value: Any, what: str) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise HybridnavError(f"{what}: expected a finite number, got {value!r}")
    return v


class _EdgeShape:
    """Mixin for obstacles made of edges (segments and convex polygons)."""

    _A: FloatArray
    _B: FloatArray
    _closed: bool

    def clearance(self, P: ArrayLike) -> FloatArray:
        """Signed distance from points to the surface (negative inside).

        Parameters
        ----------
        P : array_like, shape (N, 2)

        Returns
        -------
        ndarray, shape (N,)
        """
        return self._query(_points(P))[0]

    def nearest(self, P: ArrayLike) -> FloatArray:
        """Nearest surface point to each point.

        Parameters
        ----------
        P : array_like, shape (N, 2)

        Returns
        -------
        ndarray, shape (N, 2)
        """
        return self._query(_points(P))[1]

    def _query(self, P: FloatArray) -> tuple[FloatArray, FloatArray]:
        d, Q = _project(P[:, None, :], self._A[None], self._B[None])
        k = np.argmin(d, axis=1)
        rows = np.arange(P.shape[0])
        dist = d[rows, k]
        if self._closed:
            cr = _cross((self._B - self._A)[None], P[:, None, :] - self._A[None])
            dist = np.where(np.all(cr > 0.0, axis=1), -dist, dist)
        return dist, Q[rows, k]


@dataclass(frozen=True)
class Circle:
    """A solid disk.

    Parameters
    ----------
    center : (float, float)
    radius : float
        Positive.
    """

    center: tuple[float, float]
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _pt(self.center, "center"))
        r = _finite(self.radius, "radius")
        if r <= 0:
            raise HybridnavError(f"radius: expected a positive number, got {self.radius!r}")
        object.__setattr__(self, "radius", r)

    def clearance(self, P: ArrayLike) -> FloatArray:
        """Signed distance from points to the circle (negative inside).

        Parameters
        ----------
        P : array_like, shape (N, 2)

        Returns
        -------
        ndarray, shape (N,)
        """
        D = _points(P) - np.asarray(self.center)
        return np.hypot(D[:, 0], D[:, 1]) - self.radius

    def nearest(self, P: ArrayLike) -> FloatArray:
        """Nearest point on the circle (for the centre itself, the point at angle 0).

        Parameters
        ----------
        P : array_like, shape (N, 2)

        Returns
        -------
        ndarray, shape (N, 2)
        """
        P = _points(P)
        C = np.broadcast_to(np.asarray(self.center), P.shape)
        return _nearest_on_circle(P, C, np.full(P.shape[0], self.radius))


@dataclass(frozen=True)
class Segment(_EdgeShape):
    """A line obstacle (a wall of zero thickness) from ``a`` to ``b``.

    Parameters
    ----------
    a, b : (float, float)
        Distinct end points.
    """

    a: tuple[float, float]
    b: tuple[float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", _pt(self.a, "a"))
        object.__setattr__(self, "b", _pt(self.b, "b"))
        if self.a == self.b:
            raise HybridnavError(f"b: expected a point different from a (zero-length segment at {self.a})")
        object.__setattr__(self, "_A", np.asarray([self.a]))
        object.__setattr__(self, "_B", np.asarray([self.b]))
        object.__setattr__(self, "_closed", False)


@dataclass(frozen=True)
class Polygon(_EdgeShape):
    """A solid convex polygon.

    Parameters
    ----------
    points : sequence of (float, float)
        At least 3 vertices of a convex polygon, clockwise or counter-clockwise. They are kept as
        given; :attr:`vertices` holds them counter-clockwise.
    """

    points: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        pts = tuple(_pt(p, f"points[{i}]") for i, p in enumerate(self.points))
        object.__setattr__(self, "points", pts)
        V = _ccw_convex(pts)
        object.__setattr__(self, "_A", V)
        object.__setattr__(self, "_B", np.roll(V, -1, axis=0))
        object.__setattr__(self, "_closed", True)

    @property
    def vertices(self) -> FloatArray:
        """Vertices in counter-clockwise order, shape (M, 2)."""
        return self._A.copy()


@dataclass(frozen=True)
class Rectangle(_EdgeShape):
    """A solid axis-aligned rectangle ``[min[0], max[0]] x [min[1], max[1]]``.

    Parameters
    ----------
    min, max : (float, float)
        Lower-left and upper-right corners; ``min < max`` in both coordinates.
    """

    min: tuple[float, float]
    max: tuple[float, float]

    def __post_init__(self) -> None:
        lo = _pt(self.min, "min")
        hi = _pt(self.max, "max")
        if not (lo[0] < hi[0] and lo[1] < hi[1]):
            raise HybridnavError(f"max: expected max > min in both coordinates, got min={lo}, max={hi}")
        object.__setattr__(self, "min", lo)
        object.__setattr__(self, "max", hi)
        V = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
        object.__setattr__(self, "_A", V)
        object.__setattr__(self, "_B", np.roll(V, -1, axis=0))
        object.__setattr__(self, "_closed", True)

    @property
    def vertices(self) -> FloatArray:
        """Corners in counter-clockwise order from ``min``, shape (4, 2)."""
        return self._A.copy()

    def to_polygon(self) -> Polygon:
        """The same rectangle as a :class:`Polygon`."""
        return Polygon(tuple(map(tuple, self._A)))


@dataclass(frozen=True)
class MovingCircle:
    """A disk moving at constant velocity.

    Parameters
    ----------
    center : (float, float)
        Centre at ``t = 0``.
    radius : float
        Positive.
    velocity : float
        Speed (non-negative), in workspace units per second.
    heading : float
        Direction of motion, radians from the x axis.
    """

    center: tuple[float, float]
    radius: float
    velocity: float
    heading: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _pt(self.center, "center"))
        r = _finite(self.radius, "radius")
        if r <= 0:
            raise HybridnavError(f"radius: expected a positive number, got {self.radius!r}")
        v = _finite(self.velocity, "velocity")
        if v < 0:
            raise HybridnavError(f"velocity: expected a non-negative speed, got {self.velocity!r}")
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "velocity", v)
        object.__setattr__(self, "heading", _finite(self.heading, "heading"))

    @property
    def velocity_vector(self) -> FloatArray:
        """``(vx, vy)``, shape (2,)."""
        return self.velocity * np.array([math.cos(self.heading), math.sin(self.heading)])

    def center_at(self, t: ArrayLike) -> FloatArray:
        """Centre at time(s) ``t``: shape (2,) for a scalar, (N, 2) for N times."""
        t = np.asarray(t, dtype=float)
        return np.asarray(self.center) + t[..., None] * self.velocity_vector

    def at(self, t: float) -> Circle:
        """The :class:`Circle` occupied at time ``t``."""
        c = self.center_at(float(t))
        return Circle((float(c[0]), float(c[1])), self.radius)

    def clearance(self, P: ArrayLike, t: ArrayLike = 0.0) -> FloatArray:
        """Signed distance from points to the circle at time ``t`` (scalar or one per point).

        Parameters
        ----------
        P : array_like, shape (N, 2)
        t : float or array_like, shape (N,)

        Returns
        -------
        ndarray, shape (N,)
        """
        P = _points(P)
        D = P - np.broadcast_to(self.center_at(t), P.shape)
        return np.hypot(D[:, 0], D[:, 1]) - self.radius

    def nearest(self, P: ArrayLike, t: ArrayLike = 0.0) -> FloatArray:
        """Nearest point on the circle at time ``t``.

        Parameters
        ----------
        P : array_like, shape (N, 2)
        t : float or array_like, shape (N,)

        Returns
        -------
        ndarray, shape (N, 2)
        """
        P = _points(P)
        C = np.broadcast_to(self.center_at(t), P.shape)
        return _nearest_on_circle(P, C, np.full(P.shape[0], self.radius))


Obstacle = Union[Circle, Segment, Rectangle, Polygon, MovingCircle]

_TYPE_OF = {Circle: "circle", Segment: "segment", Rectangle: "rectangle", Polygon: "polygon",
            MovingCircle: "moving_circle"}


# --------------------------------------------------------------------------------------------
# World
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class World:
    """A rectangular workspace with obstacles and vectorized geometric queries.

    Parameters
    ----------
    workspace : (xmin, xmax, ymin, ymax)
        ``xmin < xmax`` and ``ymin < ymax``.
    obstacles : sequence of obstacles
        :class:`Circle`, :class:`Segment`, :class:`Rectangle`, :class:`Polygon`,
        :class:`MovingCircle`. Obstacle indices returned by queries refer to this sequence.

    Notes
    -----
    At construction the obstacles are packed into arrays: all circles (static and moving) as
    centres/radii, and all segment and polygon edges as one edge list grouped per obstacle, so each
    query is a handful of broadcast numpy operations over ``(N, obstacles)``.
    With no obstacles, clearances are ``+inf`` and nearest indices ``-1``.
    """

    workspace: tuple[float, float, float, float]
    obstacles: tuple[Obstacle, ...] = ()

    def __post_init__(self) -> None:
        ws = tuple(_finite(v, f"workspace[{i}]") for i, v in enumerate(self.workspace))
        if len(ws) != 4:
            raise HybridnavError(f"workspace: expected (xmin, xmax, ymin, ymax), got {self.workspace!r}")
        if not (ws[0] < ws[1] and ws[2] < ws[3]):
            raise HybridnavError(f"workspace: expected xmin < xmax and ymin < ymax, got {ws}")
        object.__setattr__(self, "workspace", ws)
        obs = tuple(self.obstacles)
        for i, o in enumerate(obs):
            if type(o) not in _TYPE_OF:
                raise HybridnavError(f"obstacles[{i}]: expected an obstacle object, got {type(o).__name__}")
        object.__setattr__(self, "obstacles", obs)
        self._pack()

    # -- packing ------------------------------------------------------------------------------

    def _pack(self) -> None:
        circ_idx, circ_c, circ_r, circ_v = [], [], [], []
        eA, eB, owner, starts, gidx, closed = [], [], [], [], [], []
        for i, o in enumerate(self.obstacles):
            if isinstance(o, (Circle, MovingCircle)):
                circ_idx.append(i)
                circ_c.append(o.center)
                circ_r.append(o.radius)
                circ_v.append(o.velocity_vector if isinstance(o, MovingCircle) else np.zeros(2))
            else:
                starts.append(len(eA))
                gidx.append(i)
                closed.append(o._closed)
                for a, b in zip(o._A, o._B):
                    eA.append(a)
                    eB.append(b)
                    owner.append(i)
        s = object.__setattr__
        s(self, "_c_idx", np.asarray(circ_idx, dtype=int))
        s(self, "_c0", np.asarray(circ_c, dtype=float).reshape(-1, 2))
        s(self, "_cr", np.asarray(circ_r, dtype=float))
        s(self, "_cv", np.asarray(circ_v, dtype=float).reshape(-1, 2))
        s(self, "_c_moving", bool(np.any(self._cv != 0.0)))
        s(self, "_eA", np.asarray(eA, dtype=float).reshape(-1, 2))
        s(self, "_eB", np.asarray(eB, dtype=float).reshape(-1, 2))
        s(self, "_e_owner", np.asarray(owner, dtype=int))
        s(self, "_g_start", np.asarray(starts, dtype=int))
        s(self, "_g_idx", np.asarray(gidx, dtype=int))
        s(self, "_g_closed", np.asarray(closed, dtype=bool))
        is_circle = np.zeros(len(self.obstacles), dtype=bool)
        is_circle[self._c_idx] = True
        col = np.full(len(self.obstacles), -1, dtype=int)
        col[self._c_idx] = np.arange(len(circ_idx))
        s(self, "_is_circle", is_circle)
        s(self, "_circle_col", col)

    def _centers(self, t: ArrayLike, n: int) -> FloatArray:
        """Circle centres at time t: (1, C, 2) for a scalar time, (N, C, 2) for per-point times."""
        t = np.asarray(t, dtype=float)
        if not self._c_moving or t.ndim == 0:
            return (self._c0 + float(t) * self._cv)[None] if self._c_moving else self._c0[None]
        if t.shape != (n,):
            raise HybridnavError(f"t: expected a scalar or an array of shape ({n},), got {t.shape}")
        return self._c0[None] + t[:, None, None] * self._cv[None]

    def _per_obstacle(self, P: FloatArray, t: ArrayLike, want_points: bool = False):
        """Signed distance to every obstacle, (N, K); optionally the edge projections."""
        n, k = P.shape[0], len(self.obstacles)
        D = np.empty((n, k))
        C = None
        if self._c_idx.size:
            C = self._centers(t, n)
            diff = P[:, None, :] - C
            D[:, self._c_idx] = np.hypot(diff[..., 0], diff[..., 1]) - self._cr[None]
        de = Qe = None
        if self._g_idx.size:
            de, Qe = _project(P[:, None, :], self._eA[None], self._eB[None])
            dmin = np.minimum.reduceat(de, self._g_start, axis=1)
            cr = _cross((self._eB - self._eA)[None], P[:, None, :] - self._eA[None])
            inside = (np.minimum.reduceat(cr, self._g_start, axis=1) > 0.0) & self._g_closed[None]
            D[:, self._g_idx] = np.where(inside, -dmin, dmin)
        if want_points:
            return D, C, de, Qe
        return D

    # -- queries ------------------------------------------------------------------------------

    def clearance(self, P: ArrayLike, t: ArrayLike = 0.0, radius: float = 0.0) -> FloatArray:
        """Signed clearance to the nearest obstacle surface, minus ``radius``.

        Parameters
        ----------
        P : array_like, shape (N, 2)
            Points.
        t : float or array_like, shape (N,)
            Time at which moving circles are evaluated (one time for all points, or one per point).
        radius : float
            Footprint radius subtracted from the distance.

        Returns
        -------
        ndarray, shape (N,)
            Negative when a disk of ``radius`` at the point overlaps an obstacle; ``+inf`` when
            the world has no obstacles.
        """
        P = _points(P)
        if not self.obstacles:
            return np.full(P.shape[0], np.inf)
        return np.min(self._per_obstacle(P, t), axis=1) - float(radius)

    def nearest(self, P: ArrayLike, t: ArrayLike = 0.0) -> tuple[FloatArray, FloatArray, NDArray[np.int_]]:
        """Nearest obstacle surface point.

        Parameters
        ----------
        P : array_like, shape (N, 2)
        t : float or array_like, shape (N,)
            Time for moving circles.

        Returns
        -------
        clearance : ndarray, shape (N,)
            Signed distance to the nearest obstacle (as :meth:`clearance` with ``radius=0``).
        point : ndarray, shape (N, 2)
            Nearest point on that obstacle's surface.
        index : ndarray of int, shape (N,)
            Index into :attr:`obstacles` (``-1`` and NaN points for a world without obstacles).
        """
        P = _points(P)
        n = P.shape[0]
        if not self.obstacles:
            return np.full(n, np.inf), np.full((n, 2), np.nan), np.full(n, -1, dtype=int)
        D, C, de, Qe = self._per_obstacle(P, t, want_points=True)
        idx = np.argmin(D, axis=1)
        rows = np.arange(n)
        clear = D[rows, idx]
        near = np.empty((n, 2))
        is_c = self._is_circle[idx]
        if np.any(is_c):
            sel = np.nonzero(is_c)[0]
            cols = self._circle_col[idx[sel]]
            Cs = C[0, cols] if C.shape[0] == 1 else C[sel, cols]
            near[sel] = _nearest_on_circle(P[sel], Cs, self._cr[cols])
        if not np.all(is_c):
            sel = np.nonzero(~is_c)[0]
            masked = np.where(self._e_owner[None, :] == idx[sel, None], de[sel], np.inf)
            e = np.argmin(masked, axis=1)
            near[sel] = Qe[sel, e]
        return clear, near, idx

    def nearest_each(self, P: ArrayLike, t: ArrayLike = 0.0) -> tuple[FloatArray, FloatArray]:
        """Signed clearance to, and nearest surface point on, every obstacle.

        Returns
        -------
        clearance : ndarray, shape (N, K)
        point : ndarray, shape (N, K, 2)
        """
        P = _points(P)
        n, k = P.shape[0], len(self.obstacles)
        if not k:
            return np.zeros((n, 0)), np.zeros((n, 0, 2))
        D, C, de, Qe = self._per_obstacle(P, t, want_points=True)
        near = np.empty((n, k, 2))
        if self._c_idx.size:
            Cb = np.broadcast_to(C, (n,) + C.shape[1:])
            nc = Cb.shape[1]
            pts = _nearest_on_circle(np.repeat(P, nc, axis=0), Cb.reshape(-1, 2),
                                     np.tile(self._cr, n))
            near[:, self._c_idx] = pts.reshape(n, nc, 2)
        if self._g_idx.size:
            ends = np.append(self._g_start[1:], de.shape[1])
            for col, (a, b) in zip(self._g_idx, zip(self._g_start, ends)):
                e = a + np.argmin(de[:, a:b], axis=1)
                near[:, col] = Qe[np.arange(n), e]
        return D, near

    def border_clearance(self, P: ArrayLike) -> FloatArray:
        """Signed distance to the workspace boundary: positive inside, negative outside.

        Parameters
        ----------
        P : array_like, shape (N, 2)

        Returns
        -------
        ndarray, shape (N,)
            Inside: distance to the nearest side. Outside: minus the Euclidean distance to the
            workspace rectangle.
        """
        P = _points(P)
        xmin, xmax, ymin, ymax = self.workspace
        dx_in = np.minimum(P[:, 0] - xmin, xmax - P[:, 0])
        dy_in = np.minimum(P[:, 1] - ymin, ymax - P[:, 1])
        inside = np.minimum(dx_in, dy_in)
        dx = np.maximum(0.0, -dx_in)
        dy = np.maximum(0.0, -dy_in)
        return np.where(inside >= 0.0, inside, -np.hypot(dx, dy))

    def inside_workspace(self, P: ArrayLike, radius: float = 0.0) -> NDArray[np.bool_]:
        """Whether a disk of ``radius`` at each point lies inside the workspace (touching allowed).

        Parameters
        ----------
        P : array_like, shape (N, 2)
        radius : float

        Returns
        -------
        ndarray of bool, shape (N,)
        """
        return self.border_clearance(P) >= float(radius)

    def collides(self, P: ArrayLike, radius: float = 0.0, t: ArrayLike = 0.0) -> NDArray[np.bool_]:
        """Whether a disk of ``radius`` at each point overlaps an obstacle at time ``t``.

        Touching (clearance exactly ``radius``) is not a collision. The workspace border is not
        an obstacle here (see :meth:`inside_workspace`).

        Parameters
        ----------
        P : array_like, shape (N, 2)
        radius : float
        t : float or array_like, shape (N,)

        Returns
        -------
        ndarray of bool, shape (N,)
        """
        return self.clearance(P, t=t, radius=radius) < 0.0

    def segment_collides(
        self, A: ArrayLike, B: ArrayLike, radius: float = 0.0, t: ArrayLike = 0.0
    ) -> NDArray[np.bool_]:
        """Whether a disk of ``radius`` swept along ``A[i] -> B[i]`` overlaps an obstacle.

        Exact for the obstacles as they are at time ``t`` (moving circles are frozen at ``t``
        for the whole move): the swept disk overlaps an obstacle when the distance from the segment
        to the solid obstacle is less than ``radius`` (point-to-segment distance for circles,
        segment-to-segment distance for segment obstacles and polygon edges), when the move crosses
        a segment obstacle or polygon edge, or when it meets a polygon's interior (Cyrus-Beck
        clipping, which also covers moves entirely inside a polygon). As for points, merely
        touching is not a collision.

        Parameters
        ----------
        A, B : array_like, shape (N, 2)
            Start and end points of the moves.
        radius : float
            Footprint radius.
        t : float or array_like, shape (N,)
            Time at which moving circles are evaluated.

        Returns
        -------
        ndarray of bool, shape (N,)
        """
        A = _points(A, "A")
        B = _points(B, "B")
        if A.shape != B.shape:
            raise HybridnavError(f"B: expected the shape of A {A.shape}, got {B.shape}")
        n = A.shape[0]
        hit = np.zeros(n, dtype=bool)
        r = float(radius)
        if self._c_idx.size:
            C = self._centers(t, n)
            d, _ = _project(C, A[:, None, :], B[:, None, :])
            hit |= np.any(d - self._cr[None] < r, axis=1)
        if self._g_idx.size:
            d, proper = _seg_seg(A[:, None, :], B[:, None, :], self._eA[None], self._eB[None])
            hit |= np.any((d < r) | proper, axis=1)
            if np.any(self._g_closed):
                closed = self._g_closed
                cols = np.nonzero(closed)[0]
                inner = _through_interior(A, B, self._eA, self._eB, self._g_start)[:, cols]
                hit |= np.any(inner, axis=1)
        return hit

    def circles(self, t: float = 0.0) -> tuple[FloatArray, FloatArray]:
        """Centres ``(C, 2)`` at time ``t`` and radii ``(C,)`` of the circles and moving circles."""
        return self._centers(float(t), 0)[0].copy(), self._cr.copy()

    def edges(self) -> tuple[FloatArray, FloatArray]:
        """End points ``A, B`` ``(E, 2)`` of every segment obstacle and polygon/rectangle edge."""
        return self._eA.copy(), self._eB.copy()

    # -- views --------------------------------------------------------------------------------

    def static(self) -> World:
        """A world with the same workspace and only the static obstacles (indices renumbered)."""
        return self._view("static", lambda o: not isinstance(o, MovingCircle))

    def moving(self) -> World:
        """A world with the same workspace and only the moving circles (indices renumbered)."""
        return self._view("moving", lambda o: isinstance(o, MovingCircle))

    def _view(self, name: str, keep) -> World:
        # worlds are immutable: each view is built once (planners ask for them in their loops)
        views = self.__dict__.setdefault("_views", {})
        if name not in views:
            views[name] = World(self.workspace, tuple(o for o in self.obstacles if keep(o)))
        return views[name]

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """Alias of :attr:`workspace`: ``(xmin, xmax, ymin, ymax)``."""
        return self.workspace


def _nearest_on_circle(P: FloatArray, C: FloatArray, R: FloatArray) -> FloatArray:
    """Row-wise nearest points: P (N,2), C (N,2), R (N,) -> (N,2)."""
    D = P - C
    n = np.hypot(D[:, 0], D[:, 1])
    zero = n == 0.0
    U = np.where(zero[:, None], np.array([1.0, 0.0]), D / np.where(zero, 1.0, n)[:, None])
    return C + R[:, None] * U


# --------------------------------------------------------------------------------------------
# Robots and scenarios
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Robot:
    """A robot of a scenario.

    Parameters
    ----------
    name : str
        Unique within the scenario.
    model : str
        One of :data:`MODEL_NAMES`.
    start : (float, float)
        Initial position.
    goal : (float, float) or None
        Fixed target; None when the robot follows another robot (``goal_follow``).
    goal_follow : str or None
        Name of another robot whose current position is this robot's (moving) target.
    goal_radius : float
        The goal is reached within this distance (positive).
    radius : float
        Footprint radius (non-negative).
    initial : dict of str to float
        Other initial states by name (e.g. ``theta``); checked by the model layer, not here.
    params : dict of str to float
        Model parameter overrides; checked by the model layer, not here.
    """

    name: str
    model: str
    start: tuple[float, float]
    goal: tuple[float, float] | None = None
    goal_follow: str | None = None
    goal_radius: float = 0.5
    radius: float = 0.5
    initial: dict[str, float] = field(default_factory=dict)
    params: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class GridSpec:
    """How a scenario is turned into an occupancy grid (see :func:`hybridnav.grid.build_grid`).

    Parameters
    ----------
    map : str or None
        ``"movingai:NAME"`` (a map shipped in ``hybridnav/scenarios/data``), a path to a MovingAI
        ``.map`` file (relative paths are relative to the scenario file), or None to rasterize the
        world's obstacles.
    resolution : float
        Cell size in workspace units (positive).
    """

    map: str | None = None
    resolution: float = 1.0


@dataclass(frozen=True)
class Scenario:
    """A navigation problem: a world, robots and simulation settings.

    Parameters
    ----------
    name, description, units : str
        ``units`` is a label only (e.g. ``"cm"``, ``"m"``).
    dt : float
        Control and integration step, seconds.
    max_time : float
        Time budget, seconds.
    world : World
    robots : list of Robot
    grid : GridSpec or None
    source : str or None
        File the scenario was read from (not compared by ``==``).
    """

    name: str
    description: str
    units: str
    dt: float
    max_time: float
    world: World
    robots: list[Robot]
    grid: GridSpec | None = None
    source: str | None = field(default=None, compare=False)

    def model(self, robot: str | Robot, **overrides: Any):
        """The kinematic model of a robot, with the scenario's ``dt`` and the robot's parameters.

        ``overrides`` are passed on to :func:`hybridnav.models.get` (e.g. ``jit=False``).
        """
        from hybridnav import models

        r = self.robot(robot) if isinstance(robot, str) else robot
        return models.get(r.model, dt=self.dt, radius=r.radius, **{**r.params, **overrides})

    def robot(self, name: str) -> Robot:
        """The robot called ``name``.

        Raises
        ------
        HybridnavError
            No robot has that name.
        """
        for r in self.robots:
            if r.name == name:
                return r
        raise HybridnavError(
            f"{where(self.source, 'robots')}: no robot named {name!r}; expected one of "
            f"{', '.join(r.name for r in self.robots)}"
        )

    @property
    def max_steps(self) -> int:
        """Number of ``dt`` steps in ``max_time`` (rounded up)."""
        return int(math.ceil(self.max_time / self.dt - 1e-9))


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------

_TOP_KEYS = ("name", "description", "units", "dt", "max_time", "workspace", "obstacles", "robots", "grid")
_TOP_REQUIRED = ("name", "dt", "max_time", "workspace", "robots")
_WS_KEYS = ("xmin", "xmax", "ymin", "ymax")
_OBSTACLE_KEYS = {
    "circle": ("center", "radius"),
    "segment": ("a", "b"),
    "rectangle": ("min", "max"),
    "polygon": ("points",),
    "moving_circle": ("center", "radius", "velocity", "heading"),
}
_ROBOT_KEYS = ("name", "model", "start", "goal", "goal_follow", "goal_radius", "radius", "initial", "params")
_ROBOT_REQUIRED = ("name", "model", "start")
_GRID_KEYS = ("map", "resolution")


def _tname(v: Any) -> str:
    if isinstance(v, bool):
        return f"boolean {v!r}"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return "an array"
    return f"{type(v).__name__} {v!r}"


class _Check:
    """Validation helpers that raise HybridnavError naming the file and dotted key."""

    def __init__(self, source: str | None):
        self.source = source

    def fail(self, key: str, msg: str) -> HybridnavError:
        return HybridnavError(f"{where(self.source, key)}: {msg}")

    def table(self, v: Any, key: str) -> Mapping[str, Any]:
        if not isinstance(v, Mapping):
            raise self.fail(key, f"expected a table, got {_tname(v)}")
        return v

    def keys(self, d: Mapping[str, Any], key: str, allowed: Sequence[str], required: Sequence[str]) -> None:
        for k in d:
            if k not in allowed:
                raise self.fail(_join(key, k), f"unknown key; expected one of: {', '.join(allowed)}")
        for k in required:
            if k not in d:
                raise self.fail(_join(key, k), "missing required key")

    def number(self, v: Any, key: str, *, lo: float | None = None, lo_open: bool = False) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(key, f"expected a number, got {_tname(v)}")
        x = float(v)
        if not math.isfinite(x):
            raise self.fail(key, f"expected a finite number, got {v!r}")
        if lo is not None:
            if lo_open and not x > lo:
                raise self.fail(key, f"expected a number > {lo:g}, got {v!r}")
            if not lo_open and not x >= lo:
                raise self.fail(key, f"expected a number >= {lo:g}, got {v!r}")
        return x

    def string(self, v: Any, key: str, *, nonempty: bool = False) -> str:
        if not isinstance(v, str):
            raise self.fail(key, f"expected a string, got {_tname(v)}")
        if nonempty and not v.strip():
            raise self.fail(key, "expected a non-empty string")
        return v

    def point(self, v: Any, key: str) -> tuple[float, float]:
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise self.fail(key, f"expected a point [x, y], got {_tname(v)}")
        return (self.number(v[0], f"{key}[0]"), self.number(v[1], f"{key}[1]"))

    def numbers_table(self, v: Any, key: str) -> dict[str, float]:
        d = self.table(v, key)
        return {str(k): self.number(x, _join(key, k)) for k, x in d.items()}


def _join(key: str, sub: str) -> str:
    return f"{key}.{sub}" if key else sub


def _parse_obstacle(chk: _Check, raw: Any, key: str) -> Obstacle:
    d = chk.table(raw, key)
    if "type" not in d:
        raise chk.fail(f"{key}.type", f"missing required key; expected one of: {', '.join(OBSTACLE_TYPES)}")
    kind = chk.string(d["type"], f"{key}.type")
    if kind not in _OBSTACLE_KEYS:
        raise chk.fail(f"{key}.type", f"unknown obstacle type {kind!r}; expected one of: {', '.join(OBSTACLE_TYPES)}")
    fields_ = _OBSTACLE_KEYS[kind]
    chk.keys(d, key, ("type",) + fields_, fields_)
    if kind == "circle":
        c = chk.point(d["center"], f"{key}.center")
        r = chk.number(d["radius"], f"{key}.radius", lo=0.0, lo_open=True)
        return Circle(c, r)
    if kind == "moving_circle":
        c = chk.point(d["center"], f"{key}.center")
        r = chk.number(d["radius"], f"{key}.radius", lo=0.0, lo_open=True)
        v = chk.number(d["velocity"], f"{key}.velocity", lo=0.0)
        h = chk.number(d["heading"], f"{key}.heading")
        return MovingCircle(c, r, v, h)
    if kind == "segment":
        a = chk.point(d["a"], f"{key}.a")
        b = chk.point(d["b"], f"{key}.b")
        if a == b:
            raise chk.fail(f"{key}.b", f"expected an end point different from a (zero-length segment at {list(a)})")
        return Segment(a, b)
    if kind == "rectangle":
        lo = chk.point(d["min"], f"{key}.min")
        hi = chk.point(d["max"], f"{key}.max")
        if not (lo[0] < hi[0] and lo[1] < hi[1]):
            raise chk.fail(f"{key}.max", f"expected max > min in both x and y, got min={list(lo)} max={list(hi)}")
        return Rectangle(lo, hi)
    # polygon
    pts_raw = d["points"]
    if not isinstance(pts_raw, list):
        raise chk.fail(f"{key}.points", f"expected an array of points [[x, y], ...], got {_tname(pts_raw)}")
    pts = tuple(chk.point(p, f"{key}.points[{i}]") for i, p in enumerate(pts_raw))
    if len(pts) < 3:
        raise chk.fail(f"{key}.points", f"expected at least 3 points, got {len(pts)}")
    try:
        return Polygon(pts)
    except HybridnavError as exc:
        raise chk.fail(f"{key}.points", str(exc)) from None


def scenario_from_dict(data: Mapping[str, Any], source: str | os.PathLike[str] | None = None) -> Scenario:
    """Validate a parsed scenario (the TOML schema as a dict) and build a :class:`Scenario`.

    Parameters
    ----------
    data : mapping
        Parsed TOML (see the schema in the README / :mod:`hybridnav.world`).
    source : str or path-like, optional
        File the data came from; used in error messages and to resolve relative grid map paths.

    Returns
    -------
    Scenario

    Raises
    ------
    HybridnavError
        On unknown or missing keys, wrong types, non-finite numbers, an empty workspace,
        non-positive ``dt``/``max_time``, bad obstacles, a start or goal footprint outside the
        workspace or overlapping a static obstacle (starts also moving circles at ``t = 0``),
        overlapping start footprints, unknown models, duplicate robot names, bad goals, or a
        missing grid map. The message names the file and the dotted key.
    """
    src = None if source is None else str(source)
    chk = _Check(src)
    d = chk.table(data, "(top level)")
    chk.keys(d, "", _TOP_KEYS, _TOP_REQUIRED)

    name = chk.string(d["name"], "name", nonempty=True)
    description = chk.string(d.get("description", ""), "description")
    units = chk.string(d.get("units", "m"), "units")
    dt = chk.number(d["dt"], "dt", lo=0.0, lo_open=True)
    max_time = chk.number(d["max_time"], "max_time", lo=0.0, lo_open=True)
    if max_time < dt:
        raise chk.fail("max_time", f"expected max_time >= dt ({dt:g}), got {max_time:g}")

    ws_raw = chk.table(d["workspace"], "workspace")
    chk.keys(ws_raw, "workspace", _WS_KEYS, _WS_KEYS)
    ws = tuple(chk.number(ws_raw[k], f"workspace.{k}") for k in _WS_KEYS)
    if not ws[0] < ws[1]:
        raise chk.fail("workspace.xmax", f"expected xmax > xmin ({ws[0]:g}), got {ws[1]:g} (empty workspace)")
    if not ws[2] < ws[3]:
        raise chk.fail("workspace.ymax", f"expected ymax > ymin ({ws[2]:g}), got {ws[3]:g} (empty workspace)")

    obs_raw = d.get("obstacles", [])
    if not isinstance(obs_raw, list):
        raise chk.fail("obstacles", f"expected an array of tables ([[obstacles]]), got {_tname(obs_raw)}")
    obstacles = tuple(_parse_obstacle(chk, o, f"obstacles[{i}]") for i, o in enumerate(obs_raw))
    world = World(ws, obstacles)  # type: ignore[arg-type]

    grid = None
    if "grid" in d:
        g = chk.table(d["grid"], "grid")
        chk.keys(g, "grid", _GRID_KEYS, ())
        gmap = None
        if "map" in g:
            gmap = chk.string(g["map"], "grid.map", nonempty=True)
        res = chk.number(g.get("resolution", 1.0), "grid.resolution", lo=0.0, lo_open=True)
        grid = GridSpec(gmap, res)

    robots = _parse_robots(chk, d["robots"], world, dt)

    scen = Scenario(name, description, units, dt, max_time, world, robots, grid, src)
    if grid is not None and grid.map is not None:
        _check_map(chk, scen)
    return scen


def _check_model(chk: _Check, key: str, model: str, dt: float, radius: float, has_radius: bool,
                 start, goal, initial: dict[str, float], params: dict[str, float]) -> float:
    """Build the robot's model to validate its params and initial states; return its radius.

    A tractor-trailer's footprint follows from its ``L`` and ``b`` parameters, so it takes no
    ``radius`` key.
    """
    from hybridnav import models

    if model == "tractor_trailer" and has_radius:
        raise chk.fail(f"{key}.radius", "a tractor_trailer's footprint follows from its params L "
                                        "and b; remove radius (set robots.params.L / b instead)")
    try:
        m = models.get(model, dt=dt, radius=radius, **params)
    except HybridnavError as exc:
        raise chk.fail(f"{key}.params", str(exc)) from None
    try:
        m.initial_state(start, goal if goal is not None else start, initial)
    except HybridnavError as exc:
        raise chk.fail(f"{key}.initial", str(exc)) from None
    return m.radius


def _parse_robots(chk: _Check, raw: Any, world: World, dt: float) -> list[Robot]:
    if not isinstance(raw, list):
        raise chk.fail("robots", f"expected an array of tables ([[robots]]), got {_tname(raw)}")
    if not raw:
        raise chk.fail("robots", "expected at least one robot")
    static = world.static()
    robots: list[Robot] = []
    for i, rr in enumerate(raw):
        key = f"robots[{i}]"
        r = chk.table(rr, key)
        chk.keys(r, key, _ROBOT_KEYS, _ROBOT_REQUIRED)
        name = chk.string(r["name"], f"{key}.name", nonempty=True)
        if any(o.name == name for o in robots):
            raise chk.fail(f"{key}.name", f"expected a unique robot name, {name!r} is used twice")
        model = chk.string(r["model"], f"{key}.model")
        if model not in MODEL_NAMES:
            raise chk.fail(f"{key}.model", f"unknown model {model!r}; expected one of: {', '.join(MODEL_NAMES)}")
        start = chk.point(r["start"], f"{key}.start")
        has_goal, has_follow = "goal" in r, "goal_follow" in r
        if has_goal == has_follow:
            what = "both" if has_goal else "neither"
            raise chk.fail(f"{key}.goal", f"expected exactly one of goal = [x, y] or goal_follow = \"robot\", got {what}")
        goal = chk.point(r["goal"], f"{key}.goal") if has_goal else None
        follow = chk.string(r["goal_follow"], f"{key}.goal_follow", nonempty=True) if has_follow else None
        goal_radius = chk.number(r.get("goal_radius", 0.5), f"{key}.goal_radius", lo=0.0, lo_open=True)
        radius = chk.number(r.get("radius", 0.5), f"{key}.radius", lo=0.0)
        initial = chk.numbers_table(r.get("initial", {}), f"{key}.initial")
        params = chk.numbers_table(r.get("params", {}), f"{key}.params")
        radius = _check_model(chk, key, model, dt, radius, "radius" in r, start, goal, initial,
                              params)

        for what, p in (("start", start), ("goal", goal)):
            if p is None:
                continue
            P = np.asarray([p])
            if not world.inside_workspace(P, radius)[0]:
                raise chk.fail(
                    f"{key}.{what}",
                    f"expected a point whose footprint (radius {radius:g}) lies inside the workspace "
                    f"{list(world.workspace)}, got {list(p)}",
                )
            check = world if what == "start" else static
            c, _, j = check.nearest(P)
            if c[0] < radius:
                obs = check.obstacles[int(j[0])]
                oi = world.obstacles.index(obs)
                raise chk.fail(
                    f"{key}.{what}",
                    f"expected a point whose footprint (radius {radius:g}) is clear of obstacles, "
                    f"got {list(p)} which overlaps obstacles[{oi}] ({_TYPE_OF[type(obs)]})",
                )
        for o in robots:
            if math.dist(o.start, start) < o.radius + radius:
                raise chk.fail(f"{key}.start", f"expected a start whose footprint (radius {radius:g}) does not overlap the start footprint of robot {o.name!r}, got {list(start)}")
        robots.append(Robot(name, model, start, goal, follow, goal_radius, radius, initial, params))

    names = [r.name for r in robots]
    for i, r in enumerate(robots):
        if r.goal_follow is not None:
            if r.goal_follow == r.name:
                raise chk.fail(f"robots[{i}].goal_follow", "expected the name of another robot, got the robot itself")
            if r.goal_follow not in names:
                raise chk.fail(
                    f"robots[{i}].goal_follow",
                    f"expected the name of another robot ({', '.join(n for n in names if n != r.name)}), got {r.goal_follow!r}",
                )
    return robots


def _check_map(chk: _Check, scen: Scenario) -> None:
    """Resolve the grid map now, and check starts/goals lie in free cells of it."""
    from hybridnav import grid as _grid  # local import: grid imports world

    try:
        og = _grid.build_grid(scen)
    except HybridnavError as exc:
        msg = str(exc)
        if chk.source and not msg.startswith(chk.source):
            raise chk.fail("grid.map", msg) from None
        raise
    for i, r in enumerate(scen.robots):
        for what, p in (("start", r.start), ("goal", r.goal)):
            if p is None:
                continue
            if not og.is_free(np.asarray([p]))[0]:
                raise chk.fail(f"robots[{i}].{what}", f"expected a point in a free cell of grid.map {scen.grid.map!r}, got {list(p)}")


# --------------------------------------------------------------------------------------------
# Loading and writing
# --------------------------------------------------------------------------------------------


def _builtin_dir():
    return resources.files(_SCENARIO_PACKAGE)


def builtin_data_path(name: str):
    """A file shipped in ``hybridnav/scenarios/data`` (an importlib.resources Traversable).

    Parameters
    ----------
    name : str
        File name, e.g. ``"arena.map"``.
    """
    return _builtin_dir().joinpath("data", name)


def list_scenarios() -> list[tuple[str, str]]:
    """Built-in scenarios as ``(name, description)`` pairs, sorted by name."""
    out = []
    for entry in _builtin_dir().iterdir():
        if entry.name.endswith(".toml"):
            try:
                desc = str(tomllib.loads(entry.read_text(encoding="utf-8")).get("description", ""))
            except tomllib.TOMLDecodeError:  # pragma: no cover - shipped files are tested
                desc = "(invalid TOML)"
            out.append((entry.name[: -len(".toml")], desc))
    return sorted(out)


def _parse_toml(text: str, source: str) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise HybridnavError(f"{source}: invalid TOML: {exc}") from None


def load_scenario(name_or_path: str | os.PathLike[str]) -> Scenario:
    """Load a built-in scenario by name, or a scenario TOML file by path.

    Parameters
    ----------
    name_or_path : str or path-like
        A built-in name (see :func:`list_scenarios`), or a path to a ``.toml`` file. Strings that
        end in ``.toml`` or contain a path separator are paths.

    Returns
    -------
    Scenario

    Raises
    ------
    HybridnavError
        Unknown built-in name, unreadable file, TOML syntax error (the message gives the line), or
        invalid content (see :func:`scenario_from_dict`).
    """
    s = os.fspath(name_or_path)
    is_path = isinstance(name_or_path, os.PathLike) or s.endswith(".toml") or "/" in s or os.sep in s
    if is_path:
        path = Path(s)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise HybridnavError(f"{s}: cannot read scenario file ({exc.strerror or exc})") from None
        source = str(path)
    else:
        entry = _builtin_dir().joinpath(f"{s}.toml")
        if not entry.is_file():
            names = ", ".join(n for n, _ in list_scenarios())
            raise HybridnavError(f"scenario {s!r}: expected a built-in scenario name ({names}) or a path to a .toml file")
        text = entry.read_text(encoding="utf-8")
        source = str(entry)
    log.debug("loading scenario from %s", source)
    return scenario_from_dict(_parse_toml(text, source), source)


def _obstacle_to_dict(o: Obstacle) -> dict[str, Any]:
    kind = _TYPE_OF[type(o)]
    if isinstance(o, Circle):
        return {"type": kind, "center": list(o.center), "radius": o.radius}
    if isinstance(o, MovingCircle):
        return {"type": kind, "center": list(o.center), "radius": o.radius, "velocity": o.velocity,
                "heading": o.heading}
    if isinstance(o, Segment):
        return {"type": kind, "a": list(o.a), "b": list(o.b)}
    if isinstance(o, Rectangle):
        return {"type": kind, "min": list(o.min), "max": list(o.max)}
    return {"type": kind, "points": [list(p) for p in o.points]}


def scenario_to_dict(s: Scenario) -> dict[str, Any]:
    """The TOML-schema dict of a scenario (inverse of :func:`scenario_from_dict`).

    Parameters
    ----------
    s : Scenario

    Returns
    -------
    dict
        Plain lists, floats and strings; ``scenario_from_dict(scenario_to_dict(s)) == s``.
    """
    xmin, xmax, ymin, ymax = s.world.workspace
    out: dict[str, Any] = {
        "name": s.name,
        "description": s.description,
        "units": s.units,
        "dt": s.dt,
        "max_time": s.max_time,
        "workspace": {"xmin": xmin, "xmax": xmax, "ymin": ymin, "ymax": ymax},
        "obstacles": [_obstacle_to_dict(o) for o in s.world.obstacles],
        "robots": [],
    }
    for r in s.robots:
        rd: dict[str, Any] = {"name": r.name, "model": r.model, "start": list(r.start)}
        if r.goal is not None:
            rd["goal"] = list(r.goal)
        if r.goal_follow is not None:
            rd["goal_follow"] = r.goal_follow
        rd["goal_radius"] = r.goal_radius
        if r.model != "tractor_trailer":     # its footprint follows from its params
            rd["radius"] = r.radius
        rd["initial"] = dict(r.initial)
        rd["params"] = dict(r.params)
        out["robots"].append(rd)
    if s.grid is not None:
        g: dict[str, Any] = {"resolution": s.grid.resolution}
        if s.grid.map is not None:
            g["map"] = s.grid.map
        out["grid"] = g
    return out


# --------------------------------------------------------------------------------------------
# A minimal TOML writer (enough for the scenario schema; no third-party dependency)
# --------------------------------------------------------------------------------------------

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_toml_key(str(k))} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _is_aot(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and len(v) > 0 and all(isinstance(x, Mapping) for x in v)


def _toml_table(d: Mapping[str, Any], prefix: str, out: list[str]) -> None:
    for k, v in d.items():
        if not isinstance(v, Mapping) and not _is_aot(v):
            out.append(f"{_toml_key(str(k))} = {_toml_value(v)}")
    for k, v in d.items():
        if isinstance(v, Mapping):
            name = prefix + _toml_key(str(k))
            out += ["", f"[{name}]"]
            _toml_table(v, name + ".", out)
    for k, v in d.items():
        if _is_aot(v):
            name = prefix + _toml_key(str(k))
            for item in v:
                out += ["", f"[[{name}]]"]
                _toml_table(item, name + ".", out)


def toml_dumps(data: Mapping[str, Any]) -> str:
    """Write a mapping as TOML text (strings, numbers, booleans, arrays, tables, arrays of tables).

    Parameters
    ----------
    data : mapping

    Returns
    -------
    str
        Text that :func:`tomllib.loads` reads back to ``data`` (tuples become lists).
    """
    out: list[str] = []
    _toml_table(data, "", out)
    return "\n".join(out).lstrip("\n") + "\n"


def scenario_to_toml(s: Scenario) -> str:
    """The scenario as TOML text in the public schema (see :func:`scenario_to_dict`)."""
    return toml_dumps(scenario_to_dict(s))


def save_scenario(s: Scenario, path: str | os.PathLike[str]) -> Path:
    """Write a scenario TOML file atomically (temporary file in the same directory, then rename).

    Parameters
    ----------
    s : Scenario
    path : str or path-like

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    atomic_write_text(path, scenario_to_toml(s))
    return path
