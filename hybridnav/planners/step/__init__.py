"""Step planners that search the next position with a swarm optimizer and the kinematics —
``fastep-kinematic``, ``aco-kinematic`` — and their shared step loop (:mod:`.base`,
:class:`StepPlanner`; :mod:`.stepfit` checks candidate steps)."""

from hybridnav.planners.step.base import StepPlanner

__all__ = ["StepPlanner"]
