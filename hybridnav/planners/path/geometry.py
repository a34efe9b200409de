"""The obstacle model the plan-then-track planners plan against, and path geometry: pulling a path
tight, resampling waypoints, and the :class:`PlannedPath` a planner returns."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hybridnav.results import path_length
from hybridnav.world import MovingCircle, Rectangle, World
from hybridnav.world.grid import OccupancyGrid, build_grid

__all__ = ["grid_rectangles", "obstacle_world", "pull_tight", "resample_waypoints", "PlannedPath"]


# --------------------------------------------------------------------------------------------
# Obstacle model
# --------------------------------------------------------------------------------------------


def grid_rectangles(grid: OccupancyGrid) -> list[Rectangle]:
    """The blocked cells of a grid as few axis-aligned rectangles covering exactly them.

    Each row's runs of blocked cells are merged, then equal runs of consecutive rows.

    Parameters
    ----------
    grid : OccupancyGrid

    Returns
    -------
    list of Rectangle
        Their union is exactly the union of the blocked cells (in world coordinates).
    """
    occ = grid.occ
    x0, y0 = grid.origin
    res = grid.resolution
    open_runs: dict[tuple[int, int], int] = {}   # (c0, c1) -> first row
    boxes: list[tuple[int, int, int, int]] = []
    for r in range(occ.shape[0] + 1):
        runs: set[tuple[int, int]] = set()
        if r < occ.shape[0]:
            row = np.concatenate([[False], occ[r], [False]]).astype(np.int8)
            d = np.diff(row)
            runs = set(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))
        for run in list(open_runs):
            if run not in runs:
                boxes.append((run[0], run[1], open_runs.pop(run), r))
        for run in runs:
            open_runs.setdefault(run, r)
    return [Rectangle((x0 + c0 * res, y0 + r0 * res), (x0 + c1 * res, y0 + r1 * res))
            for c0, c1, r0, r1 in sorted(boxes, key=lambda b: (b[2], b[0]))]


def obstacle_world(scenario) -> World:
    """The static obstacle model the planners of this module plan and are simulated against.

    The scenario's static obstacles, plus, with a ``[grid] map``, the map's blocked cells
    (:func:`grid_rectangles`).

    Parameters
    ----------
    scenario : Scenario

    Returns
    -------
    World
    """
    world = scenario.world
    obs = tuple(o for o in world.obstacles if not isinstance(o, MovingCircle))
    if scenario.grid is not None and scenario.grid.map is not None:
        obs = obs + tuple(grid_rectangles(build_grid(scenario)))
    return World(world.workspace, obs)


def _cell_size(scenario) -> float:
    """The planners' length unit: the resolution :func:`build_grid` uses for this scenario."""
    if scenario.grid is not None:
        return float(scenario.grid.resolution)
    xmin, xmax, ymin, ymax = scenario.world.workspace
    return min(xmax - xmin, ymax - ymin) / 100.0


# --------------------------------------------------------------------------------------------
# Path helpers
# --------------------------------------------------------------------------------------------


def pull_tight(points: NDArray[np.float64], world: World, radius: float) -> NDArray[np.float64]:
    """Drop the vertices of a polyline that a collision-free shortcut can skip.

    From each kept vertex, the next kept vertex is the farthest later vertex whose straight
    segment is collision-free (:meth:`World.segment_collides` with ``radius``); when not even the
    next vertex is, the next vertex is kept anyway. The result keeps the first and last points,
    its vertices are vertices of the input, and it is never longer than the input.

    Parameters
    ----------
    points : ndarray, shape (M, 2)
    world : World
    radius : float

    Returns
    -------
    ndarray, shape (M', 2)
    """
    P = np.asarray(points, dtype=float)
    if len(P) <= 2:
        return P.copy()
    keep = [0]
    i = 0
    while i < len(P) - 1:
        later = np.arange(i + 1, len(P))
        free = ~world.segment_collides(np.repeat(P[i][None], len(later), axis=0), P[later],
                                       radius=radius)
        ok = later[free]
        i = int(ok.max()) if ok.size else i + 1
        keep.append(i)
    return P[keep]


def resample_waypoints(points: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    """At least ``k`` intermediate points on a polyline, adding points on its longest segments.

    Parameters
    ----------
    points : ndarray, shape (M, 2)
        ``start, ..., goal``, ``M >= 2``.
    k : int
        Wanted number of intermediate points.

    Returns
    -------
    ndarray, shape (max(k, M - 2), 2)
        The intermediate points: the input's own (all kept) and, when ``M - 2 < k``, points that
        split the longest segments evenly (a segment split into ``m`` equal parts gets ``m - 1``
        points; the parts are assigned one by one to the segment whose parts are longest). The
        polyline through them is the input polyline.
    """
    P = np.asarray(points, dtype=float)
    seg = np.hypot(*np.diff(P, axis=0).T)
    parts = np.ones(len(seg), dtype=int)
    for _ in range(max(0, k - (len(P) - 2))):
        parts[int(np.argmax(seg / parts))] += 1
    out = []
    for j in range(len(seg)):
        if j > 0:
            out.append(P[j])
        for s in range(1, parts[j]):
            out.append(P[j] + (P[j + 1] - P[j]) * (s / parts[j]))
    return np.array(out).reshape(-1, 2)


def sample_along(points: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    """``k`` points evenly spaced by arc length along a polyline, its ends excluded.

    Parameters
    ----------
    points : ndarray, shape (M, 2)
        ``start, ..., goal``, ``M >= 2``.
    k : int
        Number of points.

    Returns
    -------
    ndarray, shape (k, 2)
        The points at arc lengths ``j L / (k + 1)``, ``j = 1 .. k`` (``L`` the polyline's length).
        Unlike :func:`resample_waypoints` the polyline through them cuts the input's corners.
    """
    P = np.asarray(points, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(P, axis=0).T))])
    at = s[-1] * np.arange(1, k + 1) / (k + 1)
    return np.stack([np.interp(at, s, P[:, 0]), np.interp(at, s, P[:, 1])], axis=1)


def _densify(points: NDArray[np.float64], spacing: float) -> tuple[NDArray, NDArray]:
    """Samples of a polyline at most ``spacing`` apart (every vertex kept) and their arc length."""
    P = np.asarray(points, dtype=float)
    out = [P[:1]]
    for a, b in itertools.pairwise(P):
        m = max(1, math.ceil(float(np.hypot(*(b - a))) / spacing))
        s = (np.arange(1, m + 1) / m)[:, None]
        out.append(a + s * (b - a))
    S = np.concatenate(out)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(S, axis=0).T))])
    return S, arc


@dataclass(eq=False)
class PlannedPath:
    """A robot's planned path.

    Attributes
    ----------
    found : bool
    points : ndarray, shape (M, 2)
        ``start, ..., goal`` (empty when not found).
    length : float
        Polyline length of ``points`` (``inf`` when not found).
    time : float
        Planning wall time in seconds.
    reason : str
        Why planning failed (empty when found).
    info : dict
        Method-specific details: ``grid``, the search result (``search``, ``rfd``), the PSO
        ``opt`` result, ``rfd_points`` and ``seed_points`` (RFD-PSO's RFD path and its seed
        particle as a path).
    metrics : dict
        Method-specific per-robot metrics for ``result.json`` (see the module docstring).
    """

    found: bool
    points: NDArray[np.float64]
    length: float
    time: float = 0.0
    reason: str = ""
    info: dict[str, Any] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)

    @property
    def waypoints(self) -> int:
        """Number of intermediate points."""
        return max(0, len(self.points) - 2)


def _failed(reason: str, **info: Any) -> PlannedPath:
    return PlannedPath(False, np.zeros((0, 2)), math.inf, reason=reason, info=info)


def _found(points: NDArray[np.float64], **info: Any) -> PlannedPath:
    points = np.asarray(points, dtype=float)
    return PlannedPath(True, points, path_length(points), info=info)
