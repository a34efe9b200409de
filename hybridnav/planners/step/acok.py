"""ACO-Kinematic (Chaudhary, Prasad, Chand & Sharma 2022): ants plan every step of the way.

For every step the robot takes, ACOR (:func:`hybridnav.planners.swarm.acor`) places the next step
minimizing eq. 13, ``f = a / f1 + b / f2 + c / f3 + d * distance(candidate, goal)`` (circles, line
segments, other robots, goal), and the robot's kinematic equations drive it there. Defaults are
the paper's Table 1: archive 300, sample size 10000, deviation-distance ratio ``xi = 1``,
intensification factor ``q = 0.5``, ``a = b = c = 0.18``, ``d = 0.01`` (its Table 3 uses
``a = 0.02`` and ``c = 0.05`` / 0.18 for the comparison with LbCS). One ACOR generation per step,
as in the paper's Algorithm 1; by default the archive starts afresh at every step (with the goal
in it), because the robot has moved and every stored fitness, which includes the feasibility of
driving there from the robot's state, would be stale. ``profile=paper`` keeps one archive for the
run as Algorithm 1 does (``archive=persistent``, its solutions re-evaluated at every step) and
leaves the goal out (``goal_candidate=false``). See :mod:`hybridnav.planners.step.base` for the
shared loop and feasibility check.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from hybridnav.planners.base import Param
from hybridnav.planners.step.base import COMMON, StepPlanner
from hybridnav.planners.swarm import ACO_KINEMATIC, acor

__all__ = ["ACOKinematic"]


class ACOKinematic(StepPlanner):
    """Plan every step with ACOR; drive to it with the robot's kinematic equations."""

    name = "aco-kinematic"
    description = "ACO-Kinematic: ACOR places every step, kinematic equations drive to it"
    direct_first = False
    parameters: ClassVar[dict[str, Param]] = {
        "a": Param(0.18, "safety weight of the circular obstacles (eq. 13)", lo=0.0),
        "b": Param(0.18, "safety weight of the line segments (eq. 13)", lo=0.0),
        "c": Param(0.18, "safety weight of the other robots (eq. 13)", lo=0.0),
        "d": Param(0.01, "weight of the distance to the goal (eq. 13)", lo=0.0),
        "k": Param(int(ACO_KINEMATIC["k"]), "archive size (population)", lo=2),
        "m": Param(int(ACO_KINEMATIC["m"]), "sample size (ants per generation)", lo=1),
        "xi": Param(float(ACO_KINEMATIC["xi"]), "deviation-distance ratio", lo=0.0, lo_open=True),
        "q": Param(float(ACO_KINEMATIC["q"]), "intensification factor", lo=0.0, lo_open=True),
        "iterations": Param(1, "ACOR generations per step", lo=1),
        "archive": Param("fresh", "ACOR archive of a step: 'fresh' (random, with the goal, at every "
                                  "step) or 'persistent' (the paper's Algorithm 1: one archive for "
                                  "the run, re-evaluated at every step)",
                         choices=("fresh", "persistent")),
        **COMMON,
    }

    profiles: ClassVar[dict[str, dict[str, Any]]] = {
        "paper": {"distance": "euclidean", "goal_candidate": False, "archive": "persistent"}}
    paper_notes = ("paper: the straight-line distance to the goal in the step fitness (eq. 13), "
                   "no goal candidate, one ACOR archive for the whole run (Algorithm 1; its "
                   "solutions are re-evaluated at every step, since a step's feasibility "
                   "depends on where the robot is)")

    def optimize(self, f, lower, upper, rng, init, memory):
        v = self.values
        if v["archive"] == "persistent" and "archive" in memory:
            kept = np.clip(memory["archive"], lower, upper)
            init = kept if init is None else np.concatenate([init, kept])[:v["k"]]
        res = acor(f, (lower, upper), k=v["k"], m=v["m"], iterations=v["iterations"], seed=rng,
                   init=init, xi=v["xi"], q=v["q"])
        if v["archive"] == "persistent":
            memory["archive"] = res.population
        return res
