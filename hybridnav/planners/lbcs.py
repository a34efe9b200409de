"""The Lyapunov-based control scheme (LbCS) as a planner, for point masses and tractor-trailers.

Every robot gets its own :class:`hybridnav.models.LbCS` function ``L`` (the scenario's static
circles; its goal as the target) and the velocity field ``-(1/delta) grad L``, i.e.
``xdot = -(1/delta1) dL/dx``, ``ydot = -(1/delta2) dL/dy``.

Point masses (``rp`` = the robot radius)
    The LbCS model itself is simulated: the robot *is* the gradient flow, so ``Ldot <= 0`` along
    the way. The scheme stops wherever ``grad L`` vanishes: in a local minimum such as the cup of
    ``aco-local-minimum`` the robot stalls and the run ends ``stuck`` (the shared no-progress
    test).
Tractor-trailers (``rp`` = the model's ``radius``, ``sqrt(L^2 + b^2) / 2``)
    Our reconstruction, not Sharma et al. (2008)'s acceleration-controlled scheme, whose equations
    the ACO-Kinematic paper does not print: each control cycle the LbCS velocity at the tractor's
    reference point ``(x, y)`` is turned into a target point with the tractor-trailer model's
    :meth:`~hybridnav.models.TractorTrailer.carrot` (as :mod:`hybridnav.planners.field.base` drives
    models from a velocity field), and the model's own steering law follows it. With the defaults
    (``alpha = 0.1``, ``delta = 10``, so ``1 / (alpha delta) = 1``) the carrot away from obstacles
    is (nearly) the goal itself. The tractor is nonholonomic, so it follows the field only
    approximately and ``L`` at the tractor is not guaranteed to decrease at every step (near an
    obstacle the field can turn faster than the tractor). ``L`` keeps only the tractor's disk
    off the circles; the trailer is left to the shared collision check.

    The commanded speed is ``min(|v|, alpha ||x - p||)``: never more than the speed at which the
    model's own law drives the tractor straight to its goal ``p`` (the carrot is never farther
    away than the goal is). ``|grad L|`` grows like ``1 / FO_l^2`` near an obstacle, and a tractor
    that cannot turn with the field gets close enough there to be commanded tens of units per
    second: without the cap, with ``beta = 0.1`` in ``tractor-trailer-1``, it jumps about 6 units
    (more than an obstacle's diameter) in one control cycle, then spins and leaves the workspace.
    Away from obstacles ``|v|`` is about ``(1 + sum beta / FO_l) ||x - p|| / delta``, so with the
    defaults the cap is active on most of a run but takes off little, and where the field
    points at the goal with the cap active the carrot is the goal itself: a fixed target, which
    the steering law reaches when lined up early enough, rather than one moving with the tractor
    that can hold it on the orbit the law settles on around a target closer than about ``9L/7``
    (see :mod:`hybridnav.models.tractor_trailer`).

Of the ACO-Kinematic paper's Table 4, this planner uses ``beta`` (one gain for every obstacle)
and ``delta1``, ``delta2``, for both robot kinds. ``beta1`` is not used (the paper does not say
what it weighs; the LbCS model has no workspace-boundary terms), and ``beta3``, ``beta4`` and
``gamma`` are not modelled: they belong to Sharma et al.'s acceleration-controlled tractor-trailer
scheme, which is not reconstructed here. Circle obstacles and fixed goals only; the other
robots of a scenario are not part of any robot's ``L`` (only the collision check sees them).
"""

from __future__ import annotations

from typing import ClassVar

import casadi as cs
import numpy as np

from hybridnav.models import LbCS
from hybridnav.models.compile import _Buffered
from hybridnav.params import check_seed
from hybridnav.planners.base import Param, Planner
from hybridnav.planners.simulate import Simulation, model_groups, simulate
from hybridnav.results import Result

__all__ = ["LbCSPlanner"]


class LbCSPlanner(Planner):
    """Lyapunov-based control scheme (Sharma & Vanualailai) among circles.

    Drives point masses (the LbCS gradient flow itself) and tractor-trailers (the LbCS velocity
    at the tractor, followed through the model's carrot); see the module docstring.
    """

    name = "lbcs"
    description = "Lyapunov-based control scheme: gradient flow of L = V (1 + sum beta / FO)"
    #: point masses follow L's gradient flow themselves; a tractor-trailer tracks it
    drives = (frozenset({"holonomic"}), frozenset({"trailer"}))
    moving_obstacles = False
    moving_targets = False
    parameters: ClassVar[dict[str, Param]] = {
        "beta": LbCS.parameters["beta"],
        "delta1": LbCS.parameters["delta1"],
        "delta2": LbCS.parameters["delta2"],
        "stuck_window": Param(20.0, "seconds without leaving a small disk that count as stuck "
                                    "(0: off)", lo=0.0),
        "stuck_radius": Param(0.5, "that disk's radius, in goal radii", lo=0.0),
    }

    def lbcs(self, scenario, robot: str, rp: float | None = None) -> LbCS:
        """The LbCS model (function ``L``) of a robot of ``scenario`` with this planner's gains.

        Parameters
        ----------
        scenario : Scenario
        robot : str
            The robot's name (its goal is the target).
        rp : float, optional
            Robot radius in ``FO_l`` (default: the robot's radius).

        Returns
        -------
        LbCS
        """
        v = self.values
        extra = {} if rp is None else {"rp": rp}
        return LbCS.from_scenario(scenario, robot, beta=v["beta"], delta1=v["delta1"],
                                  delta2=v["delta2"], **extra)

    def check_scenario(self, scenario) -> None:
        """Also reject obstacles the LbCS model cannot take (so ``compare`` fails before work)."""
        super().check_scenario(scenario)
        for r in scenario.robots:
            self.lbcs(scenario, r.name)

    def run(self, scenario, seed: int | None = None) -> Result:
        self.check_scenario(scenario)
        seed = check_seed(seed)
        v = self.values
        from hybridnav.models import MODELS

        # a holonomic robot (the point mass) is the LbCS gradient flow; others track it
        models = [self.lbcs(scenario, r.name) if "holonomic" in MODELS[r.model].capabilities
                  else scenario.model(r) for r in scenario.robots]
        # one LbCS velocity field per group of equal vehicle models (equal radius, so equal rp)
        fields = [(model, members, _Velocity(self.lbcs(scenario, scenario.robots[members[0]].name,
                                                       rp=model.radius), len(members)))
                  for model, members in model_groups(models) if not isinstance(model, LbCS)]
        goal_r = np.array([r.goal_radius for r in scenario.robots])

        def controller(sim: Simulation) -> np.ndarray:
            goals = sim.goals()
            T = goals.copy()           # LbCS models take their goal as the target
            for model, members, velocity in fields:
                X = np.array([sim.X[i] for i in members])
                V = velocity(X[:, :2], goals[members])
                T[members] = _capped_carrot(model, X, V, goals[members])
            return T

        robots, _ = simulate(scenario, models, controller, stuck_window=v["stuck_window"],
                             stuck_radius=v["stuck_radius"] * goal_r)
        return Result(scenario=scenario.name, planner=self.name, params=self.describe(),
                      seed=seed, robots=robots)


def _capped_carrot(model, X: np.ndarray, V: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """Targets for a batch of vehicles asked to move with the LbCS velocities ``V``.

    ``model.carrot(X, V')`` where ``V'`` is ``V`` scaled down, where needed, to the speed
    ``alpha * ||x - goal||`` of the model's go-to-point law driving to the goal.

    Parameters
    ----------
    model : TractorTrailer
        The vehicles' model (one model for the whole batch; it has a speed gain ``alpha``).
    X : ndarray, shape (N, nx)
    V : ndarray, shape (N, 2)
    goals : ndarray, shape (N, 2)

    Returns
    -------
    ndarray, shape (N, 2)
    """
    cap = model.values["alpha"] * np.hypot(*(goals - X[:, :2]).T)
    speed = np.hypot(V[:, 0], V[:, 1])
    scale = np.minimum(1.0, cap / np.where(speed > 0, speed, 1.0))
    return model.carrot(X, V * scale[:, None])


class _Velocity:
    """``-(1/delta) grad L`` of an LbCS model for a batch of ``n`` points, compiled once."""

    def __init__(self, lb: LbCS, n: int) -> None:
        s = lb.sym
        u = cs.substitute(lb.controller(s.x, s.target, s.p), s.p, cs.DM(lb.p_value()))
        fn = cs.Function("lbcs_velocity", [s.x, s.target], [u]).map(n)
        self._b = _Buffered(fn, [(n, 2), (n, 2)], [(n, 2)])

    def __call__(self, P: np.ndarray, goals: np.ndarray) -> np.ndarray:
        self._b.ins[0][...] = P
        self._b.ins[1][...] = goals
        self._b()
        return self._b.outs[0].copy()
