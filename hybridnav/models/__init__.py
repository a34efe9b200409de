"""CasADi kinematic models with their go-to-point controllers, compiled for batches.

``get(name, dt=0.1, **params)`` is the entry point other parts and outside tools use::

    >>> from hybridnav import models
    >>> m = models.get("point_mass", alpha1=0.2)
    >>> traj = m.rollout([[0.0, 0.0]], [[10.0, 5.0]], steps=100)   # (1, 101, 2)
"""

from __future__ import annotations

from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.models.base import Model, jit_available, wrap_angle
from hybridnav.models.lbcs import LbCS
from hybridnav.models.point_mass import PointMass
from hybridnav.models.tractor_trailer import TractorTrailer
from hybridnav.models.unicycle import Unicycle

MODELS: dict[str, type[Model]] = {
    cls.name: cls for cls in (PointMass, TractorTrailer, Unicycle, LbCS)
}

__all__ = ["MODELS", "LbCS", "analyzable", "Model", "PointMass", "TractorTrailer", "Unicycle", "get", "jit_available",
           "wrap_angle"]


def analyzable() -> dict[str, str]:
    """The models ``hybridnav analyze`` knows, with the scenario each declares for it."""
    return {name: cls.analysis_scenario for name, cls in MODELS.items() if cls.analysis_scenario}


def get(name: str, dt: float = 0.1, **params: Any) -> Model:
    """Return the kinematic model ``name`` with control step ``dt`` and parameter overrides.

    Parameters
    ----------
    name : str
        One of :data:`MODELS`: ``point_mass``, ``tractor_trailer``, ``unicycle``, ``lbcs``.
    dt : float
        Control and integration step in seconds.
    **params
        Model parameters and options (see each model's ``defaults`` and ``option_defaults``), plus
        ``jit`` (bool or None) and ``radius`` (footprint radius of disk-shaped robots).

    Raises
    ------
    HybridnavError
        Unknown model name or parameter, or a bad value.
    """
    try:
        cls = MODELS[name]
    except (KeyError, TypeError):
        raise HybridnavError(
            f"model: unknown model {name!r}; expected one of: {', '.join(sorted(MODELS))}"
        ) from None
    return cls(dt=dt, **params)
