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
one batched rollout and rejects a candidate when the swept footprint comes closer than a safety
margin to an obstacle (moving circles where they are at each sample's time), to another robot or to
the workspace border before the robot gets within ``reach`` of it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hybridnav.world import World, point_segment_distance

__all__ = ["GoalDistance", "Surroundings", "feasible_steps", "step_fitness"]

FloatArray = NDArray[np.float64]

# segments checked per block (bounds the memory of the (segments, obstacles) distance arrays)
_BLOCK = 1 << 16
# rollout pieces per stretch whose safety is first bounded from the clearance at its two ends
_STRIDE = 8
# control cycles integrated at a time: a candidate the robot has reached is not integrated
# further (a multiple of _STRIDE, so every stretch a used piece lies in is computed)
_ROLL_BLOCK = 8 * _STRIDE


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


def rollout_until_reached(model, x0: FloatArray, P: FloatArray, steps: int,
                          reach: float) -> FloatArray:
    """``model.rollout`` from ``x0`` towards each candidate, integrated :data:`_ROLL_BLOCK`
    cycles at a time and no further for a candidate once a sample is within ``reach`` of it.

    What :func:`feasible_steps` reads is the same as the full rollout's, sample for sample:
    everything up to the end of the block in which the move ends (the RK4 cycle is a function of
    the state and the target alone). Later samples, which it does not read, repeat that last
    state.

    Parameters
    ----------
    model : Model
    x0 : ndarray, shape (nx,)
    P : ndarray, shape (N, 2)
    steps : int
    reach : float

    Returns
    -------
    ndarray, shape (N, steps + 1, nx)
    """
    n = len(P)
    traj = np.empty((n, steps + 1, model.nx))
    traj[:, 0] = x0
    active = np.flatnonzero(np.hypot(x0[0] - P[:, 0], x0[1] - P[:, 1]) > reach)
    traj[np.setdiff1d(np.arange(n), active), 1:] = x0
    k = 0
    while k < steps and len(active):
        b = min(_ROLL_BLOCK, steps - k)
        part = model.rollout(traj[active, k], P[active], b)[:, 1:]       # (na, b, nx)
        traj[active, k + 1:k + b + 1] = part
        d = np.hypot(part[:, :, 0] - P[active, None, 0], part[:, :, 1] - P[active, None, 1])
        done = (d <= reach).any(axis=1)
        k += b
        finished = active[done]
        traj[finished, k + 1:] = traj[finished, k][:, None]
        active = active[~done]
    return traj


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
    """
    P = np.asarray(P, dtype=float).reshape(-1, 2)
    n = P.shape[0]
    ok = np.ones(n, dtype=bool)
    if n == 0:
        return ok
    traj = rollout_until_reached(model, x0, P, steps, reach)            # (n, steps+1, nx)
    # a move ends at its first sample within reach of the candidate
    dist = np.hypot(traj[:, :, 0] - P[:, None, 0], traj[:, :, 1] - P[:, None, 1])
    within = dist <= reach
    last = np.where(within.any(axis=1), within.argmax(axis=1), steps)     # last checked sample
    used = np.arange(steps)[None, :] < last[:, None]                    # pieces k -> k+1
    # the candidate itself must be in sight: the whole-body disk swept straight from where the
    # move ends to the candidate keeps the margin too (the next step is planned from there)
    end = traj[np.arange(n), last, :2]
    body = model.radius + (margin if end_margin is None else end_margin)
    world = env.world
    t_end = env.t + last * model.dt
    if world.obstacles:
        ok &= ~world.segment_collides(end, P, radius=body, t=t_end)
    other_c, other_r = env.robot_discs
    if len(other_r):
        dd, _ = point_segment_distance(other_c[None], end[:, None], P[:, None])
        ok &= ~np.any(dd < body + other_r[None], axis=1)
    if not used.any():
        return ok
    coarse = np.arange(0, steps + 1, _STRIDE)
    if coarse[-1] != steps:
        coarse = np.append(coarse, steps)
    chunk_of = np.searchsorted(coarse, np.arange(steps), side="right") - 1  # piece -> stretch
    # the last stretch a candidate's used pieces lie in, and the samples any of them needs:
    # nothing after that is read, so the footprint and clearances stop there
    top = np.where(last > 0, chunk_of[np.maximum(last, 1) - 1] + 1, 0)
    horizon = int(coarse[top.max()])
    if horizon < steps:
        steps, traj, used = horizon, traj[:, :horizon + 1], used[:, :horizon]
        coarse, chunk_of = coarse[:top.max() + 1], chunk_of[:horizon]
    centres, radii = model.footprint(traj.reshape(-1, model.nx))
    centres = centres.reshape(n, steps + 1, len(radii), 2)
    static, moving = env.static, env.moving
    needed = np.arange(len(coarse))[None, :] <= top[:, None]          # coarse samples read
    bad = np.zeros(n, dtype=bool)

    def frozen_clearance(Q: FloatArray) -> FloatArray:
        # everything that does not move during the plan: static obstacles, border, other robots
        c = world.border_clearance(Q)
        if static.obstacles:
            c = np.minimum(c, static.clearance(Q))
        if len(other_r):
            d = np.hypot(Q[:, None, 0] - other_c[None, :, 0], Q[:, None, 1] - other_c[None, :, 1])
            c = np.minimum(c, np.min(d - other_r[None], axis=1))
        return c

    for j, rad in enumerate(radii):
        need = rad + margin
        C = centres[:, :, j]
        # A stretch of the move between two samples with clearances cA, cB and arc length s
        # cannot come closer than (cA + cB - s) / 2 to anything frozen (each of its points is
        # within arc length a of one sample and s - a of the other): stretches of _STRIDE pieces
        # proven safe that way skip the exact swept-disk tests of their pieces.
        seg = np.hypot(*np.diff(C, axis=1).transpose(2, 0, 1))                  # (n, steps)
        arc = np.concatenate([np.zeros((n, 1)), np.cumsum(seg, axis=1)], axis=1)
        pts = C[:, coarse][needed]
        clear = np.full((n, len(coarse)), np.inf)              # inf: a stretch nobody uses
        got = np.empty(len(pts))
        for lo in range(0, len(pts), _BLOCK):
            got[lo:lo + _BLOCK] = frozen_clearance(pts[lo:lo + _BLOCK])
        clear[needed] = got
        bound = 0.5 * (clear[:, :-1] + clear[:, 1:] - np.diff(arc[:, coarse], axis=1))
        rows, ks = np.nonzero(used & (bound < need)[:, chunk_of])
        for lo in range(0, len(rows), _BLOCK):
            r_, k_ = rows[lo:lo + _BLOCK], ks[lo:lo + _BLOCK]
            A, B = C[r_, k_], C[r_, k_ + 1]
            hit = ~world.inside_workspace(B, need)
            if static.obstacles:
                hit |= static.segment_collides(A, B, radius=need)
            if len(other_r):
                dd, _ = point_segment_distance(other_c[None], A[:, None], B[:, None])
                hit |= np.any(dd < need + other_r[None], axis=1)
            bad[r_[hit]] = True
        if moving.obstacles:
            rows, ks = np.nonzero(used)
            for lo in range(0, len(rows), _BLOCK):
                r_, k_ = rows[lo:lo + _BLOCK], ks[lo:lo + _BLOCK]
                hit = moving.segment_collides(C[r_, k_], C[r_, k_ + 1], radius=need,
                                              t=env.t + k_ * model.dt)
                bad[r_[hit]] = True
    return ok & ~bad


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
        best = np.full(len(P), np.inf)
        for dc in (0, 1):
            for dr in (0, 1):
                cells = base + np.array([dc, dr])
                inside = g.in_bounds(cells)
                val = np.full(len(P), np.inf)
                val[inside] = field[g.cell_index(cells[inside])]
                c = g.to_world(cells)
                best = np.minimum(best, val + np.hypot(P[:, 0] - c[:, 0], P[:, 1] - c[:, 1]))
        straight = np.hypot(P[:, 0] - goal[0], P[:, 1] - goal[1])
        return np.where(straight < radius, straight, best)
