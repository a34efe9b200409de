"""The :class:`World`: a rectangular workspace plus obstacles, queries vectorized over points and
obstacles."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError
from hybridnav.world.clearmap import ClearMap
from hybridnav.world.geometry import (
    FloatArray,
    _cross,
    _nearest_on_circle,
    _points,
    _project,
    _seg_seg,
    _through_interior,
)
from hybridnav.world.obstacles import _TYPE_OF, Circle, MovingCircle, Obstacle, _finite

__all__ = ["World"]


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

    def boxes(self, t0: ArrayLike = 0.0, t1: ArrayLike | None = None
              ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Where each obstacle is, as a box and a pad: obstacle ``k`` lies within ``pad[k]`` of
        the box ``[lo[..., k, :], hi[..., k, :]]`` (circles: the centre and the radius; moving
        circles: their centres from time ``t0`` to ``t1``, default ``t0``, and the radius;
        segments and polygons: their bounding box and 0). For pruning: a point farther than
        ``pad[k]`` from the box is outside obstacle ``k``.

        Parameters
        ----------
        t0, t1 : float or array_like
            Times (broadcasting against each other).

        Returns
        -------
        lo, hi : ndarray, shape (..., K, 2)
            ``...`` is the times' shape.
        pad : ndarray, shape (K,)
        """
        t0 = np.asarray(t0, dtype=float)
        t1 = t0 if t1 is None else np.asarray(t1, dtype=float)
        shape = np.broadcast_shapes(t0.shape, t1.shape) + (len(self.obstacles), 2)
        lo, hi, pad = np.empty(shape), np.empty(shape), np.zeros(len(self.obstacles))
        if self._c_idx.size:
            ca = self._c0 + t0[..., None, None] * self._cv
            cb = self._c0 + t1[..., None, None] * self._cv
            lo[..., self._c_idx, :] = np.minimum(ca, cb)
            hi[..., self._c_idx, :] = np.maximum(ca, cb)
            pad[self._c_idx] = self._cr
        if self._g_idx.size:
            lo[..., self._g_idx, :] = np.minimum.reduceat(np.minimum(self._eA, self._eB),
                                                           self._g_start)
            hi[..., self._g_idx, :] = np.maximum.reduceat(np.maximum(self._eA, self._eB),
                                                           self._g_start)
        return lo, hi, pad

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

    def clear_map(self, reach: float) -> ClearMap:
        """The cells of the workspace farther than (at least) ``reach`` from every static
        obstacle and from the border (:class:`~hybridnav.world.clearmap.ClearMap`). Maps are
        built once, for ``reach`` rounded up to a multiple of 1/1024 of the workspace's longer
        side, so close values share one."""
        maps = self.__dict__.setdefault("_clear_maps", {})
        xmin, xmax, ymin, ymax = self.workspace
        q = max(xmax - xmin, ymax - ymin) / 1024
        key = math.ceil(float(reach) / q * (1 + 1e-9)) + 1      # a step up: never below reach
        if key not in maps:
            if len(maps) >= 16:
                maps.pop(next(iter(maps)))
            maps[key] = ClearMap(self, key * q)
        return maps[key]

    def singles(self) -> tuple[World, ...]:
        """One world per obstacle, with the same workspace, in :attr:`obstacles` order (built
        once). A query of this world is the combination of theirs (e.g. ``segment_collides``
        is true where one of theirs is), each computed by the same operations."""
        views = self.__dict__.setdefault("_views", {})
        if "singles" not in views:
            views["singles"] = tuple(World(self.workspace, (o,)) for o in self.obstacles)
        return views["singles"]

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
