"""What a step planner asks of a candidate next step: its fitness and whether it is feasible.

Both functions take a whole swarm of candidate points ``P`` of shape ``(N, 2)`` at once.

:func:`step_fitness` is ACO-Kinematic's eq. 13 (FAStep-Kinematic's eq. 10 is the same without the
line term)::

    f = a / f1 + b / f2 + c / f3 + d * ||P - goal||

with ``f1`` the sum of the distances from ``P`` to the centres of the circular obstacles (eq. 7-8),
``f2`` the sum of the minimum distances from ``P`` to the line segments (eq. 9-10; the paper's
*minimum distance technique* samples points on each segment and keeps the nearest, we use the exact
point-to-segment distance it approximates; the edges of rectangles and polygons count as line
segments) and ``f3`` the sum of the distances to the other robots (eq. 11-12). A term whose set is
empty (no circles, no lines, a single robot) is left out.

:func:`feasible_steps` is what the papers leave to the fitness and a serious planner cannot: it
simulates the robot's own compiled closed loop from its current state towards every candidate in
batched rollouts and rejects a candidate when the swept footprint comes closer than a safety
margin to an obstacle (moving circles where they are at each sample's time), to another robot or to
the workspace border before the robot gets within ``reach`` of it (:mod:`.sweep`: block by block,
pruned by bounding boxes).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from hybridnav.planners.step.sweep import sweep
from hybridnav.world import World, point_segment_distance

__all__ = ["GoalDistance", "Surroundings", "feasible_steps", "step_fitness"]

FloatArray = NDArray[np.float64]
#: the 2 x 2 cells round a point, (column, row) offsets from the lower left one
_CORNERS = np.array([[0, 0], [0, 1], [1, 0], [1, 1]])


@dataclass(frozen=True)
class Surroundings:
    """What one robot plans against, frozen at the planning time ``t``.

    Attributes
    ----------
    world : World
        The scenario's world (moving circles are evaluated at ``t + k * dt`` by the sweep).
    t : float
        Planning time.
    circles : ndarray, shape (C, 2)
        Centres of the circular obstacles at ``t`` (for ``f1``).
    edges : (ndarray, ndarray), each of shape (E, 2)
        Line segments (for ``f2``).
    robots : ndarray, shape (H, 2)
        Positions of the other robots (for ``f3``).
    robot_discs : (ndarray, ndarray)
        Footprint disk centres ``(D, 2)`` and radii ``(D,)`` of the other robots (obstacles for
        the sweep, frozen at ``t``).
    static, moving : World
        The world's static obstacles and its moving circles.
    """

    world: World
    t: float
    circles: FloatArray
    edges: tuple[FloatArray, FloatArray]
    robots: FloatArray
    robot_discs: tuple[FloatArray, FloatArray]
    static: World
    moving: World

    @classmethod
    def at(cls, world: World, t: float, robots: FloatArray,
           robot_discs: tuple[FloatArray, FloatArray]) -> Surroundings:
        centres, _ = world.circles(t)
        return cls(world, float(t), centres, world.edges(), np.asarray(robots, float).reshape(-1, 2),
                   robot_discs, world.static(), world.moving())

    @cached_property
    def frozen_boxes(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Boxes ``lo, hi`` (K, 2) and pads (K,) of what stands still while a step is planned:
        the static obstacles (:meth:`World.boxes`), then the other robots' disks (the centre
        and the radius). Computed once for the many checks of one plan."""
        lo, hi, pad = self.static.boxes()
        oc = np.asarray(self.robot_discs[0], dtype=float).reshape(-1, 2)
        return (np.concatenate([lo, oc]), np.concatenate([hi, oc]),
                np.concatenate([pad, np.asarray(self.robot_discs[1], dtype=float).reshape(-1)]))


def step_fitness(P: FloatArray, goal: FloatArray, env: Surroundings, a: float, b: float, c: float,
                 d: float, goal_distance: Callable[[FloatArray, FloatArray], FloatArray] | None
                 = None) -> FloatArray:
    """ACO-Kinematic's step fitness (eq. 13) of the candidates ``P`` ``(N, 2)``; lower is better.

    ``goal_distance(P, goal)`` measures the distance term (default: straight-line, as the papers;
    :class:`GoalDistance` measures it along the shortest obstacle-free path).
    """
    P = np.asarray(P, dtype=float)
    if goal_distance is None:
        f = d * np.hypot(P[:, 0] - goal[0], P[:, 1] - goal[1])
    else:
        f = d * goal_distance(P, goal)
    with np.errstate(divide="ignore"):
        if len(env.circles):
            diff = P[:, None, :] - env.circles[None]
            f = f + a / np.hypot(diff[..., 0], diff[..., 1]).sum(axis=1)
        A, B = env.edges
        if len(A):
            dist, _ = point_segment_distance(P[:, None, :], A[None], B[None])
            f = f + b / dist.sum(axis=1)
        if len(env.robots):
            diff = P[:, None, :] - env.robots[None]
            f = f + c / np.hypot(diff[..., 0], diff[..., 1]).sum(axis=1)
    return f


def feasible_steps(model, x0: FloatArray, P: FloatArray, env: Surroundings, *, steps: int,
                   reach: float, margin: float,
                   end_margin: float | None = None) -> NDArray[np.bool_]:
    """Whether driving from ``x0`` towards each candidate keeps the footprint safe.

    Parameters
    ----------
    model : Model
        The robot's model at the planning step ``model.dt`` (compiled, batched rollout).
    x0 : ndarray, shape (nx,)
        The robot's current state.
    P : ndarray, shape (N, 2)
        Candidate targets.
    env : Surroundings
    steps : int
        Rollout length (the look-ahead horizon is ``steps * model.dt``).
    reach : float
        The move ends when the robot is within ``reach`` of its candidate (later samples are not
        checked: the planner picks the next step there).
    margin : float
        Required clearance between each footprint disk and obstacles, other robots and the
        workspace border, beyond touching, along the rollout.
    end_margin : float, optional
        Clearance of the whole-body disk (radius ``model.radius``) swept straight from where the
        move ends to the candidate (default ``margin``).

    Returns
    -------
    ndarray of bool, shape (N,)
        The footprint, swept along straight pieces between consecutive rollout samples, keeps
        ``margin``, and the candidate is in sight from where the move ends. (Moving circles are
        frozen at each piece's start time.)

    Notes
    -----
    The rollout and the sweep run block by block (:func:`~hybridnav.planners.step.sweep.
    sweep`): a candidate is integrated no further once its move ends or collides, and only the
    pieces of stretches whose bounding box comes near something are tested exactly.
    """
    P = np.asarray(P, dtype=float).reshape(-1, 2)
    if P.shape[0] == 0:
        return np.ones(0, dtype=bool)
    return sweep(model, x0, P, env, steps=steps, reach=reach, margin=margin,
                 end_margin=end_margin)


class GoalDistance:
    """Distance to a goal along the shortest obstacle-free path (a grid's cost-to-go field).

    The scenario's static obstacles are rasterized (:func:`hybridnav.world.grid.build_grid`, 1/100
    of the shorter workspace side unless the scenario's ``[grid]`` says otherwise) with cells
    closer than ``inflate`` (the robot's radius) to an obstacle blocked. The goal is a node of its
    own, joined by straight segments to every free cell inside its *free disk* (the largest disk
    round the goal that no static obstacle reaches), weighted by the straight-line distance;
    one Dijkstra search from it (:func:`scipy.sparse.csgraph.dijkstra` on
    :meth:`OccupancyGrid.adjacency`, 8-connected, no corner cutting) gives every free cell's
    cost-to-go ``g``. A point's distance is the straight-line distance inside the free disk (so
    it is 0 at the goal itself, and exact wherever the goal is in plain sight across free space),
    elsewhere ``min(g(c) + ||P - c||)`` over the centres ``c`` of the 2 x 2 cells around it
    (``inf`` where they are all blocked or cut off from the goal). It is never below the
    straight-line distance; behind an obstacle it is the way round (octile moves: within a few
    percent), so a step planner does not walk into a cup-shaped trap just because its bottom is
    near the goal. A goal whose free disk holds no free cell (closer to an obstacle than about
    ``inflate``) is joined to the nearest free cell instead. Fields are cached per goal.
    """

    def __init__(self, scenario, inflate: float) -> None:
        from hybridnav.world.grid import build_grid

        self.grid = build_grid(scenario, inflate=float(inflate))
        self._adj = self.grid.adjacency()
        occ = self.grid.occ.ravel()
        self._free = np.flatnonzero(~occ)
        self._world = scenario.world.static()
        g = self.grid
        self._free_centres = g.to_world(np.stack([self._free % g.width, self._free // g.width],
                                                 axis=1))
        self._fields: dict[tuple[float, float], tuple[FloatArray, float]] = {}

    def free_radius(self, goal: FloatArray) -> float:
        """Radius of the goal's free disk: the distance to the nearest static obstacle's surface.

        Parameters
        ----------
        goal : ndarray
            The goal (2,).

        Returns
        -------
        float
            ``inf`` in a world without static obstacles; 0 for a goal inside one.
        """
        if not self._world.obstacles:
            return math.inf
        return max(0.0, float(self._world.clearance(np.asarray(goal, float).reshape(1, 2))[0]))

    def field(self, goal: FloatArray) -> FloatArray:
        """Cost-to-go of every cell (flat, ``row * width + col``) for ``goal``."""
        return self._field(goal)[0]

    def _field(self, goal: FloatArray) -> tuple[FloatArray, float]:
        from scipy.sparse import csr_matrix
        from scipy.sparse import vstack as sparse_vstack
        from scipy.sparse.csgraph import dijkstra

        goal = np.asarray(goal, float).reshape(2)
        key = (float(goal[0]), float(goal[1]))
        if key in self._fields:
            return self._fields[key]
        n = self.grid.occ.size
        if not len(self._free):
            out = (np.full(n, np.inf), 0.0)
            self._fields[key] = out
            return out
        d = np.hypot(*(self._free_centres - goal).T)
        radius = self.free_radius(goal)
        near = d < radius
        if not near.any():  # no free cell in the free disk: the nearest free cell
            near = d == d.min()
        # the goal is node n; its edges are straight segments (a zero weight would be no edge)
        w = np.maximum(d[near], np.finfo(float).tiny)
        row = csr_matrix((w, (np.zeros(len(w), dtype=int), self._free[near])), shape=(1, n + 1))
        adj = self._adj.copy()
        adj.resize((n, n + 1))
        graph = sparse_vstack([adj, row]).tocsr()
        field = dijkstra(graph, indices=n)[:n]
        field[self.grid.occ.ravel()] = np.inf
        if len(self._fields) > 64:
            self._fields.pop(next(iter(self._fields)))
        self._fields[key] = (field, radius)
        return field, radius

    def __call__(self, P: FloatArray, goal: FloatArray) -> FloatArray:
        g = self.grid
        field, radius = self._field(goal)
        P = np.asarray(P, dtype=float).reshape(-1, 2)
        goal = np.asarray(goal, float).reshape(2)
        # the 2 x 2 cell centres around each point
        base = np.floor((P - np.asarray(g.origin)) / g.resolution - 0.5).astype(int)
        cells = (base[None] + _CORNERS[:, None]).reshape(-1, 2)         # (4 N, 2), corner-major
        inside = g.in_bounds(cells)
        val = np.full(len(cells), np.inf)
        val[inside] = field[g.cell_index(cells[inside])]
        c = g.to_world(cells)
        P4 = np.tile(P, (4, 1))
        best = (val + np.hypot(P4[:, 0] - c[:, 0], P4[:, 1] - c[:, 1])).reshape(4, -1).min(axis=0)
        straight = np.hypot(P[:, 0] - goal[0], P[:, 1] - goal[1])
        return np.where(straight < radius, straight, best)
