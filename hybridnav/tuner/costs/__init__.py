"""Tuning costs: a batch of candidate systems and a context in, ``(n, m)`` objectives out
(:class:`Cost`); :class:`NavigationCost` (a planner on worlds), :class:`DataCost` (input/output
samples) and :class:`FunctionCost` (your own function)."""

from hybridnav.tuner.costs.base import Candidates, Context, Cost, Evaluation
from hybridnav.tuner.costs.data import DataCost
from hybridnav.tuner.costs.function import FunctionCost
from hybridnav.tuner.costs.navigation import NavigationCost

__all__ = ["Candidates", "Context", "Cost", "DataCost", "Evaluation", "FunctionCost",
           "NavigationCost"]
