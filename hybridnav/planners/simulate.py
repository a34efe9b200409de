"""The shared closed-loop simulation every planner drives: targets in, outcomes out.

A planner gives, once per control cycle, a target point for every robot (a carrot along a force,
the next waypoint, a point on a path); :func:`simulate` steps each robot's compiled model towards
it (one batched call per model group), then checks, at the new time:

* ``collided``: a footprint disk closer than 0 to an obstacle (moving ones at that time) or to
  another robot's footprint (``min_robot_clearance`` tells which: below 0 for a robot that
  touched another robot);
* ``out_of_bounds``: a footprint disk leaving the workspace, or a step that diverged (a state
  that is not finite, a position beyond :data:`hybridnav.limits.MAX_POSITION` or a component
  beyond :data:`hybridnav.resultspec.MAX_MAGNITUDE`: a result could not hold it); such a step is
  not recorded, the robot ends at its last state;
* ``reached``: within ``goal_radius`` of the goal (a ``goal_follow`` goal is the followed robot's
  current position);
* ``stuck``: the controller said so (``sim.stop(i, "stuck")``), or the last ``stuck_window``
  seconds of the path fit in a disk of radius ``stuck_radius`` (no progress: a local minimum or an
  oscillation);
* ``timeout``: still going at ``max_time``.

A robot whose model gives its commanded body rates (:meth:`hybridnav.models.Model.body_rates`:
the unicycle's linear speed ``v`` and turn rate ``omega``) gets the metric ``control_effort``,
``sum_k (v_k^2 + omega_k^2) dt`` over its control cycles (units^2/s plus rad^2/s, with ``v_k``,
``omega_k`` the commands at the start of cycle ``k``: what a zero-order-hold controller holds over
the cycle, after the model's saturation): the paper's "control effort signal" is the angular
velocity, and the linear part counts a robot that drives longer.

A robot that ends keeps its last state. The loop has a fixed step budget, so it always ends.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hybridnav.limits import MAX_POSITION
from hybridnav.models.base import Model
from hybridnav.results import RobotResult
from hybridnav.resultspec import MAX_MAGNITUDE

__all__ = ["Simulation", "model_groups", "simulate"]


@dataclass
class Simulation:
    """The state of a running simulation, as a planner's controller sees it."""

    scenario: Any
    models: list                      # one model per robot
    X: list[np.ndarray]               # one state vector per robot
    t: float = 0.0
    k: int = 0
    active: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    outcome: list = field(default_factory=list)
    time_to_goal: list = field(default_factory=list)
    #: the run's own storage: what a planner keeps for this run only (its context, traced
    #: signals), so that nothing per-run lives on the planner object
    notes: dict[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.X)

    @property
    def positions(self) -> np.ndarray:
        """``(n, 2)`` current robot positions."""
        return np.array([x[:2] for x in self.X])

    def goals(self) -> np.ndarray:
        """``(n, 2)`` current goals (a followed robot's current position for ``goal_follow``)."""
        P = self.positions
        out = np.empty((self.n, 2))
        names = {r.name: i for i, r in enumerate(self.scenario.robots)}
        for i, r in enumerate(self.scenario.robots):
            out[i] = r.goal if r.goal is not None else P[names[r.goal_follow]]
        return out

    def stop(self, i: int, outcome: str) -> None:
        """End robot ``i`` now with ``outcome`` (e.g. ``"stuck"``)."""
        if self.active[i]:
            self.active[i] = False
            self.outcome[i] = outcome


def _recordable(X: np.ndarray) -> np.ndarray:
    """Rows of states ``X`` a result can hold (:func:`hybridnav.results.read_result` reads them
    back): finite, ``x`` and ``y`` within ``MAX_POSITION``, every component within
    ``MAX_MAGNITUDE``."""
    A = np.abs(np.asarray(X, dtype=float))        # (NaN compares False, without a warning)
    return np.all(A <= MAX_MAGNITUDE, axis=1) & np.all(A[:, :2] <= MAX_POSITION, axis=1)


def model_groups(models) -> list[tuple[Any, np.ndarray]]:
    """Robots whose models are equal share one batched step."""
    groups: dict[tuple, list[int]] = {}
    first: dict[tuple, Any] = {}
    for i, m in enumerate(models):
        key = m._key()
        groups.setdefault(key, []).append(i)
        first.setdefault(key, m)
    return [(first[k], np.array(v)) for k, v in groups.items()]


def simulate(
    scenario,
    models: list,
    controller: Callable[[Simulation], np.ndarray],
    *,
    stuck_window: float = 10.0,
    stuck_radius: np.ndarray | float | None = None,
    max_steps: int | None = None,
    notes: dict[str, Any] | None = None,
) -> tuple[list[RobotResult], Simulation]:
    """Run the closed loop of every robot of ``scenario`` under ``controller``.

    Parameters
    ----------
    scenario : Scenario
    models : list of Model
        One per robot (equal models are batched together).
    controller : callable
        ``controller(sim) -> (n, 2)`` target points for every robot (rows of robots that have
        ended are ignored). It may call ``sim.stop(i, "stuck")``.
    stuck_window, stuck_radius :
        The no-progress test (seconds; distance, per robot or shared; default twice each robot's
        goal radius). ``stuck_window <= 0`` disables it.
    max_steps : int, optional
        Step budget (default ``ceil(max_time / dt)``).
    notes : dict, optional
        The run's storage :attr:`Simulation.notes` starts with (e.g. the planner's context).

    Returns
    -------
    robots : list of RobotResult
        ``compute_time`` is the wall time of the loop shared among the robots active each cycle.
        ``min_clearance`` is the smallest clearance to obstacles and other robots while the robot
        moved; in a scenario with more than one robot, the metric ``min_robot_clearance`` is the
        smallest clearance to the other robots' footprints alone (negative: it touched a robot,
        whether that one was moving or had ended where it stands).
    sim : Simulation
        The final state (for planners that report more).
    """
    robots = scenario.robots
    n = len(robots)
    dt = scenario.dt
    steps = max_steps if max_steps is not None else int(math.ceil(scenario.max_time / dt - 1e-9))
    starts = {r.name: np.asarray(r.start, dtype=float) for r in robots}
    X = []
    for r, m in zip(robots, models):
        goal = r.goal if r.goal is not None else starts[r.goal_follow]
        X.append(m.initial_state(r.start, goal, r.initial))
    sim = Simulation(scenario, models, X, active=np.ones(n, dtype=bool), outcome=[None] * n,
                     time_to_goal=[None] * n, notes=dict(notes or {}))
    groups = model_groups(models)
    world = scenario.world
    goal_r = np.array([r.goal_radius for r in robots])
    if stuck_radius is None:
        stuck_radius = 2.0 * goal_r
    stuck_radius = np.broadcast_to(np.asarray(stuck_radius, dtype=float), (n,))
    # a window longer than the run is never tested: cut to steps + 1 cycles (as lockstep's
    # stuck_cycles), so the buffer below is sized by the run, not by any window one may set
    window = int(round(min(stuck_window / dt, steps + 1))) if stuck_window > 0 else 0
    hist_t = [[0.0] for _ in range(n)]
    hist_x = [[x.copy()] for x in X]
    # the last positions of hist_x, in order, as one array per robot (the no-progress test reads
    # its last window + 1 rows as a view instead of stacking them every cycle): a buffer of twice
    # that, whose last window rows move to its front when it is full
    cap = 2 * (window + 1)
    hist_p = np.empty((n, cap if window else 1, 2))
    hist_p[:, 0] = [x[:2] for x in X]
    fill = np.ones(n, dtype=int)
    min_clear = np.full(n, np.inf)
    min_robot = np.full(n, np.inf)
    compute = np.zeros(n)
    effort = np.zeros(n)                 # control effort, for models that give body rates
    _update_clearance(sim, world, 0.0, min_clear, np.ones(n, dtype=bool), min_robot)
    for k in range(steps):
        if not sim.active.any():
            break
        tic = time.perf_counter()
        sim.k = k
        T = np.asarray(controller(sim), dtype=float)
        was_active = sim.active.copy()
        for model, idx in groups:
            act = idx[sim.active[idx]]
            if not len(act):
                continue
            Xg = np.array([sim.X[i] for i in idx])
            Tg = np.where(np.isfinite(T[idx]), T[idx], Xg[:, :2])
            rates = model.commanded_rates(Xg, Tg)
            if rates is not None:
                on = sim.active[idx]
                effort[idx[on]] += np.sum(rates[on] ** 2, axis=1) * dt
            Xn = model.step(Xg, Tg)
            sane = _recordable(Xn)
            for j, i in enumerate(idx):
                if sim.active[i]:
                    if sane[j]:
                        sim.X[i] = Xn[j]
                    else:               # diverged: ends where it was (see the module docstring)
                        sim.stop(i, "out_of_bounds")
        sim.t = (k + 1) * dt
        share = (time.perf_counter() - tic) / max(1, int(was_active.sum()))
        compute[was_active] += share
        moved = was_active & sim.active
        for i in np.flatnonzero(moved):
            hist_t[i].append(sim.t)
            hist_x[i].append(sim.X[i].copy())
            if window:
                if fill[i] == cap:
                    hist_p[i, :window] = hist_p[i, cap - window:]
                    fill[i] = window
                hist_p[i, fill[i]] = sim.X[i][:2]
                fill[i] += 1
        # outcomes at the new time
        hit, outside = _update_clearance(sim, world, sim.t, min_clear, moved, min_robot)
        goals = sim.goals()
        P = sim.positions
        for i in np.flatnonzero(moved):
            if hit[i]:
                sim.stop(i, "collided")
            elif outside[i]:
                sim.stop(i, "out_of_bounds")
            elif np.hypot(*(P[i] - goals[i])) <= goal_r[i]:
                sim.stop(i, "reached")
                sim.time_to_goal[i] = sim.t
            elif window and len(hist_x[i]) > window:
                recent = hist_p[i, fill[i] - window - 1:fill[i]]
                span = np.max(np.hypot(*(recent - recent.mean(axis=0)).T))
                if span < stuck_radius[i]:
                    sim.stop(i, "stuck")
    for i in range(n):
        if sim.active[i]:
            sim.active[i] = False
            sim.outcome[i] = "timeout"
    results = []
    for i, (r, m) in enumerate(zip(robots, models)):
        results.append(RobotResult(
            name=r.name, outcome=sim.outcome[i], t=np.array(hist_t[i]),
            states=np.array(hist_x[i]), state_names=m.state_names,
            time_to_goal=sim.time_to_goal[i], min_clearance=float(min_clear[i]),
            compute_time=float(compute[i]),
            metrics={**({"control_effort": float(effort[i])} if _has_rates(m) else {}),
                     **({"min_robot_clearance": float(min_robot[i])} if n > 1 else {})},
        ))
    return results, sim


def _has_rates(model) -> bool:
    """Whether a model says its commanded body rates (so its runs have a control effort)."""
    return type(model).body_rates is not Model.body_rates


def _update_clearance(sim: Simulation, world, t: float, min_clear: np.ndarray,
                      which: np.ndarray, min_robot: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Update the running minimum clearance (and ``min_robot``, the clearance to the other
    robots alone); return (collided, out of bounds) per robot."""
    n = sim.n
    discs = [m.footprint(x[None]) for m, x in zip(sim.models, sim.X)]
    centers = [c[0] for c, _ in discs]
    radii = [r for _, r in discs]
    hit = np.zeros(n, dtype=bool)
    outside = np.zeros(n, dtype=bool)
    for i in np.flatnonzero(which):
        c, r = centers[i], radii[i]
        clear = world.clearance(c, t=t) - r if world.obstacles else np.full(len(r), np.inf)
        others = [j for j in range(n) if j != i]
        robot_clear = np.inf
        for j in others:
            d = np.linalg.norm(c[:, None, :] - centers[j][None, :, :], axis=2)
            gap = (d - r[:, None] - radii[j][None, :]).min(axis=1)
            clear = np.minimum(clear, gap)
            robot_clear = min(robot_clear, float(gap.min()))
        if min_robot is not None:
            min_robot[i] = min(min_robot[i], robot_clear)
        cmin = float(np.min(clear))
        min_clear[i] = min(min_clear[i], cmin)
        hit[i] = cmin < 0
        outside[i] = not bool(np.all(world.inside_workspace(c, r.max())))
    return hit, outside
