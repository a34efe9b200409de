"""Potential-field planners that command a velocity every control cycle — ``apf``, ``effc``,
``hapf``, ``pbpf`` — their shared loop (:mod:`.base`, :class:`FieldPlanner`), the lockstep batch of
many worlds (:mod:`.lockstep`, :mod:`.worldstack`) the tuner runs."""

from hybridnav.planners.field.base import FieldPlanner

__all__ = ["FieldPlanner"]
