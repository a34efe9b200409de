"""Axis labels with their units: ``"x (m)"``, ``"heading theta (rad)"``, ``"alpha (dimensionless)"``.

Units come from declarations, never from the labels: a model's :attr:`~hybridnav.models.base.
Model.state_units`, a planner's ``signal_units`` and ``fuzzy_units``. A declared unit may contain
the word ``length``, the scenario's length unit (``"length/s"`` is ``"cm/s"`` on a scenario in
centimetres); ``""`` declares a dimensionless quantity.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["LENGTH", "axis_label", "fuzzy_units", "resolve_unit"]

#: the word standing for the scenario's length unit in a declared unit
LENGTH = "length"


def resolve_unit(unit: str | None, length: str | None = None) -> str | None:
    """A declared unit with ``length`` replaced by the length unit (``None``: unknown).

    Parameters
    ----------
    unit : str or None
        ``"rad"``, ``"s"``, ``"length"``, ``"length/s"``, ``""`` (dimensionless) or None.
    length : str, optional
        The scenario's length unit; without it a unit that needs one is unknown.
    """
    if unit is None:
        return None
    if LENGTH in unit:
        return None if length is None else unit.replace(LENGTH, length)
    return unit


def axis_label(name: str, unit: str | None = None, length: str | None = None) -> str:
    """``"name (unit)"``; ``"name (dimensionless)"`` for ``unit == ""``; ``name`` alone when
    the unit is unknown.

    Parameters
    ----------
    name : str
        What the axis shows.
    unit : str or None
        A declared unit (see :func:`resolve_unit`).
    length : str, optional
        The scenario's length unit.
    """
    u = resolve_unit(unit, length)
    if u is None:
        return name
    return f"{name} ({u or 'dimensionless'})"


def fuzzy_units(system) -> dict[str, str]:
    """The units of a fuzzy system's variables, as declared by the planner that feeds it
    (``fuzzy_units`` of ``effc``, ``fuzzy-steer``): that planner provides its inputs (and reads
    its output, when the output has the name the planner declares). Empty for a system no
    planner takes (its units are unknown).

    Parameters
    ----------
    system : FuzzySystem
    """
    from hybridnav.planners import PLANNERS
    from hybridnav.planners.base import accepts_inputs

    names = [*system.input_names, system.output.name]
    for cls in PLANNERS.values():
        units: Mapping[str, str] = getattr(cls, "fuzzy_units", {})
        if units and getattr(cls, "fuzzy_inputs", None) \
                and accepts_inputs(cls, system.input_names) \
                and all(n in units for n in system.input_names):
            return {n: units[n] for n in names if n in units}
    return {}
