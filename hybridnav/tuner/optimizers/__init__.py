"""Tuning optimizers with one step interface (``setup / ask / tell / state``): :class:`GA`,
:class:`CMAES`, :class:`PSO` and :class:`NSGA2` (several objectives), and the variation operators
the evolutionary ones take as objects."""

from hybridnav.errors import HybridnavError
from hybridnav.tuner.optimizers.base import Optimizer, Problem
from hybridnav.tuner.optimizers.cmaes import CMAES
from hybridnav.tuner.optimizers.ga import GA
from hybridnav.tuner.optimizers.nsga2 import NSGA2, non_dominated
from hybridnav.tuner.optimizers.operators import SBX, Blend, Gaussian, Polynomial
from hybridnav.tuner.optimizers.pso import PSO

__all__ = ["CMAES", "GA", "NSGA2", "OPTIMIZERS", "PSO", "SBX", "Blend", "Gaussian", "Optimizer",
           "Polynomial", "Problem", "make_optimizer", "non_dominated"]

#: kind (as a job file's ``[optimizer] kind`` writes it) -> class
OPTIMIZERS: dict[str, type[Optimizer]] = {"ga": GA, "cmaes": CMAES, "pso": PSO, "nsga2": NSGA2}


def make_optimizer(table: dict, where: str = "") -> Optimizer:
    """An optimizer from a job file's ``[optimizer]`` table: ``kind`` and its own settings."""
    t = dict(table)
    kind = t.pop("kind", "ga")
    if not isinstance(kind, str) or kind not in OPTIMIZERS:
        raise HybridnavError(f"{where}optimizer.kind: expected one of {', '.join(OPTIMIZERS)}, "
                             f"got {kind!r}")
    try:
        return OPTIMIZERS[kind](**t)
    except HybridnavError as exc:
        msg = str(exc)
        if msg.startswith(f"{kind}: "):
            msg = msg[len(kind) + 2:]
        raise HybridnavError(f"{where}optimizer.{msg}") from None
