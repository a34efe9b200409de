"""Experiments over planners: the comparison harness (:mod:`~hybridnav.experiments.compare`, what
``hybridnav compare`` runs) and the convergence of the planners' swarm searches
(:mod:`~hybridnav.experiments.convergence`). The papers' own protocols, built on them, are in
:mod:`hybridnav.reproduce`.

The modules are imported on use (they load matplotlib and pandas).
"""

__all__: list[str] = []
