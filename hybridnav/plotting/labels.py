"""Axis labels with their units: ``"x (m)"``, ``"heading theta (rad)"``, ``"alpha (dimensionless)"``.

Units come from declarations, never from the labels: a model's :attr:`~hybridnav.models.base.
Model.state_units`, a planner's ``signal_units`` and ``fuzzy_units``
(:func:`hybridnav.planners.fuzzy_units`). A declared unit may contain
the word ``length``, the scenario's length unit (``"length/s"`` is ``"cm/s"`` on a scenario in
centimetres); ``""`` declares a dimensionless quantity.
"""

from __future__ import annotations

__all__ = ["LENGTH", "axis_label", "resolve_unit"]

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
