"""PSO-BA (Abed et al. 2022): PSO tunes a bat algorithm that places each path point; local search
repairs infeasible points; range sensors and wall following get round obstacles.

Every robot plans its path one point at a time while it drives (an online, sensor-based method),
inside the shared closed loop (:func:`hybridnav.planners.simulate.simulate`). Moving obstacles
(``moving_circle``) and moving targets (``goal_follow``: the goal is the followed robot's current
position, ``sim.goals()``) are handled; every query uses the obstacles where they are at the
current time.

Planning a path point (``goal`` mode)
-------------------------------------
The bats search the disk of radius ``step`` around the robot (a box of half-width ``step``, each
bat mapped radially onto the disk, within the workspace shrunk by the robot's safety radius).
Their fitness is eq. 6 with the normalised objectives of section 2.1.2::

    fitness = 1 / (w1 * dn + w2 * an + 0.001),   w2 = 1 - w1,
    dn = floor + (1 - floor) * min(d / ST, 1),   an = angle / 90,

``d`` the distance from the candidate to the goal, ``angle`` (degrees, in [0, 180]) the angle at
the robot between the directions to the candidate and to the goal (eq. 3). Choices where the paper
is unclear:

* the paper keeps the normalised distance "in the range [0.3, 1.0]" near the target so that it
  never vanishes; we map ``[0, ST]`` affinely onto ``[floor, 1]`` (``floor = 0.3``) rather than
  clip at 0.3, so candidates nearer the goal still rank better when the robot is close to it;
* ``ST`` is the start-to-goal distance (the goal's current position for a moving target), raised to
  ``|robot - goal| + step`` when that is larger (after a detour, or when the target moved away),
  so the distance term never saturates at 1 for a candidate;
* the angle is not clipped to 90 degrees: candidates behind the robot score worse still;
* when the goal itself is within the step disk and the move to it is feasible, it is the path
  point (it maximizes the fitness over the disk: ``dn = floor``, ``angle = 0``) and no search
  runs; a moving target is then tracked every control cycle.

PSO tunes the bat algorithm's loudness decay ``alpha`` and pulse-rate constant ``gamma``
(Algorithm 1, :func:`pso_ba`): a PSO particle is ``(alpha, gamma)`` and its value is the best
fitness of one bat run with those parameters (:func:`hybridnav.planners.swarm.bat`, which
minimizes, runs on ``-fitness``). The path point is the best bat found over all runs. The optimizers
are :func:`hybridnav.planners.swarm.pso` and :func:`~hybridnav.planners.swarm.bat` with their
default coefficients; the bat's swarm is vectorized, and the PSO's objective runs one bat search
per particle.

Local search (section 4.2)
--------------------------
A point is infeasible when a disk of the safety radius ``R (1 + margin)`` swept from the robot to it
meets an obstacle (or the workspace border). :func:`~hybridnav.planners.psoba.sensors.local_search`
moves it back along the same ray to the first point whose clearance is ``ds`` (eq. 22; see
:mod:`hybridnav.planners.psoba.sensors` for the exact continuous version we use). When that leaves
less than ``step / 2`` of progress, the way is blocked and the robot starts wall following.

Obstacle detection and avoidance (section 5)
--------------------------------------------
``sensors`` (12) range sensors of radius ``sr`` around the robot, in the world frame, give the
sensing vector ``Vs`` and the gap vector ``Vg(j) = NOT(Vs(j) OR Vs(j + 1))``
(:mod:`~hybridnav.planners.psoba.sensors`). A wall-following episode (``wall`` mode):

* **side**: at the first contact, left when the nearest free gap counter-clockwise from the
  goal direction is no farther than the nearest one clockwise, otherwise right (the paper leaves
  the choice open); an episode starting within ``2 sr`` of where the previous one ended keeps the
  previous side (the same obstacle, most likely: switching sides there would oscillate); when the
  obstacle met is a moving circle (within ``2 ds``), the side whose tangent runs against its
  velocity, so that the robot passes behind it rather than racing it;
* **the wall**: the nearest obstacle among those within ``2 ds`` on the following side of the
  robot's last heading (on its right when following left; ahead up to 30 degrees to the other
  side counts), else the nearest of all -- so that squeezed between two obstacles the robot keeps
  following the one it followed instead of switching to the one on its other side;
* **following**: with ``q`` the wall's nearest point and ``n`` the unit vector from it to the
  robot, the robot heads along the tangent (left: ``-n`` turned 90 degrees counter-clockwise, the
  obstacle on its right), steered towards the obstacle when farther than ``ds`` and away when
  nearer; when that ray leaves less than ``step / 2`` before coming within ``ds`` of an obstacle,
  the direction is turned away from the obstacle in 15 degree steps until one does (concave
  corners, a second obstacle); where no direction does (a passage narrower than ``2 ds``), the
  same search keeps only the safety radius; the step is at most ``step``; a robot inside the
  region a moving circle will sweep (or closer than its safety radius) and with no such move
  steps straight away from the obstacle's axis;
* **room boundary** (Fig. 10-11): when the robot is within ``sr`` of a workspace side and its
  next move heads into it (component along the side's outward normal above 0.5), or when no
  direction is free, it changes direction (left <-> right) -- once per episode;
* **memory** (Fig. 13-14): every wall-following position is remembered for ``memory`` seconds;
* **leaving**: the episode ends when the goal is within ``step`` and directly reachable, when the
  sensors see nothing, or when the gap towards the goal (the gap whose centre ray is nearest to
  the goal direction) is free and no remembered point lies in the corridor of half-width
  ``step / 2`` from the robot towards the goal (points within ``step`` of the robot excepted) --
  otherwise the robot keeps following the wall, as the paper's exception case requires.

Obstacles, other robots, time
-----------------------------
For planning and local search, moving circles are swept over the next ``step / speed`` seconds (a
capsule from where they are now to where they will be; our choice, the paper moves them between
iterations) and other robots are disks at their current positions -- except the robot a robot
follows and the robots following it: meeting them is the goal. The sensors see moving circles
and robots where they are now. Every control cycle the move to the current path point is
re-checked against the moving things, and re-planned when it is no longer feasible. For a scenario
with a ``[grid] map`` the map's blocked cells are obstacles too
(:func:`hybridnav.planners.path.geometry.obstacle_world`), in planning and in the simulation.

Driving
-------
Each cycle the robot is commanded the velocity ``speed`` towards its path point (less in the last
cycle before it), turned into a target point by its model's
:meth:`~hybridnav.models.Model.carrot`: a point mass moves at exactly that velocity, a unicycle
(the paper's differential drive) at that speed once it faces the point. The next point is planned
when the robot is within ``step / 4`` of the current one. A robot for which no move is possible
holds its position and retries every half second; after ``patience`` seconds it is ``stuck``.

Lengths (``step``, ``ds``, ``sr``, ``margin``, ``speed``) are in robot radii, so one set of
defaults serves the centimetre scenarios and the grid-cell ``arena``.

Metrics and diagnostics
-----------------------
Per robot: ``path_points`` (planned points), ``pso_ba_runs`` (searches), ``ls_repairs``,
``wall_episodes``, ``direction_changes`` (room-boundary reversals), ``memory_refusals`` (leaves
refused by the memory), ``planning_time`` (seconds, part of the loop's wall time that
``compute_time`` shares equally among the robots active each cycle).
:meth:`PSOBAPlanner.diagnostics` gives ``pso_ba.png`` (the run with the path points by mode, and
the fitness and tuned ``(alpha, gamma)`` of every search) and ``path_points_<robot>.csv``;
``candidates_<robot>.csv`` holds the best bat of each bat run of every search (its cost: minus
its fitness), what :func:`hybridnav.plotting.animate` draws around each planning step.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from hybridnav.errors import HybridnavError
from hybridnav.params import check_seed
from hybridnav.planners.base import Param, Planner, candidates_table, searches_table
from hybridnav.planners.path.geometry import obstacle_world
from hybridnav.planners.psoba.fitness import disk_candidates, psoba_fitness
from hybridnav.planners.psoba.sensors import (
    WALL_NORMALS,
    Scene,
    escape_step,
    feasible,
    followed_wall,
    gap_index,
    gap_vector,
    local_search,
    near_room_walls,
    ray_entry,
    sector_ranges,
    sensing_vector,
)
from hybridnav.planners.simulate import Simulation, model_groups, simulate
from hybridnav.planners.swarm.pso_ba import PSOBAResult, pso_ba
from hybridnav.results import Result
from hybridnav.world import MovingCircle, World

__all__ = ["PSOBAPlanner", "PSOBAResult", "disk_candidates", "pso_ba", "psoba_fitness"]

#: path point modes in the trace
GOAL, REPAIRED, WALL, TRACK = "goal", "repaired", "wall", "track"


# --------------------------------------------------------------------------------------------
# The planner
# --------------------------------------------------------------------------------------------


@dataclass
class _Robot:
    """Per-robot planning state."""

    R: float                      # footprint radius
    rng: np.random.Generator
    start: NDArray[np.float64]
    wp: NDArray[np.float64] | None = None
    mode: str = GOAL              # GOAL or WALL
    tracking: bool = False        # wp follows the goal directly
    side: int = 1                 # +1 left (obstacle on the right), -1 right
    reversed: bool = False        # direction changed in this episode
    last_leave: NDArray[np.float64] | None = None
    heading: NDArray[np.float64] | None = None    # direction of the last planned move
    memory: list[tuple[float, float, float]] = field(default_factory=list)
    retry_at: float = 0.0
    fail_since: float = math.nan
    trace: list[tuple] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=lambda: {
        "path_points": 0, "pso_ba_runs": 0, "ls_repairs": 0, "wall_episodes": 0,
        "direction_changes": 0, "memory_refusals": 0})
    planning_time: float = 0.0
    #: the PSO's best cost per iteration, one array per PSO-BA run (``swarm_best_<robot>``)
    searches: list = field(default_factory=list)
    #: each PSO-BA run's candidates: the best bat of every bat run (``candidates_<robot>``)
    candidates: list = field(default_factory=list)


class PSOBAPlanner(Planner):
    """PSO-BA: PSO-tuned bats place each path point; local search; sensors and wall following."""

    name = "pso-ba"
    description = ("PSO-BA (Abed et al. 2022): PSO tunes the bat algorithm placing each path "
                   "point, local search repairs, 12 range sensors and wall following")
    drives: ClassVar[tuple[frozenset[str], ...]] = (frozenset({"disk"}),)   # 12 sensors on a disk
    moving_obstacles: ClassVar[bool] = True
    moving_targets: ClassVar[bool] = True
    stochastic: ClassVar[bool] = True
    parameters: ClassVar[dict[str, Param]] = {
        "step": Param(3.0, "radius of the disk the bats search around the robot: the spacing of "
                           "path points, robot radii", lo=0.0, lo_open=True),
        "ds": Param(1.5, "local search safety distance (eq. 22): a repaired point's distance "
                         "from the nearest obstacle, robot radii (> 1 + margin)", lo=0.0, lo_open=True),
        "margin": Param(0.1, "a move is feasible when a disk of radius (1 + margin) robot radii "
                             "swept along it meets no obstacle", lo=0.0),
        "sr": Param(6.0, "sensing radius of the range sensors, robot radii", lo=0.0, lo_open=True),
        "sensors": Param(12, "number of range sensors (equal sectors)", lo=3),
        "w1": Param(0.5, "weight of the distance in the fitness (w2 = 1 - w1)", lo=0.0, hi=1.0),
        "floor": Param(0.3, "lower end of the normalised distance near the goal", lo=0.0,
                       hi=0.99),
        "particles": Param(5, "PSO particles (alpha, gamma)", lo=1),
        "pso_iterations": Param(5, "PSO iterations", lo=1),
        "pso_w": Param(0.7298, "PSO inertia weight (the paper's eq. 9 has none: 1)", lo=0.0),
        "pso_c1": Param(1.49618, "PSO cognitive coefficient (the paper: not given)", lo=0.0),
        "pso_c2": Param(1.49618, "PSO social coefficient (the paper: not given)", lo=0.0),
        "bats": Param(12, "bats per bat run", lo=1),
        "bat_iterations": Param(12, "iterations per bat run", lo=1),
        "alpha_min": Param(0.1, "lower bound of the bats' loudness decay alpha", lo=0.0, lo_open=True,
                           hi=1.0),
        "alpha_max": Param(1.0, "upper bound of alpha", lo=0.0, lo_open=True, hi=1.0),
        "gamma_min": Param(0.0, "lower bound of the bats' pulse-rate constant gamma", lo=0.0),
        "gamma_max": Param(1.0, "upper bound of gamma", lo=0.0),
        "speed": Param(1.0, "driving speed, robot radii per second", lo=0.0, lo_open=True),
        "memory": Param(120.0, "seconds a wall-following position is remembered (0: no memory)",
                        lo=0.0),
        "patience": Param(10.0, "seconds without any possible move before the robot is stuck",
                          lo=0.0),
        "stuck_window": Param(30.0, "seconds without leaving a small disk that count as stuck "
                                    "(0: off)", lo=0.0),
        "stuck_radius": Param(1.0, "that disk's radius, robot radii", lo=0.0),
    }

    profiles: ClassVar[dict[str, dict[str, Any]]] = {"paper": {"pso_w": 1.0}}
    paper_notes = ("paper: eq. 9's PSO velocity update has no inertia factor (pso_w = 1); its "
                   "c1, c2 are not given. In both profiles the PSO barely matters: the fitness "
                   "has no obstacle term, so the best bat is a full step towards the goal whatever "
                   "(alpha, gamma) are (pso-ba-dynamic: seeds 0 and 1 give paths 5e-4 apart)")
    paper_deviations = (
        "values the paper does not give: PSO 5 particles x 5 iterations with c1 = c2 = 1.49618, "
        "12 bats x 12 iterations per bat run, step = 3, ds = 1.5 and sr = 6 robot radii, speed "
        "1 robot radius per second (the paper places one path point per iteration)",
        "fitness: the normalised distance maps [0, ST] affinely onto [floor, 1] (the paper keeps "
        "it 'in the range [0.3, 1.0]'), ST is raised to |robot - goal| + step when larger, and "
        "the angle is not clipped to 90 degrees",
        "the goal is the next path point without a search when it is within the step disk and "
        "the move to it is feasible",
        "moving circles are swept over the next step / speed seconds when planning (the paper "
        "moves them between iterations)",
        "wall following: the choice of side (the paper leaves it open), of the wall followed, "
        "the 15-degree turns away from it and the leaving rule's corridor are ours; the "
        "room-boundary reversal (Figs. 10-11) and the memory (Figs. 13-14; kept for memory = "
        "120 s) are our reading of the paper's figures",
        "stop rules the paper does not have: `patience` s without a possible move, "
        "`stuck_window` s inside a small disk",
    )

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        v = self.values
        if not v["ds"] > 1.0 + v["margin"]:
            raise HybridnavError(
                f"planner {self.name}: ds: expected more than 1 + margin = {1.0 + v['margin']!r} "
                f"robot radii, got {v['ds']!r}")
        if not v["alpha_min"] < v["alpha_max"]:
            raise HybridnavError(
                f"planner {self.name}: alpha_max: expected more than alpha_min = "
                f"{v['alpha_min']!r}, got {v['alpha_max']!r}")
        if not v["gamma_min"] < v["gamma_max"]:
            raise HybridnavError(
                f"planner {self.name}: gamma_max: expected more than gamma_min = "
                f"{v['gamma_min']!r}, got {v['gamma_max']!r}")

    # ---- the run ------------------------------------------------------------------------------

    def run(self, scenario, seed: int | None = None) -> Result:
        """Run PSO-BA on every robot of the scenario.

        Parameters
        ----------
        scenario : Scenario
        seed : int or None
            Robot ``i`` draws from the ``i``-th child of ``numpy.random.SeedSequence(seed)``; equal
            seeds give equal results.

        Returns
        -------
        Result
            Per robot, the metrics listed in the module docstring.
        """
        self.check_scenario(scenario)
        seed = check_seed(seed)
        v = self.values
        world = scenario.world
        if scenario.grid is not None and scenario.grid.map is not None:
            moving = tuple(o for o in world.obstacles if isinstance(o, MovingCircle))
            world = World(world.workspace, obstacle_world(scenario).obstacles + moving)
        sim_scenario = dataclasses.replace(scenario, world=world)
        static, moving_world = world.static(), world.moving()
        robots = scenario.robots
        n = len(robots)
        models = [scenario.model(r) for r in robots]
        children = np.random.SeedSequence(seed).spawn(n)
        states = [_Robot(R=float(m.radius), rng=np.random.default_rng(c),
                         start=np.asarray(r.start, dtype=float))
                  for r, m, c in zip(robots, models, children)]
        names = {r.name: i for i, r in enumerate(robots)}
        # robots that are not obstacles to robot i: the one it follows and those following it
        friends = [{names[r.goal_follow]} if r.goal_follow else set() for r in robots]
        for i, r in enumerate(robots):
            if r.goal_follow:
                friends[names[r.goal_follow]].add(i)
        R = np.array([s.R for s in states])
        dt = scenario.dt
        groups = model_groups(models)
        dynamic = bool(moving_world.obstacles) or n > 1
        ctx = {"static": static, "moving": moving_world, "friends": friends, "R": R,
               "workspace": world.workspace}    # the run's context: sim.notes["ctx"]

        def controller(sim: Simulation) -> np.ndarray:
            P = sim.positions
            G = sim.goals()
            V = np.zeros((n, 2))
            for i in np.flatnonzero(sim.active):
                st = states[i]
                step = v["step"] * st.R
                need = st.wp is None and sim.t >= st.retry_at
                if st.wp is not None:
                    # re-plan: every cycle while tracking a goal within reach (cheap: no
                    # search), near the path point, or when moving things block the move to it
                    need = bool(st.tracking or np.hypot(*(st.wp - P[i])) <= step / 4.0
                                or (dynamic and not feasible(self._scene(sim, i, walls=True),
                                                             P[i], st.wp,
                                                             st.R * (1.0 + v["margin"]))))
                if need:
                    tic = time.perf_counter()
                    self._plan(sim, i, st, P[i], G[i])
                    st.planning_time += time.perf_counter() - tic
                if st.wp is not None:
                    d = st.wp - P[i]
                    dist = float(np.hypot(*d))
                    if dist > 0:
                        sp = min(v["speed"] * st.R, dist / dt)
                        V[i] = d * (sp / dist)
            T = np.full((n, 2), np.nan)
            for model, members in groups:
                act = members[sim.active[members]]
                if len(act):
                    T[act] = model.carrot(np.array([sim.X[j] for j in act]), V[act])
            return T

        results, _ = simulate(sim_scenario, models, controller,
                              stuck_window=v["stuck_window"],
                              stuck_radius=v["stuck_radius"] * R, notes={"ctx": ctx})
        for r, st in zip(results, states):
            r.metrics.update(st.counts)
            r.metrics["planning_time"] = st.planning_time
        extras = {f"path_points_{r.name}": _points_table(st.trace)
                  for r, st in zip(robots, states)}
        extras.update({f"swarm_best_{r.name}": searches_table(st.searches)
                       for r, st in zip(robots, states)})
        extras.update({f"candidates_{r.name}": candidates_table(st.candidates)
                       for r, st in zip(robots, states)})
        return Result(scenario=scenario.name, planner=self.name, params=self.describe(),
                      seed=seed, robots=results, extras=extras)

    # ---- scenes -------------------------------------------------------------------------------

    def _discs(self, sim: Simulation, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Other robots as disks at their current positions (not the followed/following ones)."""
        others = [j for j in range(sim.n) if j != i and j not in sim.notes["ctx"]["friends"][i]]
        if not others:
            return np.zeros((0, 2)), np.zeros(0)
        P = sim.positions
        return P[others], sim.notes["ctx"]["R"][others]

    def _scene(self, sim: Simulation, i: int, walls: bool) -> Scene:
        """The planning scene of robot ``i``: moving circles swept over ``step / speed``."""
        v = self.values
        horizon = v["step"] / v["speed"]
        return Scene.build(sim.notes["ctx"]["static"], sim.notes["ctx"]["moving"], t=sim.t, horizon=horizon,
                           discs=self._discs(sim, i), walls=walls)

    def _sensor_scene(self, sim: Simulation, i: int) -> Scene:
        """What the range sensors see: everything where it is now."""
        return Scene.build(sim.notes["ctx"]["static"], sim.notes["ctx"]["moving"], t=sim.t,
                           discs=self._discs(sim, i))

    # ---- planning -----------------------------------------------------------------------------

    def _plan(self, sim: Simulation, i: int, st: _Robot, p: np.ndarray, g: np.ndarray) -> None:
        v = self.values
        R = st.R
        step = v["step"] * R
        r_safe = R * (1.0 + v["margin"])
        scene = self._scene(sim, i, walls=True)
        t = sim.t
        dist_goal = float(np.hypot(*(g - p)))
        # the goal within reach and directly feasible: it is the best candidate of the disk
        if dist_goal <= step and feasible(scene, p, g, r_safe):
            if not st.tracking:
                st.counts["path_points"] += 1
                st.trace.append((t, float(g[0]), float(g[1]), TRACK, math.nan, math.nan,
                                 math.nan))
            if st.mode == WALL:
                st.mode, st.last_leave = GOAL, p.copy()
            st.wp, st.tracking = g.copy(), True
            st.fail_since = math.nan
            return
        st.tracking = False
        if st.mode == WALL and self._may_leave(sim, i, st, p, g):
            st.mode, st.last_leave = GOAL, p.copy()
        if st.mode == GOAL:
            if self._goal_step(sim, i, st, p, g, scene):
                return
            self._start_episode(sim, i, st, p, g, scene)
        self._wall_step(sim, i, st, p, scene)

    def _goal_step(self, sim, i, st: _Robot, p, g, scene: Scene) -> bool:
        """PSO-BA proposes a point, local search repairs it; False when the way is blocked."""
        v = self.values
        R = st.R
        step = v["step"] * R
        r_safe = R * (1.0 + v["margin"])
        xmin, xmax, ymin, ymax = sim.notes["ctx"]["workspace"]
        lower = np.maximum(p - step, [xmin + r_safe, ymin + r_safe])
        upper = np.minimum(p + step, [xmax - r_safe, ymax - r_safe])
        upper = np.maximum(upper, lower + 1e-9 * max(1.0, step))
        stdist = max(float(np.hypot(*(st.start - g))), float(np.hypot(*(p - g))) + step)

        def fit(X: np.ndarray) -> np.ndarray:
            return psoba_fitness(disk_candidates(X, p, step), p, g, stdist, v["w1"], v["floor"])

        res = pso_ba(fit, lower, upper, seed=st.rng, particles=v["particles"],
                     pso_iterations=v["pso_iterations"], bats=v["bats"],
                     bat_iterations=v["bat_iterations"],
                     alpha_bounds=(v["alpha_min"], v["alpha_max"]),
                     gamma_bounds=(v["gamma_min"], v["gamma_max"]),
                     pso_w=v["pso_w"], pso_c1=v["pso_c1"], pso_c2=v["pso_c2"])
        st.counts["pso_ba_runs"] += 1
        st.searches.append(np.asarray(res.pso.history.best, dtype=float))
        st.candidates.append((sim.t, disk_candidates(res.run_best, p, step), -res.run_fitness))
        c = disk_candidates(res.x, p, step)[0]
        point, repaired = local_search(scene, p, c, v["ds"] * R, r_safe)
        if repaired:
            st.counts["ls_repairs"] += 1
            if np.hypot(*(point - p)) < step / 2.0:
                return False
        self._set_wp(sim, st, p, point, REPAIRED if repaired else GOAL, res.fitness, res.alpha,
                     res.gamma)
        return True

    def _set_wp(self, sim, st: _Robot, p, point, mode: str, fitness=math.nan,
                alpha=math.nan, gamma=math.nan) -> None:
        st.wp = np.asarray(point, dtype=float).copy()
        d = st.wp - p
        n = float(np.hypot(*d))
        st.heading = d / n if n > 0 else st.heading
        st.counts["path_points"] += 1
        st.fail_since = math.nan
        st.trace.append((sim.t, float(point[0]), float(point[1]), mode, float(fitness),
                         float(alpha), float(gamma)))

    def _gaps(self, sim, i, p) -> tuple[np.ndarray, np.ndarray]:
        v = self.values
        R = sim.notes["ctx"]["R"][i]
        readings = sector_ranges(self._sensor_scene(sim, i), p, v["sensors"])[0]
        vs = sensing_vector(readings, v["sr"] * R)
        return vs, gap_vector(vs)

    def _start_episode(self, sim, i, st: _Robot, p, g, scene: Scene) -> None:
        v = self.values
        st.mode = WALL
        st.reversed = False
        st.counts["wall_episodes"] += 1
        sr = v["sr"] * st.R
        ds = v["ds"] * st.R
        bare = scene.without_walls()
        if len(bare.r):
            d, _, axis = bare.surface_points(p)
            k = int(np.argmin(d))
            vel = bare.vel[k]
            if d[k] <= 2.0 * ds and np.any(vel != 0):
                # a moving obstacle: pass behind it (the tangent side against its velocity)
                toward = axis[k] - p
                side_dot = float(-toward[1] * vel[0] + toward[0] * vel[1])
                if side_dot != 0:
                    st.side = -1 if side_dot > 0 else 1
                    return
        if st.last_leave is not None and np.hypot(*(p - st.last_leave)) <= 2.0 * sr:
            return                       # same obstacle, most likely: keep the side
        _, vg = self._gaps(sim, i, p)
        n = len(vg)
        k = gap_index(math.atan2(g[1] - p[1], g[0] - p[0]), n)
        free = np.flatnonzero(vg)
        if not len(free):
            st.side = 1
            return
        ccw = np.min((free - k) % n)
        cw = np.min((k - free) % n)
        st.side = 1 if ccw <= cw else -1

    def _may_leave(self, sim, i, st: _Robot, p, g) -> bool:
        v = self.values
        R = st.R
        step = v["step"] * R
        vs, vg = self._gaps(sim, i, p)
        if not vs.any():
            return True
        k = gap_index(math.atan2(g[1] - p[1], g[0] - p[0]), len(vg))
        if not vg[k]:
            return False
        if self._remembered(sim.t, st, p, g, step):
            st.counts["memory_refusals"] += 1
            return False
        return True

    def _remembered(self, t: float, st: _Robot, p, g, step: float) -> bool:
        """A remembered wall-following point lies in the corridor from ``p`` towards ``g``."""
        ttl = self.values["memory"]
        st.memory = [m for m in st.memory if t - m[0] <= ttl]
        if not st.memory or ttl == 0:
            return False
        Q = np.array([m[1:] for m in st.memory]) - p
        dg = g - p
        L = float(np.hypot(*dg))
        if L == 0:
            return False
        u = dg / L
        s = Q @ u
        perp = np.abs(Q[:, 0] * u[1] - Q[:, 1] * u[0])
        far = np.hypot(Q[:, 0], Q[:, 1]) > step
        return bool(np.any(far & (s > 0) & (s <= L) & (perp <= step / 2.0)))

    def _wall_step(self, sim, i, st: _Robot, p, scene: Scene) -> None:
        v = self.values
        R = st.R
        step = v["step"] * R
        ds = v["ds"] * R
        sr = v["sr"] * R
        t = sim.t
        if v["memory"] > 0:
            st.memory.append((t, float(p[0]), float(p[1])))
        dist, q, k_obs = followed_wall(scene.without_walls(), st.heading, st.side, p, ds)
        here = float(scene.clearance(p)[0])
        tol = 1e-9 * max(1.0, abs(here))
        r_safe = R * (1.0 + v["margin"])
        for _attempt in range(2):
            point = None
            if np.isfinite(dist):
                away = p - q
                na = float(np.hypot(*away))
                n_hat = away / na if na > 0 else np.array([1.0, 0.0])
                toward = -n_hat
                s = st.side
                tau = np.array([-s * toward[1], s * toward[0]])    # toward turned by s * 90 deg
                corr = float(np.clip((dist - ds) / ds, -1.0, 1.0))
                d0 = tau + corr * toward
                d0 /= np.hypot(*d0)
                ang = s * np.radians(np.arange(0, 181, 15))
                c, sn = np.cos(ang), np.sin(ang)
                dirs = np.stack([c * d0[0] - sn * d0[1], sn * d0[0] + c * d0[1]], axis=1)
                # keep ds from every obstacle; where no direction allows that (a passage
                # narrower than 2 ds), squeeze through keeping the feasibility radius
                for keep in (min(ds, here - tol), min(r_safe, here - tol)):
                    if keep < 0:
                        continue
                    lam = ray_entry(scene, p, dirs, keep)[0]
                    ok = np.flatnonzero(lam >= step / 2.0)
                    if len(ok):
                        k = int(ok[0])
                        point = p + min(float(lam[k]), step) * dirs[k]
                        break
            heading_in = False
            if point is not None:
                u = (point - p) / max(float(np.hypot(*(point - p))), 1e-300)
                near = near_room_walls(p, sim.notes["ctx"]["workspace"], sr)[0]
                heading_in = bool(np.any(near & (WALL_NORMALS @ u > 0.5)))
            if (point is None or heading_in) and not st.reversed:
                st.side = -st.side
                st.reversed = True
                st.counts["direction_changes"] += 1
                continue
            break
        if point is None and np.isfinite(dist) and here < r_safe:
            point = escape_step(scene, k_obs, p, step, ds, r_safe)
        if point is None:
            self._hold(sim, i, st)
            return
        self._set_wp(sim, st, p, point, WALL)

    def _hold(self, sim, i, st: _Robot) -> None:
        st.wp = None
        st.tracking = False
        st.retry_at = sim.t + 0.5
        if math.isnan(st.fail_since):
            st.fail_since = sim.t
        if sim.t - st.fail_since >= self.values["patience"]:
            sim.stop(i, "stuck")

    # ---- outputs ------------------------------------------------------------------------------

    def diagnostics(self, scenario, result: Result) -> dict[str, Any]:
        """``pso_ba.png``: the path points by how each was found, their fitness and the
        PSO-tuned bat parameters (the ``path_points_<robot>`` tables are the result's extras)."""
        from hybridnav.plotting import plot_pso_ba

        fig = plot_pso_ba(scenario, result)
        return {} if fig is None else {"pso_ba.png": fig}


def _points_table(trace) -> dict[str, np.ndarray]:
    """A robot's planned path points: ``t, x, y, mode, fitness, alpha, gamma`` per point."""
    cols = ("t", "x", "y", "mode", "fitness", "alpha", "gamma")
    rows = list(trace)
    return {c: np.array([row[j] for row in rows], dtype=str if c == "mode" else float)
            for j, c in enumerate(cols)}
