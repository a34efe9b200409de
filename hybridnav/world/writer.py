"""Writing scenarios back to TOML: :func:`scenario_to_dict`, :func:`toml_dumps` (:mod:`tomli_w`),
:func:`save_scenario`."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from hybridnav import models
from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text
from hybridnav.params import short_repr
from hybridnav.world.obstacles import (
    _TYPE_OF,
    Circle,
    MovingCircle,
    Obstacle,
    Rectangle,
    Segment,
)
from hybridnav.world.scenario import Scenario

__all__ = ["save_scenario", "scenario_to_dict", "scenario_to_toml", "toml_dumps"]


def _obstacle_to_dict(o: Obstacle) -> dict[str, Any]:
    kind = _TYPE_OF[type(o)]
    if isinstance(o, Circle):
        return {"type": kind, "center": list(o.center), "radius": o.radius}
    if isinstance(o, MovingCircle):
        return {"type": kind, "center": list(o.center), "radius": o.radius, "velocity": o.velocity,
                "heading": o.heading}
    if isinstance(o, Segment):
        return {"type": kind, "a": list(o.a), "b": list(o.b)}
    if isinstance(o, Rectangle):
        return {"type": kind, "min": list(o.min), "max": list(o.max)}
    return {"type": kind, "points": [list(p) for p in o.points]}


def scenario_to_dict(s: Scenario) -> dict[str, Any]:
    """The TOML-schema dict of a scenario (inverse of :func:`scenario_from_dict`).

    Parameters
    ----------
    s : Scenario

    Returns
    -------
    dict
        Plain lists, floats and strings; ``scenario_from_dict(scenario_to_dict(s)) == s``.
    """
    xmin, xmax, ymin, ymax = s.world.workspace
    out: dict[str, Any] = {
        "name": s.name,
        "description": s.description,
        "units": s.units,
        "dt": s.dt,
        "max_time": s.max_time,
        "workspace": {"xmin": xmin, "xmax": xmax, "ymin": ymin, "ymax": ymax},
        "obstacles": [_obstacle_to_dict(o) for o in s.world.obstacles],
        "robots": [],
    }
    for r in s.robots:
        rd: dict[str, Any] = {"name": r.name, "model": r.model, "start": list(r.start)}
        if r.goal is not None:
            rd["goal"] = list(r.goal)
        if r.goal_follow is not None:
            rd["goal_follow"] = r.goal_follow
        rd["goal_radius"] = r.goal_radius
        if not models.MODELS[r.model].footprint_from_params:   # else it follows from params
            rd["radius"] = r.radius
        rd["initial"] = dict(r.initial)
        rd["params"] = dict(r.params)
        out["robots"].append(rd)
    if s.grid is not None:
        g: dict[str, Any] = {"resolution": s.grid.resolution}
        if s.grid.map is not None:
            g["map"] = s.grid.map
        out["grid"] = g
    return out


def _plain(v: Any, key: str) -> Any:
    """``v`` as the types :mod:`tomli_w` writes; ``key`` names it in errors."""
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    if isinstance(v, str):
        try:                                # a lone surrogate (e.g. undecodable bytes of argv)
            v.encode("utf-8")
        except UnicodeEncodeError as exc:
            raise HybridnavError(f"{key or 'data'}: cannot write {short_repr(v)} as TOML (not "
                                 f"UTF-8: {exc.reason})") from None
        return v
    if isinstance(v, Mapping):
        # a key set to None is a key not set (TOML has no null)
        out = {}
        for k, x in v.items():
            name = str(_plain(k, key) if isinstance(k, str) else k)
            where = f"{key}.{name}" if key else name
            if name in out:                 # e.g. 1 and "1": one would silently replace the other
                raise HybridnavError(f"{where}: two keys written as {name!r}")
            if x is not None:
                out[name] = _plain(x, where)
        return out
    if isinstance(v, np.ndarray) and v.ndim == 0:
        return _plain(v[()], key)
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_plain(x, f"{key}[{i}]") for i, x in enumerate(v)]
    raise HybridnavError(f"{key or 'data'}: cannot write {type(v).__name__} as TOML; expected a "
                         "string, number, boolean, array or table")


def toml_dumps(data: Mapping[str, Any]) -> str:
    """Write a mapping as TOML text (with :mod:`tomli_w`).

    Keys set to ``None`` are left out (TOML has no null); tuples and NumPy arrays are written as
    arrays and NumPy scalars as numbers.

    Parameters
    ----------
    data : mapping

    Returns
    -------
    str
        Text that :func:`tomllib.loads` reads back to ``data``.

    Raises
    ------
    HybridnavError
        For a value TOML cannot hold (``None`` in an array, an object), naming its key.
    """
    if not isinstance(data, Mapping):
        raise HybridnavError(f"cannot write {type(data).__name__} as a TOML document; expected a "
                             "table (mapping)")
    return tomli_w.dumps(_plain(data, ""))


def scenario_to_toml(s: Scenario) -> str:
    """The scenario as TOML text in the public schema (see :func:`scenario_to_dict`)."""
    return toml_dumps(scenario_to_dict(s))


def save_scenario(s: Scenario, path: str | os.PathLike[str]) -> Path:
    """Write a scenario TOML file atomically (temporary file in the same directory, then rename).

    Parameters
    ----------
    s : Scenario
    path : str or path-like

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    atomic_write_text(path, scenario_to_toml(s))
    return path
