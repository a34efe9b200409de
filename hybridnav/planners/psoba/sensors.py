"""PSO-BA's geometry: range sensors, sensing and gap vectors, and the local search (eq. 22).

Abed et al. (2022) work on grid points of the obstacles; here everything is exact continuous
geometry on a :class:`Scene`, the obstacles as *capsules* (a segment ``A-B`` thickened by a radius
``r``): a static circle is a capsule with ``A = B``, a segment obstacle or a polygon edge one with
``r = 0``, a moving circle at time ``t`` one with ``A = B = centre(t)``, and a moving circle *swept*
over a time window ``[t, t + h]`` the capsule from ``centre(t)`` to ``centre(t + h)``. A static
:class:`~hybridnav.world.World` kept beside the capsules gives the sign of the clearance inside
solid polygons. All queries are vectorized over query points, directions and capsules.

Range sensors (paper section 5.1)
---------------------------------
``n`` sensors (12 in the paper) split the full turn into equal sectors in the world frame: sensor
``j`` (0-based) covers the directions ``[j, j + 1) * 360 / n`` degrees from the x axis. Its reading
is the distance from the robot to the nearest obstacle point whose direction lies in its sector --
the paper's "grid points of the obstacle within SR binned by their angle (eq. 24)", for the
continuous obstacle. It is computed exactly: for a convex piece seen from outside, the distance of
its first hit as a function of the ray angle is quasi-convex, so the minimum over a sector is either
the piece's nearest point (when its direction lies in the sector) or a first hit of one of the two
rays bounding the sector (:func:`ray_entry`). A polygon is the union of its edges for this purpose
(from outside, its nearest point in any sector lies on an edge).

The sensing vector is ``Vs(j) = reading(j) < sr`` (eq. 23: detected when ``D < sr``) and the gap
vector ``Vg(j) = NOT(Vs(j) OR Vs(j + 1))`` (indices modulo ``n``): gap ``j`` is free when both
sectors ``j`` and ``j + 1`` are, and it is centred on their common boundary ray, at
``(j + 1) * 360 / n`` degrees. The paper's example ``Vs = [1 1 0 0 0 0 0 0 0 0 1 1]`` gives
``Vg = [0 0 1 1 1 1 1 1 1 0 0 0]``.

Local search (paper section 4.2, eqs. 17-22)
--------------------------------------------
A candidate ``c`` proposed from the current position ``p`` is infeasible when a disk of the robot's
safety radius swept along ``p -> c`` meets an obstacle (the candidate lies inside an obstacle, case
1, or the segment crosses one, case 2). Eq. 22 moves it back along the same ray,
``p' = p + (c - p) (|p - q| - ds) / |p - c|``, where ``q`` is the obstacle grid point nearest to
``p`` among those within the grid scale of the segment. Taken literally this puts ``p'`` ``ds``
before the obstacle *along the ray*, which is closer than ``ds`` when the ray meets the obstacle
obliquely. Our choice, the exact continuous version of the intent: ``p'`` is the first point of
the ray whose clearance equals ``ds`` (:func:`local_search`), so ``p'`` is exactly ``ds`` from the
nearest obstacle and the whole segment ``p -> p'`` keeps at least ``ds``. When the robot is
already closer than ``ds`` (a moving obstacle came near), its present clearance replaces ``ds``:
the repaired move never brings it closer than it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hybridnav.errors import HybridnavError
from hybridnav.world import MovingCircle, World

__all__ = [
    "WALL_NORMALS",
    "Scene",
    "escape_step",
    "feasible",
    "followed_wall",
    "gap_index",
    "gap_vector",
    "local_search",
    "near_room_walls",
    "ray_entry",
    "sector_ranges",
    "sensing_vector",
]

FloatArray = NDArray[np.float64]


# --------------------------------------------------------------------------------------------
# The obstacle scene
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Scene:
    """Obstacles as capsules, with a static world for the sign inside polygons.

    Parameters
    ----------
    A, B : ndarray, shape (K, 2)
        Capsule axis end points (``A == B``: a disk).
    r : ndarray, shape (K,)
        Capsule radii (0 for segments and polygon edges).
    static : World
        The static obstacles among the capsules (for the clearance sign inside polygons).
    walls : bool
        Whether the four workspace sides count as obstacles (segments) in :meth:`clearance`,
        :func:`ray_entry` and :func:`local_search`. The range sensors never see them (the paper
        detects the room boundary from the coordinates, :func:`near_room_walls`).
    vel : ndarray, shape (K, 2), optional
        Velocity of each capsule's obstacle (moving circles; zero for the rest). Default zeros.
    """

    A: FloatArray
    B: FloatArray
    r: FloatArray
    static: World
    walls: bool = False
    vel: FloatArray | None = None

    def __post_init__(self) -> None:
        if self.vel is None:
            object.__setattr__(self, "vel", np.zeros((len(self.r), 2)))

    @classmethod
    def build(cls, static: World, moving: World | None = None, t: float = 0.0,
              horizon: float = 0.0, discs: tuple[ArrayLike, ArrayLike] | None = None,
              walls: bool = False) -> Scene:
        """The scene at time ``t``.

        Parameters
        ----------
        static : World
            Static obstacles (moving circles in it are ignored).
        moving : World, optional
            Moving circles, evaluated at time ``t`` -- swept over ``[t, t + horizon]`` when
            ``horizon > 0`` (a capsule from the centre at ``t`` to the centre at ``t + horizon``).
        t : float
        horizon : float
        discs : (centres (M, 2), radii (M,)), optional
            Further disks (e.g. other robots).
        walls : bool
            Add the workspace sides as obstacles.
        """
        if any(isinstance(o, MovingCircle) for o in static.obstacles):
            static = static.static()
        eA, eB = static.edges()
        cC, cR = static.circles()
        A = [eA, cC]
        B = [eB, cC]
        r = [np.zeros(len(eA)), cR]
        vel = [np.zeros((len(eA) + len(cR), 2))]
        if moving is not None and moving.obstacles:
            c0, mr = moving.circles(t)
            c1, _ = moving.circles(t + max(0.0, horizon))
            A.append(c0)
            B.append(c1)
            r.append(mr)
            vel.append(np.array([o.velocity_vector for o in moving.obstacles
                                 if isinstance(o, MovingCircle)]).reshape(-1, 2))
        if discs is not None:
            dc = np.asarray(discs[0], dtype=float).reshape(-1, 2)
            A.append(dc)
            B.append(dc)
            r.append(np.asarray(discs[1], dtype=float).reshape(-1))
            vel.append(np.zeros((len(dc), 2)))
        if walls:
            xmin, xmax, ymin, ymax = static.workspace
            corners = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
            A.append(corners)
            B.append(np.roll(corners, -1, axis=0))
            r.append(np.zeros(4))
            vel.append(np.zeros((4, 2)))
        return cls(np.concatenate(A), np.concatenate(B), np.concatenate(r), static, walls,
                   np.concatenate(vel))

    def without_walls(self) -> Scene:
        """The same obstacles without the workspace sides."""
        if not self.walls:
            return self
        return Scene(self.A[:-4], self.B[:-4], self.r[:-4], self.static, False, self.vel[:-4])

    def nearest(self, P: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Distance to, and nearest surface point of, the nearest capsule.

        Parameters
        ----------
        P : array_like, shape (N, 2)

        Returns
        -------
        dist : ndarray, shape (N,)
            ``inf`` without capsules (negative inside a capsule).
        point : ndarray, shape (N, 2)
            NaN without capsules.
        """
        P = _pts(P)
        if not len(self.r):
            return np.full(len(P), np.inf), np.full((len(P), 2), np.nan)
        d, Q = _seg_project(P[:, None, :], self.A[None], self.B[None])
        k = np.argmin(d - self.r[None], axis=1)
        rows = np.arange(len(P))
        dist = d[rows, k] - self.r[k]
        Qk = Q[rows, k]
        D = P - Qk
        n = np.hypot(D[:, 0], D[:, 1])
        U = np.where((n > 0)[:, None], D / np.where(n > 0, n, 1.0)[:, None], np.array([1.0, 0.0]))
        return dist, Qk + self.r[k][:, None] * U

    def surface_points(self, p: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Distance to, and nearest surface and axis points of, every capsule from one point.

        Parameters
        ----------
        p : array_like, shape (2,)

        Returns
        -------
        dist : ndarray, shape (K,)
            Negative inside a capsule.
        point : ndarray, shape (K, 2)
            The nearest surface point.
        axis : ndarray, shape (K, 2)
            The nearest point of the capsule's axis segment.
        """
        p = np.asarray(p, dtype=float).reshape(1, 2)
        d, Q = _seg_project(p, self.A, self.B)
        D = p - Q
        n = np.hypot(D[:, 0], D[:, 1])
        U = np.where((n > 0)[:, None], D / np.where(n > 0, n, 1.0)[:, None], np.array([1.0, 0.0]))
        return d - self.r, Q + self.r[:, None] * U, Q

    def subset(self, keep: ArrayLike) -> Scene:
        """The scene with only the capsules selected by the boolean mask ``keep`` (the walls,
        the last four capsules when ``walls`` is set, are always kept)."""
        keep = np.asarray(keep, dtype=bool).copy()
        if self.walls:
            keep[-4:] = True
        return Scene(self.A[keep], self.B[keep], self.r[keep], self.static, self.walls,
                     self.vel[keep])

    def clearance(self, P: ArrayLike) -> FloatArray:
        """Signed distance to the nearest obstacle (negative inside; walls included if set).

        Parameters
        ----------
        P : array_like, shape (N, 2)

        Returns
        -------
        ndarray, shape (N,)
        """
        P = _pts(P)
        out = self.nearest(P)[0]
        if self.static.obstacles:
            out = np.minimum(out, self.static.clearance(P))
        if self.walls:
            out = np.minimum(out, self.static.border_clearance(P))
        return out


def _pts(P: ArrayLike) -> FloatArray:
    arr = np.asarray(P, dtype=float)
    if arr.ndim == 1:
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise HybridnavError(f"P: expected an (N, 2) array of points, got shape {arr.shape}")
    return arr


def _seg_project(P: FloatArray, A: FloatArray, B: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Distance from points to segments and the nearest segment points (broadcasting)."""
    AB = B - A
    den = np.sum(AB * AB, axis=-1)
    s = np.sum((P - A) * AB, axis=-1) / np.where(den > 0, den, 1.0)
    s = np.clip(np.where(den > 0, s, 0.0), 0.0, 1.0)
    Q = A + s[..., None] * AB
    D = P - Q
    return np.hypot(D[..., 0], D[..., 1]), Q


# --------------------------------------------------------------------------------------------
# Ray casting
# --------------------------------------------------------------------------------------------


def _ray_capsules(P: FloatArray, U: FloatArray, A: FloatArray, B: FloatArray,
                  rho: FloatArray) -> FloatArray:
    """First entry ``lambda >= 0`` of rays ``P + lambda U`` into capsules, per capsule.

    ``P`` (N, 1, 2), ``U`` (N or 1, M, 2) unit directions; capsules ``A``, ``B`` (K, 2), ``rho``
    (K,). Returns (N, M, K); ``inf`` for a miss, 0 when the ray starts inside.
    """
    P4 = P[:, :, None, :]                   # (N, 1, 1, 2)
    U4 = U[:, :, None, :]                   # (., M, 1, 2)
    out = np.full(np.broadcast_shapes(P4.shape[:2], U4.shape[:2]) + (len(rho),), np.inf)
    for C in (A, B):                        # end disks
        W = P4 - C[None, None]              # (N, 1, K, 2)
        b = -np.sum(U4 * W, axis=-1)        # (N, M, K)
        w2 = np.sum(W * W, axis=-1)
        c = w2 - rho ** 2
        disc = b * b - c
        ok = disc >= -1e-12 * w2            # (a ray grazing a bare end point still hits it)
        lam = b - np.sqrt(np.maximum(disc, 0.0))
        lam = np.where(c <= 0.0, 0.0, lam)
        out = np.where(ok & (lam >= 0.0) & (lam < out), lam, out)
    AB = B - A
    L = np.hypot(AB[:, 0], AB[:, 1])
    long = L > 0
    if np.any(long):
        e = AB / np.where(long, L, 1.0)[:, None]
        nrm = np.stack([-e[:, 1], e[:, 0]], axis=1)
        rel = P4 - A[None, None]
        h = np.sum(rel * nrm, axis=-1)      # (N, 1, K) signed offset from the axis
        s0 = np.sum(rel * e, axis=-1)
        un = np.sum(U4 * nrm, axis=-1)      # (., M, K)
        ue = np.sum(U4 * e, axis=-1)
        inside = (np.abs(h) <= rho) & (s0 >= 0) & (s0 <= L)
        with np.errstate(divide="ignore", invalid="ignore"):
            for sgn in (1.0, -1.0):         # the two sides of the thickened segment
                lam = (sgn * rho - h) / un
                s = s0 + lam * ue
                ok = long & (un != 0) & (lam >= 0) & (s >= 0) & (s <= L)
                out = np.where(ok & (lam < out), lam, out)
        out = np.where(inside & long, 0.0, out)
    return out


def ray_entry(scene: Scene, P: ArrayLike, U: ArrayLike, inflate: float = 0.0) -> FloatArray:
    """Distance along rays to the first point within ``inflate`` of an obstacle.

    Parameters
    ----------
    scene : Scene
    P : array_like, shape (N, 2)
        Ray origins.
    U : array_like, shape (M, 2) or (N, M, 2)
        Ray directions (normalized here).
    inflate : float
        Obstacles are grown by this distance (0: the obstacles themselves).

    Returns
    -------
    ndarray, shape (N, M)
        ``inf`` for rays that never come within ``inflate`` of an obstacle; 0 for origins
        already within it. Walls of the scene count like segment obstacles.
    """
    P = _pts(P)
    U = np.asarray(U, dtype=float)
    if U.ndim == 2:
        U = U[None]
    norm = np.hypot(U[..., 0], U[..., 1])
    if np.any(norm == 0):
        raise HybridnavError("U: expected non-zero ray directions")
    U = U / norm[..., None]
    if not len(scene.r):
        return np.full((len(P), U.shape[1]), np.inf)
    lam = _ray_capsules(P[:, None, :], U, scene.A, scene.B, scene.r + float(inflate))
    return lam.min(axis=2)


# --------------------------------------------------------------------------------------------
# Range sensors, sensing vector, gap vector
# --------------------------------------------------------------------------------------------


def sector_ranges(scene: Scene, P: ArrayLike, sensors: int = 12) -> FloatArray:
    """Readings of ``sensors`` sector range sensors at each point (exact, unlimited range).

    Sensor ``j`` (0-based) covers directions ``[j, j + 1) * 2 pi / sensors`` from the x axis;
    its reading is the distance to the nearest obstacle point in that sector (``inf`` when there
    is none). The scene's walls are not seen.

    Parameters
    ----------
    scene : Scene
    P : array_like, shape (N, 2)
    sensors : int

    Returns
    -------
    ndarray, shape (N, sensors)
        0 in every sector for a point inside an obstacle.
    """
    P = _pts(P)
    n = int(sensors)
    if n < 3:
        raise HybridnavError(f"sensors: expected at least 3 sensors, got {sensors!r}")
    sc = scene.without_walls()
    if not len(sc.r):
        return np.full((len(P), n), np.inf)
    ang = 2.0 * np.pi * np.arange(n) / n
    U = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    hits = _ray_capsules(P[:, None, :], U[None], sc.A, sc.B, sc.r)      # (N, n, K)
    bound = np.minimum(hits, np.roll(hits, -1, axis=1))                 # rays j and j + 1
    d, Q = _seg_project(P[:, None, :], sc.A[None], sc.B[None])          # (N, K)
    dist = d - sc.r[None]
    D = Q - P[:, None, :]
    phi = np.mod(np.arctan2(D[..., 1], D[..., 0]), 2.0 * np.pi)
    sector = np.minimum((phi / (2.0 * np.pi / n)).astype(int), n - 1)
    near = np.where(np.arange(n)[None, :, None] == sector[:, None, :], dist[:, None, :], np.inf)
    out = np.minimum(bound, near).min(axis=2)
    inside = sc.clearance(P) <= 0.0
    out[inside] = 0.0
    return out


def sensing_vector(readings: ArrayLike, sr: float) -> NDArray[np.bool_]:
    """``Vs(j) = reading(j) < sr`` (eq. 23: an obstacle closer than the sensing radius).

    Parameters
    ----------
    readings : array_like, shape (..., n)
    sr : float
        Sensing radius.

    Returns
    -------
    ndarray of bool, shape (..., n)
    """
    return np.asarray(readings, dtype=float) < float(sr)


def gap_vector(vs: ArrayLike) -> NDArray[np.bool_]:
    """``Vg(j) = NOT(Vs(j) OR Vs(j + 1))``, indices modulo ``n`` (paper section 5.1).

    Parameters
    ----------
    vs : array_like of bool or 0/1, shape (..., n)

    Returns
    -------
    ndarray of bool, shape (..., n)
        Gap ``j`` is centred on the boundary between sectors ``j`` and ``j + 1``.
    """
    v = np.asarray(vs)
    if v.ndim == 0 or v.shape[-1] < 2:
        raise HybridnavError(f"vs: expected a sensing vector of at least 2 bits, got {v!r}")
    if not np.all((v == 0) | (v == 1)):
        raise HybridnavError(f"vs: expected bits (0/1 or bool), got {v!r}")
    v = v.astype(bool)
    return ~(v | np.roll(v, -1, axis=-1))


def gap_index(theta: float, n: int) -> int:
    """Index of the gap whose centre ray is nearest to direction ``theta`` (radians)."""
    step = 2.0 * math.pi / n
    m = round((theta % (2.0 * math.pi)) / step)
    return (m - 1) % n


def near_room_walls(P: ArrayLike, workspace: tuple[float, float, float, float],
                    sr: float) -> NDArray[np.bool_]:
    """Room-boundary detection: ``|x - xmin| < sr``, ``|x - xmax| < sr``, ``|y - ymin| < sr``,
    ``|y - ymax| < sr`` (paper section 5.2; its fourth line repeats ``ymin``, a typo).

    Parameters
    ----------
    P : array_like, shape (N, 2)
    workspace : (xmin, xmax, ymin, ymax)
    sr : float

    Returns
    -------
    ndarray of bool, shape (N, 4)
        Columns: the ``xmin``, ``xmax``, ``ymin``, ``ymax`` walls.
    """
    P = _pts(P)
    xmin, xmax, ymin, ymax = workspace
    return np.stack([np.abs(P[:, 0] - xmin) < sr, np.abs(P[:, 0] - xmax) < sr,
                     np.abs(P[:, 1] - ymin) < sr, np.abs(P[:, 1] - ymax) < sr], axis=1)


#: outward normals of the xmin, xmax, ymin, ymax walls
WALL_NORMALS = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])


# --------------------------------------------------------------------------------------------
# Local search
# --------------------------------------------------------------------------------------------


def feasible(scene: Scene, p: ArrayLike, c: ArrayLike, radius: float) -> bool:
    """Whether a disk of ``radius`` swept along ``p -> c`` stays clear of the obstacles.

    When ``p`` itself is closer than ``radius`` to an obstacle, its present clearance replaces
    ``radius`` (a move that never gets closer than the robot already is counts as feasible).

    Parameters
    ----------
    scene : Scene
    p, c : array_like, shape (2,)
    radius : float

    Returns
    -------
    bool
    """
    p = np.asarray(p, dtype=float).reshape(2)
    c = np.asarray(c, dtype=float).reshape(2)
    L = float(np.hypot(*(c - p)))
    here = float(scene.clearance(p)[0])
    r_ok = min(radius, here - 1e-9 * max(1.0, abs(here), L))
    if r_ok < 0:
        return False
    if L == 0.0:
        return True
    return bool(ray_entry(scene, p, ((c - p) / L)[None], r_ok)[0, 0] >= L)


def local_search(scene: Scene, p: ArrayLike, c: ArrayLike, ds: float,
                 radius: float) -> tuple[FloatArray, bool]:
    """Make the move ``p -> c`` feasible (paper eq. 22, exact continuous version).

    Parameters
    ----------
    scene : Scene
        Obstacles (with ``walls`` the workspace sides count too).
    p : array_like, shape (2,)
        Current position.
    c : array_like, shape (2,)
        Candidate.
    ds : float
        Safety distance: a repaired candidate is exactly this far from the nearest obstacle.
    radius : float
        Feasibility radius: the move is feasible when a disk of this radius swept along it
        meets no obstacle (``radius <= ds``).

    Returns
    -------
    point : ndarray, shape (2,)
        ``c`` when feasible; otherwise the first point of the ray ``p -> c`` whose clearance is
        ``ds`` (or the present clearance of ``p`` when that is smaller), which may be ``p`` itself.
    repaired : bool
        Whether ``c`` was infeasible.
    """
    p = np.asarray(p, dtype=float).reshape(2)
    c = np.asarray(c, dtype=float).reshape(2)
    if not ds >= radius >= 0:
        raise HybridnavError(f"ds: expected ds >= radius >= 0, got ds={ds!r}, radius={radius!r}")
    d = c - p
    L = float(np.hypot(*d))
    if L == 0.0:
        return c.copy(), False
    u = d / L
    if feasible(scene, p, c, radius):
        return c.copy(), False
    here = float(scene.clearance(p)[0])
    tol = 1e-9 * max(1.0, abs(here), L)
    keep = min(ds, here - tol)
    if keep < 0:                          # inside an obstacle already: do not move
        return p.copy(), True
    lam = float(ray_entry(scene, p, u[None], keep)[0, 0])
    return p + min(lam, L) * u, True


def escape_step(scene: Scene, k: int, p, step: float, ds: float, r_safe: float):
    """A step of length ``step`` away from the axis of obstacle ``k`` (the robot is in the
    region a moving obstacle will sweep, or closer than its safety radius), repaired against the
    others with :func:`local_search`; None when it cannot move."""
    _, _, axis = scene.surface_points(p)
    away = p - axis[k]
    n = float(np.hypot(*away))
    if n == 0:
        vel = scene.vel[k]
        away = np.array([-vel[1], vel[0]]) if np.any(vel != 0) else np.array([1.0, 0.0])
        n = float(np.hypot(*away))
    others = np.ones(len(scene.r), dtype=bool)
    others[k] = False
    point, _ = local_search(scene.subset(others), p, p + step * away / n, ds, r_safe)
    return point if np.hypot(*(point - p)) > 0 else None


def followed_wall(scene: Scene, heading: FloatArray | None, side: float, p: FloatArray,
                  ds: float) -> tuple[float, FloatArray, int]:
    """The wall to follow: the nearest obstacle on the robot's following side (``side``: +1
    left following, -1 right; ``heading``: the last unit heading, None at the first step).

    Left following keeps the obstacle on the robot's right: among the obstacles within
    ``2 ds`` that lie to the right of the last heading (or ahead, up to 30 degrees to the
    left), the nearest; the nearest of all when there is none (e.g. at the first step).
    Between two close obstacles this keeps the followed one instead of switching to the one
    on the other side. Returns its distance, nearest surface point and capsule index.
    """
    d, Q, _ = scene.surface_points(p)
    if not len(d):
        return math.inf, np.full(2, np.nan), -1
    best = int(np.argmin(d))
    if heading is not None:
        U = Q - p
        n = np.hypot(U[:, 0], U[:, 1])
        U = U / np.where(n > 0, n, 1.0)[:, None]
        cross = heading[0] * U[:, 1] - heading[1] * U[:, 0]
        side_ok = (side * cross <= 0.5) & (d <= 2.0 * ds)
        if side_ok.any():
            best = int(np.flatnonzero(side_ok)[np.argmin(d[side_ok])])
    return float(d[best]), Q[best], best
