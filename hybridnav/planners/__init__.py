"""Navigation methods: one module per planner; ``planners/swarm`` holds the pure optimizers.

``get(name, **params)`` returns a planner; :data:`PLANNERS` maps names to classes.
"""

from __future__ import annotations

from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.planners.acok import ACOKinematic
from hybridnav.planners.apf import APF
from hybridnav.planners.base import Param, Planner, parse_assignments
from hybridnav.planners.effc import EFFC
from hybridnav.planners.fastepk import FAStepKinematic
from hybridnav.planners.hapf import HAPF
from hybridnav.planners.lbcs import LbCSPlanner
from hybridnav.planners.paths import (
    AStarPlanner,
    DijkstraPlanner,
    PSOPathPlanner,
    RFDPlanner,
    RFDPSOPlanner,
)
from hybridnav.planners.pbpf import PBPF
from hybridnav.planners.psoba import PSOBAPlanner

PLANNERS: dict[str, type[Planner]] = {
    cls.name: cls for cls in (ACOKinematic, APF, AStarPlanner, DijkstraPlanner, EFFC,
                              FAStepKinematic, HAPF, LbCSPlanner, PBPF, PSOBAPlanner, PSOPathPlanner,
                              RFDPlanner, RFDPSOPlanner)
}

__all__ = ["PLANNERS", "Param", "Planner", "get", "parse_assignments"]


def get(name: str, **params: Any) -> Planner:
    """The planner ``name`` with parameter overrides (strings are parsed as on the CLI)."""
    try:
        cls = PLANNERS[name]
    except KeyError:
        raise HybridnavError(
            f"planner: unknown planner {name!r}; expected one of: {', '.join(sorted(PLANNERS))}"
        ) from None
    return cls(**params)
