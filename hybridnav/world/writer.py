"""Writing scenarios back to TOML: :func:`scenario_to_dict`, a minimal TOML writer, :func:`save_scenario`."""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hybridnav import models
from hybridnav.fileio import atomic_write_text
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


# --------------------------------------------------------------------------------------------
# A minimal TOML writer (enough for the scenario schema; no third-party dependency)
# --------------------------------------------------------------------------------------------

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_toml_key(str(k))} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _is_aot(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and len(v) > 0 and all(isinstance(x, Mapping) for x in v)


def _toml_table(d: Mapping[str, Any], prefix: str, out: list[str]) -> None:
    for k, v in d.items():
        if not isinstance(v, Mapping) and not _is_aot(v):
            out.append(f"{_toml_key(str(k))} = {_toml_value(v)}")
    for k, v in d.items():
        if isinstance(v, Mapping):
            name = prefix + _toml_key(str(k))
            out += ["", f"[{name}]"]
            _toml_table(v, name + ".", out)
    for k, v in d.items():
        if _is_aot(v):
            name = prefix + _toml_key(str(k))
            for item in v:
                out += ["", f"[[{name}]]"]
                _toml_table(item, name + ".", out)


def toml_dumps(data: Mapping[str, Any]) -> str:
    """Write a mapping as TOML text (strings, numbers, booleans, arrays, tables, arrays of tables).

    Parameters
    ----------
    data : mapping

    Returns
    -------
    str
        Text that :func:`tomllib.loads` reads back to ``data`` (tuples become lists).
    """
    out: list[str] = []
    _toml_table(data, "", out)
    return "\n".join(out).lstrip("\n") + "\n"


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
