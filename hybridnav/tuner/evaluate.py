"""The lockstep navigation simulation's helpers shared by the navigation cost, the held-out
judging and the falsification search: packed world sets (:func:`scenario_set`) and the reward of
every run (:func:`run_costs`). The cost itself is
:class:`hybridnav.tuner.costs.navigation.NavigationCost`; the EFFC lockstep controller is
:func:`hybridnav.planners.field.effc.effc_lockstep`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from hybridnav.planners.field.effc import effc_lockstep as lockstep_effc
from hybridnav.planners.field.lockstep import LockstepResult
from hybridnav.planners.field.worldstack import WorldStack

__all__ = ["ScenarioSet", "lockstep_effc", "run_costs", "scenario_set"]


@dataclass
class ScenarioSet:
    """Scenarios packed for the lockstep simulation (one robot model for all)."""

    scenarios: list
    stack: WorldStack
    radius: np.ndarray           # robot radius per environment


def scenario_set(scenarios) -> ScenarioSet:
    """Scenarios packed for the lockstep simulation (one robot model for all)."""
    return ScenarioSet(list(scenarios), WorldStack([s.world for s in scenarios]),
                       np.array([s.robots[0].radius for s in scenarios]))


def run_costs(reward: dict[str, Any], speed: float, scenarios, res: LockstepResult
              ) -> np.ndarray:
    """The cost (reward) of every run, ``(E, M)``, by ``reward["kind"]`` (see
    :mod:`hybridnav.tuner.costs.navigation`)."""
    rw = reward
    outcome = res.outcome
    reached = outcome == "reached"
    if rw["kind"] == "length":
        return np.where(reached, res.path_length, rw["penalty"])
    if rw["kind"] == "paper":
        return np.where(reached, res.path_length, -rw["penalty"])
    start = np.array([s.robots[0].start for s in scenarios], dtype=float)
    goal = np.array([s.robots[0].goal for s in scenarios], dtype=float)
    goal_r = np.array([s.robots[0].goal_radius for s in scenarios])
    radius = np.array([s.robots[0].radius for s in scenarios])
    d0 = np.hypot(*(goal - start).T)
    D = np.maximum(d0 - goal_r, goal_r)[:, None]
    ok = (rw["length"] * res.path_length / D
          + rw["time"] * np.nan_to_num(res.time) * speed / D)
    safety = rw["safety_distance"] * radius[:, None]
    if rw["clearance"] > 0 and np.any(safety > 0):
        short = np.clip(1.0 - res.min_clearance / np.where(safety > 0, safety, 1.0), 0.0, 1.0)
        ok = ok + rw["clearance"] * np.where(safety > 0, short, 0.0)
    crash = (outcome == "collided") | (outcome == "out_of_bounds")
    left = np.minimum(1.0, res.final_distance / np.maximum(d0, 1e-12)[:, None])
    fail = rw["failure"] + rw["progress"] * left
    return np.where(reached, ok, np.where(crash, rw["collision"], fail))
