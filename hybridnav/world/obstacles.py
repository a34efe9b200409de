"""Obstacle shapes with vectorized signed-distance (``clearance``) and nearest-point queries."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Union

import numpy as np
from numpy.typing import ArrayLike

from hybridnav.errors import HybridnavError
from hybridnav.params import check_real
from hybridnav.world.geometry import (
    FloatArray,
    _ccw_convex,
    _cross,
    _nearest_on_circle,
    _points,
    _project,
)

__all__ = ["OBSTACLE_TYPES", "Circle", "MovingCircle", "Obstacle", "Polygon", "Rectangle", "Segment"]

#: Obstacle ``type`` values of the TOML schema.
OBSTACLE_TYPES: tuple[str, ...] = ("circle", "segment", "rectangle", "polygon", "moving_circle")


def _pt(value: Any, what: str) -> tuple[float, float]:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise HybridnavError(f"{what}: expected a finite point [x, y], got {value!r}")
    return (float(arr[0]), float(arr[1]))


def _finite(value: Any, what: str) -> float:
    return check_real(what, value)


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

    #: the obstacle ``type`` of the TOML schema
    kind: ClassVar[str] = "circle"

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

    #: the obstacle ``type`` of the TOML schema
    kind: ClassVar[str] = "segment"

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

    #: the obstacle ``type`` of the TOML schema
    kind: ClassVar[str] = "polygon"

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

    #: the obstacle ``type`` of the TOML schema
    kind: ClassVar[str] = "rectangle"

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

    #: the obstacle ``type`` of the TOML schema
    kind: ClassVar[str] = "moving_circle"

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

_TYPE_OF = {cls: cls.kind for cls in (Circle, Segment, Rectangle, Polygon, MovingCircle)}
