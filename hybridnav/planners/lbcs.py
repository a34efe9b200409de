"""The Lyapunov-based control scheme (LbCS) as a planner: the LbCS model drives every robot.

Each point-mass robot of the scenario gets its own :class:`hybridnav.models.LbCS` (the scenario's
static circles, the robot radius as ``rp``) and follows ``xdot = -(1/delta) grad L`` to its goal.
``Ldot <= 0`` along the way, but the scheme stops wherever ``grad L`` vanishes: in a local minimum
such as the cup of ``aco-local-minimum`` the robot stalls and the run ends ``stuck`` (the shared
no-progress test). Circle obstacles, point masses and fixed goals only; the other robots of a
scenario are not part of each robot's ``L`` (only the collision check sees them).
"""

from __future__ import annotations

from typing import ClassVar

from hybridnav.models import LbCS
from hybridnav.planners.base import Param, Planner
from hybridnav.planners.simulate import simulate
from hybridnav.results import Result

__all__ = ["LbCSPlanner"]


class LbCSPlanner(Planner):
    """Lyapunov-based control scheme (Sharma & Vanualailai) for point masses among circles."""

    name = "lbcs"
    description = "Lyapunov-based control scheme: gradient flow of L = V (1 + sum beta / FO)"
    models: ClassVar[tuple[str, ...]] = ("point_mass",)
    moving_obstacles = False
    moving_targets = False
    params: ClassVar[dict[str, Param]] = {
        "beta": Param(LbCS.defaults["beta"], "obstacle avoidance gain", lo=1e-12),
        "delta1": Param(LbCS.defaults["delta1"], "gain: xdot = -(1/delta1) dL/dx", lo=1e-12),
        "delta2": Param(LbCS.defaults["delta2"], "gain: ydot = -(1/delta2) dL/dy", lo=1e-12),
        "stuck_window": Param(20.0, "seconds without leaving a small disk that count as stuck "
                                    "(0: off)", lo=0.0),
        "stuck_radius": Param(0.5, "that disk's radius, in goal radii", lo=0.0),
    }

    def run(self, scenario, seed: int | None = None) -> Result:
        self.check_scenario(scenario)
        v = self.values
        models = [LbCS.from_scenario(scenario, r.name, beta=v["beta"], delta1=v["delta1"],
                                     delta2=v["delta2"]) for r in scenario.robots]
        goal_r = [r.goal_radius for r in scenario.robots]
        robots, _ = simulate(scenario, models, lambda sim: sim.goals(),
                             stuck_window=v["stuck_window"],
                             stuck_radius=[v["stuck_radius"] * g for g in goal_r])
        return Result(scenario=scenario.name, planner=self.name, params=self.describe(),
                      seed=seed, robots=robots)
