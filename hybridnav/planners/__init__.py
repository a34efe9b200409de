"""Navigation methods, grouped by family: ``field/`` (potential fields), ``step/`` (swarm-searched
steps), ``path/`` (plan then track), ``psoba/``, and ``lbcs``; ``swarm/`` holds the pure
optimizers, which know nothing about robots; :mod:`.simulate` is the loop every family shares.

``get(name, **params)`` returns a planner; :data:`PLANNERS` maps names to classes.

The deprecated module paths of 0.2 (``hybridnav.planners.apf``, ``.paths``, ``.stepping``, ...)
still import, with a warning, until 0.4.0 (:data:`hybridnav.deprecation.MOVED_MODULES`).
"""

from __future__ import annotations

from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.planners.base import Param, Planner, parse_assignments
from hybridnav.planners.field.apf import APF
from hybridnav.planners.field.effc import EFFC
from hybridnav.planners.field.hapf import HAPF
from hybridnav.planners.field.pbpf import PBPF
from hybridnav.planners.field.steer import FuzzySteer
from hybridnav.planners.lbcs import LbCSPlanner
from hybridnav.planners.path.planners import (
    AStarPlanner,
    DijkstraPlanner,
    PSOPathPlanner,
    RFDPlanner,
    RFDPSOPlanner,
)
from hybridnav.planners.psoba.planner import PSOBAPlanner
from hybridnav.planners.step.acok import ACOKinematic
from hybridnav.planners.step.fastepk import FAStepKinematic

PLANNERS: dict[str, type[Planner]] = {
    cls.name: cls for cls in (ACOKinematic, APF, AStarPlanner, DijkstraPlanner, EFFC,
                              FAStepKinematic, FuzzySteer, HAPF, LbCSPlanner, PBPF, PSOBAPlanner, PSOPathPlanner,
                              RFDPlanner, RFDPSOPlanner)
}

__all__ = ["PLANNERS", "Param", "Planner", "fuzzy_units", "get", "parse_assignments"]

def get(name: str, **params: Any) -> Planner:
    """The planner ``name`` with parameter overrides (strings are parsed as on the CLI).

    Parameters
    ----------
    name : str
        A key of :data:`PLANNERS`.
    **params
        Parameter values (see ``Planner.parameters``; ``hybridnav planners`` lists them).
    """
    try:
        cls = PLANNERS[name]
    except KeyError:
        raise HybridnavError(
            f"planner: unknown planner {name!r}; expected one of: {', '.join(sorted(PLANNERS))}"
        ) from None
    return cls(**params)


def fuzzy_units(system) -> dict[str, str]:
    """The units of a fuzzy system's variables (figures' axes), as declared by the planner that
    feeds it (``fuzzy_units`` of ``effc``, ``fuzzy-steer``; ``""``: dimensionless): that
    planner provides its inputs, and reads its output when the output has the name the planner
    declares. Empty for a system no planner takes (its units are unknown).

    Parameters
    ----------
    system : FuzzySystem
    """
    from hybridnav.planners.base import accepts_inputs

    names = [*system.input_names, system.output.name]
    for cls in PLANNERS.values():
        units = getattr(cls, "fuzzy_units", {})
        if units and getattr(cls, "fuzzy_inputs", None) \
                and accepts_inputs(cls, system.input_names) \
                and all(n in units for n in system.input_names):
            return {n: units[n] for n in names if n in units}
    return {}


def __getattr__(name: str) -> Any:
    if name == "MOVED":                     # the flat 0.2 module names, now hybridnav.deprecation's
        from hybridnav.deprecation import MOVED_MODULES, warn_renamed

        warn_renamed("hybridnav.planners.MOVED", "hybridnav.deprecation.MOVED_MODULES")
        prefix = f"{__name__}."
        return {k[len(prefix):]: v[len(prefix):] for k, v in MOVED_MODULES.items()
                if k.startswith(prefix)}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
