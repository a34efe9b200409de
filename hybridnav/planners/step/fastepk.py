"""FAStep-Kinematic (Chaudhary, Prasad, Prasad & Sharma 2024): kinematics first, fireflies to avoid.

The robot drives with its kinematic equations straight to the goal. While an obstacle or another
robot is within the protective region ``eps`` (eq. 11) it checks that move; when the move is no
longer safe, the stepping-ahead firefly algorithm (:func:`hybridnav.planners.swarm.fastep`) places a
step minimizing eq. 10 extended by ACO-Kinematic's line term::

    f = a / f1 + a_lines / f_lines + b / f2 + c * distance(candidate, goal)

(``f1``: circles, ``f2``: other robots -- the paper's numbering; the paper avoids line segments
with ACO-Kinematic's minimum distance technique but gives no weight, ours is ``a_lines = a``). The
robot drives to the step, and at the step drives straight on to the goal if that is now safe or
places another step. Defaults are the paper's Table 1 (50 fireflies, ``beta0 = 2``, ``alpha = 0.2``
damped by 0.8, ``a = b = 0.18``, ``c = 0.01``; ``alpha1 = alpha2 = 0.1`` are the point mass's
model defaults). The table leaves the absorption coefficient and the number of generations
blank: ``gamma = 100`` relative to the search box diagonal (see :func:`~hybridnav.planners.swarm.
fastep`) and 30 generations (3050 candidates per step) are our choices. See
:mod:`hybridnav.planners.step.base` for the shared loop and feasibility check.
"""

from __future__ import annotations

from typing import Any, ClassVar

from hybridnav.planners.base import Param
from hybridnav.planners.step.base import COMMON, StepPlanner
from hybridnav.planners.swarm import PRESETS, fastep

__all__ = ["FAStepKinematic"]

_TABLE1 = PRESETS["fastep"]["fastep-kinematic"]


class FAStepKinematic(StepPlanner):
    """Drive straight to the goal; place steps with the stepping-ahead firefly algorithm."""

    name = "fastep-kinematic"
    description = ("FAStep-Kinematic: kinematic equations to the goal, stepping-ahead firefly "
                   "steps round obstacles in the way")
    direct_first = True
    weight_names = ("a", "a_lines", "b", "c")
    parameters: ClassVar[dict[str, Param]] = {
        "a": Param(0.18, "safety weight of the circular obstacles (eq. 10)", lo=0.0),
        "a_lines": Param(0.18, "safety weight of the line segments (minimum distance technique)",
                         lo=0.0),
        "b": Param(0.18, "safety weight of the other robots (eq. 10)", lo=0.0),
        "c": Param(0.01, "weight of the distance to the goal (eq. 10)", lo=0.0),
        "n": Param(int(_TABLE1["n"]), "number of fireflies", lo=2),
        "iterations": Param(30, "generations per step", lo=1),
        "beta0": Param(float(_TABLE1["beta0"]), "attraction coefficient base value", lo=0.0),
        "gamma": Param(float(_TABLE1["gamma"]), "light absorption coefficient (relative to the "
                                                "search box diagonal)", lo=0.0),
        "alpha": Param(float(_TABLE1["alpha"]), "mutation coefficient (fraction of the box)",
                       lo=0.0),
        "damping": Param(float(_TABLE1["damping"]), "mutation coefficient damping ratio",
                         lo=0.0, hi=1.0),
        **COMMON,
        "window": Param(10.0, "half-width of the square the fireflies search around the robot, "
                              "in robot radii; 0: the whole workspace", lo=0.0),
    }

    profiles: ClassVar[dict[str, dict[str, Any]]] = {
        "paper": {"distance": "euclidean", "goal_candidate": False}}
    paper_notes = ("paper: the straight-line distance to the goal in the step fitness (eq. 10), "
                   "no goal among the fireflies' starting points")
    paper_deviations = StepPlanner.paper_deviations + (
        "search window: the fireflies search a square of `window` = 10 robot radii around the "
        "robot; the paper does not bound the search",
        "obstacle in the protective region: the robot keeps driving straight to the goal while "
        "that move's rollout is feasible and places a firefly step only when it is not; the "
        "paper switches to firefly steps whenever an obstacle is within eps (eq. 11)",
        "values the paper leaves out: eps = 6 robot radii (no value given), the absorption "
        "coefficient gamma = 100 relative to the search box diagonal and 30 generations "
        "(blank in Table 1), and a_lines = a for line segments (the paper gives no line "
        "weight)",)

    def optimize(self, f, lower, upper, rng, init, memory):
        v = self.values
        return fastep(f, (lower, upper), n=v["n"], iterations=v["iterations"], seed=rng,
                      init=init, alpha=v["alpha"], beta0=v["beta0"], gamma=v["gamma"],
                      damping=v["damping"])
