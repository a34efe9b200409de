"""Offline GA tuning of the EFFC fuzzy force weight (DEAP), on one machine or a Dask cluster.

``load_job(path)`` reads and validates a job file (``None``: the built-in job), ``run_job(job,
out)`` tunes and writes every output (what ``hybridnav tune`` runs), ``tune(job, out)`` only
tunes (checkpointing in ``out``) and returns a :class:`TuneResult`.
"""

from hybridnav.tuner.ga import TuneResult, tune
from hybridnav.tuner.job import DEFAULT_JOB, Job, load_job, quick
from hybridnav.tuner.run import run_job, write_outputs

__all__ = ["DEFAULT_JOB", "Job", "TuneResult", "load_job", "quick", "run_job", "tune",
           "write_outputs"]
