"""PSO-BA (Abed et al. 2022): the planner (:mod:`.planner`) and its range sensors, local-search
repair and wall following (:mod:`.sensors`)."""

from hybridnav.planners.psoba.planner import (
    PSOBAPlanner,
    PSOBAResult,
    disk_candidates,
    pso_ba,
    psoba_fitness,
)

__all__ = ["PSOBAPlanner", "PSOBAResult", "disk_candidates", "pso_ba", "psoba_fitness"]
