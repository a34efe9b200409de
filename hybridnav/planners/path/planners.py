"""Plan once, then track: grid A*/Dijkstra, river formation dynamics, PSO and RFD-PSO.

Every planner here plans, for each robot in turn, one path from its start to its goal around the
scenario's *static* obstacles, then the robot follows that path in the shared closed loop
(:func:`hybridnav.planners.simulate.simulate`) with a pure-pursuit tracking controller. Nothing is
replanned: moving obstacles and moving targets are refused (``moving_obstacles`` and
``moving_targets`` are False), and the other robots are left to the shared collision check.

Obstacles and units
-------------------
The obstacle model is the scenario's static obstacles, plus, for a scenario with a ``[grid] map``
(e.g. ``arena``, whose map is its only obstacle model), one axis-aligned rectangle per run of
blocked map cells (:func:`obstacle_world`). The tracking run is simulated against that same model,
so ``collided`` and ``min_clearance`` also count the map's cells.

The *cell* is the scenario's grid resolution (``[grid] resolution``; without ``[grid]``, 1/100 of
the shorter workspace side, as :func:`hybridnav.world.grid.build_grid` rasterizes): ``speed``,
``lookahead`` and ``margin`` are given in cells, so one set of defaults suits the 700 cm
``rfd-pso-700`` (10 cm cells) and the 49-cell ``arena``.

The grid planners (``astar``, ``dijkstra``, ``rfd`` and the RFD stage of ``rfd-pso``) search the
scenario's grid unless their ``grid`` parameter asks for another one: ``grid = n`` rasterizes the
workspace at ``n`` cells across its shorter side (a scenario with a ``[grid] map`` keeps the map's
cells, which are its obstacle model). That changes the planning grid only: the *cell* above, the
unit of ``speed``, ``lookahead`` and ``margin``, stays the scenario's.

The RFD-PSO paper's grid (profile ``paper``: ``grid = 20``)
    The paper never states its grids, but its three maps are 20 x 20: Table 4's alley map is a
    20 x 20 cell map (its lengths are in cells: Dijkstra's and A*'s 33.48 is 25 straight and 6
    diagonal moves), and the 20 x 20 m map is the map of the ant-colony papers it compares with
    in Table 3 (SAACO [28], FACO [29]), which by our reading is a grid map of 20 x 20 cells of
    1 m, as grid maps in that literature usually are (we could not check [28, 29]). With one RFD
    implementation for all three maps, the 700 x 700 cm map is 20 x 20 too, 35 cm cells (a cell
    holds the 20 cm robot). On our 0.25 m grid of the 20 x 20 m map (80 x 80 cells) flat RFD's
    20 drops rarely reach the goal at all; on the 1 m grid they do, at lengths near the paper's
    32.68 m (see ``tests/test_rfdpso_profile.py``). On a grid this coarse the straight segment
    between two free cell centres can pass an obstacle corner closer than the robot radius (the
    inflation tests cell centres only): ``rfd`` with ``grid = 20`` collides in some runs of
    ``rfd-pso-700``.

Planners
--------
``astar``, ``dijkstra``
    Optimal 8-connected octile search (:mod:`hybridnav.planners.path.gridsearch`) on
    ``build_grid(scenario, inflate=radius + margin)``: cells whose centre is closer than the robot
    radius plus ``margin`` to an obstacle are blocked.
``rfd``
    River formation dynamics (:func:`hybridnav.planners.path.rfd_core.rfd`) on the same grid.
``pso``
    Particle swarm optimization (:func:`hybridnav.planners.swarm.pso`) over ``waypoints`` (K)
    intermediate points in the continuous workspace; a particle is the ``2K`` vector
    ``(x1, y1, ..., xK, yK)`` inside the workspace shrunk by the robot radius plus ``margin``, and
    its cost is the length of the polyline ``start, w1, ..., wK, goal`` plus ``penalty`` workspace
    diagonals for every one of its ``K + 1`` segments along which a disk of the robot radius plus
    ``margin`` would meet an obstacle (:meth:`hybridnav.world.World.segment_collides`). Velocity
    clamping (``vmax``) and reflection at the box are :func:`~hybridnav.planners.swarm.pso`'s.
    The swarm starts uniformly at random in the box, each particle's waypoints sorted by their
    projection on the start -> goal direction (the same random points, visited without needless
    back-and-forth). The defaults are the RFD-PSO paper's Table 1 (``w = 0.5``, ``c1 = c2 =
    0.75``) for both swarm planners, so ``pso`` is the paper's PSO baseline. With these
    low-energy settings the swarm converges within a few tens of iterations and, in cluttered
    maps, often onto a path with one colliding segment: then the plan fails (``stuck``), unless
    ``restarts`` allows further runs from new random swarms (the first collision-free run wins;
    all runs count into ``planning_time``).
``rfd-pso``
    RFD-PSO (Hassen, Amin & Al-Araji 2023): RFD first, then the same PSO with one particle seeded
    from the RFD path. The seed is the RFD path *resampled to K waypoints*: its corners are pulled
    tight first (from each vertex, the farthest later vertex whose segment is collision-free under
    the PSO's own test becomes the next corner; so the seed's vertices lie on the RFD path and it
    is no longer than it), then points are added on the longest segments until there are K. When
    the pulled path needs more than K corners, K is raised to that number for this robot (the
    ``waypoints`` metric reports the K used). The PSO keeps its best point, so whenever the
    seed is collision-free the planned path is collision-free and no longer than the RFD path.
    ``rfd`` and ``rfd-pso`` run with the same seed (and ``grid``) plan identical RFD paths.

    Profile ``paper`` (the paper's seeding, section 4.3: "one of the particles in the PSO
    algorithm starts from this RFD channel") seeds the RFD path itself, sampled at K points
    evenly along its length (``shorten = false``), with ``K = 28``: a particle that holds the
    RFD path has one waypoint per interior cell of it, and a grid path of the paper's RFD length
    (32.68 m) between opposite corner cells of the 20 x 20 grid of 1 m cells (the start and goal
    of our reconstruction) has 29 moves (20 straight and 9 diagonal, 32.73 m), so 28 interior
    cells. The paper gives no K. With the 8 waypoints of profile ``hybridnav`` the sampled seed
    cuts the RFD path's corners through obstacles, and on ``rfd-pso-20m`` the plan failed in 3
    of 6 seeds (0-5); K = 16, 20, 24, 25, 28 and 30 reached in all 6.

A planned path is always ``start, ..., goal`` (grid paths: the start, the centres of the cells
between the start cell and the goal cell, the goal). A robot for which no path is found (goal
unreachable on the inflated grid, start or goal cell blocked by the inflation, or no
collision-free PSO path) ends ``stuck`` at its start; that is not an exception.

Tracking
--------
The path is sampled densely (all its vertices kept). Each control cycle the robot's progress is
the nearest sample within ``2 lookahead`` ahead of its previous progress (never backwards); the
carrot is the sample ``lookahead`` further along. The commanded velocity points at the carrot with
``speed`` (scaled down by ``distance to goal / lookahead`` within ``lookahead`` of the goal), and
the robot's model turns it into its target point (:meth:`hybridnav.models.Model.carrot`): a point
mass then moves at exactly that velocity; a unicycle (the paper's differential drive, its default
go-to-point controller) drives at that speed once it faces the carrot.

Metrics
-------
Each robot's ``result.json`` entry gets ``planned_length`` (length of the planned path
``start, ..., goal``; null when none was found), ``planning_time`` (seconds, also counted in
``compute_time``) and ``waypoints`` (intermediate points of the planned path), and

* ``astar``, ``dijkstra``: ``grid_length`` (the cell path's length, centre to centre: the number
  MovingAI's optimal lengths give) and ``expanded`` (nodes expanded);
* ``rfd``: ``grid_length`` and ``rfd_iterations``;
* ``pso``: ``pso_runs`` (1 plus the restarts used);
* ``rfd-pso``: ``rfd_length`` (its RFD stage's planned length, as ``rfd`` reports it),
  ``rfd_iterations`` and ``pso_runs``.

Where the start or goal is not a cell centre, ``planned_length`` and ``grid_length`` differ a
little, and two optimal cell paths (A* and Dijkstra may return different ones) can give different
``planned_length``.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from abc import abstractmethod
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from hybridnav.params import check_seed
from hybridnav.planners.base import Param, Planner, searches_table
from hybridnav.planners.path.geometry import (
    PlannedPath,
    _cell_size,
    _densify,
    _failed,
    _found,
    grid_rectangles,
    obstacle_world,
    pull_tight,
    resample_waypoints,
    sample_along,
)
from hybridnav.planners.path.gridsearch import HEURISTICS, astar, dijkstra
from hybridnav.planners.path.rfd_core import rfd
from hybridnav.planners.simulate import Simulation, model_groups, simulate
from hybridnav.planners.swarm import pso
from hybridnav.results import Result
from hybridnav.world import World
from hybridnav.world.grid import OccupancyGrid, build_grid

__all__ = [
    "AStarPlanner",
    "DijkstraPlanner",
    "PSOPathPlanner",
    "PathPlanner",
    "PlannedPath",
    "RFDPSOPlanner",
    "RFDPlanner",
    "grid_rectangles",
    "obstacle_world",
    "pull_tight",
    "resample_waypoints",
]

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------------------------
# Planners
# --------------------------------------------------------------------------------------------

TRACKING: dict[str, Param] = {
    "speed": Param(1.0, "tracking speed, cells of the scenario's grid per second", lo=0.0,
                   lo_open=True),
    "lookahead": Param(0.5, "pure-pursuit carrot distance along the path, cells of the "
                            "scenario's grid", lo=0.0, lo_open=True),
    "margin": Param(0.25, "clearance kept beyond the robot radius when planning, cells of the "
                          "scenario's grid (whatever `grid` is)", lo=0.0),
    "stuck_window": Param(10.0, "seconds without leaving a small disk that count as stuck "
                                "(0: off)", lo=0.0),
    "stuck_radius": Param(0.1, "that disk's radius, as a fraction of the distance covered at "
                               "speed in stuck_window", lo=0.0),
}


@dataclass
class _Context:
    """What every robot's planning shares within one run."""

    scenario: Any
    world: World          # the static obstacle model (map cells included)
    cell: float           # the length unit
    grids: dict[tuple[float, int], OccupancyGrid] = field(default_factory=dict)

    def grid(self, inflate: float, cells: int = 0) -> OccupancyGrid:
        """``build_grid(scenario, inflate=inflate)``, with the cells whose centre is closer than
        ``inflate`` to the workspace boundary blocked too.

        ``cells > 0`` rasterizes at ``cells`` cells across the workspace's shorter side instead
        of the scenario's ``[grid] resolution`` (the planners' ``grid`` parameter); a scenario
        with a ``[grid] map`` keeps the map's own cells (the map is the obstacle model)."""
        key = (inflate, cells)
        if key not in self.grids:
            resolution = None
            mapped = self.scenario.grid is not None and self.scenario.grid.map is not None
            if cells and not mapped:
                xmin, xmax, ymin, ymax = self.world.workspace
                resolution = min(xmax - xmin, ymax - ymin) / cells
            g = build_grid(self.scenario, resolution=resolution, inflate=inflate)
            centres = np.argwhere(np.ones(g.shape, dtype=bool))[:, ::-1]
            near = self.world.border_clearance(g.to_world(centres)) < inflate
            self.grids[key] = OccupancyGrid(g.occ | near.reshape(g.shape), g.resolution,
                                            g.origin, g.source)
        return self.grids[key]


class PathPlanner(Planner):
    """Base of the plan-then-track planners: :meth:`plan` one path per robot, then follow it."""

    drives: ClassVar[tuple[frozenset[str], ...]] = (frozenset({"disk"}),)   # grid paths: one disk
    moving_obstacles: ClassVar[bool] = False
    moving_targets: ClassVar[bool] = False
    parameters: ClassVar[dict[str, Param]] = dict(TRACKING)

    @abstractmethod
    def plan(self, ctx: _Context, robot, rngs: list[np.random.Generator]) -> PlannedPath:
        """Plan the path of one robot (``rngs``: two generators, the RFD's and the PSO's)."""

    def _clearance(self, ctx: _Context, robot) -> float:
        """Robot radius plus the margin, in world units."""
        return float(robot.radius) + self.values["margin"] * ctx.cell

    def _shortened(self, ctx: _Context, robot, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """``points`` pulled tight under the planner's clearance when ``shorten`` is set."""
        if not self.values.get("shorten"):
            return points
        return pull_tight(points, ctx.world, self._clearance(ctx, robot))

    def plans(self, scenario, seed: int | None = None) -> list[PlannedPath]:
        """Plan every robot's path without simulating: the paths :meth:`run` follows with the
        same seed (with the planner's internals in ``info``: its grid, search, swarm result)."""
        return self._plan_all(scenario, seed)[2]

    def _plan_all(self, scenario, seed):
        self.check_scenario(scenario)
        world = obstacle_world(scenario)
        ctx = _Context(scenario, world, _cell_size(scenario))
        children = np.random.SeedSequence(seed).spawn(len(scenario.robots))
        plans: list[PlannedPath] = []
        for robot, child in zip(scenario.robots, children):
            rngs = [np.random.default_rng(s) for s in child.spawn(2)]
            tic = time.perf_counter()
            p = self.plan(ctx, robot, rngs)
            p.time = time.perf_counter() - tic
            if not p.found:
                log.info("%s: robot %s: no path (%s)", self.name, robot.name, p.reason)
            plans.append(p)
        return ctx, world, plans

    def run(self, scenario, seed: int | None = None) -> Result:
        """Plan every robot's path, then simulate the robots following them.

        Parameters
        ----------
        scenario : Scenario
        seed : int or None
            Seeds the RFD drops and the swarm (robot ``i`` uses the ``i``-th child of
            ``numpy.random.SeedSequence(seed)``, split in two: RFD, PSO); equal seeds give equal
            results.

        Returns
        -------
        Result
            Per robot, ``planned_length``, ``planning_time`` and ``waypoints`` in ``metrics``.
        """
        seed = check_seed(seed)
        ctx, world, plans = self._plan_all(scenario, seed)
        sim_scenario = scenario
        if scenario.grid is not None and scenario.grid.map is not None:
            sim_scenario = dataclasses.replace(scenario, world=world)   # map cells as obstacles
        models = [scenario.model(r) for r in scenario.robots]
        robots, _ = simulate(sim_scenario, models, self._controller(ctx, plans, models),
                             stuck_window=self.values["stuck_window"],
                             stuck_radius=self.values["stuck_radius"] * self.values["speed"]
                             * ctx.cell * self.values["stuck_window"])
        for r, p in zip(robots, plans):
            r.compute_time += p.time
            r.metrics.update(planned_length=p.length if p.found else None,
                             planning_time=p.time, waypoints=p.waypoints if p.found else None,
                             **p.metrics)
        return Result(scenario=scenario.name, planner=self.name, params=self.describe(),
                      seed=seed, robots=robots, extras=_plan_extras(scenario, plans))

    def _controller(self, ctx: _Context, plans: list[PlannedPath], models):
        """The pure-pursuit controller of every robot (see the module docstring)."""
        cell = ctx.cell
        speed = self.values["speed"] * cell
        look = self.values["lookahead"] * cell
        spacing = min(look, speed * ctx.scenario.dt) / 4.0
        tracks = [_densify(p.points, spacing) if p.found else None for p in plans]
        progress = np.zeros(len(plans), dtype=int)
        groups = model_groups(models)
        goals = np.array([p.points[-1] if p.found else np.zeros(2) for p in plans])

        def controller(sim: Simulation) -> np.ndarray:
            V = np.zeros((sim.n, 2))
            P = sim.positions
            for i in np.flatnonzero(sim.active):
                if tracks[i] is None:
                    sim.stop(int(i), "stuck")
                    continue
                S, arc = tracks[i]
                k = progress[i]
                hi = int(np.searchsorted(arc, arc[k] + 2.0 * look, side="right"))
                k = k + int(np.argmin(np.hypot(*(S[k:hi] - P[i]).T)))
                progress[i] = k
                c = min(int(np.searchsorted(arc, arc[k] + look)), len(S) - 1)
                d = S[c] - P[i]
                dist = float(np.hypot(*d))
                if dist > 0.0:
                    to_goal = float(np.hypot(*(goals[i] - P[i])))
                    V[i] = d * (speed * min(1.0, to_goal / look) / dist)
            T = np.full((sim.n, 2), np.nan)
            for model, members in groups:       # one carrot call per model group
                act = members[sim.active[members]]
                if len(act):
                    T[act] = model.carrot(np.array([sim.X[i] for i in act]), V[act])
            return T

        return controller

    def diagnostics(self, scenario, result: Result) -> dict[str, Any]:
        """``planned_paths.png``: the runs with the planned paths (and the swarm's best cost)."""
        from hybridnav.plotting import plot_planned

        fig = plot_planned(scenario, result)
        return {} if fig is None else {"planned_paths.png": fig}


def _grid_endpoints(grid: OccupancyGrid, robot) -> tuple | PlannedPath:
    """The start and goal cells, or a failed plan when one is outside or blocked."""
    cells = []
    for what, p in (("start", robot.start), ("goal", robot.goal)):
        c = grid.to_cell(np.asarray(p, dtype=float))[0]
        if grid.blocked_cells(c)[0]:
            return _failed(f"{what} cell {tuple(c.tolist())} is blocked once obstacles are "
                           f"inflated by the robot radius plus the margin", grid=grid)
        cells.append((int(c[0]), int(c[1])))
    return cells[0], cells[1]


def _cells_to_path(robot, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Start, the centres of the cells strictly between the start and goal cells, goal."""
    inner = np.asarray(points, dtype=float)[1:-1]
    return np.vstack([np.asarray(robot.start, dtype=float)[None], inner,
                      np.asarray(robot.goal, dtype=float)[None]])


GRID: dict[str, Param] = {
    "grid": Param(0, "planning grid: cells across the workspace's shorter side (0: the "
                     "scenario's [grid] resolution; a [grid] map keeps its own cells); the "
                     "RFD-PSO paper's maps are 20 x 20 cells, so profile 'paper' of rfd and "
                     "rfd-pso sets 20: 1 m cells on rfd-pso-20m, 35 cm on rfd-pso-700",
                  lo=0),
    "diagonal": Param(True, "8-connected octile moves (false: 4-connected)"),
    "corner_cutting": Param(False, "allow a diagonal move past a blocked orthogonal cell"),
    "shorten": Param(False, "pull the grid path tight before tracking (drop the corners a "
                            "collision-free shortcut skips; for ablations)"),
}


class AStarPlanner(PathPlanner):
    """A* on the inflated occupancy grid, then pure-pursuit tracking."""

    name = "astar"
    description = "A* on the inflated grid (octile, no corner cutting), pure-pursuit tracking"
    parameters: ClassVar[dict[str, Param]] = {
        **GRID,
        "heuristic": Param("octile", "A* heuristic", choices=HEURISTICS),
        **TRACKING,
    }

    def search(self, grid, s, t):
        v = self.values
        return astar(grid, s, t, diagonal=v["diagonal"], corner_cutting=v["corner_cutting"],
                     heuristic=v["heuristic"])

    def plan(self, ctx, robot, rngs):
        grid = ctx.grid(self._clearance(ctx, robot), self.values["grid"])
        ends = _grid_endpoints(grid, robot)
        if isinstance(ends, PlannedPath):
            return ends
        gp = self.search(grid, *ends)
        if not gp.found:
            out = _failed("the goal cell is not reachable from the start cell", grid=grid,
                          search=gp)
        else:
            out = _found(self._shortened(ctx, robot, _cells_to_path(robot, gp.points)),
                         grid=grid, search=gp)
        out.metrics.update(grid_length=gp.length, expanded=gp.expanded)
        return out


class DijkstraPlanner(AStarPlanner):
    """Dijkstra's algorithm on the inflated occupancy grid, then pure-pursuit tracking."""

    name = "dijkstra"
    description = "Dijkstra on the inflated grid (octile, no corner cutting), pure-pursuit tracking"
    parameters: ClassVar[dict[str, Param]] = {**GRID, **TRACKING}

    def search(self, grid, s, t):
        v = self.values
        return dijkstra(grid, s, t, diagonal=v["diagonal"], corner_cutting=v["corner_cutting"])


RFD: dict[str, Param] = {
    "drops": Param(20, "RFD: drops released per iteration (the paper: 20)", lo=1),
    "rfd_iterations": Param(300, "RFD: iteration cap", lo=1),
    "patience": Param(60, "RFD: stop after this many iterations without a shorter path", lo=1),
    "slope": Param(0.01, "RFD: initial terrain tilt towards the goal (0: flat, standard RFD)",
                   lo=0.0),
}

SWARM: dict[str, Param] = {
    "waypoints": Param(8, "PSO: intermediate waypoints K of a path (profile 'paper': 28, one "
                          "per interior cell of an RFD path of the paper's 32.68 m on its 20 x "
                          "20 grid; the paper gives no K)", lo=1),
    "particles": Param(50, "PSO: swarm size", lo=2),
    "iterations": Param(100, "PSO: iterations", lo=1),
    "w": Param(0.5, "PSO: inertia weight (RFD-PSO Table 1)", lo=0.0),
    "c1": Param(0.75, "PSO: cognitive coefficient (RFD-PSO Table 1)", lo=0.0),
    "c2": Param(0.75, "PSO: social coefficient (RFD-PSO Table 1)", lo=0.0),
    "vmax": Param(0.2, "PSO: velocity limit, fraction of the workspace size", lo=0.0, lo_open=True, hi=1.0),
    "penalty": Param(1.0, "PSO: cost per colliding segment, in workspace diagonals", lo=0.0),
    "restarts": Param(0, "PSO: further runs from new random swarms while the best path "
                         "collides", lo=0),
}


class RFDPlanner(PathPlanner):
    """River formation dynamics on the inflated occupancy grid, then pure-pursuit tracking."""

    name = "rfd"
    description = "river formation dynamics on the inflated grid, pure-pursuit tracking"
    stochastic = True
    parameters: ClassVar[dict[str, Param]] = {**GRID, **RFD, **TRACKING}
    profiles: ClassVar[dict[str, dict[str, Any]]] = {"paper": {"slope": 0.0, "grid": 20}}
    paper_notes = ("paper: flat initial terrain (standard RFD) on the paper's 20 x 20 grid (1 m "
                   "cells on rfd-pso-20m, 35 cm on rfd-pso-700; see the module docstring)")
    paper_deviations = (
        "grid: the paper does not state its grids; 20 x 20 is our reading (its alley map is 20 x "
        "20 cells, its 20 x 20 m map that of the ant-colony papers it compares with, by our "
        "reading a 20 x 20 grid of 1 m cells), and the "
        "grid's inflation tests cell centres only, so on 35 cm cells a path can clip an "
        "obstacle corner (collisions in some rfd-pso-700 runs)",
        "RFD details the paper does not give, ours (see hybridnav.planners.path.rfd_core): "
        "erosion coefficient E = 0.5 (N - 1), erosion of flat and uphill steps at gradient "
        "0.01, omega = 1e-3, delta = 1e-7 (uphill weights capped at omega), dead-end deposit, "
        "a 300-iteration cap and 60 iterations' patience",
        "the path is the best drop's cell path from start to goal (cell centres), tracked by "
        "pure pursuit at 1 cell/s (the scenario's cells) by the robot's go-to-point controller; "
        "the paper gives the planned length only",
    )

    def rfd_path(self, ctx, robot, rng) -> PlannedPath:
        v = self.values
        grid = ctx.grid(self._clearance(ctx, robot), self.values["grid"])
        ends = _grid_endpoints(grid, robot)
        if isinstance(ends, PlannedPath):
            return ends
        res = rfd(grid, *ends, drops=v["drops"], iterations=v["rfd_iterations"],
                  patience=v["patience"], seed=rng, slope=v["slope"], diagonal=v["diagonal"],
                  corner_cutting=v["corner_cutting"])
        if not res.found:
            out = _failed(f"no drop reached the goal ({res.reason})", grid=grid, rfd=res)
        else:
            out = _found(_cells_to_path(robot, res.points), grid=grid, rfd=res)
        out.metrics.update(grid_length=res.length, rfd_iterations=res.iterations)
        return out

    def plan(self, ctx, robot, rngs):
        out = self.rfd_path(ctx, robot, rngs[0])
        if out.found and self.values["shorten"]:
            tight = _found(self._shortened(ctx, robot, out.points), **out.info)
            tight.metrics.update(out.metrics)
            out = tight
        return out


class PSOPathPlanner(PathPlanner):
    """PSO over K intermediate waypoints in the continuous workspace, then tracking."""

    name = "pso"
    description = ("PSO over K waypoints: length + penalty per colliding segment (RFD-PSO's "
                   "Table 1 parameters), pure-pursuit tracking")
    stochastic = True
    parameters: ClassVar[dict[str, Param]] = {**SWARM, **TRACKING}
    profiles: ClassVar[dict[str, dict[str, Any]]] = {
        "paper": {"iterations": 50, "waypoints": 28}}
    paper_notes = ("paper (RFD-PSO's PSO baseline): 50 iterations (Figs. 7 and 10), K = 28 "
                   "waypoints as rfd-pso's paper profile (the hybrid is this PSO with one "
                   "seeded particle); unseeded, its 56-dimensional swarm ends on a colliding "
                   "path in every run of rfdpso-table3 (K = 8 reached in 2-3 of 10)")
    paper_deviations = (
        "waypoints: K = 28 is ours (the paper gives no K; rfd-pso's paper profile explains it)",
        "cost: length plus one workspace diagonal per colliding segment (penalty = 1); the "
        "paper's cost function is not given beyond 'distance'",
        "velocity limit (vmax = 0.2 of the workspace) and the swarm size (50) are ours; the "
        "paper gives only w = 0.5, c1 = c2 = 0.75 (Table 1) and 50 iterations",
        "a plan whose best path still collides fails (stuck); the paper reports a length for "
        "each map",
        "iterations: 50 on every map; Table 4 gives 100 repetitions on the alley map",
        "the path is tracked by pure pursuit by the robot's go-to-point controller; the paper "
        "gives the planned length only",
    )

    def seed_particle(self, ctx, robot, rngs) -> tuple[NDArray | None, PlannedPath | None]:
        """The waypoints of a seeded particle and the plan they come from (plain PSO: none)."""
        return None, None

    def plan(self, ctx, robot, rngs):
        v = self.values
        world = ctx.world
        clear = self._clearance(ctx, robot)
        start = np.asarray(robot.start, dtype=float)
        goal = np.asarray(robot.goal, dtype=float)
        xmin, xmax, ymin, ymax = world.workspace
        lo = np.array([xmin + clear, ymin + clear])
        hi = np.array([xmax - clear, ymax - clear])
        if not np.all(lo < hi):
            return _failed("the workspace is narrower than twice the robot radius plus margin")
        seed_wp, base = self.seed_particle(ctx, robot, rngs)
        info: dict[str, Any] = {}
        metrics: dict[str, Any] = {}
        if base is not None:
            metrics = {"rfd_length": base.length if base.found else None,
                       "rfd_iterations": base.metrics.get("rfd_iterations", 0)}
            if not base.found:
                out = _failed(base.reason, **base.info)
                out.metrics.update(pso_runs=0, **metrics)
                return out
            info = {"rfd": base.info["rfd"], "rfd_points": base.points,
                    "seed_points": np.vstack([base.points[0], seed_wp, base.points[-1]])}
        K = v["waypoints"] if seed_wp is None else len(seed_wp)
        penalty = v["penalty"] * math.hypot(xmax - xmin, ymax - ymin)

        def cost(X: NDArray[np.float64]) -> NDArray[np.float64]:
            n = X.shape[0]
            P = np.concatenate([np.broadcast_to(start, (n, 1, 2)), X.reshape(n, K, 2),
                                np.broadcast_to(goal, (n, 1, 2))], axis=1)
            A, B = P[:, :-1].reshape(-1, 2), P[:, 1:].reshape(-1, 2)
            hits = world.segment_collides(A, B, radius=clear).reshape(n, K + 1)
            length = np.hypot(*(B - A).T).reshape(n, K + 1).sum(axis=1)
            return length + penalty * hits.sum(axis=1)

        rng = rngs[1]
        box = (np.tile(lo, K), np.tile(hi, K))
        n = v["particles"]
        for run in range(v["restarts"] + 1):
            # the swarm starts uniformly in the box, each particle's waypoints ordered along the
            # start -> goal direction (the same random points, without needless loops)
            W = rng.uniform(box[0], box[1], (n, 2 * K)).reshape(n, K, 2)
            order = np.argsort(W @ (goal - start), axis=1, kind="stable")
            init = np.take_along_axis(W, order[..., None], axis=1).reshape(n, -1)
            if seed_wp is not None:
                init[0] = np.clip(seed_wp, lo, hi).reshape(-1)
            opt = pso(cost, box, n=n, iterations=v["iterations"], seed=rng, init=init,
                      w=v["w"], c1=v["c1"], c2=v["c2"], vmax=v["vmax"])
            points = np.vstack([start, opt.x.reshape(K, 2), goal])
            hits = world.segment_collides(points[:-1], points[1:], radius=clear)
            if not hits.any():
                out = _found(points, opt=opt, **info)
                out.metrics.update(pso_runs=run + 1, **metrics)
                return out
            log.debug("%s: robot %s: PSO run %d ends with %d colliding segment(s)", self.name,
                      robot.name, run + 1, int(hits.sum()))
        out = _failed(f"the best path of each of {v['restarts'] + 1} PSO run(s) has colliding "
                      "segments", opt=opt, **info)
        out.metrics.update(pso_runs=v["restarts"] + 1, **metrics)
        return out


class RFDPSOPlanner(PSOPathPlanner, RFDPlanner):
    """RFD-PSO: RFD path, then PSO with one particle seeded from it, then tracking."""

    name = "rfd-pso"
    description = ("RFD-PSO: river formation dynamics seeds one PSO particle (w 0.5, c1 = c2 = "
                   "0.75), pure-pursuit tracking")
    stochastic = True
    parameters: ClassVar[dict[str, Param]] = {
        **GRID,
        "shorten": Param(True, "pull the RFD path tight before it seeds the PSO particle (the "
                               "paper seeds the RFD path itself: false samples it at K points)"),
        **RFD, **SWARM, **TRACKING}
    profiles: ClassVar[dict[str, dict[str, Any]]] = {
        "paper": {"slope": 0.0, "iterations": 50, "shorten": False, "grid": 20,
                  "waypoints": 28}}
    paper_notes = ("paper: flat RFD terrain on the paper's 20 x 20 grid (1 m cells on "
                   "rfd-pso-20m, 35 cm on rfd-pso-700), 50 PSO iterations (Figs. 7-11), the "
                   "seed particle is the RFD path sampled at K = 28 points (no shortening)")
    paper_deviations = (
        "grid: 20 x 20 cells is our reading, the paper does not state its grids (see rfd); "
        "the RFD stage's details (E, omega, delta, deposit, stop rules) are ours as in rfd",
        "waypoints: K = 28 is ours, one per interior cell of an RFD path of the paper's 32.68 m "
        "between opposite corners of the 20 x 20 grid; the paper gives no K",
        "seed: the RFD path sampled at K points evenly along its length; the paper does not say "
        "how a cell path becomes a particle",
        "PSO cost, velocity limit and swarm size are ours as in pso (penalty = 1 diagonal per "
        "colliding segment, vmax = 0.2, 50 particles); a plan whose best path still collides "
        "fails (stuck)",
        "iterations: 50 on every map; Table 4 gives 100 repetitions on the alley map",
        "repetitions: hybridnav reproduce runs each planner several times per map (seeded) and "
        "reports means over the reached runs; the paper gives one length per map ('lengths of "
        "the shortest paths') and no number of runs",
        "the path is tracked by pure pursuit by the robot's go-to-point controller; the paper "
        "gives the planned length only",
    )

    def seed_particle(self, ctx, robot, rngs):
        base = self.rfd_path(ctx, robot, rngs[0])
        if not base.found:
            return None, base
        k = self.values["waypoints"]
        if not self.values["shorten"]:
            return sample_along(base.points, k), base
        wp = resample_waypoints(self._shortened(ctx, robot, base.points), k)
        if len(wp) > k:
            log.info("rfd-pso: robot %s: the RFD path needs %d waypoints; using %d instead of %d",
                     robot.name, len(wp), len(wp), k)
        return wp, base

    def plan(self, ctx, robot, rngs):
        return PSOPathPlanner.plan(self, ctx, robot, rngs)


def _plan_extras(scenario, plans: list[PlannedPath]) -> dict[str, Any]:
    """The planned paths as result extras: ``planned_<robot>`` (``x, y``; empty when none was
    found), the RFD path and seed of hybrids (``rfd_path_<robot>``, ``rfd_seed_<robot>``) and the
    swarm's best cost per iteration (``swarm_best_<robot>``: ``plan`` 0, ``iteration``, ``best``)."""
    def xy(points) -> dict[str, np.ndarray]:
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        return {"x": pts[:, 0], "y": pts[:, 1]}

    out: dict[str, Any] = {}
    for r, p in zip(scenario.robots, plans):
        out[f"planned_{r.name}"] = xy(p.points if p.found else np.zeros((0, 2)))
        for key, name in (("rfd_points", "rfd_path"), ("seed_points", "rfd_seed")):
            if p.info.get(key) is not None:
                out[f"{name}_{r.name}"] = xy(p.info[key])
        opt = p.info.get("opt")
        if opt is not None:
            out[f"swarm_best_{r.name}"] = searches_table([np.asarray(opt.history.best,
                                                                     dtype=float)])
    return out
