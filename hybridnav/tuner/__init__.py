"""Tune any Mamdani fuzzy system: a problem (:class:`TunableSettings`), a cost
(:class:`NavigationCost`, :class:`DataCost`, :class:`FunctionCost`) and an optimizer
(:class:`GA`, :class:`CMAES`, :class:`PSO`, :class:`NSGA2`), on one machine or a Dask cluster.

>>> from hybridnav.tuner import tune, DataCost, CMAES            # doctest: +SKIP
>>> result = tune(start, DataCost(X, y), optimizer=CMAES(), seed=3)
>>> result.system, result.logbook, result.front

Tuning jobs (TOML files, ``hybridnav tune``) are a thin front over the same objects:
``load_job(path)`` reads and validates one (``None``: the built-in EFFC job) and
``run_job(job, out)`` tunes and writes every output.
"""

from hybridnav.tuner.animation import animate_tuning
from hybridnav.tuner.core import KFold, learn, select_member, tune
from hybridnav.tuner.costs import (
    Candidates,
    Context,
    Cost,
    DataCost,
    Evaluation,
    FunctionCost,
    NavigationCost,
)
from hybridnav.tuner.job import DEFAULT_JOB, Job, load_job, quick
from hybridnav.tuner.optimizers import CMAES, GA, NSGA2, PSO, SBX, Blend, Gaussian, Polynomial
from hybridnav.tuner.result import Member, TuningResult
from hybridnav.tuner.run import run_job, write_generations, write_outputs
from hybridnav.tuner.settings import TunableSettings

__all__ = ["CMAES", "DEFAULT_JOB", "animate_tuning", "GA", "NSGA2", "PSO", "SBX", "Blend", "Candidates",
           "Context", "Cost", "DataCost", "Evaluation", "FunctionCost", "Gaussian", "Job",
           "KFold", "Member", "learn", "NavigationCost", "Polynomial", "TunableSettings", "TuningResult",
           "load_job", "quick", "run_job", "select_member", "tune", "write_generations",
           "write_outputs"]
