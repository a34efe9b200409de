"""Swarm optimizers: pure, vectorized, seeded minimizers that know nothing about robots.

Every optimizer has the signature ``name(f, bounds, *, <population size>, iterations=100,
max_evals=None, target=None, seed=None, init=None, **method_parameters) -> OptResult``:

* ``f(X)`` takes an ``(N, d)`` array of points and returns ``N`` values (lower is better; NaN
  counts as ``+inf``). It is called once for the initial population and once per iteration with
  the whole swarm, never per individual. An objective that also offers cheap lower bounds
  (:class:`~hybridnav.planners.swarm._core.BoundedObjective`) is asked for its exact values
  only where they can change the run (``acor``, ``fastep``: in a few batches per iteration);
  the result is the same.
* ``bounds = (lower, upper)``, two sequences of length ``d`` with ``lower < upper``; every point
  passed to ``f`` lies inside the box.
* the budget is ``iterations`` and/or ``max_evals`` (an iteration that would exceed ``max_evals``
  is not started) and optionally a ``target`` value.
* all randomness comes from one :class:`numpy.random.Generator` built from ``seed``: the same seed
  gives the identical result.

:data:`OPTIMIZERS` maps names to the functions, :func:`minimize` calls one by name, and
:data:`PRESETS` holds the parameter sets of the papers hybridnav implements.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.planners.swarm._core import (
    BoundsLike,
    History,
    Objective,
    OptResult,
    SeedLike,
)
from hybridnav.planners.swarm.acor import ACO_KINEMATIC, acor, acor_weights
from hybridnav.planners.swarm.bat import bat
from hybridnav.planners.swarm.firefly import fastep, firefly
from hybridnav.planners.swarm.pso import pso
from hybridnav.planners.swarm.pso_ba import PSOBAResult, pso_ba

__all__ = ["ACO_KINEMATIC", "OPTIMIZERS", "PRESETS", "History", "OptResult", "PSOBAResult",
           "acor", "acor_weights", "bat", "fastep", "firefly", "minimize", "pso", "pso_ba"]

#: name -> optimizer function.
OPTIMIZERS: dict[str, Callable[..., OptResult]] = {
    "firefly": firefly,
    "fastep": fastep,
    "acor": acor,
    "pso": pso,
    "bat": bat,
}

#: optimizer name -> preset name -> parameters taken from a paper.
PRESETS: dict[str, dict[str, dict[str, Any]]] = {
    # FAStep-Kinematic (Chaudhary et al. 2024), Table 1; gamma is blank there (our choice: 100,
    # relative to the box diagonal, see fastep). These are also fastep's defaults.
    "fastep": {"fastep-kinematic": {"n": 50, "gamma": 100.0, "beta0": 2.0, "alpha": 0.2,
                                    "damping": 0.8}},
    # ACO-Kinematic (Chaudhary et al. 2022), Table 1.
    "acor": {"aco-kinematic": dict(ACO_KINEMATIC)},
    # RFD-PSO (Hassen et al. 2023), Table 1: inertia 0.5, c1 = c2 = 0.75.
    "pso": {"rfd-pso": {"w": 0.5, "c1": 0.75, "c2": 0.75}},
}


def minimize(name: str, f: Objective, bounds: BoundsLike, *, preset: str | None = None,
             seed: SeedLike = None, **params: Any) -> OptResult:
    """Run the optimizer ``name`` on ``f`` over ``bounds``.

    Parameters
    ----------
    name : str
        A key of :data:`OPTIMIZERS`: ``"firefly"``, ``"fastep"``, ``"acor"``, ``"pso"``,
        ``"bat"``.
    f : callable
        Vectorized objective ``f(X) -> values`` with ``X`` of shape ``(N, d)``.
    bounds : (lower, upper)
        Box of the search.
    preset : str or None, optional
        A key of ``PRESETS[name]``; its parameters are applied first, ``params`` override them.
    seed : int, SeedSequence, Generator or None, optional
        Seed of the run's random generator.
    **params
        Keyword arguments of the optimizer (population size, budget, method parameters).

    Returns
    -------
    OptResult

    Raises
    ------
    HybridnavError
        Unknown optimizer, preset or parameter, or a bad value.
    """
    try:
        fn = OPTIMIZERS[name]
    except (KeyError, TypeError):
        raise HybridnavError(f"name: unknown optimizer {name!r}; expected one of: "
                             f"{', '.join(OPTIMIZERS)}") from None
    merged: dict[str, Any] = {}
    if preset is not None:
        known = PRESETS.get(name, {})
        if preset not in known:
            raise HybridnavError(f"preset: unknown preset {preset!r} for {name}; expected one "
                                 f"of: {', '.join(known) or '(none)'}")
        merged.update(known[preset])
    merged.update(params)
    accepted = set(inspect.signature(fn).parameters) - {"f", "bounds"}
    unknown = sorted(set(merged) - accepted)
    if unknown:
        raise HybridnavError(f"{unknown[0]}: unknown parameter of {name}; expected one of: "
                             f"{', '.join(sorted(accepted - {'seed'}))}")
    return fn(f, bounds, seed=seed, **merged)
