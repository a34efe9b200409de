"""The shared loop of the step planners: plan a step with a swarm, drive there with the kinematics.

FAStep-Kinematic and ACO-Kinematic both alternate two things for every robot: a swarm optimizer
places the robot's next step (a waypoint) by minimizing :func:`~hybridnav.planners.step.stepfit.
step_fitness` over candidate points, and the robot's own go-to-point controller (its kinematic
equations, e.g. ``xdot = alpha1 (x1 - x)``) drives it there. :class:`StepPlanner` is that loop on top
of :func:`~hybridnav.planners.simulate.simulate`; a subclass says which optimizer places a step
(:meth:`StepPlanner.optimize`) and whether the robot first tries to drive straight to its goal
(:attr:`StepPlanner.direct_first`, FAStep-Kinematic) or plans every step (ACO-Kinematic).

Every control cycle, for every active robot:

* a robot with no step, or within ``reach`` of its step, gets a new one (``direct_first``: the goal
  itself while no obstacle or robot is within the protective region ``eps`` -- eq. 11 -- or while
  driving straight to the goal is feasible; otherwise a planned step);
* a robot with an obstacle or robot within ``eps`` re-checks its current move (every cycle when the
  near object moves -- another robot, a moving circle -- and every ``horizon / 2`` seconds when it
  is static) and re-plans when the move is no longer feasible.

Planning a step: candidates lie in the workspace (shrunk by the robot's radius; or a square
``window`` around the robot), farther than ``reach`` from the robot unless they are the goal, with
the whole-body disk (radius ``model.radius``, for the tractor-trailer ``sqrt(L^2 + b^2) / 2``) at
least ``margin`` from obstacles and robots; the robot's compiled model is rolled out from its state
towards every candidate in batched calls and the candidates whose swept footprint comes closer
than ``margin`` are infeasible (:func:`~hybridnav.planners.step.stepfit.feasible_steps`); the step
fitness of the candidates that pass the cheap tests is a lower bound of their value, so the swarm
asks for the rollout only of the candidates whose value can change its run (a
:class:`~hybridnav.planners.swarm._core.BoundedObjective`; the same steps). The goal is
always one of the candidates, so a robot that can drive straight to its goal does. A robot that
finds no feasible step holds its position and tries again every second; after ``patience`` seconds
without one it is ``stuck``, and so is a robot with a fixed goal that plans ``stall_steps`` steps in
a row without getting closer to its goal (by the planner's distance) than it has been (a trap it
creeps around in). Robots that have ended stay where they are as obstacles.

The rollout integrates with the scenario's ``dt`` by default, so it replays exactly the steps
the simulation will take. A coarser ``plan_dt`` (e.g. 0.5 s) plans 4 to 8 times faster and is
accurate for the point mass, whose closed loop is linear; for the unicycle and the tractor-trailer
it can mispredict fast turns (an ACO-Kinematic unicycle in ``rfd-pso-20m`` collides with
``plan_dt = 0.5`` and reaches with the default).

Lengths (``margin``, ``eps``, ``reach``) are in robot radii (``model.radius``), so the same
defaults serve centimetre and metre scenarios; ``reach`` is at least the goal radius. For the
tractor-trailer the default ``reach`` (4 radii, 3.8 cm) is larger than the ``9L/7`` (2.1 cm) inside
which its steering law orbits a target instead of converging (see
:mod:`hybridnav.models.tractor_trailer`), so it never has to converge onto a step.

Outputs beyond the result contract (:meth:`StepPlanner.diagnostics`, written by ``hybridnav run``):
``steps_<robot>.csv`` (per control cycle: target, step cost -- 0 while driving straight to the goal,
as in the papers' cost-function graphs --, mode and the controller's ``xdot``, ``ydot``),
``waypoints_<robot>.csv`` (every planned step), ``candidates_<robot>.csv`` (each search's final
candidates, what :func:`hybridnav.plotting.animate` draws around each step), ``signals.png`` (cost, ``xdot``, ``ydot`` over
time: the papers' "convergence of the controllers") and ``waypoints.png`` (when a robot planned a
step; a run that drove straight to its goal has none, and ``path.png`` shows it).
"""

from __future__ import annotations

import math
import time
from abc import abstractmethod
from typing import Any, ClassVar

import casadi as cs
import numpy as np

from hybridnav import models as model_registry
from hybridnav.params import check_seed
from hybridnav.planners.base import Param, Planner, candidates_table, searches_table
from hybridnav.planners.simulate import Simulation, simulate
from hybridnav.planners.step.stepfit import (
    GoalDistance,
    Surroundings,
    feasible_steps,
    step_fitness,
)
from hybridnav.planners.swarm import OptResult
from hybridnav.planners.step.sweep import costly_cycles
from hybridnav.planners.swarm._core import BoundedObjective
from hybridnav.results import Result

__all__ = ["StepPlanner"]

#: mode codes in the per-cycle trace
HOLD, DIRECT, STEP = 0, 1, 2
MODE_NAMES = {HOLD: "hold", DIRECT: "goal", STEP: "step"}

COMMON: dict[str, Param] = {
    "window": Param(0.0, "half-width of the square searched around the robot, in robot radii; "
                         "0: the whole workspace", lo=0.0),
    "margin": Param(0.5, "safety margin in robot radii: clearance every footprint disk keeps "
                         "along a planned move", lo=0.0),
    "eps": Param(6.0, "protective region in robot radii: an obstacle or robot this close makes "
                      "the robot check its move (FAStep-Kinematic eq. 11)", lo=0.0),
    "reach": Param(4.0, "plan the next step within this many robot radii of the current one "
                        "(at least the goal radius)", lo=0.0),
    "horizon": Param(60.0, "look-ahead of the feasibility rollout (s)", lo=0.0, lo_open=True),
    "plan_dt": Param(0.0, "integration step of the feasibility rollout (s); 0: the scenario's "
                          "dt, so the rollout replays the simulation's own steps", lo=0.0),
    "distance": Param("geodesic", "distance-to-goal term: 'geodesic' along the shortest "
                                  "obstacle-free path (grid cost-to-go), 'euclidean' as the papers",
                      choices=("geodesic", "euclidean")),
    "goal_candidate": Param(True, "the goal is a starting candidate of every step's search, so "
                                  "a robot that can drive straight to it does (the papers: no)"),
    "stall_steps": Param(10, "a robot with a fixed goal that plans this many steps in a row "
                             "without getting closer to its goal than before is stuck", lo=1),
    "patience": Param(5.0, "seconds a robot waits for a feasible step (re-planning every second) "
                           "before it is stuck", lo=0.0),
    "stuck_window": Param(20.0, "seconds without leaving a small disk that count as stuck (0: off)",
                          lo=0.0),
    "stuck_radius": Param(0.5, "that disk's radius, in goal radii", lo=0.0),
}


class StepPlanner(Planner):
    """Base of the step planners: a swarm places each step, the model's controller drives to it."""

    stochastic = True
    paper_deviations = (
        "step switching: a robot takes its next step once within `reach` (4 robot radii, at "
        "least the goal radius) of the current one, and the goal itself once within reach of "
        "the goal; the papers drive to each step",
        "feasibility: every candidate step is rolled out with the robot's compiled model for "
        "`horizon` s and refused when its swept footprint comes closer than `margin` to an "
        "obstacle, a robot or the border; the papers judge a step by its fitness (eqs. 10, 13)",
        "stop rules the papers do not have: `patience` s without a feasible step, `stall_steps` "
        "steps without getting closer to the goal, `stuck_window` s inside a small disk",
        "candidate filter: a candidate step closer than `reach` to the robot (the goal excepted) "
        "or whose disk of the robot radius plus `margin` meets an obstacle or another robot is "
        "refused before its fitness is computed; the papers' fitness has no such bound",
        "re-checks: while an obstacle or robot is within `eps` (6 robot radii) the current move "
        "is re-checked with the rollout, every control cycle near a moving one and every "
        "`horizon` / 2 s near a static one, and a new step is planned only when the move is no "
        "longer feasible; the papers do not re-check a move",
        "line segments (walls, the edges of rectangles and polygons): the exact point-to-segment "
        "distance in the fitness's line term, where the papers' minimum distance technique "
        "takes the nearest of points sampled on each segment",
        "the tractor-trailer's xi follows a first-order filter (model option xi_law='filter'); "
        "the papers' printed law (xi_law='paper') makes the robot circle (see the model's "
        "documentation)",
    )
    #: drive straight to the goal while that is safe, plan steps only to get round obstacles
    direct_first: ClassVar[bool] = False
    #: names of (circles, lines, robots, goal distance) weights in :attr:`params`
    weight_names: ClassVar[tuple[str, str, str, str]] = ("a", "b", "c", "d")

    @abstractmethod
    def optimize(self, f, lower: np.ndarray, upper: np.ndarray, rng: np.random.Generator,
                 init: np.ndarray | None, memory: dict) -> OptResult:
        """Minimize the step fitness ``f`` over the box; ``init`` rows are starting candidates
        (None: none); ``memory`` is this robot's dict for the run (what a search keeps from one
        step to the next)."""

    # ---- the run ------------------------------------------------------------------------------

    def run(self, scenario, seed: int | None = None) -> Result:
        self.check_scenario(scenario)
        seed = check_seed(seed)
        v = self.values
        rng = np.random.default_rng(seed)
        robots = scenario.robots
        n = len(robots)
        sim_models = [scenario.model(r) for r in robots]
        plan_dt = v["plan_dt"] or scenario.dt
        plan_models = [model_registry.get(r.model, dt=plan_dt, radius=r.radius, **r.params)
                       for r in robots]
        R = np.array([m.radius for m in sim_models])
        goal_r = np.array([r.goal_radius for r in robots])
        margin = v["margin"] * R
        eps = v["eps"] * R
        reach = np.maximum(v["reach"] * R, goal_r)
        steps = max(1, int(math.ceil(v["horizon"] / plan_dt - 1e-9)))
        weights = tuple(v[k] for k in self.weight_names)
        world = scenario.world
        static_world, moving_world = world.static(), world.moving()
        xmin, xmax, ymin, ymax = world.workspace

        goal_distance: list = [None] * n
        if v["distance"] == "geodesic":
            fields: dict[float, GoalDistance] = {}
            for i in range(n):
                if R[i] not in fields:
                    fields[R[i]] = GoalDistance(scenario, inflate=R[i])
                goal_distance[i] = fields[R[i]]
        wp = np.zeros((n, 2))
        to_goal = np.zeros(n, dtype=bool)
        planned = np.zeros(n, dtype=bool)
        cost = np.zeros(n)
        checked_at = np.full(n, -np.inf)
        retry_at = np.zeros(n)
        fail_since = np.full(n, np.nan)
        waypoints: dict[str, list[tuple[float, float, float, float]]] = {
            r.name: [] for r in robots}
        trace: dict[str, list] = {"t": [], "active": [], "target": [], "cost": [], "mode": []}
        best_dist = np.full(n, np.inf)
        stalled = np.zeros(n, dtype=int)
        plan_time = np.zeros(n)
        memories: list[dict] = [{} for _ in range(n)]
        # per robot, each plan call's best cost per iteration (their number: planning_calls)
        searches: list[list[np.ndarray]] = [[] for _ in range(n)]
        # and its final candidates (the swarm's population, or the goal alone)
        candidates: list[list[tuple]] = [[] for _ in range(n)]

        def discs(sim: Simulation, others: list[int]):
            cs_, rs_ = [], []
            for j in others:
                c, r = sim.models[j].footprint(sim.X[j][None])
                cs_.append(c[0])
                rs_.append(r)
            if not cs_:
                return np.zeros((0, 2)), np.zeros(0)
            return np.concatenate(cs_), np.concatenate(rs_)

        def surroundings(sim: Simulation, i: int) -> Surroundings:
            others = [j for j in range(n) if j != i]
            return Surroundings.at(world, sim.t, sim.positions[others], discs(sim, others))

        def current_clearance(sim: Simulation, i: int, env: Surroundings) -> float:
            c, r = sim.models[i].footprint(sim.X[i][None])
            c = c[0]
            clear = np.min(world.border_clearance(c) - r)
            if world.obstacles:
                clear = min(clear, np.min(world.clearance(c, t=sim.t) - r))
            oc, orad = env.robot_discs
            if len(orad):
                d = np.hypot(*(c[:, None, :] - oc[None]).transpose(2, 0, 1))
                clear = min(clear, np.min(d - r[:, None] - orad[None]))
            return float(clear)

        def margin_now(sim, i, env) -> float:
            # a robot already closer than its margin (the real motion is not the planning
            # rollout) may still move, as long as it gets no closer than it is
            return min(margin[i], max(0.0, current_clearance(sim, i, env) - 1e-9 * (1 + R[i])))

        def move_ok(sim: Simulation, i: int, target: np.ndarray, target_reach: float) -> bool:
            env = surroundings(sim, i)
            return bool(feasible_steps(plan_models[i], sim.X[i], target[None], env, steps=steps,
                                       reach=target_reach, margin=margin_now(sim, i, env),
                                       end_margin=0.0)[0])

        def plan(sim: Simulation, i: int, goal: np.ndarray) -> None:
            tic = time.perf_counter()
            env = surroundings(sim, i)
            x0 = sim.X[i]
            pos = x0[:2]
            if robots[i].goal is not None:       # progress towards a fixed goal
                gd = goal_distance[i]
                now = float(gd(pos[None], goal)[0] if gd is not None else np.hypot(*(pos - goal)))
                if now < best_dist[i] - 1e-9:
                    best_dist[i], stalled[i] = now, 0
                else:
                    stalled[i] += 1
                    if stalled[i] >= v["stall_steps"]:
                        sim.stop(i, "stuck")
                        return
            m_i = margin_now(sim, i, env)
            body = R[i] + margin[i]
            oc, orad = env.robot_discs
            lower = np.array([xmin + R[i], ymin + R[i]])
            upper = np.array([xmax - R[i], ymax - R[i]])
            if v["window"] > 0:
                lower = np.maximum(lower, pos - v["window"] * R[i])
                upper = np.minimum(upper, pos + v["window"] * R[i])
            upper = np.maximum(upper, lower + 1e-9)

            def bound(X: np.ndarray) -> np.ndarray:
                # the step fitness where the cheap tests pass (a candidate's value if its move
                # is feasible, else +inf: a lower bound), +inf elsewhere
                is_goal = (X[:, 0] == goal[0]) & (X[:, 1] == goal[1])
                ok = is_goal | (np.hypot(X[:, 0] - pos[0], X[:, 1] - pos[1]) > reach[i])
                if world.obstacles:
                    ok &= world.clearance(X, t=sim.t) >= body
                if len(orad):
                    d = np.hypot(X[:, None, 0] - oc[None, :, 0], X[:, None, 1] - oc[None, :, 1])
                    ok &= np.all(d >= body + orad[None], axis=1)
                val = np.full(len(X), np.inf)
                sel = np.flatnonzero(ok)
                if len(sel):          # row by row: the same values for any subset of rows
                    val[sel] = step_fitness(X[sel], goal, env, *weights,
                                            goal_distance=goal_distance[i])
                return val

            def refine(X: np.ndarray, B: np.ndarray) -> np.ndarray:
                # the fitness of the candidates whose moves are feasible, +inf for the others
                val = np.array(B, dtype=float)
                sel = np.flatnonzero(val < np.inf)       # (a NaN fitness counts as +inf anyway)
                if len(sel):
                    ok = feasible_steps(plan_models[i], x0, X[sel], env, steps=steps,
                                        reach=reach[i], margin=m_i, end_margin=margin[i])
                    val[sel[~ok]] = np.inf
                return val

            # optimizers that keep only their best candidates check the moves of those that can
            # be kept (the bound decides the others)
            f = BoundedObjective(bound, refine, costly=costly_cycles(plan_models[i]))

            # within reach of the goal no candidate other than the goal itself may be taken
            # (steps are farther than reach), so the goal is the step when it is feasible:
            # otherwise a search without the goal among its candidates could only arrive by
            # aiming beyond it, and stops short once nothing farther is feasible
            if np.hypot(*(pos - goal)) <= reach[i]:
                at_goal = f(np.asarray(goal, dtype=float)[None])
                if np.isfinite(at_goal[0]):
                    plan_time[i] += time.perf_counter() - tic
                    searches[i].append(np.asarray(at_goal, dtype=float))   # no search: 1 value
                    candidates[i].append((sim.t, np.asarray(goal, dtype=float)[None], at_goal))
                    accept(sim, i, np.asarray(goal, dtype=float), float(at_goal[0]))
                    return
            init = np.clip(goal, lower, upper)[None] if v["goal_candidate"] else None
            res = self.optimize(f, lower, upper, rng, init, memories[i])
            plan_time[i] += time.perf_counter() - tic
            searches[i].append(np.asarray(res.history.best, dtype=float))
            candidates[i].append((sim.t, np.array(res.population, dtype=float),
                                  np.array(res.values, dtype=float)))
            if np.isfinite(res.fun):
                accept(sim, i, res.x, res.fun)
                return
            planned[i] = False
            retry_at[i] = sim.t + 1.0
            if np.isnan(fail_since[i]):
                fail_since[i] = sim.t
            if sim.t - fail_since[i] >= v["patience"]:
                sim.stop(i, "stuck")

        def accept(sim: Simulation, i: int, x: np.ndarray, fun: float) -> None:
            wp[i] = x
            to_goal[i] = bool(np.all(x == sim.goals()[i]))
            planned[i] = True
            cost[i] = fun
            checked_at[i] = sim.t
            fail_since[i] = np.nan
            waypoints[robots[i].name].append((sim.t, float(x[0]), float(x[1]), float(fun)))

        def go_straight(sim: Simulation, i: int) -> None:
            to_goal[i] = planned[i] = True
            cost[i] = 0.0
            fail_since[i] = np.nan

        def controller(sim: Simulation) -> np.ndarray:
            t = sim.t
            P = sim.positions
            G = sim.goals()
            idx = np.flatnonzero(sim.active)
            near_static, near_moving = self._near(sim, idx, P, R, eps, static_world, moving_world)
            near = near_static | near_moving
            dwp = np.hypot(P[:, 0] - wp[:, 0], P[:, 1] - wp[:, 1])
            arrived = planned & ~to_goal & (dwp <= reach)
            need = (~planned & (t >= retry_at)) | arrived
            stale = planned & ~need & (near_moving
                                       | (near_static & (t - checked_at >= v["horizon"] / 2)))
            for i in idx[(need | stale)[idx]]:
                if need[i]:
                    if self.direct_first and (not near[i] or move_ok(sim, i, G[i], goal_r[i])):
                        go_straight(sim, i)
                        checked_at[i] = t if near[i] else -np.inf
                    else:
                        plan(sim, i, G[i])
                else:
                    target = G[i] if to_goal[i] else wp[i]
                    checked_at[i] = t
                    if not move_ok(sim, i, target, goal_r[i] if to_goal[i] else reach[i]):
                        plan(sim, i, G[i])
            T = np.where(to_goal[:, None], G, wp)
            T = np.where(planned[:, None], T, P)        # no feasible step: hold position
            mode = np.where(planned, np.where(to_goal & (cost == 0), DIRECT, STEP), HOLD)
            trace["t"].append(t)
            trace["active"].append(sim.active.copy())
            trace["target"].append(T.copy())
            trace["cost"].append(cost.copy())
            trace["mode"].append(mode)
            return T

        robot_results, _ = simulate(scenario, sim_models, controller,
                                    stuck_window=v["stuck_window"],
                                    stuck_radius=v["stuck_radius"] * goal_r)
        for i, r in enumerate(robot_results):
            r.metrics["steps_planned"] = len(waypoints[r.name])
            r.metrics["planning_calls"] = len(searches[i])
            r.metrics["planning_time"] = float(plan_time[i])
        tables = _step_tables(sim_models, robot_results, {k: np.array(x) for k, x in
                                                          trace.items()})
        extras: dict[str, Any] = {}
        for i, r in enumerate(robot_results):
            extras[f"steps_{r.name}"] = tables[r.name]
            W = np.array(waypoints[r.name], dtype=float).reshape(-1, 4)
            extras[f"waypoints_{r.name}"] = dict(zip(("t", "x", "y", "cost"), W.T))
            extras[f"swarm_best_{r.name}"] = searches_table(searches[i])
            extras[f"candidates_{r.name}"] = candidates_table(candidates[i])
        return Result(scenario=scenario.name, planner=self.name, params=self.describe(),
                      seed=seed, robots=robot_results, extras=extras)

    @staticmethod
    def _near(sim: Simulation, idx: np.ndarray, P: np.ndarray, R: np.ndarray, eps: np.ndarray,
              static_world, moving_world) -> tuple[np.ndarray, np.ndarray]:
        """Per robot: a static obstacle / a moving thing (robot, moving circle) within ``eps``."""
        n = sim.n
        near_static = np.zeros(n, dtype=bool)
        near_moving = np.zeros(n, dtype=bool)
        if not len(idx):
            return near_static, near_moving
        Pa = P[idx]
        reach = R[idx] + eps[idx]
        if static_world.obstacles:
            near_static[idx] = static_world.clearance(Pa) <= reach
        if moving_world.obstacles:
            near_moving[idx] = moving_world.clearance(Pa, t=sim.t) <= reach
        if n > 1:
            d = np.hypot(Pa[:, None, 0] - P[None, :, 0], Pa[:, None, 1] - P[None, :, 1])
            d[np.arange(len(idx)), idx] = np.inf
            near_moving[idx] |= np.any(d <= (reach[:, None] + R[None, :]), axis=1)
        return near_static, near_moving

    # ---- outputs ------------------------------------------------------------------------------


    def diagnostics(self, scenario, result: Result) -> dict[str, Any]:
        """``signals.png`` (step cost, controller velocity) and ``waypoints.png`` (only when a
        robot planned a step: else it would repeat ``path.png``); the per-robot
        ``steps_<robot>`` and ``waypoints_<robot>`` tables are the result's extras."""
        from hybridnav.plotting import plot_steps, plot_waypoints

        fig = plot_steps(result, length=scenario.units)
        if fig is None:
            return {}
        out = {"signals.png": fig}
        steps = plot_waypoints(scenario, result)
        if steps is not None:
            out["waypoints.png"] = steps
        return out


def _step_tables(sim_models, robot_results, trace) -> dict[str, dict[str, np.ndarray]]:
    """Per robot, per control cycle: ``t``, target, cost, mode (``hold``, ``goal``, ``step``),
    and the commanded ``xdot``, ``ydot``."""
    out = {}
    for i, (r, m) in enumerate(zip(robot_results, sim_models)):
        rows = np.flatnonzero(trace["active"][:, i])
        k = min(len(rows), len(r.states) - 1)   # the last controller call may not have moved
        rows = rows[:k]
        X = r.states[:k]
        T = trace["target"][rows, i]
        if k:
            fn = m.function("closed_loop").map(k)
            xdot = np.asarray(fn(X.T, T.T, cs.repmat(cs.DM(m.p_value()), 1, k)))
        else:
            xdot = np.zeros((m.nx, 0))
        out[r.name] = {"t": trace["t"][rows], "target_x": T[:, 0], "target_y": T[:, 1],
                       "cost": trace["cost"][rows, i],
                       "mode": np.array([MODE_NAMES[int(c)] for c in trace["mode"][rows, i]],
                                        dtype=str),
                       "xdot": xdot[0], "ydot": xdot[1]}
    return out
